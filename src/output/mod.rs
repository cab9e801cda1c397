//! Writers: outcome rows (CSV, Parquet and tables) and trajectories.

pub mod chain_row;
pub mod failpoint;
pub mod guard;
pub mod lock;
pub mod parquet_file;
pub mod partial;
pub mod publish;
pub mod row;
pub mod sidecar;
pub mod trace;
pub mod units;

use crate::choice::Choice;

/// What a sweep table is written as (`--format`, `format=`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableKind {
    Csv,
    Parquet,
}

impl Choice for TableKind {
    const ALL: &'static [Self] = &[TableKind::Csv, TableKind::Parquet];
    fn name(self) -> &'static str {
        match self {
            TableKind::Csv => "csv",
            TableKind::Parquet => "parquet",
        }
    }
}

impl TableKind {
    /// The format `path`'s extension names: `.csv` CSV, `.parquet` or `.pq`
    /// Parquet (any case); `None` for any other name.
    pub fn from_extension(path: &std::path::Path) -> Option<TableKind> {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        if ext.eq_ignore_ascii_case("parquet") || ext.eq_ignore_ascii_case("pq") {
            Some(TableKind::Parquet)
        } else if ext.eq_ignore_ascii_case("csv") {
            Some(TableKind::Csv)
        } else {
            None
        }
    }

    /// The format of a table written to `path`: the one its extension
    /// names, or the one given (`--format`) for a name with another or no
    /// extension. A name's format is never silently ignored: `x.xlsx`
    /// without `--format`, or `--format parquet` into `x.csv`, is refused.
    pub fn resolve(
        given: Option<TableKind>,
        path: &std::path::Path,
    ) -> Result<TableKind, crate::InputError> {
        let named = TableKind::from_extension(path);
        match (given, named) {
            (Some(g), Some(n)) if g != n => Err(crate::error::flag(
                "--format",
                g.name(),
                &format!(
                    "the format {} names ({}), or another name for the output",
                    path.display(),
                    n.name()
                ),
            )),
            (Some(g), _) => Ok(g),
            (None, Some(n)) => Ok(n),
            (None, None) => Err(crate::error::flag(
                "--out",
                &path.display().to_string(),
                "a name ending in .csv or .parquet (.pq), or --format csv|parquet for another name (the format is never guessed)",
            )),
        }
    }
}
