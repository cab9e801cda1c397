//! Backends integrate a batch of prepared scenes and return one outcome each,
//! in order. `cpu` is rayon over the Rust engine; `gpu` runs its WGSL twin.

pub mod cpu;
pub mod gpu;

use crate::engine::{Chain, Outcome, Solver};

/// One scene ready to integrate, or a combination of sweep values that did
/// not make a valid scene (its row gets status `invalid`).
#[derive(Clone, Debug)]
pub enum Job {
    Run { chain: Chain, solver: Solver },
    Invalid { n_balls: usize },
}

pub trait Backend: Sync {
    /// `cpu` or `gpu`.
    fn name(&self) -> &'static str;
    /// What it runs on, for the summary line and the sidecar.
    fn adapter(&self) -> String;
    /// Outcomes of `jobs`, in the same order.
    fn run(&self, jobs: &[Job]) -> anyhow::Result<Vec<Outcome>>;
}
