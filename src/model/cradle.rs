//! The cradle model: a few balls on a line or on strings, contact times
//! resolved exactly (`engine::cradle`; its WGSL twin in
//! `shaders/cradle/`).

use std::time::Instant;

use serde_json::json;

use super::{Model, Outcomes, RowOutcome, SceneAt, Varied};
use crate::backend::{run_with_estimate, Backend, Job, Needs};
use crate::engine::{simulate_chain, Chain, Outcome, Overrides, Silent, Solver, Status};
use crate::error::InputError;
use crate::output::row::{self, ColType, Field, Shape};
use crate::output::trace::TraceWriter;
use crate::scene::Scene;

/// The kind's name in messages.
pub const NAME: &str = "a cradle";

/// Most trace rows a scene's closer look carries ([`Model::look`]).
pub const MAX_TRACE_ROWS: f64 = 2000.0;

/// A sweep of cradles: its base scene's ball count (an invalid scene's row
/// is that wide) and its table's per-ball columns.
#[derive(Clone, Debug)]
pub struct Cradle {
    n_balls: usize,
    shape: Shape,
}

impl Cradle {
    pub fn new(n_balls: usize, width: usize, pendulum: bool) -> Cradle {
        Cradle {
            n_balls,
            shape: Shape { width, pendulum },
        }
    }

    /// The table's per-ball columns.
    pub fn shape(&self) -> Shape {
        self.shape
    }
}

/// The job for a scene: its chain of bodies and solver, or `Invalid` when
/// its values make no valid scene (`n_balls`: the base scene's balls).
pub fn job(
    scene: Result<Scene, InputError>,
    n_balls: usize,
    o: &Overrides,
) -> Result<Job, InputError> {
    match scene {
        Ok(scene) => Ok(Job::Run {
            chain: Chain::from_scene(&scene)?,
            solver: Solver::resolve(&scene, o)?,
        }),
        Err(_) => Ok(Job::Invalid { n_balls }),
    }
}

impl Model for Cradle {
    fn name(&self) -> &'static str {
        NAME
    }

    fn header(&self) -> Vec<String> {
        row::header(&[], self.shape).split_off(1)
    }

    fn types(&self) -> Vec<ColType> {
        row::column_types(&[], self.shape).split_off(1)
    }

    fn needs(&self, base: &Scene, varied: &Varied, solver: &Solver) -> Needs {
        let base_terms = Chain::from_scene(base).map_or(true, |c| c.needs_terms());
        let terms_vary = varied.any(&["restitution", "air_drag", "length", "gravity"]);
        let fewest_balls = varied.balls.map_or(base.n, |span| span.0);
        // Glue joins balls into bodies: any count down to two may occur.
        let glued = base.glue.iter().any(|g| *g) || varied.any(&["glue"]);
        Needs {
            precision: solver.precision,
            hertz: solver.model == crate::engine::Model::Hertz,
            plain: !base_terms || terms_vary,
            terms: base_terms || terms_vary,
            bodies: (if glued { 2 } else { fewest_balls }, self.shape.width),
            chains: false,
        }
    }

    fn takes_error_estimate(&self) -> bool {
        true
    }

    fn cost(&self, scene: Result<Scene, InputError>, o: &Overrides) -> f64 {
        match job(scene, self.n_balls, o) {
            Ok(Job::Run { chain, solver }) => Solver::expected_cost(&solver, &chain),
            _ => 1.0,
        }
    }

    fn run(
        &self,
        backend: &dyn Backend,
        n: usize,
        scene: SceneAt,
        o: &Overrides,
        error_estimate: bool,
        built: &mut Instant,
    ) -> anyhow::Result<Box<dyn Outcomes>> {
        let jobs = (0..n)
            .map(|k| job(scene(k), self.n_balls, o))
            .collect::<Result<Vec<Job>, _>>()?;
        *built = Instant::now();
        Ok(Box::new(CradleOutcomes {
            v: run_with_estimate(backend, &jobs, error_estimate)?,
            shape: self.shape,
        }))
    }

    /// The outcome, the trace (at most [`MAX_TRACE_ROWS`] rows, said in
    /// the reply) and the outcome under the `hard-sphere` and `closure`
    /// contact laws.
    fn look(
        &self,
        id: u64,
        scene: Result<Scene, InputError>,
        o: &Overrides,
        _: &crate::engine::Stop,
    ) -> anyhow::Result<serde_json::Value> {
        let Job::Run { chain, solver } = job(scene, self.n_balls, o)? else {
            anyhow::bail!("scene {id} is not a valid scene (status invalid)");
        };
        let t_end = simulate_chain(&chain, &solver, &mut Silent).t_end;
        let default_every = crate::output::trace::default_every(&chain);
        let every = default_every.max(t_end / MAX_TRACE_ROWS);
        let mut bytes = Vec::new();
        let mut tw = TraceWriter::new(&mut bytes, &chain, every)?;
        let o = simulate_chain(&chain, &solver, &mut tw);
        tw.finish()?;
        let shape = Shape {
            width: chain.n_balls,
            pendulum: chain.is_pendulum(),
        };
        let outcome_of = |o: &Outcome| -> serde_json::Value {
            let header = row::header(&[], shape);
            let fields = row::fields(id, &[], o, shape);
            header
                .into_iter()
                .zip(fields)
                .skip(1)
                .map(|(h, f)| json!([h, f]))
                .collect::<Vec<_>>()
                .into()
        };
        let mut models = serde_json::Map::new();
        for m in [
            crate::engine::Model::HardSphere,
            crate::engine::Model::Closure,
        ] {
            let mut s = solver.clone();
            s.model = m;
            models.insert(
                m.name().to_string(),
                match m.unsupported(&chain) {
                    Some(why) => json!({"unsupported": why}),
                    None => outcome_of(&simulate_chain(&chain, &s, &mut Silent)),
                },
            );
        }
        Ok(json!({
            "id": id,
            "outcome": outcome_of(&o),
            "trace_csv": String::from_utf8_lossy(&bytes),
            "trace_every_s": every,
            "trace_capped": every > default_every,
            "pendulum": chain.is_pendulum(),
            "length_m": chain.length,
            "models": models,
        }))
    }
}

/// A batch of cradles' outcomes and the table's per-ball columns.
struct CradleOutcomes {
    v: Vec<Outcome>,
    shape: Shape,
}

impl Outcomes for CradleOutcomes {
    fn len(&self) -> usize {
        self.v.len()
    }

    fn status(&self, k: usize) -> Status {
        self.v[k].status
    }

    fn emit(&self, k: usize, out: &mut dyn FnMut(Field)) {
        row::emit_outcome(&self.v[k], self.shape, out)
    }

    fn into_rows(self: Box<Self>) -> Vec<RowOutcome> {
        self.v.into_iter().map(RowOutcome::Cradle).collect()
    }
}
