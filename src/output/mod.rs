//! Writers: outcome rows (CSV and tables) and trajectories.

pub mod failpoint;
pub mod guard;
pub mod lock;
pub mod merge;
pub mod partial;
pub mod row;
pub mod sidecar;
pub mod trace;
