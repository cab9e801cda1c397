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
//! over the whole chain bit for bit (test:
//! `skipping_beads_at_rest_changes_no_bit`, with `Plan::rest` = 0). Ahead
//! of a solitary wave in an uncompressed chain, contacts touch at zero
//! overlap and feel nothing: the window ends a few beads ahead of the front,
//! where δ^{3/2} of the precursor underflows to zero. A bead slower than
//! [`super::Plan::rest`] (1e-30 of the velocity scale) whose acceleration
//! would not change that in a step counts as at rest too: a damped chain's
//! dashpots spread the wave's tail four beads a step down to subnormal
//! speeds, which the window then leaves out (the outcome moves by far less
//! than its round-off).

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
    /// What a step keeps of its start and its contacts' impulses (the kink
    /// correction and the local refinement read it); nothing between steps.
    pub scratch: Scratch<R>,
    /// Regions redone by the local refinement so far, and their beads
    /// ([`Refine`]; diagnostics).
    pub regions: u64,
    pub region_beads: u64,
    /// Energy the damping has taken (J) so far: by each contact's dashpot
    /// (contacts 0 ..= n) and by each bead's air drag and the dashpots'
    /// closing correction (beads 0 .. n); empty for an undamped chain.
    pub lost_c: Vec<R>,
    pub lost_b: Vec<R>,
    /// The impulse the left wall has given bead 0 so far (N·s) when it is
    /// a piston (0 otherwise): its kicks, kink and damping; the piston's
    /// work is its speed times this.
    pub wall_imp: R,
    /// Each contact's Hunt–Crossley χ (s/m; contacts 0 ..= n, with a
    /// restitution below 1 only): a(e) over its closing speed, set by the
    /// first damping substep that finds it closed, 0 again once it opens;
    /// a contact closed at rest has a(e) / the velocity scale.
    pub chi: Vec<R>,
}

/// A step's scratch: its start over the window (contacts lo ..= hi, beads
/// lo .. hi), and each contact's impulse over the step.
#[derive(Clone, Debug, PartialEq)]
pub struct Scratch<R> {
    /// `p` at the step's start.
    pub p: Vec<R>,
    /// `v`, `a` and `x0` at the step's start (with [`Refine`] only).
    pub v: Vec<R>,
    pub a: Vec<R>,
    pub x0: R,
    /// Σ over the step's kicks of (kick weight)·e_j, plus the kink
    /// correction's impulse (with [`Refine`] only).
    pub imp: Vec<R>,
    /// Contacts near a crossing in this step, in order.
    pub near: Vec<usize>,
    /// The impulse each contact's dashpot gave its bead a over the step
    /// (N·s; damped chains only): the closing correction replaces it.
    pub dimp: Vec<R>,
    /// The springs k·δ^{3/2} of a damping substep's even contacts, which
    /// its two half-sweeps of them share (their overlaps are frozen); with
    /// the damping at the ends, every contact's at the step's end, which
    /// its last substep's forces keep for the sweeps at the step's end and
    /// the next one's start (the vector sweep only,
    /// `engine::granular::simd`; damped chains only).
    pub spring: Vec<R>,
}

impl<R: Real> Scratch<R> {
    /// Room for a chain of `n` beads (`refine`: also what the local
    /// refinement keeps).
    pub fn new(n: usize, refine: bool) -> Scratch<R> {
        let z = R::zero();
        let m = if refine { n + 1 } else { 0 };
        Scratch {
            p: vec![z; n + 1],
            v: vec![z; m],
            a: vec![z; m],
            x0: z,
            imp: vec![z; m],
            near: Vec::new(),
            dimp: Vec::new(),
            spring: Vec::new(),
        }
    }

    /// None: for states read back or converted, which take no step.
    pub fn none() -> Scratch<R> {
        Scratch {
            p: Vec::new(),
            v: Vec::new(),
            a: Vec::new(),
            x0: R::zero(),
            imp: Vec::new(),
            near: Vec::new(),
            dimp: Vec::new(),
            spring: Vec::new(),
        }
    }
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
    /// `refine`: room for the local refinement ([`Substeps::refine`]).
    pub fn start(b: &Beads, c: &Consts<R>, weights: &[f64], whole: bool, refine: bool) -> State<R> {
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
            scratch: Scratch::new(n, refine),
            regions: 0,
            region_beads: 0,
            lost_c: Vec::new(),
            lost_b: Vec::new(),
            wall_imp: zero,
            chi: Vec::new(),
        };
        if let Some(d) = &c.damp {
            (s.lost_c, s.lost_b) = (vec![zero; n + 1], vec![zero; n]);
            s.scratch.dimp = vec![zero; n + 1];
            s.scratch.spring = vec![zero; n + 1];
            if d.hc != zero {
                s.chi = (0..=n)
                    .map(|j| {
                        if c.d0[j] > zero && c.k[j] != zero {
                            d.chi_rest
                        } else {
                            zero
                        }
                    })
                    .collect();
            }
        }
        // Every contact's spring, for a damping at the ends' first sweeps
        // ([`damp_end`]: from then on each step's last substep keeps them).
        let keep = c.damp.as_ref().is_some_and(dashpots);
        forces(c, &mut s, zero, pulse_on(c, zero), None, keep);
        if !whole {
            // (Whichever the damping's split: its first step's window
            // reaches as far as either.)
            let (damped, stages) = (c.damp.is_some(), weights.len());
            // At the start only beads at exact rest wait: no speed a user
            // gave is taken for rest.
            s.shrink(
                c,
                reach(damped, stages, false).max(reach(damped, stages, true)),
                zero,
                (zero, zero),
            );
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
            scratch: Scratch::none(),
            regions: self.regions,
            region_beads: self.region_beads,
            lost_c: conv(&self.lost_c),
            lost_b: conv(&self.lost_b),
            wall_imp: self.wall_imp.to64(),
            chi: conv(&self.chi),
        })
    }

    /// Re-fit the window around the moving beads (`t`: the time now) for a
    /// step that reaches `reach` beads beyond them ([`reach`]). A bead moves
    /// unless its speed is at most `rest.0` and its acceleration at most
    /// `rest.1` (NaN moves): after a step of h, [`Consts::rest`] and rest/h
    /// (its speed then changes by at most `rest` in a step).
    fn shrink(&mut self, c: &Consts<R>, reach: usize, t: R, (rest, a_rest): (R, R)) {
        // The pulse's bead stays in while the next step (from t) feels it,
        // and a piston's first bead always (the piston may reach it).
        let pulse = c.pulse.as_ref().filter(|_| pulse_on(c, t)).map(|p| p.bead);
        let piston = (c.piston != R::zero()).then_some(0);
        // |x| above `at`, or NaN.
        let over = |x: R, at: R| {
            use std::cmp::Ordering::{Equal, Less};
            !matches!(x.abs().partial_cmp(&at), Some(Less | Equal))
        };
        let moving = |i: usize| {
            over(self.v[i], rest)
                || over(self.a[i], a_rest)
                || Some(i) == pulse
                || Some(i) == piston
        };
        let first = (self.lo..self.hi).find(|&i| moving(i));
        let Some(first) = first else {
            (self.lo, self.hi) = (0, 0);
            if let Some(i) = pulse.or(piston) {
                (self.lo, self.hi) = (i, i + 1);
            }
            return;
        };
        let last = (first..self.hi).rev().find(|&i| moving(i)).unwrap_or(first);
        let m = reach + 1 + MARGIN_EXTRA;
        let pulse_lo = pulse.unwrap_or(usize::MAX);
        self.lo = first.min(pulse_lo).saturating_sub(m);
        self.hi = (last.max(pulse.unwrap_or(0)) + 1 + m).min(self.v.len());
    }
}

/// How many beads beyond the moving ones a step of `stages` substeps can
/// move: one a substep; with damping in every substep its three sweeps of
/// dashpots three more a substep ([`damp`]); with damping at the ends
/// (`ends`) its four sweeps four more a step ([`damp_end`]).
fn reach(damped: bool, stages: usize, ends: bool) -> usize {
    match (damped, ends) {
        (false, _) => stages,
        (true, false) => 4 * stages,
        (true, true) => stages + 4,
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
/// at time `t` (the pulse's phase; `on`: [`pulse_on`] of the step);
/// `track`: the weight of the kick that follows, each contact's impulse
/// (`scratch.imp`) then adds weight·e_j; `keep`: each contact's spring
/// k·δ^{3/2} also kept in `scratch.spring` (the last substep's, for the
/// damping at the step's end, [`damp_end`]).
#[inline(always)]
fn forces<R: Real>(c: &Consts<R>, s: &mut State<R>, t: R, on: bool, track: Option<R>, keep: bool) {
    let (lo, hi) = (s.lo, s.hi);
    let e = &mut s.e[lo..=hi];
    let (k, d0, f0, p) = (&c.k[lo..=hi], &c.d0[lo..=hi], &c.f0[lo..=hi], &s.p[lo..=hi]);
    match track {
        None if keep => {
            let sp = &mut s.scratch.spring[lo..=hi];
            for j in 0..e.len() {
                let x = hertz(k[j], d0[j] + p[j]);
                sp[j] = x;
                e[j] = x - f0[j];
            }
        }
        None => {
            for j in 0..e.len() {
                e[j] = hertz(k[j], d0[j] + p[j]) - f0[j];
            }
        }
        Some(kc) if keep => {
            let (imp, sp) = (&mut s.scratch.imp[lo..=hi], &mut s.scratch.spring[lo..=hi]);
            for j in 0..e.len() {
                let x = hertz(k[j], d0[j] + p[j]);
                sp[j] = x;
                let x = x - f0[j];
                e[j] = x;
                imp[j] = imp[j] + kc * x;
            }
        }
        Some(kc) => {
            let imp = &mut s.scratch.imp[lo..=hi];
            for j in 0..e.len() {
                let x = hertz(k[j], d0[j] + p[j]) - f0[j];
                e[j] = x;
                imp[j] = imp[j] + kc * x;
            }
        }
    }
    let a = &mut s.a[lo..hi];
    let im = &c.inv_mass[lo..hi];
    let e = &s.e[lo..=hi];
    for i in 0..a.len() {
        a[i] = (e[i] - e[i + 1]) * im[i];
    }
    if let Some(pl) = &c.pulse {
        if on && (lo..hi).contains(&pl.bead) {
            let f = pl.force * push_sin(pl, t);
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

/// sin(2π·φ) for a phase φ ≥ 0 in cycles: its fraction f = φ − ⌊φ⌋ in
/// [0, 1), then [`half_sine`] of 2π·f on the first half and minus that of
/// 2π·(f − ½) on the second (a drive over many periods: the argument stays
/// within [0, π], where half_sine is exact to 2e-16, and the phase's
/// rounding grows only as φ·2^−53).
#[inline(always)]
pub fn cycle_sin<R: Real>(phase: R) -> R {
    let f = phase - phase.floor();
    let half = R::of(0.5);
    let tau = R::of(std::f64::consts::TAU);
    if f < half {
        half_sine(tau * f)
    } else {
        R::zero() - half_sine(tau * (f - half))
    }
}

/// sin(ωt) of a pulse or a drive ([`PulseConsts`](super::PulseConsts)):
/// [`pulse_sin`] for a half-sine pulse, [`cycle_sin`] of f·t for a drive.
#[inline(always)]
pub fn push_sin<R: Real>(p: &super::PulseConsts<R>, t: R) -> R {
    if p.cycles == R::zero() {
        pulse_sin(t, p.omega)
    } else {
        cycle_sin(p.cycles * t)
    }
}

/// cos(ωt) of a pulse or a drive: [`pulse_cos`], or [`cycle_sin`] a
/// quarter cycle on.
#[inline(always)]
pub fn push_cos<R: Real>(p: &super::PulseConsts<R>, t: R) -> R {
    if p.cycles == R::zero() {
        pulse_cos(t, p.omega)
    } else {
        cycle_sin(p.cycles * t + R::of(0.25))
    }
}

#[inline(always)]
fn kick<R: Real>(s: &mut State<R>, c: R) {
    let (lo, hi) = (s.lo, s.hi);
    for (v, &a) in s.v[lo..hi].iter_mut().zip(&s.a[lo..hi]) {
        *v = *v + c * a;
    }
}

/// p_j += dt·(v_{j−1} − v_j) for contacts lo ..= hi (the right wall
/// stands still, the left one moves at `piston`).
#[inline(always)]
fn drift<R: Real>(s: &mut State<R>, dt: R, piston: R) {
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
    drift_walls(s, dt, piston);
}

/// The drift of the wall contacts in the window (contact 0 when it starts
/// at bead 0, contact n when it ends at the last bead), and of bead 0's
/// position.
#[inline(always)]
fn drift_walls<R: Real>(s: &mut State<R>, dt: R, piston: R) {
    let n = s.v.len();
    if s.lo == 0 {
        if piston == R::zero() {
            s.p[0] = s.p[0] - dt * s.v[0];
        } else {
            s.p[0] = s.p[0] + dt * (piston - s.v[0]);
        }
        s.x0 = s.x0 + dt * s.v[0];
    }
    if s.hi == n {
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
/// weights at the drift positions ([`crate::engine::cradle::kick_weights`])
/// when contacts that open or close in a step get the kink correction
/// (`kinks`), the local refinement around contacts near a crossing
/// (`refine`, with `kinks` only), and where a damped chain's damping goes
/// (`ends`).
#[derive(Clone, Copy, Debug)]
pub struct Substeps<'a> {
    pub weights: &'a [f64],
    pub kicks: Option<&'a [f64]>,
    pub refine: Option<Refine>,
    /// A damped chain's damping once a step, at its ends (`damp_end`),
    /// rather than in every substep (`damp`; docs/SPEC.md §9, "Damping").
    pub ends: bool,
}

/// Beads each side of a contact near a crossing that the local refinement
/// redoes ([`Refine::reach`]).
pub const REFINE_REACH: usize = 3;
/// Finer steps a region is redone in ([`Refine::steps`]; a power of two, so
/// h/M is exact).
pub const REFINE_STEPS: usize = 8;
/// A contact is near a crossing when its smaller |δ| over the step is below
/// this many times its change |Δδ| ([`Refine::near`]).
pub const REFINE_NEAR: f64 = 3.0;
/// Changes of overlap below this fraction of v_s·t_s (the velocity and time
/// scales) do not count ([`Refine::floor`]): the precursor ahead of a
/// solitary wave, whose forces are far below any tolerance.
pub const REFINE_FLOOR: f64 = 5e-8;

/// The local refinement (docs/SPEC.md §9). A fixed step loses accuracy in
/// the few steps around each contact's crossing of zero overlap, where the
/// force k·δ^{3/2}⁺ is only C¹ in time (the methods' error then falls as
/// ~h³ whatever their order). After each step, every contact near a
/// crossing has the beads within `reach` of it redone as `steps` finer
/// steps of the same composition (with the kink correction), from the
/// step's start; a bead just outside such a region follows the quintic
/// Hermite interpolant of its velocity between its start and end (its
/// velocity, acceleration and jerk there; its displacement: the
/// interpolant's integral), and its velocity takes
/// the fine steps' impulse of the boundary contact in place of the coarse
/// one (momentum stays at round-off). Contacts near a crossing whose
/// regions would leave fewer than three beads between them share one
/// region, so regions never touch, nor read what another writes (an
/// outside bead's interpolant reads its neighbours): the GPU kernel redoes
/// them in parallel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refine {
    pub reach: usize,
    pub steps: usize,
    pub near: f64,
    /// The smallest |Δδ| over a step that counts (m).
    pub floor: f64,
}

/// The kink correction of a step of length `h`: a contact whose overlap
/// crossed zero during the step (δ^{3/2}⁺ has a kink there that the
/// composition's quadrature misses, by ∝ h^{5/2}) gets the impulse the step
/// missed along a straight δ from its start to its end
/// ([`crate::engine::cradle::kink_impulse_error`], the cradle engine's
/// correction), added to its two beads' velocities. Bead by bead (its left
/// contact's share, then its right one's), as the GPU kernel's invocations
/// do it, over beads a .. b, the overlaps at the start in `scratch.p`.
#[inline(always)]
fn kinks<R: Real>(
    c: &Consts<R>,
    s: &mut State<R>,
    (a, b): (usize, usize),
    h: R,
    w: &[f64],
    kicks: &[f64],
) {
    for i in a..b {
        let (left, right) = (miss(c, s, i, h, w, kicks), miss(c, s, i + 1, h, w, kicks));
        if let Some(x) = left {
            s.v[i] = s.v[i] + x * c.inv_mass[i];
        }
        if let Some(x) = right {
            s.v[i] = s.v[i] - x * c.inv_mass[i];
        }
    }
}

/// The impulse contact j missed in a step of length `h` (the kink
/// correction's), if its overlap crossed zero in it.
#[inline(always)]
fn miss<R: Real>(
    c: &Consts<R>,
    s: &State<R>,
    j: usize,
    h: R,
    w: &[f64],
    kicks: &[f64],
) -> Option<R> {
    let ps = s.scratch.p[j];
    // With dashpots a contact is slack before it opens ([`dashpot`]: its
    // spring and its dashpot cancel): its spring's kink at δ = 0 is not
    // felt, and the dashpot's cut would take back a correction here.
    let slack = c.damp.as_ref().is_some_and(|d| d.gamma != R::zero()) && c.d0[j] + ps > R::zero();
    (!slack && crosses(c.d0[j], c.k[j], ps, s.p[j])).then(|| {
        let (d0, d1) = (c.d0[j] + ps, c.d0[j] + s.p[j]);
        crate::engine::cradle::kink_impulse_error(c.k[j], d0, d1, w, kicks) * h
    })
}

/// Whether a contact at rest overlap `d0` with stiffness `k` crossed zero
/// going from `p_start` to `p` (no branch: scans over it vectorise).
#[inline(always)]
fn crosses<R: Real>(d0: R, k: R, p_start: R, p: R) -> bool {
    let zero = R::zero();
    ((d0 + p_start > zero) != (d0 + p > zero)) & (k != zero)
}

/// Whether a contact is near a crossing ([`Refine`]): |Δδ| > floor, and it
/// crossed, or one end of its step is closed and min |δ| < near·|Δδ|. A
/// precursor's contact going from δ = 0 to 1e-200 crosses, but its change
/// is below the floor: no region.
#[inline(always)]
fn is_near<R: Real>(d0: R, k: R, p_start: R, p: R, near: R, floor: R) -> bool {
    let zero = R::zero();
    let (da, db) = (d0 + p_start, d0 + p);
    let dd = (p - p_start).abs();
    let close = ((da > zero) | (db > zero)) & (da.abs().min(db.abs()) < near * dd);
    (((da > zero) != (db > zero)) | close) & (dd > floor) & (k != zero)
}

/// The kick after drift j of a step of length `h` with drift weights `w`:
/// half of drift j's and half of the next one's (the kicks between
/// substeps merged), the last one half of its own.
#[inline(always)]
fn kick_weight<R: Real>(w: &[f64], j: usize, h: R) -> R {
    let (half, wj) = (R::of(0.5), R::of(w[j]));
    match w.get(j + 1) {
        Some(&next) => half * (wj + R::of(next)) * h,
        None => half * wj * h,
    }
}

/// What a step keeps of its start in `scratch`: the overlaps (for the kink
/// correction, `kicks`, and the damping's closings), the dashpots'
/// impulses zeroed, and for the local refinement (`refine`) the
/// velocities, accelerations, bead 0's position and each contact's impulse
/// of the first kick (weight `c0`).
#[inline(always)]
fn keep_start<R: Real>(c: &Consts<R>, s: &mut State<R>, kicks: bool, refine: bool, c0: R) {
    let (lo, hi) = (s.lo, s.hi);
    if kicks || c.damp.is_some() {
        s.scratch.p[lo..=hi].copy_from_slice(&s.p[lo..=hi]);
    }
    if c.damp.is_some() {
        s.scratch.dimp[lo..=hi].fill(R::zero());
    }
    if refine {
        let sc = &mut s.scratch;
        sc.v[lo..hi].copy_from_slice(&s.v[lo..hi]);
        sc.a[lo..hi].copy_from_slice(&s.a[lo..hi]);
        sc.x0 = s.x0;
        for (i, &e) in sc.imp[lo..=hi].iter_mut().zip(&s.e[lo..=hi]) {
            *i = c0 * e;
        }
    }
}

#[inline(always)]
fn step_portable<R: Real>(c: &Consts<R>, s: &mut State<R>, t0: R, h: R, m: &Substeps, whole: bool) {
    let w = m.weights;
    let half = R::of(0.5);
    let mut t = t0;
    let on = pulse_on(c, t0);
    let refine = m.refine.filter(|_| m.kicks.is_some());
    let (lo, hi) = (s.lo, s.hi);
    let c0 = half * R::of(w[0]) * h;
    keep_start(c, s, m.kicks.is_some(), refine.is_some(), c0);
    let piston = c.piston != R::zero();
    // A piston's bead 0 is always in the window (`shrink`): contact 0's
    // force is what each kick gives it.
    let wall = |s: &State<R>| s.e[0] + c.f0[0];
    if piston {
        s.wall_imp = s.wall_imp + c0 * wall(s);
    }
    // Damping at the ends: its first half, the composition's substeps, its
    // second half ([`damp_end`]).
    let ends = c.damp.as_ref().filter(|_| m.ends);
    if let Some(d) = ends {
        damp_end::<R, true>(c, d, s, half * h);
    }
    kick(s, c0);
    for (j, &wj) in w.iter().enumerate() {
        let wj = R::of(wj);
        match &c.damp {
            Some(d) if !m.ends => {
                // Drift, damp, drift: a symmetric substep, so the
                // composition keeps its order ([`damp`]).
                let tau = wj * h;
                if d.drag != R::zero() {
                    // The air drag's halves ride in the drifts' passes.
                    drift_drag::<R, false>(d, s, half * tau, c.piston);
                    damp(c, d, s, tau);
                    drift_drag::<R, true>(d, s, half * tau, c.piston);
                } else {
                    drift(s, half * tau, c.piston);
                    damp(c, d, s, tau);
                    drift(s, half * tau, c.piston);
                }
            }
            _ => drift(s, wj * h, c.piston),
        }
        t = t + wj * h;
        let k = kick_weight(w, j, h);
        // The last substep's springs are the damping's at the step's end
        // and at the next one's start.
        let keep = ends.is_some_and(dashpots) && j + 1 == w.len();
        forces(c, s, t, on, refine.map(|_| k), keep);
        if piston {
            s.wall_imp = s.wall_imp + k * wall(s);
        }
        kick(s, k);
    }
    if let Some(d) = ends {
        damp_end::<R, false>(c, d, s, half * h);
    }
    if let Some(kicks) = m.kicks {
        // Most steps have no crossing: one branch-free pass over the window
        // finds out.
        let (d0, kk) = (&c.d0[lo..=hi], &c.k[lo..=hi]);
        let (ps, p) = (&s.scratch.p[lo..=hi], &s.p[lo..=hi]);
        let mut any = false;
        match refine {
            None => {
                for j in 0..d0.len() {
                    any |= crosses(d0[j], kk[j], ps[j], p[j]);
                }
            }
            Some(r) => {
                let (near, floor) = (R::of(r.near), R::of(r.floor));
                // Every crossing takes the kink correction, near or not.
                for j in 0..d0.len() {
                    any |= crosses(d0[j], kk[j], ps[j], p[j])
                        | is_near(d0[j], kk[j], ps[j], p[j], near, floor);
                }
            }
        }
        if any {
            if piston {
                if let Some(x) = miss(c, s, 0, h, w, kicks) {
                    s.wall_imp = s.wall_imp + x;
                }
            }
            kinks(c, s, (lo, hi), h, w, kicks);
            if let Some(r) = refine {
                for j in lo..=hi {
                    if let Some(x) = miss(c, s, j, h, w, kicks) {
                        s.scratch.imp[j] = s.scratch.imp[j] + x;
                    }
                }
                refine_near(c, s, (t0, h, t), m, kicks, r);
            }
        }
    }
    if let Some(d) = &c.damp {
        if piston {
            // Bead 0 is contact 0's bead b: it takes minus the dashpot's
            // impulse on the wall, and minus its closing correction.
            let x = closing_correction(c, d, s, 0).unwrap_or(R::zero());
            s.wall_imp = s.wall_imp - s.scratch.dimp[0] - x;
        }
        crossings(c, d, s);
    }
    s.steps += 1;
    if !whole {
        // rest/h, not |a|·h against rest: with rest = 0 an acceleration that
        // h would scale to zero still moves its bead.
        let rest = (c.rest, c.rest / h);
        s.shrink(c, reach(c.damp.is_some(), w.len(), m.ends), t0 + h, rest);
    }
}

/// The damping substep of length `tau` (docs/SPEC.md §9, "Damping"), at
/// the positions of the drift's middle: the flow of the dashpots and the
/// air drag with the overlaps frozen, a linear ODE in the velocities,
/// approximated by a symmetric product of exactly solvable parts — the air
/// drag for τ/2, the even contacts for τ/2, the odd ones for τ, the even
/// ones for τ/2, the air drag for τ/2 (contacts of one parity share no
/// bead) — each part by the Cayley map x ↦ (2 − x)/(2 + x) of its decay
/// (second order, symmetric: its inverse is itself at −τ). A drift–damp–
/// drift substep is then symmetric and of order 2 like the Verlet one it
/// replaces, and the compositions keep their orders. This function sweeps
/// the dashpots; the air drag's two halves are done in the passes of the
/// half-drifts around it ([`drift_drag`]).
#[inline(always)]
fn damp<R: Real>(c: &Consts<R>, d: &super::DampConsts<R>, s: &mut State<R>, tau: R) {
    let zero = R::zero();
    let half = R::of(0.5) * tau;
    if dashpots(d) {
        // The even contacts' second half-sweep reads the springs the
        // first one kept.
        use Springs::{Keep, Reuse, Take};
        for (parity, t, springs) in [(0, half, Keep), (1, tau, Take), (0, half, Reuse)] {
            let first = s.lo + (s.lo + parity) % 2;
            // Forward substeps (all of most methods') take the cheaper test
            // of a pull ([`dashpot`]).
            if t > zero {
                sweep::<R, false>(c, d, s, first, t, springs);
            } else {
                sweep::<R, true>(c, d, s, first, t, springs);
            }
        }
    }
}

/// One half of a step's damping at its ends (`Substeps::ends`; docs/SPEC.md
/// §9, "Damping"), for `t` = h/2 at the step's start (`FIRST`) or its end:
/// the same flow as [`damp`]'s, by the same exactly solvable parts — the
/// air drag, the even contacts, the odd ones — each by its Cayley map; the
/// start takes them in that order, the end in the reverse one. The step,
/// drag·even·odd · the composition · odd·even·drag, is a palindrome of
/// symmetric maps: symmetric, of order 2 in the damping (the splitting's
/// error ∝ γ·h²) and of the method's order without it. Four sweeps of
/// half the contacts a step instead of three a substep (27 with
/// kahanli6); at the step's ends, where the composition's state is of its
/// order, not at an inner substep, whose velocities are not (there the
/// dissipated energy erred by 0.4% at a step the tolerance 1e-4 picks).
#[inline(always)]
fn damp_end<R: Real, const FIRST: bool>(
    c: &Consts<R>,
    d: &super::DampConsts<R>,
    s: &mut State<R>,
    t: R,
) {
    let zero = R::zero();
    if FIRST && d.drag != zero {
        drag(d, s, t);
    }
    if dashpots(d) {
        let even = s.lo + s.lo % 2;
        let odd = s.lo + (s.lo + 1) % 2;
        let order = if FIRST { [even, odd] } else { [odd, even] };
        // The springs at these positions are kept: by this step's last
        // substep at its end, by the last step's at its start (or by
        // [`State::start`]'s forces at the first). A contact's overlap
        // changes only in a step's window, and the step's last substep
        // keeps the springs of its whole window ([`forces`]'s `keep`; the
        // local refinement, which would move overlaps after it, never
        // runs on a damped chain).
        for first in order {
            sweep::<R, false>(c, d, s, first, t, Springs::Reuse);
        }
    }
    if !FIRST && d.drag != zero {
        drag(d, s, t);
    }
}

/// Whether a damping has dashpots (a viscosity or Hunt–Crossley contacts):
/// sweeps of the contacts, not only the air drag.
#[inline(always)]
fn dashpots<R: Real>(d: &super::DampConsts<R>) -> bool {
    d.gamma != R::zero() || d.hc != R::zero()
}

/// The air drag for `t` ([`damp_end`]): every moving bead's velocity times
/// the Cayley map of c·t, the kinetic energy it takes kept per bead
/// ([`dragged`], as [`drift_drag`]'s drag).
#[inline(always)]
fn drag<R: Real>(d: &super::DampConsts<R>, s: &mut State<R>, t: R) {
    let f = drag_factor(d.drag, t);
    let (lo, hi) = (s.lo, s.hi);
    let (v, lost, m) = (&mut s.v[lo..hi], &mut s.lost_b[lo..hi], &d.mass[lo..hi]);
    for i in 0..v.len() {
        (v[i], lost[i]) = dragged(v[i], lost[i], m[i], f);
    }
}

/// The Cayley map of the air drag `c` over `t`: (2 − c·t)/(2 + c·t).
#[inline(always)]
fn drag_factor<R: Real>(c: R, t: R) -> R {
    let (two, x) = (R::of(2.0), c * t);
    (two - x) / (two + x)
}

/// A bead's velocity `v` after the drag of factor `f`, and its energy lost
/// so far `lost` with what the drag took (mass `m`): selects, not branches,
/// and a bead at rest keeps its velocity's bits, −0 too.
#[inline(always)]
fn dragged<R: Real>(v: R, lost: R, m: R, f: R) -> (R, R) {
    let zero = R::zero();
    let vn = if v != zero { v * f } else { v };
    let l = lost + R::of(0.5) * m * (v * v - vn * vn);
    (vn, if v != zero { l } else { lost })
}

/// Whether [`sweep`] takes the vector path ([`super::simd`]: f64 on an
/// x86-64 CPU with AVX2).
#[inline(always)]
fn vector_sweeps<R: Real>() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::any::TypeId::of::<R>() == std::any::TypeId::of::<f64>()
            && std::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// What a sweep does with its contacts' springs (the vector sweep only,
/// [`super::simd`]): computes them, computes and keeps them
/// (`Scratch::spring`), or reads the ones a sweep of the same contacts at
/// the same overlaps kept (or the forces, [`damp_end`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Springs {
    Take,
    Keep,
    Reuse,
}

/// The dashpots of contacts `first`, `first` + 2, … in the window for `t`,
/// one by one ([`dashpot`]); in f64 on a CPU with AVX2 the contacts between
/// beads four at a time ([`super::simd`], the same bits) and only the walls'
/// and the last few one by one. Contacts of one parity share no bead, so
/// the order changes no bit.
#[inline(always)]
fn sweep<R: Real, const BACK: bool>(
    c: &Consts<R>,
    d: &super::DampConsts<R>,
    s: &mut State<R>,
    first: usize,
    t: R,
    springs: Springs,
) {
    let mut j = first;
    #[cfg(target_arch = "x86_64")]
    if vector_sweeps::<R>() {
        let (n, hi) = (s.v.len(), s.hi);
        if j == 0 && j <= hi {
            dashpot::<R, BACK>(c, d, s, 0, t);
            j = 2;
        }
        // Contacts j, j + 2, … up to the last one between two beads.
        let top = hi.min(n - 1);
        let count = if j <= top { (top - j) / 2 + 1 } else { 0 };
        // And the last few in a chunk of their own, its other lanes left as
        // they are, where the arrays hold its eight contacts.
        let chunks = match count / 4 {
            full if count % 4 != 0 && j + 8 * full + 7 <= n => full + 1,
            full => full,
        };
        if chunks > 0 {
            use super::simd::{as64 as f, as64_mut as g};
            let sw = super::simd::Sweep {
                d0: f(&c.d0),
                k: f(&c.k),
                p: f(&s.p),
                beta: f(&d.beta),
                inv_mu: f(&d.inv_mu),
                mu: f(&d.mu),
                share_a: f(&d.share_a),
                share_b: f(&d.share_b),
                chi: f(&s.chi),
                t: t.to64(),
                hc: d.hc.to64(),
                chi_unset: d.chi_unset.to64(),
            };
            let out = super::simd::Out {
                v: g(&mut s.v),
                lost: g(&mut s.lost_c),
                dimp: g(&mut s.scratch.dimp),
                spring: g(&mut s.scratch.spring),
            };
            let sp = (springs == Springs::Keep, springs == Springs::Reuse);
            // SAFETY: the CPU has AVX2 (checked just above).
            unsafe {
                if d.hc != R::zero() {
                    super::simd::dashpots::<BACK, true>(&sw, out, sp, (j, chunks, top));
                } else {
                    super::simd::dashpots::<BACK, false>(&sw, out, sp, (j, chunks, top));
                }
            }
            // Past the chunks' contacts: past `top` if the last was masked.
            j += 2 * count.min(4 * chunks);
        }
    }
    while j <= s.hi {
        dashpot::<R, BACK>(c, d, s, j, t);
        j += 2;
    }
}

/// The impulse on bead a that contact j's dashpot missed in the step, if it
/// closed in it ([`crossings`]): −γ·δ_end minus what the substeps gave.
#[inline(always)]
fn closing_correction<R: Real>(
    c: &Consts<R>,
    d: &super::DampConsts<R>,
    s: &State<R>,
    j: usize,
) -> Option<R> {
    let zero = R::zero();
    let (a, b) = (c.d0[j] + s.scratch.p[j], c.d0[j] + s.p[j]);
    // Closed at the end as the dashpot sees it: its spring pushes (δ > 0
    // tested first, so that the many contacts open at both ends take no
    // square root; the same answer, hertz(k, δ ≤ 0) = 0).
    (d.gamma != zero && a <= zero && b > zero && hertz(c.k[j], b) > zero)
        .then(|| -(d.gamma * b) - s.scratch.dimp[j])
}

/// A drift of `dt` and the air drag for `dt` in one pass (`DRAG_FIRST`:
/// the drag, then the drift; else the drift, then the drag): the drag
/// multiplies every moving bead's velocity by the Cayley map of c·dt and
/// keeps the kinetic energy it takes per bead. The same operations on each
/// value as the drift's pass followed (or preceded) by the drag's, so the
/// same bits, in one pass over the window instead of two: contact j's
/// iteration reads its two beads' velocities and writes bead j − 1's, whose
/// last reader it is (a loop that vectorises).
#[inline(always)]
fn drift_drag<R: Real, const DRAG_FIRST: bool>(
    d: &super::DampConsts<R>,
    s: &mut State<R>,
    dt: R,
    piston: R,
) {
    let zero = R::zero();
    let f = drag_factor(d.drag, dt);
    let n = s.v.len();
    let (lo, hi) = (s.lo, s.hi);
    if lo == hi {
        return;
    }
    // A bead's velocity after the drag ([`dragged`]).
    let vel = |v: R| if v != zero { v * f } else { v };
    let dragged = |v: R, lost: R, m: R| dragged(v, lost, m, f);
    // The wall contacts read the velocities before the drag or after it.
    if !DRAG_FIRST {
        drift_walls(s, dt, piston);
    }
    // Contacts a ..= z between beads. Unless the window starts at bead 0,
    // bead a − 1 is outside it: its contact takes the drift alone.
    let (mut a, z) = (lo.max(1), hi.min(n - 1));
    if a <= z && a - 1 < lo {
        let vb = s.v[a];
        let vb = if DRAG_FIRST { vel(vb) } else { vb };
        s.p[a] = s.p[a] + dt * (s.v[a - 1] - vb);
        a += 1;
    }
    if a <= z {
        // Contact a + k between beads a − 1 + k and a + k; bead a − 1 + k
        // is dragged at it.
        let p = &mut s.p[a..=z];
        let v = &mut s.v[a - 1..=z];
        let lost = &mut s.lost_b[a - 1..z];
        let m = &d.mass[a - 1..z];
        let len = p.len();
        assert!(v.len() == len + 1 && lost.len() == len && m.len() == len);
        for k in 0..len {
            let (va, la) = dragged(v[k], lost[k], m[k]);
            let (v0, v1) = if DRAG_FIRST {
                (va, vel(v[k + 1]))
            } else {
                (v[k], v[k + 1])
            };
            p[k] = p[k] + dt * (v0 - v1);
            v[k] = va;
            lost[k] = la;
        }
    }
    // The beads with no contact to their right in the loop: the last one
    // when the window reaches the right wall; every bead of a window with
    // no contact between beads.
    for i in z.max(lo)..hi {
        let (vn, l) = dragged(s.v[i], s.lost_b[i], d.mass[i]);
        s.v[i] = vn;
        s.lost_b[i] = l;
    }
    if DRAG_FIRST {
        drift_walls(s, dt, piston);
    }
}

/// A Hunt–Crossley contact's relative velocity after its dashpot for `t`
/// (`spring` = k·δ^{3/2}, `inv_mu` = 1/μ, β = γ/μ): the implicit midpoint
/// of dw/dt = −β·w − k·δ^{3/2}·min(a, χ·w)/μ, χ = a/W, W the contact's
/// closing speed: the largest it has closed at at the steps' ends since it
/// closed (at least the floor; `chi` = 0 before its first step's end
/// closed, meaning `chi_unset`), the same all through a step ([`ratchet`]), so that the flow is
/// the same in every substep and each sweep, its implicit midpoint, is
/// symmetric. A contact whose closing speed rose at the step's start
/// (`chi` < 0, |χ| = a/W) is rising: its χ follows a over its speed, so
/// its force is a·k·δ^{3/2} and the flow affine, w' = (w·(2 − g) − 2c)/(2 + g)
/// (g = β·t, c = a·k·δ^{3/2}·t/μ), all through the step. Else the flow is
/// affine where the midpoint's w is at or above W (its speed rising again
/// inside the step), linear below — the Cayley map of
/// (β + χ·k·δ^{3/2}/μ)·t — one of the two having its midpoint on its own
/// side (they meet at W). Setting χ inside a step from the velocity each
/// sweep found instead kept the top of the splitting's saw-tooth, a speed
/// too high by O(h): order 1 (results/chains.md, "Hunt–Crossley's χ");
/// and a rising contact's sweep at the step's start, at W exactly, would
/// take the linear flow, a force short by O(h) there: order 1 at the ends.
#[inline(always)]
fn hunt_crossley<R: Real>(
    d: &super::DampConsts<R>,
    chi: R,
    w: R,
    spring: R,
    inv_mu: R,
    beta: R,
    t: R,
) -> R {
    let (zero, two) = (R::zero(), R::of(2.0));
    let affine = || {
        let (g, c) = (beta * t, d.hc * spring * inv_mu * t);
        (w * (two - g) - two * c) / (two + g)
    };
    if chi < zero {
        return affine();
    }
    let chi = d.chi_of(chi);
    // Rising needs w·χ ≥ a forward (w' ≤ w there).
    if t <= zero || w * chi >= d.hc {
        let wr = affine();
        if (w + wr) * chi >= two * d.hc {
            return wr;
        }
    }
    let x = (beta + chi * spring * inv_mu) * t;
    w * (two - x) / (two + x)
}

/// Contact j's dashpot for `t` with its overlap frozen: while closed, its
/// beads' relative velocity w = v_a − v_b decays as dw/dt = −β·w (β =
/// γ·(1/m_a + 1/m_b)), their momentum kept, by the Cayley map of β·t.
/// Never pulling: where the beads part (w < 0) the dashpot's pull over `t`
/// is at most what the spring pushes over it, k·δ^{3/2}·t at this
/// position, so the contact's force, spring and dashpot, stays ≥ 0 (near
/// the end of every contact, as δ → 0, the pull is cut so: the contact is
/// slack, the two parts cancel to O(h²) between the kicks' quadrature of
/// the spring and this one). The kinetic energy it takes is kept per
/// contact, the impulse on bead a in `scratch.dimp`.
#[inline(always)]
fn dashpot<R: Real, const BACK: bool>(
    c: &Consts<R>,
    d: &super::DampConsts<R>,
    s: &mut State<R>,
    j: usize,
    t: R,
) {
    let (zero, two, half) = (R::zero(), R::of(2.0), R::of(0.5));
    let dl = c.d0[j] + s.p[j];
    // Closed: its spring pushes (k·δ^{3/2} > 0; ahead of a solitary wave a
    // precursor's contact at δ ~ 1e-200 does not, and its dashpot would
    // carry round-off-sized velocities along the whole chain, out of the
    // window's reach for no force that matters).
    if dl <= zero || dl.is_nan() {
        return;
    }
    let n = s.v.len();
    // The left wall moves at `piston`.
    let va = if j > 0 { s.v[j - 1] } else { c.piston };
    let vb = if j < n { s.v[j] } else { zero };
    let w = va - vb;
    if w == zero {
        return;
    }
    // The spring's square root only where it is needed: an overlap of at
    // least ε with k ≥ 1 pushes in any precision (k·δ^{3/2} ≥ ε^{3/2} is
    // far from underflow), so only smaller ones test it; it is then needed
    // by Hunt–Crossley and by a parting contact's pull limit. The same bits
    // as computing it first (returning early changes nothing).
    let k = c.k[j];
    let spring = || hertz(k, dl);
    if !(dl >= R::epsilon() && k >= R::one()) && spring() <= zero {
        return;
    }
    let beta = d.beta[j];
    let mut wn = if d.hc != zero {
        hunt_crossley(d, s.chi[j], w, spring(), d.inv_mu[j], beta, t)
    } else {
        let x = beta * t;
        w * (two - x) / (two + x)
    };
    // Pulling over this substep (for t < 0, `BACK`, a substep back in
    // time, the same with the signs turned): at most the spring's push.
    // Forward only parting beads (w < 0) can pull, as the Cayley factor is
    // in (−1, 1] and rounding is monotone: a test with no division behind
    // it, so that a mispredicted branch costs less.
    if (BACK || w < zero) && (wn - w) * t > zero {
        let lim = w + spring() * t * d.inv_mu[j];
        if (wn - lim) * t > zero {
            wn = lim;
        }
    }
    let dw = wn - w;
    if j > 0 {
        s.v[j - 1] = va + dw * d.share_a[j];
    }
    if j < n {
        s.v[j] = vb - dw * d.share_b[j];
    }
    s.lost_c[j] = s.lost_c[j] + half * d.mu[j] * (w * w - wn * wn);
    s.scratch.dimp[j] = s.scratch.dimp[j] + d.mu[j] * dw;
}

/// The dashpots' closing correction after a step: a contact that closed in
/// it (δ ≤ 0 at the start, > 0 at the end) switched its dashpot on at an
/// instant inside the step that the damping substeps, frozen at their
/// positions, only see at their own: its force jumps there from 0 to γ·δ̇,
/// and the step would err by O(h) at each closing. A closing contact is
/// never slack (δ̇ > 0: its dashpot pushes), so the impulse it gave bead a over the
/// step is exactly −γ·δ_end (∫γ·δ̇ dt over the closed part); each closing
/// contact's beads get that minus what the substeps gave
/// (`scratch.dimp`), bead by bead (its left contact's share, then its
/// right one's), as the GPU kernel's invocations do; the kinetic energy
/// this takes is kept per bead. (An opening contact is slack before it
/// opens, its force continuous: nothing to correct.)
#[inline(always)]
fn crossings<R: Real>(c: &Consts<R>, d: &super::DampConsts<R>, s: &mut State<R>) {
    let zero = R::zero();
    if d.gamma != zero {
        closings(c, d, s);
    }
    if d.hc != zero {
        ratchet(c, d, s);
    }
}

/// Hunt–Crossley's χ at a step's end ([`hunt_crossley`]): an open
/// contact's cleared (its next closing sets it afresh); a closed one's a
/// over the largest closing speed of its steps' ends, negative where that
/// speed rose at this one (rising).
#[inline(always)]
fn ratchet<R: Real>(c: &Consts<R>, d: &super::DampConsts<R>, s: &mut State<R>) {
    ratchet_in(c, d, s, vector_sweeps::<R>());
}

/// [`ratchet`], four contacts to a vector (`vector`: f64 on a CPU with
/// AVX2, [`vector_sweeps`]) or one by one.
#[inline(always)]
fn ratchet_in<R: Real>(c: &Consts<R>, d: &super::DampConsts<R>, s: &mut State<R>, vector: bool) {
    let zero = R::zero();
    let (lo, hi, n) = (s.lo, s.hi, s.v.len());
    // Contact j's new χ from its χ, overlap and closing speed w: selects,
    // not branches (a rising contact's division computed for every one),
    // so that a wave's front, where contacts start and stop rising, costs
    // no mispredicted branch (LLVM leaves this loop scalar: the vector
    // one is written out, [`super::simd::ratchet`]).
    let next = |chi: R, dl: R, w: R| {
        let held = if chi < zero { zero - chi } else { chi };
        let rising = zero - d.hc / w;
        let closed = if w * d.chi_of(held) > d.hc {
            rising
        } else {
            held
        };
        if dl <= zero {
            zero
        } else {
            closed
        }
    };
    let edge = |s: &mut State<R>, j: usize| {
        let va = if j > 0 { s.v[j - 1] } else { c.piston };
        let vb = if j < n { s.v[j] } else { zero };
        s.chi[j] = next(s.chi[j], c.d0[j] + s.p[j], va - vb);
    };
    if lo == 0 {
        edge(s, 0);
    }
    // Contacts a ..= z between two beads: in f64 with AVX2 four at a time
    // up to the last whole four ([`super::simd::ratchet`], the same bits).
    let (a, z) = (lo.max(1), hi.min(n - 1));
    #[cfg(target_arch = "x86_64")]
    let a = if vector && a <= z {
        use super::simd::{as64 as f, as64_mut as g};
        // SAFETY: the CPU has AVX2 (checked by the caller).
        unsafe {
            super::simd::ratchet(
                g(&mut s.chi),
                (f(&c.d0), f(&s.p), f(&s.v)),
                (d.hc.to64(), d.chi_unset.to64()),
                (a, z),
            )
        }
    } else {
        a
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = vector;
    if a <= z {
        let (chi, d0, p, v) = (
            &mut s.chi[a..=z],
            &c.d0[a..=z],
            &s.p[a..=z],
            &s.v[a - 1..=z],
        );
        for j in 0..chi.len() {
            chi[j] = next(chi[j], d0[j] + p[j], v[j] - v[j + 1]);
        }
    }
    if hi == n && n > 0 {
        edge(s, n);
    }
}

/// The closing corrections of a step's crossings ([`crossings`]).
#[inline(always)]
fn closings<R: Real>(c: &Consts<R>, d: &super::DampConsts<R>, s: &mut State<R>) {
    let zero = R::zero();
    let (lo, hi) = (s.lo, s.hi);
    let closed = |s: &State<R>, j: usize| closing_correction(c, d, s, j);
    // Most steps close no contact: one branch-free pass over the window
    // (a loop that vectorises) finds out, by a test every contact that
    // closes passes ([`closing_correction`]'s, its spring's push > 0
    // weakened to k ≠ 0).
    let (d0, k, ps, p) = (
        &c.d0[lo..=hi],
        &c.k[lo..=hi],
        &s.scratch.p[lo..=hi],
        &s.p[lo..=hi],
    );
    let mut any = false;
    for j in 0..d0.len() {
        any |= (d0[j] + ps[j] <= zero) & (d0[j] + p[j] > zero) & (k[j] != zero);
    }
    if !any {
        return;
    }
    let half = R::of(0.5);
    for i in lo..hi {
        let v = s.v[i];
        let mut vn = v;
        // Bead i is contact i's bead b and contact i + 1's bead a.
        if let Some(x) = closed(s, i) {
            vn = vn - x * c.inv_mass[i];
        }
        if let Some(x) = closed(s, i + 1) {
            vn = vn + x * c.inv_mass[i];
        }
        if vn != v {
            s.v[i] = vn;
            s.lost_b[i] = s.lost_b[i] + half * d.mass[i] * (v * v - vn * vn);
        }
    }
}

/// The local refinement after a step ([`Refine`]): the contacts near a
/// crossing, grouped into regions, each redone. `times`: the step's start,
/// length and last substep's time.
fn refine_near<R: Real>(
    c: &Consts<R>,
    s: &mut State<R>,
    times: (R, R, R),
    m: &Substeps,
    kicks: &[f64],
    r: Refine,
) {
    let (lo, hi) = (s.lo, s.hi);
    let (nr, floor) = (R::of(r.near), R::of(r.floor));
    let mut near = std::mem::take(&mut s.scratch.near);
    near.clear();
    near.extend((lo..=hi).filter(|&j| is_near(c.d0[j], c.k[j], s.scratch.p[j], s.p[j], nr, floor)));
    let l = r.reach;
    let mut k = 0;
    while k < near.len() {
        let first = near[k];
        let mut last = first;
        k += 1;
        while k < near.len() && near[k] - last <= 2 * l + 2 {
            last = near[k];
            k += 1;
        }
        let (a, b) = (first.saturating_sub(l).max(lo), (last + l).min(hi));
        if b > a {
            s.regions += 1;
            s.region_beads += (b - a) as u64;
            redo(c, s, times, m, kicks, r.steps, (a, b));
        }
    }
    s.scratch.near = near;
}

/// A bead's displacement since the step's start along the quintic Hermite
/// interpolant of its velocity (its velocity, acceleration and jerk at both
/// ends): X(θ) = h·θ·(d0 + θ·(d1 + θ·(d2 + θ·(d3 + θ·(d4 + θ·d5))))),
/// θ = τ/h (the GPU kernel's `hermite` and `hermite_at`). The cubic one
/// (velocity and acceleration) left an O(h^5) error at a region's boundary
/// each step that outweighed the refinement's gain on chains with many
/// regions (a dimer chain: 2.5× worse than without it at t_s/90–t_s/160;
/// with the quintic 60× better).
#[derive(Clone, Copy)]
struct Hermite<R> {
    d: [R; 6],
    h: R,
}

impl<R: Real> Hermite<R> {
    /// From the velocity, acceleration and jerk at the start (`v0`, `a0`,
    /// `j0`) and end (`v1`, `a1`, `j1`) of a step of length `h`: the
    /// velocity's coefficients c0 … c5 in θ, then d_k = c_k/(k + 1).
    #[inline(always)]
    fn new([v0, a0, j0]: [R; 3], [v1, a1, j1]: [R; 3], h: R) -> Hermite<R> {
        let hh0 = h * (h * j0);
        let c1 = h * a0;
        let c2 = R::of(0.5) * hh0;
        let aa = v1 - ((v0 + c1) + c2);
        let bb = h * a1 - (c1 + R::of(2.0) * c2);
        let cc = h * (h * j1) - R::of(2.0) * c2;
        let c3 = (R::of(10.0) * aa - R::of(4.0) * bb) + R::of(0.5) * cc;
        let c4 = (R::of(7.0) * bb - R::of(15.0) * aa) - cc;
        let c5 = (R::of(6.0) * aa - R::of(3.0) * bb) + R::of(0.5) * cc;
        Hermite {
            d: [
                v0,
                R::of(0.5) * c1,
                R::of(1.0 / 6.0) * hh0,
                R::of(0.25) * c3,
                R::of(0.2) * c4,
                R::of(1.0 / 6.0) * c5,
            ],
            h,
        }
    }

    #[inline(always)]
    fn at(&self, th: R) -> R {
        let d = &self.d;
        let p = d[0] + th * (d[1] + th * (d[2] + th * (d[3] + th * (d[4] + th * d[5]))));
        self.h * th * p
    }
}

/// Velocity, acceleration and jerk of bead i at the step's start
/// (`start`: from the scratch) or its end (the state); beads outside the
/// window have not moved (their state is both). The jerk from the
/// contacts' force rates, 1.5·k·√δ·δ' (δ > 0), and the pulse's F·ω·cos ωt
/// (at `t`) while the step feels it.
#[inline(always)]
fn bead_rates<R: Real>(
    c: &Consts<R>,
    s: &State<R>,
    i: usize,
    start: bool,
    t: R,
    on: bool,
) -> [R; 3] {
    let n = s.v.len();
    let zero = R::zero();
    let inside = |k: usize| start && (s.lo..s.hi).contains(&k);
    let v = |k: usize| if inside(k) { s.scratch.v[k] } else { s.v[k] };
    let rate = |j: usize| {
        let p = if start { s.scratch.p[j] } else { s.p[j] };
        let d = c.d0[j] + p;
        if d > zero {
            let vl = if j == 0 { zero } else { v(j - 1) };
            let vr = if j == n { zero } else { v(j) };
            R::of(1.5) * c.k[j] * d.sqrt() * (vl - vr)
        } else {
            zero
        }
    };
    let mut jerk = (rate(i) - rate(i + 1)) * c.inv_mass[i];
    if let Some(pl) = c.pulse.as_ref().filter(|p| on && p.bead == i) {
        jerk = jerk + pl.force * pl.omega * push_cos(pl, t) * pl.inv_mass;
    }
    let a = if inside(i) { s.scratch.a[i] } else { s.a[i] };
    [v(i), a, jerk]
}

/// Redo beads a .. b (contacts a ..= b) of the step just taken as `mm`
/// finer steps from the step's start ([`Refine`]), in place; then the
/// beads just outside take the fine impulse of the boundary contacts and
/// their accelerations from the new forces.
/// Long (~130 lines) on purpose: the region's fine steps, the boundary
/// impulses and the kink corrections share a dozen of the step's locals;
/// it is the twin of the kernel's `redo` in `shaders/granular/chains.wgsl`,
/// kept in the same order so the two stay bit for bit alike.
fn redo<R: Real>(
    c: &Consts<R>,
    s: &mut State<R>,
    (t0, h, t_end): (R, R, R),
    m: &Substeps,
    kicks: &[f64],
    mm: usize,
    (a, b): (usize, usize),
) {
    // (A damped chain's springs kept for its next step would be stale
    // after a redo: `Beads::refinable`.)
    debug_assert!(c.damp.is_none());
    let n = s.v.len();
    let (lo, hi) = (s.lo, s.hi);
    let zero = R::zero();
    let half = R::of(0.5);
    // The outside beads' interpolants, from the step's end as it was.
    let on = pulse_on(c, t0);
    let outside = |i: usize| {
        Hermite::new(
            bead_rates(c, s, i, true, t0, on),
            bead_rates(c, s, i, false, t_end, on),
            h,
        )
    };
    let left = (a > lo).then(|| outside(a - 1));
    let right = (b < hi).then(|| outside(b));
    for j in a..=b {
        s.p[j] = s.scratch.p[j];
        s.e[j] = hertz(c.k[j], c.d0[j] + s.p[j]) - c.f0[j];
    }
    s.v[a..b].copy_from_slice(&s.scratch.v[a..b]);
    s.a[a..b].copy_from_slice(&s.scratch.a[a..b]);
    if a == 0 {
        s.x0 = s.scratch.x0;
    }
    let inv_m = R::of(1.0 / mm as f64);
    let hf = h * inv_m;
    let w = m.weights;
    let pulse = c.pulse.as_ref().filter(|p| on && (a..b).contains(&p.bead));
    // The fine steps' impulses of contacts a and b; the outside beads'
    // displacements so far.
    let (mut ja, mut jb) = (zero, zero);
    let (mut xa, mut xb) = (zero, zero);
    let mut th = zero;
    for i in 0..mm {
        s.scratch.p[a..=b].copy_from_slice(&s.p[a..=b]);
        let mut t = t0 + R::of(i as f64) * hf;
        let c0 = half * R::of(w[0]) * hf;
        ja = ja + c0 * s.e[a];
        jb = jb + c0 * s.e[b];
        for ii in a..b {
            s.v[ii] = s.v[ii] + c0 * s.a[ii];
        }
        for (j, &wj) in w.iter().enumerate() {
            let wj = R::of(wj);
            let dt = wj * hf;
            th = th + wj * inv_m;
            // Drift: contacts a ..= b, the outside beads along their
            // interpolants, walls still.
            let da = left.map(|q| {
                let x = q.at(th);
                let d = x - xa;
                xa = x;
                d
            });
            let db = right.map(|q| {
                let x = q.at(th);
                let d = x - xb;
                xb = x;
                d
            });
            for jj in a..=b {
                if jj == 0 {
                    s.p[0] = s.p[0] - dt * s.v[0];
                    s.x0 = s.x0 + dt * s.v[0];
                } else if jj == n {
                    s.p[n] = s.p[n] + dt * s.v[n - 1];
                } else if let (true, Some(d)) = (jj == a, da) {
                    s.p[jj] = s.p[jj] + (d - dt * s.v[jj]);
                } else if let (true, Some(d)) = (jj == b, db) {
                    s.p[jj] = s.p[jj] + (dt * s.v[jj - 1] - d);
                } else {
                    s.p[jj] = s.p[jj] + dt * (s.v[jj - 1] - s.v[jj]);
                }
            }
            t = t + dt;
            for jj in a..=b {
                s.e[jj] = hertz(c.k[jj], c.d0[jj] + s.p[jj]) - c.f0[jj];
            }
            for ii in a..b {
                s.a[ii] = (s.e[ii] - s.e[ii + 1]) * c.inv_mass[ii];
            }
            if let Some(pl) = pulse {
                let f = pl.force * push_sin(pl, t);
                s.a[pl.bead] = s.a[pl.bead] + f * pl.inv_mass;
            }
            let k = kick_weight(w, j, hf);
            ja = ja + k * s.e[a];
            jb = jb + k * s.e[b];
            for ii in a..b {
                s.v[ii] = s.v[ii] + k * s.a[ii];
            }
        }
        kinks(c, s, (a, b), hf, w, kicks);
        if let Some(x) = miss(c, s, a, hf, w, kicks) {
            ja = ja + x;
        }
        if let Some(x) = miss(c, s, b, hf, w, kicks) {
            jb = jb + x;
        }
    }
    // The outside beads: the fine impulse of their boundary contact in
    // place of the coarse one, and their accelerations from the new forces
    // (the pulse's at the step's last substep, as the step had it).
    let fix = |s: &mut State<R>, i: usize, dv: R| {
        s.v[i] = s.v[i] + dv * c.inv_mass[i];
        let mut acc = (s.e[i] - s.e[i + 1]) * c.inv_mass[i];
        if let Some(pl) = c.pulse.as_ref().filter(|p| on && p.bead == i) {
            acc = acc + pl.force * push_sin(pl, t_end) * pl.inv_mass;
        }
        s.a[i] = acc;
    };
    if left.is_some() {
        let dv = s.scratch.imp[a] - ja;
        fix(s, a - 1, dv);
    }
    if right.is_some() {
        let dv = jb - s.scratch.imp[b];
        fix(s, b, dv);
    }
}

#[cfg(test)]
mod tests {
    use super::{crosses, is_near};

    /// A precursor's contact going from δ = 0 to 1e-200 crosses zero (the
    /// kink correction takes it) but is not near a crossing: its change is
    /// below the floor, so no region is redone for it. A real crossing, or
    /// a contact closing to within `near`·|Δδ| of zero, is.
    #[test]
    fn a_precursor_is_no_region() {
        let (k, near, floor) = (1e10, 3.0, 1e-13);
        assert!(crosses(0.0, k, 0.0, 1e-200));
        assert!(!is_near(0.0, k, 0.0, 1e-200, near, floor));
        assert!(!is_near(0.0, k, -1e-14, 1e-14, near, floor));
        assert!(is_near(0.0, k, -1e-9, 1e-9, near, floor));
        assert!(is_near(0.0, k, 4e-9, 1e-9, near, floor));
        assert!(!is_near(0.0, k, 1e-6, 1e-6 - 1e-9, near, floor));
        // A contact with no stiffness (glue's absent spring) never is.
        assert!(!is_near(0.0, 0.0, -1e-9, 1e-9, near, floor));
    }

    /// With the damping at the steps' ends the sweeps read the springs the
    /// forces kept (`Springs::Reuse`): after the start and after every step
    /// of a windowed run, every contact's kept spring is, bit for bit, its
    /// spring at its overlap now — in the window (the last substep's
    /// forces) and out of it (an overlap moves only inside a window) — on
    /// a dimer with Hunt–Crossley contacts, dashpots and drag, pushed by a
    /// piston between precompressed walls.
    #[test]
    fn the_springs_a_step_keeps_are_those_at_its_end() {
        use super::{step, State};
        use crate::engine::granular::{hertz, plan, Beads, Consts};
        use crate::engine::{Overrides, Solver};
        use crate::scene::Scene;
        let src = "balls = 60\nradius = 0.005\n[pattern]\nradius = [0.005, 0.0035]\n\
                   [walls]\nleft = true\nright = true\nprecompression = 1.0\n[piston]\nvelocity = 0.2\n\
                   [launch]\nballs = 1\nvelocity = 0.5\n\
                   [damping]\nviscosity = 0.5\nrestitution = 0.9\nair_drag = 10.0\n\
                   [solver]\ndt = 2e-7\ndamping_split = \"ends\"\n[stop]\nduration = 2e-4\n";
        let scene = Scene::from_toml_str("kept", src).unwrap();
        let b = Beads::from_scene(&scene);
        let solver = Solver::resolve(&scene, &Overrides::default()).unwrap();
        let p = plan(&b, &solver, None);
        let m = p.substeps();
        assert!(m.ends);
        let c = Consts::<f64>::of(&b, p.rest);
        let mut s = State::start(&b, &c, m.weights, false, false);
        let kept = |s: &State<f64>| {
            (0..=b.n)
                .all(|j| s.scratch.spring[j].to_bits() == hertz(c.k[j], c.d0[j] + s.p[j]).to_bits())
        };
        assert!(kept(&s), "at the start");
        let mut widths = vec![];
        for k in 0..1000 {
            step(&c, &mut s, k as f64 * p.h, p.h, &m, false);
            assert!(kept(&s), "after step {k}");
            widths.push(s.hi - s.lo);
        }
        // The window moved and grew: contacts came into it with the springs
        // they had kept when they last moved.
        assert!(
            widths[0] < b.n && widths.iter().max() > widths.first(),
            "{widths:?}"
        );
    }

    /// A sweep of dashpots (in f64 on an AVX2 CPU, four contacts to a
    /// vector: `simd::dashpots`) gives the same bits as the contacts one by
    /// one ([`dashpot`]), on random states of a trimer chain between walls
    /// that take every branch: open contacts, overlaps of 1e-250 (a spring
    /// that underflows) to 1e-5, beads at equal speeds (−0 too), pulls cut
    /// at the spring's push, Hunt–Crossley χ new, kept and lowered, NaN;
    /// both parities first, windows starting and ending at either parity, a
    /// substep's three sweeps and a step end's two (which reuse the forces'
    /// springs), forward and back in time; dashpots, and Hunt–Crossley
    /// contacts with them and without.
    #[test]
    fn a_sweep_is_its_dashpots_one_by_one() {
        use super::{dashpot, sweep, Springs};
        use crate::engine::granular::Consts;
        let mut next = uniform(0x9e37_79b9_7f4a_7c15);
        let same = |a: &[f64], b: &[f64]| {
            a.len() == b.len()
                && a.iter()
                    .zip(b)
                    .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
        };
        let mut cut = 0;
        let dampings = [
            "viscosity = 40.0\n",
            "viscosity = 2.0\nrestitution = 0.7\n",
            "restitution = 0.7\n",
        ];
        for damping in dampings {
            let b = trimer(damping);
            let c = Consts::<f64>::of(&b, 0.0);
            let d = c.damp.as_ref().unwrap();
            for round in 0..400 {
                let n = b.n;
                let mut s = random_state(&b, &c, &mut next);
                if round == 7 {
                    s.v[20] = f64::NAN;
                }
                let t = [2e-7, 1e-6, -3e-7][round % 3];
                // Windows of every parity at both ends, and the whole chain.
                if round % 5 != 0 {
                    (s.lo, s.hi) = ((next() * 6.0) as usize, n - (next() * 14.0) as usize);
                }
                let first = s.lo + (round / 3) % 2;
                let other = if first == s.lo { s.lo + 1 } else { s.lo };
                // A damping substep's three sweeps (the even contacts keep
                // their springs, the odd ones take theirs, the even ones
                // reuse theirs), or a step end's two, which reuse the
                // forces' springs.
                let ends = round % 4 == 1;
                let t1 = if ends { t } else { 0.5 * t };
                let passes = if ends {
                    for j in 0..=n {
                        s.scratch.spring[j] = super::hertz(c.k[j], c.d0[j] + s.p[j]);
                    }
                    vec![(first, t, Springs::Reuse), (other, t, Springs::Reuse)]
                } else {
                    vec![
                        (first, t1, Springs::Keep),
                        (other, t, Springs::Take),
                        (first, t1, Springs::Reuse),
                    ]
                };
                let (pre, mut one) = (s.clone(), s.clone());
                for (from, t, springs) in passes {
                    if t > 0.0 {
                        sweep::<f64, false>(&c, d, &mut s, from, t, springs);
                    } else {
                        sweep::<f64, true>(&c, d, &mut s, from, t, springs);
                    }
                    for j in (from..=one.hi).step_by(2) {
                        if t > 0.0 {
                            dashpot::<f64, false>(&c, d, &mut one, j, t);
                        } else {
                            dashpot::<f64, true>(&c, d, &mut one, j, t);
                        }
                    }
                }
                assert!(same(&s.v, &one.v), "velocities, round {round}");
                assert!(same(&s.lost_c, &one.lost_c), "energy, round {round}");
                assert!(
                    same(&s.scratch.dimp, &one.scratch.dimp),
                    "impulse, round {round}"
                );
                assert!(same(&s.chi, &one.chi), "chi, round {round}");
                // Pulls cut at the spring's push happened (the rule's branch
                // was taken), counted on the dashpots alone in the first sweep.
                if d.hc == 0.0 {
                    cut += (first..=pre.hi)
                        .step_by(2)
                        .filter(|&j| {
                            let v = &pre.v;
                            let va = if j > 0 { v[j - 1] } else { 0.0 };
                            let w = va - if j < n { v[j] } else { 0.0 };
                            let dl = c.d0[j] + pre.p[j];
                            let x = d.beta[j] * t1;
                            let wn = w * (2.0 - x) / (2.0 + x);
                            let lim = w + super::hertz(c.k[j], dl) * t1 * d.inv_mu[j];
                            dl > 0.0 && w < 0.0 && t > 0.0 && wn > lim
                        })
                        .count();
                }
            }
        }
        assert!(cut > 0);
    }

    /// Hunt–Crossley's ratchet at a step's end (in f64 on an AVX2 CPU,
    /// four contacts to a vector: `simd::ratchet`) gives the same bits as
    /// the contacts one by one, on random states that take every branch:
    /// open contacts (cleared), χ new, kept, rising (negative) and NaN,
    /// contacts that start to rise or go on rising, windows of every
    /// length at both ends and the whole chain.
    #[test]
    fn the_ratchet_is_its_contacts_one_by_one() {
        use super::ratchet_in;
        use crate::engine::granular::Consts;
        let b = trimer("restitution = 0.7\n");
        let c = Consts::<f64>::of(&b, 0.0);
        let d = c.damp.as_ref().unwrap();
        let mut next = uniform(0x51_7cc1_b727_220a);
        let (mut rose, mut cleared, mut kept) = (0, 0, 0);
        for round in 0..300 {
            let mut s = random_state(&b, &c, &mut next);
            // Rising contacts (χ < 0), and χ of either sign near a over
            // the closing speed, so that contacts start to rise.
            for j in 0..=b.n {
                let w = if j > 0 && j < b.n {
                    s.v[j - 1] - s.v[j]
                } else {
                    0.0
                };
                s.chi[j] = match (next() * 4.0) as u32 {
                    0 => -s.chi[j],
                    1 => d.hc / w * (0.9 + 0.2 * next()),
                    _ => s.chi[j],
                };
            }
            if round == 3 {
                s.chi[17] = f64::NAN;
            }
            if round % 4 != 0 {
                s.lo = (next() * 8.0) as usize;
                s.hi = (s.lo + (next() * 40.0) as usize).min(b.n);
            }
            let (before, mut one) = (s.clone(), s.clone());
            ratchet_in(&c, d, &mut s, super::vector_sweeps::<f64>());
            ratchet_in(&c, d, &mut one, false);
            for j in 0..s.chi.len() {
                let (v, o) = (s.chi[j], one.chi[j]);
                assert!(
                    v.to_bits() == o.to_bits() || (v.is_nan() && o.is_nan()),
                    "contact {j}, round {round}: {v} against {o}"
                );
                if j >= s.lo && j <= s.hi {
                    rose += (o < 0.0 && before.chi[j] >= 0.0) as usize;
                    cleared += (o == 0.0 && before.chi[j] != 0.0) as usize;
                    kept += (o > 0.0 && o == before.chi[j]) as usize;
                }
            }
        }
        assert!(
            rose > 100 && cleared > 100 && kept > 100,
            "{rose} {cleared} {kept}"
        );
    }

    /// The random tests' chain: 43 beads of a trimer's three radii between
    /// walls, struck at one end, with `damping` (the `[damping]` table's
    /// keys).
    fn trimer(damping: &str) -> crate::engine::granular::Beads {
        let src = format!(
            "balls = 43\nradius = 0.005\n[pattern]\nradius = [0.005, 0.0035, 0.004]\n\
             [walls]\nleft = true\nright = true\n[launch]\nballs = 1\nvelocity = 0.1\n\
             [damping]\n{damping}"
        );
        let scene = crate::scene::Scene::from_toml_str("trimer", &src).unwrap();
        crate::engine::granular::Beads::from_scene(&scene)
    }

    /// Uniform numbers in [0, 1) from `seed` by xorshift64*: a fixed
    /// sequence, no dependency.
    fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut x = seed;
        move || {
            x ^= x >> 12;
            x ^= x << 25;
            x ^= x >> 27;
            (x.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// A damped chain's state for the random tests
    /// ([`a_sweep_is_its_dashpots_one_by_one`], [`the_ratchet_is_its_contacts_one_by_one`]):
    /// overlaps from open to 1e-5 (1e-250 and 1e-205 among them), energies,
    /// impulses, χ new, small and large, velocities with equal neighbours
    /// and −0.
    fn random_state(
        b: &crate::engine::granular::Beads,
        c: &crate::engine::granular::Consts<f64>,
        next: &mut impl FnMut() -> f64,
    ) -> super::State<f64> {
        let mut s = super::State::start(b, c, &[1.0], true, false);
        let n = b.n;
        for j in 0..=n {
            let r = next();
            let dl = match (r * 10.0) as u32 {
                0 => -1e-6 * next(),
                1 => 0.0,
                2 => 1e-250 * next(),
                3 => 1e-205 * (1.0 + next()),
                4 => 1e-17 * next(),
                5 | 6 => 1e-10 * (1.0 + 1e3 * next()),
                _ => 1e-5 * next(),
            };
            s.p[j] = dl - c.d0[j];
            s.lost_c[j] = next() * 1e-6;
            s.scratch.dimp[j] = (next() - 0.5) * 1e-6;
            if !s.chi.is_empty() {
                s.chi[j] = [0.0, 0.5 * next(), 50.0 * next()][(next() * 3.0) as usize];
            }
        }
        for i in 0..n {
            s.v[i] = match (next() * 12.0) as u32 {
                0 if i > 0 => s.v[i - 1],
                1 => -0.0,
                _ => 0.2 * (next() - 0.5),
            };
        }
        s
    }
}
