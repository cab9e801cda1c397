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
use serde_json::Value;

use super::parquet_file::{is_parquet, PartFile};
use super::partial::partial_path;
use super::publish::write_atomic;
use super::TableKind;
use crate::error::InputError;

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
    sidecar: Value,
    ids: (u64, u64),
}

impl Part {
    /// A shard of a refined sweep: it holds some of its ids, not all.
    fn sparse(&self) -> bool {
        self.sidecar.get("refine").is_some()
    }
}

/// The fingerprint with its shard removed: what every part must share.
fn sweep_key(fingerprint: &str) -> Option<Value> {
    let mut v: Value = serde_json::from_str(fingerprint).ok()?;
    v.as_object_mut()?.insert("shard".into(), Value::Null);
    Some(v)
}

fn read_part(p: &Path) -> Result<Part> {
    let sc = super::sidecar::path(p);
    let text = std::fs::read_to_string(&sc).map_err(|e| {
        bad(
            p,
            format!(
                "its sidecar {} cannot be read ({e}): merge needs it to know the sweep and the ids this part holds; run the shard again (with --resume if it was interrupted)",
                sc.display()
            ),
        )
    })?;
    let sidecar: Value = serde_json::from_str(&text).map_err(|e| {
        bad(
            &sc,
            format!("not a cradle sidecar ({e}); run the shard again"),
        )
    })?;
    let ids = sidecar
        .get("ids")
        .and_then(|v| Some((v.get(0)?.as_u64()?, v.get(1)?.as_u64()?)))
        .filter(|(lo, hi)| lo <= hi);
    let Some(ids) = ids else {
        return Err(bad(&sc, "no valid `ids` range; run the shard again"));
    };
    Ok(Part {
        path: p.to_path_buf(),
        sidecar,
        ids,
    })
}

/// Merge `inputs` into `out`; returns the number of rows.
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
    if TableKind::resolve(None, out) != want {
        return Err(InputError::Flag {
            flag: "--out".into(),
            value: out.display().to_string(),
            allowed: format!(
                "a name ending in {}: the parts are {}",
                if formats[0] {
                    ".parquet"
                } else {
                    ".csv (or any name not ending in .parquet)"
                },
                if formats[0] { "Parquet" } else { "CSV" }
            ),
        }
        .into());
    }
    let parquet = formats[0];
    let fp = |p: &Part| {
        p.sidecar
            .get("fingerprint")
            .and_then(|f| f.as_str())
            .and_then(sweep_key)
    };
    let key0 = fp(&parts[0]);
    let total = parts[0]
        .sidecar
        .get("total_scenes")
        .and_then(|t| t.as_u64());
    let (Some(key0), Some(total)) = (key0, total) else {
        return Err(bad(
            first,
            "its sidecar has no fingerprint or scene count (made by an older cradle?); run the shard again",
        ));
    };
    for p in &parts[1..] {
        if fp(p).as_ref() != Some(&key0) {
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
        super::parquet_file::merge(&files, &tmp, &|p, what| bad(p, what))
    } else {
        copy_rows(&parts, &tmp)
    };
    if r.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    let n = r?;

    let mut sc = parts[0].sidecar.clone();
    let sum = |k: &str| -> f64 {
        parts
            .iter()
            .filter_map(|p| p.sidecar.get(k)?.as_f64())
            .sum()
    };
    let obj = sc.as_object_mut().expect("checked: a JSON object");
    obj.insert(
        "command".into(),
        std::env::args().collect::<Vec<_>>().into(),
    );
    obj.insert("ids".into(), serde_json::json!([0, total]));
    obj.insert("shard".into(), Value::Null);
    obj.insert("scenes_ok".into(), (sum("scenes_ok") as u64).into());
    obj.insert("scenes_not_ok".into(), (sum("scenes_not_ok") as u64).into());
    obj.insert("wall_s".into(), sum("wall_s").into());
    obj.insert(
        "scenes_per_s".into(),
        (n as f64 / sum("wall_s").max(1e-9)).into(),
    );
    obj.insert("fingerprint".into(), serde_json::to_string(&key0)?.into());
    obj.insert(
        "merged_from".into(),
        parts
            .iter()
            .map(|p| p.path.display().to_string())
            .collect::<Vec<_>>()
            .into(),
    );
    for k in ["resumed_from_row", "wall_s_this_run", "stages_s"] {
        obj.remove(k);
    }
    if let Some(r) = obj.get_mut("refine").and_then(|r| r.as_object_mut()) {
        // The parts' levels added up (the same strides in every part).
        let mut levels: Vec<(u64, u64)> = vec![];
        for p in &parts {
            let ls = p.sidecar["refine"]["levels"]
                .as_array()
                .cloned()
                .unwrap_or_default();
            for (k, l) in ls.iter().enumerate() {
                let (stride, scenes) = (
                    l["stride"].as_u64().unwrap_or(0),
                    l["scenes"].as_u64().unwrap_or(0),
                );
                match levels.get_mut(k) {
                    Some(e) => e.1 += scenes,
                    None => levels.push((stride, scenes)),
                }
            }
        }
        r.insert(
            "levels".into(),
            levels
                .iter()
                .map(|(s, n)| serde_json::json!({"stride": s, "scenes": n}))
                .collect::<Vec<_>>()
                .into(),
        );
        r.insert("scenes_computed".into(), n.into());
        r.insert("fraction_computed".into(), (n as f64 / total as f64).into());
        r.remove("region_first_axis");
    }
    write_atomic(
        &super::sidecar::path(out),
        (serde_json::to_string_pretty(&sc)? + "\n").as_bytes(),
    )?;
    super::publish::publish(&tmp, out)?;
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
        let mut r = BufReader::new(
            File::open(&p.path).with_context(|| format!("cannot read {}", p.path.display()))?,
        );
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
            let id =
                super::row::line_id(&line).ok_or_else(|| bad(&p.path, "a row without an id"))?;
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
