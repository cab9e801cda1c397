//! A table (CSV or Parquet) read for plotting: named columns of numbers
//! (empty → NaN).

use std::path::{Path, PathBuf};

use crate::error::{closest, InputError};

pub struct Table {
    pub path: PathBuf,
    pub header: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

fn data_err(path: &Path, what: impl Into<String>) -> InputError {
    InputError::Data {
        path: path.to_path_buf(),
        what: what.into(),
    }
}

impl Table {
    pub fn read(path: &Path) -> Result<Table, InputError> {
        // A refined sweep's table is drawn as the full grid (`sweep::fill`),
        // a Parquet table read as the CSV's text.
        Self::read_from(path, crate::sweep::fill::full_csv(path))
    }

    /// A trace (CSV or Parquet) as it is: its sidecar is the trace's, not a
    /// sweep's.
    pub fn read_trace(path: &Path) -> Result<Table, InputError> {
        Self::read_from(path, crate::sweep::fill::csv_of(path))
    }

    fn read_from(
        path: &Path,
        source: anyhow::Result<Box<dyn std::io::Read>>,
    ) -> Result<Table, InputError> {
        let source = source.map_err(|e| {
            let e = match e.downcast::<InputError>() {
                Ok(input) => return input,
                Err(e) => e,
            };
            match e.downcast::<std::io::Error>() {
                Ok(error) => InputError::Read {
                    path: path.to_path_buf(),
                    error,
                },
                Err(e) => data_err(path, format!("cannot read the table: {e:#}")),
            }
        })?;
        let mut r = csv::ReaderBuilder::new()
            .flexible(false)
            .from_reader(source);
        let header: Vec<String> = r
            .headers()
            .map_err(|e| data_err(path, format!("not a CSV table: {e}")))?
            .iter()
            .map(str::to_string)
            .collect();
        let mut rows = vec![];
        for rec in r.records() {
            let rec = rec.map_err(|e| data_err(path, format!("not a CSV table: {e}")))?;
            rows.push(rec.iter().map(str::to_string).collect());
        }
        if rows.is_empty() {
            return Err(data_err(path, "has no rows"));
        }
        Ok(Table {
            path: path.to_path_buf(),
            header,
            rows,
        })
    }

    /// Index of column `name`; an unknown name is an error for `flag` that
    /// lists the columns and suggests the closest.
    pub fn col(&self, flag: &str, name: &str) -> Result<usize, InputError> {
        self.header.iter().position(|h| h == name).ok_or_else(|| {
            let near = closest(name, self.header.iter().map(String::as_str));
            InputError::Flag {
                flag: flag.into(),
                value: name.into(),
                allowed: format!(
                    "not a column of {}{} (columns: {})",
                    self.path.display(),
                    near.map_or(String::new(), |n| format!(" — did you mean `{n}`?")),
                    self.header.join(", ")
                ),
            }
        })
    }

    /// Column `i` as numbers (empty cells → NaN); text is an error.
    pub fn numbers(&self, i: usize) -> Result<Vec<f64>, InputError> {
        self.rows
            .iter()
            .enumerate()
            .map(|(r, row)| {
                let s = row[i].trim();
                if s.is_empty() {
                    Ok(f64::NAN)
                } else {
                    s.parse().map_err(|_| {
                        data_err(
                            &self.path,
                            format!(
                                "column `{}` row {}: {s:?} is not a number",
                                self.header[i],
                                r + 2
                            ),
                        )
                    })
                }
            })
            .collect()
    }

    /// Keep the rows where every `COL=VALUE` of `conds` holds (numbers
    /// compare as numbers, anything else as text).
    pub fn filter(&mut self, conds: &[String]) -> Result<(), InputError> {
        for c in conds {
            let (k, v) = c.split_once('=').ok_or_else(|| InputError::Flag {
                flag: "--where".into(),
                value: c.clone(),
                allowed: "COL=VALUE, e.g. --where balls=5".into(),
            })?;
            let i = self.col("--where", k.trim())?;
            let v = v.trim();
            let num: Option<f64> = v.parse().ok();
            self.rows
                .retain(|row| match (num, row[i].trim().parse::<f64>()) {
                    (Some(a), Ok(b)) => a == b || (a - b).abs() <= 1e-12 * a.abs().max(b.abs()),
                    _ => row[i].trim() == v,
                });
            if self.rows.is_empty() {
                return Err(data_err(
                    &self.path,
                    format!("no row has {k} = {v} (--where {c})"),
                ));
            }
        }
        Ok(())
    }
}

/// Sorted distinct finite values.
pub fn distinct(xs: &[f64]) -> Vec<f64> {
    let mut u: Vec<f64> = xs.iter().copied().filter(|x| x.is_finite()).collect();
    u.sort_by(|a, b| a.total_cmp(b));
    u.dedup();
    u
}

/// Whether sorted distinct values are log-spaced: at least three, all
/// positive, with a constant ratio (and not a constant difference).
pub fn log_spaced(u: &[f64]) -> bool {
    if u.len() < 3 || u[0] <= 0.0 {
        return false;
    }
    let r0 = u[1] / u[0];
    let d0 = u[1] - u[0];
    let ratio = u.windows(2).all(|w| (w[1] / w[0] / r0 - 1.0).abs() < 1e-6);
    let diff = u
        .windows(2)
        .all(|w| ((w[1] - w[0]) / d0 - 1.0).abs() < 1e-6);
    ratio && !diff
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spacing_is_detected() {
        let lin: Vec<f64> = (0..10).map(|i| 1.0 + i as f64 * 0.5).collect();
        let log: Vec<f64> = (0..10).map(|i| 1e-3 * 10f64.powf(i as f64 / 3.0)).collect();
        assert!(!log_spaced(&lin));
        assert!(log_spaced(&log));
        assert!(!log_spaced(&[1.0, 2.0]));
        assert_eq!(distinct(&[3.0, 1.0, f64::NAN, 3.0]), vec![1.0, 3.0]);
    }
}
