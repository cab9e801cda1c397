//! Validated configuration: `cli.rs` holds the raw flags as clap parsed them;
//! here they become typed, checked settings before any work starts (the
//! low-level → high-level split of ripgrep's `lowargs`/`hiargs`). Every rule
//! about what a run may do is decided here, once:
//! - the output path (`output::guard`: never an input, a directory, a device,
//!   a FIFO; a symlink is written through);
//! - a setting given both as a flag and in a file: an error naming both,
//!   unless they agree (a flag never silently replaces an axis);
//! - resource limits: threads, the tolerance's round-off floor per precision.

use std::path::{Path, PathBuf};

use crate::cli::{
    flag, parse_shard, BackendChoice, Format, SlurmArgs, SolverFlags, SweepArgs, TableKind,
};
use crate::engine::{simulate_chain, Chain, Model, Overrides, Silent, Solver};
use crate::error::InputError;
use crate::output::guard;
use crate::scene::{Precision, Scene};
use crate::sweep::Sweep;

use crate::output::partial::COMPANIONS;

/// Most worker threads per core the CPU backend accepts: beyond that a run
/// only spends memory and time spawning threads that wait for a core.
pub const MAX_THREADS_PER_CORE: usize = 8;

/// A checked `cradle sweep`.
pub struct SweepConfig {
    pub sweep: Sweep,
    /// The file really written (`--out`, or the final target of a symlink).
    pub out: PathBuf,
    /// `--out` as given, for messages.
    pub out_given: PathBuf,
    pub backend: BackendChoice,
    pub resume: bool,
    /// 1-based shard K of N.
    pub shard: Option<(u64, u64)>,
    pub threads: Option<usize>,
    pub error_estimate: bool,
    pub overrides: Overrides,
    /// The precision the base scene runs in (flags and file resolved).
    pub precision: Precision,
    /// Write Parquet (`--format`, else the extension of `--out`).
    pub parquet: bool,
}

/// `--threads N`: 1 ..= MAX_THREADS_PER_CORE × the cores this process may use.
pub fn threads(n: i64) -> Result<usize, InputError> {
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    let max = MAX_THREADS_PER_CORE * cores;
    if n < 1 || n as u64 > max as u64 {
        return Err(flag(
            "--threads",
            &n.to_string(),
            &format!(
                "1 ..= {max} ({MAX_THREADS_PER_CORE} per core; this machine gives {cores} cores)"
            ),
        ));
    }
    Ok(n as usize)
}

impl SweepConfig {
    pub fn from_args(a: &SweepArgs) -> Result<SweepConfig, InputError> {
        Self::from_args_and(a, None)
    }

    /// As [`Self::from_args`], with the sweep already read (`Some`: a sweep
    /// given as text, as the Python module allows) instead of `a.sweep`.
    pub fn from_args_and(a: &SweepArgs, sweep: Option<Sweep>) -> Result<SweepConfig, InputError> {
        let overrides = a.solver.overrides()?;
        let shard = a.shard.as_deref().map(parse_shard).transpose()?;
        let threads = a.threads.map(threads).transpose()?;
        let sweep = match sweep {
            Some(s) => s,
            None => Sweep::load(&a.sweep)?,
        };
        sweep.check_overrides(&overrides)?;
        let out = guard::output("--out", &a.out, &sweep.inputs, COMPANIONS)?;
        let precision = Solver::resolve(&sweep.base, &overrides)?.precision;
        Ok(SweepConfig {
            sweep,
            out,
            out_given: a.out.clone(),
            backend: a.backend,
            resume: a.resume,
            shard,
            threads,
            error_estimate: a.error_estimate,
            overrides,
            precision,
            parquet: TableKind::resolve(a.format, &a.out) == TableKind::Parquet,
        })
    }
}

/// Largest trace `cradle run --trace` writes (bytes); refused before running.
pub const MAX_TRACE_BYTES: f64 = 1e9;
/// Characters of one trace number (`-1.2345678901234567e-5,`).
const TRACE_BYTES_PER_NUMBER: f64 = 24.0;

/// A checked `cradle run`.
pub struct RunConfig {
    /// The scene as named on the command line (a file or a built-in).
    pub name: String,
    pub scene: Scene,
    pub chain: Chain,
    pub solver: Solver,
    pub format: Format,
    /// Where the trace goes (a checked output path) and its row spacing (s).
    pub trace: Option<(PathBuf, f64)>,
}

impl RunConfig {
    /// Run the scene, writing its trace if one was asked for.
    pub fn execute(&self) -> anyhow::Result<crate::engine::Outcome> {
        use anyhow::Context;
        let (chain, solver) = (&self.chain, &self.solver);
        Ok(match &self.trace {
            None => simulate_chain(chain, solver, &mut Silent),
            Some((path, every)) => {
                let file = std::fs::File::create(path)
                    .with_context(|| format!("cannot create trace file {}", path.display()))?;
                let mut tw = crate::output::trace::TraceWriter::new(
                    std::io::BufWriter::new(file),
                    chain,
                    *every,
                )?;
                let o = simulate_chain(chain, solver, &mut tw);
                tw.finish()
                    .with_context(|| format!("writing {}", path.display()))?;
                o
            }
        })
    }

    pub fn from_args(
        name: &str,
        format: Format,
        trace: Option<&Path>,
        trace_dt: Option<f64>,
        flags: &SolverFlags,
    ) -> anyhow::Result<RunConfig> {
        Self::from_scene(name, Scene::load(name)?, format, trace, trace_dt, flags)
    }

    /// As [`Self::from_args`] for a scene already read (`name` names it in
    /// messages).
    pub fn from_scene(
        name: &str,
        scene: Scene,
        format: Format,
        trace: Option<&Path>,
        trace_dt: Option<f64>,
        flags: &SolverFlags,
    ) -> anyhow::Result<RunConfig> {
        let overrides = flags.overrides()?;
        Solver::check_flags_against(&scene, &overrides, name)?;
        let solver = Solver::resolve(&scene, &overrides)?;
        let chain = Chain::from_scene(&scene)
            .map_err(|e| anyhow::Error::new(e).context(format!("scene {name}")))?;
        if let Some(why) = solver.model.unsupported(&chain) {
            return Err(flag("--model", solver.model.name(), &why).into());
        }
        let trace = match trace {
            None => None,
            Some(path) => {
                if solver.model != Model::Hertz {
                    return Err(flag(
                        "--trace",
                        solver.model.name(),
                        "a trajectory of the hertz model only (the others are instantaneous)",
                    )
                    .into());
                }
                let every = match trace_dt {
                    Some(d) if d.is_finite() && d > 0.0 => d,
                    Some(d) => {
                        return Err(flag("--trace-dt", &d.to_string(), "a time > 0 (s)").into())
                    }
                    None => crate::output::trace::default_every(&chain),
                };
                let inputs: Vec<PathBuf> = Path::new(name)
                    .exists()
                    .then(|| name.into())
                    .into_iter()
                    .collect();
                let path = guard::output("--trace", path, &inputs, &[])?;
                // The trace's size, known before it is written: the run's end
                // time from a silent run (one scene: milliseconds).
                let t_end = simulate_chain(&chain, &solver, &mut Silent).t_end;
                let row_bytes = (1 + 2 * chain.n_balls) as f64 * TRACE_BYTES_PER_NUMBER;
                let bytes = (t_end / every + 2.0) * row_bytes;
                if bytes.is_nan() || bytes > MAX_TRACE_BYTES {
                    return Err(flag(
                        "--trace-dt",
                        &format!("{every:e}"),
                        &format!(
                            "the run lasts {t_end:.4e} s: {:.0} rows, about {:.1} GB of trace (at most {:.0} GB); use --trace-dt ≥ {:.1e}",
                            t_end / every,
                            bytes / 1e9,
                            MAX_TRACE_BYTES / 1e9,
                            t_end * row_bytes / (MAX_TRACE_BYTES - 2.0 * row_bytes)
                        ),
                    )
                    .into());
                }
                Some((path, every))
            }
        };
        Ok(RunConfig {
            name: name.to_string(),
            scene,
            chain,
            solver,
            format,
            trace,
        })
    }
}

/// A checked `cradle slurm`: everything a task would refuse is refused now,
/// not on the cluster (flags against the file, the merged output's path,
/// the solver, the shard count).
pub fn slurm_plan(a: &SlurmArgs) -> anyhow::Result<crate::slurm::Plan> {
    let spec = Sweep::load(&a.sweep)?;
    let overrides = a.solver.overrides()?;
    spec.check_overrides(&overrides)?;
    Solver::resolve(&spec.base, &overrides)?;
    if let Some(o) = &a.out {
        guard::output("--out", o, &spec.inputs, COMPANIONS)?;
    }
    if a.shards == 0 || a.shards > spec.total {
        return Err(flag(
            "--shards",
            &a.shards.to_string(),
            &format!("1 ..= {} (the sweep's scenes)", spec.total),
        )
        .into());
    }
    let stem = a
        .sweep
        .file_stem()
        .unwrap_or_default()
        .to_string_lossy()
        .to_string();
    Ok(crate::slurm::Plan {
        out: a
            .out
            .clone()
            .unwrap_or_else(|| format!("{stem}.csv").into()),
        dir: a
            .dir
            .clone()
            .unwrap_or_else(|| format!("slurm-{stem}").into()),
        sweep: a.sweep.clone(),
        shards: a.shards,
        partition: a.partition.clone(),
        gpus_per_task: a.gpus_per_task,
        cpus_per_task: a.cpus_per_task,
        time: a.time.clone(),
        cradle: match &a.cradle {
            Some(c) => c.clone(),
            None => std::env::current_exe()?,
        },
        flags: a.solver.args(),
    })
}
