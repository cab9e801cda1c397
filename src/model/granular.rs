//! The granular-chain model (docs/SPEC.md §9): long chains of beads with
//! walls, precompression, pulses and probes, run under the error control
//! (`engine::granular`; its WGSL twin in `shaders/granular/`). Each scene
//! becomes a chain's compiled beads and step plan only when a worker is
//! about to run it, so a batch holds no more chains than there are workers
//! at once.

use std::sync::Arc;
use std::time::Instant;

use serde_json::json;

use super::{Model, Outcomes, RowOutcome, SceneAt, Varied};
use crate::backend::{run_chain_controlled, run_chains_controlled, Backend, ChainJob, Needs};
use crate::engine::granular::{self, Beads, ChainOutcome};
use crate::engine::{Overrides, Solver, Status};
use crate::error::InputError;
use crate::output::chain_row::Columns;
use crate::output::row::{ColType, Field};
use crate::scene::Scene;

/// The kind's name in messages.
pub const NAME: &str = "a granular chain";

/// Beads a batch of a chain sweep may hold, summed over its chains (its
/// outcomes keep each chain's final velocities until the rows are written):
/// a batch of 10^4-bead chains is 104 chains.
pub const BATCH_BEADS: u64 = 1 << 20;

/// Most beads and (half the most) rows of a scene's histories in a closer
/// look ([`Model::look`]).
pub const HISTORY_BEADS: usize = 200;
pub const HISTORY_ROWS: usize = 400;

/// A sweep of granular chains: its bead columns and its longest chain.
#[derive(Clone, Debug)]
pub struct Granular {
    cols: Arc<Columns>,
    most_beads: usize,
    /// The bead-steps of this sweep's runs ([`Model::work_done`]).
    tally: crate::engine::Tally,
}

impl Granular {
    /// Chains of at most `most_beads` beads with the base scene's `probes`
    /// (`kinds`: some may dissipate, have a piston, be driven:
    /// [`Columns::for_chains`]).
    pub fn new(probes: Vec<usize>, most_beads: usize, kinds: [bool; 3]) -> Granular {
        Granular {
            cols: Arc::new(Columns::for_chains(probes, most_beads, kinds)),
            most_beads,
            tally: crate::engine::Tally::new(),
        }
    }
}

/// A scene compiled and planned; `None` if its values make no valid chain
/// (its row: status `invalid`).
pub fn job(
    scene: Result<Scene, InputError>,
    o: &Overrides,
) -> Result<Option<ChainJob>, InputError> {
    let Ok(scene) = scene else {
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

impl Model for Granular {
    fn name(&self) -> &'static str {
        NAME
    }

    fn header(&self) -> Vec<String> {
        self.cols.header()
    }

    fn types(&self) -> Vec<ColType> {
        self.cols.types()
    }

    /// The chain kernel alone: `plain` where some chain may be elastic,
    /// `terms` where some may be damped (its pipeline of its own).
    fn needs(&self, base: &Scene, varied: &Varied, solver: &Solver) -> Needs {
        let damped = base.chain.as_ref().is_some_and(|c| c.damped());
        let damping_varies = varied.any(&[
            "damping.viscosity",
            "damping.restitution",
            "damping.air_drag",
        ]);
        Needs {
            precision: solver.precision,
            hertz: solver.model == crate::engine::Model::Hertz,
            plain: !damped || damping_varies,
            terms: damped || damping_varies,
            bodies: (base.n, self.most_beads),
            chains: true,
        }
    }

    fn check_solver(&self, solver: &Solver) -> Result<(), InputError> {
        granular::check_solver(solver)
    }

    fn takes_error_estimate(&self) -> bool {
        false
    }

    /// The bead-steps taken so far by the chains this model ran on the
    /// CPU engine, twins and reruns included (the GPU kernel's are not
    /// counted).
    fn work_done(&self) -> Option<u64> {
        self.tally.get()
    }

    /// At most [`BATCH_BEADS`] beads of the longest chain's length.
    fn batch_size(&self, cap: u64) -> u64 {
        (BATCH_BEADS / self.most_beads.max(1) as u64).clamp(1, cap.max(1))
    }

    /// Bead-steps.
    fn cost(&self, scene: Result<Scene, InputError>, o: &Overrides) -> f64 {
        match job(scene, o) {
            Ok(Some(j)) => {
                let t = j.plan.duration.unwrap_or_else(|| j.beads.run_length());
                j.beads.n as f64 * (t / j.plan.h).max(1.0)
            }
            _ => 1.0,
        }
    }

    /// Under the error control; each chain built by the worker that runs
    /// it (building counts as integration).
    fn run(
        &self,
        backend: &dyn Backend,
        n: usize,
        scene: SceneAt,
        o: &Overrides,
        _error_estimate: bool,
        _built: &mut Instant,
    ) -> anyhow::Result<Box<dyn Outcomes>> {
        let v = run_chains_controlled(backend, n, &|k| {
            Ok(job(scene(k), o)?.map(|mut j| {
                j.plan.tally = self.tally.clone();
                j
            }))
        })?;
        Ok(Box::new(ChainOutcomes {
            v,
            cols: self.cols.clone(),
        }))
    }

    /// The row's run under the error control, then the run it reports
    /// once more with every step offered to a history (evenly spaced rows):
    /// the same plan, so the outcome is the row's. Its outcome columns and
    /// bead histories for a space-time image (at most [`HISTORY_BEADS`]
    /// beads × 2·[`HISTORY_ROWS`] rows, as f32).
    fn look(
        &self,
        id: u64,
        scene: Result<Scene, InputError>,
        o: &Overrides,
        stop: &crate::engine::Stop,
    ) -> anyhow::Result<serde_json::Value> {
        use crate::engine::granular::history::History;
        let Some(mut job) = job(scene, o)? else {
            anyhow::bail!("scene {id} is not a valid chain (status invalid)");
        };
        job.plan.stop = stop.clone();
        let row = run_chain_controlled(&job)?;
        let mut h = History::new(&job.beads, HISTORY_BEADS, HISTORY_ROWS);
        let o = crate::backend::rerun_reported(&job, &row, &mut h, true);
        if stop.requested() {
            anyhow::bail!("scene {id} was stopped before its end");
        }
        let outcome: Vec<serde_json::Value> = self
            .cols
            .header()
            .into_iter()
            .zip(self.cols.texts(&o))
            .map(|(name, text)| json!([name, text]))
            .collect();
        // f32's shortest decimal (JSON numbers are f64: an f32 written as one
        // would take 17 digits where 7 or fewer carry all it holds).
        let f32s = |rows: &[Vec<f64>]| -> Vec<Vec<f64>> {
            rows.iter()
                .map(|r| {
                    r.iter()
                        .map(|&x| (x as f32).to_string().parse().unwrap_or(f64::NAN))
                        .collect()
                })
                .collect()
        };
        Ok(json!({
            "id": id,
            "outcome": outcome,
            "beads": job.beads.n,
            "histories": {
                "beads": h.beads,
                "t": h.t,
                "v": f32s(&h.v),
                "f": f32s(&h.f),
            },
        }))
    }
}

/// A batch of chains' outcomes and the table's bead columns.
struct ChainOutcomes {
    v: Vec<ChainOutcome>,
    cols: Arc<Columns>,
}

impl Outcomes for ChainOutcomes {
    fn len(&self) -> usize {
        self.v.len()
    }

    fn status(&self, k: usize) -> Status {
        self.v[k].status
    }

    fn emit(&self, k: usize, out: &mut dyn FnMut(Field)) {
        self.cols.emit(&self.v[k], out)
    }

    fn into_rows(self: Box<Self>) -> Vec<RowOutcome> {
        self.v.into_iter().map(RowOutcome::Chain).collect()
    }
}
