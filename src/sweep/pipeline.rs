//! The sweep pipeline: ids → jobs → backend → rows (CSV bytes or Arrow
//! record batches), with no idle stage.
//!
//! The id range is cut into batches. One *lane* per worker thread takes the
//! next batch, builds its jobs, runs them on the backend and formats their
//! rows into bytes, all on that thread (rayon's nested parallelism lets an
//! idle thread steal chunks of another lane's batch, so the last batches of a
//! sweep are shared out too). A writer thread appends the batches' bytes in
//! id order. A slow batch (a straggler scene) delays only the writing of its
//! own rows: the other lanes go on with later batches, up to [`AHEAD_ROWS`]
//! rows past the oldest unwritten batch, which bounds the memory held by
//! finished-but-unwritten rows. Lanes that reach that bound help the others
//! (rayon `yield_now`: chunks of another lane's batch) instead of sleeping.
//! The lanes are a broadcast, one on each pool thread, so no lane can be
//! run nested inside another's batch (see `stream`).
//!
//! Rows are formatted the same way whatever the lane, batch or thread count,
//! so the file is byte-identical across them (tested). For Parquet the lanes
//! build record batches and the writer encodes them into segments
//! (`output::parquet_file`), whose boundaries depend only on the id range.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{mpsc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Result;

use super::session::{Options, SweepRow};
use super::Sweep;
use crate::backend::{Backend, DeviceStats, Gate};
use crate::engine::Status;
use crate::model::Outcomes;
use crate::output::parquet_file::{Columns, Segment, SEGMENT_ROWS};
use crate::output::partial::{Partial, TableFormat};
use crate::output::row::{self, Cell};

/// Rows the lanes may run ahead of the oldest unwritten batch. With ~330
/// bytes a row (5 balls) that is ≤ 70 MB of formatted rows waiting for a
/// straggler; at least two batches, and at least as many as the backend
/// runs at once.
pub const AHEAD_ROWS: u64 = 196_608;

/// Seconds between saves of the wall time so far (for a resumed run's sidecar).
const WALL_SAVE_S: f64 = 2.0;

/// Thread-seconds spent in each stage (summed over lanes), and the writer's.
#[derive(Debug, Default, Clone, Copy)]
pub struct Stages {
    pub jobs: f64,
    pub integration: f64,
    pub formatting: f64,
    pub writing: f64,
    /// Thread-seconds lanes spent waiting for a straggler's rows to be written.
    pub waiting: f64,
    pub lanes: usize,
    /// What the GPU did (a GPU backend; totals of its lifetime so far).
    pub device: Option<DeviceStats>,
}

impl Stages {
    fn add(&mut self, o: &Stages) {
        self.jobs += o.jobs;
        self.integration += o.integration;
        self.formatting += o.formatting;
        self.waiting += o.waiting;
    }

    pub fn json(&self, wall_s: f64) -> serde_json::Value {
        let mut j = serde_json::json!({
            "lanes": self.lanes,
            "jobs": self.jobs,
            "integration": self.integration,
            "formatting": self.formatting,
            "writing": self.writing,
            "waiting_for_stragglers": self.waiting,
            "busy_fraction": (self.jobs + self.integration + self.formatting)
                / (wall_s * self.lanes as f64).max(1e-9),
        });
        if let Some(d) = self.device {
            j["gpu"] = serde_json::json!({
                "dispatches": d.dispatches,
                "rounds": d.rounds,
                "batches_per_round": d.batch_rounds as f64 / (d.rounds.max(1) as f64),
                "most_batches_in_a_round": d.most_batches,
                "in_flight": d.in_flight_s,
                "in_flight_fraction": d.in_flight_s / wall_s.max(1e-9),
                "scenes_on_cpu": d.cpu_scenes,
                "packing": d.packing_s,
                "unpacking": d.unpacking_s,
                "waiting_for_device": d.waiting_s,
                "compiling": d.compiling_s,
            });
        }
        j
    }
}

/// Rows of a finished batch, as the output wants them.
enum Rows {
    Csv(Vec<u8>),
    Arrow(arrow_array::RecordBatch),
}

/// One finished batch: its first id, its rows, how many are ok, and its
/// rows typed when a row callback wants them.
struct Done {
    first: u64,
    n: u64,
    ok: u64,
    rows: Rows,
    typed: Vec<SweepRow>,
    /// The column a [`Hooks::column`] watches, typed, for each row.
    picked: Vec<Picked>,
}

/// One row's value of a watched column (a refinement's column), typed as
/// the table types it, and whether the row is `ok`.
#[derive(Clone, Debug, PartialEq)]
pub struct Picked {
    pub id: u64,
    pub value: Cell,
    pub ok: bool,
}

/// Which scenes a stream runs: position p of the stream is scene `p`
/// (`All`) or scene `ids[p]` (`List`, ascending: a refinement level).
#[derive(Clone, Copy)]
pub enum Ids<'a> {
    All,
    List(&'a [u64]),
}

impl Ids<'_> {
    fn at(&self, p: u64) -> u64 {
        match self {
            Ids::All => p,
            Ids::List(v) => v[p as usize],
        }
    }
}

/// Jobs, outcomes and rows of the scenes at positions `first .. end`.
#[allow(clippy::too_many_arguments)]
fn batch(
    sweep: &Sweep,
    opts: &Options,
    backend: &dyn Backend,
    gate: Option<&Gate>,
    format: &TableFormat,
    ids: Ids,
    (first, end): (u64, u64),
    column: Option<usize>,
    st: &mut Stages,
) -> Result<Done> {
    let (mut t, mut t1) = (Instant::now(), Instant::now());
    let mut work = || -> Result<Box<dyn Outcomes>> {
        t = Instant::now();
        t1 = t;
        let scene = |k: usize| sweep.scene(ids.at(first + k as u64));
        let n = (end - first) as usize;
        sweep.model.run(
            backend,
            n,
            &scene,
            &opts.overrides,
            opts.error_estimate,
            &mut t1,
        )
    };
    // A backend that takes few calls at once (a GPU): the lanes waiting for
    // it build their jobs only once let in, so no more than that many
    // batches of jobs are held, whatever the thread count. (Time spent
    // waiting to be let in is in no stage: the lane is idle.)
    let outcomes = match gate {
        Some(g) => g.with(work)?,
        None => work()?,
    };
    let t2 = Instant::now();
    let n = outcomes.len();
    let ok = (0..n).filter(|&k| outcomes.status(k) == Status::Ok).count() as u64;
    // Row k: id, axes, outcome.
    let row = |k: usize, out: &mut dyn FnMut(row::Field)| {
        let id = ids.at(first + k as u64);
        out(row::Field::Int(id));
        sweep.emit_axis_values(id, out);
        outcomes.emit(k, out)
    };
    let rows = match format {
        TableFormat::Csv => {
            let mut bytes = Vec::with_capacity(256 * n);
            let mut scratch = String::with_capacity(32);
            for k in 0..n {
                let mut sep = false;
                row(k, &mut |field| {
                    if sep {
                        bytes.push(b',');
                    }
                    sep = true;
                    match field {
                        row::Field::Text(t) => row::push_csv_field(&mut bytes, t),
                        // A number's text needs no quotes.
                        f => bytes.extend_from_slice(row::field_text(f, &mut scratch).as_bytes()),
                    }
                });
                bytes.push(b'\n');
            }
            Rows::Csv(bytes)
        }
        TableFormat::Parquet(schema) => {
            let mut cols = Columns::new(schema, &sweep.column_types(), n);
            for k in 0..n {
                row(k, &mut |field| cols.push(field));
            }
            Rows::Arrow(cols.finish()?)
        }
    };
    let picked = match column {
        Some(c) => (0..n)
            .map(|k| {
                let (mut at, mut value) = (0, Cell::Null);
                row(k, &mut |field| {
                    if at == c {
                        value = Cell::from(field);
                    }
                    at += 1;
                });
                Picked {
                    id: ids.at(first + k as u64),
                    value,
                    ok: outcomes.status(k) == Status::Ok,
                }
            })
            .collect(),
        None => vec![],
    };
    // The outcomes are not needed past here: a row callback takes them.
    let typed = match opts.on_row {
        Some(_) => (first..)
            .zip(outcomes.into_rows())
            .map(|(p, o)| sweep.typed_row(ids.at(p), o))
            .collect(),
        None => vec![],
    };
    let t3 = Instant::now();
    st.jobs += (t1 - t).as_secs_f64();
    st.integration += (t2 - t1).as_secs_f64();
    st.formatting += (t3 - t2).as_secs_f64();
    Ok(Done {
        first,
        n: end - first,
        ok,
        rows,
        typed,
        picked,
    })
}

/// Sees the watched column of every batch of rows a stream appends.
pub type ColumnHook<'a> = &'a (dyn Fn(&[Picked]) + Sync);

/// What a stream does besides appending rows: `progress` gets the end
/// position of the rows written so far; `save` is called every few seconds;
/// `column` (if any): a column's index and what sees its values, typed, as
/// the rows are appended.
pub struct Hooks<'a> {
    pub progress: &'a (dyn Fn(u64) + Sync),
    pub save: &'a (dyn Fn(&Partial) -> Result<()> + Sync),
    pub column: Option<(usize, ColumnHook<'a>)>,
}

/// Run the scenes at positions `lo .. hi` of `ids` and append their rows to
/// `out` in order. Returns (ok rows, rows, the output, stage times).
/// Long (~170 lines) on purpose: the writer thread and the lanes live in one
/// `thread::scope` and share its locals (the channel, the counters, the
/// gate); split, each part would take a dozen borrowed arguments.
#[allow(clippy::too_many_arguments)]
pub fn stream(
    sweep: &Sweep,
    opts: &Options,
    backend: &dyn Backend,
    ids: Ids,
    (lo, hi): (u64, u64),
    out: Partial,
    hooks: &Hooks,
) -> Result<(u64, u64, Partial, Stages)> {
    let (progress, save) = (hooks.progress, hooks.save);
    // An interrupt stops a batch in hand too, not only the next ones.
    let stoppable;
    let backend: &dyn Backend = match &opts.cancel {
        Some(flag) => {
            stoppable = Stoppable {
                inner: backend,
                stop: crate::engine::Stop::on(flag.clone()),
            };
            &stoppable
        }
        None => backend,
    };
    let mut batch_size = sweep.model.batch_size(backend.batch_size().max(1));
    if let TableFormat::Parquet(_) = out.format {
        // A power of two ≤ a segment: no batch straddles two segments.
        batch_size = (1u64 << batch_size.ilog2()).min(SEGMENT_ROWS);
    }
    let format = out.format.clone();
    let n_batches = (hi - lo).div_ceil(batch_size);
    let lanes = rayon::current_num_threads().clamp(1, n_batches.max(1) as usize);
    // Never fewer than the backend runs at once: a GPU's calls and the
    // batches packed beside them (8 at the hardware profile) would
    // otherwise wait on the bound at large batches (32,768 scenes: 6).
    let in_flight = backend.max_concurrent_runs().min(lanes) as u64;
    let ahead = (AHEAD_ROWS / batch_size).max(2).max(in_flight);
    // A backend that takes few calls at once (a GPU) is gated; the CPU is not.
    let gate = (backend.max_concurrent_runs() < usize::MAX)
        .then(|| Gate::new(backend.max_concurrent_runs()));
    let next = AtomicU64::new(0);
    // Batches written so far (the writer's position), and a stop signal.
    let written = AtomicU64::new(0);
    let abort = AtomicBool::new(false);
    let totals = Mutex::new(Stages {
        lanes,
        ..Stages::default()
    });
    let (tx, rx) = mpsc::channel::<Result<Done>>();

    std::thread::scope(|sc| -> Result<(u64, u64, Partial, Stages)> {
        let (written, abort) = (&written, &abort);
        let writer = sc.spawn(move || -> Result<(u64, u64, Partial, f64)> {
            let mut out = out;
            let mut segment = match &out.format {
                TableFormat::Parquet(schema) => Some(Segment::new(schema.clone())),
                TableFormat::Csv => None,
            };
            let (mut ok, mut done, mut writing) = (0u64, 0u64, 0.0);
            let mut waiting: BTreeMap<u64, Done> = BTreeMap::new();
            let mut saved = Instant::now();
            let mut expect = lo;
            let mut result = Ok(());
            for msg in rx {
                match msg {
                    Ok(d) => {
                        waiting.insert(d.first, d);
                    }
                    Err(e) => {
                        // Keep every row before the failure, then stop.
                        abort.store(true, Ordering::SeqCst);
                        result = Err(e);
                    }
                }
                while let Some(d) = waiting.remove(&expect) {
                    let t = Instant::now();
                    let r = match (&d.rows, segment.as_mut()) {
                        (Rows::Csv(bytes), _) => out.append(bytes),
                        (Rows::Arrow(b), Some(seg)) => seg.write(b, d.ok).and_then(|_| {
                            // Segments end at fixed ids: lo + k·SEGMENT_ROWS, and at hi.
                            let end = d.first + d.n;
                            if (end - lo).is_multiple_of(SEGMENT_ROWS) || end == hi {
                                match seg.take_frame()? {
                                    Some(frame) => out.append(&frame),
                                    None => Ok(()),
                                }
                            } else {
                                Ok(())
                            }
                        }),
                        (Rows::Arrow(_), None) => unreachable!("record batches only for Parquet"),
                    };
                    if let Err(e) = r {
                        abort.store(true, Ordering::SeqCst);
                        return Err(e);
                    }
                    writing += t.elapsed().as_secs_f64();
                    if let Some((_, f)) = hooks.column {
                        f(&d.picked);
                    }
                    if let Some(f) = &opts.on_row {
                        d.typed.iter().for_each(|r| f(r));
                    }
                    ok += d.ok;
                    done += d.n;
                    expect += d.n;
                    written.fetch_add(1, Ordering::SeqCst);
                    progress(expect);
                    if saved.elapsed().as_secs_f64() >= WALL_SAVE_S {
                        save(&out)?;
                        saved = Instant::now();
                    }
                }
                if result.is_err() {
                    break;
                }
            }
            result.map(|_| (ok, done, out, writing))
        });

        {
            let lane = || {
                let mut st = Stages::default();
                loop {
                    if abort.load(Ordering::SeqCst) {
                        break;
                    }
                    if opts
                        .cancel
                        .as_ref()
                        .is_some_and(|c| c.load(Ordering::SeqCst))
                    {
                        // Every batch taken: the run ends as it would have
                        // (the lanes still working stop theirs, or finish
                        // them, and the writer has them all).
                        if next.load(Ordering::SeqCst) < n_batches {
                            let _ = tx.send(Err(crate::error::Interrupted.into()));
                            abort.store(true, Ordering::SeqCst);
                        }
                        break;
                    }
                    let b = next.fetch_add(1, Ordering::SeqCst);
                    if b >= n_batches {
                        break;
                    }
                    // Stay within `ahead` batches of the writer: help the others meanwhile.
                    let t = Instant::now();
                    while b >= written.load(Ordering::SeqCst) + ahead
                        && !abort.load(Ordering::SeqCst)
                    {
                        if rayon::yield_now() != Some(rayon::Yield::Executed) {
                            std::thread::sleep(Duration::from_micros(200));
                        }
                    }
                    st.waiting += t.elapsed().as_secs_f64();
                    let first = lo + b * batch_size;
                    let r = batch(
                        sweep,
                        opts,
                        backend,
                        gate.as_ref(),
                        &format,
                        ids,
                        (first, (first + batch_size).min(hi)),
                        hooks.column.map(|c| c.0),
                        &mut st,
                    );
                    let failed = r.is_err();
                    if tx.send(r).is_err() || failed {
                        abort.store(true, Ordering::SeqCst);
                        break;
                    }
                }
                totals.lock().unwrap_or_else(|e| e.into_inner()).add(&st);
            };
            // One lane on each pool thread (a broadcast, not spawned tasks:
            // a spawned lane still queued could be stolen by a thread that
            // waits inside another lane's batch — rayon runs queued work
            // while it waits — and, nested there, wait for the writer to pass
            // the very batch it sits on: a deadlock once the lanes outrun
            // `ahead`, which batches of 16,384 scenes did on a 16-core GPU
            // host. A broadcast's job runs only on its own thread.)
            rayon::broadcast(|ctx| {
                if ctx.index() < lanes {
                    lane();
                }
            });
        }
        drop(tx);
        let (ok, done, out, writing) = writer
            .join()
            .map_err(|_| anyhow::anyhow!("the CSV writer thread panicked"))??;
        let mut st = *totals.lock().unwrap_or_else(|e| e.into_inner());
        st.writing = writing;
        st.device = backend.device_stats();
        Ok((ok, done, out, st))
    })
}

/// A backend whose calls give up once `stop` is requested ([`Backend::run_until`],
/// [`Backend::run_chains_until`]): a sweep's interrupt stops the batches in
/// hand, not only the next ones. Every other method is the inner
/// backend's.
struct Stoppable<'a> {
    inner: &'a dyn Backend,
    stop: crate::engine::Stop,
}

impl Backend for Stoppable<'_> {
    fn name(&self) -> &'static str {
        self.inner.name()
    }
    fn adapter(&self) -> String {
        self.inner.adapter()
    }
    fn run(&self, jobs: &[crate::backend::Job]) -> Result<Vec<crate::engine::Outcome>> {
        self.inner.run_until(jobs, &self.stop)
    }
    fn run_until(
        &self,
        jobs: &[crate::backend::Job],
        stop: &crate::engine::Stop,
    ) -> Result<Vec<crate::engine::Outcome>> {
        self.inner.run_until(jobs, stop)
    }
    fn batch_size(&self) -> u64 {
        self.inner.batch_size()
    }
    fn max_concurrent_runs(&self) -> usize {
        self.inner.max_concurrent_runs()
    }
    fn device_stats(&self) -> Option<DeviceStats> {
        self.inner.device_stats()
    }
    fn run_chains(
        &self,
        n: usize,
        job: crate::backend::ChainSource,
    ) -> Result<Vec<crate::engine::granular::ChainOutcome>> {
        self.inner.run_chains_until(n, job, &self.stop)
    }
    fn run_chains_until(
        &self,
        n: usize,
        job: crate::backend::ChainSource,
        stop: &crate::engine::Stop,
    ) -> Result<Vec<crate::engine::granular::ChainOutcome>> {
        self.inner.run_chains_until(n, job, stop)
    }
    fn prepare(&self, needs: &crate::backend::Needs) -> Result<()> {
        self.inner.prepare(needs)
    }
}
