//! Backends integrate a batch of prepared scenes and return one outcome each,
//! in order. `cpu` is rayon over the Rust engine; `gpu` runs its WGSL twin.

pub mod cpu;
pub mod gpu;
pub mod layout;

use crate::choice::Choice;
use crate::engine::granular::{self, Beads, ChainOutcome, Plan, Rows};
use crate::engine::{Chain, Outcome, Solver, Status, Stop};
use crate::error::{flag, InputError};
use crate::scene::Precision;

/// Scenes per batch on the CPU: the unit of work of a sweep lane and of a
/// backend call (a backend says its own: [`Backend::batch_size`]).
pub const BATCH: u64 = 2048;

/// Which backend a sweep runs on (`--backend`, `backend=`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackendChoice {
    /// A hardware GPU that can run the precision, else the CPU (said on stderr).
    Auto,
    /// Any GPU adapter, software ones (Mesa lavapipe) included, or an error.
    Gpu,
    /// rayon over the Rust engine.
    Cpu,
}

impl Choice for BackendChoice {
    const ALL: &'static [Self] = &[BackendChoice::Auto, BackendChoice::Gpu, BackendChoice::Cpu];
    fn name(self) -> &'static str {
        match self {
            BackendChoice::Auto => "auto",
            BackendChoice::Gpu => "gpu",
            BackendChoice::Cpu => "cpu",
        }
    }
}

/// One scene ready to integrate, or a combination of sweep values that did
/// not make a valid scene (its row gets status `invalid`).
/// (`Invalid` is rare: boxing `Run` would cost an allocation per scene.)
#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant)]
pub enum Job {
    Run { chain: Chain, solver: Solver },
    Invalid { n_balls: usize },
}

/// A granular chain of a sweep, compiled and planned (docs/SPEC.md §9).
#[derive(Clone, Debug)]
pub struct ChainJob {
    pub beads: Beads,
    pub plan: Plan,
}

/// Builds chain k of a batch for [`Backend::run_chains`].
pub type ChainSource<'a> = &'a (dyn Fn(usize) -> Result<Option<ChainJob>, InputError> + Sync);

pub trait Backend: Sync {
    /// `cpu` or `gpu`.
    fn name(&self) -> &'static str;
    /// What it runs on, for the summary line and the sidecar.
    fn adapter(&self) -> String;
    /// Outcomes of `jobs`, in the same order.
    fn run(&self, jobs: &[Job]) -> anyhow::Result<Vec<Outcome>>;
    /// [`Backend::run`], giving up once `stop` is requested (an interrupt):
    /// then `Err(`[`crate::error::Interrupted`]`)` and no outcome, the
    /// sweep keeping the rows of the batches before. The default runs to
    /// the end (a GPU's batch is seconds at most); on the CPU no lane takes
    /// a scene after the request, the runs in the lanes ending first
    /// ([`crate::engine::simulate_batch_parallel_until`]). (The sweep
    /// pipeline's wrapper that calls this, `sweep::pipeline::Stoppable`,
    /// forwards every method of this trait: a new one goes there too.)
    fn run_until(&self, jobs: &[Job], _stop: &Stop) -> anyhow::Result<Vec<Outcome>> {
        self.run(jobs)
    }
    /// Scenes per `run` call of the sweep pipeline.
    fn batch_size(&self) -> u64 {
        BATCH
    }
    /// How many `run` calls the sweep pipeline may make at once: the CPU
    /// shares its rayon pool among any number; the GPU takes one.
    fn max_concurrent_runs(&self) -> usize {
        usize::MAX
    }
    /// What a device did so far (GPU backends).
    fn device_stats(&self) -> Option<DeviceStats> {
        None
    }
    /// Outcomes of `n` granular chains (docs/SPEC.md §9) in order, chain k
    /// built by `job(k)` only when it is about to run (`None`: its values
    /// make no valid chain, status `invalid`). A backend without a chain
    /// kernel refuses (a chain sweep is given one that has it).
    fn run_chains(&self, n: usize, _job: ChainSource) -> anyhow::Result<Vec<ChainOutcome>> {
        anyhow::bail!(
            "the {} backend has no granular-chain kernel ({n} chains): run chain sweeps with --backend cpu",
            self.name()
        )
    }
    /// [`Backend::run_chains`], giving up once `stop` is requested, as
    /// [`Backend::run_until`]. On the CPU no chain starts after the request,
    /// and a chain running sees it through its plan's stop
    /// ([`crate::engine::granular::run()`] looks every few steps) and ends.
    fn run_chains_until(
        &self,
        n: usize,
        job: ChainSource,
        _stop: &Stop,
    ) -> anyhow::Result<Vec<ChainOutcome>> {
        self.run_chains(n, job)
    }
    /// Get ready for scenes as `needs` describes, before the first one runs:
    /// a GPU backend compiles every pipeline they can use here, so a shader
    /// that does not build on the device fails before any work.
    fn prepare(&self, _needs: &Needs) -> anyhow::Result<()> {
        Ok(())
    }
}

/// What a sweep's scenes can ask of a backend, known from the sweep file
/// before any scene is built ([`crate::sweep::Sweep::needs`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Needs {
    /// The precision every scene runs in.
    pub precision: Precision,
    /// Whether the integrator is needed at all (`--model hertz`, the default;
    /// the comparison models run on the CPU).
    pub hertz: bool,
    /// Whether some scene may be elastic on a free line (the plain pipeline)
    /// and whether some may be a pendulum or dissipative (the general one);
    /// for granular chains, elastic and damped (a kernel each).
    pub plain: bool,
    pub terms: bool,
    /// Fewest and most bodies a scene's chain may have.
    pub bodies: (usize, usize),
    /// A sweep of granular chains (docs/SPEC.md §9): only the chain kernel.
    pub chains: bool,
}

/// At most `n` holders at a time (a counting semaphore): the sweep
/// pipeline's backend calls, a GPU's batches on the device.
pub(crate) struct Gate {
    free: std::sync::Mutex<usize>,
    cv: std::sync::Condvar,
}

/// A place in a [`Gate`], given back when dropped (also when its holder
/// panics).
pub(crate) struct Pass<'a>(&'a Gate);

impl Gate {
    /// A gate of `n` places (at least one).
    pub(crate) fn new(n: usize) -> Gate {
        Gate {
            free: std::sync::Mutex::new(n.max(1)),
            cv: std::sync::Condvar::new(),
        }
    }

    /// Wait for a place.
    pub(crate) fn enter(&self) -> Pass<'_> {
        let mut free = self.free.lock().unwrap_or_else(|e| e.into_inner());
        while *free == 0 {
            free = self.cv.wait(free).unwrap_or_else(|e| e.into_inner());
        }
        *free -= 1;
        Pass(self)
    }

    /// `f` run holding a place.
    pub(crate) fn with<T>(&self, f: impl FnOnce() -> T) -> T {
        let _pass = self.enter();
        f()
    }
}

impl Drop for Pass<'_> {
    fn drop(&mut self) {
        *self.0.free.lock().unwrap_or_else(|e| e.into_inner()) += 1;
        self.0.cv.notify_one();
    }
}

/// What a GPU did during a sweep (the sidecar's `stages_s.gpu`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeviceStats {
    /// Compute dispatches submitted.
    pub dispatches: u64,
    /// Rounds: submissions of dispatches followed by a look at the counters.
    pub rounds: u64,
    /// Batches the cradle kernels' rounds ran, summed over the rounds (a
    /// round's dispatches run every batch held on the device at once).
    pub batch_rounds: u64,
    /// The most batches one round ran.
    pub most_batches: u64,
    /// Seconds during which at least one submission was in flight (an upper
    /// bound of the device's busy time, as the host sees it).
    pub in_flight_s: f64,
    /// Scenes the backend ran on the CPU engine instead (`Profile::cpu_above`).
    pub cpu_scenes: u64,
    /// Thread-seconds spent planning and packing scenes for the device.
    pub packing_s: f64,
    /// Thread-seconds spent reading outcomes out of the device's words.
    pub unpacking_s: f64,
    /// Thread-seconds packed batches waited for a turn on the device.
    pub waiting_s: f64,
    /// Seconds spent building pipelines (the driver's shader compiles).
    pub compiling_s: f64,
}

/// Run `jobs`; with `estimate`, also their coarse twins (every step twice as
/// long) and fill each `ok` outcome's `error_estimate` by Richardson.
pub fn run_with_estimate(
    backend: &dyn Backend,
    jobs: &[Job],
    estimate: bool,
) -> anyhow::Result<Vec<Outcome>> {
    if !estimate {
        return backend.run(jobs);
    }
    let mut all = jobs.to_vec();
    all.extend(jobs.iter().map(|j| match j {
        Job::Run { chain, solver } => Job::Run {
            chain: chain.clone(),
            solver: solver.coarse(),
        },
        other => other.clone(),
    }));
    let mut out = backend.run(&all)?;
    let coarse = out.split_off(jobs.len());
    for ((o, c), j) in out.iter_mut().zip(&coarse).zip(jobs) {
        if let Job::Run { chain, solver } = j {
            if o.status == Status::Ok && c.status == Status::Ok {
                o.error_estimate = solver.error_estimate(&o.v, &c.v, chain.v_in());
            }
        }
    }
    Ok(out)
}

/// Run `n` granular chains under the error control (docs/SPEC.md §9,
/// [`crate::engine::granular::control`]): each `ok` run, then its twin
/// (the same chain to the same end at [`crate::engine::granular::control::TWIN_RATIO`] times its
/// step), then, for chains under a tolerance whose estimate is above it,
/// reruns at finer steps, each checked against the run before it. Each
/// pass is one `run_chains` call of the backend over the chains that need
/// it (the others are skipped as `None`), so both backends run the same
/// plans and give the same rows. Each outcome is the last (finest) run's,
/// with its `error_estimate`, and status `inaccurate` or `sensitive` where
/// the estimate stayed above the tolerance.
pub fn run_chains_controlled(
    backend: &dyn Backend,
    n: usize,
    job: ChainSource,
) -> anyhow::Result<Vec<ChainOutcome>> {
    use crate::engine::granular::control;
    let mut out = backend.run_chains(n, job)?;
    // Per chain under control: the last run's step, the differences of
    // its pairs so far, and whether it may be refined further.
    struct Track {
        h: f64,
        diffs: Vec<f64>,
        open: bool,
        /// The order of the last pair's estimate.
        q: f64,
    }
    let mut track: Vec<Option<Track>> = out
        .iter()
        .map(|o| {
            (o.status == Status::Ok).then(|| Track {
                h: o.dt,
                diffs: vec![],
                open: true,
                q: control::ESTIMATE_ORDER,
            })
        })
        .collect();
    let ends: Vec<f64> = out.iter().map(|o| o.t_end).collect();
    // Chains with dashpots take a rerun even when the twin says they meet
    // their tolerance: beads that barely touch in a wake switch their
    // dashpot on and off with the sign of an overlap at round-off, an error
    // that need not fall with the step and that one pair can miss (a driven
    // chain `ok` at 1.9x its 1e-8: results/chains.md). The second pair
    // then shows whether the difference falls (the verdict's `sensitive`).
    // Pass 0: the twins (a coarser step); then reruns at finer steps.
    for pass in 0..=control::MAX_RERUNS {
        let steps: Vec<Option<f64>> = track
            .iter()
            .zip(&out)
            .map(|(t, o)| {
                let t = t.as_ref().filter(|t| t.open)?;
                if pass == 0 {
                    return Some(t.h * control::TWIN_RATIO);
                }
                let tol = o.tolerance?;
                (o.error_estimate > tol || (pass == 1 && o.dashpots))
                    .then(|| control::next_step(t.h, o.error_estimate, tol, t.q))
            })
            .collect();
        if steps.iter().all(Option::is_none) {
            break;
        }
        let runs = backend.run_chains(n, &|k| {
            let Some(h) = steps[k] else { return Ok(None) };
            Ok(job(k)?.map(|mut j| {
                if pass == 0 {
                    // The twin is never reported, so never traced: not
                    // aligned to a record's `every`, which could round its
                    // step back to the run's own (a step of `every`: no
                    // twin at all, an estimate of 0/0).
                    j.plan.every = None;
                }
                j.plan = j.plan.rerun(&j.beads, h, ends[k], false);
                j
            }))
        })?;
        for (k, r) in runs.into_iter().enumerate() {
            let (Some(t), Some(_)) = (track[k].as_mut(), steps[k]) else {
                continue;
            };
            if pass > 0 && r.status != Status::Ok {
                // A finer run that failed (the step cap): the row stays
                // the last good run's, with its estimate.
                t.open = false;
                continue;
            }
            let (fine, coarse) = if pass == 0 {
                (&out[k], &r)
            } else {
                (&r, &out[k])
            };
            let d = control::difference(out[k].v_scale, fine, coarse);
            t.q = control::order(fine.refined, coarse.refined);
            let est = control::estimate(d, coarse.dt / fine.dt, t.q);
            t.diffs.push(d);
            if pass > 0 {
                t.h = r.dt;
                out[k] = r;
            }
            out[k].error_estimate = est;
        }
    }
    for (o, t) in out.iter_mut().zip(&track) {
        if let (Some(t), Some(tol)) = (t, o.tolerance) {
            o.status = control::verdict(o.error_estimate, tol, &t.diffs);
        }
    }
    Ok(out)
}

/// One chain under the error control ([`run_chains_controlled`]) on the
/// CPU: `cradle run`, Python's `run` and the explorer's chain view.
pub fn run_chain_controlled(job: &ChainJob) -> anyhow::Result<ChainOutcome> {
    Ok(run_chains_controlled(&cpu::Cpu, 1, &|_| Ok(Some(job.clone())))?.remove(0))
}

/// The run that `row`, a controlled outcome of `job`, reports, run again
/// with its rows to `rows` (every step offered to them if `every_step`):
/// the same plan, so the same bits, with the row's status and estimate. A
/// trace or a history is thus the row's own run.
pub fn rerun_reported(
    job: &ChainJob,
    row: &ChainOutcome,
    rows: &mut dyn Rows,
    every_step: bool,
) -> ChainOutcome {
    let mut plan = if row.dt == job.plan.h {
        job.plan.clone()
    } else {
        job.plan.rerun(&job.beads, row.dt, row.t_end, false)
    };
    if every_step {
        plan.every = Some(plan.h);
    }
    ChainOutcome {
        status: row.status,
        error_estimate: row.error_estimate,
        ..granular::run(&job.beads, &plan, rows)
    }
}

/// `auto`: a hardware GPU that can run `precision`, else the CPU (said on
/// stderr); `gpu`: any adapter, software ones included, or an error.
pub fn choose(choice: BackendChoice, precision: Precision) -> anyhow::Result<Box<dyn Backend>> {
    let want = match choice {
        BackendChoice::Cpu => return Ok(Box::new(cpu::Cpu)),
        BackendChoice::Auto => gpu::Want::Hardware,
        BackendChoice::Gpu => gpu::Want::Any,
    };
    let Some(adapter) = gpu::find_adapter(want) else {
        if choice == BackendChoice::Gpu {
            return Err(flag("--backend", "gpu", "no GPU adapter found (not even a software one such as Mesa lavapipe); use --backend cpu").into());
        }
        eprintln!(
            "cradle: no hardware GPU found; running on the CPU ({})",
            cpu::Cpu.adapter()
        );
        return Ok(Box::new(cpu::Cpu));
    };
    let mut gpu = gpu::Gpu::new(&adapter)?;
    if let Some(profile) = gpu::Profile::from_env()? {
        gpu = gpu.with_profile(profile);
    }
    if precision == Precision::F64 && !gpu.has_f64() {
        if choice == BackendChoice::Gpu {
            return Err(flag(
                "--backend",
                "gpu",
                &format!(
                    "{} has no 64-bit floats (SHADER_F64): add --precision df64 (f32 pairs, f64's results) or f32",
                    gpu.adapter()
                ),
            )
            .into());
        }
        eprintln!("cradle: {} has no 64-bit floats; running f64 on the CPU ({}); --precision df64 (f32 pairs, f64's results) or f32 would use the GPU", gpu.adapter(), cpu::Cpu.adapter());
        return Ok(Box::new(cpu::Cpu));
    }
    eprintln!("cradle: backend gpu: {}", gpu.adapter());
    Ok(Box::new(gpu))
}
