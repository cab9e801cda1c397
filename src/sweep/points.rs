//! `[points] file = "params.csv"`: one scene per row of a table whose header
//! names the params (the names `[[axis]]` takes: `mass[2]`, `gap`, `glue`,
//! …). Scene id = the row's index from 0. Every cell is checked before any
//! work, and a bad table gets the errors a bad TOML gets: the file, the
//! line, the column, the value and what is allowed.

use std::path::Path;

use super::axis::{self, Kind, Param, Value, Values};
use super::Axis;
use crate::error::InputError;
use crate::scene::{Scene, SceneSpec};

fn invalid(path: &Path, line: u64, key: &str, value: String, allowed: String) -> InputError {
    InputError::Invalid {
        origin: path.display().to_string(),
        line: Some(line as usize),
        key: key.to_string(),
        value,
        allowed,
    }
}

/// The columns of `path` as axes of a point list (each `Values::List`).
pub fn read(path: &Path, spec: &SceneSpec, base: &Scene) -> Result<Vec<Axis>, InputError> {
    let file = crate::error::open_input(path, crate::error::MAX_TABLE_BYTES)?;
    let mut r = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_reader(file);
    let (header, params) = header_params(path, &mut r)?;
    let mut cols: Vec<Vec<Value>> = vec![vec![]; header.len()];
    for rec in r.records() {
        let rec = rec.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line());
            invalid(
                path,
                line,
                "row",
                String::new(),
                format!(
                    "{} fields, one per column of the header ({e})",
                    header.len()
                ),
            )
        })?;
        let line = rec.position().map_or(0, |p| p.line());
        if cols[0].len() >= axis::MAX_AXIS_VALUES {
            return Err(invalid(
                path,
                line,
                "row",
                format!("more than {} rows", axis::MAX_AXIS_VALUES),
                format!("at most {} scenes", axis::MAX_AXIS_VALUES),
            ));
        }
        let row = row_values(path, line, &rec, &header, &params)?;
        check_row(path, line, spec, base, (&header, &params), &row)?;
        for (c, v) in cols.iter_mut().zip(row) {
            c.push(v);
        }
    }
    if cols[0].is_empty() {
        return Err(invalid(
            path,
            2,
            "row",
            "(none)".into(),
            "at least one row after the header: one scene per row".into(),
        ));
    }
    Ok(header
        .into_iter()
        .zip(params)
        .zip(cols)
        .map(|((name, param), values)| Axis {
            name,
            param,
            values: Values::List(values),
            line: None,
        })
        .collect())
}

/// The header's names and the params they parse to (each quantity once).
fn header_params<R: std::io::Read>(
    path: &Path,
    r: &mut csv::Reader<R>,
) -> Result<(Vec<String>, Vec<Param>), InputError> {
    let header: Vec<String> = r
        .headers()
        .map_err(|e| {
            invalid(
                path,
                1,
                "header",
                String::new(),
                format!("a CSV header ({e})"),
            )
        })?
        .iter()
        .map(str::to_string)
        .collect();
    if header.iter().all(|h| h.is_empty()) {
        return Err(invalid(
            path,
            1,
            "header",
            "(empty)".into(),
            "a header naming the params, e.g. `mass[2],gap`, then one row per scene".into(),
        ));
    }
    let mut params: Vec<Param> = vec![];
    for (k, h) in header.iter().enumerate() {
        let p = Param::parse(h).map_err(|allowed| {
            invalid(
                path,
                1,
                &format!("column {}", k + 1),
                format!("{h:?}"),
                allowed,
            )
        })?;
        if let Some(j) = params.iter().position(|q| q.overlaps(&p)) {
            return Err(invalid(
                path,
                1,
                h,
                format!("column {}", k + 1),
                format!(
                    "sets what column {} ({:?}) already sets: each scene quantity may have one column",
                    j + 1,
                    header[j]
                ),
            ));
        }
        params.push(p);
    }
    Ok((header, params))
}

/// One row's values, each checked against its column's kind.
fn row_values(
    path: &Path,
    line: u64,
    rec: &csv::StringRecord,
    header: &[String],
    params: &[Param],
) -> Result<Vec<Value>, InputError> {
    let mut row = Vec::with_capacity(header.len());
    for (k, cell) in rec.iter().enumerate() {
        let p = &params[k];
        let v = if p.kind == Kind::Glue {
            Value::Text(cell.to_string())
        } else {
            let x: f64 = cell
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
                .ok_or_else(|| {
                    invalid(
                        path,
                        line,
                        &header[k],
                        format!("{cell:?}"),
                        "a finite number".into(),
                    )
                })?;
            if p.kind == Kind::Integer && x.fract() != 0.0 {
                return Err(invalid(
                    path,
                    line,
                    &header[k],
                    cell.to_string(),
                    "a whole number: this parameter is an integer".into(),
                ));
            }
            Value::Num(x)
        };
        row.push(v);
    }
    Ok(row)
}

/// The row must make a valid scene; name the column that breaks it (the
/// first one that is invalid on its own), else all of them.
fn check_row(
    path: &Path,
    line: u64,
    spec: &SceneSpec,
    base: &Scene,
    (header, params): (&[String], &[Param]),
    row: &[Value],
) -> Result<(), InputError> {
    let mut s = spec.clone();
    for (p, v) in params.iter().zip(row) {
        axis::apply(&mut s, base, p, v);
    }
    let n = s.balls.map_or(base.n, |b| b as usize);
    for (k, p) in params.iter().enumerate() {
        if let Err(allowed) = p.check_index(n, spec) {
            return Err(invalid(
                path,
                line,
                &header[k],
                format!("index {}", p.index.unwrap_or(0)),
                allowed,
            ));
        }
    }
    // A row must make the same kind of scene as the base (an axis or a
    // sample value that turns a cradle into a chain is refused the same way).
    let e = match s.validate() {
        Ok(scene) if crate::model::kind(&scene) == crate::model::kind(base) => return Ok(()),
        Ok(_) => {
            let k = params
                .iter()
                .zip(row)
                .position(|(p, v)| {
                    let mut one = spec.clone();
                    axis::apply(&mut one, base, p, v);
                    one.validate()
                        .is_ok_and(|o| crate::model::kind(&o) != crate::model::kind(base))
                })
                .unwrap_or(0);
            return Err(invalid(
                path,
                line,
                &header[k],
                row[k].to_string(),
                crate::model::mixed_sweep(base),
            ));
        }
        Err(e) => e,
    };
    let alone = params.iter().zip(row).position(|(p, v)| {
        let mut one = spec.clone();
        axis::apply(&mut one, base, p, v);
        one.validate().is_err()
    });
    let (key, value) = match alone {
        Some(k) => (header[k].clone(), row[k].to_string()),
        None => (
            header.join(","),
            row.iter()
                .map(|v| v.to_string())
                .collect::<Vec<_>>()
                .join(","),
        ),
    };
    Err(invalid(
        path,
        line,
        &key,
        value,
        format!("makes an invalid scene: {e}"),
    ))
}
