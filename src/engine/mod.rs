//! The physics engine on the CPU: contact law, chain of rigid bodies,
//! integrator, outcomes. The GPU backend runs the WGSL twin of `integrate`.

pub mod chain;
pub mod contact;
pub mod integrate;
pub mod models;
pub mod outcome;
pub mod real;
pub mod solver;

pub use chain::Chain;
pub use integrate::{integrate, End, Limits, Observer, Run, Silent, StepPlan};
pub use models::Model;
pub use outcome::{Outcome, Status, MAX_OVERLAP_RATIO};
pub use solver::{Overrides, Solver, StepRule};

use crate::scene::Precision;

/// The step (`None`: nothing can collide) and caps of one run; both backends
/// start from exactly these.
pub fn plan(chain: &Chain, solver: &Solver) -> (Option<StepPlan>, Limits) {
    let lim = Limits {
        max_steps: solver.max_steps,
        max_time: solver.max_time,
    };
    (solver.step_plan(chain), lim)
}

/// The plan of a chain where nothing can collide: it settles before any step.
pub const UNSTEPPED: StepPlan = StepPlan {
    h: f64::INFINITY,
    weights: &[1.0],
    graded: false,
    h_min: f64::INFINITY,
    grade_quarters: 0,
    t_scale: f64::INFINITY,
    settle_rel: 0.0,
    h_free: f64::INFINITY,
};

/// Simulate one compiled chain with `solver`, reporting states to `obs`.
pub fn simulate_chain<O: Observer>(chain: &Chain, solver: &Solver, obs: &mut O) -> Outcome {
    if solver.model != Model::Hertz {
        if solver.model.unsupported(chain).is_some() {
            return Outcome::invalid(chain.n_balls);
        }
        let run = match solver.model {
            Model::HardSphere => models::hard_sphere(chain),
            _ => models::closure(chain),
        };
        return Outcome::from_run(chain, &run, f64::NAN);
    }
    let (sp, lim) = plan(chain, solver);
    // A chain where nothing can collide still runs: the integrator sees it settled.
    let sp = sp.unwrap_or(UNSTEPPED);
    let run = match solver.precision {
        Precision::F64 => integrate::<f64, O>(chain, &sp, &lim, obs),
        Precision::F32 => integrate::<f32, O>(chain, &sp, &lim, obs),
    };
    Outcome::from_run(chain, &run, if sp.h.is_finite() { sp.h } else { f64::NAN })
}
