//! A refined table (`[refine]`) as the full grid: every scene that was not
//! computed takes the row of its nearest computed scene (Euclidean distance
//! in grid steps, `sweep::refine::nearest`), with its own id and axis
//! values. `cradle fill` writes it (CSV, from a CSV or Parquet table);
//! `cradle plot` draws it. Computed rows of a CSV are copied byte for byte,
//! so they equal a full sweep's.

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::Path;

use anyhow::Result;

use super::axis::{Value, Values};
use crate::error::InputError;

/// What a refined table's sidecar says of its grid.
pub struct Grid {
    pub dims: Vec<u64>,
    pub axes: Vec<Values>,
}

fn bad(path: &Path, what: impl Into<String>) -> anyhow::Error {
    InputError::Data {
        path: path.to_path_buf(),
        what: what.into(),
    }
    .into()
}

/// The grid of a refined table (from its sidecar), or `None` when the table
/// is not refined.
pub fn grid(table: &Path) -> Result<Option<Grid>> {
    let Some(sc) = crate::output::sidecar::read_checked(table)? else {
        return Ok(None);
    };
    if sc.refine.is_none() {
        return Ok(None);
    }
    let axes = super::axis::from_sidecar(&sc)
        .ok_or_else(|| {
            bad(
                &crate::output::sidecar::path(table),
                "a refined table's sidecar without readable axis values",
            )
        })?
        .into_iter()
        .map(|(_, v)| v)
        .collect::<Vec<_>>();
    let dims = axes.iter().map(|v| v.len() as u64).collect();
    Ok(Some(Grid { dims, axes }))
}

/// Any table as CSV text: a Parquet table as the CSV it stands for (built
/// in memory), a CSV as it is.
pub fn csv_of(table: &Path) -> Result<Box<dyn Read>> {
    if !crate::output::parquet_file::is_parquet(table) {
        return Ok(Box::new(crate::error::open_input(
            table,
            crate::error::MAX_TABLE_BYTES,
        )?));
    }
    // A corrupt file is the input's fault: name it (exit 2), not the
    // Parquet reader's words alone.
    let (header, rows) =
        crate::output::parquet_file::read_text(table).map_err(|e| crate::InputError::Data {
            path: table.to_path_buf(),
            what: format!("not a readable Parquet table ({e:#})"),
        })?;
    let mut bytes = Vec::new();
    for row in std::iter::once(&header).chain(&rows) {
        for (k, f) in row.iter().enumerate() {
            if k > 0 {
                bytes.push(b',');
            }
            crate::output::row::push_csv_field(&mut bytes, f);
        }
        bytes.push(b'\n');
    }
    Ok(Box::new(std::io::Cursor::new(bytes)))
}

/// A table to read whole, as CSV text: a refined one filled to its grid
/// (built in memory), any other as [`csv_of`].
pub fn full_csv(table: &Path) -> Result<Box<dyn Read>> {
    match grid(table)? {
        Some(g) => {
            let mut bytes = Vec::new();
            fill(table, &g, &mut |row| {
                bytes.extend_from_slice(row);
                Ok(())
            })?;
            Ok(Box::new(std::io::Cursor::new(bytes)))
        }
        None => csv_of(table),
    }
}

/// Every row of the full grid, in id order, to `out` (header first):
/// computed rows as they are, the others filled from their nearest.
pub fn fill(table: &Path, g: &Grid, out: &mut dyn FnMut(&[u8]) -> Result<()>) -> Result<u64> {
    // A Parquet table is read as the CSV's text (a refined table is small).
    let source = csv_of(table)?;
    let mut r = BufReader::new(source);
    let mut header = Vec::new();
    r.read_until(b'\n', &mut header)?;
    out(&header)?;
    let mut rows: HashMap<u64, Vec<u8>> = HashMap::new();
    let mut line = Vec::new();
    let total: u64 = g.dims.iter().product();
    loop {
        line.clear();
        if r.read_until(b'\n', &mut line)? == 0 {
            break;
        }
        let id: u64 = crate::output::row::line_id(&line)
            .filter(|&id| id < total)
            .ok_or_else(|| {
                bad(
                    table,
                    format!("a row without a valid id (grid of {total} scenes)"),
                )
            })?;
        rows.insert(id, line.clone());
    }
    if rows.is_empty() {
        return Err(bad(table, "has no rows"));
    }
    let sites: Vec<u64> = rows.keys().copied().collect();
    let near = super::refine::nearest(&g.dims, &sites);
    let mut steps = vec![1u64; g.dims.len()];
    for k in (0..g.dims.len().saturating_sub(1)).rev() {
        steps[k] = steps[k + 1] * g.dims[k + 1];
    }
    // The outcome fields of each computed row (after id and axes), once.
    let mut tails: HashMap<u64, Vec<u8>> = HashMap::with_capacity(rows.len());
    for (&id, row) in &rows {
        let mut rd = csv::ReaderBuilder::new()
            .has_headers(false)
            .from_reader(&row[..]);
        let rec = rd
            .records()
            .next()
            .and_then(|r| r.ok())
            .ok_or_else(|| bad(table, format!("row {id} cannot be read")))?;
        let mut tail = Vec::new();
        for f in rec.iter().skip(1 + g.axes.len()) {
            tail.push(b',');
            crate::output::row::push_csv_field(&mut tail, f);
        }
        tail.push(b'\n');
        tails.insert(id, tail);
    }
    let (mut buf, mut s) = (Vec::new(), String::new());
    for id in 0..total {
        if let Some(row) = rows.get(&id) {
            out(row)?;
            continue;
        }
        buf.clear();
        let _ = write!(buf, "{id}");
        for (k, a) in g.axes.iter().enumerate() {
            buf.push(b',');
            let i = ((id / steps[k]) % g.dims[k]) as usize;
            match a.get(i) {
                Value::Num(x) => {
                    crate::output::row::num_into(x, &mut s);
                    buf.extend_from_slice(s.as_bytes());
                }
                Value::Text(t) => crate::output::row::push_csv_field(&mut buf, &t),
            }
        }
        buf.extend_from_slice(&tails[&near[id as usize]]);
        out(&buf)?;
    }
    Ok(total)
}
