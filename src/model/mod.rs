//! Models: the kinds of system a sweep's scenes can be, as siblings behind
//! one interface (docs/ARCHITECTURE.md, "Models").
//!
//! A [`Model`] turns checked scenes into work for a backend, runs a batch
//! of them and returns its [`Outcomes`], which know their columns (names,
//! types) and give each row's fields. The sweep (its pipeline, shards,
//! resume, refinement), the output, the sidecar, the typed API, Python and
//! the explorer are written once against it. Two models are registered:
//! the cradle ([`cradle::Cradle`]: a few balls, exact contact times,
//! `engine::cradle`) and the granular chain ([`granular::Granular`]:
//! long chains of beads, error-controlled steps, `engine::granular`;
//! docs/SPEC.md §9).
//!
//! **Registration** is this file: [`of`] picks a sweep's model from its
//! base scene, [`kind`] names a scene's, [`RowOutcome`] holds either's
//! typed outcome. A third model adds its folder's model file, its engine
//! and shader, and one line in each of these.
//!
//! (Not to be confused with `engine::Model`, the contact law a cradle runs
//! under: `hertz`, `hard-sphere`, `closure`.)

pub mod cradle;
pub mod granular;

use std::sync::Arc;
use std::time::Instant;

use crate::backend::{Backend, Needs};
use crate::engine::granular::ChainOutcome;
use crate::engine::{Outcome, Overrides, Solver, Status};
use crate::error::InputError;
use crate::output::row::{ColType, Field};
use crate::scene::Scene;

/// Scene `k` of a batch, or why its values make no valid scene (its row:
/// status `invalid`). Built by the worker about to run it.
pub type SceneAt<'a> = &'a (dyn Fn(usize) -> Result<Scene, InputError> + Sync);

/// What a sweep (or an optimisation) varies, as a model needs it: to size
/// its table ([`of`]) and to say what its scenes ask of a backend
/// ([`Model::needs`]).
pub struct Varied<'a> {
    /// The parameter names of the axes.
    pub names: Vec<&'a str>,
    /// The fewest and most balls a `balls` axis gives, if there is one.
    pub balls: Option<(usize, usize)>,
}

impl Varied<'_> {
    /// Whether an axis varies one of `names`.
    pub fn any(&self, names: &[&str]) -> bool {
        self.names.iter().any(|n| names.contains(n))
    }
}

/// One kind of system (a cradle, a granular chain): its columns, what its
/// scenes ask of a backend, and how a batch of them runs. One value per
/// sweep, built from its base scene ([`of`]).
pub trait Model: std::fmt::Debug + Send + Sync {
    /// The kind, as messages name it: `a cradle`, `a granular chain`.
    fn name(&self) -> &'static str;
    /// Names of the outcome's columns (after a table's `id` and axes).
    fn header(&self) -> Vec<String>;
    /// Types of the outcome's columns, parallel to [`Model::header`].
    fn types(&self) -> Vec<ColType>;
    /// What the scenes of a sweep with this base scene, varying `varied`,
    /// can ask of a backend (for [`Backend::prepare`]).
    fn needs(&self, base: &Scene, varied: &Varied, solver: &Solver) -> Needs;
    /// Refuse a solver this model cannot run (before any output is opened).
    fn check_solver(&self, _solver: &Solver) -> Result<(), InputError> {
        Ok(())
    }
    /// Whether `--error-estimate` means anything: a cradle's estimate is
    /// asked for; a chain always carries its own (docs/SPEC.md §9).
    fn takes_error_estimate(&self) -> bool;
    /// Scenes per batch, at most `cap` (the backend's).
    fn batch_size(&self, cap: u64) -> u64 {
        cap
    }
    /// Expected cost of a scene (any unit, the same for every scene of a
    /// sweep), for balancing shards; 1 for an invalid one.
    fn cost(&self, scene: Result<Scene, InputError>, o: &Overrides) -> f64;
    /// Run `n` scenes on `backend`; `built` is set when their work is
    /// prepared (the pipeline's `jobs` stage ends there).
    fn run(
        &self,
        backend: &dyn Backend,
        n: usize,
        scene: SceneAt,
        o: &Overrides,
        error_estimate: bool,
        built: &mut Instant,
    ) -> anyhow::Result<Box<dyn Outcomes>>;
    /// Scene `id` run again on the CPU for a closer look (the explorer's
    /// scene panel): its outcome's columns and what the model can show of
    /// its motion, as JSON.
    /// Bead-steps (or the model's unit of work) its runs have taken so far,
    /// as they step: `None` when the model does not count them (a sweep's
    /// progress then moves with its rows alone).
    fn work_done(&self) -> Option<u64> {
        None
    }

    /// A long run ends early, with an error, when `stop` is requested.
    fn look(
        &self,
        id: u64,
        scene: Result<Scene, InputError>,
        o: &Overrides,
        stop: &crate::engine::Stop,
    ) -> anyhow::Result<serde_json::Value>;
}

/// A batch's outcomes, in scene order.
pub trait Outcomes: Send {
    fn len(&self) -> usize;
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    fn status(&self, k: usize) -> Status;
    /// Outcome `k`'s columns (after the row's `id` and axes), field by field.
    fn emit(&self, k: usize, out: &mut dyn FnMut(Field));
    /// The outcomes, typed, for a row callback.
    fn into_rows(self: Box<Self>) -> Vec<RowOutcome>;
}

/// A row's outcome: a cradle's, or a granular chain's (docs/SPEC.md §9).
#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant)]
pub enum RowOutcome {
    Cradle(Outcome),
    Chain(ChainOutcome),
}

impl RowOutcome {
    /// The cradle's outcome (`None` for a chain).
    pub fn cradle(&self) -> Option<&Outcome> {
        match self {
            RowOutcome::Cradle(o) => Some(o),
            RowOutcome::Chain(_) => None,
        }
    }

    /// The chain's outcome (`None` for a cradle).
    pub fn chain(&self) -> Option<&ChainOutcome> {
        match self {
            RowOutcome::Chain(o) => Some(o),
            RowOutcome::Cradle(_) => None,
        }
    }

    pub fn status(&self) -> Status {
        match self {
            RowOutcome::Cradle(o) => o.status,
            RowOutcome::Chain(o) => o.status,
        }
    }
}

/// The model of a sweep whose base scene is `base` and which varies
/// `varied`: its table is as wide as its longest chain (the base scene's, or
/// a `balls` value's), a chain's has `energy_dissipated` when it is damped
/// or its damping varied (`shock_speed`, `piston_work` with a piston), and a cradle's has displacement columns when its
/// scenes hang on strings (`[pendulum]`, or a `length`/`gravity` key varied).
pub fn of(base: &Scene, varied: &Varied) -> Arc<dyn Model> {
    let width = varied.balls.map_or(base.n, |span| span.1.max(base.n));
    let pendulum = base.pendulum.is_some() || varied.any(&["length", "gravity"]);
    match &base.chain {
        Some(c) => {
            // A damped chain's table has `energy_dissipated`.
            let damped = c.viscosity > 0.0
                || c.air_drag > 0.0
                || c.restitution() < 1.0
                || varied.any(&[
                    "damping.viscosity",
                    "damping.air_drag",
                    "damping.restitution",
                ]);
            let piston = c.piston > 0.0 || varied.any(&["piston.velocity"]);
            let drive = c.pulse.as_ref().is_some_and(|p| p.is_drive());
            Arc::new(granular::Granular::new(
                c.probes.clone(),
                width,
                [damped, piston, drive],
            ))
        }
        None => Arc::new(cradle::Cradle::new(base.n, width, pendulum)),
    }
}

/// Which model runs `scene` (a sweep's scenes all have its base scene's).
pub fn kind(scene: &Scene) -> &'static str {
    match scene.chain {
        Some(_) => granular::NAME,
        None => cradle::NAME,
    }
}

/// Why a value of an axis is refused when it makes a scene of another kind
/// than the base scene (docs/SPEC.md §9): a table has one model's columns.
pub fn mixed_sweep(base: &Scene) -> String {
    let (base, value) = match kind(base) {
        granular::NAME => (granular::NAME, cradle::NAME),
        _ => (cradle::NAME, granular::NAME),
    };
    format!(
        "a scene like the base scene: the base scene is {base} and this value makes {value} \
         (a sweep's scenes are all cradles or all granular chains; a chain of at most 64 beads \
         is one when it has [walls], [pulse], [probes], [record], [pattern], [taper], [impurity], [gravity], [piston] or [drive])"
    )
}
