//! The compiled scene both backends integrate: a chain of rigid bodies.
//!
//! Glue merges balls into one body (masses summed, one velocity): glue removes
//! a degree of freedom, it is not a stiff spring. Contact c joins body c and
//! body c+1; its stiffness comes from the two boundary balls (docs/SPEC.md §2).

use super::contact::{contact_time, hertz_stiffness, hunt_crossley_a, impact_coefficients};
use crate::error::InputError;
use crate::scene::Scene;

#[derive(Clone, Debug, PartialEq)]
pub struct Chain {
    /// Number of balls N.
    pub n_balls: usize,
    /// Body index of each ball.
    pub body_of_ball: Vec<usize>,
    /// Mass of each ball (kg).
    pub ball_mass: Vec<f64>,
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
    /// Initial displacement of each body (m; arc length on a pendulum).
    pub x0: Vec<f64>,
    /// Gravity g (m/s²) of a pendulum; 0 for a free line.
    pub gravity: f64,
    /// String length L (m) of a pendulum; infinite for a free line.
    pub length: f64,
    /// Coefficient of restitution e (1: elastic).
    pub restitution: f64,
    /// Hunt–Crossley a = χ·v_imp for `restitution` (0: elastic).
    pub damping_a: f64,
    /// Linear air drag (1/s): dv/dt = −γ·v.
    pub air_drag: f64,
}

impl Chain {
    /// Compile a checked scene. Features the engine does not integrate yet are
    /// refused here with a clear error rather than silently ignored.
    pub fn from_scene(s: &Scene) -> Result<Chain, InputError> {
        let mut body_of_ball = Vec::with_capacity(s.n);
        let (mut mass, mut v0, mut k, mut gap, mut r_min, mut x0) =
            (vec![], vec![], vec![], vec![], vec![], vec![]);
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
                x0.push(s.displacement[i]);
            }
            body_of_ball.push(mass.len() - 1);
        }
        let restitution = s.damping.as_ref().map_or(1.0, |d| d.restitution);
        Ok(Chain {
            n_balls: s.n,
            body_of_ball,
            ball_mass: s.mass.clone(),
            mass,
            v0,
            k,
            gap,
            r_min,
            x0,
            gravity: s.pendulum.as_ref().map_or(0.0, |p| p.gravity),
            length: s.pendulum.as_ref().map_or(f64::INFINITY, |p| p.length),
            restitution,
            damping_a: hunt_crossley_a(restitution),
            air_drag: s.damping.as_ref().map_or(0.0, |d| d.air_drag),
        })
    }

    /// Whether the balls hang on strings (gravity acts; the run ends at the duration).
    pub fn is_pendulum(&self) -> bool {
        self.gravity > 0.0
    }

    /// Whether energy is lost on purpose (contact damping or air drag).
    pub fn is_dissipative(&self) -> bool {
        self.damping_a > 0.0 || self.air_drag > 0.0
    }

    /// Whether integrating it needs the gravity, damping or drag terms: both
    /// integrators (CPU lanes and shader) have a variant without them for
    /// elastic free lines.
    pub fn needs_terms(&self) -> bool {
        self.is_pendulum() || self.is_dissipative()
    }

    /// Angular frequency √(g/L) of small swings (rad/s); 0 for a free line.
    pub fn omega(&self) -> f64 {
        (self.gravity / self.length).sqrt()
    }

    /// Speed at the bottom of the swing of a body released from displacement x (m/s).
    fn swing_speed(&self, x: f64) -> f64 {
        if self.is_pendulum() {
            2.0 * (self.gravity * self.length).sqrt() * (0.5 * x / self.length).sin().abs()
        } else {
            0.0
        }
    }

    pub fn n_bodies(&self) -> usize {
        self.mass.len()
    }

    /// Largest initial speed |v| (docs/SPEC.md §5); for balls lifted on a pendulum,
    /// their speed at the bottom of the swing, √(2gh).
    pub fn v_in(&self) -> f64 {
        let v = self.v0.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        self.x0.iter().fold(v, |m, &x| m.max(self.swing_speed(x)))
    }

    /// Reduced mass m_c·m_{c+1}/(m_c + m_{c+1}) of contact c (kg).
    pub fn reduced_mass(&self, c: usize) -> f64 {
        let (a, b) = (self.mass[c], self.mass[c + 1]);
        a * b / (a + b)
    }

    /// Closed-form impact coefficients of contact c
    /// ([`super::contact::impact_coefficients`]).
    pub fn impact_coefficients(&self, c: usize) -> (f64, f64) {
        impact_coefficients(self.reduced_mass(c), self.k[c])
    }

    /// Coefficients (left, right) of contact c for a bound on the chain's
    /// fastest local frequency ω, relative to `omega_ref` (rad/s):
    /// (ω/ω_ref)⁴ ≤ max_b (right_{b−1}·δ⁺_{b−1} + left_b·δ⁺_b). The local
    /// stiffness of contact c is k'_c = (3/2)·k_c·√δ_c; by Gershgorin, ω² is
    /// at most the largest row sum of M^{−1/2}·K'·M^{−1/2}, k'_{b−1}·(1/m_b +
    /// 1/√(m_{b−1}m_b)) + k'_b·(1/m_b + 1/√(m_b m_{b+1})), and (x + y)² ≤
    /// 2(x² + y²) squares it without a square root per contact. Exact for a
    /// light ball squeezed equally from both sides; 2^{1/4} high for one contact.
    pub fn stiffness_coefficients(&self, c: usize, omega_ref: f64) -> (f64, f64) {
        let (ia, ib) = (1.0 / self.mass[c], 1.0 / self.mass[c + 1]);
        let cross = (ia * ib).sqrt();
        let scale = 2.0 * (1.5 * self.k[c]).powi(2) / omega_ref.powi(4);
        (scale * (ia + cross).powi(2), scale * (ib + cross).powi(2))
    }

    /// Shortest time scale of the chain (s): the two-body Hertz contact time of
    /// the stiffest, lightest contact at the largest initial relative speed.
    /// Outcomes of a touching chain scale exactly when steps are a fixed
    /// fraction of it. `None` when nothing can ever collide.
    pub fn time_scale(&self) -> Option<f64> {
        let vmax = self.v0.iter().copied().fold(f64::MIN, f64::max);
        let vmin = self.v0.iter().copied().fold(f64::MAX, f64::min);
        // A lifted pendulum ball reaches its swing speed at the bottom.
        let lift = self
            .x0
            .iter()
            .fold(0.0f64, |m, &x| m.max(self.swing_speed(x)));
        let v = vmax - vmin + lift;
        if v.is_nan() || v <= 0.0 || self.k.is_empty() {
            return None;
        }
        (0..self.k.len())
            .map(|c| contact_time(self.reduced_mass(c), self.k[c], v))
            .reduce(f64::min)
    }

    /// Total energy (J) of a state: kinetic, elastic and (pendulum) potential,
    /// m·g·L·(1 − cos(x/L)) = 2·m·g·L·sin²(x/2L) for each body at displacement `x`.
    pub fn energy(&self, v: &[f64], overlap: &[f64], x: &[f64]) -> f64 {
        let kin: f64 = self.mass.iter().zip(v).map(|(m, v)| 0.5 * m * v * v).sum();
        let pot: f64 = if self.is_pendulum() {
            let (g, l) = (self.gravity, self.length);
            self.mass
                .iter()
                .zip(x)
                .map(|(m, x)| 2.0 * m * g * l * (0.5 * x / l).sin().powi(2))
                .sum()
        } else {
            0.0
        };
        let el: f64 = self
            .k
            .iter()
            .zip(overlap)
            .map(|(&k, &d)| super::contact::hertz_energy(k, d))
            .sum();
        kin + el + pot
    }

    /// Overlap of every contact at the start: δ_c = x_c − x_{c+1} − gap_c.
    pub fn initial_overlap(&self) -> Vec<f64> {
        (0..self.k.len()).map(|c| self.overlap0(c)).collect()
    }

    /// Contact c's initial overlap (m; negative: a gap).
    pub fn overlap0(&self, c: usize) -> f64 {
        self.x0[c] - self.x0[c + 1] - self.gap[c]
    }

    /// Displacement of every body from body 0's and the overlaps:
    /// x_{b+1} = x_b − gap_b − δ_b.
    pub fn positions(&self, x0: f64, overlap: &[f64]) -> Vec<f64> {
        let mut x = vec![x0; self.n_bodies()];
        for c in 0..self.k.len() {
            x[c + 1] = x[c] - self.gap[c] - overlap[c];
        }
        x
    }

    pub fn momentum(&self, v: &[f64]) -> f64 {
        self.mass.iter().zip(v).map(|(m, v)| m * v).sum()
    }
}
