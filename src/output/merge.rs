//! `cradle merge`: join shard CSVs into one, refusing any missing or repeated id.
//! Rows are copied byte for byte, so the merge of a sweep's shards equals the
//! unsharded run's file.

use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use super::partial::partial_path;

fn first_id(line: &[u8]) -> Option<u64> {
    let end = line.iter().position(|&b| b == b',').unwrap_or(line.len());
    std::str::from_utf8(&line[..end]).ok()?.trim().parse().ok()
}

/// Total scene count recorded in a CSV's sidecar, if there is one.
fn sidecar_total(csv: &Path) -> Option<u64> {
    let text = std::fs::read_to_string(super::sidecar::path(csv)).ok()?;
    serde_json::from_str::<serde_json::Value>(&text)
        .ok()?
        .get("total_scenes")?
        .as_u64()
}

/// Merge `inputs` into `out`; returns the number of rows.
pub fn merge(inputs: &[PathBuf], out: &Path) -> Result<u64> {
    if inputs.is_empty() {
        bail!("nothing to merge");
    }
    // Order the files by their first id; each holds a contiguous id range.
    let mut files = Vec::new();
    let mut header: Option<Vec<u8>> = None;
    let mut total = None;
    for p in inputs {
        let mut r =
            BufReader::new(File::open(p).with_context(|| format!("cannot read {}", p.display()))?);
        let mut h = Vec::new();
        r.read_until(b'\n', &mut h)?;
        match &header {
            None => header = Some(h.clone()),
            Some(h0) if *h0 != h => bail!(
                "{}: its header differs from {}",
                p.display(),
                inputs[0].display()
            ),
            _ => {}
        }
        let mut first = Vec::new();
        r.read_until(b'\n', &mut first)?;
        let id = if first.is_empty() {
            u64::MAX
        } else {
            first_id(&first).with_context(|| format!("{}: no id in its first row", p.display()))?
        };
        if let Some(t) = sidecar_total(p) {
            if total.is_some_and(|t0| t0 != t) {
                bail!(
                    "{}: from a sweep of {t} scenes, the others from {}",
                    p.display(),
                    total.unwrap()
                );
            }
            total = Some(t);
        }
        files.push((id, p.clone()));
    }
    files.sort();
    let header = header.unwrap();
    let tmp = partial_path(out);
    let mut w = BufWriter::new(
        File::create(&tmp).with_context(|| format!("cannot create {}", tmp.display()))?,
    );
    w.write_all(&header)?;
    let mut next = 0u64;
    let mut line = Vec::new();
    for (_, p) in &files {
        let mut r = BufReader::new(File::open(p)?);
        line.clear();
        r.read_until(b'\n', &mut line)?;
        loop {
            line.clear();
            if r.read_until(b'\n', &mut line)? == 0 {
                break;
            }
            if line.last() != Some(&b'\n') {
                bail!(
                    "{}: its last row is incomplete (an interrupted run? finish it with --resume)",
                    p.display()
                );
            }
            let id =
                first_id(&line).with_context(|| format!("{}: a row without an id", p.display()))?;
            if id != next {
                let _ = std::fs::remove_file(&tmp);
                if id < next {
                    bail!("id {id} appears more than once (again in {})", p.display());
                }
                bail!(
                    "ids {next} ..= {} are missing (next found: {id} in {})",
                    id - 1,
                    p.display()
                );
            }
            w.write_all(&line)?;
            next += 1;
        }
    }
    if let Some(t) = total {
        if next != t {
            let _ = std::fs::remove_file(&tmp);
            bail!(
                "ids {next} ..= {} are missing: the sweep has {t} scenes",
                t - 1
            );
        }
    }
    w.flush()?;
    drop(w);
    std::fs::rename(&tmp, out)?;
    Ok(next)
}
