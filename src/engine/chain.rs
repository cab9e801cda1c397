//! The compiled scene both backends integrate: a chain of rigid bodies.
//!
//! Glue merges balls into one body (masses summed, one velocity): glue removes
//! a degree of freedom, it is not a stiff spring. Contact c joins body c and
//! body c+1; its stiffness comes from the two boundary balls (SPEC §2).

use super::contact::{contact_time, hertz_stiffness};
use crate::error::InputError;
use crate::scene::Scene;

#[derive(Clone, Debug, PartialEq)]
pub struct Chain {
    /// Number of balls N.
    pub n_balls: usize,
    /// Body index of each ball.
    pub body_of_ball: Vec<usize>,
    /// Mass of each body (kg).
    pub mass: Vec<f64>,
    /// Initial velocity of each body (m/s).
    pub v0: Vec<f64>,
    /// Hertz stiffness of each contact (N/m^{3/2}), one per pair of adjacent bodies.
    pub k: Vec<f64>,
    /// Surface gap of each contact at rest (m).
    pub gap: Vec<f64>,
    /// Radius of the smaller boundary ball of each contact (m): Hertz theory
    /// is trusted while overlap/radius stays below [`super::MAX_OVERLAP_RATIO`].
    pub r_min: Vec<f64>,
}

impl Chain {
    /// Compile a checked scene. Features the engine does not integrate yet are
    /// refused here with a clear error rather than silently ignored.
    pub fn from_scene(s: &Scene) -> Result<Chain, InputError> {
        if s.pendulum.is_some() {
            return Err(unsupported("pendulum", "pendulum suspension is not implemented yet (issue: full pendulum cradles); remove [pendulum] to simulate a free line"));
        }
        if s.damping.is_some() {
            return Err(unsupported("damping", "contact damping is not implemented yet (issue: full pendulum cradles); remove [damping] for an elastic cradle"));
        }
        let mut body_of_ball = Vec::with_capacity(s.n);
        let (mut mass, mut v0, mut k, mut gap, mut r_min) =
            (vec![], vec![], vec![], vec![], vec![]);
        for i in 0..s.n {
            if i > 0 && s.glue[i - 1] {
                *mass.last_mut().unwrap() += s.mass[i];
            } else {
                if i > 0 {
                    let j = i - 1;
                    k.push(hertz_stiffness(
                        s.radius[j],
                        s.young_modulus[j],
                        s.poisson_ratio[j],
                        s.radius[i],
                        s.young_modulus[i],
                        s.poisson_ratio[i],
                    ));
                    gap.push(s.gap[j]);
                    r_min.push(s.radius[j].min(s.radius[i]));
                }
                mass.push(s.mass[i]);
                v0.push(s.velocity[i]);
            }
            body_of_ball.push(mass.len() - 1);
        }
        Ok(Chain {
            n_balls: s.n,
            body_of_ball,
            mass,
            v0,
            k,
            gap,
            r_min,
        })
    }

    pub fn n_bodies(&self) -> usize {
        self.mass.len()
    }

    /// Largest initial speed |v| (SPEC §5).
    pub fn v_in(&self) -> f64 {
        self.v0.iter().fold(0.0, |m, v| m.max(v.abs()))
    }

    /// Shortest time scale of the chain (s): the two-body Hertz contact time of
    /// the stiffest, lightest contact at the largest initial relative speed.
    /// Outcomes of a touching chain scale exactly when steps are a fixed
    /// fraction of it. `None` when nothing can ever collide.
    pub fn time_scale(&self) -> Option<f64> {
        let vmax = self.v0.iter().copied().fold(f64::MIN, f64::max);
        let vmin = self.v0.iter().copied().fold(f64::MAX, f64::min);
        let v = vmax - vmin;
        if v.is_nan() || v <= 0.0 || self.k.is_empty() {
            return None;
        }
        (0..self.k.len())
            .map(|c| {
                let (a, b) = (self.mass[c], self.mass[c + 1]);
                contact_time(a * b / (a + b), self.k[c], v)
            })
            .reduce(f64::min)
    }

    /// Total energy (J) of a state: kinetic plus elastic.
    pub fn energy(&self, v: &[f64], overlap: &[f64]) -> f64 {
        let kin: f64 = self.mass.iter().zip(v).map(|(m, v)| 0.5 * m * v * v).sum();
        let el: f64 = self
            .k
            .iter()
            .zip(overlap)
            .map(|(&k, &d)| super::contact::hertz_energy(k, d))
            .sum();
        kin + el
    }

    pub fn momentum(&self, v: &[f64]) -> f64 {
        self.mass.iter().zip(v).map(|(m, v)| m * v).sum()
    }
}

fn unsupported(key: &str, what: &str) -> InputError {
    InputError::Unsupported {
        origin: "scene".into(),
        line: None,
        key: key.into(),
        what: what.into(),
    }
}
