//! Writers: outcome rows (CSV, Parquet and tables) and trajectories.

pub mod failpoint;
pub mod fill;
pub mod guard;
pub mod lock;
pub mod merge;
pub mod parquet_file;
pub mod partial;
pub mod row;
pub mod sidecar;
pub mod trace;
