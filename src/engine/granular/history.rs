//! Bead histories held in memory, bounded: the data of a space-time image
//! (bead × time, coloured by velocity or contact force) for a chain of any
//! length, e.g. for the explorer's view of a clicked chain scene.
//!
//! At most [`History::beads`] beads are kept (every k-th bead, the last one
//! too) and at most twice `rows` rows: when the rows fill up, every other
//! one is dropped and the spacing doubles, so a run that lasts longer than
//! planned keeps evenly spaced rows in bounded memory.

use super::run::Rows;
use super::step::State;
use super::Beads;

/// Histories of chosen beads at evenly spaced steps.
#[derive(Clone, Debug, PartialEq)]
pub struct History {
    /// The beads kept, ascending.
    pub beads: Vec<usize>,
    /// Row times (s).
    pub t: Vec<f64>,
    /// Per kept bead, its velocity at each row (m/s).
    pub v: Vec<Vec<f64>>,
    /// Per kept bead b, the force of contact (b, b+1) at each row (N; the
    /// right wall's for the last bead, 0 without one).
    pub f: Vec<Vec<f64>>,
    /// Rows are kept every `stride` calls.
    stride: u64,
    calls: u64,
    max_rows: usize,
}

impl History {
    /// Histories of at most `beads` evenly spaced beads of `b` (all when it
    /// has no more), at most `2·rows` rows.
    pub fn new(b: &Beads, beads: usize, rows: usize) -> History {
        let k = b.n.div_ceil(beads.max(2) - 1).max(1);
        let mut kept: Vec<usize> = (0..b.n).step_by(k).collect();
        if kept.last() != Some(&(b.n - 1)) {
            kept.push(b.n - 1);
        }
        History {
            v: vec![vec![]; kept.len()],
            f: vec![vec![]; kept.len()],
            beads: kept,
            t: vec![],
            stride: 1,
            calls: 0,
            max_rows: 2 * rows.max(1),
        }
    }

    fn halve(&mut self) {
        let keep = |x: &mut Vec<f64>| {
            let mut i = 0;
            x.retain(|_| {
                i += 1;
                i % 2 == 1
            })
        };
        keep(&mut self.t);
        self.v.iter_mut().for_each(keep);
        self.f.iter_mut().for_each(keep);
        self.stride *= 2;
    }
}

impl Rows for History {
    fn row(&mut self, t: f64, b: &Beads, st: &State) {
        let call = self.calls;
        self.calls += 1;
        if !call.is_multiple_of(self.stride) {
            return;
        }
        self.t.push(t);
        for (k, &i) in self.beads.iter().enumerate() {
            self.v[k].push(st.v[i]);
            self.f[k].push(st.force(b, i + 1));
        }
        if self.t.len() >= self.max_rows {
            self.halve();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::granular::{plan, run};
    use crate::engine::{Overrides, Solver};
    use crate::scene::Scene;

    #[test]
    fn keeps_bounded_evenly_spaced_rows_of_the_trace() {
        let s = Scene::from_toml_str(
            "h",
            "balls = 100\nradius = 0.005\n[launch]\nballs = 1\nvelocity = 0.1\n[stop]\nduration = 2e-3\n",
        )
        .unwrap();
        let b = Beads::from_scene(&s);
        let solver = Solver::resolve(&s, &Overrides::default()).unwrap();
        let mut p = plan(&b, &solver, None);
        p.every = Some(p.h);
        let mut h = History::new(&b, 30, 50);
        let o = run(&b, &p, &mut h);
        assert!(h.beads.len() <= 31 && h.beads[0] == 0 && *h.beads.last().unwrap() == 99);
        assert!(h.t.len() >= 50 && h.t.len() < 100, "{} rows", h.t.len());
        assert_eq!(h.t[0], 0.0);
        let dt: Vec<f64> = h.t.windows(2).map(|w| w[1] - w[0]).collect();
        for d in &dt[..dt.len() - 1] {
            assert!((d / dt[0] - 1.0).abs() < 1e-6, "uneven rows {d} {}", dt[0]);
        }
        // The striker's velocity at t = 0, and the wave has left it by the end.
        assert_eq!(h.v[0][0], 0.1);
        assert!(o.steps as usize > h.t.len());
        assert!(h.f.iter().flatten().any(|&f| f > 0.0));
    }
}
