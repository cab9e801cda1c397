//! The CPU backend: every scene of a batch on the rayon pool.

use rayon::prelude::*;

use super::{Backend, Job};
use crate::engine::{simulate_chain, Outcome, Silent};

pub struct Cpu;

impl Backend for Cpu {
    fn name(&self) -> &'static str {
        "cpu"
    }

    fn adapter(&self) -> String {
        format!("rayon, {} threads", rayon::current_num_threads())
    }

    fn run(&self, jobs: &[Job]) -> anyhow::Result<Vec<Outcome>> {
        Ok(jobs
            .par_iter()
            .with_min_len(4)
            .map(|j| match j {
                Job::Run { chain, solver } => simulate_chain(chain, solver, &mut Silent),
                Job::Invalid { n_balls } => Outcome::invalid(*n_balls),
            })
            .collect())
    }
}
