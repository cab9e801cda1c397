//! One fixed step of a chain: a symmetric composition of Verlet substeps
//! (kick, drift, force, kick; the kicks between substeps merged), over the
//! window of beads that can move.
//!
//! **The window.** A bead at rest (v = 0) with no net force (a = 0) whose
//! neighbours are also at rest stays exactly as it is: its contacts do not
//! drift, their forces do not change. Within one step of s substeps a
//! disturbance spreads at most s + 1 beads (each substep: a drift changes
//! the contacts of moving beads, the force reaches the next bead, the kick
//! moves it). So the step works on the beads within [`MARGIN_EXTRA`] + s of
//! the first and last moving bead, and its results are those of a step
//! over the whole chain bit for bit (test: `window_changes_no_bit`). Ahead
//! of a solitary wave in an uncompressed chain, contacts touch at zero
//! overlap and feel nothing: the window ends a few beads ahead of the front,
//! where δ^{3/2} of the precursor underflows to zero.

use super::{hertz, Beads, Consts};
use crate::engine::real::Real;

/// Beads beyond the s + 1 a step can reach, kept in the window for safety.
pub const MARGIN_EXTRA: usize = 1;

/// A chain's state between steps, in the precision `R` of its run.
#[derive(Clone, Debug, PartialEq)]
pub struct State<R = f64> {
    /// Steps taken.
    pub steps: u64,
    /// Change of each contact's overlap from rest (m), contacts 0 ..= n.
    pub p: Vec<R>,
    /// Bead velocities (m/s).
    pub v: Vec<R>,
    /// Bead accelerations at this state (m/s²).
    pub a: Vec<R>,
    /// Excess force of each contact at this state (N): k·δ^{3/2} − f0.
    pub e: Vec<R>,
    /// Displacement of bead 0 from rest (m): the others follow from `p`.
    pub x0: R,
    /// The window: beads lo .. hi (contacts lo ..= hi).
    pub lo: usize,
    pub hi: usize,
    /// Scratch: `p` of contacts lo ..= hi at the start of the step being
    /// taken (for the kink correction, [`Substeps::kicks`]); nothing between
    /// steps.
    pub p_start: Vec<R>,
}

impl State<f64> {
    /// Displacement of every bead from rest (m): x_i = x_{i−1} − p_i.
    pub fn positions(&self) -> Vec<f64> {
        let mut x = Vec::with_capacity(self.v.len());
        let mut xi = self.x0;
        x.push(xi);
        for j in 1..self.v.len() {
            xi -= self.p[j];
            x.push(xi);
        }
        x
    }

    /// Force of contact j (N): k·δ^{3/2}, δ = δ0 + p.
    pub fn force(&self, b: &Beads, j: usize) -> f64 {
        self.e[j] + b.f0[j]
    }
}

impl<R: Real> State<R> {
    /// The chain at rest (or with its initial velocities), forces evaluated.
    pub fn start(b: &Beads, c: &Consts<R>, weights: &[f64], whole: bool) -> State<R> {
        let n = b.n;
        let zero = R::zero();
        let mut s = State {
            steps: 0,
            p: vec![zero; n + 1],
            v: b.v0.iter().map(|&v| R::of(v)).collect(),
            a: vec![zero; n],
            e: vec![zero; n + 1],
            x0: zero,
            lo: 0,
            hi: n,
            p_start: vec![zero; n + 1],
        };
        forces(c, &mut s, zero, pulse_on(c, zero));
        if !whole {
            s.shrink(c, weights.len(), zero);
        }
        s
    }

    /// The state in f64 (what traces, histories and the outcome read): the
    /// state itself when `R` is f64, else a converted copy.
    pub fn in_f64(&self) -> std::borrow::Cow<'_, State<f64>> {
        use std::borrow::Cow;
        if let Some(s) = (self as &dyn std::any::Any).downcast_ref::<State<f64>>() {
            return Cow::Borrowed(s);
        }
        let conv = |x: &[R]| x.iter().map(|x| x.to64()).collect::<Vec<f64>>();
        Cow::Owned(State {
            steps: self.steps,
            p: conv(&self.p),
            v: conv(&self.v),
            a: conv(&self.a),
            e: conv(&self.e),
            x0: self.x0.to64(),
            lo: self.lo,
            hi: self.hi,
            p_start: Vec::new(),
        })
    }

    /// Re-fit the window around the moving beads (`t`: the time now).
    fn shrink(&mut self, c: &Consts<R>, stages: usize, t: R) {
        // The pulse's bead stays in while the next step (from t) feels it.
        let pulse = c.pulse.as_ref().filter(|_| pulse_on(c, t)).map(|p| p.bead);
        let zero = R::zero();
        let moving = |i: usize| self.v[i] != zero || self.a[i] != zero || Some(i) == pulse;
        let first = (self.lo..self.hi).find(|&i| moving(i));
        let Some(first) = first else {
            (self.lo, self.hi) = (0, 0);
            if let Some(i) = pulse {
                (self.lo, self.hi) = (i, i + 1);
            }
            return;
        };
        let last = (first..self.hi).rev().find(|&i| moving(i)).unwrap_or(first);
        let m = stages + 1 + MARGIN_EXTRA;
        let pulse_lo = pulse.unwrap_or(usize::MAX);
        self.lo = first.min(pulse_lo).saturating_sub(m);
        self.hi = (last.max(pulse.unwrap_or(0)) + 1 + m).min(self.v.len());
    }
}

/// Whether the pulse pushes during the step that starts at `t0`: a step
/// that starts before the pulse ends feels sin(ωt) at every substep, even
/// one past τ (the sine's smooth continuation), and a step that starts at
/// or after τ feels nothing. With τ on a step boundary ([`super::plan`])
/// every step then integrates a smooth force, and the methods keep their
/// order; a step across τ would see the force's kink.
#[inline(always)]
pub fn pulse_on<R: Real>(c: &Consts<R>, t0: R) -> bool {
    c.pulse.as_ref().is_some_and(|p| t0 < p.duration)
}

/// Excess forces of contacts lo ..= hi and accelerations of beads lo .. hi
/// at time `t` (the pulse's phase; `on`: [`pulse_on`] of the step).
#[inline(always)]
fn forces<R: Real>(c: &Consts<R>, s: &mut State<R>, t: R, on: bool) {
    let (lo, hi) = (s.lo, s.hi);
    let e = &mut s.e[lo..=hi];
    let (k, d0, f0, p) = (&c.k[lo..=hi], &c.d0[lo..=hi], &c.f0[lo..=hi], &s.p[lo..=hi]);
    for j in 0..e.len() {
        e[j] = hertz(k[j], d0[j] + p[j]) - f0[j];
    }
    let a = &mut s.a[lo..hi];
    let im = &c.inv_mass[lo..hi];
    let e = &s.e[lo..=hi];
    for i in 0..a.len() {
        a[i] = (e[i] - e[i + 1]) * im[i];
    }
    if let Some(pl) = &c.pulse {
        if on && (lo..hi).contains(&pl.bead) {
            let f = pl.force * pulse_sin(t, pl.omega);
            s.a[pl.bead] = s.a[pl.bead] + f * pl.inv_mass;
        }
    }
}

/// 1/((2k)(2k+1)) for k = 10, 9, …, 1: the factors of [`half_sine`]'s Horner
/// scheme (the GPU twin has them as constants, printed from these).
pub const SINE_FACTORS: [f64; 10] = {
    let mut f = [0.0; 10];
    let mut i = 0;
    while i < 10 {
        let k = (10 - i) as f64;
        f[i] = 1.0 / ((2.0 * k) * (2.0 * k + 1.0));
        i += 1;
    }
    f
};

/// sin x for x in [−π/2, π] (what a half-sine pulse needs): x > π/2
/// reflected to π − x, then the Taylor series to x^21 by Horner with
/// multiplications only ([`SINE_FACTORS`]), each constant first in its
/// product, so the GPU twin gives the same bits (Mesa reassociates a
/// product to bring its constants together: (x²·p)·c became (x²·c)·p, and
/// pendulum_sin's division by a constant is not exact there either); error
/// < 1e-17 on [−π/2, π/2].
#[inline(always)]
pub fn half_sine<R: Real>(x: R) -> R {
    let x = if x > R::of(std::f64::consts::FRAC_PI_2) {
        R::of(std::f64::consts::PI) - x
    } else {
        x
    };
    let x2 = x * x;
    let one = R::one();
    let mut p = one;
    for f in SINE_FACTORS {
        p = one - R::of(f) * x2 * p;
    }
    x * p
}

/// sin(ωt) of a half-sine pulse, ω = π/τ (t within a step of [0, τ]).
#[inline(always)]
pub fn pulse_sin<R: Real>(t: R, omega: R) -> R {
    half_sine(omega * t)
}

/// cos(ωt) = sin(π/2 − ωt) of a half-sine pulse (0 ≤ t < τ).
#[inline(always)]
pub fn pulse_cos<R: Real>(t: R, omega: R) -> R {
    half_sine(R::of(std::f64::consts::FRAC_PI_2) - omega * t)
}

#[inline(always)]
fn kick<R: Real>(s: &mut State<R>, c: R) {
    let (lo, hi) = (s.lo, s.hi);
    for (v, &a) in s.v[lo..hi].iter_mut().zip(&s.a[lo..hi]) {
        *v = *v + c * a;
    }
}

/// p_j += dt·(v_{j−1} − v_j) for contacts lo ..= hi (walls do not move).
#[inline(always)]
fn drift<R: Real>(s: &mut State<R>, dt: R) {
    let n = s.v.len();
    let (lo, hi) = (s.lo, s.hi);
    if lo == hi {
        return;
    }
    let (a, z) = (lo.max(1), hi.min(n - 1));
    if a <= z {
        let (p, v) = (&mut s.p[a..=z], &s.v[a - 1..=z]);
        for j in 0..p.len() {
            p[j] = p[j] + dt * (v[j] - v[j + 1]);
        }
    }
    if lo == 0 {
        s.p[0] = s.p[0] - dt * s.v[0];
        s.x0 = s.x0 + dt * s.v[0];
    }
    if hi == n {
        s.p[n] = s.p[n] + dt * s.v[n - 1];
    }
}

/// One step from time `t0` to `t0 + h` with substep weights `w`; `whole`:
/// the window is the whole chain (the reference the window is tested against).
///
/// On x86-64 CPUs with AVX2 the same code is compiled for 4-wide vectors
/// (chosen at run time): the force loop's square roots are most of a
/// step's cost. The results are the same bits (IEEE square roots are
/// correctly rounded at any width, and no multiply-add is fused).
pub fn step<R: Real>(c: &Consts<R>, s: &mut State<R>, t0: R, h: R, m: &Substeps, whole: bool) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            return unsafe { step_avx2(c, s, t0, h, m, whole) };
        }
    }
    step_portable(c, s, t0, h, m, whole)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn step_avx2<R: Real>(
    c: &Consts<R>,
    s: &mut State<R>,
    t0: R,
    h: R,
    m: &Substeps,
    whole: bool,
) {
    step_portable(c, s, t0, h, m, whole)
}

/// A step's substeps: the composition's drift weights, and the kick
/// weights at the drift positions ([`crate::engine::integrate::kick_weights`])
/// when contacts that open or close in a step get the kink correction
/// (`kinks`).
#[derive(Clone, Copy, Debug)]
pub struct Substeps<'a> {
    pub weights: &'a [f64],
    pub kicks: Option<&'a [f64]>,
}

/// The kink correction of a step of length `h`: a contact whose overlap
/// crossed zero during the step (δ^{3/2}⁺ has a kink there that the
/// composition's quadrature misses, by ∝ h^{5/2}) gets the impulse the step
/// missed along a straight δ from its start to its end
/// ([`crate::engine::integrate::kink_impulse_error`], the cradle engine's
/// correction), added to its two beads' velocities. Bead by bead (its left
/// contact's share, then its right one's), as the GPU kernel's invocations
/// do it.
#[inline(always)]
fn kinks<R: Real>(c: &Consts<R>, s: &mut State<R>, h: R, w: &[f64], kicks: &[f64]) {
    // Whether a contact at rest overlap `d0` with stiffness `k` crossed zero
    // going from `p_start` to `p` (no branch: the scan below vectorises).
    #[inline(always)]
    fn crosses<R: Real>(d0: R, k: R, p_start: R, p: R) -> bool {
        let zero = R::zero();
        ((d0 + p_start > zero) != (d0 + p > zero)) & (k != zero)
    }
    let (lo, hi) = (s.lo, s.hi);
    let crossed = |j: usize| {
        crosses(c.d0[j], c.k[j], s.p_start[j], s.p[j])
            .then_some((c.d0[j] + s.p_start[j], c.d0[j] + s.p[j]))
    };
    // Most steps have none: one branch-free pass over the window finds out.
    let (d0, k) = (&c.d0[lo..=hi], &c.k[lo..=hi]);
    let (ps, p) = (&s.p_start[lo..=hi], &s.p[lo..=hi]);
    let mut any = false;
    for j in 0..d0.len() {
        any |= crosses(d0[j], k[j], ps[j], p[j]);
    }
    if !any {
        return;
    }
    let miss = |j: usize, (d0, d1): (R, R)| {
        crate::engine::integrate::kink_impulse_error(c.k[j], d0, d1, w, kicks) * h
    };
    for i in lo..hi {
        let (left, right) = (crossed(i), crossed(i + 1));
        if let Some(d) = left {
            s.v[i] = s.v[i] + miss(i, d) * c.inv_mass[i];
        }
        if let Some(d) = right {
            s.v[i] = s.v[i] - miss(i + 1, d) * c.inv_mass[i];
        }
    }
}

#[inline(always)]
fn step_portable<R: Real>(c: &Consts<R>, s: &mut State<R>, t0: R, h: R, m: &Substeps, whole: bool) {
    let w = m.weights;
    let half = R::of(0.5);
    let mut t = t0;
    let on = pulse_on(c, t0);
    if m.kicks.is_some() {
        let (lo, hi) = (s.lo, s.hi);
        s.p_start[lo..=hi].copy_from_slice(&s.p[lo..=hi]);
    }
    kick(s, half * R::of(w[0]) * h);
    for (j, &wj) in w.iter().enumerate() {
        let wj = R::of(wj);
        drift(s, wj * h);
        t = t + wj * h;
        forces(c, s, t, on);
        let k = match w.get(j + 1) {
            Some(&next) => half * (wj + R::of(next)) * h,
            None => half * wj * h,
        };
        kick(s, k);
    }
    if let Some(kicks) = m.kicks {
        kinks(c, s, h, w, kicks);
    }
    s.steps += 1;
    if !whole {
        s.shrink(c, w.len(), t0 + h);
    }
}
