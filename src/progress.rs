//! A progress bar on stderr for the command line (`cradle sweep`): a
//! [`crate::sweep::session::OnProgress`] drawn with indicatif,
//! shown only when stderr is a terminal. Behind the `progress` feature: the
//! core reports progress through the callback alone (the Python module
//! draws its own bar, or calls the user's function, from it).

use std::io::IsTerminal;
use std::sync::Arc;

use crate::sweep::session::{OnProgress, Progress};

/// Scenes per second as a person reads them: "6418 scenes/s", "12.5
/// scenes/s", "0.31 scenes/s" (indicatif's own printed "6,418.4702/s", and
/// a sweep of slow chains "0 scenes/s").
pub fn rate(per_s: f64) -> String {
    match per_s {
        r if !r.is_finite() => "- scenes/s".to_string(),
        r if r >= 100.0 => format!("{r:.0} scenes/s"),
        r if r >= 10.0 => format!("{r:.1} scenes/s"),
        r => format!("{r:.2} scenes/s"),
    }
}

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
                    "{bar:40} {pos}/{len} scenes  {rate}  ETA {eta}",
                )
                .map(|st| {
                    st.with_key(
                        "rate",
                        |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
                            let _ = write!(w, "{}", rate(s.per_sec()));
                        },
                    )
                })
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
