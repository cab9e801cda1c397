//! What a chain run measures between steps (docs/SPEC.md §9): each probe
//! bead's leading pulse (arrival, peak velocity, peak force), the walls'
//! peak force and impulse, the far end's first peak (the default end).
//!
//! Peaks and integrals are taken from the quintic Hermite polynomial of a
//! quantity, its rate and its second rate at both ends of a step (the state
//! carries them: v, a and the jerk from the contact forces' rates), so they
//! are good to O(h^6) of the step, not the nearest step's value.

use super::step::State;
use super::Consts;
use crate::engine::real::Real;

/// Coefficients c0..c5 (in θ ∈ [0, 1]) of the quintic with values f, first
/// derivatives d and second derivatives s (per unit θ) at both ends.
pub fn quintic<R: Real>(f: [R; 2], d: [R; 2], s: [R; 2]) -> [R; 6] {
    let ([f0, f1], [d0, d1], [s0, s1]) = (f, d, s);
    let c = R::of;
    [
        f0,
        d0,
        c(0.5) * s0,
        c(-10.0) * f0 - c(6.0) * d0 - c(1.5) * s0 + c(0.5) * s1 - c(4.0) * d1 + c(10.0) * f1,
        c(15.0) * f0 + c(8.0) * d0 + c(1.5) * s0 - s1 + c(7.0) * d1 - c(15.0) * f1,
        c(-6.0) * f0 - c(3.0) * d0 - c(0.5) * s0 + c(0.5) * s1 - c(3.0) * d1 + c(6.0) * f1,
    ]
}

fn poly<R: Real>(c: &[R; 6], x: R) -> R {
    c.iter().rev().fold(R::zero(), |acc, &ci| acc * x + ci)
}

fn dpoly<R: Real>(c: &[R; 6], x: R) -> R {
    (1..6)
        .rev()
        .fold(R::zero(), |acc, i| acc * x + R::of(i as f64) * c[i])
}

/// The maximum of the quintic inside [0, 1] whose derivative falls from
/// ≥ 0 at 0 to ≤ 0 at 1: (θ, value), by bisection on the derivative.
pub fn peak<R: Real>(c: &[R; 6]) -> (R, R) {
    let x = bisect(|m| dpoly(c, m) > R::zero());
    (x, poly(c, x))
}

/// The point of [0, 1] where `before` turns false, by 60 bisections (the
/// GPU kernel's `peak` takes the same ones).
fn bisect<R: Real>(before: impl Fn(R) -> bool) -> R {
    let (mut a, mut b) = (R::zero(), R::one());
    let half = R::of(0.5);
    for _ in 0..60 {
        let m = half * (a + b);
        if before(m) {
            a = m;
        } else {
            b = m;
        }
    }
    half * (a + b)
}

/// ∫₀¹ of the quintic (exact).
pub fn integral<R: Real>(f: [R; 2], d: [R; 2], s: [R; 2]) -> R {
    R::of(0.5) * (f[0] + f[1]) + R::of(0.1) * (d[0] - d[1]) + (s[0] + s[1]) / R::of(120.0)
}

/// x_{j−1} − x_j for a per-bead rate x (v or a) across contact j: the rate
/// of δ_j; the walls do not move.
fn across<R: Real>(x: &[R], j: usize) -> R {
    let l = if j == 0 { R::zero() } else { x[j - 1] };
    let r = x.get(j).copied().unwrap_or(R::zero());
    l - r
}

/// δ̇ of contact j, v_{j−1} − v_j: the right wall stands still, the left
/// one moves at the piston's speed.
fn closing<R: Real>(c: &Consts<R>, st: &State<R>, j: usize) -> R {
    if j == 0 && c.piston != R::zero() {
        c.piston - st.v[0]
    } else {
        across(&st.v, j)
    }
}

/// The force of contact j's dashpot (N; on bead a, pushing it back: +):
/// γ·δ̇ while closed, never pulling harder than the spring pushes (the
/// step's [`super::step`] `dashpot`); 0 when open or undamped.
fn dashpot_force<R: Real>(c: &Consts<R>, st: &State<R>, j: usize) -> R {
    let d = c.d0[j] + st.p[j];
    let spring = super::hertz(c.k[j], d);
    match &c.damp {
        // Closed as the step's dashpot sees it: its spring pushes.
        Some(dp) if spring > R::zero() => {
            let r1 = closing(c, st, j);
            let f = match hunt_crossley_chi(dp, st, j) {
                Some(chi) if chi < R::zero() => dp.gamma * r1 + spring * dp.hc,
                Some(chi) => dp.gamma * r1 + spring * (chi * r1).min(dp.hc),
                None => dp.gamma * r1,
            };
            f.max(R::zero() - spring)
        }
        _ => R::zero(),
    }
}

/// A Hunt–Crossley contact's χ (s/m; `None` without them): a over its
/// closing speed so far, a over the floor before its first step's end
/// closed, negative while it rises. Its force is k·δ^{3/2}·min(a, χ·δ̇)
/// (the step's `hunt_crossley`): a·k·δ^{3/2} while its closing speed
/// rises.
fn hunt_crossley_chi<R: Real>(d: &super::DampConsts<R>, st: &State<R>, j: usize) -> Option<R> {
    match st.chi.get(j) {
        Some(&chi) if d.hc != R::zero() => Some(d.chi_of(chi)),
        _ => None,
    }
}

/// Bead i's acceleration (m/s²): the elastic forces' (`st.a`, what the
/// step kicks with), plus on a damped chain its dashpots' and the air
/// drag's, so that the observers' interpolants see the motion's own rates.
pub fn acceleration<R: Real>(c: &Consts<R>, st: &State<R>, i: usize) -> R {
    acceleration_in(c, st, i, &mut Dashpots::new())
}

/// [`acceleration`], the dashpots' forces taken from `m`.
fn acceleration_in<R: Real>(c: &Consts<R>, st: &State<R>, i: usize, m: &mut Dashpots<R>) -> R {
    match &c.damp {
        None => st.a[i],
        Some(d) => {
            let g = m.force(c, st, i) - m.force(c, st, i + 1);
            st.a[i] + g * c.inv_mass[i] - d.drag * st.v[i]
        }
    }
}

/// The dashpots' forces (`dashpot_force`) an observation has computed:
/// the rates of a probe on a damped chain read its few contacts' forces
/// many times (each bead's acceleration, across contacts, in the jerk), a
/// square root each. A force is a function of the state alone, so reading
/// it here gives the same bits as computing it again.
pub struct Dashpots<R> {
    at: [usize; DASHPOTS_KEPT],
    force: [R; DASHPOTS_KEPT],
    len: usize,
}

/// How many forces [`Dashpots`] keeps (an observation of two probes, both
/// walls and the far end reads 12); later ones are computed each time.
const DASHPOTS_KEPT: usize = 16;

impl<R: Real> Dashpots<R> {
    pub fn new() -> Self {
        Dashpots {
            at: [0; DASHPOTS_KEPT],
            force: [R::zero(); DASHPOTS_KEPT],
            len: 0,
        }
    }

    /// Contact j's dashpot force, computed at its first reading.
    fn force(&mut self, c: &Consts<R>, st: &State<R>, j: usize) -> R {
        if let Some(k) = self.at[..self.len].iter().position(|&a| a == j) {
            return self.force[k];
        }
        let f = dashpot_force(c, st, j);
        if self.len < DASHPOTS_KEPT {
            (self.at[self.len], self.force[self.len]) = (j, f);
            self.len += 1;
        }
        f
    }
}

impl<R: Real> Default for Dashpots<R> {
    fn default() -> Self {
        Self::new()
    }
}

/// [`acceleration`] across contact j: the rate of δ̇_j.
fn across_acceleration<R: Real>(c: &Consts<R>, st: &State<R>, j: usize, m: &mut Dashpots<R>) -> R {
    if c.damp.is_none() {
        return across(&st.a, j);
    }
    let l = if j == 0 {
        R::zero()
    } else {
        acceleration_in(c, st, j - 1, m)
    };
    let r = if j < st.v.len() {
        acceleration_in(c, st, j, m)
    } else {
        R::zero()
    };
    l - r
}

/// The rate of bead i's acceleration from its damping (m/s³): its
/// dashpots' γ·δ̈ and the air drag's −c·a (0 undamped).
fn damping_jerk<R: Real>(c: &Consts<R>, st: &State<R>, i: usize, m: &mut Dashpots<R>) -> R {
    let Some(d) = &c.damp else {
        return R::zero();
    };
    let mut rate = |j: usize| {
        let dl = c.d0[j] + st.p[j];
        let spring = super::hertz(c.k[j], dl);
        if spring <= R::zero() {
            return R::zero();
        }
        let r1 = closing(c, st, j);
        let spring_rate = R::of(1.5) * c.k[j] * dl.sqrt() * r1;
        let chi = hunt_crossley_chi(d, st, j);
        // Rising: the Hunt–Crossley part is a·k·δ^{3/2}.
        let rising = chi.is_some_and(|chi| chi < R::zero() || chi * r1 >= d.hc);
        let g = match chi {
            Some(chi) if !rising => d.gamma + chi * spring,
            _ => d.gamma,
        };
        let f = if rising {
            g * r1 + d.hc * spring
        } else {
            g * r1
        };
        if f < R::zero() - spring {
            // Slack: the dashpot's force is −k·δ^{3/2}, its rate −1.5·k·√δ·δ̇.
            R::zero() - spring_rate
        } else if rising {
            // γ·δ̈ + a·(1.5·k·√δ·δ̇).
            g * across_acceleration(c, st, j, m) + d.hc * spring_rate
        } else {
            // (γ + χ·k·δ^{3/2})·δ̈ + χ·(1.5·k·√δ·δ̇)·δ̇.
            let extra = chi.map_or(R::zero(), |chi| chi * spring_rate * r1);
            g * across_acceleration(c, st, j, m) + extra
        }
    };
    let (l, r) = (rate(i), rate(i + 1));
    (l - r) * c.inv_mass[i] - d.drag * acceleration_in(c, st, i, m)
}

/// Force of contact j and its first two rates: (F, dF/dt, d²F/dt²).
/// d²F/dt² has a 1/√δ term: near an opening contact it is left out
/// (the polynomial then is cubic in effect; the force there is small).
pub fn force_rates<R: Real>(
    c: &Consts<R>,
    st: &State<R>,
    j: usize,
    m: &mut Dashpots<R>,
) -> (R, R, R) {
    let d = c.d0[j] + st.p[j];
    let zero = R::zero();
    if d <= zero || c.k[j] == zero {
        return (zero, zero, zero);
    }
    let k = c.k[j];
    let sq = d.sqrt();
    let (r1, r2) = (closing(c, st, j), across_acceleration(c, st, j, m));
    let (c15, c075) = (R::of(1.5), R::of(0.75));
    (
        k * d * sq,
        c15 * k * sq * r1,
        c075 * k * r1 * r1 / sq + c15 * k * sq * r2,
    )
}

/// Velocity, acceleration and jerk of bead i.
pub fn bead_rates<R: Real>(
    c: &Consts<R>,
    st: &State<R>,
    i: usize,
    t: R,
    m: &mut Dashpots<R>,
) -> (R, R, R) {
    let (fl, fr) = (force_rates(c, st, i, m), force_rates(c, st, i + 1, m));
    bead_rates_with(c, st, i, t, (fl.1, fr.1), m)
}

/// [`bead_rates`] from the rates of bead i's contact forces, left and right
/// (N/s), when the caller has them.
pub fn bead_rates_with<R: Real>(
    c: &Consts<R>,
    st: &State<R>,
    i: usize,
    t: R,
    (left, right): (R, R),
    m: &mut Dashpots<R>,
) -> (R, R, R) {
    let mut jerk = (left - right) * c.inv_mass[i];
    if let Some(p) = c.pulse.as_ref().filter(|p| p.bead == i && t < p.duration) {
        let w = p.omega;
        jerk = jerk + p.force * w * super::step::push_cos(p, t) * p.inv_mass;
    }
    if c.damp.is_some() {
        jerk = jerk + damping_jerk(c, st, i, m);
    }
    (st.v[i], acceleration_in(c, st, i, m), jerk)
}

/// How many record peaks [`FirstPeak::see_leading`] keeps.
pub const LEADING_RECORDS: usize = 4;
/// The leading pulse's peak is the first local maximum at least this
/// fraction of the largest ([`FirstPeak::see_leading`]): a quarter keeps a
/// dispersive wave's first lobe (its front, which travels at the sound
/// speed; the lobes behind it lag) where it is a real part of the pulse,
/// and drops a precursor's wiggle.
pub const LEADING_FRACTION: f64 = 0.25;

/// Peaks of a quantity above a floor, watched step by step.
/// [`FirstPeak::see`] takes the first local maximum above the floor (the
/// far end's peak, which ends a run by default); [`FirstPeak::see_leading`]
/// finds the **leading pulse's peak** (a probe's arrival): the first local
/// maximum at least [`LEADING_FRACTION`] of the largest one seen over the
/// run, so that neither a precursor's wiggle ahead of the pulse nor the
/// floor's value decides it.
#[derive(Clone, Debug)]
pub struct FirstPeak<R = f64> {
    last: Option<(R, [R; 3])>,
    /// (time, value) of [`FirstPeak::see`]'s peak, once found.
    pub found: Option<(R, R)>,
    /// [`FirstPeak::see_leading`]'s record peaks (each higher than every
    /// local maximum before it), oldest first, those below
    /// [`LEADING_FRACTION`] of the highest dropped: the first is the
    /// leading pulse's peak so far.
    records: [(R, R); LEADING_RECORDS],
    count: usize,
}

impl<R: Real> Default for FirstPeak<R> {
    fn default() -> Self {
        FirstPeak {
            last: None,
            found: None,
            records: [(R::zero(), R::zero()); LEADING_RECORDS],
            count: 0,
        }
    }
}

impl<R: Real> FirstPeak<R> {
    /// A local maximum inside the step from the last look to `t` (q: value,
    /// rate, second rate): (time, value).
    fn local_max(&self, t: R, q: [R; 3]) -> Option<(R, R)> {
        let (t0, q0) = self.last?;
        (q0[1] > R::zero() && q[1] <= R::zero()).then(|| {
            let h = t - t0;
            let c = quintic(
                [q0[0], q[0]],
                [q0[1] * h, q[1] * h],
                [q0[2] * h * h, q[2] * h * h],
            );
            let (x, v) = peak(&c);
            (t0 + x * h, v)
        })
    }

    /// Watch the quantity with rates `q` = (value, rate, second rate) at
    /// `t`: the first local maximum above `floor` is the peak.
    pub fn see(&mut self, t: R, q: [R; 3], floor: R) {
        if self.found.is_some() {
            return;
        }
        if let Some((tp, v)) = self.local_max(t, q).filter(|&(_, v)| v > floor) {
            self.found = Some((tp, v));
        }
        self.last = Some((t, q));
    }

    /// Watch as [`FirstPeak::see`] for the leading pulse's peak: a local
    /// maximum above `floor` and above every earlier one is a record; the
    /// records below [`LEADING_FRACTION`] of it are dropped (no later
    /// maximum can make them the first at that fraction of the largest).
    /// With [`LEADING_RECORDS`] kept, a new record beyond them replaces the
    /// newest (the peak then found can be a later one than the first at
    /// the fraction, never one below it). Whether this look took a new
    /// record (the largest maximum so far).
    pub fn see_leading(&mut self, t: R, q: [R; 3], floor: R) -> bool {
        let mut taken = false;
        if let Some((tp, v)) = self.local_max(t, q) {
            let top = match self.count {
                0 => floor,
                k => self.records[k - 1].1,
            };
            if v > top {
                let bar = R::of(LEADING_FRACTION) * v;
                let drop = (0..self.count)
                    .find(|&i| self.records[i].1 >= bar)
                    .unwrap_or(self.count);
                self.records.copy_within(drop..self.count, 0);
                self.count -= drop;
                if self.count == LEADING_RECORDS {
                    self.count -= 1;
                }
                self.records[self.count] = (tp, v);
                self.count += 1;
                taken = true;
            }
        }
        self.last = Some((t, q));
        taken
    }

    /// [`FirstPeak::see_leading`]'s peak: (time, value) in f64.
    pub fn leading64(&self) -> Option<(f64, f64)> {
        (self.count > 0).then(|| (self.records[0].0.to64(), self.records[0].1.to64()))
    }
}

/// Reals of a packed [`FirstPeak`] ([`FirstPeak::pack`]).
pub const FIRST_PEAK_REALS: usize = 9 + 2 * LEADING_RECORDS;
/// Reals of a packed [`WallWatch`] ([`WallWatch::pack`]).
pub const WALL_WATCH_REALS: usize = 7;

/// `last` as (has, t, q0, q1, q2).
fn pack_last<R: Real>(last: &Option<(R, [R; 3])>) -> [R; 5] {
    match last {
        Some((t, q)) => [R::one(), *t, q[0], q[1], q[2]],
        None => [R::zero(); 5],
    }
}

fn unpack_last<R: Real>(r: &[R]) -> Option<(R, [R; 3])> {
    (r[0] != R::zero()).then_some((r[1], [r[2], r[3], r[4]]))
}

impl<R: Real> FirstPeak<R> {
    /// As reals for the GPU twin: has_last, last t and q, found, its t and
    /// value, the records' count, each record's t and value.
    pub fn pack(&self) -> [R; FIRST_PEAK_REALS] {
        let l = pack_last(&self.last);
        let zero = R::zero();
        let (f, ft, fv) = match self.found {
            Some((t, v)) => (R::one(), t, v),
            None => (zero, zero, zero),
        };
        let mut r = [zero; FIRST_PEAK_REALS];
        r[..9].copy_from_slice(&[
            l[0],
            l[1],
            l[2],
            l[3],
            l[4],
            f,
            ft,
            fv,
            R::of(self.count as f64),
        ]);
        for (k, &(t, v)) in self.records.iter().enumerate() {
            r[9 + 2 * k] = t;
            r[10 + 2 * k] = v;
        }
        r
    }

    pub fn unpack(r: &[R]) -> FirstPeak<R> {
        let mut records = [(R::zero(), R::zero()); LEADING_RECORDS];
        for (k, rec) in records.iter_mut().enumerate() {
            *rec = (r[9 + 2 * k], r[10 + 2 * k]);
        }
        FirstPeak {
            last: unpack_last(r),
            found: (r[5] != R::zero()).then_some((r[6], r[7])),
            records,
            count: r[8].to64() as usize,
        }
    }
}

impl<R: Real> WallWatch<R> {
    /// As reals for the GPU twin: has_last, last t and q, peak, impulse.
    pub fn pack(&self) -> [R; WALL_WATCH_REALS] {
        let l = pack_last(&self.last);
        [l[0], l[1], l[2], l[3], l[4], self.peak, self.impulse]
    }

    pub fn unpack(r: &[R]) -> WallWatch<R> {
        WallWatch {
            last: unpack_last(r),
            peak: r[5],
            impulse: r[6],
        }
    }
}

/// The first time a quantity reaches a level (a piston's shock front at a
/// probe: its velocity reaching half the piston's speed), located on the
/// quintic Hermite interpolant of the step in which it does (60
/// bisections; O(h^6), as the peaks).
#[derive(Clone, Debug)]
pub struct Rise<R = f64> {
    last: Option<(R, [R; 3])>,
    /// When it reached the level, once it has.
    pub at: Option<R>,
}

impl<R: Real> Default for Rise<R> {
    fn default() -> Self {
        Rise {
            last: None,
            at: None,
        }
    }
}

impl<R: Real> Rise<R> {
    pub fn see(&mut self, t: R, q: [R; 3], level: R) {
        if self.at.is_some() {
            return;
        }
        match self.last {
            None if q[0] >= level => self.at = Some(t),
            Some((t0, q0)) if q0[0] < level && q[0] >= level => {
                let h = t - t0;
                let c = quintic(
                    [q0[0] - level, q[0] - level],
                    [q0[1] * h, q[1] * h],
                    [q0[2] * h * h, q[2] * h * h],
                );
                self.at = Some(t0 + h * bisect(|m| poly(&c, m) < R::zero()));
            }
            _ => {}
        }
        self.last = Some((t, q));
    }
}

/// Reals of a packed [`Rise`] ([`Rise::pack`]).
pub const RISE_REALS: usize = 7;

impl<R: Real> Rise<R> {
    /// As reals for the GPU twin: has_last, last t and q, reached, when.
    pub fn pack(&self) -> [R; RISE_REALS] {
        let l = pack_last(&self.last);
        let (a, at) = match self.at {
            Some(t) => (R::one(), t),
            None => (R::zero(), R::zero()),
        };
        [l[0], l[1], l[2], l[3], l[4], a, at]
    }

    pub fn unpack(r: &[R]) -> Rise<R> {
        Rise {
            last: unpack_last(r),
            at: (r[5] != R::zero()).then_some(r[6]),
        }
    }
}

/// A drive's steady response at a bead: the amplitude of the bead's
/// velocity at the drive's frequency f over the window [from, end] (the
/// run's second half), by a lock-in with a Hann window w:
/// A = 2·|∫ v·w·e^{−iωt} dt| / ∫ w dt (trapezoids on the steps; the window
/// keeps the transient's other frequencies — a drive switched on at t = 0
/// rings the whole band — out to ~1e-4 of their size, where a largest |v|
/// would take them in).
#[derive(Clone, Debug)]
pub struct Amplitude<R = f64> {
    /// The last step's t and v·w·(cos, sin), and w.
    last: Option<(R, [R; 3])>,
    /// ∫ v·w·cos ωt, ∫ v·w·sin ωt, ∫ w.
    sums: [R; 3],
    pub from: R,
    pub end: R,
    pub frequency: R,
}

impl<R: Real> Amplitude<R> {
    pub fn new(from: f64, end: f64, frequency: f64) -> Amplitude<R> {
        Amplitude {
            last: None,
            sums: [R::zero(); 3],
            from: R::of(from),
            end: R::of(end),
            frequency: R::of(frequency),
        }
    }

    /// The bead's velocity `v` at `t` (steps at or after `from` count).
    pub fn see(&mut self, t: R, v: R) {
        use super::step::cycle_sin;
        if t < self.from {
            return;
        }
        let x = (t - self.from) / (self.end - self.from);
        let hann = cycle_sin(R::of(0.5) * x);
        let w = hann * hann;
        let phase = self.frequency * t;
        let now = [
            v * w * cycle_sin(phase + R::of(0.25)),
            v * w * cycle_sin(phase),
            w,
        ];
        if let Some((t0, q0)) = self.last {
            let h = R::of(0.5) * (t - t0);
            for k in 0..3 {
                self.sums[k] = self.sums[k] + h * (q0[k] + now[k]);
            }
        }
        self.last = Some((t, now));
    }

    /// The amplitude (m/s; 0 before the window has two steps).
    pub fn value(&self) -> f64 {
        let [c, s, w] = self.sums.map(|x| x.to64());
        if w > 0.0 {
            2.0 * (c * c + s * s).sqrt() / w
        } else {
            0.0
        }
    }
}

/// Reals of a packed [`Amplitude`]'s running state ([`Amplitude::pack`]).
pub const AMP_REALS: usize = 8;

impl<R: Real> Amplitude<R> {
    /// Its running state as reals for the GPU twin: has_last, last t and
    /// v·w·(cos, sin), w, then the three sums (`from`, `end` and
    /// `frequency` are the chain's scalars).
    pub fn pack(&self) -> [R; AMP_REALS] {
        let l = pack_last(&self.last);
        let s = self.sums;
        [l[0], l[1], l[2], l[3], l[4], s[0], s[1], s[2]]
    }

    /// `self` with the running state `r` ([`Amplitude::pack`]'s).
    pub fn unpacked(&self, r: &[R]) -> Amplitude<R> {
        Amplitude {
            last: unpack_last(r),
            sums: [r[5], r[6], r[7]],
            ..self.clone()
        }
    }
}

/// A wall's largest force and its impulse (of the force above the static one).
#[derive(Clone, Debug)]
pub struct WallWatch<R = f64> {
    last: Option<(R, [R; 3])>,
    pub peak: R,
    pub impulse: R,
}

impl<R: Real> Default for WallWatch<R> {
    fn default() -> Self {
        WallWatch {
            last: None,
            peak: R::zero(),
            impulse: R::zero(),
        }
    }
}

impl<R: Real> WallWatch<R> {
    pub fn see(&mut self, t: R, q: [R; 3], f0: R) {
        let zero = R::zero();
        self.peak = self.peak.max(q[0]);
        if let Some((t0, q0)) = self.last {
            let h = t - t0;
            let smooth = q0[0] > zero && q[0] > zero;
            let (s0, s1) = if smooth {
                (q0[2] * h * h, q[2] * h * h)
            } else {
                (zero, zero)
            };
            let (f, d, s) = ([q0[0], q[0]], [q0[1] * h, q[1] * h], [s0, s1]);
            self.impulse = self.impulse + h * (integral(f, d, s) - f0);
            if smooth && q0[1] > zero && q[1] <= zero {
                self.peak = self.peak.max(peak(&quintic(f, d, s)).1);
            }
        }
        self.last = Some((t, q));
    }
}

/// One probe bead's leading pulse.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeOutcome {
    pub bead: usize,
    /// Time of the leading pulse's velocity peak (s); NaN if none arrived.
    pub arrival: f64,
    /// Its peak velocity (m/s).
    pub peak_velocity: f64,
    /// Peak of the bead's mean contact force (F_left + F_right)/2 (N), what
    /// a sensor inside the bead reads, in the leading pulse.
    pub peak_force: f64,
    /// Final velocity (m/s).
    pub v_final: f64,
}

/// A wall's outcome.
#[derive(Clone, Debug, PartialEq)]
pub struct WallOutcome {
    /// Largest force on the wall (N), the static force included.
    pub peak_force: f64,
    /// ∫(F − F0) dt (N·s).
    pub impulse: f64,
    /// Without precompression: whether its bead still touches it at the
    /// end (the impulse is then partial: the rebound was not over).
    pub in_contact: bool,
}

/// The outcome of one chain run.
#[derive(Clone, Debug, PartialEq)]
pub struct ChainOutcome {
    pub status: crate::engine::Status,
    pub probes: Vec<ProbeOutcome>,
    /// Distance between the first and last probe over the difference of
    /// their arrival times (m/s); NaN with fewer than two arrivals.
    pub pulse_speed: f64,
    /// Full width at half maximum of the bead-velocity profile (beads) at
    /// the step nearest the last probe's arrival; NaN without an arrival.
    pub pulse_width: f64,
    pub left_wall: Option<WallOutcome>,
    pub right_wall: Option<WallOutcome>,
    /// Energy at the end (relative to rest) in beads before the first
    /// probe, after the last probe, and from the first to the last, over
    /// the energy put in; a contact across a boundary counts half to each
    /// side. NaN without probes.
    pub energy_reflected: f64,
    pub energy_transmitted: f64,
    pub energy_left: f64,
    /// Groups of beads separated by opened gaps at the end (1: one piece).
    pub fragments: usize,
    /// Relative energy error (to the energy after the pulse, if any): of
    /// the energy plus what the damping took, so an error of the
    /// integration, not of the model.
    pub energy_error: f64,
    /// Energy the dashpots and the air drag took over the run (J; 0
    /// without `[damping]`).
    pub energy_dissipated: f64,
    /// A piston's shock front speed (m/s): the distance at rest between
    /// the first and last probe over the difference of the times their
    /// velocity reached half the piston's speed (NaN without a piston).
    pub shock_speed: f64,
    /// The work the piston did on the chain (J; its speed times the
    /// impulse it gave bead 0; 0 without one).
    pub piston_work: f64,
    /// Under a drive, each probe's velocity amplitude at the drive's
    /// frequency over the run's second half (m/s; [`Amplitude`]); empty
    /// without one.
    pub amplitudes: Vec<f64>,
    /// Relative momentum error without walls (NaN with a wall).
    pub momentum_error: f64,
    /// Largest overlap / smaller radius seen.
    pub max_overlap_ratio: f64,
    /// Final velocity of every bead (m/s): rows show the probes' only.
    pub v: Vec<f64>,
    pub t_end: f64,
    pub steps: u64,
    /// Regions the local refinement redid, and their beads in all
    /// ([`super::step::Refine`]).
    pub regions: u64,
    pub region_beads: u64,
    /// The step (s).
    pub dt: f64,
    /// The error estimate (relative to the velocity scale, in the metric of
    /// [`super::control::difference`]) from the error control's twin run;
    /// NaN where none was run.
    pub error_estimate: f64,
    /// The velocity scale errors are relative to (m/s; [`super::Beads::v_scale`]).
    pub v_scale: f64,
    /// The tolerance the run was planned for (`None`: a given step).
    pub tolerance: Option<f64>,
    /// Whether the run had the local refinement on ([`super::Plan::refine`]).
    pub refined: bool,
    /// Whether the chain has dashpots (`[damping] viscosity`): the error
    /// control then always takes a rerun ([`crate::backend::run_chains_controlled`]).
    pub dashpots: bool,
}

impl ChainOutcome {
    /// The outcome of a combination of sweep values that made no valid
    /// chain: status `invalid`, nothing measured.
    pub fn invalid() -> ChainOutcome {
        ChainOutcome {
            status: crate::engine::Status::Invalid,
            probes: vec![],
            pulse_speed: f64::NAN,
            pulse_width: f64::NAN,
            left_wall: None,
            right_wall: None,
            energy_reflected: f64::NAN,
            energy_transmitted: f64::NAN,
            energy_left: f64::NAN,
            fragments: 0,
            energy_error: f64::NAN,
            energy_dissipated: f64::NAN,
            shock_speed: f64::NAN,
            piston_work: f64::NAN,
            amplitudes: vec![],
            momentum_error: f64::NAN,
            max_overlap_ratio: f64::NAN,
            v: vec![],
            t_end: f64::NAN,
            steps: 0,
            regions: 0,
            region_beads: 0,
            dt: f64::NAN,
            error_estimate: f64::NAN,
            v_scale: f64::NAN,
            tolerance: None,
            refined: false,
            dashpots: false,
        }
    }
}
