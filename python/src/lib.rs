//! `hertz_cradle._native`: the Rust side of the Python module, a client of
//! the core's typed API (`hertz_cradle::request`): keyword arguments become
//! `SweepSettings` / `RunSettings`, checked by the same code as the command
//! line's flags, so a bad input raises `ValueError` with the message `cradle`
//! prints, and a sweep runs exactly as `cradle sweep` runs it (same pipeline,
//! output files, resume, sidecar). No command-line parser is linked in.
//! The Python layer (`hertz_cradle/__init__.py`) reads the tables.
//!
//! The GIL is released while scenes run. A sweep runs on a thread of its
//! own; the calling thread wakes every 50 ms to let Python handle signals:
//! on Ctrl-C the sweep is told to stop (its rows so far stay in the
//! `.partial` file, which `resume=True` continues) and KeyboardInterrupt is
//! raised once it has stopped. No panic crosses into Python: a panic in the
//! sweep thread becomes RuntimeError.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use hertz_cradle::backend::BackendChoice;
use hertz_cradle::choice::Choice;
use hertz_cradle::engine::Model;
use hertz_cradle::output::row::{self, ColType, Field};
use hertz_cradle::output::TableKind;
use hertz_cradle::scene::{builtin, Method, Precision};
use hertz_cradle::{
    Error, Hooks, Progress, RunRequest, RunSettings, SolverSettings, SweepRequest, SweepSettings,
};
use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// An error as Python sees it: bad input → ValueError (the CLI's message),
/// an interrupt → KeyboardInterrupt, anything else → RuntimeError.
/// Writes a row's fields, in order, to the function it is given.
type Emit<'a> = &'a mut dyn FnMut(&mut dyn FnMut(Field));

fn to_py(e: Error) -> PyErr {
    let text = e.to_string();
    match e {
        Error::Interrupted => PyKeyboardInterrupt::new_err(text),
        Error::Input(_) => PyValueError::new_err(text),
        Error::Runtime(_) => PyRuntimeError::new_err(text),
    }
}

/// A closed-set setting from its name, `None` kept.
fn choice<C: Choice>(flag: &str, value: Option<&str>) -> PyResult<Option<C>> {
    value
        .map(|v| C::parse_flag(flag, v).map_err(|e| to_py(e.into())))
        .transpose()
}

/// The solver keyword arguments as the core's settings.
fn solver(
    precision: Option<&str>,
    tolerance: Option<f64>,
    method: Option<&str>,
    model: Option<&str>,
) -> PyResult<SolverSettings> {
    Ok(SolverSettings {
        precision: choice::<Precision>("--precision", precision)?,
        tolerance,
        method: choice::<Method>("--method", method)?,
        model: choice::<Model>("--model", model)?,
    })
}

/// TOML text from a JSON document (a Python dict, dumped).
fn toml_from_json(name: &str, json: &str) -> PyResult<String> {
    let value: serde_json::Value =
        serde_json::from_str(json).map_err(|e| PyValueError::new_err(format!("{name}: {e}")))?;
    let value = toml::Value::try_from(value).map_err(|e| {
        PyValueError::new_err(format!(
            "{name}: not a TOML document ({e}); None is not allowed"
        ))
    })?;
    toml::to_string(&value).map_err(|e| PyValueError::new_err(format!("{name}: {e}")))
}

fn type_name(t: ColType) -> &'static str {
    match t {
        ColType::Int => "int64",
        ColType::Num => "float64",
        ColType::Text => "string",
        ColType::Status => "dictionary",
    }
}

/// Run a sweep: the sweep file `path`, or `text` (TOML, or JSON when
/// `json`) named `name` in messages, whose relative `scene = "file"` is
/// found from `base_dir`; written to `out`; the other arguments are
/// `cradle sweep`'s flags; `progress`, if given, is called as
/// `progress(done, total)` (scenes) from this thread, with the GIL, when the
/// count has moved (every 50 ms at most) and once at the end. Returns a
/// summary: scenes, ok, wall_s, backend, already_complete, and columns
/// (name, type) of the table written.
#[pyfunction]
#[pyo3(signature = (path, text, json, name, base_dir, out, *, backend="auto", precision=None,
    tolerance=None, method=None, model=None, threads=None, format=None, resume=false,
    shard=None, error_estimate=false, progress=None))]
#[allow(clippy::too_many_arguments)]
fn sweep(
    py: Python<'_>,
    path: Option<String>,
    text: Option<String>,
    json: bool,
    name: &str,
    base_dir: &str,
    out: &str,
    backend: &str,
    precision: Option<&str>,
    tolerance: Option<f64>,
    method: Option<&str>,
    model: Option<&str>,
    threads: Option<i64>,
    format: Option<&str>,
    resume: bool,
    shard: Option<String>,
    error_estimate: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Py<PyDict>> {
    let settings = SweepSettings {
        backend: BackendChoice::parse_flag("--backend", backend).map_err(|e| to_py(e.into()))?,
        resume,
        shard,
        threads,
        format: choice::<TableKind>("--format", format)?,
        error_estimate,
        solver: solver(precision, tolerance, method, model)?,
    };
    let req = match (path, text) {
        (Some(p), _) => SweepRequest::from_file(p, out, &settings),
        (None, Some(t)) => {
            let t = if json { toml_from_json(name, &t)? } else { t };
            SweepRequest::from_toml(name, &t, base_dir, out, &settings)
        }
        (None, None) => return Err(PyValueError::new_err("a sweep needs a path or a text")),
    }
    .map_err(|e| to_py(e.into()))?;
    let columns: Vec<(String, &str)> = req
        .columns()
        .into_iter()
        .map(|(n, t)| (n, type_name(t)))
        .collect();
    let command = vec![
        "python".to_string(),
        "hertz_cradle.sweep".to_string(),
        req.out_given.display().to_string(),
    ];

    let cancel = Arc::new(AtomicBool::new(false));
    // Set by the worker when it ends.
    let finished = Arc::new((Mutex::new(false), Condvar::new()));
    // The rows written and the total, as the run tells them; `progress` is
    // called from here, where the GIL is.
    let counts = Arc::new((AtomicU64::new(0), AtomicU64::new(0)));
    let worker = {
        let (cancel, finished, counts) = (cancel.clone(), finished.clone(), counts.clone());
        std::thread::spawn(move || {
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                req.run(Hooks {
                    command,
                    on_progress: Some(Arc::new(move |p: Progress| {
                        counts.1.store(p.total, Ordering::Relaxed);
                        counts.0.store(p.done, Ordering::Relaxed);
                    })),
                    on_row: None,
                    cancel: Some(cancel),
                })
            }));
            *finished.0.lock().unwrap_or_else(|e| e.into_inner()) = true;
            finished.1.notify_all();
            r
        })
    };
    let mut interrupted = None;
    let mut told = None;
    // Tell `progress` the counts if they moved; an exception it raises
    // stops the run like an interrupt.
    let mut tell = |py: Python<'_>, interrupted: &mut Option<PyErr>| {
        let Some(cb) = progress.as_ref() else { return };
        let now = (
            counts.0.load(Ordering::Relaxed),
            counts.1.load(Ordering::Relaxed),
        );
        if now.1 == 0 || told == Some(now) || interrupted.is_some() {
            return;
        }
        told = Some(now);
        stop_on(cb.call1(py, now).map(drop), &cancel, interrupted);
    };
    loop {
        let done = py.detach(|| {
            let g = finished.0.lock().unwrap_or_else(|e| e.into_inner());
            let (g, _) = finished
                .1
                .wait_timeout_while(g, Duration::from_millis(50), |done| !*done)
                .unwrap_or_else(|e| e.into_inner());
            *g
        });
        tell(py, &mut interrupted);
        if done {
            break;
        }
        if interrupted.is_none() {
            stop_on(py.check_signals(), &cancel, &mut interrupted);
        }
    }
    let summary = joined(py, worker, interrupted, "the sweep thread")?;
    let d = PyDict::new(py);
    d.set_item("scenes", summary.scenes)?;
    d.set_item("ok", summary.ok)?;
    d.set_item("wall_s", summary.wall_s)?;
    d.set_item("backend", summary.backend)?;
    d.set_item("already_complete", summary.already_complete)?;
    d.set_item("columns", columns)?;
    Ok(d.unbind())
}

/// A run's first Python exception (Ctrl-C's KeyboardInterrupt, one a
/// `progress` callback raised) stops it: `cancel` set, the exception kept
/// to raise once the worker has stopped; later ones are dropped. Whether
/// this one stopped it.
/// The run on `worker` once it has ended: the interrupt that stopped it
/// (Ctrl-C, or an exception `progress` raised) first, else its own result;
/// a panic in it as a RuntimeError naming `what`.
fn joined<T: Send>(
    py: Python<'_>,
    worker: std::thread::JoinHandle<std::thread::Result<Result<T, Error>>>,
    interrupted: Option<PyErr>,
    what: &str,
) -> PyResult<T> {
    let result = py.detach(|| worker.join());
    if let Some(e) = interrupted {
        return Err(e);
    }
    match result {
        Ok(Ok(r)) => r.map_err(to_py),
        _ => Err(PyRuntimeError::new_err(format!("{what} panicked"))),
    }
}

fn stop_on(r: PyResult<()>, cancel: &AtomicBool, interrupted: &mut Option<PyErr>) -> bool {
    match r {
        Err(e) if interrupted.is_none() => {
            cancel.store(true, Ordering::SeqCst);
            *interrupted = Some(e);
            true
        }
        _ => false,
    }
}

/// A row field as a Python value (missing → None).
fn field_to_py<'py>(py: Python<'py>, f: Field) -> PyResult<Bound<'py, PyAny>> {
    Ok(match f {
        Field::Int(x) => x.into_pyobject(py)?.into_any(),
        Field::Num(x) if x.is_nan() => py.None().into_bound(py),
        Field::Num(x) => x.into_pyobject(py)?.into_any(),
        Field::Text(t) => t.into_pyobject(py)?.into_any(),
        Field::Null => py.None().into_bound(py),
    })
}

/// Run one scene: a built-in scene's name or a file (`scene`), or `text`
/// (TOML, or JSON when `json`) named `name` in messages. Returns the outcome
/// row as a dict (the columns of `cradle run --format csv`); a trace, if
/// asked for, is written to `trace`.
#[pyfunction]
#[pyo3(signature = (scene, text, json, name, *, precision=None, tolerance=None, method=None,
    model=None, trace=None, trace_dt=None))]
#[allow(clippy::too_many_arguments)]
fn run(
    py: Python<'_>,
    scene: Option<String>,
    text: Option<String>,
    json: bool,
    name: &str,
    precision: Option<&str>,
    tolerance: Option<f64>,
    method: Option<&str>,
    model: Option<&str>,
    trace: Option<String>,
    trace_dt: Option<f64>,
) -> PyResult<Py<PyDict>> {
    let settings = RunSettings {
        solver: solver(precision, tolerance, method, model)?,
        trace: trace.map(Into::into),
        trace_dt,
    };
    let cfg = match (scene, text) {
        (Some(s), _) => RunRequest::from_name(&s, &settings),
        (None, Some(t)) => {
            let t = if json { toml_from_json(name, &t)? } else { t };
            RunRequest::from_toml(name, &t, &settings)
        }
        (None, None) => return Err(PyValueError::new_err("a run needs a scene or a text")),
    }
    .map_err(to_py)?;
    /// Run off the GIL, a panic as a Python error.
    fn unwound<T: Send>(
        py: Python<'_>,
        f: impl FnOnce() -> Result<T, hertz_cradle::Error> + Send,
    ) -> PyResult<T> {
        py.detach(|| std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)))
            .map_err(|_| PyRuntimeError::new_err("the run panicked"))?
            .map_err(to_py)
    }
    let d = PyDict::new(py);
    // Each emitted field under its column's name (from `skip` on).
    let fill = |header: &[String], skip: usize, emit: Emit| {
        let (mut k, mut err) = (0, Ok(()));
        emit(&mut |f| {
            if k >= skip && err.is_ok() {
                err = field_to_py(py, f).and_then(|v| d.set_item(&header[k], v));
            }
            k += 1;
        });
        err
    };
    if let Some(beads) = &cfg.beads {
        // A granular chain (docs/SPEC.md §9): the chain's columns.
        let o = unwound(py, || cfg.run_chain())?;
        let cols = hertz_cradle::output::chain_row::Columns::of(beads);
        fill(&cols.header(), 0, &mut |out| cols.emit(&o, out))?;
    } else {
        let outcome = unwound(py, || cfg.run())?;
        let shape = cfg.shape();
        // Column 0 is the id, meaningless for one scene.
        fill(&row::header(&[], shape), 1, &mut |out| {
            row::emit_fields(0, |_| {}, &outcome, shape, out)
        })?;
    }
    d.set_item("model", cfg.solver.model.name())?;
    d.set_item("scene", &cfg.name)?;
    Ok(d.unbind())
}

/// Run an optimisation (`cradle optimize`): the problem file `path`, or
/// `text` (TOML, or JSON when `json`) named `name`, whose relative
/// `scene = "file"` is found from `base_dir`; the evaluations written to
/// `out` (CSV or Parquet by the name), the best design to `best`.
/// Runs off the GIL, on a thread of its own: `progress(generation,
/// generations, evaluations, best)` is called here as each generation
/// ends; Ctrl-C (or an exception `progress` raises) stops the run between
/// generations, the finished ones kept in `out.partial` for `resume`.
/// Returns a summary with `columns` and `best_scene`.
#[pyfunction]
#[pyo3(signature = (path, text, json, name, base_dir, out, *, best=None, backend="auto",
    precision=None, tolerance=None, method=None, model=None, threads=None, resume=false,
    progress=None))]
#[allow(clippy::too_many_arguments)]
fn optimize(
    py: Python<'_>,
    path: Option<String>,
    text: Option<String>,
    json: bool,
    name: &str,
    base_dir: &str,
    out: &str,
    best: Option<String>,
    backend: &str,
    precision: Option<&str>,
    tolerance: Option<f64>,
    method: Option<&str>,
    model: Option<&str>,
    threads: Option<i64>,
    resume: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Py<PyDict>> {
    let req = problem_request(
        (path, text, json, name, base_dir),
        out,
        best,
        (backend, precision, tolerance, method, model, threads),
        resume,
    )?;
    let columns = problem_columns(&req);
    let cancel = Arc::new(AtomicBool::new(false));
    // What the worker tells this thread (which holds the GIL): each
    // generation's report, then that it ended. With a `progress`, the
    // worker waits until the report is told before it starts the next
    // generation, so that an exception `progress` raises stops the run
    // right after the generation it was told of.
    #[derive(Default)]
    struct Shared {
        report: Option<(u64, u64, u64, Option<f64>)>,
        /// The last report was told to `progress`.
        told: bool,
        done: bool,
    }
    let shared = Arc::new((Mutex::new(Shared::default()), Condvar::new()));
    let wait_for_tell = progress.is_some();
    let worker = {
        let (cancel, shared) = (cancel.clone(), shared.clone());
        std::thread::spawn(move || {
            let (m, cv) = &*shared;
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                req.run(Some(cancel.clone()), &mut |r| {
                    let mut g = m.lock().unwrap_or_else(|e| e.into_inner());
                    g.report = Some((r.generation + 1, r.generations, r.evaluations, r.best));
                    g.told = false;
                    cv.notify_all();
                    while wait_for_tell && !g.told && !cancel.load(Ordering::SeqCst) {
                        g = cv.wait(g).unwrap_or_else(|e| e.into_inner());
                    }
                })
            }));
            m.lock().unwrap_or_else(|e| e.into_inner()).done = true;
            cv.notify_all();
            r
        })
    };
    let mut interrupted: Option<PyErr> = None;
    loop {
        let (m, cv) = &*shared;
        let (report, done) = py.detach(|| {
            let g = m.lock().unwrap_or_else(|e| e.into_inner());
            let (mut g, _) = cv
                .wait_timeout_while(g, Duration::from_millis(50), |s| {
                    !s.done && s.report.is_none()
                })
                .unwrap_or_else(|e| e.into_inner());
            (g.report.take(), g.done)
        });
        if let (Some(r), Some(cb)) = (report, progress.as_ref()) {
            if interrupted.is_none() {
                stop_on(cb.call1(py, r).map(drop), &cancel, &mut interrupted);
            }
        }
        // The report is told: the worker goes on (or stops, if cancelled).
        if report.is_some() {
            m.lock().unwrap_or_else(|e| e.into_inner()).told = true;
        }
        cv.notify_all();
        if done {
            break;
        }
        if interrupted.is_none() && stop_on(py.check_signals(), &cancel, &mut interrupted) {
            cv.notify_all();
        }
    }
    let summary = joined(py, worker, interrupted, "the optimisation")?;
    let d = PyDict::new(py);
    d.set_item("columns", columns)?;
    d.set_item("evaluations", summary.evaluations)?;
    d.set_item("wall_s", summary.wall_s)?;
    d.set_item("engine_s", summary.engine_s)?;
    d.set_item("backend", summary.backend)?;
    d.set_item("best_objective", summary.best.as_ref().map(|b| b.objective))?;
    d.set_item(
        "best_generation",
        summary.best.as_ref().map(|b| b.generation),
    )?;
    d.set_item("best_candidate", summary.best.as_ref().map(|b| b.candidate))?;
    d.set_item("best_scene", summary.best_toml)?;
    Ok(d.unbind())
}

/// A problem (its path or its text: TOML, or JSON when `json`, named
/// `name`, relative files found from `base_dir`) checked with the flags,
/// its table going to `out`.
#[allow(clippy::type_complexity)]
fn problem_request(
    (path, text, json, name, base_dir): (Option<String>, Option<String>, bool, &str, &str),
    out: &str,
    best: Option<String>,
    (backend, precision, tolerance, method, model, threads): (
        &str,
        Option<&str>,
        Option<f64>,
        Option<&str>,
        Option<&str>,
        Option<i64>,
    ),
    resume: bool,
) -> PyResult<hertz_cradle::optimize::request::OptimizeRequest> {
    use hertz_cradle::optimize::request::{OptimizeRequest, OptimizeSettings};
    use hertz_cradle::optimize::Problem;
    let input = |e: hertz_cradle::InputError| to_py(e.into());
    let problem = match (path, text) {
        (Some(p), _) => Problem::load(std::path::Path::new(&p)).map_err(input)?,
        (None, Some(t)) => {
            let t = if json { toml_from_json(name, &t)? } else { t };
            Problem::parse(
                &hertz_cradle::error::Source::new(name, &t),
                std::path::Path::new(base_dir),
            )
            .map_err(input)?
        }
        (None, None) => {
            return Err(PyValueError::new_err(
                "an optimisation needs a path or a text",
            ))
        }
    };
    let settings = OptimizeSettings {
        backend: BackendChoice::parse_flag("--backend", backend).map_err(input)?,
        threads,
        solver: solver(precision, tolerance, method, model)?,
        resume,
        command: vec![
            "python".to_string(),
            "hertz_cradle.optimize".to_string(),
            out.to_string(),
        ],
    };
    OptimizeRequest::new(
        problem,
        std::path::Path::new(out),
        best.as_deref().map(std::path::Path::new),
        &settings,
    )
    .map_err(input)
}

/// The problem's table columns: (name, type) pairs.
fn problem_columns(
    req: &hertz_cradle::optimize::request::OptimizeRequest,
) -> Vec<(String, &'static str)> {
    req.problem
        .header()
        .into_iter()
        .zip(req.problem.types())
        .map(|(n, t)| (n, type_name(t)))
        .collect()
}

/// Ask/tell: `designs` (JSON: a list of designs, each a mapping from
/// variable name to value or a list of the variables' values in the
/// problem's order; numbers or strings) run as one batch of the problem
/// (as [`optimize`] takes it); their rows written to `out`. Runs off the
/// GIL; returns the table's `columns`.
#[pyfunction]
#[pyo3(signature = (path, text, json, name, base_dir, out, designs, *, backend="auto",
    precision=None, tolerance=None, method=None, model=None, threads=None))]
#[allow(clippy::too_many_arguments)]
fn evaluate(
    py: Python<'_>,
    path: Option<String>,
    text: Option<String>,
    json: bool,
    name: &str,
    base_dir: &str,
    out: &str,
    designs: &str,
    backend: &str,
    precision: Option<&str>,
    tolerance: Option<f64>,
    method: Option<&str>,
    model: Option<&str>,
    threads: Option<i64>,
) -> PyResult<Vec<(String, &'static str)>> {
    use hertz_cradle::sweep::Value;
    let req = problem_request(
        (path, text, json, name, base_dir),
        out,
        None,
        (backend, precision, tolerance, method, model, threads),
        false,
    )?;
    let parsed: Vec<serde_json::Value> = serde_json::from_str(designs)
        .map_err(|e| PyValueError::new_err(format!("designs: {e}")))?;
    let names: Vec<&str> = req
        .problem
        .variables
        .iter()
        .map(|v| v.name.as_str())
        .collect();
    let mut values = Vec::with_capacity(parsed.len());
    for (k, d) in parsed.iter().enumerate() {
        // A mapping by variable name, in the problem's order; or the values.
        let cells: Vec<&serde_json::Value> = match d {
            serde_json::Value::Object(m) => {
                let unknown: Vec<&str> = m
                    .keys()
                    .map(String::as_str)
                    .filter(|n| !names.contains(n))
                    .collect();
                let missing: Vec<&str> = names
                    .iter()
                    .copied()
                    .filter(|n| !m.contains_key(*n))
                    .collect();
                if !unknown.is_empty() || !missing.is_empty() {
                    let list = |what: &str, v: &[&str]| match v {
                        [] => String::new(),
                        v => format!("; {what}: {}", v.join(", ")),
                    };
                    return Err(PyValueError::new_err(format!(
                        "design {k}: the problem's variables are {}{}{}",
                        names.join(", "),
                        list("unknown", &unknown),
                        list("missing", &missing)
                    )));
                }
                names.iter().map(|n| &m[*n]).collect()
            }
            serde_json::Value::Array(a) => a.iter().collect(),
            other => {
                return Err(PyValueError::new_err(format!(
                    "design {k}: {other} is neither a mapping nor a list of values"
                )))
            }
        };
        let row: PyResult<Vec<Value>> = cells
            .into_iter()
            .map(|x| match x {
                serde_json::Value::Number(n) => n
                    .as_f64()
                    .map(Value::Num)
                    .ok_or_else(|| PyValueError::new_err(format!("design {k}: {n}"))),
                serde_json::Value::String(t) => Ok(Value::Text(t.clone())),
                other => Err(PyValueError::new_err(format!(
                    "design {k}: {other} is neither a number nor a string"
                ))),
            })
            .collect();
        values.push(row?);
    }
    py.detach(|| std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| req.evaluate(&values))))
        .map_err(|_| PyRuntimeError::new_err("the evaluation panicked"))?
        .map_err(to_py)?;
    Ok(problem_columns(&req))
}

/// The built-in scenes: (name, summary) pairs.
#[pyfunction]
fn scenes(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    PyList::new(py, builtin::BUILTINS.iter().map(|b| (b.name, b.summary)))
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    hertz_cradle::backend::gpu::quiet_mesa_without_session();
    m.add_function(wrap_pyfunction!(sweep, m)?)?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(optimize, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(scenes, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
