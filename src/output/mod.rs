//! Writers: outcome rows (CSV, Parquet and tables) and trajectories.

pub mod chain_row;
pub mod failpoint;
pub mod fill;
pub mod guard;
pub mod lock;
pub mod merge;
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
    /// The format given, else the one `path`'s extension names
    /// (`.parquet` or `.pq`: Parquet; anything else: CSV).
    pub fn resolve(given: Option<TableKind>, path: &std::path::Path) -> TableKind {
        given.unwrap_or_else(|| {
            let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
            if ext.eq_ignore_ascii_case("parquet") || ext.eq_ignore_ascii_case("pq") {
                TableKind::Parquet
            } else {
                TableKind::Csv
            }
        })
    }
}
