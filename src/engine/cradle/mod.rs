//! The cradle's integrator — the one place on the Rust side that advances a
//! cradle in time. Its WGSL twins are in `shaders/cradle/` (same function
//! names; see below).
//!
//! State, in contact coordinates: the overlap δ_c of every contact and the
//! velocity v_b of every body. Forces depend only on δ, so nothing is ever
//! computed from large absolute positions (in f32, x_i − x_{i+1} of two
//! positions that have drifted a metre loses every digit of a 10 µm overlap).
//!
//! A sweep's chains run side by side ([`integrate_batch`]): lane l of every
//! state array is one chain, each lane takes its own steps, and the substeps
//! of all lanes are one loop that the compiler vectorises (AVX when the CPU
//! has it, picked at run time) — a single chain spends most of its time
//! waiting on each √δ in turn. Each lane does the same operations as a chain
//! run alone ([`integrate`], one lane), so results do not depend on the
//! batch, and are bit-identical to the shader's in f64.
//!
//! Work a scene does not need is skipped: while every contact is open the chain
//! is in free flight and is advanced analytically to the next contact onset
//! (0 steps); an impact nothing else can join is taken in closed form
//! (`Lanes::exact_impact`, 0 steps); the run ends as soon as no contact is
//! closed and none is closing.
//!
//! Pendulum (`Chain::is_pendulum`): every body feels −g·sin(x_b/L), with x_b
//! rebuilt from body 0's displacement and the overlaps. Free flight is then
//! stepped with the long steps `StepPlan::h_free` (chosen from the tolerance
//! and the duration), halving them towards each contact onset, and the run
//! ends exactly at the duration. Damping: Hunt–Crossley contacts
//! (`contact::contact_force`, χ set from each contact's closing speed when it
//! closes, lowered if it is later driven closed faster) and air drag (the exact decay e^{−γ·s} in every kick).

//!
//! Split by concern, each the twin of the WGSL in `shaders/` (`lanes.wgsl`,
//! `wide.wgsl`, `kernels.wgsl`: same function names):
//! - this file: what a run is planned with and what it returns (`StepPlan`,
//!   `Limits`, `Task`, `Run`, `End`, `Observer`);
//! - `kernels.rs`: the scalar kernels the shader repeats operation for
//!   operation (`pendulum_sin`, `decay`, `add`, `graded_steps`,
//!   `stiffness_cap`, `kick_weights`, `kink_impulse_error`, …);
//! - `lanes.rs`: the state of `L` chains side by side and the step kernels
//!   on it (`Lanes`: forces, kicks, drifts, exact impacts, free flight);
//! - `driver.rs`: `integrate` and `integrate_batch`: grouping, lane refill,
//!   AVX dispatch.

mod driver;
mod kernels;
mod lanes;

use super::contact::{contact_force, fifth_root, hertz_force};
use super::real::Real;
use super::Chain;
use crate::scene::MAX_BALLS;
pub use driver::{integrate, integrate_batch, integrate_batch_until, LANES};
use kernels::*;
pub use kernels::{closing_speed_floor, decay, kick_weights, kink_impulse_error, pendulum_sin};

/// A velocity at or above this magnitude (m/s) counts as non-finite; the
/// shader has no `isfinite`, so both twins use this test.
pub const FINITE_LIMIT: f64 = 1e30;

/// Why a run stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum End {
    /// Every contact open and no two bodies approaching: no collision can follow.
    Settled,
    /// A pendulum run reached its duration.
    Duration,
    StepCap,
    TimeCap,
    NonFinite,
}

/// Caps on one run.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    pub max_steps: u64,
    /// Simulated time (s).
    pub max_time: f64,
}

/// Receives the state after every step and at both ends of every free flight,
/// per body: displacement x (m) and velocity v (m/s).
pub trait Observer {
    /// `false` compiles the calls (and the position bookkeeping) away.
    const ACTIVE: bool = true;
    fn state(&mut self, t: f64, x: &[f64], v: &[f64]);
}

/// The observer of a sweep: sees nothing, costs nothing.
pub struct Silent;
impl Observer for Silent {
    const ACTIVE: bool = false;
    fn state(&mut self, _: f64, _: &[f64], _: &[f64]) {}
}

/// What a run produced, per body, in f64.
#[derive(Clone, Debug)]
pub struct Run {
    pub end: End,
    pub v: Vec<f64>,
    pub overlap: Vec<f64>,
    pub steps: u64,
    /// Time of the last state (s).
    pub t: f64,
    /// Onset of the first contact (s), if any.
    pub t_first_contact: Option<f64>,
    /// Last time a contact opened (s), located inside its step.
    pub t_last_release: Option<f64>,
    /// Largest overlap seen (m) and its ratio to the smaller boundary radius.
    pub max_overlap: f64,
    pub max_overlap_ratio: f64,
    /// Final displacement of each body (m): body 0's, then x_{b+1} = x_b − gap_b − δ_b.
    /// NaN for a free line run without an observer (not tracked).
    pub x: Vec<f64>,
    /// Contact onsets (a contact open at the start of a step and closed at its end).
    pub contacts: u64,
}

/// How steps are taken: a symmetric composition of velocity-Verlet substeps
/// of sizes `weights[i]·s`, with the step `s` graded near contact kinks.
#[derive(Clone, Copy, Debug)]
pub struct StepPlan {
    /// Nominal step (s); `INFINITY` when nothing can collide.
    pub h: f64,
    /// Substep weights (sum 1): `[1]` is velocity Verlet.
    pub weights: &'static [f64],
    /// Grade steps near contact onsets and releases (methods of order > 2).
    pub graded: bool,
    /// Smallest graded step (s).
    pub h_min: f64,
    /// Grading exponent in quarters: at time distance T from a kink the step
    /// is h·(T/t_c)^(q/4).
    pub grade_quarters: u32,
    /// The chain's time scale t_c (s), where grading ends.
    pub t_scale: f64,
    /// Closing speeds below this fraction of v_in are noise: the run ends
    /// (a tenth of the tolerance; 0 with a fixed `dt`).
    pub settle_rel: f64,
    /// Pendulum: the step (s) while every contact is open; unused on a free line.
    pub h_free: f64,
    /// Take isolated two-body impacts in closed form (elastic free lines
    /// under a tolerance; a fixed `dt` integrates every impact).
    pub exact: bool,
    /// Stiffness cap: while the chain's fastest local frequency ω exceeds
    /// `omega_ref` (rad/s), the step is at most `h_stiff`·ω_ref/ω
    /// ([`super::Chain::stiffness_coefficients`]); `h_stiff` 0: no cap.
    pub h_stiff: f64,
    pub omega_ref: f64,
}

/// One run of a batch: a chain, its steps and its caps.
#[derive(Clone, Copy, Debug)]
pub struct Task<'a> {
    pub chain: &'a Chain,
    pub plan: StepPlan,
    pub lim: Limits,
}

impl Task<'_> {
    /// Runs with equal keys share a lane group: the same bodies, substeps and
    /// terms (everything else may differ from lane to lane).
    fn key(&self) -> (usize, usize, usize, bool, u32, bool, bool, bool) {
        let ch = self.chain;
        (
            ch.n_bodies(),
            self.plan.weights.as_ptr() as usize,
            self.plan.weights.len(),
            self.plan.graded,
            self.plan.grade_quarters,
            ch.is_pendulum(),
            ch.damping_a > 0.0,
            ch.air_drag > 0.0,
        )
    }
}
