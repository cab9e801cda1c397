//! The CPU backend: every scene of a batch on the rayon pool.

use super::{Backend, Job};
use crate::engine::{simulate_batch_parallel, Outcome};

pub struct Cpu;

impl Backend for Cpu {
    fn name(&self) -> &'static str {
        "cpu"
    }

    fn adapter(&self) -> String {
        format!("rayon, {} threads", rayon::current_num_threads())
    }

    fn run(&self, jobs: &[Job]) -> anyhow::Result<Vec<Outcome>> {
        let runs: Vec<_> = jobs
            .iter()
            .filter_map(|j| match j {
                Job::Run { chain, solver } => Some((chain, solver)),
                Job::Invalid { .. } => None,
            })
            .collect();
        let mut done = simulate_batch_parallel(&runs).into_iter();
        Ok(jobs
            .iter()
            .map(|j| match j {
                Job::Run { .. } => done.next().expect("one outcome per run"),
                Job::Invalid { n_balls } => Outcome::invalid(*n_balls),
            })
            .collect())
    }
}
