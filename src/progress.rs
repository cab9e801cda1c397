//! A progress bar on stderr for the front ends (`cradle sweep`, the Python
//! module): a [`crate::sweep::session::OnProgress`] drawn with indicatif,
//! shown only when stderr is a terminal. Behind the `progress` feature: the
//! core reports progress through the callback alone.

use std::io::IsTerminal;
use std::sync::Arc;

use crate::sweep::session::{OnProgress, Progress};

/// A bar that draws itself as the callback is told; cleared when dropped.
pub struct Bar {
    bar: indicatif::ProgressBar,
}

impl Bar {
    /// A bar on stderr when `show` and stderr is a terminal, else a hidden one.
    pub fn stderr(show: bool) -> Bar {
        let bar = if show && std::io::stderr().is_terminal() {
            let b = indicatif::ProgressBar::new(0);
            b.set_style(
                indicatif::ProgressStyle::with_template(
                    "{bar:40} {pos}/{len} scenes  {per_sec}  ETA {eta}",
                )
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            b
        } else {
            indicatif::ProgressBar::hidden()
        };
        Bar { bar }
    }

    /// The callback that moves this bar.
    pub fn callback(&self) -> OnProgress {
        let bar = self.bar.clone();
        Arc::new(move |p: Progress| {
            bar.set_length(p.total);
            bar.set_position(p.done);
        })
    }
}

impl Drop for Bar {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}
