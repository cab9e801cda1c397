//! What a chain run measures between steps (docs/SPEC.md §9): each probe
//! bead's leading pulse (arrival, peak velocity, peak force), the walls'
//! peak force and impulse, the far end's first peak (the default end).
//!
//! Peaks and integrals are taken from the quintic Hermite polynomial of a
//! quantity, its rate and its second rate at both ends of a step (the state
//! carries them: v, a and the jerk from the contact forces' rates), so they
//! are good to O(h^6) of the step, not the nearest step's value.

use super::step::State;
use super::Beads;

/// Coefficients c0..c5 (in θ ∈ [0, 1]) of the quintic with values f, first
/// derivatives d and second derivatives s (per unit θ) at both ends.
pub fn quintic(f: [f64; 2], d: [f64; 2], s: [f64; 2]) -> [f64; 6] {
    let ([f0, f1], [d0, d1], [s0, s1]) = (f, d, s);
    [
        f0,
        d0,
        0.5 * s0,
        -10.0 * f0 - 6.0 * d0 - 1.5 * s0 + 0.5 * s1 - 4.0 * d1 + 10.0 * f1,
        15.0 * f0 + 8.0 * d0 + 1.5 * s0 - s1 + 7.0 * d1 - 15.0 * f1,
        -6.0 * f0 - 3.0 * d0 - 0.5 * s0 + 0.5 * s1 - 3.0 * d1 + 6.0 * f1,
    ]
}

fn poly(c: &[f64; 6], x: f64) -> f64 {
    c.iter().rev().fold(0.0, |acc, &ci| acc * x + ci)
}

fn dpoly(c: &[f64; 6], x: f64) -> f64 {
    (1..6).rev().fold(0.0, |acc, i| acc * x + i as f64 * c[i])
}

/// The maximum of the quintic inside [0, 1] whose derivative falls from
/// ≥ 0 at 0 to ≤ 0 at 1: (θ, value), by bisection on the derivative.
pub fn peak(c: &[f64; 6]) -> (f64, f64) {
    let (mut a, mut b) = (0.0f64, 1.0f64);
    for _ in 0..60 {
        let m = 0.5 * (a + b);
        if dpoly(c, m) > 0.0 {
            a = m;
        } else {
            b = m;
        }
    }
    let x = 0.5 * (a + b);
    (x, poly(c, x))
}

/// ∫₀¹ of the quintic (exact).
pub fn integral(f: [f64; 2], d: [f64; 2], s: [f64; 2]) -> f64 {
    0.5 * (f[0] + f[1]) + 0.1 * (d[0] - d[1]) + (s[0] + s[1]) / 120.0
}

/// x_{j−1} − x_j for a per-bead rate x (v or a) across contact j: the rate
/// of δ_j; the walls do not move.
fn across(x: &[f64], j: usize) -> f64 {
    let l = if j == 0 { 0.0 } else { x[j - 1] };
    let r = x.get(j).copied().unwrap_or(0.0);
    l - r
}

/// Force of contact j and its first two rates: (F, dF/dt, d²F/dt²).
/// d²F/dt² has a 1/√δ term: near an opening contact it is left out
/// (the polynomial then is cubic in effect; the force there is small).
pub fn force_rates(b: &Beads, st: &State, j: usize) -> (f64, f64, f64) {
    let d = b.d0[j] + st.p[j];
    if d <= 0.0 || b.k[j] == 0.0 {
        return (0.0, 0.0, 0.0);
    }
    let k = b.k[j];
    let sq = d.sqrt();
    let (r1, r2) = (across(&st.v, j), across(&st.a, j));
    (
        k * d * sq,
        1.5 * k * sq * r1,
        0.75 * k * r1 * r1 / sq + 1.5 * k * sq * r2,
    )
}

/// Velocity, acceleration and jerk of bead i.
pub fn bead_rates(b: &Beads, st: &State, i: usize, t: f64) -> (f64, f64, f64) {
    let (fl, fr) = (force_rates(b, st, i), force_rates(b, st, i + 1));
    bead_rates_with(b, st, i, t, fl.1, fr.1)
}

/// [`bead_rates`] from the rates of bead i's contact forces, left and right
/// (N/s), when the caller has them.
pub fn bead_rates_with(
    b: &Beads,
    st: &State,
    i: usize,
    t: f64,
    left: f64,
    right: f64,
) -> (f64, f64, f64) {
    let mut jerk = (left - right) * b.inv_mass[i];
    if let Some(p) = b.pulse.as_ref().filter(|p| p.bead == i && t < p.duration) {
        let w = p.omega();
        jerk += p.force * w * super::step::pulse_cos(t, w) * b.inv_mass[i];
    }
    (st.v[i], st.a[i], jerk)
}

/// The first peak of a quantity above a floor: watched step by step.
#[derive(Clone, Debug, Default)]
pub struct FirstPeak {
    last: Option<(f64, [f64; 3])>,
    /// (time, value) of the first local maximum above the floor.
    pub found: Option<(f64, f64)>,
}

impl FirstPeak {
    /// Watch the quantity with rates `q` = (value, rate, second rate) at `t`.
    pub fn see(&mut self, t: f64, q: [f64; 3], floor: f64) {
        if self.found.is_some() {
            return;
        }
        if let Some((t0, q0)) = self.last {
            if q0[1] > 0.0 && q[1] <= 0.0 {
                let h = t - t0;
                let c = quintic(
                    [q0[0], q[0]],
                    [q0[1] * h, q[1] * h],
                    [q0[2] * h * h, q[2] * h * h],
                );
                let (x, v) = peak(&c);
                if v > floor {
                    self.found = Some((t0 + x * h, v));
                }
            }
        }
        self.last = Some((t, q));
    }
}

/// Reals of a packed [`FirstPeak`] ([`FirstPeak::pack`]).
pub const FIRST_PEAK_REALS: usize = 8;
/// Reals of a packed [`WallWatch`] ([`WallWatch::pack`]).
pub const WALL_WATCH_REALS: usize = 7;

/// `last` as (has, t, q0, q1, q2).
fn pack_last(last: &Option<(f64, [f64; 3])>) -> [f64; 5] {
    match last {
        Some((t, q)) => [1.0, *t, q[0], q[1], q[2]],
        None => [0.0; 5],
    }
}

fn unpack_last(r: &[f64]) -> Option<(f64, [f64; 3])> {
    (r[0] != 0.0).then_some((r[1], [r[2], r[3], r[4]]))
}

impl FirstPeak {
    /// As reals for the GPU twin: has_last, last t and q, found, its t and value.
    pub fn pack(&self) -> [f64; FIRST_PEAK_REALS] {
        let l = pack_last(&self.last);
        let (f, ft, fv) = match self.found {
            Some((t, v)) => (1.0, t, v),
            None => (0.0, 0.0, 0.0),
        };
        [l[0], l[1], l[2], l[3], l[4], f, ft, fv]
    }

    pub fn unpack(r: &[f64]) -> FirstPeak {
        FirstPeak {
            last: unpack_last(r),
            found: (r[5] != 0.0).then_some((r[6], r[7])),
        }
    }
}

impl WallWatch {
    /// As reals for the GPU twin: has_last, last t and q, peak, impulse.
    pub fn pack(&self) -> [f64; WALL_WATCH_REALS] {
        let l = pack_last(&self.last);
        [l[0], l[1], l[2], l[3], l[4], self.peak, self.impulse]
    }

    pub fn unpack(r: &[f64]) -> WallWatch {
        WallWatch {
            last: unpack_last(r),
            peak: r[5],
            impulse: r[6],
        }
    }
}

/// A wall's largest force and its impulse (of the force above the static one).
#[derive(Clone, Debug, Default)]
pub struct WallWatch {
    last: Option<(f64, [f64; 3])>,
    pub peak: f64,
    pub impulse: f64,
}

impl WallWatch {
    pub fn see(&mut self, t: f64, q: [f64; 3], f0: f64) {
        self.peak = self.peak.max(q[0]);
        if let Some((t0, q0)) = self.last {
            let h = t - t0;
            let smooth = q0[0] > 0.0 && q[0] > 0.0;
            let (s0, s1) = if smooth {
                (q0[2] * h * h, q[2] * h * h)
            } else {
                (0.0, 0.0)
            };
            let (f, d, s) = ([q0[0], q[0]], [q0[1] * h, q[1] * h], [s0, s1]);
            self.impulse += h * (integral(f, d, s) - f0);
            if smooth && q0[1] > 0.0 && q[1] <= 0.0 {
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
    /// Relative energy error (to the energy after the pulse, if any).
    pub energy_error: f64,
    /// Relative momentum error without walls (NaN with a wall).
    pub momentum_error: f64,
    /// Largest overlap / smaller radius seen.
    pub max_overlap_ratio: f64,
    /// Final velocity of every bead (m/s): rows show the probes' only.
    pub v: Vec<f64>,
    pub t_end: f64,
    pub steps: u64,
    /// The step (s).
    pub dt: f64,
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
            momentum_error: f64::NAN,
            max_overlap_ratio: f64::NAN,
            v: vec![],
            t_end: f64::NAN,
            steps: 0,
            dt: f64::NAN,
        }
    }
}
