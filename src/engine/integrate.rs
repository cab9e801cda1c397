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
//!
//! Pendulum (`Chain::is_pendulum`): every body feels −g·sin(x_b/L), with x_b
//! rebuilt from body 0's displacement and the overlaps. Free flight is then
//! stepped with the long steps `StepPlan::h_free` (chosen from the tolerance
//! and the duration), halving them towards each contact onset, and the run
//! ends exactly at the duration. Damping: Hunt–Crossley contacts
//! (`contact::contact_force`, χ set from each contact's closing speed when it
//! closes, lowered if it is later driven closed faster) and air drag (the exact decay e^{−γ·s} in every kick).

use super::contact::{contact_force, hertz_force};
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

struct State<R> {
    v: [R; MAX_BALLS],
    /// Kahan compensation of `v` (f32 only).
    cv: [R; MAX_BALLS],
    d: [R; MAX_BALLS],
    /// Kahan compensation of `d` (f32 only).
    cd: [R; MAX_BALLS],
    /// Contact forces (N).
    f: [R; MAX_BALLS],
    /// Gravity accelerations of the bodies (pendulum; m/s²).
    acc: [R; MAX_BALLS],
    /// Hunt–Crossley χ of each contact (s/m), set while it is open.
    chi: [R; MAX_BALLS],
    /// Overlaps at the start of the step (onset counting).
    d0: [R; MAX_BALLS],
    /// Displacement of body 0 (m) and its compensation.
    x0: [R; 1],
    cx0: [R; 1],
}

/// sin θ for the pendulum force: θ reduced to [−π/2, π/2], then Taylor to θ^21
/// (error < 2e-18), the same operations as `pendulum_sin` in the shader
/// (SPIR-V has no f64 sin).
#[inline(always)]
pub fn pendulum_sin<R: Real>(th: R) -> R {
    use std::f64::consts::{FRAC_PI_2, PI, TAU};
    let mut x = th - R::of(TAU) * (th / R::of(TAU) + R::of(0.5)).floor();
    if x > R::of(FRAC_PI_2) {
        x = R::of(PI) - x;
    } else if x < -R::of(FRAC_PI_2) {
        x = -R::of(PI) - x;
    }
    let x2 = x * x;
    let mut p = R::one();
    for n in (1..=10u32).rev() {
        p = R::one() - x2 * p / R::of((2 * n * (2 * n + 1)) as f64);
    }
    x * p
}

/// e^{−y} for y ≥ 0 (air drag over a kick): halve y below 1/16, Taylor to y^9,
/// square back; the same operations as `decay` in the shader (SPIR-V has no
/// f64 exp).
#[inline(always)]
pub fn decay<R: Real>(y: R) -> R {
    let mut z = y;
    let mut k = 0u32;
    while z > R::of(0.0625) && k < 64 {
        z = z * R::of(0.5);
        k += 1;
    }
    let mut p = R::one();
    for n in (1..=9u32).rev() {
        p = R::one() - z * p / R::of(n as f64);
    }
    for _ in 0..k {
        p = p * p;
    }
    p
}

/// Constants of one run, in the run's precision.
struct Consts<R> {
    nb: usize,
    nc: usize,
    inv_m: [R; MAX_BALLS],
    gap: [R; MAX_BALLS],
    pend: bool,
    damped: bool,
    dragged: bool,
    g: R,
    inv_l: R,
    drag: R,
}

/// Half a kick of `hh` seconds: air drag (exact decay), then contact forces
/// and gravity. Body b is pushed left by contact b and right by contact b−1.
#[inline(always)]
fn kick<R: Real>(k: &Consts<R>, s: &mut State<R>, hh: R) {
    let nb = k.nb;
    if k.dragged {
        let q = decay(k.drag * hh);
        for b in 0..nb {
            s.v[b] = s.v[b] * q;
            s.cv[b] = s.cv[b] * q;
        }
    }
    let inv_m = &k.inv_m;
    push(k, s, 0, -(hh * s.f[0] * inv_m[0]), hh);
    for b in 1..nb - 1 {
        push(k, s, b, hh * (s.f[b - 1] - s.f[b]) * inv_m[b], hh);
    }
    push(k, s, nb - 1, hh * s.f[nb - 2] * inv_m[nb - 1], hh);
}

/// Body b's share of a kick: the contact push `inc`, plus gravity on a pendulum
/// (added after, as in the shader's `push`).
#[inline(always)]
fn push<R: Real>(k: &Consts<R>, s: &mut State<R>, b: usize, inc: R, hh: R) {
    let inc = if k.pend { inc + hh * s.acc[b] } else { inc };
    add(&mut s.v, &mut s.cv, b, inc);
}

/// v[b] += inc; in f32 with Kahan compensation (`cv` carries the lost low
/// bits): thousands of kicks 1e-4 the size of v would otherwise lose ~1e-4·v.
#[inline(always)]
fn add<R: Real, const N: usize>(v: &mut [R; N], cv: &mut [R; N], b: usize, inc: R) {
    if R::COMPENSATED {
        let y = inc - cv[b];
        let t = v[b] + y;
        cv[b] = (t - v[b]) - y;
        v[b] = t;
    } else {
        v[b] = v[b] + inc;
    }
}

/// Forces of every contact from the overlaps (and, damped, the closing
/// speeds); gravity from the displacements on a pendulum. Returns whether any
/// contact is closed.
#[inline(always)]
fn forces<R: Real>(k: &Consts<R>, kc: &[R; MAX_BALLS], s: &mut State<R>) -> bool {
    let mut closed = false;
    for c in 0..k.nc {
        s.f[c] = if k.damped {
            contact_force(kc[c], s.d[c], s.chi[c], s.v[c] - s.v[c + 1])
        } else {
            hertz_force(kc[c], s.d[c])
        };
        closed |= s.d[c] > R::zero();
    }
    if k.pend {
        let mut x = s.x0[0];
        s.acc[0] = -(k.g * pendulum_sin(x * k.inv_l));
        for b in 1..k.nb {
            x = x - k.gap[b - 1] - s.d[b - 1];
            s.acc[b] = -(k.g * pendulum_sin(x * k.inv_l));
        }
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
    /// Pendulum: the step (s) while every contact is open; unused on a free line.
    pub h_free: f64,
}

/// The step to take now, at most `s0`. The Hertz force has a δ^{3/2} kink
/// where a contact opens or closes, which costs a high-order method its order;
/// steps are made small near every kink, on both sides: at time distance
/// T = |δ|/|r| < t_c from a kink the step is h·(T/t_c)^(q/4) (the p-th
/// derivative of the force grows as T^{3/2−p}); at any distance it is at most
/// T/2 before the kink and 2T after it, never less than `h_min`, where a step
/// crosses the kink. On a free line `s0 = h`; on a pendulum in free flight
/// `s0` is the long free-flight step, halved towards each onset.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn graded_step<R: Real>(
    nc: usize,
    d: &[R; MAX_BALLS],
    v: &[R; MAX_BALLS],
    s0: R,
    h: R,
    h_min: R,
    tc: R,
    quarters: u32,
) -> R {
    let zero = R::zero();
    let half = R::of(0.5);
    let mut s = s0;
    for c in 0..nc {
        let r = v[c] - v[c + 1];
        let dc = d[c];
        let ar = r.abs();
        if ar <= zero {
            continue;
        }
        let tk = dc.abs() / ar;
        if tk >= s + s {
            continue; // no restriction from this contact
        }
        let ahead = (dc < zero && r > zero) || (dc > zero && r < zero);
        // Halve the distance to a kink ahead, at most double the distance
        // from one behind: no substep (Yoshida's step backwards included)
        // reaches across a kink until the step is down to h_min.
        let cap = if ahead { tk * half } else { tk + tk };
        let mut sc = cap;
        if tk < tc {
            let q = (tk / tc).sqrt().sqrt();
            let mut g = R::one();
            for _ in 0..quarters {
                g = g * q;
            }
            sc = sc.min(h * g);
        }
        s = s.min(sc.max(h_min));
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
    // Work a scene does not need is not compiled in: an elastic free line
    // runs a variant without the gravity, damping and drag terms.
    if ch.is_pendulum() || ch.is_dissipative() {
        integrate_terms::<R, O, true>(ch, plan, lim, obs)
    } else {
        integrate_terms::<R, O, false>(ch, plan, lim, obs)
    }
}

/// [`integrate`] with (`TERMS`) or without the pendulum and damping terms.
fn integrate_terms<R: Real, O: Observer, const TERMS: bool>(
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
        acc: [zero; MAX_BALLS],
        chi: [zero; MAX_BALLS],
        d0: [zero; MAX_BALLS],
        x0: [R::of(ch.x0[0])],
        cx0: [zero],
    };
    let mut kn = Consts {
        nb,
        nc,
        inv_m: [zero; MAX_BALLS],
        gap: [zero; MAX_BALLS],
        pend: TERMS && ch.is_pendulum(),
        damped: TERMS && ch.damping_a > 0.0,
        dragged: TERMS && ch.air_drag > 0.0,
        g: R::of(ch.gravity),
        inv_l: R::of(if ch.is_pendulum() {
            1.0 / ch.length
        } else {
            0.0
        }),
        drag: R::of(ch.air_drag),
    };
    let mut inv_r = [0.0f64; MAX_BALLS];
    for b in 0..nb {
        s.v[b] = R::of(ch.v0[b]);
        kn.inv_m[b] = R::of(1.0 / ch.mass[b]);
    }
    let d_init = ch.initial_overlap();
    for c in 0..nc {
        s.d[c] = R::of(d_init[c]);
        kn.gap[c] = R::of(ch.gap[c]);
        inv_r[c] = 1.0 / ch.r_min[c];
    }
    let kc = {
        let mut k = [zero; MAX_BALLS];
        for c in 0..nc {
            k[c] = R::of(ch.k[c]);
        }
        k
    };
    let pend = kn.pend;
    // Body 0's displacement matters to gravity and to an observer; a free line
    // in a sweep does without (its displacements are not reported).
    let track_x = pend || O::ACTIVE;
    let hr = R::of(plan.h);
    let h_free = R::of(plan.h_free);
    let h_min = R::of(plan.h_min);
    let t_scale = R::of(plan.t_scale);
    let quarters = if plan.graded { plan.grade_quarters } else { 0 };
    let a_e = R::of(ch.damping_a);
    let half = R::of(0.5);
    // Closing speeds at round-off level are noise, not an approach: without
    // this floor two balls left at ±1e-15 m/s would "collide" a billion years
    // later and hit the time cap.
    let v_floor = closing_speed_floor::<R>(ch.v_in(), plan.settle_rel);
    let mut t = 0.0f64;
    let mut steps = 0u64;
    let mut contacts = 0u64;
    let mut closed = forces(&kn, &kc, &mut s);
    let (mut t_first, mut t_release) = (None, None);
    let (mut max_ov, mut max_ratio) = (0.0f64, 0.0f64);
    let observe = |t: f64, s: &State<R>, obs: &mut O| {
        if O::ACTIVE {
            let d: Vec<f64> = s.d[..nc].iter().map(|d| d.to64()).collect();
            let x = ch.positions(s.x0[0].to64(), &d);
            let v: Vec<f64> = s.v[..nb].iter().map(|v| v.to64()).collect();
            obs.state(t, &x, &v);
        }
    };
    observe(t, &s, obs);

    let end = loop {
        if !closed && !pend {
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
                if track_x {
                    s.x0[0] = s.x0[0] + s.v[0] * tau;
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
        if pend && t >= lim.max_time {
            break End::Duration;
        }
        if steps >= lim.max_steps {
            break End::StepCap;
        }
        if t >= lim.max_time {
            break End::TimeCap;
        }
        // The step: graded near kinks; on a pendulum long in free flight and
        // landing exactly on the duration.
        let mut step = if pend {
            graded_step(
                nc,
                &s.d,
                &s.v,
                if closed { hr } else { h_free },
                hr,
                h_min,
                t_scale,
                quarters,
            )
        } else if plan.graded {
            graded_step(nc, &s.d, &s.v, hr, hr, h_min, t_scale, quarters)
        } else {
            hr
        };
        let mut last = false;
        if pend {
            let rest = R::of(lim.max_time - t);
            if rest <= step {
                step = rest;
                last = true;
            }
        }
        for c in 0..nc {
            s.d0[c] = s.d[c];
            if kn.damped {
                // Hunt–Crossley: χ = a/v_imp, v_imp the closing speed the contact
                // closes with — or, if it is driven harder while closed (a gentle
                // touch, then a hit from behind), the largest closing speed since.
                let chi = a_e / (s.v[c] - s.v[c + 1]).max(v_floor);
                s.chi[c] = if s.d[c] <= zero {
                    chi
                } else {
                    s.chi[c].min(chi)
                };
            }
        }
        // One step: velocity-Verlet substeps (kick, drift, forces, kick).
        for &w in plan.weights {
            let ws = R::of(w) * step;
            let hh = ws * half;
            kick(&kn, &mut s, hh);
            for c in 0..nc {
                add(&mut s.d, &mut s.cd, c, ws * (s.v[c] - s.v[c + 1]));
            }
            if track_x {
                add(&mut s.x0, &mut s.cx0, 0, ws * s.v[0]);
            }
            closed = forces(&kn, &kc, &mut s);
            kick(&kn, &mut s, hh);
        }
        let h = step.to64();
        let t_start = t;
        t = if last { lim.max_time } else { t + h };
        steps += 1;
        // Onsets, overlaps, releases (located inside the step by linear
        // interpolation of δ; graded methods land on them anyway).
        for c in 0..nc {
            let (d0, d1) = (s.d0[c], s.d[c]);
            if d1 > zero {
                if d0 <= zero {
                    contacts += 1;
                    t_first.get_or_insert(t_start);
                }
                let d = d1.to64();
                if d > max_ov {
                    max_ov = d;
                }
                max_ratio = max_ratio.max(d * inv_r[c]);
            } else if d0 > zero {
                let (d0, d1) = (d0.to64(), d1.to64());
                let tr = t_start + h * d0 / (d0 - d1);
                t_release = Some(t_release.map_or(tr, |x: f64| x.max(tr)));
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
    let x = if track_x {
        ch.positions(s.x0[0].to64(), &overlap)
    } else {
        vec![f64::NAN; nb]
    };
    let settled = matches!(end, End::Settled | End::Duration);
    let end = if settled
        && (v.iter().chain(&overlap).any(|x| !x.is_finite())
            || track_x && x.iter().any(|x| !x.is_finite()))
    {
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
        x,
        contacts,
    }
}
