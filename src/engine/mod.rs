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

/// The step (`None`: nothing can collide) and caps of one run; both backends
/// start from exactly these.
pub fn plan(chain: &Chain, solver: &Solver) -> (Option<f64>, Limits) {
    let lim = Limits {
        max_steps: solver.max_steps,
        max_time: solver.max_time,
    };
    (solver.dt(chain), lim)
}

/// Simulate one compiled chain with `solver`, reporting states to `obs`.
pub fn simulate_chain<O: Observer>(chain: &Chain, solver: &Solver, obs: &mut O) -> Outcome {
    let (dt, lim) = plan(chain, solver);
    // A chain where nothing can collide still runs: the integrator sees it settled.
    let h = dt.unwrap_or(f64::INFINITY);
    let run = match solver.precision {
        Precision::F64 => integrate::<f64, O>(chain, h, &lim, obs),
        Precision::F32 => integrate::<f32, O>(chain, h, &lim, obs),
    };
    Outcome::from_run(chain, &run, dt.unwrap_or(f64::NAN))
}
