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

/// `n` bead-steps at `per_s` as the bar shows them: "  1.23e9 bead-steps,
/// 4.10e8/s".
pub fn work(n: u64, per_s: f64) -> String {
    format!("  {:.2e} bead-steps, {per_s:.2e}/s", n as f64)
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
                    "{bar:40} {pos}/{len} scenes  {rate}  ETA {eta}{msg}",
                )
                .map(|st| {
                    st.with_key(
                        "rate",
                        |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
                            let _ = write!(w, "{}", rate(s.per_sec()));
                        },
                    )
                    // No "ETA 0s" before the first row: nothing to tell it from.
                    .with_key(
                        "eta",
                        |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
                            let _ = match s.pos() {
                                0 => write!(w, "-"),
                                _ => write!(w, "{:#}", indicatif::HumanDuration(s.eta())),
                            };
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

    /// Show, every half second while the bar lives, the work `done`
    /// reports (a chain sweep's bead-steps, `Model::work_done`) and its
    /// rate beside the scenes: a sweep of a few long chains writes no row
    /// for minutes, yet its bar moves.
    pub fn watch(&self, done: impl Fn() -> Option<u64> + Send + 'static) {
        if self.bar.is_hidden() {
            return;
        }
        let bar = self.bar.clone();
        let t0 = std::time::Instant::now();
        std::thread::spawn(move || {
            // The rate over the last ~5 s (the window of beads in motion
            // grows as a chain runs: its long-run average would lag).
            let mut seen = std::collections::VecDeque::new();
            while !bar.is_finished() {
                let now = t0.elapsed().as_secs_f64();
                if let Some(n) = done() {
                    seen.push_back((now, n));
                    if seen.len() > 10 {
                        seen.pop_front();
                    }
                    let (t_old, n_old) = seen[0];
                    if n > 0 && now > t_old {
                        bar.set_message(work(n, (n - n_old) as f64 / (now - t_old)));
                    }
                }
                std::thread::sleep(std::time::Duration::from_millis(500));
            }
        });
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
