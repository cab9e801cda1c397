//! Sweeps of granular chains (docs/SPEC.md §9): each scene id becomes a
//! chain's compiled beads and step plan only when a worker is about to run
//! it, so a batch holds no more chains than there are workers at once.

use super::Sweep;
use crate::backend::ChainJob;
use crate::engine::granular::{self, Beads};
use crate::engine::{Overrides, Solver};
use crate::error::InputError;

/// Beads a batch of a chain sweep may hold, summed over its chains (its
/// outcomes keep each chain's final velocities until the rows are written):
/// a batch of 10^4-bead chains is 104 chains.
pub const BATCH_BEADS: u64 = 1 << 20;

impl Sweep {
    /// Scene `id` of a chain sweep, compiled and planned; `None` if its
    /// values make no valid chain (its row: status `invalid`).
    pub fn chain_job(&self, id: u64, o: &Overrides) -> Result<Option<ChainJob>, InputError> {
        let Ok(scene) = self.scene(id) else {
            return Ok(None);
        };
        if scene.chain.is_none() {
            return Ok(None);
        }
        let solver = Solver::resolve(&scene, o)?;
        let beads = Beads::from_scene(&scene);
        let plan = granular::plan(&beads, &solver, None);
        // A step that underflows makes no runnable chain: an `invalid` row.
        if granular::unrunnable(&plan).is_some() {
            return Ok(None);
        }
        Ok(Some(ChainJob { beads, plan }))
    }

    /// Expected cost of scene `id` of a chain sweep (bead-steps), for
    /// balancing shards.
    pub fn chain_cost(&self, id: u64, o: &Overrides) -> f64 {
        match self.chain_job(id, o) {
            Ok(Some(j)) => {
                let t = j.plan.duration.unwrap_or_else(|| j.beads.run_length());
                j.beads.n as f64 * (t / j.plan.h).max(1.0)
            }
            _ => 1.0,
        }
    }

    /// Scenes per batch of a chain sweep: at most [`BATCH_BEADS`] beads of
    /// its longest chain's length, at most `cap` (the backend's batch).
    pub fn chain_batch(&self, cap: u64) -> u64 {
        (BATCH_BEADS / self.width.max(1) as u64).clamp(1, cap.max(1))
    }
}
