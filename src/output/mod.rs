//! Writers: outcome rows (CSV and tables) and trajectories.

pub mod row;
pub mod trace;
