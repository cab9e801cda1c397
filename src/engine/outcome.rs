//! Outcomes of one scene (docs/SPEC.md §4–§5): per-ball final velocities, `ejected`,
//! diagnostics and a status that is never `ok` for garbage.

use std::fmt;

use serde::Serialize;

use super::cradle::{End, Run};
use super::Chain;

/// Relative slack of the ordering test of [`ejected`] (the default tolerance).
pub const EJECT_SLACK: f64 = 1e-6;
/// Energy error above which a scene is not `ok`.
pub const ENERGY_BOUND: f64 = 1e-3;
/// Overlap / radius above which Hertz theory is not trusted.
pub const MAX_OVERLAP_RATIO: f64 = 0.1;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Ok,
    /// The step cap was reached before the chain settled.
    StepCap,
    /// The time cap (`[stop] duration`) was reached before the chain settled.
    TimeCap,
    /// NaN or infinity appeared.
    NonFinite,
    /// The relative energy error exceeded [`ENERGY_BOUND`] (step too large?).
    EnergyError,
    /// Overlap beyond the validity of Hertz theory ([`MAX_OVERLAP_RATIO`]).
    OverlapInvalid,
    /// The scene failed validation (in a sweep: this combination of values).
    Invalid,
    /// A granular chain whose error estimate stayed above its tolerance
    /// after the error control's reruns (docs/SPEC.md §9).
    Inaccurate,
    /// A granular chain whose outcome does not converge as the step
    /// shrinks: it depends on its initial data (and round-off) more than
    /// the tolerance allows, e.g. chaotic scattering (docs/SPEC.md §9).
    Sensitive,
}

impl Status {
    /// Every status, in declaration order.
    pub const ALL: [Status; 9] = [
        Status::Ok,
        Status::StepCap,
        Status::TimeCap,
        Status::NonFinite,
        Status::EnergyError,
        Status::OverlapInvalid,
        Status::Invalid,
        Status::Inaccurate,
        Status::Sensitive,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::StepCap => "step_cap",
            Status::TimeCap => "time_cap",
            Status::NonFinite => "non_finite",
            Status::EnergyError => "energy_error",
            Status::OverlapInvalid => "overlap_invalid",
            Status::Invalid => "invalid",
            Status::Inaccurate => "inaccurate",
            Status::Sensitive => "sensitive",
        }
    }
}

/// The statuses as the tables write them (`Choice::from_name` reads one).
impl crate::choice::Choice for Status {
    const ALL: &'static [Self] = &Status::ALL;
    fn name(self) -> &'static str {
        Status::name(self)
    }
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    pub status: Status,
    /// Final velocity of each ball (m/s); glued balls repeat their body's.
    pub v: Vec<f64>,
    /// Balls leaving at the far end (docs/SPEC.md §5).
    pub ejected: usize,
    /// Relative energy error; for a dissipative scene only a gain counts.
    pub energy_error: f64,
    pub momentum_error: f64,
    pub max_overlap_m: f64,
    pub steps: u64,
    /// Final over initial energy.
    pub energy_left: f64,
    /// Kinetic energy of the last ball over the initial energy.
    pub energy_last: f64,
    /// Contact onsets.
    pub contacts: u64,
    /// Final displacement of each ball (m; arc length on a pendulum).
    pub x: Vec<f64>,
    /// Simulated time at the end (s).
    pub t_end: f64,
    /// First contact onset and last release (s); NaN when there was no contact.
    pub t_contact: f64,
    pub t_release: f64,
    /// Step used (s); NaN when nothing could collide.
    pub dt: f64,
    /// Estimated error of `v` relative to v_in (`--error-estimate`); NaN when not asked.
    pub error_estimate: f64,
}

impl Outcome {
    pub fn from_run(chain: &Chain, run: &Run, dt: f64) -> Outcome {
        let v: Vec<f64> = chain.body_of_ball.iter().map(|&b| run.v[b]).collect();
        let e0 = chain.energy(&chain.v0, &chain.initial_overlap(), &chain.x0);
        let e1 = chain.energy(&run.v, &run.overlap, &run.x);
        let p0 = chain.momentum(&chain.v0);
        let p1 = chain.momentum(&run.v);
        let p_scale: f64 = chain
            .mass
            .iter()
            .zip(&chain.v0)
            .map(|(m, v)| m * v.abs())
            .sum();
        let gain = if chain.is_dissipative() {
            (e1 - e0).max(0.0)
        } else {
            (e1 - e0).abs()
        };
        let energy_error = if e0 > 0.0 { gain / e0 } else { e1.abs() };
        // Gravity and drag change momentum: on a pendulum it is not conserved.
        let momentum_error = if chain.is_pendulum() || chain.air_drag > 0.0 {
            f64::NAN
        } else if p_scale > 0.0 {
            (p1 - p0).abs() / p_scale
        } else {
            p1.abs()
        };
        let status = match run.end {
            End::NonFinite => Status::NonFinite,
            End::StepCap => Status::StepCap,
            End::TimeCap => Status::TimeCap,
            End::Settled | End::Duration
                if energy_error.is_nan() || energy_error > ENERGY_BOUND =>
            {
                Status::EnergyError
            }
            End::Settled | End::Duration if run.max_overlap_ratio > MAX_OVERLAP_RATIO => {
                Status::OverlapInvalid
            }
            End::Settled | End::Duration => Status::Ok,
        };
        Outcome {
            status,
            ejected: ejected(&v),
            v,
            energy_error,
            momentum_error,
            max_overlap_m: run.max_overlap,
            steps: run.steps,
            energy_left: if e0 > 0.0 { e1 / e0 } else { f64::NAN },
            energy_last: {
                let last = chain.body_of_ball.len() - 1;
                let vl = run.v[chain.body_of_ball[last]];
                // the last ball's own mass (a glued body's is shared by its balls)
                let m_ball = chain.ball_mass[last];
                if e0 > 0.0 {
                    0.5 * m_ball * vl * vl / e0
                } else {
                    f64::NAN
                }
            },
            contacts: run.contacts,
            x: chain.body_of_ball.iter().map(|&b| run.x[b]).collect(),
            t_end: run.t,
            t_contact: run.t_first_contact.unwrap_or(f64::NAN),
            t_release: run.t_last_release.unwrap_or(f64::NAN),
            dt,
            error_estimate: f64::NAN,
        }
    }

    /// An outcome for a scene that could not be built (a sweep keeps going).
    pub fn invalid(n_balls: usize) -> Outcome {
        Outcome {
            status: Status::Invalid,
            v: vec![f64::NAN; n_balls],
            ejected: 0,
            energy_error: f64::NAN,
            momentum_error: f64::NAN,
            max_overlap_m: f64::NAN,
            steps: 0,
            energy_left: f64::NAN,
            energy_last: f64::NAN,
            contacts: 0,
            x: vec![f64::NAN; n_balls],
            t_end: f64::NAN,
            t_contact: f64::NAN,
            t_release: f64::NAN,
            dt: f64::NAN,
            error_estimate: f64::NAN,
        }
    }
}

/// docs/SPEC.md §5: the number of balls at the right end that leave faster than half
/// the largest final velocity, with velocities non-decreasing toward the end.
/// Velocities equal to within [`EJECT_SLACK`]·max count as non-decreasing: two
/// balls leaving together at 1 and 1 − 1e-15 are two balls out, not one.
pub fn ejected(v: &[f64]) -> usize {
    let vmax = v.iter().copied().fold(f64::MIN, f64::max);
    if vmax.is_nan() || vmax <= 0.0 {
        return 0;
    }
    let mut count = 0;
    for i in (0..v.len()).rev() {
        let fast = v[i] > 0.5 * vmax;
        let ordered = i + 1 == v.len() || v[i] <= v[i + 1] + EJECT_SLACK * vmax;
        if !(fast && ordered) {
            break;
        }
        count += 1;
    }
    count
}

#[cfg(test)]
mod tests {
    use super::ejected;

    #[test]
    fn ejected_counts_the_fast_tail() {
        assert_eq!(ejected(&[0.0, 0.0, 0.0, 0.0, 1.0]), 1);
        assert_eq!(ejected(&[0.0, 0.0, 0.0, 1.0, 1.0]), 2);
        assert_eq!(ejected(&[-0.07, -0.03, -0.01, 0.127, 0.989]), 1);
        // a fast ball that is followed by a slower one does not count
        assert_eq!(ejected(&[0.0, 0.0, 0.9, 0.6, 1.0]), 2);
        assert_eq!(ejected(&[0.0, 0.0, 1.0, 0.1, 0.2]), 0);
        assert_eq!(ejected(&[-1.0, 0.0]), 0);
    }
}
