//! Running a sweep: a refined sweep goes to `refine.rs`; any other streams
//! its id range through the pipeline (`pipeline.rs`: ids → jobs → backend →
//! rows in id order) between the output's opening and its publication
//! (`session.rs`).

use std::time::Instant;

use anyhow::Result;

use super::session::{self, Counts, Options, Summary};
use super::{pipeline, Sweep};
use crate::backend::Backend;

/// Run `sweep` on `backend` as `opts` say. With `opts.threads` unset this
/// runs on the current rayon pool.
pub fn run(sweep: &Sweep, opts: &Options, backend: &dyn Backend) -> Result<Summary> {
    // Every pipeline the scenes can use, built before any output is opened.
    backend.prepare(&sweep.needs(&opts.overrides)?)?;
    if let Some(spec) = &sweep.refine {
        return super::refine::run(sweep, spec, opts, backend);
    }
    let (lo, hi) = sweep.shard_range(opts.shard, &opts.overrides);
    let o = session::open(sweep, opts, lo, false)?;
    let Some(out) = o.out else {
        return Ok(Summary {
            already_complete: true,
            ..Default::default()
        });
    };
    let start_id = lo + out.rows_done;
    let resumed = opts
        .resume
        .then_some((out.rows_done, out.dropped_bytes))
        .filter(|&(rows, dropped)| rows > 0 || dropped > 0);
    let (ok_before, wall_before) = (out.ok_done, out.wall_before);
    opts.progress(out.rows_done, hi - lo);
    let t0 = Instant::now();
    let (ok, done, out, stages) = pipeline::stream(
        sweep,
        opts,
        backend,
        pipeline::Ids::All,
        (start_id, hi),
        out,
        &pipeline::Hooks {
            progress: &|rows_end| opts.progress(rows_end - lo, hi - lo),
            save: &|out| out.save_wall(wall_before + t0.elapsed().as_secs_f64()),
            column: None,
        },
    )?;
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
    session::finish(sweep, opts, backend, &o.fingerprint, out, counts)?;
    Ok(Summary {
        scenes: done,
        ok,
        wall_s,
        already_complete: false,
        backend: String::new(),
        resumed,
    })
}
