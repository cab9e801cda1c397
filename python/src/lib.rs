//! `hertz_cradle._native`: the Rust side of the Python module. Every call
//! goes through the CLI's own argument parser and checked configuration
//! (`cli`, `config`), so a bad input raises `ValueError` with the message
//! `cradle` prints, and a sweep runs exactly as `cradle sweep` runs it (same
//! pipeline, output files, resume, sidecar). The Python layer
//! (`hertz_cradle/__init__.py`) builds the argument lists and reads tables.
//!
//! The GIL is released while scenes run. A sweep runs on a thread of its
//! own; the calling thread wakes every 50 ms to let Python handle signals:
//! on Ctrl-C the sweep is told to stop (its rows so far stay in the
//! `.partial` file, which `resume=True` continues) and KeyboardInterrupt is
//! raised once it has stopped. No panic crosses into Python: a panic in the
//! sweep thread becomes RuntimeError.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use clap::Parser;
use hertz_cradle::cli::{Cli, Command, Format};
use hertz_cradle::config::{RunConfig, SweepConfig};
use hertz_cradle::error::{Interrupted, Source};
use hertz_cradle::output::row::{self, ColType, Field};
use hertz_cradle::scene::{builtin, Scene};
use hertz_cradle::sweep::Sweep;
use hertz_cradle::InputError;
use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// An error as Python sees it: bad input → ValueError (the CLI's message),
/// an interrupt → KeyboardInterrupt, anything else → RuntimeError.
fn to_py(e: anyhow::Error) -> PyErr {
    let text = format!("{e:#}");
    if e.chain().any(|c| c.downcast_ref::<Interrupted>().is_some()) {
        PyKeyboardInterrupt::new_err(text)
    } else if e.chain().any(|c| c.downcast_ref::<InputError>().is_some()) {
        PyValueError::new_err(text)
    } else {
        PyRuntimeError::new_err(text)
    }
}

/// Parse `cradle SUBCOMMAND ARGS...` as the CLI does; a usage error is a
/// ValueError with clap's message.
fn parse(subcommand: &str, args: Vec<String>) -> PyResult<Command> {
    let argv = ["cradle".to_string(), subcommand.to_string()]
        .into_iter()
        .chain(args);
    Cli::try_parse_from(argv)
        .map(|c| c.command)
        .map_err(|e| PyValueError::new_err(e.render().to_string().trim_end().to_string()))
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

/// Run a sweep: `args` are `cradle sweep`'s arguments. With `text` (TOML,
/// or JSON when `json`), the sweep is that document instead of the file
/// `args[0]` names (a relative `scene = "file"` is found from `base_dir`).
/// Returns a summary: scenes, ok, wall_s, backend, already_complete, and
/// columns (name, type) of the table written.
#[pyfunction]
#[pyo3(signature = (args, text=None, json=false, name="<string>", base_dir=".", progress=true))]
fn sweep(
    py: Python<'_>,
    args: Vec<String>,
    text: Option<String>,
    json: bool,
    name: &str,
    base_dir: &str,
    progress: bool,
) -> PyResult<Py<PyDict>> {
    let Command::Sweep(a) = parse("sweep", args)? else {
        return Err(PyValueError::new_err("not a sweep"));
    };
    let given = match text {
        None => None,
        Some(t) => {
            let t = if json { toml_from_json(name, &t)? } else { t };
            Some(
                Sweep::parse(&Source::new(name, t), Path::new(base_dir))
                    .map_err(|e| to_py(e.into()))?,
            )
        }
    };
    let cfg = SweepConfig::from_args_and(&a, given).map_err(|e| to_py(e.into()))?;
    let columns: Vec<(String, &str)> = cfg
        .sweep
        .header()
        .into_iter()
        .zip(cfg.sweep.column_types().into_iter().map(type_name))
        .collect();
    let command = vec![
        "python".to_string(),
        "hertz_cradle.sweep".to_string(),
        cfg.out_given.display().to_string(),
    ];

    let cancel = Arc::new(AtomicBool::new(false));
    // Set by the worker when it ends.
    let finished = Arc::new((Mutex::new(false), Condvar::new()));
    let worker = {
        let (cancel, finished) = (cancel.clone(), finished.clone());
        std::thread::spawn(move || {
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                hertz_cradle::sweep::run::execute(&cfg, command, progress, Some(cancel))
            }));
            *finished.0.lock().unwrap_or_else(|e| e.into_inner()) = true;
            finished.1.notify_all();
            r
        })
    };
    let mut interrupted = None;
    loop {
        let done = py.detach(|| {
            let g = finished.0.lock().unwrap_or_else(|e| e.into_inner());
            let (g, _) = finished
                .1
                .wait_timeout_while(g, Duration::from_millis(50), |done| !*done)
                .unwrap_or_else(|e| e.into_inner());
            *g
        });
        if done {
            break;
        }
        if interrupted.is_none() {
            if let Err(e) = py.check_signals() {
                cancel.store(true, Ordering::SeqCst);
                interrupted = Some(e);
            }
        }
    }
    let result = py.detach(|| worker.join());
    if let Some(e) = interrupted {
        return Err(e);
    }
    let summary = match result {
        Ok(Ok(r)) => r.map_err(to_py)?,
        _ => return Err(PyRuntimeError::new_err("the sweep thread panicked")),
    };
    let d = PyDict::new(py);
    d.set_item("scenes", summary.scenes)?;
    d.set_item("ok", summary.ok)?;
    d.set_item("wall_s", summary.wall_s)?;
    d.set_item("backend", summary.backend)?;
    d.set_item("already_complete", summary.already_complete)?;
    d.set_item("columns", columns)?;
    Ok(d.unbind())
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

/// Run one scene: `args` are `cradle run`'s arguments (the scene first).
/// With `text` (TOML, or JSON when `json`), the scene is that document,
/// named `name` in messages. Returns the outcome row as a dict (the columns
/// of `cradle run --format csv`); a trace, if asked for, is in the file
/// given with `--trace`.
#[pyfunction]
#[pyo3(signature = (args, text=None, json=false, name="<string>"))]
fn run(
    py: Python<'_>,
    args: Vec<String>,
    text: Option<String>,
    json: bool,
    name: &str,
) -> PyResult<Py<PyDict>> {
    let Command::Run {
        scene,
        trace,
        trace_dt,
        solver,
        ..
    } = parse("run", args)?
    else {
        return Err(PyValueError::new_err("not a run"));
    };
    let cfg = match text {
        None => RunConfig::from_args(&scene, Format::Csv, trace.as_deref(), trace_dt, &solver),
        Some(t) => {
            let t = if json { toml_from_json(name, &t)? } else { t };
            Scene::from_toml_str(name, &t)
                .map_err(anyhow::Error::from)
                .and_then(|s| {
                    RunConfig::from_scene(name, s, Format::Csv, trace.as_deref(), trace_dt, &solver)
                })
        }
    }
    .map_err(to_py)?;
    let outcome = py
        .detach(|| std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| cfg.execute())))
        .map_err(|_| PyRuntimeError::new_err("the run panicked"))?
        .map_err(to_py)?;
    let shape = row::Shape {
        width: cfg.scene.n,
        pendulum: cfg.chain.is_pendulum(),
    };
    let header = row::header(&[], shape);
    let d = PyDict::new(py);
    let mut k = 0;
    let mut err = Ok(());
    row::emit_fields(0, |_| {}, &outcome, shape, &mut |f| {
        if k > 0 {
            // Column 0 is the id, meaningless for one scene.
            let r = field_to_py(py, f).and_then(|v| d.set_item(&header[k], v));
            if err.is_ok() {
                err = r;
            }
        }
        k += 1;
    });
    err?;
    d.set_item("model", cfg.solver.model.name())?;
    d.set_item("scene", &cfg.name)?;
    Ok(d.unbind())
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
    m.add_function(wrap_pyfunction!(scenes, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
