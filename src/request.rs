//! The typed API: what a front end — the command line, the Python module,
//! the explorer, or a physicist's own Rust program — asks of the core.
//!
//! Settings come in unchecked ([`SweepSettings`], [`RunSettings`],
//! [`SolverSettings`]: plain values, as a user typed them) and are checked
//! into a request ([`SweepRequest`], [`RunRequest`]) before any work starts
//! (the low-level → high-level split of ripgrep's `lowargs`/`hiargs`).
//! Every rule about what a run may do is decided here, once:
//! - the output path (`output::guard`: never an input, a directory, a device,
//!   a FIFO; a symlink is written through);
//! - a setting given both here and in a file: an error naming both, unless
//!   they agree (a setting never silently replaces an axis);
//! - resource limits: threads, the tolerance's round-off floor per precision,
//!   the size of a trace.
//!
//! ```no_run
//! use hertz_cradle::{SweepRequest, SweepSettings, Hooks};
//! use std::sync::{Arc, Mutex};
//!
//! let req = SweepRequest::from_file("examples/mass_gap.toml", "mass_gap.csv", &SweepSettings::default())?;
//! let ejected = Arc::new(Mutex::new(vec![]));
//! let sink = ejected.clone();
//! let summary = req.run(Hooks {
//!     on_row: Some(Arc::new(move |row| sink.lock().unwrap().push((row.id, row.outcome.cradle().unwrap().ejected)))),
//!     ..Hooks::default()
//! })?;
//! println!("{} scenes, {} ok", summary.scenes, summary.ok);
//! # Ok::<(), hertz_cradle::Error>(())
//! ```

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use crate::backend::BackendChoice;
use crate::engine::granular::{self, Beads, ChainOutcome};
use crate::engine::{simulate_chain, Chain, Model, Outcome, Overrides, Silent, Solver};
use crate::error::{flag, InputError, Interrupted, Source};
use crate::output::partial::COMPANIONS;
use crate::output::{guard, TableKind};
use crate::scene::{Method, Precision, Scene, MAX_BALLS};
use crate::sweep::session::{OnProgress, OnRow, Options, Summary};
use crate::sweep::Sweep;

/// Most worker threads per core the CPU backend accepts: beyond that a run
/// only spends memory and time spawning threads that wait for a core.
pub const MAX_THREADS_PER_CORE: usize = 8;

/// Largest trace a run writes (bytes); refused before running.
pub const MAX_TRACE_BYTES: f64 = 1e9;
/// Characters of one trace number (`-1.2345678901234567e-5,`).
const TRACE_BYTES_PER_NUMBER: f64 = 24.0;

/// Why a request failed: bad input (a file, a key, a setting; the CLI's exit
/// 2), a run stopped on request, or the environment (a disk full, a GPU
/// lost; exit 1). Each keeps the whole message, file and key included.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The chain holds an [`InputError`].
    #[error("{0:#}")]
    Input(anyhow::Error),
    /// Stopped through [`Hooks::cancel`]: the rows so far stay in the
    /// partial file, which a run with `resume` continues.
    #[error("interrupted")]
    Interrupted,
    #[error("{0:#}")]
    Runtime(anyhow::Error),
}

impl Error {
    /// Back to the error chain it came from (the CLI reads its exit code
    /// from the chain: an [`InputError`] in it is exit 2).
    pub fn into_anyhow(self) -> anyhow::Error {
        match self {
            Error::Input(e) | Error::Runtime(e) => e,
            Error::Interrupted => Interrupted.into(),
        }
    }

    /// The input error at the root of this one, if it is one.
    pub fn input_error(&self) -> Option<&InputError> {
        match self {
            Error::Input(e) => e.chain().find_map(|c| c.downcast_ref::<InputError>()),
            _ => None,
        }
    }
}

impl From<anyhow::Error> for Error {
    fn from(e: anyhow::Error) -> Error {
        if e.chain().any(|c| c.downcast_ref::<Interrupted>().is_some()) {
            Error::Interrupted
        } else if e.chain().any(|c| c.downcast_ref::<InputError>().is_some()) {
            Error::Input(e)
        } else {
            Error::Runtime(e)
        }
    }
}

impl From<InputError> for Error {
    fn from(e: InputError) -> Error {
        Error::Input(e.into())
    }
}

/// Solver settings that override a file's `[solver]` (the two must agree).
/// `None` keeps the file's value, else the default.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SolverSettings {
    /// f64 (default), f32, or df64 (pairs of f32).
    pub precision: Option<Precision>,
    /// Target error of outcome velocities relative to v_in, in (0, 1).
    pub tolerance: Option<f64>,
    /// hertz (default), hard-sphere or closure.
    pub model: Option<Model>,
    /// kahanli6 (default), yoshida6, suzuki4, yoshida4 or verlet.
    pub method: Option<Method>,
}

impl SolverSettings {
    /// The settings, checked (the tolerance's range).
    pub fn overrides(&self) -> Result<Overrides, InputError> {
        let tolerance = match self.tolerance {
            None => None,
            Some(t) if t.is_finite() && t > 0.0 && t < 1.0 => Some(t),
            Some(t) => {
                return Err(flag(
                    "--tolerance",
                    &t.to_string(),
                    "the tolerance must be > 0 and < 1 (a relative error, e.g. 1e-6)",
                ))
            }
        };
        Ok(Overrides {
            model: self.model,
            method: self.method,
            precision: self.precision,
            tolerance,
        })
    }
}

/// A sweep's settings as given (`cradle sweep`'s flags), before checking.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepSettings {
    pub backend: BackendChoice,
    /// Continue an interrupted run into the same output.
    pub resume: bool,
    /// `K/N` (1 ≤ K ≤ N) or `slurm`: run only that shard.
    pub shard: Option<String>,
    /// CPU worker threads (default: all cores).
    pub threads: Option<i64>,
    /// CSV or Parquet (default: from the output's extension).
    pub format: Option<TableKind>,
    /// Fill `error_estimate`: every scene again with steps twice as long.
    pub error_estimate: bool,
    pub solver: SolverSettings,
}

impl Default for SweepSettings {
    fn default() -> Self {
        SweepSettings {
            backend: BackendChoice::Auto,
            resume: false,
            shard: None,
            threads: None,
            format: None,
            error_estimate: false,
            solver: SolverSettings::default(),
        }
    }
}

/// `threads`: 1 ..= [`MAX_THREADS_PER_CORE`] × the cores this process may use.
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

/// What a sweep's run reports and may be stopped by.
#[derive(Clone, Default)]
pub struct Hooks {
    /// What made the run, recorded in the sidecar (e.g. the command line).
    pub command: Vec<String>,
    /// Told as rows are written.
    pub on_progress: Option<OnProgress>,
    /// Given every row, typed, once it is written to the output.
    pub on_row: Option<OnRow>,
    /// Set it to stop the run early: [`Error::Interrupted`].
    pub cancel: Option<Arc<AtomicBool>>,
}

/// A checked sweep: the sweep, its output and how to run it.
#[derive(Debug)]
pub struct SweepRequest {
    pub sweep: Sweep,
    /// The file really written (the output given, or a symlink's target).
    pub out: PathBuf,
    /// The output as given, for messages.
    pub out_given: PathBuf,
    pub backend: BackendChoice,
    pub resume: bool,
    /// 1-based shard K of N.
    pub shard: Option<(u64, u64)>,
    pub threads: Option<usize>,
    pub error_estimate: bool,
    pub overrides: Overrides,
    /// The precision the base scene runs in (settings and file resolved).
    pub precision: Precision,
    /// CSV or Parquet, resolved.
    pub format: TableKind,
}

impl SweepRequest {
    /// Check `settings` for `sweep`, written to `out`.
    pub fn new(
        sweep: Sweep,
        out: impl AsRef<Path>,
        settings: &SweepSettings,
    ) -> Result<SweepRequest, InputError> {
        let out_given = out.as_ref().to_path_buf();
        let overrides = settings.solver.overrides()?;
        let shard = settings
            .shard
            .as_deref()
            .map(crate::sweep::shard::parse_shard)
            .transpose()?;
        let threads = settings.threads.map(threads).transpose()?;
        sweep.check_overrides(&overrides)?;
        let out = guard::output("--out", &out_given, &sweep.inputs, COMPANIONS)?;
        let format = TableKind::resolve(settings.format, &out_given)?;
        let solver = Solver::resolve(&sweep.base, &overrides)?;
        let precision = solver.precision;
        sweep.model.check_solver(&solver)?;
        // Chains always carry their error estimate (docs/SPEC.md §9): the
        // flag is the cradles' (and part of the fingerprint only for them).
        let error_estimate = settings.error_estimate && sweep.model.takes_error_estimate();
        Ok(SweepRequest {
            sweep,
            out,
            format,
            out_given,
            backend: settings.backend,
            resume: settings.resume,
            shard,
            threads,
            error_estimate,
            overrides,
            precision,
        })
    }

    /// A sweep file, checked with `settings`, written to `out`.
    pub fn from_file(
        path: impl AsRef<Path>,
        out: impl AsRef<Path>,
        settings: &SweepSettings,
    ) -> Result<SweepRequest, InputError> {
        Self::new(Sweep::load(path.as_ref())?, out, settings)
    }

    /// A sweep given as TOML text, named `name` in messages; a relative
    /// `scene = "file"` in it is found from `base_dir`.
    pub fn from_toml(
        name: &str,
        text: &str,
        base_dir: impl AsRef<Path>,
        out: impl AsRef<Path>,
        settings: &SweepSettings,
    ) -> Result<SweepRequest, InputError> {
        let sweep = Sweep::parse(&Source::new(name, text), base_dir.as_ref())?;
        Self::new(sweep, out, settings)
    }

    /// The table's columns: names and types, as the output writes them.
    pub fn columns(&self) -> Vec<(String, crate::output::row::ColType)> {
        self.sweep
            .header()
            .into_iter()
            .zip(self.sweep.column_types())
            .collect()
    }

    /// Run the sweep: the backend chosen, a pool of `threads` workers if
    /// given, every row written to the output (then its sidecar, then the
    /// output published under its name) and given to `hooks.on_row`.
    pub fn run(&self, hooks: Hooks) -> Result<Summary, Error> {
        let backend = crate::backend::choose(self.backend, self.precision)?;
        let opts = Options {
            out: self.out.clone(),
            resume: self.resume,
            shard: self.shard,
            overrides: self.overrides.clone(),
            command: hooks.command,
            error_estimate: self.error_estimate,
            parquet: self.format == TableKind::Parquet,
            on_progress: hooks.on_progress,
            on_row: hooks.on_row,
            cancel: hooks.cancel,
        };
        // The label inside the pool that ran it: `--threads 1` says 1 thread.
        let go = || -> anyhow::Result<Summary> {
            let mut s = crate::sweep::run::run(&self.sweep, &opts, backend.as_ref())?;
            s.backend = format!("{} ({})", backend.name(), backend.adapter());
            Ok(s)
        };
        Ok(pooled(self.threads, go)??)
    }
}

/// Run `work` on a pool of `threads` worker threads of its own (`--threads`),
/// or on the global pool (every core).
pub fn pooled<T: Send>(
    threads: Option<usize>,
    work: impl FnOnce() -> T + Send,
) -> anyhow::Result<T> {
    Ok(match threads {
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()?
            .install(work),
        None => work(),
    })
}

/// One scene's settings as given (`cradle run`'s flags), before checking.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RunSettings {
    pub solver: SolverSettings,
    /// Write the trajectory (t, x_i, v_i) as CSV to this file.
    pub trace: Option<PathBuf>,
    /// The trace's row spacing (s of simulated time); default: 1/20 of the
    /// shortest contact time.
    pub trace_dt: Option<f64>,
}

/// A trace's output path, checked (`--trace`): never the scene file it
/// comes from.
fn trace_output(name: &str, path: &Path) -> Result<PathBuf, InputError> {
    let inputs: Vec<PathBuf> = Path::new(name)
        .exists()
        .then(|| name.into())
        .into_iter()
        .collect();
    let checked = guard::output(
        "--trace",
        path,
        &inputs,
        crate::output::publish::ALONE_COMPANIONS,
    )?;
    // A trace's format is its name's: a name that says neither is refused,
    // never filled with CSV (`--trace w.xlsx`).
    if TableKind::from_extension(path).is_none() {
        return Err(flag(
            "--trace",
            &path.display().to_string(),
            "a name ending in .csv or .parquet (.pq): the trace's format",
        ));
    }
    Ok(checked)
}

/// A checked scene, ready to run.
#[derive(Debug)]
pub struct RunRequest {
    /// The scene as named (a file, a built-in, or a name for text).
    pub name: String,
    pub scene: Scene,
    pub chain: Chain,
    pub solver: Solver,
    /// Where the trace goes (a checked output path) and its row spacing (s).
    pub trace: Option<(PathBuf, f64)>,
    /// A granular chain's compiled beads (docs/SPEC.md §9): the scene runs
    /// with [`RunRequest::run_chain`]; `None` for a cradle.
    pub beads: Option<Beads>,
    /// The recorded beads of a chain's trace.
    pub trace_beads: Vec<usize>,
    /// A chain's controlled run, when checking its trace's size needed it
    /// (`run_chain` reports it instead of running it again).
    ran: Option<ChainOutcome>,
}

impl RunRequest {
    /// A scene file or a built-in scene's name.
    ///
    /// ```
    /// use hertz_cradle::{RunRequest, RunSettings};
    /// let r = RunRequest::from_name("cradle-1", &RunSettings::default()).unwrap();
    /// let o = r.run().unwrap();
    /// // One ball in, one ball out — nearly: Hertzian contacts leave the
    /// // others a little motion (v_4 = 0.98878), and momentum is kept.
    /// assert_eq!(o.ejected, 1);
    /// assert!((o.v[4] - 0.98878).abs() < 1e-5);
    /// assert!((o.v.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    /// ```
    pub fn from_name(name: &str, settings: &RunSettings) -> Result<RunRequest, Error> {
        Self::new(name, Scene::load(name)?, settings)
    }

    /// A scene given as TOML text, named `name` in messages.
    pub fn from_toml(name: &str, text: &str, settings: &RunSettings) -> Result<RunRequest, Error> {
        Self::new(name, Scene::from_toml_str(name, text)?, settings)
    }

    /// Check `settings` for `scene` (`name` names it in messages).
    pub fn new(name: &str, scene: Scene, settings: &RunSettings) -> Result<RunRequest, Error> {
        let overrides = settings.solver.overrides()?;
        Solver::check_flags_against(&scene, &overrides, name)?;
        let solver = Solver::resolve(&scene, &overrides)?;
        let chain = Chain::from_scene(&scene)
            .map_err(|e| Error::Input(anyhow::Error::new(e).context(format!("scene {name}"))))?;
        if let Some(why) = solver.model.unsupported(&chain) {
            return Err(flag("--model", solver.model.name(), &why).into());
        }
        if scene.chain.is_some() {
            return Self::new_chain(name, scene, chain, solver, settings);
        }
        let trace = match &settings.trace {
            None => None,
            Some(path) => Some(Self::check_trace(
                name,
                &chain,
                &solver,
                path,
                settings.trace_dt,
            )?),
        };
        Ok(RunRequest {
            name: name.to_string(),
            scene,
            chain,
            solver,
            trace,
            beads: None,
            trace_beads: vec![],
            ran: None,
        })
    }

    /// A granular chain: its beads compiled, its trace checked against
    /// `[record]` (the beads; `--trace-dt`, if given, must equal
    /// `record.every`).
    fn new_chain(
        name: &str,
        scene: Scene,
        chain: Chain,
        solver: Solver,
        settings: &RunSettings,
    ) -> Result<RunRequest, Error> {
        granular::check_solver(&solver)?;
        let beads = Beads::from_scene(&scene);
        if let Some(why) = granular::unrunnable(&granular::plan(&beads, &solver, None)) {
            return Err(flag("scene", name, &format!("a chain that can be run: {why}")).into());
        }
        let record = scene.chain.as_ref().and_then(|c| c.record.clone());
        let (mut trace, mut trace_beads, mut ran) = (None, vec![], None);
        if let Some(path) = &settings.trace {
            let every = match (&record, settings.trace_dt) {
                (Some(r), Some(d)) if d != r.every => {
                    return Err(flag(
                        "--trace-dt",
                        &format!("{d:e}"),
                        &format!(
                            "{name} sets [record] every = {:e}: give the spacing in one place",
                            r.every
                        ),
                    )
                    .into())
                }
                (Some(r), _) => r.every,
                (None, Some(d)) if d.is_finite() && d > 0.0 => d,
                (None, Some(d)) => {
                    return Err(flag("--trace-dt", &d.to_string(), "a time > 0 (s)").into())
                }
                (None, None) => beads.time_scale() / 20.0,
            };
            trace_beads = match &record {
                Some(r) => r.beads.clone(),
                None if beads.n <= MAX_BALLS => (0..beads.n).collect(),
                None => {
                    return Err(flag(
                        "--trace",
                        &path.display().to_string(),
                        &format!(
                            "a chain of {} beads records the beads named in a [record] table (beads = [...], every = ...)",
                            beads.n
                        ),
                    )
                    .into())
                }
            };
            let path = trace_output(name, path)?;
            let plan = granular::plan(&beads, &solver, Some(every));
            let columns = 1 + 3 * trace_beads.len() + 2;
            let size = |t: f64| (t / every + 2.0) * columns as f64 * TRACE_BYTES_PER_NUMBER;
            // The run's end: its duration, else the cap — only a bound: when
            // the cap would refuse the trace, the run itself (under the error
            // control, as `run_chain` runs it, which then reuses it) says when
            // it ends (a 1,000-bead chain's cap is 1.09 s, its run 0.026 s).
            let mut t_end = plan.duration.unwrap_or(plan.max_time);
            let capped = size(t_end);
            if plan.duration.is_none() && (capped.is_nan() || capped > MAX_TRACE_BYTES) {
                let job = crate::backend::ChainJob {
                    beads: beads.clone(),
                    plan: plan.clone(),
                };
                let o = crate::backend::run_chain_controlled(&job).map_err(Error::Runtime)?;
                t_end = o.t_end;
                ran = Some(o);
            }
            let bytes = size(t_end);
            if bytes.is_nan() || bytes > MAX_TRACE_BYTES {
                let over = if ran.is_some() {
                    "; the run lasts"
                } else {
                    " over up to"
                };
                return Err(flag(
                    "--trace",
                    &path.display().to_string(),
                    &format!(
                        "a record of {} beads every {every:e} s{over} {t_end:.4e} s: about {:.1} GB of trace (at most {:.0} GB); record fewer beads, a larger `every` or set [stop] duration",
                        trace_beads.len(),
                        bytes / 1e9,
                        MAX_TRACE_BYTES / 1e9
                    ),
                )
                .into());
            }
            trace = Some((path, every));
        }
        Ok(RunRequest {
            name: name.to_string(),
            scene,
            chain,
            solver,
            trace,
            beads: Some(beads),
            trace_beads,
            ran,
        })
    }

    /// Run a granular chain (a scene with [`RunRequest::beads`]), writing
    /// its trace if one was asked for.
    pub fn run_chain(&self) -> Result<ChainOutcome, Error> {
        use anyhow::Context;
        let Some(beads) = &self.beads else {
            return Err(flag(
                "scene",
                &self.name,
                "a granular chain (this is a cradle: use run)",
            )
            .into());
        };
        let every = self.trace.as_ref().map(|t| t.1);
        let plan = granular::plan(beads, &self.solver, every);
        // Under the error control (docs/SPEC.md §9), on the CPU.
        let job = crate::backend::ChainJob {
            beads: beads.clone(),
            plan,
        };
        let o = match &self.ran {
            Some(o) => o.clone(),
            None => crate::backend::run_chain_controlled(&job)?,
        };
        let Some((path, _)) = &self.trace else {
            return Ok(o);
        };
        // The trace is the reported run's: that run again, rows written.
        // Written beside the path and published whole (a kill or a full
        // disk leaves the previous trace, never a cut-off one).
        let traced = crate::output::publish::write_alone(path, |w| {
            crate::output::trace::in_format(path, w, |w| {
                let mut tw =
                    crate::output::trace::ChainTraceWriter::new(w, beads, self.trace_beads.clone())
                        .with_context(|| format!("writing {}", path.display()))?;
                let traced = crate::backend::rerun_reported(&job, &o, &mut tw, false);
                tw.finish()
                    .with_context(|| format!("writing {}", path.display()))?;
                Ok(traced)
            })
        })?;
        self.trace_sidecar(path)?;
        Ok(traced)
    }

    /// Beside a trace just written, its sidecar (`TRACE.json`): the scene's
    /// name and description, which `cradle plot --trace` takes for its
    /// title.
    fn trace_sidecar(&self, path: &Path) -> anyhow::Result<()> {
        let json = serde_json::json!({
            "trace_of": self.name,
            "description": Scene::description_of(&self.name),
            "version": env!("CARGO_PKG_VERSION"),
        });
        crate::output::publish::write_atomic(
            &crate::output::sidecar::path(path),
            format!("{json:#}\n").as_bytes(),
        )
    }

    /// The trace's path and spacing, checked: the hertz model only, a
    /// spacing > 0, an output that may be written, a size within
    /// [`MAX_TRACE_BYTES`].
    fn check_trace(
        name: &str,
        chain: &Chain,
        solver: &Solver,
        path: &Path,
        trace_dt: Option<f64>,
    ) -> Result<(PathBuf, f64), InputError> {
        if solver.model != Model::Hertz {
            return Err(flag(
                "--trace",
                solver.model.name(),
                "a trajectory of the hertz model only (the others are instantaneous)",
            ));
        }
        let every = match trace_dt {
            Some(d) if d.is_finite() && d > 0.0 => d,
            Some(d) => return Err(flag("--trace-dt", &d.to_string(), "a time > 0 (s)")),
            None => crate::output::trace::default_every(chain),
        };
        let path = trace_output(name, path)?;
        // The trace's size, known before it is written: the run's end
        // time from a silent run (one scene: milliseconds).
        let t_end = simulate_chain(chain, solver, &mut Silent).t_end;
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
            ));
        }
        Ok((path, every))
    }

    /// Run the scene, writing its trace if one was asked for (a cradle; a
    /// granular chain runs with [`RunRequest::run_chain`]).
    pub fn run(&self) -> Result<Outcome, Error> {
        use anyhow::Context;
        if self.beads.is_some() {
            return Err(flag(
                "scene",
                &self.name,
                "a cradle (this is a granular chain, docs/SPEC.md §9: use run_chain)",
            )
            .into());
        }
        let (chain, solver) = (&self.chain, &self.solver);
        Ok(match &self.trace {
            None => simulate_chain(chain, solver, &mut Silent),
            Some((path, every)) => {
                let o = crate::output::publish::write_alone(path, |w| {
                    crate::output::trace::in_format(path, w, |w| {
                        let mut tw = crate::output::trace::TraceWriter::new(w, chain, *every)
                            .with_context(|| format!("writing {}", path.display()))?;
                        let o = simulate_chain(chain, solver, &mut tw);
                        tw.finish()
                            .with_context(|| format!("writing {}", path.display()))?;
                        Ok(o)
                    })
                })?;
                self.trace_sidecar(path)?;
                o
            }
        })
    }

    /// The shape of this scene's row (its column count).
    pub fn shape(&self) -> crate::output::row::Shape {
        crate::output::row::Shape {
            width: self.scene.n,
            pendulum: self.chain.is_pendulum(),
        }
    }
}
