//! Solver settings: the scene's `[solver]` table, overridden by CLI flags,
//! resolved into the step an integration uses.

use serde::Serialize;

use super::Chain;
use crate::error::InputError;
use crate::scene::{Method, Precision, Scene};

/// Default target error of outcome velocities relative to v_in.
pub const DEFAULT_TOLERANCE: f64 = 1e-6;
/// Smallest tolerance f32 arithmetic can honour (round-off floor).
pub const F32_TOLERANCE_FLOOR: f64 = 1e-5;
/// Default step cap per scene.
pub const DEFAULT_MAX_STEPS: u64 = 50_000_000;
/// Default cap on simulated time for a free line (s); free flight costs nothing.
pub const DEFAULT_MAX_TIME: f64 = 100.0;
/// Velocity Verlet's error on outcome velocities is at most about
/// `VERLET_ERROR_COEFF · (h/t_c)²` relative to v_in (t_c: [`Chain::time_scale`]).
/// Measured against a Richardson-extrapolated reference: the worst of 216
/// five-ball scenes (masses 0.1…10 m, gaps 0…100 µm, 1–3 balls launched) is
/// 9.3·(h/t_c)² at every tolerance from 1e-3 to 1e-8; the worst of the
/// 10,000-scene grid100 is 21·(h/t_c)² (results/bench_grid100.csv). 24 keeps
/// both below the tolerance.
pub const VERLET_ERROR_COEFF: f64 = 24.0;
/// Never take fewer than this many steps per contact time.
pub const MIN_STEPS_PER_CONTACT: f64 = 20.0;

/// Flags that override a scene's `[solver]` table (`None`: not given).
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    pub method: Option<Method>,
    pub precision: Option<Precision>,
    pub tolerance: Option<f64>,
}

/// How the step is chosen.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum StepRule {
    /// A fixed step (s).
    Dt(f64),
    /// A target error on outcome velocities relative to v_in.
    Tolerance(f64),
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Solver {
    pub method: Method,
    pub precision: Precision,
    pub step: StepRule,
    pub max_steps: u64,
    pub max_time: f64,
}

impl Solver {
    pub fn resolve(scene: &Scene, o: &Overrides) -> Result<Solver, InputError> {
        let precision = o
            .precision
            .or(scene.solver.precision)
            .unwrap_or(Precision::F64);
        let step = match (o.tolerance, scene.solver.dt, scene.solver.tolerance) {
            (Some(t), _, _) => StepRule::Tolerance(t),
            (None, Some(dt), _) => StepRule::Dt(dt),
            (None, None, Some(t)) => StepRule::Tolerance(t),
            (None, None, None) => StepRule::Tolerance(match precision {
                Precision::F64 => DEFAULT_TOLERANCE,
                Precision::F32 => F32_TOLERANCE_FLOOR,
            }),
        };
        if let (StepRule::Tolerance(t), Precision::F32) = (step, precision) {
            if t < F32_TOLERANCE_FLOOR {
                return Err(InputError::Flag {
                    flag: "tolerance".into(),
                    value: format!("{t:e}"),
                    allowed: format!(
                        "below the f32 round-off floor {F32_TOLERANCE_FLOOR:e}; use --precision f64 or a tolerance ≥ {F32_TOLERANCE_FLOOR:e}"
                    ),
                });
            }
        }
        Ok(Solver {
            method: o.method.or(scene.solver.method).unwrap_or(Method::Verlet),
            precision,
            step,
            max_steps: scene.max_steps.unwrap_or(DEFAULT_MAX_STEPS),
            max_time: scene.duration.unwrap_or(DEFAULT_MAX_TIME),
        })
    }

    /// The step (s) for this chain; `None` when nothing can collide.
    pub fn dt(&self, chain: &Chain) -> Option<f64> {
        let tc = chain.time_scale()?;
        Some(match self.step {
            StepRule::Dt(dt) => dt,
            StepRule::Tolerance(tol) => {
                let per_contact = match self.method {
                    Method::Verlet => (VERLET_ERROR_COEFF / tol).sqrt(),
                };
                tc / per_contact.max(MIN_STEPS_PER_CONTACT)
            }
        })
    }
}
