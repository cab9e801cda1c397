//! Solver settings: the scene's `[solver]` table, overridden by CLI flags,
//! resolved into the step an integration uses.

use serde::Serialize;

use super::cradle::StepPlan;
use super::{Chain, Model};
use crate::error::InputError;
use crate::scene::{Method, Precision, Scene};

/// Default method: the fastest at every tolerance on grid100 (results/).
pub const DEFAULT_METHOD: Method = Method::KahanLi6;
/// Default target error of outcome velocities relative to v_in.
pub const DEFAULT_TOLERANCE: f64 = 1e-6;
/// Smallest tolerance f32 arithmetic can honour (round-off floor).
pub const F32_TOLERANCE_FLOOR: f64 = 1e-5;

/// Smallest tolerance in f64. Round-off in the outcome velocities is ~1e-14
/// (cradle-1: kahanli6's results scatter by 5e-15 from 1e-13 down; Verlet at
/// 1e-14 reaches the 5e7-step cap), so 1e-12 keeps it below 1% of the
/// tolerance; the work-precision reference runs at 1e-11.
pub const F64_TOLERANCE_FLOOR: f64 = 1e-12;
/// Smallest tolerance in df64 (pairs of f32): its sums carry ~2^-46, so
/// outcomes scatter by ~1e-12·v_in (grid100 at 1e-10: 3.2e-12 from f64,
/// worst error 3.0e-11 as f64's); 1e-10 keeps that a few % of it.
pub const DF64_TOLERANCE_FLOOR: f64 = 1e-10;
/// Default step cap per scene.
pub const DEFAULT_MAX_STEPS: u64 = 50_000_000;
/// Default cap on simulated time for a free line (s). Free flight costs no
/// steps, so it is generous: a ball at 1e-4 m/s crossing 63 gaps of 1 mm takes
/// 630 s. A chain that keeps colliding meets the step cap instead.
pub const DEFAULT_MAX_TIME: f64 = 1e6;
/// Velocity Verlet's error on outcome velocities is at most about
/// `VERLET_ERROR_COEFF · (h/t_c)²` relative to v_in (t_c: [`Chain::time_scale`]).
/// Measured against a Richardson-extrapolated reference: the worst of 216
/// five-ball scenes (masses 0.1…10 m, gaps 0…100 µm, 1–3 balls launched) is
/// 9.3·(h/t_c)² at every tolerance from 1e-3 to 1e-8; the worst of the
/// 10,000-scene grid100 was 21·(h/t_c)² when this was fitted (today Verlet
/// meets every tolerance with a worst ratio of 0.88: results/tolerance_check.csv). 24 keeps
/// both below the tolerance.
pub const VERLET_ERROR_COEFF: f64 = 24.0;
/// Never take fewer than this many steps per contact time.
pub const MIN_STEPS_PER_CONTACT: f64 = 20.0;

/// Steps are graded within this fraction of t_c from a contact kink: beyond,
/// the force is smooth enough (measured on grid100: 0.1 takes 27% fewer steps
/// than 1 at 1e-6 with the same worst error; 0.05 takes 12–14% fewer than 0.1
/// with yoshida6 at 1e-6 and 1e-8, 4% with suzuki4, and lower worst errors).
pub const GRADING_SCALE: f64 = 0.05;

/// The stiffness cap of graded methods under a tolerance
/// ([`StepPlan::h_stiff`]): where the chain's fastest local frequency ω
/// exceeds ω_ref = `STIFFNESS_REF`/t_c, the step is at most
/// `STIFFNESS_STEP`·h·ω_ref/ω. ω_ref is about the bound on ω at the peak of
/// the two-body impact that sets t_c (4.03/t_c exactly, times 2^{1/4} for the
/// bound). A light ball squeezed between two heavy ones rings faster than any
/// two-body impact of its chain: on grid100 such scenes erred 10× more than
/// the median at equal h and set the worst error of every tolerance.
pub const STIFFNESS_REF: f64 = 4.8;
pub const STIFFNESS_STEP: f64 = 0.7;

/// A run ends when no two bodies close faster than this fraction of the
/// tolerance (times v_in): a later collision that slow changes velocities by
/// less than the error the tolerance allows anyway.
pub const SETTLE_FRACTION: f64 = 0.1;

/// Phase error per radian of each method on a harmonic oscillator,
/// c·(ω·H)^p at step H, with a margin of 2 for the pendulum's nonlinearity.
/// c is (θ − ωH)/(ωH)^{p+1}, θ the rotation angle of the method's one-step map
/// (the product of its Verlet substep matrices, cos θ = trace/2), evaluated at
/// ωH = 0.05…0.4 (constant to 1%).
pub fn swing_error_coeff(m: Method) -> f64 {
    match m {
        Method::Verlet => 2.0 * 0.0417,
        Method::Yoshida4 => 2.0 * 0.0663,
        Method::Suzuki4 => 2.0 * 0.00093,
        Method::Yoshida6 => 2.0 * 0.0038,
        Method::KahanLi6 => 2.0 * 0.00041,
    }
}

/// Longest free-flight step of a pendulum, in radians of swing (ω·H).
pub const MAX_SWING_STEP: f64 = 0.5;

/// Substep weights of each method: a symmetric composition of Verlet steps.
pub fn weights(m: Method) -> &'static [f64] {
    const W4: f64 = 1.3512071919596578; // 1/(2 − 2^{1/3})
    const S4: f64 = 0.4144907717943757; // 1/(4 − 4^{1/3})
    const Y6: [f64; 4] = [
        0.784_513_610_477_557_3,
        0.235_573_213_359_358_1,
        -1.177_679_984_178_871,
        1.315_186_320_683_911_2,
    ];
    // Kahan & Li 1997, s9odr6a (Hairer, Lubich, Wanner: Geometric Numerical
    // Integration, 2nd ed., V.3.2).
    const K6: [f64; 5] = [
        0.392_161_444_007_314_1,
        0.332_599_136_789_359_4,
        -0.706_246_172_557_639_4,
        0.082_213_596_293_550_8,
        0.798_543_990_934_83,
    ];
    match m {
        Method::Verlet => &[1.0],
        Method::Yoshida4 => &[W4, 1.0 - 2.0 * W4, W4],
        Method::Suzuki4 => &[S4, S4, 1.0 - 4.0 * S4, S4, S4],
        Method::Yoshida6 => &[Y6[0], Y6[1], Y6[2], Y6[3], Y6[2], Y6[1], Y6[0]],
        Method::KahanLi6 => &[
            K6[0], K6[1], K6[2], K6[3], K6[4], K6[3], K6[2], K6[1], K6[0],
        ],
    }
}

/// Error model of each method on outcome velocities, relative to v_in:
/// error ≈ C·(h/t_c)^q. q is the order measured over grid100 (step grading
/// keeps most, not all, of a high-order method's order across the δ^{3/2}
/// kinks); C is the worst scene's coefficient times a margin. Measured against
/// a reference good to 1e-10 (see results/README.md).
pub fn error_model(m: Method) -> (f64, f64) {
    match m {
        Method::Verlet => (VERLET_ERROR_COEFF, 2.0),
        Method::Suzuki4 => (4.0, 3.3),
        Method::Yoshida4 => (1e5, 4.0),
        Method::Yoshida6 => (0.2, 3.4),
        Method::KahanLi6 => (0.01, 3.4),
    }
}

/// At coarse steps (20–40 per contact time) yoshida6's error falls with its
/// full order 6, faster than the fitted q = 3.4 of [`error_model`] says — and
/// above it: error ≈ A·(h/t_c)^6 with A = 2,100 for the worst grid100 scene
/// at 4 tolerances per decade from 1e-5 to 1e-6 (q = 3.4 alone let 1e-5 …
/// 3e-6 through by up to 2×). The step is the smaller of the two models'; A
/// has a margin of 1.4. kahanli6 likewise: A = 200 (its worst grid100 scene
/// gave 28–43 at 20–43 steps per t_c), C = 0.01 (1.7e-3 at 71–140).
/// `None`: the fitted model holds everywhere.
pub fn coarse_error_model(m: Method) -> Option<f64> {
    match m {
        Method::Yoshida6 => Some(6000.0),
        Method::KahanLi6 => Some(200.0),
        _ => None,
    }
}

/// Flags that override a scene's `[solver]` table (`None`: not given).
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    pub model: Option<Model>,
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
    /// The physics: Hertz (integrated) or a comparison model.
    pub model: Model,
    pub method: Method,
    pub precision: Precision,
    pub step: StepRule,
    pub max_steps: u64,
    pub max_time: f64,
    /// Multiplies every step (1; 2 for the coarse run of an error estimate).
    pub step_factor: f64,
    /// A damped chain's damping at the steps' ends (`Some(true)`,
    /// `[solver] damping_split = "ends"`), in every substep (`Some(false)`,
    /// "substeps"), or chosen per chain (`None`, "auto", the default:
    /// [`crate::engine::granular::Beads::auto_damping_ends`]; docs/SPEC.md
    /// §9, "Damping").
    pub damping_ends: Option<bool>,
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
                Precision::F64 | Precision::Df64 => DEFAULT_TOLERANCE,
                Precision::F32 => F32_TOLERANCE_FLOOR,
            }),
        };
        if let StepRule::Tolerance(t) = step {
            let floor = match precision {
                Precision::F32 => F32_TOLERANCE_FLOOR,
                Precision::F64 => F64_TOLERANCE_FLOOR,
                Precision::Df64 => DF64_TOLERANCE_FLOOR,
            };
            if t < floor {
                let other = match precision {
                    Precision::F32 | Precision::Df64 => "use --precision f64 or ",
                    Precision::F64 => "use ",
                };
                return Err(InputError::Flag {
                    flag: "tolerance".into(),
                    value: format!("{t:e}"),
                    allowed: format!(
                        "below the {} round-off floor {floor:e} (round-off would swamp it: every scene would run to the step cap); {other}a tolerance ≥ {floor:e}",
                        precision.name()
                    ),
                });
            }
        }
        Ok(Solver {
            model: o.model.unwrap_or_default(),
            method: o.method.or(scene.solver.method).unwrap_or(DEFAULT_METHOD),
            precision,
            step,
            max_steps: scene.max_steps.unwrap_or(DEFAULT_MAX_STEPS),
            max_time: scene.duration.unwrap_or(DEFAULT_MAX_TIME),
            step_factor: 1.0,
            damping_ends: scene.solver.damping_ends,
        })
    }

    /// One rule for a setting given both as a flag and in a file: the same
    /// value is fine, different values are an error naming both (a row must
    /// never be labelled with a setting it was not computed with). `origin`
    /// names the file that holds `scene`.
    pub fn check_flags_against(
        scene: &Scene,
        o: &Overrides,
        origin: &str,
    ) -> Result<(), InputError> {
        let conflict = |flag: &str, value: String, key: &str, file_value: String| {
            InputError::Flag {
            flag: flag.into(),
            value,
            allowed: format!(
                "{origin} sets [solver] {key} = {file_value}: give this setting in one place (remove the flag or the key)"
            ),
        }
        };
        let f = &scene.solver;
        if let (Some(a), Some(b)) = (o.method, f.method) {
            if a != b {
                return Err(conflict(
                    "--method",
                    a.name().into(),
                    "method",
                    format!("{:?}", b.name()),
                ));
            }
        }
        if let (Some(a), Some(b)) = (o.precision, f.precision) {
            if a != b {
                return Err(conflict(
                    "--precision",
                    a.name().into(),
                    "precision",
                    format!("{:?}", b.name()),
                ));
            }
        }
        if let Some(t) = o.tolerance {
            if let Some(dt) = f.dt {
                return Err(conflict(
                    "--tolerance",
                    format!("{t:e}"),
                    "dt",
                    format!("{dt:e} (a fixed step)"),
                ));
            }
            if let Some(b) = f.tolerance.filter(|b| *b != t) {
                return Err(conflict(
                    "--tolerance",
                    format!("{t:e}"),
                    "tolerance",
                    format!("{b:e}"),
                ));
            }
        }
        Ok(())
    }

    /// The step (s) for this chain; `None` when nothing can collide.
    pub fn dt(&self, chain: &Chain) -> Option<f64> {
        chain.time_scale().map(|tc| self.step_for(tc, chain))
    }

    /// Contact events a run may see: 1 on a free line (the tolerance holds
    /// for its one collision sequence); on a pendulum one per contact every
    /// half swing over the duration. Their errors add up, so each event gets
    /// the tolerance divided by their number.
    pub fn events(&self, chain: &Chain) -> f64 {
        if chain.is_pendulum() {
            let half_swings = (chain.omega() * self.max_time / std::f64::consts::PI).max(1.0);
            half_swings * chain.k.len() as f64
        } else {
            1.0
        }
    }

    /// The step (s) for a chain of time scale `tc`.
    fn step_for(&self, tc: f64, chain: &Chain) -> f64 {
        self.step_factor
            * match self.step {
                StepRule::Dt(dt) => dt,
                StepRule::Tolerance(tol) => {
                    let tol = tol / self.events(chain);
                    let (c, q) = error_model(self.method);
                    let mut per_contact = (c / tol).powf(1.0 / q);
                    if let Some(a) = coarse_error_model(self.method) {
                        let p = self.method.order() as f64;
                        per_contact = per_contact.max((a / tol).powf(1.0 / p));
                    }
                    tc / per_contact.max(MIN_STEPS_PER_CONTACT)
                }
            }
    }

    /// The same solver with every step twice as long: the coarse run of a
    /// per-scene error estimate.
    pub fn coarse(&self) -> Solver {
        Solver {
            step_factor: 2.0 * self.step_factor,
            ..self.clone()
        }
    }

    /// Error estimate of a run from its coarse twin (Richardson): the
    /// difference of the outcome velocities over 2^q − 1, relative to v_in.
    pub fn error_estimate(&self, fine: &[f64], coarse: &[f64], v_in: f64) -> f64 {
        let q = error_model(self.method).1;
        let d = fine
            .iter()
            .zip(coarse)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        d / ((2f64.powf(q) - 1.0) * v_in)
    }

    /// Expected cost of running `chain` (loop iterations, roughly): steps per
    /// contact event × events × substeps × bodies, plus a pendulum's free
    /// flight. Only its proportions matter (shard balancing).
    pub fn expected_cost(&self, chain: &Chain) -> f64 {
        if self.model != Model::Hertz {
            return 1.0;
        }
        let (Some(plan), Some(tc)) = (self.step_plan(chain), chain.time_scale()) else {
            return 1.0;
        };
        let nb = chain.n_bodies() as f64;
        let per_event = tc / plan.h;
        let events = if chain.is_pendulum() {
            self.events(chain)
        } else {
            nb - 1.0
        };
        let free = if chain.is_pendulum() {
            self.max_time / plan.h_free
        } else {
            0.0
        };
        1.0 + (per_event * events + free) * plan.weights.len() as f64 * nb
    }

    /// How this chain is stepped; `None` when nothing can collide.
    pub fn step_plan(&self, chain: &Chain) -> Option<StepPlan> {
        let tc = chain.time_scale()?;
        let h = self.step_for(tc, chain);
        let p = self.method.order();
        // The p-th derivative of δ^{3/2} grows as T^{3/2−p} at time T from a
        // kink: steps h·(T/t_c)^{(p−3/2)/(p+1)} keep every local error below
        // h^{p+1} (0.5 for order 4, 0.64 for order 6). Measured on grid100,
        // 1/2 takes 7% fewer steps than 3/4 at equal worst error for the
        // order-6 methods too, so every graded method uses it. The step that
        // crosses a kink errs by ~s^{5/2}, mostly taken back by the kink
        // impulse correction (`integrate::kink_impulse_error`); with it
        // h_min = h·(h/t_c)^{0.8} takes 5–8% fewer kahanli6 steps at equal
        // worst error than h·(h/t_c) (0.6: more), the others unchanged.
        let h_min = h * (h / tc).min(1.0).powf(0.8);
        Some(StepPlan {
            h,
            weights: weights(self.method),
            graded: p > 2,
            h_min,
            grade_quarters: 2,
            t_scale: GRADING_SCALE * tc,
            settle_rel: match self.step {
                StepRule::Tolerance(tol) => SETTLE_FRACTION * tol,
                StepRule::Dt(_) => 0.0,
            },
            h_free: self.free_step(chain, h),
            exact: matches!(self.step, StepRule::Tolerance(_)) && !chain.needs_terms(),
            h_stiff: match self.step {
                StepRule::Tolerance(_) if p > 2 => STIFFNESS_STEP * h,
                _ => 0.0,
            },
            omega_ref: STIFFNESS_REF / tc,
        })
    }

    /// A pendulum's step (s) while no contact is closed: the phase error of
    /// the swings, c·(ω·H)^p per radian over ω·duration radians, is kept to
    /// half the tolerance (velocities err by about the phase error times
    /// v_in). Never shorter than the contact step `h`. A fixed `dt` is used
    /// everywhere.
    pub fn free_step(&self, chain: &Chain, h: f64) -> f64 {
        if !chain.is_pendulum() {
            return f64::INFINITY;
        }
        let w = chain.omega();
        let free = match self.step {
            StepRule::Dt(dt) => return self.step_factor * dt,
            StepRule::Tolerance(tol) => {
                let p = self.method.order() as f64;
                let radians = (w * self.max_time).max(1.0);
                let wh = (0.5 * tol / (swing_error_coeff(self.method) * radians)).powf(1.0 / p);
                self.step_factor * wh.min(MAX_SWING_STEP) / w
            }
        };
        free.max(h)
    }
}
