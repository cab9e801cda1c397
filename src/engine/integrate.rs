//! The integrator — the one place on the Rust side that advances a chain in
//! time. Its WGSL twin is `src/engine/integrate.wgsl` (same function names).
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

use super::contact::{contact_force, fifth_root, hertz_force};
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
fn add<R: Real>(v: &mut R, cv: &mut R, inc: R) {
    if R::COMPENSATED {
        let y = inc - *cv;
        let t = *v + y;
        *cv = (t - *v) - y;
        *v = t;
    } else {
        *v = *v + inc;
    }
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
fn graded_steps<R: Real, const L: usize>(
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
struct Accel<'a, R, const L: usize> {
    f: &'a [[R; L]; MAX_BALLS],
    inv_m: &'a [[R; L]; MAX_BALLS],
    g: &'a [[R; L]; MAX_BALLS],
    pend: bool,
}

/// min and max without the NaN care of `f64::min`: one instruction each.
/// A NaN anywhere ends the run as non-finite before it matters.
#[inline(always)]
fn lo<R: Real>(a: R, b: R) -> R {
    if b < a {
        b
    } else {
        a
    }
}
#[inline(always)]
fn hi<R: Real>(a: R, b: R) -> R {
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
fn stiffness_cap<R: Real, const L: usize>(
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

/// Chains of up to 12 bodies integrated side by side per batch (longer ones:
/// 4, so that every lane's state stays in L1 cache).
pub const LANES: usize = 32;

/// Integrate every task, [`LANES`] at a time; results in task order. The
/// same arithmetic, operation for operation, as [`integrate`] on each.
pub fn integrate_batch<R: Real>(tasks: &[Task]) -> Vec<Run> {
    let keys: Vec<_> = tasks.iter().map(Task::key).collect();
    let mut order: Vec<usize> = (0..tasks.len()).collect();
    order.sort_by_key(|&i| keys[i]);
    let mut out: Vec<Option<Run>> = vec![None; tasks.len()];
    for group in order.chunk_by(|&a, &b| keys[a] == keys[b]) {
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx") {
            // SAFETY: the CPU has AVX (checked just above).
            unsafe { run_group_avx::<R>(tasks, group, &mut out) };
            continue;
        }
        run_group::<R>(tasks, group, &mut out);
    }
    out.into_iter()
        .map(|r| r.expect("every task ran"))
        .collect()
}

/// [`run_group`] compiled for AVX: four f64 (eight f32) lanes per
/// instruction instead of two (four). No FMA: the rounding is the same as
/// without AVX, operation for operation.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn run_group_avx<R: Real>(tasks: &[Task], group: &[usize], out: &mut [Option<Run>]) {
    run_group::<R>(tasks, group, out)
}

/// One group of equal keys, with or without the gravity and damping terms.
#[inline(always)]
fn run_group<R: Real>(tasks: &[Task], group: &[usize], out: &mut [Option<Run>]) {
    let ch = tasks[group[0]].chain;
    // Long chains in fewer lanes: the state of every lane stays in L1 cache.
    match (ch.needs_terms(), ch.n_bodies() <= 12) {
        (false, true) => run_lanes::<R, Silent, false, LANES>(tasks, group, out, &mut Silent),
        (false, false) => run_lanes::<R, Silent, false, 4>(tasks, group, out, &mut Silent),
        (true, true) => run_lanes::<R, Silent, true, LANES>(tasks, group, out, &mut Silent),
        (true, false) => run_lanes::<R, Silent, true, 4>(tasks, group, out, &mut Silent),
    }
}

/// Integrate one chain with the steps of `plan`, in precision `R`, reporting
/// states to `obs`. See the module doc for what is skipped.
pub fn integrate<R: Real, O: Observer>(
    ch: &Chain,
    plan: &StepPlan,
    lim: &Limits,
    obs: &mut O,
) -> Run {
    let tasks = [Task {
        chain: ch,
        plan: *plan,
        lim: *lim,
    }];
    let mut out = vec![None];
    // Work a scene does not need is not compiled in: an elastic free line
    // runs a variant without the gravity, damping and drag terms.
    if ch.needs_terms() {
        run_lanes::<R, O, true, 1>(&tasks, &[0], &mut out, obs);
    } else {
        run_lanes::<R, O, false, 1>(&tasks, &[0], &mut out, obs);
    }
    out.pop().flatten().expect("the task ran")
}

/// Settings shared by every lane of a group.
struct Shape {
    nb: usize,
    nc: usize,
    pend: bool,
    damped: bool,
    dragged: bool,
    graded: bool,
    quarters: u32,
    track_x: bool,
}

/// The state and constants of `L` runs, lane l of each array for run l.
struct Lanes<R, const L: usize> {
    v: [[R; L]; MAX_BALLS],
    /// Kahan compensation of `v` (f32 only).
    cv: [[R; L]; MAX_BALLS],
    d: [[R; L]; MAX_BALLS],
    /// Kahan compensation of `d` (f32 only).
    cd: [[R; L]; MAX_BALLS],
    /// Contact forces (N).
    f: [[R; L]; MAX_BALLS],
    /// Gravity accelerations of the bodies (pendulum; m/s²).
    acc: [[R; L]; MAX_BALLS],
    /// Hunt–Crossley χ of each contact (s/m), set while it is open.
    chi: [[R; L]; MAX_BALLS],
    /// Overlaps at the start of the step (onset counting).
    d0: [[R; L]; MAX_BALLS],
    /// Displacement of body 0 (m) and its compensation.
    x0: [R; L],
    cx0: [R; L],
    inv_m: [[R; L]; MAX_BALLS],
    gap: [[R; L]; MAX_BALLS],
    kc: [[R; L]; MAX_BALLS],
    g: [R; L],
    inv_l: [R; L],
    drag: [R; L],
    a_e: [R; L],
    v_floor: [R; L],
    hr: [R; L],
    h_free: [R; L],
    h_min: [R; L],
    t_scale: [R; L],
    /// The step each lane takes now (0: idle lane).
    step: [R; L],
    closed: [bool; L],
    /// Largest overlap seen (m), its ratio to the smaller radius, and
    /// 1/radius of each contact.
    max_ov: [f64; L],
    max_ratio: [f64; L],
    /// Largest overlap of each contact after a step (m); folded into
    /// `max_ov` and `max_ratio` when the run ends.
    dmax: [[R; L]; MAX_BALLS],
    inv_r: [[f64; L]; MAX_BALLS],
    /// Closed-form impact coefficients of each contact
    /// ([`super::contact::impact_coefficients`]).
    imp_t: [[R; L]; MAX_BALLS],
    imp_d: [[R; L]; MAX_BALLS],
    exact: [bool; L],
    /// Stiffness-cap coefficients of each contact
    /// ([`super::Chain::stiffness_coefficients`]) and the cap's step.
    stiff_l: [[R; L]; MAX_BALLS],
    stiff_r: [[R; L]; MAX_BALLS],
    h_stiff: [R; L],
    run: [Book; L],
}

/// A lane's bookkeeping, in f64.
#[derive(Clone, Copy)]
struct Book {
    /// Index of the task in the lane; `None`: idle.
    task: Option<usize>,
    t: f64,
    steps: u64,
    contacts: u64,
    t_first: Option<f64>,
    t_release: Option<f64>,
    /// The step lands on a pendulum's duration.
    last: bool,
    lim: Limits,
}

const IDLE: Book = Book {
    task: None,
    t: 0.0,
    steps: 0,
    contacts: 0,
    t_first: None,
    t_release: None,
    last: false,
    lim: Limits {
        max_steps: 0,
        max_time: 0.0,
    },
};

/// Force of one contact: Hertz, or Hunt–Crossley with closing speed `r`.
#[inline(always)]
fn contact<R: Real>(damped: bool, k: R, d: R, chi: R, r: R) -> R {
    if damped {
        contact_force(k, d, chi, r)
    } else {
        hertz_force(k, d)
    }
}

impl<R: Real, const L: usize> Lanes<R, L> {
    fn new() -> Box<Self> {
        let z = [[R::zero(); L]; MAX_BALLS];
        let zl = [R::zero(); L];
        Box::new(Lanes {
            v: z,
            cv: z,
            d: z,
            cd: z,
            f: z,
            acc: z,
            chi: z,
            d0: z,
            x0: zl,
            cx0: zl,
            inv_m: z,
            gap: z,
            kc: z,
            g: zl,
            inv_l: zl,
            drag: zl,
            a_e: zl,
            v_floor: zl,
            hr: zl,
            h_free: zl,
            h_min: zl,
            t_scale: zl,
            step: zl,
            closed: [false; L],
            max_ov: [0.0; L],
            max_ratio: [0.0; L],
            dmax: z,
            inv_r: [[0.0; L]; MAX_BALLS],
            imp_t: z,
            imp_d: z,
            exact: [false; L],
            stiff_l: z,
            stiff_r: z,
            h_stiff: zl,
            run: [IDLE; L],
        })
    }

    /// Put run `i` into lane `l`.
    fn load(&mut self, sh: &Shape, l: usize, i: usize, task: &Task) {
        let (ch, plan) = (task.chain, &task.plan);
        let zero = R::zero();
        for b in 0..sh.nb {
            self.v[b][l] = R::of(ch.v0[b]);
            self.inv_m[b][l] = R::of(1.0 / ch.mass[b]);
            self.acc[b][l] = zero;
            self.cv[b][l] = zero;
        }
        let d_init = ch.initial_overlap();
        let mut book = IDLE;
        for c in 0..sh.nc {
            self.d[c][l] = R::of(d_init[c]);
            self.gap[c][l] = R::of(ch.gap[c]);
            self.kc[c][l] = R::of(ch.k[c]);
            self.cd[c][l] = zero;
            self.chi[c][l] = zero;
            self.f[c][l] = zero;
            self.inv_r[c][l] = 1.0 / ch.r_min[c];
            let (a, b) = ch.impact_coefficients(c);
            self.imp_t[c][l] = R::of(a);
            self.imp_d[c][l] = R::of(b);
            let (sl, sr) = ch.stiffness_coefficients(c, plan.omega_ref);
            self.stiff_l[c][l] = R::of(sl);
            self.stiff_r[c][l] = R::of(sr);
        }
        self.h_stiff[l] = R::of(plan.h_stiff);
        self.exact[l] = plan.exact;
        self.x0[l] = R::of(ch.x0[0]);
        self.cx0[l] = zero;
        self.g[l] = R::of(ch.gravity);
        self.inv_l[l] = R::of(if ch.is_pendulum() {
            1.0 / ch.length
        } else {
            0.0
        });
        self.drag[l] = R::of(ch.air_drag);
        self.a_e[l] = R::of(ch.damping_a);
        self.hr[l] = R::of(plan.h);
        self.h_free[l] = R::of(plan.h_free);
        self.h_min[l] = R::of(plan.h_min);
        self.t_scale[l] = R::of(plan.t_scale);
        // Closing speeds at round-off level are noise, not an approach: without
        // this floor two balls left at ±1e-15 m/s would "collide" a billion years
        // later and hit the time cap.
        self.v_floor[l] = closing_speed_floor::<R>(ch.v_in(), plan.settle_rel);
        self.step[l] = zero;
        self.max_ov[l] = 0.0;
        self.max_ratio[l] = 0.0;
        for c in 0..sh.nc {
            self.dmax[c][l] = R::zero();
        }
        book.task = Some(i);
        book.lim = task.lim;
        self.run[l] = book;
        self.closed[l] = self.forces_one(sh, l);
    }

    /// The running lanes, moved into a kernel of `M` lanes (at least as many).
    fn narrow<const M: usize>(&self, sh: &Shape) -> Box<Lanes<R, M>> {
        let mut to = Lanes::<R, M>::new();
        let mut m = 0;
        for l in 0..L {
            if self.run[l].task.is_some() {
                self.move_lane(sh, l, &mut to, m);
                m += 1;
            }
        }
        to
    }

    /// Move lane l, state and bookkeeping, into lane m of `to`.
    fn move_lane<const M: usize>(&self, sh: &Shape, l: usize, to: &mut Lanes<R, M>, m: usize) {
        for b in 0..sh.nb {
            to.v[b][m] = self.v[b][l];
            to.cv[b][m] = self.cv[b][l];
            to.acc[b][m] = self.acc[b][l];
            to.inv_m[b][m] = self.inv_m[b][l];
        }
        for c in 0..sh.nc {
            to.d[c][m] = self.d[c][l];
            to.cd[c][m] = self.cd[c][l];
            to.f[c][m] = self.f[c][l];
            to.chi[c][m] = self.chi[c][l];
            to.d0[c][m] = self.d0[c][l];
            to.gap[c][m] = self.gap[c][l];
            to.kc[c][m] = self.kc[c][l];
            to.inv_r[c][m] = self.inv_r[c][l];
            to.imp_t[c][m] = self.imp_t[c][l];
            to.imp_d[c][m] = self.imp_d[c][l];
            to.stiff_l[c][m] = self.stiff_l[c][l];
            to.stiff_r[c][m] = self.stiff_r[c][l];
        }
        to.h_stiff[m] = self.h_stiff[l];
        to.x0[m] = self.x0[l];
        to.cx0[m] = self.cx0[l];
        to.g[m] = self.g[l];
        to.inv_l[m] = self.inv_l[l];
        to.drag[m] = self.drag[l];
        to.a_e[m] = self.a_e[l];
        to.v_floor[m] = self.v_floor[l];
        to.hr[m] = self.hr[l];
        to.h_free[m] = self.h_free[l];
        to.h_min[m] = self.h_min[l];
        to.t_scale[m] = self.t_scale[l];
        to.step[m] = self.step[l];
        to.closed[m] = self.closed[l];
        to.exact[m] = self.exact[l];
        to.max_ov[m] = self.max_ov[l];
        to.max_ratio[m] = self.max_ratio[l];
        for c in 0..sh.nc {
            to.dmax[c][m] = self.dmax[c][l];
        }
        to.run[m] = self.run[l];
    }

    /// Lane l takes task `i`, or idles (step 0, state cleared) if there is none.
    fn next<O: Observer>(
        &mut self,
        sh: &Shape,
        l: usize,
        i: Option<usize>,
        tasks: &[Task],
        obs: &mut O,
    ) {
        match i {
            Some(i) => {
                self.load(sh, l, i, &tasks[i]);
                observe(sh, self, l, tasks[i].chain, obs);
            }
            None => {
                for b in 0..sh.nb {
                    self.v[b][l] = R::zero();
                    self.d[b][l] = R::zero();
                    self.f[b][l] = R::zero();
                    self.acc[b][l] = R::zero();
                }
                self.step[l] = R::zero();
                self.run[l] = IDLE;
            }
        }
    }

    /// Forces of lane l's contacts (and gravity on a pendulum); whether any
    /// contact is closed.
    #[inline(always)]
    fn forces_one(&mut self, sh: &Shape, l: usize) -> bool {
        let mut closed = false;
        for c in 0..sh.nc {
            let r = self.v[c][l] - self.v[c + 1][l];
            self.f[c][l] = contact(sh.damped, self.kc[c][l], self.d[c][l], self.chi[c][l], r);
            closed |= self.d[c][l] > R::zero();
        }
        if sh.pend {
            let mut x = self.x0[l];
            self.acc[0][l] = -(self.g[l] * pendulum_sin(x * self.inv_l[l]));
            for b in 1..sh.nb {
                x = x - self.gap[b - 1][l] - self.d[b - 1][l];
                self.acc[b][l] = -(self.g[l] * pendulum_sin(x * self.inv_l[l]));
            }
        }
        closed
    }

    /// [`Self::forces_one`] on every lane, one loop over the lanes per contact.
    #[inline(always)]
    fn forces(&mut self, sh: &Shape) {
        let zero = R::zero();
        let mut closed = [false; L];
        for c in 0..sh.nc {
            let (k, d, chi, f) = (&self.kc[c], &self.d[c], &self.chi[c], &mut self.f[c]);
            let (va, vb) = (&self.v[c], &self.v[c + 1]);
            // Lanes four at a time (one AVX vector of f64): where the contact
            // is open in all four, the force is 0 without a square root.
            let w = if L.is_multiple_of(4) { 4 } else { L };
            for j in (0..L).step_by(w) {
                let mut any = false;
                for l in j..j + w {
                    any |= d[l] > zero;
                }
                if any {
                    for l in j..j + w {
                        f[l] = contact(sh.damped, k[l], d[l], chi[l], va[l] - vb[l]);
                    }
                } else {
                    f[j..j + w].fill(zero);
                }
                for l in j..j + w {
                    closed[l] |= d[l] > zero;
                }
            }
        }
        self.closed = closed;
        if sh.pend {
            let mut x = self.x0;
            for l in 0..L {
                self.acc[0][l] = -(self.g[l] * pendulum_sin(x[l] * self.inv_l[l]));
            }
            for b in 1..sh.nb {
                for l in 0..L {
                    x[l] = x[l] - self.gap[b - 1][l] - self.d[b - 1][l];
                    self.acc[b][l] = -(self.g[l] * pendulum_sin(x[l] * self.inv_l[l]));
                }
            }
        }
    }

    /// Half a kick of `hh` seconds on every lane: air drag (exact decay), then
    /// contact forces and gravity. Body b is pushed left by contact b and right
    /// by contact b−1; gravity is added after the contact push (as in the
    /// shader's `push`).
    #[inline(always)]
    fn kick(&mut self, sh: &Shape, hh: &[R; L]) {
        let nb = sh.nb;
        if sh.dragged {
            for l in 0..L {
                let q = decay(self.drag[l] * hh[l]);
                for b in 0..nb {
                    self.v[b][l] = self.v[b][l] * q;
                    self.cv[b][l] = self.cv[b][l] * q;
                }
            }
        }
        for b in 0..nb {
            for l in 0..L {
                let im = self.inv_m[b][l];
                let mut inc = if b == 0 {
                    -(hh[l] * self.f[0][l] * im)
                } else if b == nb - 1 {
                    hh[l] * self.f[nb - 2][l] * im
                } else {
                    hh[l] * (self.f[b - 1][l] - self.f[b][l]) * im
                };
                if sh.pend {
                    inc = inc + hh[l] * self.acc[b][l];
                }
                add(&mut self.v[b][l], &mut self.cv[b][l], inc);
            }
        }
    }

    /// One step of every lane: velocity-Verlet substeps (kick, drift, forces,
    /// kick) of sizes `w·step`, the closing half kick of each substep joined
    /// with the opening one of the next ([`kick_weights`]).
    #[inline(always)]
    fn substeps(&mut self, sh: &Shape, weights: &[f64], kicks: &[f64]) {
        let times = |c: f64, step: &[R; L]| {
            let c = R::of(c);
            let mut hk = [R::zero(); L];
            for l in 0..L {
                hk[l] = c * step[l];
            }
            hk
        };
        self.kick(sh, &times(kicks[0], &self.step));
        for (&w, &k) in weights.iter().zip(&kicks[1..]) {
            let ws = times(w, &self.step);
            for c in 0..sh.nc {
                for l in 0..L {
                    let inc = ws[l] * (self.v[c][l] - self.v[c + 1][l]);
                    add(&mut self.d[c][l], &mut self.cd[c][l], inc);
                }
            }
            if sh.track_x {
                for l in 0..L {
                    let inc = ws[l] * self.v[0][l];
                    add(&mut self.x0[l], &mut self.cx0[l], inc);
                }
            }
            self.forces(sh);
            self.kick(sh, &times(k, &self.step));
        }
    }

    /// The impact that contact c (open, just touching, closing) starts, in
    /// closed form, if nothing else can touch while it lasts: bodies a = c
    /// and b = c+1 leave with the elastic two-body velocities after the
    /// two-body contact time t_c, both having moved V_cm·t_c (the overlap is
    /// 0 at both ends), every other body v·t_c. Isolated: the neighbour
    /// contacts stay open even if a and b moved at the extreme speeds they
    /// pass through, and no other contact closes within t_c. Returns whether
    /// it was taken; the same operations as `exact_impact` in the shader.
    fn exact_impact(&mut self, sh: &Shape, l: usize, c: usize) -> bool {
        let zero = R::zero();
        let (a, b) = (c, c + 1);
        let (va, vb) = (self.v[a][l], self.v[b][l]);
        let u = va - vb;
        let (ia, ib) = (self.inv_m[a][l], self.inv_m[b][l]);
        let fa = ia / (ia + ib); // m_b / (m_a + m_b)
        let fb = ib / (ia + ib); // m_a / (m_a + m_b)
        let w = fifth_root(u);
        let tc = self.imp_t[c][l] / w;
        let va2 = va - (fa + fa) * u;
        let vb2 = vb + (fb + fb) * u;
        let vcm = va - fa * u;
        if c > 0 && self.d[c - 1][l] + (self.v[a - 1][l] - va.min(va2)).max(zero) * tc > zero {
            return false;
        }
        if b < sh.nc && self.d[b][l] + (vb.max(vb2) - self.v[b + 1][l]).max(zero) * tc > zero {
            return false;
        }
        let speed =
            |v: &[[R; L]; MAX_BALLS], i: usize| if i == a || i == b { vcm } else { v[i][l] };
        for j in 0..sh.nc {
            if (j + 1 < c || j > b) && self.d[j][l] + (self.v[j][l] - self.v[j + 1][l]) * tc > zero
            {
                return false;
            }
        }
        for j in 0..sh.nc {
            if j != c {
                self.d[j][l] = self.d[j][l] + (speed(&self.v, j) - speed(&self.v, j + 1)) * tc;
            }
        }
        if sh.track_x {
            self.x0[l] = self.x0[l] + speed(&self.v, 0) * tc;
        }
        self.v[a][l] = va2;
        self.v[b][l] = vb2;
        self.cv[a][l] = zero;
        self.cv[b][l] = zero;
        let dmax = (self.imp_d[c][l] * u / w).to64();
        self.max_ov[l] = self.max_ov[l].max(dmax);
        self.max_ratio[l] = self.max_ratio[l].max(dmax * self.inv_r[c][l]);
        let book = &mut self.run[l];
        book.t += tc.to64();
        book.contacts += 1;
        book.t_release = Some(book.t_release.map_or(book.t, |x: f64| x.max(book.t)));
        true
    }

    /// Free flight of lane l (every contact open): jump to the next onset,
    /// taking isolated impacts in closed form on the way. `Some(end)` when
    /// the run is over.
    #[inline(never)]
    fn fly<O: Observer>(&mut self, sh: &Shape, l: usize, ch: &Chain, obs: &mut O) -> Option<End> {
        let zero = R::zero();
        let nc = sh.nc;
        loop {
            // Free flight: every contact open. Jump to the next onset, if any.
            let book = &mut self.run[l];
            let mut tau = R::infinity();
            let mut next = None;
            for c in 0..nc {
                let r = self.v[c][l] - self.v[c + 1][l];
                if r > self.v_floor[l] {
                    let dt = -self.d[c][l] / r;
                    if dt < tau {
                        tau = dt;
                        next = Some(c);
                    }
                }
            }
            let Some(next) = next else {
                return Some(End::Settled);
            };
            let mut tau64 = tau.to64();
            let capped = book.t + tau64 > book.lim.max_time;
            if capped {
                tau64 = (book.lim.max_time - book.t).max(0.0);
                tau = R::of(tau64);
            }
            if tau > zero {
                for c in 0..nc {
                    let r = self.v[c][l] - self.v[c + 1][l];
                    let d = self.d[c][l] + r * tau;
                    // A closing speed at or below the floor is no onset, but
                    // while the rest of the chain goes on the pair must not
                    // pass through each other: it stops touching (its collision
                    // would change velocities by less than the floor).
                    self.d[c][l] = if r > zero && r <= self.v_floor[l] {
                        d.min(zero)
                    } else {
                        d
                    };
                }
                if sh.track_x {
                    self.x0[l] = self.x0[l] + self.v[0][l] * tau;
                }
                book.t += tau64;
                observe(sh, self, l, ch, obs);
            }
            let book = &mut self.run[l];
            if capped {
                return Some(End::TimeCap);
            }
            self.d[next][l] = zero; // the onset, exactly
            self.cd[next][l] = zero;
            book.t_first.get_or_insert(book.t);
            // An isolated impact is over in one jump; then free flight again.
            if !(self.exact[l] && self.exact_impact(sh, l, next)) {
                break;
            }
            observe(sh, self, l, ch, obs);
        }
        None
    }

    /// Lane l before its next step: free flight to the next onset (free line),
    /// then the end checks. `Some(end)` when the run is over.
    #[inline(always)]
    fn ready<O: Observer>(&mut self, sh: &Shape, l: usize, ch: &Chain, obs: &mut O) -> Option<End> {
        if !self.closed[l] && !sh.pend {
            if let Some(end) = self.fly(sh, l, ch, obs) {
                return Some(end);
            }
        }
        let book = &mut self.run[l];
        if sh.pend && book.t >= book.lim.max_time {
            return Some(End::Duration);
        }
        if book.steps >= book.lim.max_steps {
            return Some(End::StepCap);
        }
        if book.t >= book.lim.max_time {
            return Some(End::TimeCap);
        }
        None
    }

    /// The step of every lane (0 for an idle one): graded near kinks; on a
    /// pendulum long in free flight and landing exactly on the duration. Then
    /// the overlaps at its start and, damped, each contact's χ.
    #[inline(always)]
    fn plan_steps(&mut self, sh: &Shape) {
        let zero = R::zero();
        let mut step = self.hr;
        if sh.pend || sh.graded {
            let mut s0 = self.hr;
            if sh.pend {
                for l in 0..L {
                    if !self.closed[l] {
                        s0[l] = self.h_free[l];
                    }
                }
            }
            stiffness_cap(
                sh.nc,
                &self.d,
                &self.stiff_l,
                &self.stiff_r,
                &self.h_stiff,
                &self.h_min,
                &mut s0,
            );
            let acc = Accel {
                f: &self.f,
                inv_m: &self.inv_m,
                g: &self.acc,
                pend: sh.pend,
            };
            step = graded_steps(
                sh.nc,
                &self.d,
                &self.v,
                &acc,
                &s0,
                &self.hr,
                &self.h_min,
                &self.t_scale,
                if sh.graded { sh.quarters } else { 0 },
            );
        }
        for l in 0..L {
            let book = &mut self.run[l];
            book.last = false;
            if book.task.is_none() {
                step[l] = zero;
            } else if sh.pend {
                let rest = R::of(book.lim.max_time - book.t);
                if rest <= step[l] {
                    step[l] = rest;
                    book.last = true;
                }
            }
        }
        self.step = step;
        self.d0[..sh.nc].copy_from_slice(&self.d[..sh.nc]);
        if sh.damped {
            for c in 0..sh.nc {
                for l in 0..L {
                    // Hunt–Crossley: χ = a/v_imp, v_imp the closing speed the
                    // contact closes with — or, if it is driven harder while
                    // closed (a gentle touch, then a hit from behind), the
                    // largest closing speed since.
                    let chi = self.a_e[l] / (self.v[c][l] - self.v[c + 1][l]).max(self.v_floor[l]);
                    self.chi[c][l] = if self.d[c][l] <= zero {
                        chi
                    } else {
                        self.chi[c][l].min(chi)
                    };
                }
            }
        }
    }

    /// Every lane after its step: time, overlaps (vectorised), then, on the
    /// lanes where a contact opened or closed, onsets and releases (located
    /// inside the step by linear interpolation of δ; graded methods land on
    /// them anyway) and, for graded methods on elastic contacts, the kink
    /// impulse correction of the crossing step ([`kink_impulse_error`]).
    /// Returns the lanes whose velocities went non-finite.
    #[inline(always)]
    fn account(&mut self, sh: &Shape, weights: &[f64], kicks: &[f64]) -> [bool; L] {
        let zero = R::zero();
        let mut event = [false; L];
        for c in 0..sh.nc {
            for l in 0..L {
                let (d0, d1) = (self.d0[c][l], self.d[c][l]);
                event[l] |= (d1 > zero) != (d0 > zero);
                self.dmax[c][l] = hi(self.dmax[c][l], d1);
            }
        }
        let lim = R::of(FINITE_LIMIT);
        let mut bad = [false; L];
        for b in 0..sh.nb {
            for l in 0..L {
                let v = self.v[b][l];
                bad[l] |= v.is_nan() || v.abs() >= lim;
            }
        }
        for l in 0..L {
            let book = &mut self.run[l];
            let h = self.step[l].to64();
            let t_start = book.t;
            book.t = if book.last {
                book.lim.max_time
            } else {
                book.t + h
            };
            book.steps += 1;
            if !event[l] {
                continue;
            }
            for c in 0..sh.nc {
                let (d0, d1) = (self.d0[c][l], self.d[c][l]);
                if sh.graded && !sh.damped && (d1 > zero) != (d0 > zero) {
                    let dj =
                        kink_impulse_error(self.kc[c][l], d0, d1, weights, kicks) * self.step[l];
                    add(
                        &mut self.v[c][l],
                        &mut self.cv[c][l],
                        -(dj * self.inv_m[c][l]),
                    );
                    add(
                        &mut self.v[c + 1][l],
                        &mut self.cv[c + 1][l],
                        dj * self.inv_m[c + 1][l],
                    );
                }
                if d1 > zero {
                    if d0 <= zero {
                        book.contacts += 1;
                        book.t_first.get_or_insert(t_start);
                    }
                } else if d0 > zero {
                    let (d0, d1) = (d0.to64(), d1.to64());
                    let tr = t_start + h * d0 / (d0 - d1);
                    book.t_release = Some(book.t_release.map_or(tr, |x: f64| x.max(tr)));
                }
            }
        }
        bad
    }

    /// The outcome of lane l's run, which ended with `end`.
    fn finish(&self, sh: &Shape, l: usize, end: End, ch: &Chain) -> Run {
        let book = &self.run[l];
        let v: Vec<f64> = (0..sh.nb).map(|b| self.v[b][l].to64()).collect();
        let overlap: Vec<f64> = (0..sh.nc).map(|c| self.d[c][l].to64()).collect();
        let x = if sh.track_x {
            ch.positions(self.x0[l].to64(), &overlap)
        } else {
            vec![f64::NAN; sh.nb]
        };
        let (mut max_ov, mut max_ratio) = (self.max_ov[l], self.max_ratio[l]);
        for c in 0..sh.nc {
            let d = self.dmax[c][l].to64();
            max_ov = max_ov.max(d);
            max_ratio = max_ratio.max(d * self.inv_r[c][l]);
        }
        let settled = matches!(end, End::Settled | End::Duration);
        let end = if settled
            && (v.iter().chain(&overlap).any(|x| !x.is_finite())
                || sh.track_x && x.iter().any(|x| !x.is_finite()))
        {
            End::NonFinite
        } else {
            end
        };
        Run {
            end,
            v,
            overlap,
            steps: book.steps,
            t: book.t,
            t_first_contact: book.t_first,
            t_last_release: book.t_release,
            max_overlap: max_ov,
            max_overlap_ratio: max_ratio,
            x,
            contacts: book.contacts,
        }
    }
}

/// Report lane l's state to the observer (a traced run has one lane).
#[inline(always)]
fn observe<R: Real, O: Observer, const L: usize>(
    sh: &Shape,
    s: &Lanes<R, L>,
    l: usize,
    ch: &Chain,
    obs: &mut O,
) {
    if O::ACTIVE {
        let d: Vec<f64> = (0..sh.nc).map(|c| s.d[c][l].to64()).collect();
        let x = ch.positions(s.x0[l].to64(), &d);
        let v: Vec<f64> = (0..sh.nb).map(|b| s.v[b][l].to64()).collect();
        obs.state(s.run[l].t, &x, &v);
    }
}

/// Run the tasks of one group (`group`: indices into `tasks`, equal keys),
/// `L` lanes at a time: a lane whose run ends takes the next task.
#[inline(always)]
fn run_lanes<R: Real, O: Observer, const TERMS: bool, const L: usize>(
    tasks: &[Task],
    group: &[usize],
    out: &mut [Option<Run>],
    obs: &mut O,
) {
    let first = &tasks[group[0]];
    let ch0 = first.chain;
    let nb = ch0.n_bodies();
    let pend = TERMS && ch0.is_pendulum();
    let sh = Shape {
        nb,
        nc: nb - 1,
        pend,
        damped: TERMS && ch0.damping_a > 0.0,
        dragged: TERMS && ch0.air_drag > 0.0,
        graded: first.plan.graded,
        quarters: first.plan.grade_quarters,
        // Body 0's displacement matters to gravity and to an observer; a free
        // line in a sweep does without (its displacements are not reported).
        track_x: pend || O::ACTIVE,
    };
    let weights = first.plan.weights;
    let kicks = kick_weights(weights);
    let kicks = &kicks[..];
    let mut s = Lanes::<R, L>::new();
    let mut queue = group.iter().copied().peekable();
    for l in 0..L {
        if let Some(i) = queue.next() {
            s.load(&sh, l, i, &tasks[i]);
            observe(&sh, &s, l, tasks[i].chain, obs);
        }
    }
    // The last runs of a group go on in narrower kernels: a long run alone
    // in wide lanes would pay for all of them.
    if L > 8 {
        drive(&mut s, &sh, weights, kicks, &mut queue, 8, tasks, out, obs);
        let mut t = s.narrow::<8>(&sh);
        drive(&mut t, &sh, weights, kicks, &mut queue, 2, tasks, out, obs);
        let mut u = t.narrow::<2>(&sh);
        drive(&mut u, &sh, weights, kicks, &mut queue, 0, tasks, out, obs);
    } else if L > 2 {
        drive(&mut s, &sh, weights, kicks, &mut queue, 2, tasks, out, obs);
        let mut u = s.narrow::<2>(&sh);
        drive(&mut u, &sh, weights, kicks, &mut queue, 0, tasks, out, obs);
    } else {
        drive(&mut s, &sh, weights, kicks, &mut queue, 0, tasks, out, obs);
    }
}

/// Step the lanes until every run is over, refilling ended lanes from
/// `queue`; return early once the queue is empty and at most `tail` lanes
/// are still running.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn drive<R: Real, O: Observer, const L: usize>(
    s: &mut Lanes<R, L>,
    sh: &Shape,
    weights: &[f64],
    kicks: &[f64],
    queue: &mut std::iter::Peekable<impl Iterator<Item = usize>>,
    tail: usize,
    tasks: &[Task],
    out: &mut [Option<Run>],
    obs: &mut O,
) {
    loop {
        if queue.peek().is_none() && s.run.iter().filter(|b| b.task.is_some()).count() <= tail {
            return;
        }
        let mut busy = false;
        for l in 0..L {
            while let Some(i) = s.run[l].task {
                let Some(end) = s.ready(sh, l, tasks[i].chain, obs) else {
                    busy = true;
                    break;
                };
                out[i] = Some(s.finish(sh, l, end, tasks[i].chain));
                s.next(sh, l, queue.next(), tasks, obs);
            }
        }
        if !busy {
            return;
        }
        s.plan_steps(sh);
        s.substeps(sh, weights, kicks);
        let bad = s.account(sh, weights, kicks);
        for l in 0..L {
            let Some(i) = s.run[l].task else { continue };
            observe(sh, s, l, tasks[i].chain, obs);
            if bad[l] {
                out[i] = Some(s.finish(sh, l, End::NonFinite, tasks[i].chain));
                s.next(sh, l, queue.next(), tasks, obs);
            }
        }
    }
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
fn kink_impulse_error<R: Real>(k: R, d0: R, d1: R, weights: &[f64], kicks: &[f64]) -> R {
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
