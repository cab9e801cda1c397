//! The physics engines on the CPU, one folder per model (`crate::model`):
//! `cradle` (the cradle's integrator) and `granular` (long chains), and what
//! they share: contact law, chain of rigid bodies, outcomes, precisions. The
//! GPU backend runs their WGSL twins, `shaders/cradle/` and
//! `shaders/granular/`.

pub mod chain;
pub mod contact;
pub mod cradle;
pub mod granular;
pub mod models;
pub mod outcome;
pub mod real;
pub mod solver;

pub use chain::Chain;
pub use cradle::{
    integrate, integrate_batch, integrate_batch_until, End, Limits, Observer, Run, Silent,
    StepPlan, Task,
};
pub use models::Model;
pub use outcome::{Outcome, Status, MAX_OVERLAP_RATIO};
pub use solver::{Overrides, Solver, StepRule};

use crate::scene::Precision;
use real::Df64;

/// A request to end a long run early, shared with whoever may make it (the
/// explorer, when a scene passes its time limit and its caller has been
/// answered): a granular chain's run looks at it every
/// [`granular::run::CHECK_EVERY`] steps and ends. The outcome of a stopped run
/// is not the scene's: the one who stopped it discards it. Not part of a
/// plan's identity (plans compare equal whatever their `Stop`).
#[derive(Clone, Debug, Default)]
pub struct Stop(Option<std::sync::Arc<std::sync::atomic::AtomicBool>>);

impl PartialEq for Stop {
    fn eq(&self, _: &Stop) -> bool {
        true
    }
}

/// A running count of the bead-steps runs have taken, shared with whoever
/// shows progress (a sweep of long chains moves its bar as the chains
/// step, not only when a batch ends): a granular chain's run adds to it
/// every 2^16 bead-steps or so and at its end, twins and reruns included.
/// Not part of a plan's identity.
#[derive(Clone, Debug, Default)]
pub struct Tally(Option<std::sync::Arc<std::sync::atomic::AtomicU64>>);

impl PartialEq for Tally {
    fn eq(&self, _: &Tally) -> bool {
        true
    }
}

impl Tally {
    /// A count from 0 that every clone adds to.
    pub fn new() -> Tally {
        Tally(Some(Default::default()))
    }

    pub fn add(&self, n: u64) {
        if let Some(c) = &self.0 {
            c.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
        }
    }

    /// The count so far (`None`: not counting).
    pub fn get(&self) -> Option<u64> {
        self.0
            .as_ref()
            .map(|c| c.load(std::sync::atomic::Ordering::Relaxed))
    }
}

impl Stop {
    /// A stop that [`Stop::request`] on any clone triggers.
    pub fn new() -> Stop {
        Stop(Some(Default::default()))
    }

    pub fn request(&self) {
        if let Some(f) = &self.0 {
            f.store(true, std::sync::atomic::Ordering::Relaxed);
        }
    }

    /// A stop that `flag` triggers, as set by whoever holds it (a sweep's
    /// interrupt, Ctrl-C).
    pub fn on(flag: std::sync::Arc<std::sync::atomic::AtomicBool>) -> Stop {
        Stop(Some(flag))
    }

    /// Whether it can ever be requested (not [`Stop::default`]).
    pub fn is_live(&self) -> bool {
        self.0.is_some()
    }

    pub fn requested(&self) -> bool {
        self.0
            .as_ref()
            .is_some_and(|f| f.load(std::sync::atomic::Ordering::Relaxed))
    }
}

/// The step (`None`: nothing can collide) and caps of one run; both backends
/// start from exactly these.
pub fn plan(chain: &Chain, solver: &Solver) -> (Option<StepPlan>, Limits) {
    let lim = Limits {
        max_steps: solver.max_steps,
        max_time: solver.max_time,
    };
    (solver.step_plan(chain), lim)
}

/// The plan of a chain where nothing can collide: it settles before any step.
pub const UNSTEPPED: StepPlan = StepPlan {
    h: f64::INFINITY,
    weights: &[1.0],
    graded: false,
    h_min: f64::INFINITY,
    grade_quarters: 0,
    t_scale: f64::INFINITY,
    settle_rel: 0.0,
    h_free: f64::INFINITY,
    exact: false,
    h_stiff: 0.0,
    omega_ref: 1.0,
};

/// Simulate one compiled chain with `solver`, reporting states to `obs`.
pub fn simulate_chain<O: Observer>(chain: &Chain, solver: &Solver, obs: &mut O) -> Outcome {
    if solver.model != Model::Hertz {
        return simulate_model(chain, solver);
    }
    let (task, dt) = hertz_task(chain, solver);
    let run = match solver.precision {
        Precision::F64 => integrate::<f64, O>(chain, &task.plan, &task.lim, obs),
        Precision::F32 => integrate::<f32, O>(chain, &task.plan, &task.lim, obs),
        Precision::Df64 => integrate::<Df64, O>(chain, &task.plan, &task.lim, obs),
    };
    Outcome::from_run(chain, &run, dt)
}

/// Simulate many chains, in order: the Hertz runs of each precision are
/// integrated side by side ([`integrate_batch`]), with the same results as
/// [`simulate_chain`] on each.
pub fn simulate_batch(jobs: &[(&Chain, &Solver)]) -> Vec<Outcome> {
    simulate_batch_until(jobs, &Stop::default()).expect("a stop nobody requests")
}

/// [`simulate_batch`], no Hertz run started once `stop` is set: then
/// `None`, after the runs in the lanes end ([`integrate_batch_until`]).
pub fn simulate_batch_until(jobs: &[(&Chain, &Solver)], stop: &Stop) -> Option<Vec<Outcome>> {
    let mut out: Vec<Option<Outcome>> = vec![None; jobs.len()];
    for (precision, idx) in hertz_groups(jobs, |_, s| s.precision) {
        let tasks: Vec<(Task, f64)> = idx
            .iter()
            .map(|&i| hertz_task(jobs[i].0, jobs[i].1))
            .collect();
        let plain: Vec<Task> = tasks.iter().map(|t| t.0).collect();
        let runs = match precision {
            Precision::F32 => integrate_batch_until::<f32>(&plain, stop),
            Precision::F64 => integrate_batch_until::<f64>(&plain, stop),
            Precision::Df64 => integrate_batch_until::<Df64>(&plain, stop),
        }?;
        for ((i, run), (task, dt)) in idx.into_iter().zip(runs).zip(tasks) {
            out[i] = Some(Outcome::from_run(task.chain, &run, dt));
        }
    }
    Some(
        out.into_iter()
            .zip(jobs)
            .map(|(o, (c, s))| o.unwrap_or_else(|| simulate_model(c, s)))
            .collect(),
    )
}

/// [`simulate_batch`] on the rayon pool, in chunks small enough to share
/// out uneven scenes between the threads, large enough to fill the lanes.
pub fn simulate_batch_parallel(jobs: &[(&Chain, &Solver)]) -> Vec<Outcome> {
    simulate_batch_parallel_until(jobs, &Stop::default()).expect("a stop nobody requests")
}

/// [`simulate_batch_parallel`], no run started once `stop` is set: then
/// `None`, after the runs in the lanes end (a scene a lane). The same
/// chunks and lanes, so the same outcomes.
pub fn simulate_batch_parallel_until(
    jobs: &[(&Chain, &Solver)],
    stop: &Stop,
) -> Option<Vec<Outcome>> {
    use rayon::prelude::*;
    let chunk = (jobs.len() / (8 * rayon::current_num_threads())).clamp(8, 256);
    let chunks: Option<Vec<Vec<Outcome>>> = jobs
        .par_chunks(chunk)
        .map(|c| simulate_batch_until(c, stop))
        .collect();
    Some(chunks?.into_iter().flatten().collect())
}

/// Job routing, one definition for every backend: the Hertz runs of `jobs`
/// (indices, in order) grouped by `key` (precision, and whatever else picks
/// a kernel: the GPU adds `TERMS` and the size class). Comparison models are
/// left out: they are instant on the CPU ([`simulate_chain`]).
pub fn hertz_groups<K: Ord>(
    jobs: &[(&Chain, &Solver)],
    key: impl Fn(&Chain, &Solver) -> K,
) -> std::collections::BTreeMap<K, Vec<usize>> {
    let mut groups = std::collections::BTreeMap::<K, Vec<usize>>::new();
    for (i, (c, s)) in jobs.iter().enumerate() {
        if s.model == Model::Hertz {
            groups.entry(key(c, s)).or_default().push(i);
        }
    }
    groups
}

/// A Hertz run of `chain` and its nominal step (NaN when nothing can collide).
fn hertz_task<'a>(chain: &'a Chain, solver: &Solver) -> (Task<'a>, f64) {
    let (sp, lim) = plan(chain, solver);
    // A chain where nothing can collide still runs: the integrator sees it settled.
    let plan = sp.unwrap_or(UNSTEPPED);
    (Task { chain, plan, lim }, row_dt(&plan))
}

/// The `dt` column of a Hertz run planned as `plan`: its nominal step, NaN
/// when nothing can collide. Every backend reports this one.
pub fn row_dt(plan: &StepPlan) -> f64 {
    if plan.h.is_finite() {
        plan.h
    } else {
        f64::NAN
    }
}

/// A comparison model's outcome (closed-form or event-driven).
fn simulate_model(chain: &Chain, solver: &Solver) -> Outcome {
    if solver.model.unsupported(chain).is_some() {
        return Outcome::invalid(chain.n_balls);
    }
    let run = match solver.model {
        Model::HardSphere => models::hard_sphere(chain),
        _ => models::closure(chain),
    };
    Outcome::from_run(chain, &run, f64::NAN)
}
