//! Error control of chain runs (docs/SPEC.md §9 "Error control"): every
//! chain run is checked by a *twin* of itself, and rerun at finer steps
//! while the estimate says the tolerance is not met.
//!
//! A run at step h ends at t_end. Its twin runs the same chain to the same
//! t_end at step r·h (r = [`TWIN_RATIO`], or what a pulse's end on a step
//! boundary makes of it), with the local refinement where its own step
//! takes it (from t_s/[`super::REFINE_FROM`] down: coarser, the refinement
//! costs more than it gains). The difference Δ of the two outcomes in the metric of
//! results/chains.md ([`difference`]: the probes' peak times / t_end and
//! peak velocities / v, every bead's final velocity / v) gives the run's
//! error estimate Δ/(r^q − 1) ([`estimate`], Richardson with an order q
//! calibrated against an independent reference, lower than the methods'
//! so that it errs on the high side where the error does not yet fall at
//! the method's order: [`order`]).
//! Under a tolerance, a run whose estimate is above it
//! is rerun at a finer step ([`next_step`]); the previous run is the new
//! one's twin, so a rerun costs one run. After [`MAX_RERUNS`] reruns (or
//! the step cap) a row whose estimate is still above its tolerance says so
//! ([`verdict`]): `sensitive` when halving the step no longer shrank the
//! difference (the outcome depends on round-off-sized changes: chaotic
//! scattering), `inaccurate` otherwise.

use super::ChainOutcome;
use crate::engine::Status;

/// The twin's step over the run's.
pub const TWIN_RATIO: f64 = 2.0;
/// The orders the estimate assumes (docs/SPEC.md §9), calibrated on the
/// family of results/chains.md against an independent reference (scipy's
/// DOP853 with every contact's opening and closing located), so that the
/// estimate is at least a third of the finer run's true error on every pair
/// the reference resolves. Without the local refinement a kink's error
/// depends on where in its step the contact crosses: the error scatters
/// ~10× about its ~h^3 trend, and only q = 2 kept the estimate above a
/// third (0.43 of the true error at worst, on the pairs that differ by less
/// than 1e-3; 0.26 on pairs whose errors are ~0.1).
pub const ESTIMATE_ORDER: f64 = 2.0;
/// … with the refinement in both runs (the error falls as ~h^6): q = 4
/// (0.53 at worst) …
pub const ESTIMATE_ORDER_REFINED: f64 = 4.0;
/// … and with the refinement in the finer run only (the twin of a run at
/// t_s/[`super::REFINE_FROM`]–t_s/180, coarser than where the refinement
/// pays): the refinement's own fitted order (`refined_error_model`), 6.2
/// (0.93 at worst: the unrefined twin errs 70–470× more than the run).
pub const ESTIMATE_ORDER_MIXED: f64 = 6.2;
/// Reruns at finer steps after the first run and its twin.
pub const MAX_RERUNS: usize = 3;
/// A rerun's step is at least this many times finer than the last one's …
pub const MIN_REFINE: f64 = 2.0;
/// … and at most this many.
pub const MAX_REFINE: f64 = 8.0;
/// The estimate aims this far below the tolerance when it picks a finer step.
pub const SAFETY: f64 = 0.5;

/// The largest difference between two runs of one chain that end at the
/// same time, in the metric of results/chains.md: each probe's peak time
/// over the run's length and its peak velocity over the velocity scale
/// `v_scale`, each bead's final velocity over `v_scale`. A peak one run saw
/// and the other did not, or anything not finite: infinite.
pub fn difference(v_scale: f64, a: &ChainOutcome, b: &ChainOutcome) -> f64 {
    let t = a.t_end;
    let mut d = 0.0f64;
    if a.probes.len() != b.probes.len() || a.v.len() != b.v.len() {
        return f64::INFINITY;
    }
    for (p, q) in a.probes.iter().zip(&b.probes) {
        match (p.arrival.is_nan(), q.arrival.is_nan()) {
            (true, true) => {}
            (false, false) => {
                d = d
                    .max((p.arrival - q.arrival).abs() / t)
                    .max((p.peak_velocity - q.peak_velocity).abs() / v_scale)
            }
            _ => return f64::INFINITY,
        }
    }
    for (x, y) in a.v.iter().zip(&b.v) {
        d = d.max((x - y).abs() / v_scale);
    }
    if d.is_finite() {
        d
    } else {
        f64::INFINITY
    }
}

/// The order the estimate of a pair assumes, from whether its finer and
/// its coarser run had the local refinement on.
pub fn order(fine: bool, coarse: bool) -> f64 {
    match (fine, coarse) {
        (true, true) => ESTIMATE_ORDER_REFINED,
        (true, false) => ESTIMATE_ORDER_MIXED,
        (false, _) => ESTIMATE_ORDER,
    }
}

/// The error estimate of the finer of two runs whose steps are in ratio
/// `r` > 1 and whose outcomes differ by `diff` ([`difference`]), of
/// [`order`] `q`: diff/(r^q − 1), r at most [`TWIN_RATIO`] (the ratio the
/// orders were calibrated at: a rerun 8× finer is not assumed 8^q times
/// better, only 2^q).
pub fn estimate(diff: f64, r: f64, q: f64) -> f64 {
    diff / (r.min(TWIN_RATIO).powf(q) - 1.0)
}

/// The step of the rerun after a run at step `h` whose estimate `est` (of
/// order `q`) is above `tol`: the step that order says meets [`SAFETY`]·tol,
/// at least [`MIN_REFINE`] and at most [`MAX_REFINE`] times finer.
pub fn next_step(h: f64, est: f64, tol: f64, q: f64) -> f64 {
    let f = (est / (SAFETY * tol)).powf(1.0 / q);
    h / f.clamp(MIN_REFINE, MAX_REFINE)
}

/// The status of a run whose estimate is `est` under tolerance `tol`,
/// `diffs` the differences of its successive pairs (first: the first run
/// and its twin): `ok` when the estimate meets the tolerance; else
/// `sensitive` when the last refinement did not halve the difference
/// (the outcome is not converging as the step shrinks), else `inaccurate`.
pub fn verdict(est: f64, tol: f64, diffs: &[f64]) -> Status {
    if est <= tol {
        return Status::Ok;
    }
    match diffs {
        [.., a, b] if *b > 0.5 * a => Status::Sensitive,
        _ => Status::Inaccurate,
    }
}
