//! The physics engine on the CPU: contact law, chain of rigid bodies,
//! integrator, outcomes. The GPU backend runs the WGSL twin of `integrate`.

pub mod chain;
pub mod contact;
pub mod integrate;
pub mod outcome;
pub mod real;
pub mod solver;

pub use chain::Chain;
pub use integrate::{integrate, End, Limits, Observer, Run, Silent};
pub use outcome::{Outcome, Status, MAX_OVERLAP_RATIO};
pub use solver::{Overrides, Solver, StepRule};

use crate::scene::Precision;

/// Simulate one compiled chain with `solver`, reporting states to `obs`.
pub fn simulate_chain<O: Observer>(chain: &Chain, solver: &Solver, obs: &mut O) -> Outcome {
    let lim = Limits {
        max_steps: solver.max_steps,
        max_time: solver.max_time,
    };
    // A chain where nothing can collide still runs: the integrator sees it settled.
    let dt = solver.dt(chain);
    let h = dt.unwrap_or(f64::INFINITY);
    let run = match solver.precision {
        Precision::F64 => integrate::<f64, O>(chain, h, &lim, obs),
        Precision::F32 => integrate::<f32, O>(chain, h, &lim, obs),
    };
    Outcome::from_run(chain, &run, dt.unwrap_or(f64::NAN))
}
