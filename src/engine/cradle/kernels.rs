//! The scalar kernels of the integrator that the shader repeats operation for
//! operation (same names in `shaders/cradle/lanes.wgsl` and `shaders/cradle/wide.wgsl`).

use super::*;

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

/// v += inc; in f32 with Kahan compensation (`cv` carries the lost low
/// bits): thousands of kicks 1e-4 the size of v would otherwise lose ~1e-4·v.
#[inline(always)]
pub(super) fn add<R: Real>(v: &mut R, cv: &mut R, inc: R) {
    if R::COMPENSATED {
        let y = inc - *cv;
        let t = *v + y;
        *cv = (t - *v) - y;
        *v = t;
    } else {
        *v = *v + inc;
    }
}

/// The step each lane takes now, at most `s0`. The Hertz force has a δ^{3/2} kink
/// where a contact opens or closes, which costs a high-order method its order;
/// steps are made small near every kink, on both sides: at time distance
/// T < t_c from a kink the step is h·(T/t_c)^(q/4) (the p-th derivative of
/// the force grows as T^{3/2−p}); at any distance it is at most T/2 before
/// the kink and 2T after it, never less than `h_min`, where a step crosses
/// the kink. A kink ahead is the first root of |δ| − r·t − a·t²/2 (r, a: the
/// pair's speed and acceleration towards it; a comes from the neighbours'
/// pushes, so a contact that has just opened and is pushed shut again is seen
/// coming); one behind (moving away) is |δ|/|r| ago. Kinks at T ≥ 2·s0
/// restrict nothing. On a free line `s0` is h or the stiffness cap; on a
/// pendulum in free flight it is the long free-flight step, halved towards
/// each onset.
///
/// (T/t_c)^(q/4) grows with T, so the grading is evaluated once, at the
/// nearest kink: min over contacts of max(min(cap, h·g(T)), h_min) is
/// max(min(min cap, h·g(min T)), h_min), to the last bit.
///
/// Without branches (every lane at once); the same operations as
/// `graded_step` in the shader.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn graded_steps<R: Real, const L: usize>(
    nc: usize,
    d: &[[R; L]; MAX_BALLS],
    v: &[[R; L]; MAX_BALLS],
    acc: &Accel<'_, R, L>,
    s0: &[R; L],
    h: &[R; L],
    h_min: &[R; L],
    tc: &[R; L],
    quarters: u32,
) -> [R; L] {
    let zero = R::zero();
    let half = R::of(0.5);
    let inf = R::infinity();
    let mut cap = [inf; L];
    let mut near = [inf; L];
    for c in 0..nc {
        let fc = &acc.f[c];
        let (im_a, im_b) = (&acc.inv_m[c], &acc.inv_m[c + 1]);
        for l in 0..L {
            let r = v[c][l] - v[c + 1][l];
            let dc = d[c][l];
            // δ̈ of the pair: its neighbours' contact pushes and gravity.
            let left = if c > 0 { acc.f[c - 1][l] } else { zero };
            let right = if c + 1 < nc { acc.f[c + 1][l] } else { zero };
            let mut a = (left - fc[l]) * im_a[l] - (fc[l] - right) * im_b[l];
            if acc.pend {
                a = a + (acc.g[c][l] - acc.g[c + 1][l]);
            }
            // Distance to the kink, and speed and acceleration towards it.
            let dd = dc.abs();
            let (rr, aa) = if dc > zero { (-r, -a) } else { (r, a) };
            let disc = rr * rr + (aa + aa) * dd;
            let den = rr + hi(disc, zero).sqrt();
            let ahead = if disc >= zero && den > zero {
                (dd + dd) / den
            } else {
                inf
            };
            let behind = if rr < zero { dd / -rr } else { inf };
            let tk = lo(ahead, behind);
            let skip = tk >= s0[l] + s0[l];
            let cc = lo(ahead * half, behind + behind);
            cap[l] = if skip { cap[l] } else { lo(cap[l], cc) };
            near[l] = if skip { near[l] } else { lo(near[l], tk) };
        }
    }
    let mut s = *s0;
    for l in 0..L {
        let q = (near[l] / tc[l]).sqrt().sqrt();
        let mut g = R::one();
        for _ in 0..quarters {
            g = g * q;
        }
        let graded = if near[l] < tc[l] {
            lo(cap[l], h[l] * g)
        } else {
            cap[l]
        };
        s[l] = lo(s[l], hi(graded, h_min[l]));
    }
    s
}

/// What the pairs' relative accelerations are made of: the contact forces
/// at the start of the step, the inverse masses, and (pendulum) gravity.
pub(super) struct Accel<'a, R, const L: usize> {
    pub(super) f: &'a [[R; L]; MAX_BALLS],
    pub(super) inv_m: &'a [[R; L]; MAX_BALLS],
    pub(super) g: &'a [[R; L]; MAX_BALLS],
    pub(super) pend: bool,
}

/// min and max without the NaN care of `f64::min`: one instruction each.
/// A NaN anywhere ends the run as non-finite before it matters.
#[inline(always)]
pub(super) fn lo<R: Real>(a: R, b: R) -> R {
    if b < a {
        b
    } else {
        a
    }
}

#[inline(always)]
pub(super) fn hi<R: Real>(a: R, b: R) -> R {
    if b > a {
        b
    } else {
        a
    }
}

/// The stiffness cap of every lane: `s0` at most h_stiff/Λ^{1/4} (not below
/// h_min), Λ = max_b (stiff_r_{b−1}·δ⁺_{b−1} + stiff_l_b·δ⁺_b) bounding
/// (ω/ω_ref)⁴, ω the chain's fastest local frequency
/// ([`super::Chain::stiffness_coefficients`]). No cap while every contact is
/// open or where h_stiff is 0. The same operations as `stiffness_cap` in the
/// shader.
#[inline(always)]
pub(super) fn stiffness_cap<R: Real, const L: usize>(
    nc: usize,
    d: &[[R; L]; MAX_BALLS],
    sl: &[[R; L]; MAX_BALLS],
    sr: &[[R; L]; MAX_BALLS],
    h_stiff: &[R; L],
    h_min: &[R; L],
    s0: &mut [R; L],
) {
    let zero = R::zero();
    let mut lam = [zero; L];
    let mut right = [zero; L]; // the row's part from the contact on the left
    for c in 0..nc {
        for l in 0..L {
            let dp = hi(d[c][l], zero);
            lam[l] = hi(lam[l], right[l] + sl[c][l] * dp);
            right[l] = sr[c][l] * dp;
        }
    }
    for l in 0..L {
        let lm = hi(lam[l], right[l]);
        let cap = hi(h_stiff[l] / lm.sqrt().sqrt(), h_min[l]);
        if lm > zero && h_stiff[l] > zero && cap < s0[l] {
            s0[l] = cap;
        }
    }
}

/// Kick sizes of a step, in units of the step, for substep weights w_0..w_{n−1}:
/// w_0/2, (w_0 + w_1)/2, …, (w_{n−2} + w_{n−1})/2, w_{n−1}/2. Substep i's
/// closing half kick and substep i+1's opening one use the same forces, so
/// they are one kick: n + 1 kicks a step instead of 2n. The shader gets the
/// same numbers from the host.
pub fn kick_weights(weights: &[f64]) -> Vec<f64> {
    let n = weights.len();
    (0..=n)
        .map(|i| {
            let before = if i > 0 { weights[i - 1] } else { 0.0 };
            let after = if i < n { weights[i] } else { 0.0 };
            0.5 * (before + after)
        })
        .collect()
}

/// The impulse per second of step that a step misses on a contact whose
/// overlap crossed zero during it, from d0 to d1: the exact integral of
/// k·δ⁺^{3/2} along a straight line from d0 to d1, (2/5)·k·(d1⁺^{5/2} −
/// d0⁺^{5/2})/(d1 − d0), minus the composition's quadrature of it (the force
/// at each drift position P_i, weighted by the kick there, [`kick_weights`]).
/// Near the kink the contact's own force is tiny and δ is straight to high
/// order, so this is the leading error of the crossing step, ∝ s^{5/2}; the
/// same operations as `kink_impulse_error` in the shader.
#[inline(always)]
pub fn kink_impulse_error<R: Real>(k: R, d0: R, d1: R, weights: &[f64], kicks: &[f64]) -> R {
    let zero = R::zero();
    let dd = d1 - d0;
    let p0 = hi(d0, zero);
    let p1 = hi(d1, zero);
    let exact = R::of(0.4) * (p1 * p1 * p1.sqrt() - p0 * p0 * p0.sqrt()) / dd;
    let mut pos = zero;
    let mut quad = R::of(kicks[0]) * (p0 * p0.sqrt());
    for (&w, &kw) in weights.iter().zip(&kicks[1..]) {
        pos = pos + R::of(w);
        let p = hi(d0 + pos * dd, zero);
        quad = quad + R::of(kw) * (p * p.sqrt());
    }
    k * (exact - quad)
}
