//! The CPU backend: every scene of a batch on the rayon pool.

use rayon::prelude::*;

use super::{Backend, Job};
use crate::engine::{simulate_batch, Outcome};

pub struct Cpu;

impl Backend for Cpu {
    fn name(&self) -> &'static str {
        "cpu"
    }

    fn adapter(&self) -> String {
        format!("rayon, {} threads", rayon::current_num_threads())
    }

    fn run(&self, jobs: &[Job]) -> anyhow::Result<Vec<Outcome>> {
        // Chunks small enough to share out uneven scenes between the
        // threads, large enough to fill the lanes of `simulate_batch`.
        let chunk = (jobs.len() / (8 * rayon::current_num_threads())).clamp(8, 256);
        Ok(jobs
            .par_chunks(chunk)
            .flat_map_iter(|chunk| {
                let runs: Vec<_> = chunk
                    .iter()
                    .filter_map(|j| match j {
                        Job::Run { chain, solver } => Some((chain, solver)),
                        Job::Invalid { .. } => None,
                    })
                    .collect();
                let mut done = simulate_batch(&runs).into_iter();
                chunk
                    .iter()
                    .map(|j| match j {
                        Job::Run { .. } => done.next().expect("one outcome per run"),
                        Job::Invalid { n_balls } => Outcome::invalid(*n_balls),
                    })
                    .collect::<Vec<_>>()
            })
            .collect())
    }
}
