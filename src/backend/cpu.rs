//! The CPU backend: every scene of a batch on the rayon pool.

use rayon::prelude::*;

use super::{Backend, ChainSource, Job};
use crate::engine::granular::{self, ChainOutcome};
use crate::engine::{simulate_batch_parallel, Outcome};

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

    /// Every chain a task of its own (a chain's cost varies with its
    /// length and speed: one long chain must not hold others back).
    fn run_chains(&self, n: usize, job: ChainSource) -> anyhow::Result<Vec<ChainOutcome>> {
        (0..n)
            .into_par_iter()
            .with_max_len(1)
            .map(|k| {
                Ok(match job(k)? {
                    Some(j) => granular::run(&j.beads, &j.plan, &mut granular::NoRows),
                    None => ChainOutcome::invalid(),
                })
            })
            .collect()
    }
}
