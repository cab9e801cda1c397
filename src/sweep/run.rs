//! Running a sweep: the output opened (locked, resumed), the pipeline
//! (`pipeline.rs`: ids → jobs → backend → rows in id order) run with
//! progress on stderr, then the sidecar and the atomic publication.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Result;
use rayon::prelude::*;

use super::{pipeline, Sweep};
use crate::backend::{Backend, Job};
use crate::engine::{Chain, Overrides, Solver};
use crate::error::InputError;
use crate::output::lock::OutputLock;
use crate::output::partial::{Opened, Partial, TableFormat};
use crate::output::{row, sidecar};

pub struct Options {
    pub out: PathBuf,
    pub resume: bool,
    /// 1-based shard K of N.
    pub shard: Option<(u64, u64)>,
    pub overrides: Overrides,
    pub command: Vec<String>,
    /// Add a per-scene error estimate (a second, coarse run of every scene).
    pub error_estimate: bool,
    /// Write Parquet instead of CSV.
    pub parquet: bool,
    /// Show a progress bar (on stderr, when it is a terminal).
    pub progress: bool,
    /// Set to stop the run early (an interrupt): the rows so far stay in the
    /// partial file, which `--resume` continues.
    pub cancel: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
}

#[derive(Debug, Default)]
pub struct Summary {
    pub scenes: u64,
    pub ok: u64,
    pub wall_s: f64,
    pub already_complete: bool,
    /// The backend that ran it: its name and adapter.
    pub backend: String,
}

/// A checked sweep, run as `cradle sweep` runs it (the CLI and the Python
/// module both come here): the backend chosen, a pool of `--threads`
/// workers if given, the pipeline. `command` goes into the sidecar;
/// `cancel`, when set, stops the run early (`error::Interrupted`).
pub fn execute(
    cfg: &crate::config::SweepConfig,
    command: Vec<String>,
    progress: bool,
    cancel: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
) -> Result<Summary> {
    let backend = crate::backend::choose(cfg.backend, cfg.precision)?;
    let opts = Options {
        out: cfg.out.clone(),
        resume: cfg.resume,
        shard: cfg.shard,
        overrides: cfg.overrides.clone(),
        command,
        error_estimate: cfg.error_estimate,
        parquet: cfg.parquet,
        progress,
        cancel,
    };
    let go = || run(&cfg.sweep, &opts, backend.as_ref());
    let mut s = match cfg.threads {
        Some(t) => rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()?
            .install(go)?,
        None => go()?,
    };
    s.backend = format!("{} ({})", backend.name(), backend.adapter());
    Ok(s)
}

/// Scenes sampled to estimate the cost profile of a sweep for sharding.
pub const COST_SAMPLES: u64 = 65_536;

impl Sweep {
    /// The id range [lo, hi) of shard k of n (1-based): contiguous ids,
    /// balanced in expected cost (scene costs differ by orders of magnitude
    /// across a sweep). The cumulative cost is estimated from every scene, or
    /// from [`COST_SAMPLES`] evenly spaced ones (linear in between), with
    /// [`Solver::expected_cost`]; every shard computes the same boundaries.
    pub fn shard_range(&self, shard: Option<(u64, u64)>, o: &Overrides) -> (u64, u64) {
        let total = self.total;
        let Some((k, n)) = shard else {
            return (0, total);
        };
        let samples = total.min(COST_SAMPLES);
        let ids: Vec<u64> = (0..samples)
            .map(|j| ((j as u128 * total as u128) / samples as u128) as u64)
            .collect();
        let costs: Vec<f64> = ids
            .par_iter()
            .map(|&id| match self.job(id, o) {
                Ok(Job::Run { chain, solver }) => solver.expected_cost(&chain),
                _ => 1.0,
            })
            .collect();
        // Sample j stands for ids [ids[j], ids[j+1]): cumulative cost at its start.
        let mut cum = Vec::with_capacity(ids.len() + 1);
        let mut acc = 0.0;
        cum.push(0.0);
        for (j, c) in costs.iter().enumerate() {
            let next = ids.get(j + 1).copied().unwrap_or(total);
            acc += c * (next - ids[j]) as f64;
            cum.push(acc);
        }
        // The first id where the cumulative cost reaches i/n of the total.
        let at = |i: u64| -> u64 {
            if i == 0 {
                return 0;
            }
            if i == n {
                return total;
            }
            let target = acc * i as f64 / n as f64;
            let j = cum.partition_point(|&c| c < target).clamp(1, ids.len()) - 1;
            let end = ids.get(j + 1).copied().unwrap_or(total);
            let per = costs[j].max(f64::MIN_POSITIVE);
            let id = ids[j] + ((target - cum[j]) / per).ceil().max(0.0) as u64;
            id.min(end)
        };
        let (lo, hi) = (at(k - 1), at(k));
        (lo, hi.max(lo))
    }

    /// The job for scene `id`: its chain and solver, or why it is invalid.
    pub fn job(&self, id: u64, o: &Overrides) -> Result<Job, InputError> {
        match self.scene(id) {
            Ok(scene) => match Chain::from_scene(&scene) {
                Ok(chain) => Ok(Job::Run {
                    chain,
                    solver: Solver::resolve(&scene, o)?,
                }),
                Err(e) => Err(e),
            },
            Err(_) => Ok(Job::Invalid {
                n_balls: self.base.n,
            }),
        }
    }

    pub fn header(&self) -> Vec<String> {
        row::header(&self.axis_names(), self.shape())
    }

    /// The Arrow schema of this sweep's table (its Parquet output).
    pub fn arrow_schema(&self) -> arrow_schema::SchemaRef {
        crate::output::parquet_file::schema(&self.header(), &self.column_types())
    }
}

/// What every run shares before its rows: the output locked and opened
/// (or found complete), the fingerprint, the progress bar.
pub(super) struct Opening {
    pub _lock: OutputLock,
    pub fingerprint: String,
    pub out: Option<Partial>,
    pub bar: indicatif::ProgressBar,
}

/// `csv_partial`: the partial file holds CSV rows even for a Parquet output.
pub(super) fn open(
    sweep: &Sweep,
    opts: &Options,
    lo: u64,
    len: u64,
    csv_partial: bool,
) -> Result<Opening> {
    // One writer per output, for the whole run, before anything is touched.
    let lock = OutputLock::acquire(&opts.out)?;
    // Everything a resumed run must share with the first, in one string.
    let fingerprint = serde_json::to_string(&serde_json::json!({
        "sweep": sweep, "shard": opts.shard, "overrides": format!("{:?}", opts.overrides),
        "error_estimate": opts.error_estimate,
        "precision_default": "f64", "version": env!("CARGO_PKG_VERSION"),
    }))?;
    // Fail on a bad solver choice (e.g. f32 below its floor) before any output.
    sweep.job(lo.min(sweep.total.saturating_sub(1)), &opts.overrides)?;
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
    let bar = if opts.progress && std::io::stderr().is_terminal() && out.is_some() {
        let b = indicatif::ProgressBar::new(len);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {pos}/{len} scenes  {per_sec}  ETA {eta}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    } else {
        indicatif::ProgressBar::hidden()
    };
    Ok(Opening {
        _lock: lock,
        fingerprint,
        out,
        bar,
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
    pub refine: Option<serde_json::Value>,
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
    let text = sidecar::text(&sidecar::Sidecar {
        tool: "cradle",
        version: env!("CARGO_PKG_VERSION"),
        git_revision: sidecar::GIT_REVISION,
        command: opts.command.clone(),
        sweep_file: &sweep.origin,
        sweep,
        backend: backend.name(),
        adapter: &backend.adapter(),
        solver: serde_json::json!({
            "flags": {
                "method": opts.overrides.method.map(|m| m.name()),
                "precision": opts.overrides.precision.map(|p| p.name()),
                "tolerance": opts.overrides.tolerance,
            },
            "base_scene": match sweep.job(lo.min(sweep.total.saturating_sub(1)), &opts.overrides)? {
                Job::Run { solver, .. } => serde_json::to_value(solver)?,
                Job::Invalid { .. } => serde_json::Value::Null,
            },
        }),
        ids: [lo, hi],
        total_scenes: sweep.total,
        shard: opts.shard.map(|(k, n)| [k, n]),
        scenes_ok: c.ok,
        scenes_not_ok: c.done - c.ok,
        wall_s: c.wall_s,
        scenes_per_s: c.done as f64 / c.wall_s.max(1e-9),
        resumed_from_row: c.resumed_from_row,
        wall_s_this_run: c.wall_s_this_run,
        stages_s: c.stages,
        refine: c.refine,
        fingerprint,
    })?;
    out.finish((&sidecar::path(&opts.out), text.as_bytes()))
}

pub fn run(sweep: &Sweep, opts: &Options, backend: &dyn Backend) -> Result<Summary> {
    if let Some(spec) = &sweep.refine {
        return super::refine::run(sweep, spec, opts, backend);
    }
    let (lo, hi) = sweep.shard_range(opts.shard, &opts.overrides);
    let o = open(sweep, opts, lo, hi - lo, false)?;
    let Some(out) = o.out else {
        return Ok(Summary {
            already_complete: true,
            ..Default::default()
        });
    };
    let bar = o.bar;
    let start_id = lo + out.rows_done;
    let (ok_before, wall_before) = (out.ok_done, out.wall_before);
    bar.set_position(out.rows_done);
    let t0 = Instant::now();
    let (ok, done, out, stages) = pipeline::stream(
        sweep,
        opts,
        backend,
        pipeline::Ids::All,
        (start_id, hi),
        out,
        &pipeline::Hooks {
            progress: &|rows_end| bar.set_position(rows_end - lo),
            save: &|out| out.save_wall(wall_before + t0.elapsed().as_secs_f64()),
            rows: None,
        },
    )?;
    bar.finish_and_clear();
    let wall_s = t0.elapsed().as_secs_f64();
    let counts = Counts {
        ids: (lo, hi),
        ok: ok_before + ok,
        done: start_id - lo + done,
        wall_s: wall_before + wall_s,
        resumed_from_row: start_id - lo,
        wall_s_this_run: wall_s,
        stages: stages.json(wall_s),
        refine: None,
    };
    finish(sweep, opts, backend, &o.fingerprint, out, counts)?;
    Ok(Summary {
        scenes: done,
        ok,
        wall_s,
        already_complete: false,
        backend: String::new(),
    })
}
