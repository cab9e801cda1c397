//! A chain run: fixed steps ([`super::step`]) from rest to the end
//! (docs/SPEC.md §9), the observers of [`super::observe`] between steps,
//! and the outcome.

use super::observe::*;
use super::step::{step, State};
use super::{Beads, Consts, Plan, END_MARGIN, PEAK_FLOOR};
use crate::engine::outcome::MAX_OVERLAP_RATIO;
use crate::engine::real::{Df64, Real};
use crate::engine::Status;
use crate::scene::Precision;

/// Receives the state at every trace row (t = 0, every, 2·every, …, and
/// the end).
pub trait Rows {
    fn row(&mut self, t: f64, beads: &Beads, state: &State);
}

/// No trace.
pub struct NoRows;

impl Rows for NoRows {
    fn row(&mut self, _: f64, _: &Beads, _: &State) {}
}

/// A gap between beads counts towards `fragments` when wider than this
/// fraction of the smaller radius (5 pm for 5 mm beads).
pub const FRAGMENT_GAP: f64 = 1e-9;

/// Check overlaps and finiteness every this many steps (over the window).
pub const CHECK_EVERY: u64 = 16;

/// A run tells its plan's tally its bead-steps in chunks of at least this
/// many (one shared atomic add per ~10^5 bead-steps: no contention).
const TALLY_CHUNK: u64 = 1 << 16;

/// Run `beads` as planned (in the plan's precision), rows to `rows`.
pub fn run(beads: &Beads, plan: &Plan, rows: &mut dyn Rows) -> ChainOutcome {
    run_with(beads, plan, rows, false)
}

/// [`run`], the window the whole chain when `whole` (for tests).
pub fn run_with(b: &Beads, plan: &Plan, rows: &mut dyn Rows, whole: bool) -> ChainOutcome {
    // The front ends refuse f32 (`check_solver`); a plan that asks for it
    // anyway gets it, never another precision in its place.
    match plan.precision {
        Precision::F64 => run_in::<f64>(b, plan, rows, whole),
        Precision::Df64 => run_in::<Df64>(b, plan, rows, whole),
        Precision::F32 => run_in::<f32>(b, plan, rows, whole),
    }
}

/// The time step k of a plan ends at (steps end at k·h exactly; the one
/// nearest a pulse's end lands on it, for rounding: the step after must
/// start at τ, `step::pulse_on`; the last one lands on the duration).
pub fn step_end<R: Real>(c: &Consts<R>, plan: &Plan, k: u64) -> R {
    let h = R::of(plan.h);
    let mut t1 = R::of(k as f64) * h;
    if let Some(p) = &c.pulse {
        if (t1 - p.duration).abs() <= R::of(1e-9) * h {
            t1 = p.duration;
        }
    }
    if let Some(d) = plan.duration {
        if t1 > R::of(d) * R::of(1.0 - 1e-12) {
            t1 = R::of(d);
        }
    }
    t1
}

/// [`run_with`] in precision `R`.
fn run_in<R: Real>(b: &Beads, plan: &Plan, rows: &mut dyn Rows, whole: bool) -> ChainOutcome {
    let w = plan.weights;
    let m = plan.substeps();
    let c = Consts::<R>::of(b, plan.rest);
    let mut st = State::start(b, &c, w, whole, m.refine.is_some());
    let mut obs = Watch::new(b);
    let mut e_ref = b.pulse.is_none().then(|| budget(b, &st));
    let every = plan.every.map(|e| ((e / plan.h).round() as u64).max(1));
    let mut t = R::zero();
    rows.row(0.0, b, &st.in_f64());
    obs.see(b, &c, &st, t, None);
    let mut end_at = plan.duration.map(R::of);
    let mut status = Status::Ok;
    // At rest every contact counts (the window then holds the moving ones).
    let mut max_ratio = overlap_ratio(&c, &st, 0, b.n);
    let (max_time, pulse_end) = (R::of(plan.max_time), c.pulse.map(|p| p.duration));
    // Bead-steps taken (the beads each step stepped: its window's) and
    // told to the plan's tally so far (in chunks of ~2^16).
    let (mut done, mut told) = (0u64, 0u64);
    loop {
        if let Some(end) = end_at {
            if t >= end {
                break;
            }
        }
        if st.steps >= plan.max_steps {
            status = Status::StepCap;
            break;
        }
        if plan.duration.is_none() && t >= max_time {
            status = Status::TimeCap;
            break;
        }
        let t1 = step_end(&c, plan, st.steps + 1);
        done += (st.hi - st.lo) as u64;
        let moved = (st.lo, st.hi);
        step(&c, &mut st, t, t1 - t, &m, whole);
        t = t1;
        obs.see(b, &c, &st, t, Some(moved));
        if e_ref.is_none() && pulse_end.is_some_and(|d| t >= d) {
            e_ref = Some(budget(b, &st));
        }
        if every.is_some_and(|e| st.steps.is_multiple_of(e)) {
            rows.row(t.to64(), b, &st.in_f64());
        }
        if end_at.is_none() {
            if let Some((tp, _)) = obs.far.found {
                end_at = Some(tp * R::of(1.0 + END_MARGIN));
            }
        }
        if st.steps.is_multiple_of(CHECK_EVERY) {
            max_ratio = max_ratio.max(overlap_ratio(&c, &st, st.lo, st.hi));
            if !st.v[st.lo..st.hi].iter().all(|v| v.is_finite()) {
                status = Status::NonFinite;
                break;
            }
            if plan.stop.requested() {
                // Discarded by whoever stopped it (`Stop`).
                status = Status::TimeCap;
                break;
            }
            if done - told >= TALLY_CHUNK {
                plan.tally.add(done - told);
                told = done;
            }
        }
    }
    if every.is_none_or(|e| !st.steps.is_multiple_of(e)) {
        rows.row(t.to64(), b, &st.in_f64());
    }
    max_ratio = max_ratio.max(overlap_ratio(&c, &st, st.lo, st.hi));
    plan.tally.add(done - told);
    finish(b, plan, &st, obs, t, status, e_ref, max_ratio)
}

/// The energy the damping has taken so far (J; 0 without damping): each
/// contact's and each bead's share, summed in f64 in their order.
pub fn dissipated<R: Real>(st: &State<R>) -> f64 {
    lost(&st.lost_c, &st.lost_b)
}

/// [`dissipated`] from the contacts' and the beads' shares (the GPU's
/// energy snapshot keeps them apart from the state). Summed from +0, so
/// that a chain without damping reports 0, not −0 (`Iterator::sum` of
/// f64 starts at −0.0).
pub fn lost<R: Real>(lost_c: &[R], lost_b: &[R]) -> f64 {
    lost_c.iter().chain(lost_b).fold(0.0, |a, x| a + x.to64())
}

/// The work a piston has done on the chain so far (J): its speed times the
/// impulse it gave bead 0 (0 without one).
pub fn piston_work<R: Real>(b: &Beads, st: &State<R>) -> f64 {
    b.piston * st.wall_imp.to64()
}

/// [`Beads::energy`] of a state plus the energy its damping took
/// ([`dissipated`]) minus a piston's work ([`piston_work`]): what an exact
/// run conserves, damped, pushed or not.
pub fn budget<R: Real>(b: &Beads, st: &State<R>) -> f64 {
    energy(b, st) + dissipated(st) - piston_work(b, st)
}

/// [`Beads::energy`] of a state in any precision.
pub fn energy<R: Real>(b: &Beads, st: &State<R>) -> f64 {
    let s = st.in_f64();
    b.energy(&s.p, &s.v)
}

/// The radius an overlap of contact j is measured against: the smaller of
/// its beads' (a wall's contact: its bead's).
pub fn contact_radius(b: &Beads, j: usize) -> f64 {
    match j {
        0 => b.radius[0],
        j if j == b.n => b.radius[b.n - 1],
        j => b.radius[j - 1].min(b.radius[j]),
    }
}

/// Largest overlap over the smaller radius of its contact, contacts lo ..= hi.
pub fn overlap_ratio<R: Real>(c: &Consts<R>, st: &State<R>, lo: usize, hi: usize) -> R {
    let n = c.k.len() - 1;
    let mut m = R::zero();
    for j in lo..=hi.min(n) {
        if c.k[j] == R::zero() {
            continue;
        }
        m = m.max((c.d0[j] + st.p[j]) / c.r[j]);
    }
    m
}

/// The observers of one run.
#[derive(Clone, Debug)]
pub struct Watch<R = f64> {
    /// Per probe: its velocity peak and its force peak.
    pub probes: Vec<(FirstPeak<R>, FirstPeak<R>)>,
    pub far: FirstPeak<R>,
    pub walls: [WallWatch<R>; 2],
    /// FWHM (beads) taken when the last probe's velocity reaches its
    /// largest peak ([`FirstPeak::see_leading`]'s newest record).
    pub width: f64,
    pub floor_v: R,
    pub floor_f: R,
    /// Per probe, when its velocity reached half a piston's speed (none
    /// without a piston).
    pub rises: Vec<Rise<R>>,
    pub rise_level: R,
    /// Under a drive, per probe, its velocity's amplitude at the drive's
    /// frequency over the run's second half.
    pub amps: Vec<Amplitude<R>>,
    /// The rates [`Watch::see`] last computed at each place it reads.
    kept: Kept<R>,
}

/// The rates [`Watch::see`] computed at each probe (its left and right
/// contacts' force rates, its bead's v, a, jerk), at each wall's contact
/// and at the far end, reused while no step comes near them.
#[derive(Clone, Debug)]
struct Kept<R> {
    probes: Vec<Option<[[R; 3]; 3]>>,
    walls: [Option<[R; 3]>; 2],
    far: Option<[R; 3]>,
}

impl<R: Real> Watch<R> {
    /// How many rises and amplitudes the observers keep: one per probe
    /// under a piston, one per probe under a drive (which has a duration);
    /// the GPU sizes a chain's reals by it.
    pub fn counts(b: &Beads) -> (usize, usize) {
        let probes = b.probes.len();
        let rises = if b.piston > 0.0 { probes } else { 0 };
        let amps = match (&b.pulse, b.duration) {
            (Some(p), Some(_)) if p.is_drive() => probes,
            _ => 0,
        };
        (rises, amps)
    }

    pub fn new(b: &Beads) -> Watch<R> {
        let vs = b.v_scale();
        let fs = b.mass.iter().cloned().fold(0.0, f64::max) * vs / b.time_scale();
        let (rises, amps) = Self::counts(b);
        Watch {
            probes: vec![Default::default(); b.probes.len()],
            far: FirstPeak::default(),
            walls: Default::default(),
            width: f64::NAN,
            floor_v: R::of(PEAK_FLOOR * vs),
            floor_f: R::of(PEAK_FLOOR * fs),
            rises: vec![Rise::default(); rises],
            rise_level: R::of(0.5 * b.piston),
            amps: match (&b.pulse, b.duration) {
                (Some(p), Some(end)) => vec![Amplitude::new(0.5 * end, end, p.frequency); amps],
                _ => vec![],
            },
            kept: Kept {
                probes: vec![None; b.probes.len()],
                walls: [None; 2],
                far: None,
            },
        }
    }

    /// Observe the state at time `t`. `moved`: the window (beads lo .. hi,
    /// contacts lo ..= hi) of the step that led to it, the only beads and
    /// contacts that step changed (None: the first observation, or none
    /// known). A place whose rates read only beads and contacts away from
    /// it, and no pulse, takes the rates it last computed: the same values,
    /// as its state has not changed (probes ahead of a wave, the far end).
    pub fn see(
        &mut self,
        b: &Beads,
        c: &Consts<R>,
        st: &State<R>,
        t: R,
        moved: Option<(usize, usize)>,
    ) {
        let n = b.n;
        let last = b.probes.len().wrapping_sub(1);
        let half = R::of(0.5);
        // The dashpots' forces read more than once are computed once.
        let m = &mut Dashpots::new();
        // Whether the rates of a place reading beads a ..= z and the
        // contacts between them are what they were: no bead or contact
        // within one of them moved, and no pulse pushes there.
        let kept = |a: usize, z: usize| {
            moved.is_some_and(|(lo, hi)| z + 1 < lo || a > hi + 1)
                && !c
                    .pulse
                    .as_ref()
                    .is_some_and(|p| p.bead + 1 >= a && p.bead <= z + 1)
        };
        for (k, &i) in b.probes.iter().enumerate() {
            // A probe's rates read beads i − 2 ..= i + 2 (the dashpots of
            // its neighbours' contacts) and contacts i − 1 ..= i + 2.
            let rates = match self.kept.probes[k] {
                Some(r) if kept(i.saturating_sub(2), i + 2) => r,
                _ => {
                    let (fl, dl, sl) = force_rates(c, st, i, m);
                    let (fr, dr, sr) = force_rates(c, st, i + 1, m);
                    let (v, a, j) = bead_rates_with(c, st, i, t, (dl, dr), m);
                    let r = [[fl, dl, sl], [fr, dr, sr], [v, a, j]];
                    self.kept.probes[k] = Some(r);
                    r
                }
            };
            let [[fl, dl, sl], [fr, dr, sr], [v, a, j]] = rates;
            let (vp, fp) = &mut self.probes[k];
            let taken = vp.see_leading(t, [v, a, j], self.floor_v);
            if let Some(r) = self.rises.get_mut(k) {
                r.see(t, [v, a, j], self.rise_level);
            }
            if let Some(r) = self.amps.get_mut(k) {
                r.see(t, v);
            }
            let base = half * (c.f0[i] + c.f0[i + 1]);
            let q = [half * (fl + fr) - base, half * (dl + dr), half * (sl + sr)];
            fp.see_leading(t, q, self.floor_f);
            if k == last && taken {
                let v: Vec<f64> = st.v[st.lo..st.hi].iter().map(|v| v.to64()).collect();
                self.width = fwhm(&v);
            }
        }
        // The walls' contacts read beads 0 ..= 1 and n − 2 ..= n − 1; the
        // far end's bead n − 1 reads n − 3 ..= n − 1 (the right wall n).
        let (left, right) = ((0, 1), (n.saturating_sub(3), n));
        let mut wall = |slot: &mut Option<[R; 3]>, (a, z): (usize, usize), j: usize| match *slot {
            Some(r) if kept(a, z) => r,
            _ => {
                let (f, d, s) = force_rates(c, st, j, m);
                *slot = Some([f, d, s]);
                [f, d, s]
            }
        };
        // Each wall contact's rates once: the right one's are also the far
        // end's when it is a wall.
        let [kl, kr] = &mut self.kept.walls;
        let rates = [(0, kl, left), (n, kr, right)].map(|(j, slot, at)| {
            (c.k[j] > R::zero() || (j == n && b.right_wall)).then(|| wall(slot, at, j))
        });
        for (w, (j, r)) in self.walls.iter_mut().zip([0, n].into_iter().zip(rates)) {
            if let Some(r) = r.filter(|_| c.k[j] > R::zero()) {
                w.see(t, r, c.f0[j]);
            }
        }
        if let Some([f, d, s]) = rates[1].filter(|_| b.right_wall) {
            self.far.see(t, [f - c.f0[n], d, s], self.floor_f);
        } else {
            let r = match self.kept.far {
                Some(r) if kept(right.0, right.1) => r,
                _ => {
                    let (v, a, j) = bead_rates(c, st, n - 1, t, m);
                    self.kept.far = Some([v, a, j]);
                    [v, a, j]
                }
            };
            self.far.see(t, r, self.floor_v);
        }
    }
}

/// Full width at half maximum of a velocity profile (beads), the crossings
/// interpolated linearly between beads.
pub fn fwhm(v: &[f64]) -> f64 {
    let Some((m, &top)) = v.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)) else {
        return f64::NAN;
    };
    if top <= 0.0 {
        return f64::NAN;
    }
    let half = 0.5 * top;
    let cross = |i: usize, j: usize| {
        // v[i] ≥ half > v[j], neighbours: the fractional position of half.
        let f = (v[i] - half) / (v[i] - v[j]);
        i as f64 + f * (j as f64 - i as f64)
    };
    let mut l = m;
    while l > 0 && v[l - 1] >= half {
        l -= 1;
    }
    let left = if l == 0 { 0.0 } else { cross(l, l - 1) };
    let mut r = m;
    while r + 1 < v.len() && v[r + 1] >= half {
        r += 1;
    }
    let right = if r + 1 == v.len() {
        r as f64
    } else {
        cross(r, r + 1)
    };
    right - left
}

/// The outcome of a run that ended at `t` in `st` with `status`, from its
/// observers, the energy it is measured against and the largest overlap
/// ratio seen (the last window's is taken here).
/// Long (~130 lines) on purpose: one outcome field after another, each
/// from its observer; the GPU's read-back finishes a chain through it.
#[allow(clippy::too_many_arguments)]
pub fn finish<R: Real>(
    b: &Beads,
    plan: &Plan,
    st: &State<R>,
    obs: Watch<R>,
    t: R,
    mut status: Status,
    e_ref: Option<f64>,
    max_ratio: R,
) -> ChainOutcome {
    let (t, max_ratio) = (t.to64(), max_ratio.to64());
    let st = st.in_f64();
    let n = b.n;
    let probes: Vec<ProbeOutcome> = b
        .probes
        .iter()
        .zip(&obs.probes)
        .map(|(&i, (vp, fp))| {
            let (arrival, peak_velocity) = vp.leading64().unwrap_or((f64::NAN, f64::NAN));
            let base = 0.5 * (b.f0[i] + b.f0[i + 1]);
            ProbeOutcome {
                bead: i,
                arrival,
                peak_velocity,
                peak_force: fp.leading64().map_or(f64::NAN, |(_, f)| f + base),
                v_final: st.v[i],
            }
        })
        .collect();
    let pulse_speed = match (probes.first(), probes.last()) {
        (Some(a), Some(z)) if z.bead > a.bead => {
            b.distance(a.bead, z.bead) / (z.arrival - a.arrival)
        }
        _ => f64::NAN,
    };
    // Energy per bead: kinetic plus half of each of its contacts'.
    let contact = |j: usize| super::excess_energy(b.k[j], b.d0[j], st.p[j]);
    let bead_energy = |i: usize| {
        0.5 * b.mass[i] * st.v[i] * st.v[i]
            + if i == 0 { contact(0) } else { 0.5 * contact(i) }
            + if i == n - 1 {
                contact(n)
            } else {
                0.5 * contact(i + 1)
            }
    };
    let e_end: f64 = (0..n).map(bead_energy).sum();
    let work = piston_work(b, &st);
    // The energy put in: the start's (or the pulse's), or a piston's work
    // if more.
    let e_in = match e_ref {
        Some(e) if b.piston > 0.0 => e.max(work.abs()),
        e => e.unwrap_or(f64::NAN),
    };
    let (er, et, el) = match (b.probes.first(), b.probes.last()) {
        (Some(&f), Some(&l)) => {
            let sum = |r: std::ops::Range<usize>| r.map(bead_energy).sum::<f64>() / e_in;
            (sum(0..f), sum(l + 1..n), sum(f..l + 1))
        }
        _ => (f64::NAN, f64::NAN, f64::NAN),
    };
    let energy_dissipated = dissipated(&st);
    let e_start = e_ref.unwrap_or(f64::NAN);
    let energy_error = ((e_end + energy_dissipated - work - e_start) / e_in).abs();
    let rises: Vec<f64> = obs
        .rises
        .iter()
        .map(|r| r.at.map_or(f64::NAN, |t| t.to64()))
        .collect();
    let shock_speed = match (
        b.probes.first(),
        b.probes.last(),
        rises.first(),
        rises.last(),
    ) {
        (Some(&a), Some(&z), Some(ta), Some(tz)) if z > a => b.distance(a, z) / (tz - ta),
        _ => f64::NAN,
    };
    let momentum_error = if b.left_wall || b.right_wall || b.air_drag > 0.0 {
        f64::NAN
    } else {
        let p = |v: &[f64]| b.mass.iter().zip(v).map(|(m, v)| m * v).sum::<f64>();
        let kick = b.pulse.as_ref().map_or(0.0, |pl| {
            if t >= pl.duration {
                pl.impulse()
            } else {
                f64::NAN
            }
        });
        let want = p(&b.v0) + kick;
        let scale = b.mass.iter().sum::<f64>() * b.v_scale();
        ((p(&st.v) - want) / scale).abs()
    };
    // The run's own check looks every CHECK_EVERY steps: a run that ends
    // (or blows up) between two looks is caught here, so no row is `ok`
    // with NaN or infinite velocities (a user dt far too large over a few
    // steps did that).
    if status != Status::Invalid && !st.v.iter().chain(&st.p).all(|x| x.is_finite()) {
        status = Status::NonFinite;
    }
    if status == Status::Ok {
        if max_ratio > MAX_OVERLAP_RATIO {
            status = Status::OverlapInvalid;
        } else if energy_error > crate::engine::outcome::ENERGY_BOUND {
            status = Status::EnergyError;
        }
    }
    // A gap counts when it is wider than FRAGMENT_GAP of its contact's
    // radius: far above round-off (a tail's contacts open by ~1e-20 m),
    // far below any gap an experiment resolves.
    let fragments = 1
        + (1..n)
            .filter(|&j| b.d0[j] + st.p[j] < -FRAGMENT_GAP * contact_radius(b, j))
            .count();
    let [lw, rw] = obs.walls;
    let wall = |w: WallWatch<R>, on: bool, j: usize| {
        on.then_some(WallOutcome {
            peak_force: w.peak.to64(),
            impulse: w.impulse.to64(),
            // (under precompression the wall is always touched)
            in_contact: b.d0[j] <= 0.0 && b.d0[j] + st.p[j] > 0.0,
        })
    };
    ChainOutcome {
        status,
        probes,
        pulse_speed,
        pulse_width: obs.width,
        left_wall: wall(lw, b.left_wall, 0),
        right_wall: wall(rw, b.right_wall, n),
        energy_reflected: er,
        energy_transmitted: et,
        energy_left: el,
        fragments,
        energy_error,
        energy_dissipated,
        shock_speed,
        piston_work: work,
        amplitudes: obs.amps.iter().map(|a| a.value()).collect(),
        momentum_error,
        max_overlap_ratio: max_ratio,
        v: st.v.clone(),
        t_end: t,
        steps: st.steps,
        regions: st.regions,
        region_beads: st.region_beads,
        dt: plan.h,
        error_estimate: f64::NAN,
        v_scale: b.v_scale(),
        tolerance: plan.tolerance,
        refined: plan.substeps().refine.is_some(),
        dashpots: b.viscosity > 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::{Overrides, Solver};
    use crate::scene::Scene;

    /// The rates [`Watch::see`] keeps for a place no step came near are,
    /// bit for bit, the ones it would compute: a run observed with each
    /// step's window and the same run observed computing every place at
    /// every step agree at every step, on chains whose waves reach their
    /// probes, walls and far end partway through (damped and not, a
    /// pulse, Hunt–Crossley contacts, a free far end), in f64 and df64.
    #[test]
    fn kept_rates_are_the_ones_computed() {
        for text in [
            "balls = 60\n[walls]\nleft = true\nright = true\nprecompression = 10.0\n[launch]\nballs = 1\nvelocity = 0.1\n\
             [probes]\nbeads = [12, 40]\n[damping]\nviscosity = 0.5\n[solver]\ndt = 2e-7\n[stop]\nduration = 3e-4\n",
            "balls = 50\n[launch]\nballs = 1\nvelocity = 0.1\n[probes]\nbeads = [10, 30]\n[damping]\nrestitution = 0.8\n\
             [solver]\ndt = 2e-7\n[stop]\nduration = 3e-4\n",
            "balls = 60\n[walls]\nleft = true\nright = true\nprecompression = 5.0\n[pulse]\nbead = 30\nforce = 2.0\n\
             duration = 1e-5\n[probes]\nbeads = [8, 29, 52]\n[solver]\ndt = 2e-7\n[stop]\nduration = 2e-4\n",
        ] {
            let s = Scene::from_toml_str("chain", text).unwrap();
            let b = Beads::from_scene(&s);
            let solver = Solver::resolve(&s, &Overrides::default()).unwrap();
            let plan = super::super::plan(&b, &solver, None);
            let kept_some = watch_both::<f64>(&b, &plan, text);
            assert!(kept_some > 0, "no rates were kept: {text}");
            watch_both::<Df64>(&b, &plan, text);
        }
    }

    /// Steps `b` as [`run_in`] does, observing each state twice; returns
    /// how many observations found a probe away from the window.
    fn watch_both<R: Real>(b: &Beads, plan: &Plan, text: &str) -> usize {
        let m = plan.substeps();
        let c = Consts::<R>::of(b, plan.rest);
        let mut st = State::start(b, &c, plan.weights, false, m.refine.is_some());
        let (mut kept, mut fresh) = (Watch::<R>::new(b), Watch::<R>::new(b));
        let mut t = R::zero();
        kept.see(b, &c, &st, t, None);
        fresh.see(b, &c, &st, t, None);
        let steps = (plan.duration.unwrap() / plan.h).round() as u64;
        let mut away = 0;
        for k in 1..=steps {
            let t1 = step_end(&c, plan, k);
            let moved = (st.lo, st.hi);
            step(&c, &mut st, t, t1 - t, &m, false);
            t = t1;
            away += b.probes.iter().filter(|&&i| i + 3 < moved.0).count();
            away += b.probes.iter().filter(|&&i| i > moved.1 + 3).count();
            kept.see(b, &c, &st, t, Some(moved));
            fresh.see(b, &c, &st, t, None);
            let seen = |w: &Watch<R>| format!("{:?}", (&w.probes, &w.far, &w.walls, w.width));
            assert_eq!(seen(&kept), seen(&fresh), "step {k}: {text}");
        }
        away
    }
}
