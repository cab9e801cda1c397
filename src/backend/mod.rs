//! Backends integrate a batch of prepared scenes and return one outcome each,
//! in order. `cpu` is rayon over the Rust engine; `gpu` runs its WGSL twin.

pub mod cpu;
pub mod gpu;
pub mod layout;

use crate::choice::Choice;
use crate::engine::granular::{Beads, ChainOutcome, Plan};
use crate::engine::{Chain, Outcome, Solver, Status};
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
    /// and whether some may be a pendulum or dissipative (the general one).
    pub plain: bool,
    pub terms: bool,
    /// Fewest and most bodies a scene's chain may have.
    pub bodies: (usize, usize),
    /// A sweep of granular chains (docs/SPEC.md §9): only the chain kernel.
    pub chains: bool,
}

/// What a GPU did during a sweep (the sidecar's `stages_s.gpu`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeviceStats {
    /// Compute dispatches submitted.
    pub dispatches: u64,
    /// Rounds: submissions of dispatches followed by a look at the counters.
    pub rounds: u64,
    /// Seconds during which at least one submission was in flight (an upper
    /// bound of the device's busy time, as the host sees it).
    pub in_flight_s: f64,
    /// Scenes the backend ran on the CPU engine instead (`Profile::cpu_above`).
    pub cpu_scenes: u64,
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
