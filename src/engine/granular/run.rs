//! A chain run: fixed steps ([`super::step`]) from rest to the end
//! (docs/SPEC.md §9), the observers of [`super::observe`] between steps,
//! and the outcome.

use super::observe::*;
use super::step::{step, State};
use super::{Beads, Plan, END_MARGIN, PEAK_FLOOR};
use crate::engine::outcome::MAX_OVERLAP_RATIO;
use crate::engine::Status;

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

/// Check overlaps and finiteness every this many steps (over the window).
pub const CHECK_EVERY: u64 = 16;

/// Run `beads` as planned, rows to `rows`.
pub fn run(beads: &Beads, plan: &Plan, rows: &mut dyn Rows) -> ChainOutcome {
    run_with(beads, plan, rows, false)
}

/// [`run`], the window the whole chain when `whole` (for tests).
pub fn run_with(b: &Beads, plan: &Plan, rows: &mut dyn Rows, whole: bool) -> ChainOutcome {
    let w = plan.weights;
    let m = plan.substeps();
    let mut st = State::start(b, w, whole);
    let mut obs = Watch::new(b);
    let e_start = b.energy(&st.p, &st.v);
    let mut e_ref = b.pulse.is_none().then_some(e_start);
    let every = plan.every.map(|e| ((e / plan.h).round() as u64).max(1));
    let mut t = 0.0;
    rows.row(0.0, b, &st);
    obs.see(b, &st, t);
    let mut end_at = plan.duration;
    let mut status = Status::Ok;
    // At rest every contact counts (the window then holds the moving ones).
    let mut max_ratio = overlap_ratio(b, &st, 0, b.n);
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
        if plan.duration.is_none() && t >= plan.max_time {
            status = Status::TimeCap;
            break;
        }
        // Steps end at k·h exactly; the one nearest a pulse's end lands on
        // it (the plan put it there, but for rounding: the step after must
        // start at τ, `step::pulse_on`); the last one lands on the duration.
        let mut t1 = (st.steps + 1) as f64 * plan.h;
        if let Some(p) = &b.pulse {
            if (t1 - p.duration).abs() <= 1e-9 * plan.h {
                t1 = p.duration;
            }
        }
        if let Some(d) = plan.duration {
            if t1 > d * (1.0 - 1e-12) {
                t1 = d;
            }
        }
        step(b, &mut st, t, t1 - t, &m, whole);
        t = t1;
        obs.see(b, &st, t);
        if e_ref.is_none() && b.pulse.as_ref().is_some_and(|p| t >= p.duration) {
            e_ref = Some(b.energy(&st.p, &st.v));
        }
        if every.is_some_and(|e| st.steps.is_multiple_of(e)) {
            rows.row(t, b, &st);
        }
        if end_at.is_none() {
            if let Some((tp, _)) = obs.far.found {
                end_at = Some(tp * (1.0 + END_MARGIN));
            }
        }
        if st.steps.is_multiple_of(CHECK_EVERY) {
            max_ratio = max_ratio.max(overlap_ratio(b, &st, st.lo, st.hi));
            if !st.v[st.lo..st.hi].iter().all(|v| v.is_finite()) {
                status = Status::NonFinite;
                break;
            }
        }
    }
    if every.is_none_or(|e| !st.steps.is_multiple_of(e)) {
        rows.row(t, b, &st);
    }
    max_ratio = max_ratio.max(overlap_ratio(b, &st, st.lo, st.hi));
    finish(b, plan, st, obs, t, status, e_ref, max_ratio)
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
pub fn overlap_ratio(b: &Beads, st: &State, lo: usize, hi: usize) -> f64 {
    let n = b.n;
    let mut m = 0.0f64;
    for j in lo..=hi.min(n) {
        if b.k[j] == 0.0 {
            continue;
        }
        m = m.max((b.d0[j] + st.p[j]) / contact_radius(b, j));
    }
    m
}

/// The observers of one run.
#[derive(Clone, Debug)]
pub struct Watch {
    /// Per probe: its velocity peak and its force peak.
    pub probes: Vec<(FirstPeak, FirstPeak)>,
    pub far: FirstPeak,
    pub walls: [WallWatch; 2],
    /// FWHM (beads) taken when the last probe's pulse arrives.
    pub width: f64,
    pub floor_v: f64,
    pub floor_f: f64,
}

impl Watch {
    pub fn new(b: &Beads) -> Watch {
        let vs = b.v_scale();
        let fs = b.mass.iter().cloned().fold(0.0, f64::max) * vs / b.time_scale();
        Watch {
            probes: vec![Default::default(); b.probes.len()],
            far: FirstPeak::default(),
            walls: Default::default(),
            width: f64::NAN,
            floor_v: PEAK_FLOOR * vs,
            floor_f: PEAK_FLOOR * fs,
        }
    }

    pub fn see(&mut self, b: &Beads, st: &State, t: f64) {
        let n = b.n;
        let last = b.probes.len().wrapping_sub(1);
        for (k, &i) in b.probes.iter().enumerate() {
            let (vp, fp) = &mut self.probes[k];
            let had = vp.found.is_some();
            let (fl, dl, sl) = force_rates(b, st, i);
            let (fr, dr, sr) = force_rates(b, st, i + 1);
            let (v, a, j) = bead_rates_with(b, st, i, t, dl, dr);
            vp.see(t, [v, a, j], self.floor_v);
            let base = 0.5 * (b.f0[i] + b.f0[i + 1]);
            let q = [0.5 * (fl + fr) - base, 0.5 * (dl + dr), 0.5 * (sl + sr)];
            fp.see(t, q, self.floor_f);
            if k == last && !had && vp.found.is_some() {
                self.width = fwhm(&st.v[st.lo..st.hi]);
            }
        }
        for (w, j) in self.walls.iter_mut().zip([0, n]) {
            if b.k[j] > 0.0 {
                let (f, d, s) = force_rates(b, st, j);
                w.see(t, [f, d, s], b.f0[j]);
            }
        }
        if b.right_wall {
            let (f, d, s) = force_rates(b, st, n);
            self.far.see(t, [f - b.f0[n], d, s], self.floor_f);
        } else {
            let (v, a, j) = bead_rates(b, st, n - 1, t);
            self.far.see(t, [v, a, j], self.floor_v);
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
#[allow(clippy::too_many_arguments)]
pub fn finish(
    b: &Beads,
    plan: &Plan,
    st: State,
    obs: Watch,
    t: f64,
    mut status: Status,
    e_ref: Option<f64>,
    max_ratio: f64,
) -> ChainOutcome {
    let n = b.n;
    let probes: Vec<ProbeOutcome> = b
        .probes
        .iter()
        .zip(&obs.probes)
        .map(|(&i, (vp, fp))| {
            let (arrival, peak_velocity) = vp.found.unwrap_or((f64::NAN, f64::NAN));
            let base = 0.5 * (b.f0[i] + b.f0[i + 1]);
            ProbeOutcome {
                bead: i,
                arrival,
                peak_velocity,
                peak_force: fp.found.map_or(f64::NAN, |(_, f)| f + base),
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
    let e_in = e_ref.unwrap_or(f64::NAN);
    let (er, et, el) = match (b.probes.first(), b.probes.last()) {
        (Some(&f), Some(&l)) => {
            let sum = |r: std::ops::Range<usize>| r.map(bead_energy).sum::<f64>() / e_in;
            (sum(0..f), sum(l + 1..n), sum(f..l + 1))
        }
        _ => (f64::NAN, f64::NAN, f64::NAN),
    };
    let energy_error = ((e_end - e_in) / e_in).abs();
    let momentum_error = if b.left_wall || b.right_wall {
        f64::NAN
    } else {
        let p = |v: &[f64]| b.mass.iter().zip(v).map(|(m, v)| m * v).sum::<f64>();
        let kick = b.pulse.as_ref().map_or(0.0, |pl| {
            if t >= pl.duration {
                2.0 * pl.force * pl.duration / std::f64::consts::PI
            } else {
                f64::NAN
            }
        });
        let want = p(&b.v0) + kick;
        let scale = b.mass.iter().sum::<f64>() * b.v_scale();
        ((p(&st.v) - want) / scale).abs()
    };
    if status == Status::Ok {
        if max_ratio > MAX_OVERLAP_RATIO {
            status = Status::OverlapInvalid;
        } else if energy_error > crate::engine::outcome::ENERGY_BOUND {
            status = Status::EnergyError;
        }
    }
    let fragments = 1 + (1..n).filter(|&j| b.d0[j] + st.p[j] < 0.0).count();
    let [lw, rw] = obs.walls;
    let wall = |w: WallWatch, on: bool| {
        on.then_some(WallOutcome {
            peak_force: w.peak,
            impulse: w.impulse,
        })
    };
    ChainOutcome {
        status,
        probes,
        pulse_speed,
        pulse_width: obs.width,
        left_wall: wall(lw, b.left_wall),
        right_wall: wall(rw, b.right_wall),
        energy_reflected: er,
        energy_transmitted: et,
        energy_left: el,
        fragments,
        energy_error,
        momentum_error,
        max_overlap_ratio: max_ratio,
        v: st.v,
        t_end: t,
        steps: st.steps,
        dt: plan.h,
    }
}
