//! `cradle merge`: join shard CSVs (or Parquet files) into one. CSV rows are
//! copied byte for byte, Parquet row groups still encoded, so the merge of a
//! sweep's shards holds the unsharded run's rows.
//!
//! Nothing is taken on trust: every part must have its sidecar (`FILE.json`,
//! written when the part completed), and the sidecars must agree on the sweep
//! and the solver settings (their fingerprints, less the shard). A part must
//! hold exactly the ids its sidecar names, and the parts together every id of
//! the sweep once. The merged file gets a sidecar of its own, whose
//! fingerprint is the unsharded run's: `cradle sweep --resume` onto it
//! recognises it as complete.

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::session::Fingerprint;
use crate::error::InputError;
use crate::output::parquet_file::{is_parquet, PartFile};
use crate::output::partial::partial_path;
use crate::output::publish::write_atomic;
use crate::output::sidecar::{Level, Sidecar};
use crate::output::TableKind;

fn bad(path: &Path, what: impl Into<String>) -> anyhow::Error {
    InputError::Data {
        path: path.to_path_buf(),
        what: what.into(),
    }
    .into()
}

/// One part: its file, its sidecar, the id range the sidecar names.
struct Part {
    path: PathBuf,
    sidecar: Sidecar,
    ids: (u64, u64),
}

impl Part {
    /// A shard of a refined sweep: it holds some of its ids, not all.
    fn sparse(&self) -> bool {
        self.sidecar.refine.is_some()
    }

    /// Its fingerprint less the shard: what every part must share.
    fn sweep_key(&self) -> Option<Fingerprint> {
        Fingerprint::decode(&self.sidecar.fingerprint).map(|f| f.without_shard())
    }
}

fn read_part(p: &Path) -> Result<Part> {
    let sc = crate::output::sidecar::path(p);
    let sidecar = match crate::output::sidecar::read_checked(p) {
        Ok(Some(s)) => s,
        Ok(None) => {
            return Err(bad(
                p,
                format!(
                    "its sidecar {} cannot be read (no such file): merge needs it to know the sweep and the ids this part holds; run the shard again (with --resume if it was interrupted)",
                    sc.display()
                ),
            ))
        }
        // A trace is no shard: running it again would not help.
        Err(InputError::Data { path, what }) if path == p => return Err(bad(&path, what)),
        Err(InputError::Data { path, what }) => {
            return Err(bad(&path, format!("{what}; run the shard again")))
        }
        Err(e) => return Err(e.into()),
    };
    let [lo, hi] = sidecar.ids;
    if lo > hi {
        return Err(bad(&sc, "no valid `ids` range; run the shard again"));
    }
    Ok(Part {
        path: p.to_path_buf(),
        sidecar,
        ids: (lo, hi),
    })
}

/// Merge `inputs` into `out`; returns the number of rows.
/// Long (~130 lines) on purpose: one pass of checks (every part's seal,
/// fingerprint and id range, named in its error) and then one copy, in the
/// order a reader follows a merge.
pub fn merge(inputs: &[PathBuf], out: &Path) -> Result<u64> {
    let Some(first) = inputs.first() else {
        return Err(InputError::Flag {
            flag: "merge".into(),
            value: "(no files)".into(),
            allowed: "one or more shard CSVs".into(),
        }
        .into());
    };
    let mut parts = inputs
        .iter()
        .map(|p| read_part(p))
        .collect::<Result<Vec<_>>>()?;
    let formats = parts
        .iter()
        .map(|p| is_parquet(&p.path))
        .collect::<Vec<_>>();
    if let Some(k) = formats.iter().position(|&q| q != formats[0]) {
        return Err(bad(
            &parts[k].path,
            format!(
                "is {} but {} is {}: merge parts of one format",
                if formats[k] { "Parquet" } else { "CSV" },
                parts[0].path.display(),
                if formats[0] { "Parquet" } else { "CSV" },
            ),
        ));
    }
    let want = if formats[0] {
        TableKind::Parquet
    } else {
        TableKind::Csv
    };
    if TableKind::from_extension(out) != Some(want) {
        return Err(InputError::Flag {
            flag: "--out".into(),
            value: out.display().to_string(),
            allowed: format!(
                "a name ending in {}: the parts are {}",
                if formats[0] { ".parquet" } else { ".csv" },
                if formats[0] { "Parquet" } else { "CSV" }
            ),
        }
        .into());
    }
    let parquet = formats[0];
    let Some(key0) = parts[0].sweep_key() else {
        return Err(bad(
            first,
            "its sidecar has no readable fingerprint (made by an older cradle?); run the shard again",
        ));
    };
    let total = parts[0].sidecar.total_scenes;
    for p in &parts[1..] {
        if p.sweep_key().as_ref() != Some(&key0) {
            return Err(bad(
                &p.path,
                format!(
                    "made by a different sweep or solver settings than {} (their sidecars' fingerprints differ): merge only shards of one `cradle sweep` command",
                    first.display()
                ),
            ));
        }
    }
    // Each part holds one contiguous id range; together they must tile 0..total.
    parts.sort_by_key(|p| p.ids);
    let mut next = 0u64;
    for p in &parts {
        if p.ids.0 > next {
            return Err(bad(
                &p.path,
                format!(
                    "ids {next} ..= {} are missing: in no part (this one starts at {}); the sweep has {total} scenes: add the missing shard",
                    p.ids.0 - 1,
                    p.ids.0
                ),
            ));
        }
        if p.ids.0 < next {
            return Err(bad(
                &p.path,
                format!(
                    "ids {} .. {} appear more than once (again in this part): give each shard once",
                    p.ids.0,
                    next.min(p.ids.1)
                ),
            ));
        }
        next = p.ids.1;
    }
    if next != total {
        return Err(bad(
            &parts[parts.len() - 1].path,
            format!(
                "ids {next} ..= {} are missing: in no part, and the sweep has {total} scenes; add the missing shard",
                total - 1
            ),
        ));
    }

    let tmp = partial_path(out);
    let r = if parquet {
        let files = parts
            .iter()
            .map(|p| PartFile {
                path: &p.path,
                ids: p.ids,
                sparse: p.sparse(),
            })
            .collect::<Vec<_>>();
        crate::output::parquet_file::merge(&files, &tmp, &|p, what| bad(p, what))
    } else {
        copy_rows(&parts, &tmp)
    };
    if r.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    let n = r?;

    let mut sc = merged_sidecar(&parts, &key0, total, n);
    sc.table = Some(crate::output::sidecar::seal(&tmp, n)?);
    write_atomic(
        &crate::output::sidecar::path(out),
        crate::output::sidecar::text(&sc)?.as_bytes(),
    )?;
    crate::output::publish::publish(&tmp, out)?;
    Ok(n)
}

/// Copy every part's rows to `tmp` after one header, checking each part holds
/// exactly its ids; returns the row count.
fn copy_rows(parts: &[Part], tmp: &Path) -> Result<u64> {
    let mut w = BufWriter::new(
        File::create(tmp).with_context(|| format!("cannot create {}", tmp.display()))?,
    );
    let mut header: Option<Vec<u8>> = None;
    let mut line = Vec::new();
    let mut n = 0;
    for p in parts {
        let mut r = BufReader::new(crate::error::open_input(
            &p.path,
            crate::error::MAX_TABLE_BYTES,
        )?);
        line.clear();
        r.read_until(b'\n', &mut line)?;
        match &header {
            None => {
                w.write_all(&line)?;
                header = Some(line.clone());
            }
            Some(h) if *h != line => {
                return Err(bad(
                    &p.path,
                    format!("its header differs from {}'s", parts[0].path.display()),
                ))
            }
            _ => {}
        }
        let mut next = p.ids.0;
        loop {
            line.clear();
            if r.read_until(b'\n', &mut line)? == 0 {
                break;
            }
            if line.last() != Some(&b'\n') {
                return Err(bad(
                    &p.path,
                    "its last row is incomplete (an interrupted run? finish it with --resume)",
                ));
            }
            let id = crate::output::row::line_id(&line)
                .ok_or_else(|| bad(&p.path, "a row without an id"))?;
            if p.sparse() && id >= next && id < p.ids.1 {
                next = id;
            }
            if id != next || id >= p.ids.1 {
                return Err(bad(
                    &p.path,
                    format!(
                        "row with id {id} where its sidecar's range {} .. {} expects {next}: the file was changed after it was written; run the shard again",
                        p.ids.0, p.ids.1
                    ),
                ));
            }
            w.write_all(&line)
                .with_context(|| format!("cannot write {}", tmp.display()))?;
            next += 1;
            n += 1;
        }
        if next != p.ids.1 && !p.sparse() {
            return Err(bad(
                &p.path,
                format!(
                    "holds ids {} .. {next} but its sidecar says {} .. {}: the file was cut short after it was written; run the shard again",
                    p.ids.0, p.ids.0, p.ids.1
                ),
            ));
        }
    }
    w.flush()
        .and_then(|_| w.get_ref().sync_all())
        .with_context(|| format!("cannot write {}", tmp.display()))?;
    Ok(n)
}

/// The merged table's sidecar: the first part's, with the parts' counts and
/// times added up, the whole id range, no shard, the unsharded run's
/// fingerprint, and a refinement's levels summed over the parts.
fn merged_sidecar(parts: &[Part], key: &Fingerprint, total: u64, n: u64) -> Sidecar {
    let mut sc = parts[0].sidecar.clone();
    let sum = |f: fn(&Sidecar) -> f64| parts.iter().map(|p| f(&p.sidecar)).sum::<f64>();
    let wall_s = sum(|s| s.wall_s);
    sc.command = std::env::args().collect();
    sc.ids = [0, total];
    sc.shard = None;
    sc.scenes_ok = parts.iter().map(|p| p.sidecar.scenes_ok).sum();
    sc.scenes_not_ok = parts.iter().map(|p| p.sidecar.scenes_not_ok).sum();
    sc.wall_s = wall_s;
    sc.scenes_per_s = n as f64 / wall_s.max(1e-9);
    sc.fingerprint = key.encode();
    sc.merged_from = Some(parts.iter().map(|p| p.path.display().to_string()).collect());
    sc.resumed_from_row = None;
    sc.wall_s_this_run = None;
    sc.stages_s = None;
    if let Some(r) = &mut sc.refine {
        // The parts' levels added up (the same strides in every part).
        let mut levels: Vec<Level> = vec![];
        for p in parts {
            let ls = p.sidecar.refine.as_ref().map_or(&[][..], |r| &r.levels[..]);
            for (k, l) in ls.iter().enumerate() {
                match levels.get_mut(k) {
                    Some(e) => e.scenes += l.scenes,
                    None => levels.push(*l),
                }
            }
        }
        r.levels = levels;
        r.scenes_computed = n;
        r.fraction_computed = n as f64 / total as f64;
        r.region_first_axis = None;
    }
    sc
}
