//! Running a refined sweep: the levels of a [`super::Refiner`] through the
//! sweep pipeline, the refined column's values kept typed, resumable level
//! by level.

use std::collections::{BTreeSet, HashMap};
use std::io::BufRead;
use std::sync::Mutex;
use std::time::Instant;

use super::{RefineSpec, Refiner, Values};
use crate::backend::Backend;
use crate::engine::Status;
use crate::error::InputError;
use crate::output::partial::Partial;
use crate::output::row::Cell;
use crate::output::sidecar::{Level, Refined};
use crate::sweep::pipeline::{self, Hooks, Ids, Picked};
use crate::sweep::session::{self, Options, Summary};
use crate::sweep::Sweep;

/// Run a refined sweep: level after level through the sweep pipeline, each
/// level's rows appended to the partial file (a section in id order); the
/// finished file interleaves the sections in id order. `--resume` reads the
/// rows already there, replays the levels they make (the same ids, since
/// each level follows from the values before it), and goes on from the
/// first missing row.
/// Long (~160 lines) on purpose: the level loop moves the output through
/// `pipeline::stream` and back and shares the closures that record each
/// row's value; the parts around it (`slab`, `earlier_rows`, `finish`) are
/// separate.
pub fn run(
    sweep: &Sweep,
    spec: &RefineSpec,
    opts: &session::Options,
    backend: &dyn Backend,
) -> anyhow::Result<Summary> {
    let dims = sweep.dims();
    let ((lo, hi), region) = slab(sweep, spec, opts.shard)?;
    let header = sweep.header();
    let col = header
        .iter()
        .position(|h| *h == spec.column)
        .expect("checked when the sweep was read");
    // The partial file holds CSV rows (levels as sections) whatever the
    // output's format; a Parquet output is made from them at the end.
    let o = session::open(sweep, opts, lo, true)?;
    let Some(mut out) = o.out else {
        return Ok(Summary {
            already_complete: true,
            ..Default::default()
        });
    };
    let values: Mutex<Values> = Mutex::new(HashMap::new());
    // Ids of the rows whose status is ok (for the sidecar's counts).
    let ok_ids: Mutex<BTreeSet<u64>> = Mutex::new(BTreeSet::new());
    // The column's value (and whether ok) of each row as it is appended.
    let record = |rows: &[Picked]| {
        let mut v = values.lock().unwrap_or_else(|e| e.into_inner());
        let mut ok = ok_ids.lock().unwrap_or_else(|e| e.into_inner());
        for r in rows {
            v.insert(r.id, r.value.clone());
            if r.ok {
                ok.insert(r.id);
            }
        }
    };
    // A row an earlier run wrote (a resumed run): its CSV text read back
    // with the column's type.
    let (status, col_type) = (1 + sweep.axes.len(), sweep.column_types()[col]);
    let record_line = |line: &[u8]| {
        let mut r = csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(line);
        let picked: Vec<Picked> = r
            .records()
            .flatten()
            .filter_map(|rec| {
                Some(Picked {
                    id: rec.get(0)?.parse::<u64>().ok()?,
                    value: Cell::parse(rec.get(col).unwrap_or(""), col_type),
                    ok: rec.get(status) == Some(Status::Ok.name()),
                })
            })
            .collect();
        record(&picked);
    };
    // Rows already in the partial file (a resumed run), in file order.
    let earlier = if out.rows_done > 0 {
        earlier_rows(&opts.out)?
    } else {
        vec![]
    };
    let (wall_before, resumed_from) = (out.wall_before, out.rows_done);
    let resumed = opts
        .resume
        .then_some((out.rows_done, out.dropped_bytes))
        .filter(|&(rows, dropped)| rows > 0 || dropped > 0);
    let mut refiner = Refiner::with_range(&dims, spec.stride, region);
    let mut level = if lo < hi { refiner.start() } else { vec![] };
    let mut stats: Vec<Level> = vec![];
    let mut sections = vec![];
    let (mut ok_run, mut done_run, mut consumed) = (0u64, 0u64, 0usize);
    let mut stages = serde_json::Value::Null;
    let t0 = Instant::now();
    loop {
        // Rows of this level already written by an earlier run.
        let have = (earlier.len() - consumed).min(level.len());
        for (k, (id, line)) in earlier[consumed..consumed + have].iter().enumerate() {
            if *id != level[k] {
                return Err(InputError::Data {
                    path: crate::output::partial::partial_path(&opts.out),
                    what: format!(
                        "cannot resume: row {} has id {id} where refinement level {} computes {}; run without --resume to start over",
                        consumed + k + 1,
                        stats.len(),
                        level[k]
                    ),
                }
                .into());
            }
            record_line(line);
        }
        consumed += have;
        let done_before = (resumed_from + done_run) as usize;
        let total = done_before as u64 + (level.len() - have) as u64;
        opts.progress(done_before as u64, total);
        if have < level.len() {
            let (ok, done, o2, st) = pipeline::stream(
                sweep,
                opts,
                backend,
                Ids::List(&level),
                (have as u64, level.len() as u64),
                out,
                &Hooks {
                    progress: &|end| opts.progress(done_before as u64 + end - have as u64, total),
                    save: &|out| out.save_wall(wall_before + t0.elapsed().as_secs_f64()),
                    column: Some((col, &record)),
                },
            )?;
            out = o2;
            ok_run += ok;
            done_run += done;
            stages = st.json(t0.elapsed().as_secs_f64());
        }
        stats.push(Level {
            stride: refiner.stride(),
            scenes: level.len() as u64,
        });
        sections.push(level.len() as u64);
        let v = values.lock().unwrap_or_else(|e| e.into_inner());
        let next = refiner.next(
            &|id| v.get(&id).cloned().unwrap_or(Cell::Null),
            spec.threshold,
        );
        drop(v);
        match next {
            Some(l) => level = l,
            None => break,
        }
    }
    let wall_s = t0.elapsed().as_secs_f64();
    let ids = (lo, hi);
    let run = Ran {
        sections,
        stats,
        region,
        resumed_from,
        wall_before,
        wall_s,
        stages,
    };
    finish(
        sweep,
        spec,
        opts,
        backend,
        &o.fingerprint,
        out,
        ids,
        run,
        &values,
        &ok_ids,
    )?;
    Ok(Summary {
        scenes: done_run,
        ok: ok_run,
        wall_s,
        already_complete: false,
        backend: String::new(),
        resumed,
    })
}

/// The ids a shard keeps (`lo .. hi`) and the region of the first axis it
/// refines (first and last index). A shard refines a slab of whole coarse
/// steps of the first axis, and one coarse step beyond it on each side, so
/// that every point on its borders is computed exactly when the whole sweep
/// would compute it; it keeps the rows of its own slab (a contiguous id
/// range).
fn slab(
    sweep: &Sweep,
    spec: &RefineSpec,
    shard: Option<(u64, u64)>,
) -> anyhow::Result<((u64, u64), (u64, u64))> {
    let dims = sweep.dims();
    let coarse = Refiner::coarse_first_axis(&dims, spec.stride);
    let steps0 = (coarse.len() - 1) as u64;
    let per_id0: u64 = dims[1..].iter().product();
    Ok(match shard {
        None => ((0, sweep.total), (0, dims[0] - 1)),
        Some((k, n)) => {
            if dims[0] < 2 {
                return Err(InputError::Flag {
                    flag: "--shard".into(),
                    value: "with [refine]".into(),
                    allowed: "a refined sweep is sharded along its first axis, which needs 2 or more values".into(),
                }
                .into());
            }
            let (c0, c1) = ((k - 1) * steps0 / n, k * steps0 / n);
            let lo = coarse[c0 as usize] * per_id0;
            let hi = if c1 == steps0 {
                sweep.total
            } else {
                coarse[c1 as usize] * per_id0
            };
            let region = (
                coarse[c0.saturating_sub(1) as usize],
                coarse[(c1 + 1).min(steps0) as usize],
            );
            ((lo, hi), region)
        }
    })
}

/// The rows of a refined sweep's partial file (the header skipped), with
/// their ids, up to the last whole line.
fn earlier_rows(out: &std::path::Path) -> anyhow::Result<Vec<(u64, Vec<u8>)>> {
    let mut earlier = vec![];
    let partial = crate::output::partial::partial_path(out);
    let mut r = std::io::BufReader::new(std::fs::File::open(&partial)?);
    let mut line = Vec::new();
    r.read_until(b'\n', &mut line)?; // the header
    loop {
        line.clear();
        if r.read_until(b'\n', &mut line)? == 0 || line.last() != Some(&b'\n') {
            break;
        }
        let id = crate::output::row::line_id(&line).unwrap_or(u64::MAX);
        earlier.push((id, line.clone()));
    }
    Ok(earlier)
}

/// What the level loop of a run leaves for its sidecar.
struct Ran {
    /// Rows of each level (the partial file's sections).
    sections: Vec<u64>,
    stats: Vec<Level>,
    region: (u64, u64),
    resumed_from: u64,
    wall_before: f64,
    wall_s: f64,
    stages: serde_json::Value,
}

/// The sidecar of a refined run (its levels, counts of the rows this
/// shard keeps), then the output published.
#[allow(clippy::too_many_arguments)]
fn finish(
    sweep: &Sweep,
    spec: &RefineSpec,
    opts: &Options,
    backend: &dyn Backend,
    fingerprint: &str,
    mut out: Partial,
    (lo, hi): (u64, u64),
    run: Ran,
    values: &Mutex<Values>,
    ok_ids: &Mutex<BTreeSet<u64>>,
) -> anyhow::Result<()> {
    let dims = sweep.dims();
    let computed: u64 = run.sections.iter().sum();
    out.sections = run.sections;
    if opts.shard.is_some() {
        out.keep = Some((lo, hi));
    }
    if opts.parquet {
        out.to_parquet = Some((sweep.arrow_schema(), sweep.column_types()));
    }
    // What the finished file holds: this shard's rows, and how many are ok.
    let rows = values
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .keys()
        .filter(|id| (lo..hi).contains(*id))
        .count() as u64;
    let ok_rows = ok_ids
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .range(lo..hi)
        .count() as u64;
    let refine = Refined {
        column: spec.column.clone(),
        threshold: spec.threshold,
        coarse_stride: spec.stride,
        grid: dims,
        region_first_axis: Some([run.region.0, run.region.1]),
        levels: run.stats,
        scenes_computed: computed,
        fraction_computed: computed as f64 / sweep.total as f64,
    };
    session::finish(
        sweep,
        opts,
        backend,
        fingerprint,
        out,
        session::Counts {
            ids: (lo, hi),
            ok: ok_rows,
            done: rows,
            wall_s: run.wall_before + run.wall_s,
            resumed_from_row: run.resumed_from,
            wall_s_this_run: run.wall_s,
            stages: run.stages,
            refine: Some(refine),
        },
    )
}
