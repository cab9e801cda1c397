//! The CPU backend: every scene of a batch on the rayon pool.

use rayon::prelude::*;

use super::{Backend, ChainSource, Job};
use crate::engine::granular::{self, ChainOutcome};
use crate::engine::{simulate_batch_parallel_until, Outcome, Stop};
use crate::error::Interrupted;

pub struct Cpu;

impl Backend for Cpu {
    fn name(&self) -> &'static str {
        "cpu"
    }

    fn adapter(&self) -> String {
        match rayon::current_num_threads() {
            1 => "rayon, 1 thread".to_string(),
            n => format!("rayon, {n} threads"),
        }
    }

    fn run(&self, jobs: &[Job]) -> anyhow::Result<Vec<Outcome>> {
        self.run_until(jobs, &Stop::default())
    }

    fn run_until(&self, jobs: &[Job], stop: &Stop) -> anyhow::Result<Vec<Outcome>> {
        let runs: Vec<_> = jobs
            .iter()
            .filter_map(|j| match j {
                Job::Run { chain, solver } => Some((chain, solver)),
                Job::Invalid { .. } => None,
            })
            .collect();
        let Some(done) = simulate_batch_parallel_until(&runs, stop) else {
            return Err(Interrupted.into());
        };
        let mut done = done.into_iter();
        Ok(jobs
            .iter()
            .map(|j| match j {
                Job::Run { .. } => done.next().expect("one outcome per run"),
                Job::Invalid { n_balls } => Outcome::invalid(*n_balls),
            })
            .collect())
    }

    /// Every chain a task of its own (a chain's cost varies with its
    /// length and speed: one long chain must not hold others back).
    fn run_chains(&self, n: usize, job: ChainSource) -> anyhow::Result<Vec<ChainOutcome>> {
        self.run_chains_until(n, job, &Stop::default())
    }

    fn run_chains_until(
        &self,
        n: usize,
        job: ChainSource,
        stop: &Stop,
    ) -> anyhow::Result<Vec<ChainOutcome>> {
        (0..n)
            .into_par_iter()
            .with_max_len(1)
            .map(|k| {
                if stop.requested() {
                    return Err(Interrupted.into());
                }
                let o = match job(k)? {
                    Some(mut j) => {
                        // A chain running sees the request too (every few
                        // steps); its outcome is then not the scene's.
                        if stop.is_live() {
                            j.plan.stop = stop.clone();
                        }
                        granular::run(&j.beads, &j.plan, &mut granular::NoRows)
                    }
                    None => ChainOutcome::invalid(),
                };
                if stop.requested() {
                    return Err(Interrupted.into());
                }
                Ok(o)
            })
            .collect()
    }
}
