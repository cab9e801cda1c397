//! The integrator — the one place on the Rust side that advances a chain in
//! time. Its WGSL twin is `shaders/integrate.wgsl` (same function names).
//!
//! State, in contact coordinates: the overlap δ_c of every contact and the
//! velocity v_b of every body. Forces depend only on δ, so nothing is ever
//! computed from large absolute positions (in f32, x_i − x_{i+1} of two
//! positions that have drifted a metre loses every digit of a 10 µm overlap).
//!
//! Work a scene does not need is skipped: while every contact is open the chain
//! is in free flight and is advanced analytically to the next contact onset
//! (0 steps); the run ends as soon as no contact is closed and none is closing.

use super::contact::hertz_force;
use super::real::Real;
use super::Chain;
use crate::scene::MAX_BALLS;

/// Closing speeds below [`Real::FLOOR_ULPS`] ulps of v_in count as zero:
/// round-off, not an approach. Both backends start from this value.
///
/// With a tolerance, closing speeds below `settle_rel`·v_in count as zero too:
/// the velocities themselves are only that accurate, and a collision at
/// closing speed r changes them by about r. Without this, residuals of 1e-9·v
/// left by exact exchanges "collide" 10^7 s later and hit the time cap.
pub fn closing_speed_floor<R: Real>(v_in: f64, settle_rel: f64) -> R {
    (R::of(R::FLOOR_ULPS) * R::epsilon() * R::of(v_in)).max(R::of(settle_rel * v_in))
}

/// A velocity at or above this magnitude (m/s) counts as non-finite; the
/// shader has no `isfinite`, so both twins use this test.
pub const FINITE_LIMIT: f64 = 1e30;

/// Why a run stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum End {
    /// Every contact open and no two bodies approaching: no collision can follow.
    Settled,
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
}

struct State<R> {
    v: [R; MAX_BALLS],
    /// Kahan compensation of `v` (f32 only).
    cv: [R; MAX_BALLS],
    d: [R; MAX_BALLS],
    /// Kahan compensation of `d` (f32 only).
    cd: [R; MAX_BALLS],
    f: [R; MAX_BALLS],
    x0: f64,
}

#[inline(always)]
fn kick<R: Real>(
    nb: usize,
    v: &mut [R; MAX_BALLS],
    cv: &mut [R; MAX_BALLS],
    f: &[R; MAX_BALLS],
    inv_m: &[R; MAX_BALLS],
    hh: R,
) {
    // Body b is pushed left by contact b and right by contact b−1.
    add(v, cv, 0, -(hh * f[0] * inv_m[0]));
    for b in 1..nb - 1 {
        add(v, cv, b, hh * (f[b - 1] - f[b]) * inv_m[b]);
    }
    add(v, cv, nb - 1, hh * f[nb - 2] * inv_m[nb - 1]);
}

/// v[b] += inc; in f32 with Kahan compensation (`cv` carries the lost low
/// bits): thousands of kicks 1e-4 the size of v would otherwise lose ~1e-4·v.
#[inline(always)]
fn add<R: Real>(v: &mut [R; MAX_BALLS], cv: &mut [R; MAX_BALLS], b: usize, inc: R) {
    if R::COMPENSATED {
        let y = inc - cv[b];
        let t = v[b] + y;
        cv[b] = (t - v[b]) - y;
        v[b] = t;
    } else {
        v[b] = v[b] + inc;
    }
}

/// Forces of every contact from the overlaps; returns the largest overlap
/// relative to the boundary radius, and whether any contact is closed.
#[inline(always)]
fn forces<R: Real>(
    nc: usize,
    d: &[R; MAX_BALLS],
    k: &[R; MAX_BALLS],
    f: &mut [R; MAX_BALLS],
) -> bool {
    let mut closed = false;
    for c in 0..nc {
        f[c] = hertz_force(k[c], d[c]);
        closed |= d[c] > R::zero();
    }
    closed
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
}

/// The step to take now. The Hertz force has a δ^{3/2} kink where a contact
/// opens or closes, which costs a high-order method its order; steps are made
/// small near every kink, on both sides: at time distance T = |δ|/|r| from a
/// kink the step is h·(T/t_c)^(q/4) (the p-th derivative of the force grows as
/// T^{3/2−p}), at most T/2 before the kink and 2T after it, never less than
/// `h_min`, where a step crosses the kink.
#[inline(always)]
pub fn graded_step<R: Real>(
    nc: usize,
    d: &[R; MAX_BALLS],
    v: &[R; MAX_BALLS],
    h: R,
    h_min: R,
    tc: R,
    quarters: u32,
) -> R {
    let zero = R::zero();
    let half = R::of(0.5);
    let mut s = h;
    for c in 0..nc {
        let r = v[c] - v[c + 1];
        let dc = d[c];
        let ar = r.abs();
        if ar <= zero {
            continue;
        }
        let tk = dc.abs() / ar;
        if tk >= tc || tk >= s + s {
            continue; // no restriction from this contact
        }
        let ahead = (dc < zero && r > zero) || (dc > zero && r < zero);
        let q = (tk / tc).sqrt().sqrt();
        let mut g = R::one();
        for _ in 0..quarters {
            g = g * q;
        }
        // Halve the distance to a kink ahead, at most double the distance
        // from one behind: no substep (Yoshida's step backwards included)
        // reaches across a kink until the step is down to h_min.
        let cap = if ahead { tk * half } else { tk + tk };
        let sc = (h * g).min(cap).max(h_min);
        s = s.min(sc);
    }
    s
}

/// Integrate a chain between contact events with the steps of `plan`, in
/// precision `R`. See the module doc for what is skipped.
pub fn integrate<R: Real, O: Observer>(
    ch: &Chain,
    plan: &StepPlan,
    lim: &Limits,
    obs: &mut O,
) -> Run {
    let nb = ch.n_bodies();
    let nc = nb - 1;
    let zero = R::zero();
    let mut s = State {
        v: [zero; MAX_BALLS],
        cv: [zero; MAX_BALLS],
        cd: [zero; MAX_BALLS],
        d: [zero; MAX_BALLS],
        f: [zero; MAX_BALLS],
        x0: 0.0,
    };
    let mut inv_m = [zero; MAX_BALLS];
    let mut k = [zero; MAX_BALLS];
    let mut inv_r = [0.0f64; MAX_BALLS];
    for b in 0..nb {
        s.v[b] = R::of(ch.v0[b]);
        inv_m[b] = R::of(1.0 / ch.mass[b]);
    }
    for c in 0..nc {
        s.d[c] = R::of(-ch.gap[c]);
        k[c] = R::of(ch.k[c]);
        inv_r[c] = 1.0 / ch.r_min[c];
    }
    let hr = R::of(plan.h);
    let h_min = R::of(plan.h_min);
    let t_scale = R::of(plan.t_scale);
    let half = R::of(0.5);
    // Closing speeds at round-off level are noise, not an approach: without
    // this floor two balls left at ±1e-15 m/s would "collide" a billion years
    // later and hit the time cap.
    let v_floor = closing_speed_floor::<R>(ch.v_in(), plan.settle_rel);
    let mut t = 0.0f64;
    let mut steps = 0u64;
    let mut closed = false;
    let (mut t_first, mut t_release) = (None, None);
    let (mut max_ov, mut max_ratio) = (0.0f64, 0.0f64);
    let observe = |t: f64, s: &State<R>, obs: &mut O| {
        if O::ACTIVE {
            let mut x = vec![s.x0; nb];
            for c in 0..nc {
                x[c + 1] = x[c] - ch.gap[c] - s.d[c].to64();
            }
            let v: Vec<f64> = s.v[..nb].iter().map(|v| v.to64()).collect();
            obs.state(t, &x, &v);
        }
    };
    observe(t, &s, obs);

    let end = loop {
        if !closed {
            // Free flight: every contact open. Jump to the next onset, if any.
            let mut tau = R::infinity();
            let mut next = None;
            for c in 0..nc {
                let r = s.v[c] - s.v[c + 1];
                if r > v_floor {
                    let dt = -s.d[c] / r;
                    if dt < tau {
                        tau = dt;
                        next = Some(c);
                    }
                }
            }
            let Some(next) = next else { break End::Settled };
            let mut tau64 = tau.to64();
            let capped = t + tau64 > lim.max_time;
            if capped {
                tau64 = (lim.max_time - t).max(0.0);
                tau = R::of(tau64);
            }
            if tau > zero {
                for c in 0..nc {
                    s.d[c] = s.d[c] + (s.v[c] - s.v[c + 1]) * tau;
                }
                if O::ACTIVE {
                    s.x0 += s.v[0].to64() * tau64;
                }
                t += tau64;
                observe(t, &s, obs);
            }
            if capped {
                break End::TimeCap;
            }
            s.d[next] = zero; // the onset, exactly
            s.cd[next] = zero;
            t_first.get_or_insert(t);
        }
        if steps >= lim.max_steps {
            break End::StepCap;
        }
        if t >= lim.max_time {
            break End::TimeCap;
        }
        // One step: velocity-Verlet substeps (kick, drift, forces, kick).
        let step = if plan.graded {
            graded_step(nc, &s.d, &s.v, hr, h_min, t_scale, plan.grade_quarters)
        } else {
            hr
        };
        for &w in plan.weights {
            let ws = R::of(w) * step;
            let hh = ws * half;
            kick(nb, &mut s.v, &mut s.cv, &s.f, &inv_m, hh);
            for c in 0..nc {
                add(&mut s.d, &mut s.cd, c, ws * (s.v[c] - s.v[c + 1]));
            }
            if O::ACTIVE {
                s.x0 += s.v[0].to64() * ws.to64();
            }
            closed = forces(nc, &s.d, &k, &mut s.f);
            kick(nb, &mut s.v, &mut s.cv, &s.f, &inv_m, hh);
        }
        let h = step.to64();
        t += h;
        steps += 1;
        if closed {
            for c in 0..nc {
                let d = s.d[c].to64();
                if d > max_ov {
                    max_ov = d;
                }
                max_ratio = max_ratio.max(d * inv_r[c]);
            }
        } else {
            // Every contact just opened. With all forces now zero the last
            // drift velocity equals the final one (exactly so for Verlet), so δ
            // at the start of the step is recovered; locate each release by
            // linear interpolation (graded methods land on it anyway).
            for c in 0..nc {
                let d1 = s.d[c].to64();
                let d0 = d1 - h * (s.v[c] - s.v[c + 1]).to64();
                if d0 > 0.0 && d1 <= 0.0 {
                    let tr = t - h + h * d0 / (d0 - d1);
                    t_release = Some(t_release.map_or(tr, |x: f64| x.max(tr)));
                }
            }
        }
        observe(t, &s, obs);
        if s.v[..nb]
            .iter()
            .any(|v| v.is_nan() || v.abs() >= R::of(FINITE_LIMIT))
        {
            break End::NonFinite;
        }
    };
    let v: Vec<f64> = s.v[..nb].iter().map(|v| v.to64()).collect();
    let overlap: Vec<f64> = s.d[..nc].iter().map(|d| d.to64()).collect();
    let end = if end == End::Settled && (v.iter().chain(&overlap).any(|x| !x.is_finite())) {
        End::NonFinite
    } else {
        end
    };
    Run {
        end,
        v,
        overlap,
        steps,
        t,
        t_first_contact: t_first,
        t_last_release: t_release,
        max_overlap: max_ov,
        max_overlap_ratio: max_ratio,
    }
}
