//! What every way of running a sweep shares (the plain run in `run.rs`, the
//! refined one in `refine.rs`): its options, the output opened (locked,
//! resumed, fingerprinted) before any row, and the sidecar and atomic
//! publication after the last one.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use anyhow::Result;
use serde::{Deserialize, Serialize};

use super::Sweep;
use crate::backend::{Backend, Job};
use crate::engine::{Overrides, Solver};
use crate::error::InputError;
use crate::output::lock::OutputLock;
use crate::output::partial::{Opened, Partial, TableFormat};
use crate::output::row::Cell;
use crate::output::sidecar;

/// Where a running sweep stands: rows written so far and rows it will write
/// (a refinement's total grows level by level, as it finds what to refine).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Progress {
    pub done: u64,
    pub total: u64,
}

/// Called as rows are written (from the writer thread).
pub type OnProgress = Arc<dyn Fn(Progress) + Send + Sync>;

/// One scene's row, typed: its id, its sweep values (one per axis, as the
/// table's columns after `id`) and its outcome.
#[derive(Clone, Debug)]
pub struct SweepRow {
    pub id: u64,
    pub params: Vec<Cell>,
    pub outcome: RowOutcome,
}

pub use crate::model::RowOutcome;

/// Called with every row once it is written, in the order the output holds
/// them (id order; level by level for a refinement).
pub type OnRow = Arc<dyn Fn(&SweepRow) + Send + Sync>;

/// How a sweep is run (the checked form of `cradle sweep`'s flags).
#[derive(Clone)]
pub struct Options {
    pub out: PathBuf,
    pub resume: bool,
    /// 1-based shard K of N.
    pub shard: Option<(u64, u64)>,
    pub overrides: Overrides,
    /// What made the run, for the sidecar (the command line, or a name).
    pub command: Vec<String>,
    /// Add a per-scene error estimate (a second, coarse run of every scene).
    pub error_estimate: bool,
    /// Write Parquet instead of CSV.
    pub parquet: bool,
    /// Told as rows are written.
    pub on_progress: Option<OnProgress>,
    /// Given every row, typed, once it is written.
    pub on_row: Option<OnRow>,
    /// Set to stop the run early (an interrupt): the rows so far stay in the
    /// partial file, which `--resume` continues (`error::Interrupted`).
    pub cancel: Option<Arc<AtomicBool>>,
}

impl Options {
    /// A plain run into `out`: not resumed, unsharded, no flags, no error
    /// estimate, CSV, no callbacks.
    pub fn new(out: PathBuf) -> Options {
        Options {
            out,
            resume: false,
            shard: None,
            overrides: Overrides::default(),
            command: vec![],
            error_estimate: false,
            parquet: false,
            on_progress: None,
            on_row: None,
            cancel: None,
        }
    }

    /// Tell the progress callback, if any.
    pub fn progress(&self, done: u64, total: u64) {
        if let Some(f) = &self.on_progress {
            f(Progress { done, total })
        }
    }
}

/// What a run did.
#[derive(Debug, Default, Clone)]
pub struct Summary {
    /// Scenes this run computed (not those an earlier, resumed run did).
    pub scenes: u64,
    /// Of those, how many ended with status `ok`.
    pub ok: u64,
    pub wall_s: f64,
    /// The output was complete before the run: nothing was done.
    pub already_complete: bool,
    /// The backend that ran it: its name and adapter.
    pub backend: String,
    /// A resumed run: the rows kept from earlier runs and the bytes dropped
    /// after them (an incomplete or torn last row, a zero-filled tail).
    pub resumed: Option<(u64, u64)>,
}

impl Sweep {
    /// The job for scene `id` of a sweep of cradles: its chain and solver,
    /// or `Invalid`.
    pub fn job(&self, id: u64, o: &Overrides) -> Result<Job, InputError> {
        crate::model::cradle::job(self.scene(id), self.base.n, o)
    }

    /// The solver of scene `id` (`None`: its values make no valid scene),
    /// or why the flags cannot run it.
    pub fn solver_at(&self, id: u64, o: &Overrides) -> Result<Option<Solver>, InputError> {
        match self.scene(id) {
            Ok(scene) => Solver::resolve(&scene, o).map(Some),
            Err(_) => Ok(None),
        }
    }

    /// The table's columns: `id`, the axes, the model's outcome.
    pub fn header(&self) -> Vec<String> {
        let mut h = vec!["id".to_string()];
        h.extend(self.axis_names());
        h.extend(self.model.header());
        h
    }

    /// The Arrow schema of this sweep's table (its Parquet output).
    pub fn arrow_schema(&self) -> arrow_schema::SchemaRef {
        crate::output::parquet_file::schema(&self.header(), &self.column_types())
    }

    /// Scene `id`'s row, typed.
    pub fn typed_row(&self, id: u64, outcome: RowOutcome) -> SweepRow {
        let mut params = Vec::with_capacity(self.axes.len());
        self.emit_axis_values(id, &mut |f| params.push(Cell::from(f)));
        SweepRow {
            id,
            params,
            outcome,
        }
    }
}

/// What a resumed run, and every part of a merge, must share with the run
/// it continues: the sweep as resolved, the shard, the solver flags, the
/// error estimate and the crate version. [`Fingerprint::encode`] writes it
/// as compact JSON with the keys of every object in alphabetical order and
/// each flag by its name (`null` when not given), e.g.
/// `{"error_estimate":false,"overrides":{"method":null,"model":null,
/// "precision":"f32","tolerance":null},"precision_default":"f64",
/// "shard":[1,3],"sweep":{…},"version":"0.1.0"}` — the text the partial
/// file's first line and the sidecar's `fingerprint` hold (docs/SPEC.md §8).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Fingerprint {
    pub error_estimate: bool,
    pub overrides: FlagNames,
    /// The precision a scene without one runs in.
    pub precision_default: String,
    /// `--shard K/N` as [K, N].
    pub shard: Option<(u64, u64)>,
    /// The sweep as resolved (the sidecar's `sweep`).
    pub sweep: serde_json::Value,
    pub version: String,
}

/// The solver flags of a run, by name.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FlagNames {
    pub method: Option<String>,
    pub model: Option<String>,
    pub precision: Option<String>,
    pub tolerance: Option<f64>,
}

impl Fingerprint {
    pub fn of(
        sweep: &Sweep,
        shard: Option<(u64, u64)>,
        o: &Overrides,
        error_estimate: bool,
    ) -> Result<Fingerprint> {
        Ok(Fingerprint {
            error_estimate,
            overrides: FlagNames {
                method: o.method.map(|m| m.name().to_string()),
                model: o.model.map(|m| m.name().to_string()),
                precision: o.precision.map(|p| p.name().to_string()),
                tolerance: o.tolerance,
            },
            precision_default: "f64".into(),
            shard,
            sweep: serde_json::to_value(sweep)?,
            version: env!("CARGO_PKG_VERSION").into(),
        })
    }

    /// The encoding described above (serde_json's maps keep keys sorted).
    pub fn encode(&self) -> String {
        serde_json::to_value(self)
            .and_then(|v| serde_json::to_string(&v))
            .expect("a fingerprint is plain JSON")
    }

    /// A fingerprint's text read back; `None` if it is not one.
    pub fn decode(text: &str) -> Option<Fingerprint> {
        serde_json::from_str(text).ok()
    }

    /// The same without its shard: what every part of a merge shares.
    pub fn without_shard(&self) -> Fingerprint {
        Fingerprint {
            shard: None,
            ..self.clone()
        }
    }
}

/// What every run shares before its rows: the output locked and opened
/// (or found complete), and the fingerprint.
pub(super) struct Opening {
    pub _lock: OutputLock,
    pub fingerprint: String,
    pub out: Option<Partial>,
}

/// `csv_partial`: the partial file holds CSV rows even for a Parquet output.
pub(super) fn open(sweep: &Sweep, opts: &Options, lo: u64, csv_partial: bool) -> Result<Opening> {
    // One writer per output, for the whole run, before anything is touched.
    let lock = OutputLock::acquire(&opts.out)?;
    // Everything a resumed run must share with the first, in one string.
    let fingerprint =
        Fingerprint::of(sweep, opts.shard, &opts.overrides, opts.error_estimate)?.encode();
    // Fail on a bad solver choice (e.g. f32 below its floor) before any output.
    sweep.solver_at(lo.min(sweep.total.saturating_sub(1)), &opts.overrides)?;
    let mut header = Vec::new();
    {
        let mut w = csv::Writer::from_writer(&mut header);
        w.write_record(sweep.header())?;
        w.flush()?;
    }
    let format = if opts.parquet && !csv_partial {
        TableFormat::Parquet(sweep.arrow_schema())
    } else {
        TableFormat::Csv
    };
    let out = match Partial::open(&opts.out, format, &header, &fingerprint, opts.resume)? {
        Opened::AlreadyComplete => None,
        Opened::Writing(w) => Some(*w),
    };
    Ok(Opening {
        _lock: lock,
        fingerprint,
        out,
    })
}

/// The counts a sidecar records.
pub(super) struct Counts {
    pub ids: (u64, u64),
    pub ok: u64,
    pub done: u64,
    pub wall_s: f64,
    pub resumed_from_row: u64,
    pub wall_s_this_run: f64,
    pub stages: serde_json::Value,
    pub refine: Option<sidecar::Refined>,
}

/// Write the sidecar and publish the output.
pub(super) fn finish(
    sweep: &Sweep,
    opts: &Options,
    backend: &dyn Backend,
    fingerprint: &str,
    out: Partial,
    c: Counts,
) -> Result<()> {
    let (lo, hi) = c.ids;
    let sc = sidecar::Sidecar {
        tool: "cradle".into(),
        version: env!("CARGO_PKG_VERSION").into(),
        git_revision: sidecar::GIT_REVISION.into(),
        command: opts.command.clone(),
        sweep_file: sweep.origin.clone(),
        sweep,
        backend: backend.name().into(),
        adapter: backend.adapter(),
        solver: serde_json::json!({
            "flags": sidecar::flags(&opts.overrides),
            "base_scene": match sweep.solver_at(lo.min(sweep.total.saturating_sub(1)), &opts.overrides)? {
                Some(solver) => serde_json::to_value(solver)?,
                None => serde_json::Value::Null,
            },
        }),
        ids: [lo, hi],
        total_scenes: sweep.total,
        shard: opts.shard.map(|(k, n)| [k, n]),
        scenes_ok: c.ok,
        scenes_not_ok: c.done - c.ok,
        wall_s: c.wall_s,
        scenes_per_s: c.done as f64 / c.wall_s.max(1e-9),
        resumed_from_row: Some(c.resumed_from_row),
        wall_s_this_run: Some(c.wall_s_this_run),
        stages_s: Some(c.stages),
        refine: c.refine,
        fingerprint: fingerprint.to_string(),
        merged_from: None,
        table: None,
    };
    out.finish(&sidecar::path(&opts.out), c.done, |seal| {
        sidecar::text(&sidecar::Sidecar {
            table: Some(seal),
            ..sc
        })
    })
}
