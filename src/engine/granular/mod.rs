//! Long granular chains (docs/SPEC.md §9): up to 10^4 beads between
//! optional walls, at rest or under a static precompression, struck by a
//! striker or driven by a force pulse.
//!
//! The cradle engine (`engine::cradle`) steps every contact onset
//! exactly; in a long chain contacts open and close somewhere every few
//! steps, so this one takes **fixed steps** of a symmetric composition of
//! Verlet substeps ([`super::solver::weights`]), chosen from the tolerance
//! once per run ([`plan`]), and works only on the beads that can move
//! (the window of [`step`]).
//!
//! **State relative to rest.** Contact j (0 ..= n: the left wall, then the
//! pairs (j−1, j), then the right wall) carries the change p_j of its
//! overlap from rest, δ_j = δ0_j + p_j, and its *excess* force
//! e_j = k_j·δ_j^{3/2} − f0_j with f0_j = k_j·δ0_j^{3/2} computed by the same
//! expression. A chain at rest has p = 0, δ_j = δ0_j bit for bit, e = 0:
//! it stays at rest exactly, whatever the stiffnesses (no absolute
//! positions of 10^4 beads, whose differences would not cancel).
//!
//! **Precision.** A run computes in the plan's precision (`Plan::precision`:
//! f64, or [`crate::engine::real::Df64`] pairs of f32 for GPUs without fast
//! f64): the state ([`step::State`]), the constants ([`Consts`]), the step
//! and the observers are generic over [`Real`]; the outcome is f64.

pub mod control;
pub mod history;
pub mod observe;
pub mod run;
#[cfg(target_arch = "x86_64")]
mod simd;
pub mod step;

use super::contact::{contact_time, hertz_energy, hertz_stiffness};
use super::real::Real;
use super::solver::{weights, Solver, StepRule};
use crate::scene::{Precision, Pulse, Record, Scene};

pub use observe::{ChainOutcome, ProbeOutcome, WallOutcome};
pub use run::{run, NoRows, Rows};

/// `damping_split = "auto"` (the default) puts a damped chain's damping at
/// the steps' ends when its [`Beads::damping_strength`] is below this (and
/// its Hunt–Crossley a(e) below [`HC_ENDS_BELOW`]:
/// [`Beads::auto_damping_ends`]), in every substep otherwise (docs/SPEC.md §9, "Damping"). At the ends a
/// step costs 1.0–1.6× the undamped one against 2–5× in the substeps, but
/// its splitting errs ∝ γ·h²: where the damping sets the pace the error
/// control then takes many more steps (a piston into dashpots of strength
/// 1.9: 21× the steps). The chains of results/chains.md whose ends were
/// cheaper are at strengths 0.003–0.11; the one where they were not, at
/// 1.9.
pub const ENDS_BELOW: f64 = 0.25;

/// `damping_split = "auto"` keeps Hunt–Crossley contacts at the steps'
/// ends while their a(e) (`contact::hunt_crossley_a`: their force's part
/// a·k·δ^{3/2} at the closing speed, relative to the spring's) is below
/// this: e > 0.61. The ends were cheaper at a = 0.17 and 0.63 (e = 0.9,
/// 0.7; struck and precompressed chains at tolerances 1e-4 and 1e-6) and
/// 2.1× dearer at a = 1.43 (e = 0.5, the struck chain at 1e-6;
/// results/chains.md, "Hunt–Crossley's χ at the steps' ends").
pub const HC_ENDS_BELOW: f64 = 1.0;

/// The run length (in time scales t_s) of the chain the step rule was
/// fitted on ([`chain_error_model`]): shorter runs are stepped as if this
/// long (their kink errors do not shrink with the run).
pub const FIT_LENGTH: f64 = 82.0;
/// Never fewer steps than this per time scale of the run ([`Beads::time_scale`]).
pub const MIN_STEPS_PER_SCALE: f64 = 20.0;
/// A bead slower than this fraction of the run's velocity scale
/// ([`Beads::v_scale`]), whose acceleration would change its speed by less
/// than that in a step, is at rest for the window ([`Plan::rest`],
/// [`step::State`]'s `shrink`): fourteen orders of magnitude below the
/// velocities' own round-off. Without it a damped chain steps a tail of
/// ~10^-300 m/s (subnormal at its end) 90–180 beads ahead of its wave,
/// which the dashpots' sweeps spread four beads a step (results/chains.md,
/// "Beads at rest to 1e-30").
pub const REST_BELOW: f64 = 1e-30;
/// Leading-pulse detection floor: a velocity peak counts when it is above
/// this fraction of the run's velocity scale ([`Beads::v_scale`]).
pub const PEAK_FLOOR: f64 = 1e-3;
/// A run without `[stop] duration` ends this long after the leading pulse
/// peaked at the far end (the last bead, or the right wall's force), as a
/// fraction of that time.
pub const END_MARGIN: f64 = 0.1;
/// A run without `[stop] duration` whose pulse never reaches the far end is
/// capped at this many times the transit time at the slowest wave speed
/// the chain can carry (`time_cap` status).
pub const TIME_CAP_TRANSITS: f64 = 20.0;

/// A compiled chain of beads (the engine's view of a chain [`Scene`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Beads {
    pub n: usize,
    pub mass: Vec<f64>,
    pub inv_mass: Vec<f64>,
    pub radius: Vec<f64>,
    /// Hertz stiffness of contact j (0 ..= n; 0 for an absent wall).
    pub k: Vec<f64>,
    /// Overlap of contact j at rest: δ0 under precompression, −gap otherwise.
    pub d0: Vec<f64>,
    /// k_j·δ0_j^{3/2}, computed as the force is (0 without precompression).
    pub f0: Vec<f64>,
    /// Static force (N) between the walls.
    pub precompression: f64,
    /// Gravity towards the left wall (m/s²; 0: none): contact j's static
    /// force is then the precompression plus the weight above it.
    pub gravity: f64,
    /// Dashpot γ at each closed contact (N·s/m; 0: none, issue #45).
    pub viscosity: f64,
    /// Air drag on every bead (1/s; 0: none).
    pub air_drag: f64,
    /// Speed of the left wall into the chain (m/s; 0: it stands still).
    pub piston: f64,
    /// Restitution e of every contact (Hunt–Crossley; 1: elastic).
    pub restitution: f64,
    pub left_wall: bool,
    pub right_wall: bool,
    /// Initial velocity of each bead (m/s).
    pub v0: Vec<f64>,
    pub pulse: Option<Pulse>,
    pub record: Option<Record>,
    pub probes: Vec<usize>,
    /// Distance between the centres of beads i and i+1 at rest (m).
    pub spacing: Vec<f64>,
    /// `[stop] duration` (s): the run ends exactly there.
    pub duration: Option<f64>,
}

/// The Hertz force of overlap `d`, δ·√δ as everywhere in the engine; the
/// same values as [`super::contact::hertz_force`], written without a branch
/// so the chain's force loop vectorises.
#[inline(always)]
pub fn hertz<R: Real>(k: R, d: R) -> R {
    let d = d.max(R::zero());
    k * d * d.sqrt()
}

/// What a step reads of a chain, in the precision `R` it runs in
/// (docs/SPEC.md §9): each contact's stiffness, rest overlap, the force
/// there (computed in `R` as the step computes forces, so a chain at rest
/// has zero excess force bit for bit in every precision) and the radius
/// its overlap is measured against; each bead's 1/m; the pulse.
#[derive(Clone, Debug, PartialEq)]
pub struct Consts<R> {
    pub k: Vec<R>,
    pub d0: Vec<R>,
    pub f0: Vec<R>,
    /// [`run::contact_radius`] of each contact.
    pub r: Vec<R>,
    pub inv_mass: Vec<R>,
    pub pulse: Option<PulseConsts<R>>,
    /// The dashpots and air drag of a damped chain ([`Beads::damped`]).
    pub damp: Option<DampConsts<R>>,
    /// The left wall's speed (m/s; 0: it stands still).
    pub piston: R,
    /// The speed below which a bead is at rest for the window ([`Plan::rest`];
    /// 0: only a bead at exact rest).
    pub rest: R,
}

/// What the damping ([`step`]'s `damp` and `damp_end`) reads, in the step's
/// precision (docs/SPEC.md §9, "Damping"). Contact j joins bead a = j − 1
/// and bead b = j (a wall for j = 0 and j = n: infinitely heavy).
#[derive(Clone, Debug, PartialEq)]
pub struct DampConsts<R> {
    /// γ (N·s/m).
    pub gamma: R,
    /// The Hunt–Crossley parameter a(e) of the contacts' restitution e
    /// ([`crate::engine::contact::hunt_crossley_a`]; 0: elastic): a closed
    /// contact's dashpot is then χ·k·δ^{3/2} more, χ = a / its closing
    /// speed ([`step::State::chi`]).
    pub hc: R,
    /// χ of a contact closed at rest (precompressed, under gravity): a / the
    /// velocity scale.
    pub chi_rest: R,
    /// χ of a contact before its first step's end closed: a over the
    /// smallest closing speed χ is taken at (1e-3 of the velocity scale: a
    /// precursor's contact, closing at ~1e-30 m/s, would have a χ that
    /// stiffens its dashpot past any step).
    pub chi_unset: R,
    /// Air drag (1/s).
    pub drag: R,
    /// γ·(1/m_a + 1/m_b) of each contact (1/s): the rate its relative
    /// velocity decays at; 0 without a contact.
    pub beta: Vec<R>,
    /// 1/m_a + 1/m_b (1/kg), and μ = its inverse (kg).
    pub inv_mu: Vec<R>,
    pub mu: Vec<R>,
    /// μ/m_a and μ/m_b: the shares of a change of relative velocity that
    /// beads a and b take (1 for a bead against a wall).
    pub share_a: Vec<R>,
    pub share_b: Vec<R>,
    /// Each bead's mass (kg), for the energy the air drag takes.
    pub mass: Vec<R>,
}

impl<R: Real> DampConsts<R> {
    /// A Hunt–Crossley contact's χ as the dashpots read it from its stored
    /// `chi` (or |chi| where it is rising): `chi_unset` before its first
    /// step's end closed (stored 0). The shader's twin is `chi_of`.
    #[inline(always)]
    pub fn chi_of(&self, chi: R) -> R {
        if chi == R::zero() {
            self.chi_unset
        } else {
            chi
        }
    }

    fn of(b: &Beads) -> DampConsts<R> {
        let n = b.n;
        // 1/m of contact j's beads (0 for a wall).
        let im = |i: Option<usize>| i.map_or(0.0, |i| b.inv_mass[i]);
        let ends = |j: usize| ((j > 0).then(|| j - 1), (j < n).then_some(j));
        let inv_mu: Vec<f64> = (0..=n)
            .map(|j| {
                let (a, z) = ends(j);
                im(a) + im(z)
            })
            .collect();
        // μ/m of one bead: (1/m)/(1/m_a + 1/m_b).
        let share = |j: usize, bead: Option<usize>| im(bead) / inv_mu[j];
        let conv = |x: Vec<f64>| x.into_iter().map(R::of).collect::<Vec<R>>();
        // A per-contact value, 0 where there is no contact (an absent wall).
        let per_contact = |f: &dyn Fn(usize) -> f64| {
            conv(
                (0..=n)
                    .map(|j| if b.k[j] == 0.0 { 0.0 } else { f(j) })
                    .collect(),
            )
        };
        let hc = crate::engine::contact::hunt_crossley_a(b.restitution);
        DampConsts {
            gamma: R::of(b.viscosity),
            hc: R::of(hc),
            chi_rest: R::of(hc / b.v_scale()),
            chi_unset: R::of(hc) / R::of(1e-3 * b.v_scale()),
            drag: R::of(b.air_drag),
            beta: per_contact(&|j| b.viscosity * inv_mu[j]),
            mu: conv(
                inv_mu
                    .iter()
                    .map(|&x| if x > 0.0 { 1.0 / x } else { 0.0 })
                    .collect(),
            ),
            share_a: per_contact(&|j| share(j, ends(j).0)),
            share_b: per_contact(&|j| share(j, ends(j).1)),
            inv_mu: conv(inv_mu),
            mass: conv(b.mass.clone()),
        }
    }
}

/// A half-sine pulse in the step's precision.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PulseConsts<R> {
    pub bead: usize,
    pub force: R,
    /// ω = π/τ.
    pub omega: R,
    /// τ (s).
    pub duration: R,
    /// 1/m of its bead.
    pub inv_mass: R,
    /// A drive's frequency f (Hz; its force is F·sin(2π·f·t),
    /// [`step::push_sin`]); 0 for a half-sine pulse.
    pub cycles: R,
}

impl<R: Real> Consts<R> {
    /// The constants of chain `b`, with `rest` ([`Plan::rest`]: m/s) the
    /// speed below which a bead is at rest for the window.
    pub fn of(b: &Beads, rest: f64) -> Consts<R> {
        let conv = |x: &[f64]| x.iter().map(|&x| R::of(x)).collect::<Vec<R>>();
        let (k, d0) = (conv(&b.k), conv(&b.d0));
        let f0 = k.iter().zip(&d0).map(|(&k, &d)| hertz(k, d)).collect();
        Consts {
            f0,
            k,
            d0,
            r: (0..=b.n)
                .map(|j| R::of(run::contact_radius(b, j)))
                .collect(),
            inv_mass: conv(&b.inv_mass),
            pulse: b.pulse.as_ref().map(|p| PulseConsts {
                bead: p.bead,
                force: R::of(p.force),
                omega: R::of(p.omega()),
                duration: R::of(p.duration),
                inv_mass: R::of(b.inv_mass[p.bead]),
                cycles: R::of(p.frequency),
            }),
            damp: b.damped().then(|| DampConsts::of(b)),
            piston: R::of(b.piston),
            rest: R::of(rest),
        }
    }
}

impl Beads {
    /// Compile a checked chain scene (`scene.chain` is `Some`).
    pub fn from_scene(s: &Scene) -> Beads {
        let setup = s.chain.clone().unwrap_or_default();
        let n = s.n;
        let mut k = vec![0.0; n + 1];
        for j in 1..n {
            k[j] = hertz_stiffness(
                s.radius[j - 1],
                s.young_modulus[j - 1],
                s.poisson_ratio[j - 1],
                s.radius[j],
                s.young_modulus[j],
                s.poisson_ratio[j],
            );
        }
        // Sphere–flat: the wall's radius is infinite (R* = the bead's).
        let wall_k = |w: &crate::scene::Wall, bead: usize| {
            hertz_stiffness(
                s.radius[bead],
                s.young_modulus[bead],
                s.poisson_ratio[bead],
                f64::INFINITY,
                w.young_modulus,
                w.poisson_ratio,
            )
        };
        if let Some(w) = &setup.left_wall {
            k[0] = wall_k(w, 0);
        }
        if let Some(w) = &setup.right_wall {
            k[n] = wall_k(w, n - 1);
        }
        let f = setup.precompression;
        let g = setup.gravity;
        // The static force on contact j: the precompression, plus under
        // gravity the weight of the beads above it (j .. n, towards the
        // right wall), summed from the top down.
        let mut weight_above = vec![0.0; n + 1];
        if g > 0.0 {
            for j in (0..n).rev() {
                weight_above[j] = weight_above[j + 1] + s.mass[j] * g;
            }
        }
        let d0: Vec<f64> = (0..=n)
            .map(|j| {
                let fj = if g > 0.0 { f + weight_above[j] } else { f };
                if k[j] == 0.0 {
                    0.0
                } else if fj > 0.0 {
                    (fj / k[j]).powf(2.0 / 3.0)
                } else if (1..n).contains(&j) {
                    -s.gap[j - 1]
                } else {
                    0.0
                }
            })
            .collect();
        let f0 = (0..=n).map(|j| hertz(k[j], d0[j])).collect();
        let spacing = (0..n - 1)
            .map(|i| s.radius[i] + s.radius[i + 1] - d0[i + 1])
            .collect();
        Beads {
            n,
            inv_mass: s.mass.iter().map(|m| 1.0 / m).collect(),
            mass: s.mass.clone(),
            radius: s.radius.clone(),
            k,
            d0,
            f0,
            precompression: f,
            gravity: g,
            viscosity: setup.viscosity,
            air_drag: setup.air_drag,
            piston: setup.piston,
            restitution: setup.restitution(),
            left_wall: setup.left_wall.is_some(),
            right_wall: setup.right_wall.is_some(),
            v0: s.velocity.clone(),
            pulse: setup.pulse,
            record: setup.record,
            probes: setup.probes,
            spacing,
            duration: s.duration,
        }
    }

    /// Whether the chain dissipates (a dashpot, Hunt–Crossley contacts or
    /// air drag, issue #45).
    pub fn damped(&self) -> bool {
        crate::scene::dissipates(self.viscosity, self.air_drag, self.restitution)
    }

    /// Whether the local refinement may run on this chain ([`Plan::refine`]):
    /// not on a damped one (its redone regions have no damping) nor
    /// one with a piston (a redone region would move bead 0 past the
    /// piston's account of its impulse).
    pub fn refinable(&self) -> bool {
        !self.damped() && self.piston == 0.0
    }

    /// The speed every velocity error is relative to (m/s): the largest
    /// initial speed (a piston's among them), or the speed the pulse's
    /// impulse 2Fτ/π gives its bead.
    pub fn v_scale(&self) -> f64 {
        let v = self.v0.iter().fold(self.piston, |m, v| m.max(v.abs()));
        let p = self.pulse.as_ref().map_or(0.0, |p| {
            if p.is_drive() {
                // A free bead driven at ω swings at F/(m·ω).
                p.force.abs() / p.omega() * self.inv_mass[p.bead]
            } else {
                2.0 * p.force.abs() * p.duration / std::f64::consts::PI * self.inv_mass[p.bead]
            }
        });
        v.max(p)
    }

    /// Linear stiffness K = (3/2)·k·√δ0 of contact j under precompression (N/m).
    pub fn linear_stiffness(&self, j: usize) -> f64 {
        1.5 * self.k[j] * self.d0[j].max(0.0).sqrt()
    }

    /// The shortest time scale of the run (s): [`Beads::elastic_time_scale`],
    /// or the damping's if shorter.
    pub fn time_scale(&self) -> f64 {
        let t = self.elastic_time_scale();
        match self.damping_rate() {
            Some(rate) => t.min(1.0 / rate),
            None => t,
        }
    }

    /// The fastest decay rate of the dashpots and the air drag (1/s):
    /// 2γ/m_min (a contact's relative velocity decays at γ·(1/m_a + 1/m_b))
    /// or the drag's c; `None` without either.
    fn damping_rate(&self) -> Option<f64> {
        (self.viscosity > 0.0 || self.air_drag > 0.0).then(|| {
            let m_min = self.mass.iter().fold(f64::INFINITY, |m, &x| m.min(x));
            (2.0 * self.viscosity / m_min).max(self.air_drag)
        })
    }

    /// How strong the dashpots and the air drag are on the chain's own
    /// time scale ([`Beads::elastic_time_scale`] t_s): their fastest rate
    /// times t_s (0 without them).
    pub fn damping_strength(&self) -> f64 {
        self.damping_rate()
            .map_or(0.0, |rate| rate * self.elastic_time_scale())
    }

    /// Where `damping_split = "auto"` puts a damped chain's damping: at the
    /// steps' ends (true) when its [`Beads::damping_strength`] is below
    /// [`ENDS_BELOW`] and its Hunt–Crossley a(e) below [`HC_ENDS_BELOW`],
    /// else in every substep (docs/SPEC.md §9, "Damping").
    pub fn auto_damping_ends(&self) -> bool {
        self.damping_strength() < ENDS_BELOW
            && crate::engine::contact::hunt_crossley_a(self.restitution) < HC_ENDS_BELOW
    }

    /// The shortest time scale of the conservative chain (s): the two-body
    /// contact time of the stiffest, lightest contact at the velocity
    /// scale; under precompression also 1/ω_max of the linearised chain
    /// (Gershgorin: ω² ≤ max_i (K_i + K_{i+1})·2/m_i); with a pulse also
    /// τ/π.
    pub fn elastic_time_scale(&self) -> f64 {
        let v = self.v_scale();
        let mut t = f64::INFINITY;
        for j in 0..=self.n {
            if self.k[j] == 0.0 {
                continue;
            }
            let mu = match j {
                0 => self.mass[0],
                j if j == self.n => self.mass[j - 1],
                j => self.mass[j - 1] * self.mass[j] / (self.mass[j - 1] + self.mass[j]),
            };
            if v > 0.0 {
                t = t.min(contact_time(mu, self.k[j], v));
            }
        }
        if self.precompression > 0.0 || self.gravity > 0.0 {
            for i in 0..self.n {
                let w2 = 2.0
                    * (self.linear_stiffness(i) + self.linear_stiffness(i + 1))
                    * self.inv_mass[i];
                t = t.min(1.0 / w2.sqrt());
            }
        }
        if let Some(p) = &self.pulse {
            // τ/π for a pulse, 1/ω for a drive.
            t = t.min(if p.is_drive() {
                1.0 / p.omega()
            } else {
                p.duration / std::f64::consts::PI
            });
        }
        t
    }

    /// Length of the chain between the first and last bead's centres (m).
    pub fn length(&self) -> f64 {
        self.spacing.iter().sum()
    }

    /// Distance between the centres of beads `a` < `b` at rest (m).
    pub fn distance(&self, a: usize, b: usize) -> f64 {
        self.spacing[a..b].iter().sum()
    }

    /// The slowest wave the chain carries for bead speeds `v` (m/s): the
    /// linear sound speed under precompression, else Nesterenko's
    /// solitary-wave speed ([`nesterenko_speed`]) of the softest, heaviest
    /// bead pair (under gravity the faster of the two at each pair).
    pub fn wave_speed(&self, v: f64) -> f64 {
        let mut c = f64::INFINITY;
        for i in 0..self.n - 1 {
            let j = i + 1;
            let m = self.mass[i].max(self.mass[j]);
            let a = self.spacing[i];
            let speed = if self.gravity > 0.0 {
                // Loaded by the weight above, least near the top: the
                // faster of the linear and the solitary wave.
                (a * (self.linear_stiffness(j) / m).sqrt())
                    .max(nesterenko_speed(self.k[j], m, a, v))
            } else if self.precompression > 0.0 {
                a * (self.linear_stiffness(j) / m).sqrt()
            } else {
                nesterenko_speed(self.k[j], m, a, v)
            };
            c = c.min(speed);
        }
        c
    }

    /// The run's length for the step rule (s): `[stop] duration`, else the
    /// default end's (the chain's length at the wave speed of the velocity
    /// scale, plus [`END_MARGIN`]).
    pub fn run_length(&self) -> f64 {
        self.duration
            .unwrap_or_else(|| self.length() / self.wave_speed(self.v_scale()) * (1.0 + END_MARGIN))
    }

    /// Total energy (J) relative to rest: kinetic, plus each contact's
    /// elastic energy U(δ) − U(δ0) − f0·(δ − δ0) ([`excess_energy`]); with
    /// both walls fixed the f0 terms sum to zero, and under gravity to the
    /// beads' potential energy Σ m·g·u (u: a bead's displacement from
    /// rest, away from the floor), so this is conserved.
    pub fn energy(&self, p: &[f64], v: &[f64]) -> f64 {
        let kin: f64 = self.mass.iter().zip(v).map(|(m, v)| 0.5 * m * v * v).sum();
        let el: f64 = (0..=self.n)
            .map(|j| excess_energy(self.k[j], self.d0[j], p[j]))
            .sum();
        kin + el
    }
}

/// U(δ0+p) − U(δ0) − k·δ0^{3/2}·p with U(δ) = (2/5)·k·δ^{5/2}⁺, written
/// without cancellation: for δ, δ0 > 0 and a = √δ, b = √δ0 it is
/// k·(a−b)²·(0.4a³ + 0.8a²b + 1.2ab² + 0.6b³), a − b = p/(a+b).
pub fn excess_energy(k: f64, d0: f64, p: f64) -> f64 {
    if k == 0.0 {
        return 0.0;
    }
    let d = d0 + p;
    if d0 <= 0.0 {
        return hertz_energy(k, d);
    }
    let b = d0.sqrt();
    if d <= 0.0 {
        // Opened: −U(δ0) − f0·p with f0 = k·b³.
        return 0.6 * k * d0 * d0 * b - k * d0 * b * d;
    }
    let a = d.sqrt();
    let amb = p / (a + b);
    k * amb * amb * (0.4 * a * a * a + 0.8 * a * a * b + 1.2 * a * b * b + 0.6 * b * b * b)
}

/// Nesterenko's long-wave solitary-wave speed V = (16/25)^{1/5}·c^{4/5}·v_m^{1/5}
/// for the largest bead velocity `v_m` in the wave, c² = k·a^{5/2}/m
/// (`a` the bead spacing; for equal spheres c² = 2E/(πρ(1−ν²))).
pub fn nesterenko_speed(k: f64, m: f64, a: f64, v_m: f64) -> f64 {
    let c = (k * a.powf(2.5) / m).sqrt();
    (16.0f64 / 25.0).powf(0.2) * c.powf(0.8) * v_m.powf(0.2)
}

/// What a chain run accepts of a resolved solver: the hertz model (the
/// comparison models are for cradles) in f64 or df64 (f32's 24 bits cannot
/// carry a wave over 10^5–10^6 steps to any useful tolerance): anything
/// else is refused, never silently replaced.
pub fn check_solver(solver: &Solver) -> Result<(), crate::error::InputError> {
    if solver.model != crate::engine::Model::Hertz {
        return Err(crate::error::flag(
            "--model",
            solver.model.name(),
            "hertz for a granular chain (the comparison models are for cradles)",
        ));
    }
    if solver.precision == Precision::F32 {
        return Err(crate::error::flag(
            "--precision",
            solver.precision.name(),
            "f64 or df64 for a granular chain (f32 cannot carry a wave over a long run; a scene's [solver] precision counts too)",
        ));
    }
    Ok(())
}

/// Why `plan` cannot be run: its step is not a positive normal number (a
/// velocity, force or stiffness so large, or a mass so small, that the
/// chain's time scale underflows: the run would never advance and only meet
/// the step cap). `None`: it can.
pub fn unrunnable(plan: &Plan) -> Option<String> {
    (!(plan.h.is_normal() && plan.h > 0.0)).then(|| {
        format!(
            "its step would be {:e} s (the chain's time scale underflows: an extreme velocity, force, stiffness or mass); such a chain never advances",
            plan.h
        )
    })
}

/// The step, substep weights and end of one chain run.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// The step (s).
    pub h: f64,
    pub weights: &'static [f64],
    /// Kick weights at the drift positions when contacts that open or close
    /// inside a step get the kink correction ([`step::Substeps`]): methods
    /// above order 2, as in the cradle engine. `None`: no correction.
    pub kicks: Option<Vec<f64>>,
    /// The local refinement around contacts near a crossing
    /// ([`step::Refine`]): for the methods with a [`refined_error_model`]
    /// at steps of t_s/[`REFINE_FROM`] and finer (needs `kicks`).
    pub refine: Option<step::Refine>,
    /// `[stop] duration`, if given: the run ends exactly there.
    pub duration: Option<f64>,
    /// Without a duration: the time cap (s).
    pub max_time: f64,
    pub max_steps: u64,
    /// Trace row spacing (s): a whole number of steps.
    pub every: Option<f64>,
    /// What the step computes in: f64, or df64 (pairs of f32, the GPU's
    /// choice where f64 is slow or missing).
    pub precision: Precision,
    /// The method (its substeps are `weights`).
    pub method: crate::scene::Method,
    /// The tolerance the run is to meet ([`control`]); `None`: a given step.
    pub tolerance: Option<f64>,
    /// A damped chain's damping once a step, at its ends, not in every
    /// substep ([`step::Substeps::ends`]).
    pub damping_ends: bool,
    /// Ends the run early when requested (its outcome then not the
    /// scene's: [`crate::engine::Stop`]).
    pub stop: crate::engine::Stop,
    /// Counts the bead-steps this run takes ([`crate::engine::Tally`]).
    pub tally: crate::engine::Tally,
    /// The speed (m/s) below which a bead whose acceleration would change
    /// its speed by less in a step is at rest for the window:
    /// [`REST_BELOW`] × [`Beads::v_scale`]. Such a bead keeps its speed
    /// unstepped until the window reaches it again. 0: only beads at exact
    /// rest wait, and the window changes no bit of a run (test
    /// `skipping_beads_at_rest_changes_no_bit`).
    pub rest: f64,
}

impl Plan {
    /// What a step of this plan does ([`step::step`]).
    pub fn substeps(&self) -> step::Substeps<'_> {
        step::Substeps {
            weights: self.weights,
            kicks: self.kicks.as_deref(),
            refine: self.refine.filter(|_| self.kicks.is_some()),
            ends: self.damping_ends,
        }
    }
}

/// Error model of each method on a chain's outcomes without the local
/// refinement (docs/SPEC.md §9): error ≈ C·(h/t_s)^q·(T/t_s) relative to
/// the velocity scale, t_s = [`Beads::time_scale`], T the run's length
/// ([`Beads::run_length`]): a travelling wave's phase error grows with the
/// time it travels. Fitted by `scripts/chain_error_fit.py` on uniform steel
/// chains struck at one end (R = 5 mm, 0.1 m/s) of 200 and 1,000 beads,
/// run while the wave is in the chain (T = 82 and 408 t_s; the worst of the
/// probes' peak times and values and every bead's final velocity, against
/// kahanli6 at t_s/16000) at 36 steps from t_s/20 to t_s/2560 — for the
/// methods the refinement is for ([`refined_error_model`]) the 11 coarser
/// than t_s/[`REFINE_FROM`], where this model applies: q by least squares
/// over both chains, C the envelope of every point (error/T ≤ C·(h/t_s)^q)
/// times a margin of 3 (verlet's, fitted before the kink correction and
/// unchanged: 2.3); errors below 1e-10, f64's round-off over millions of
/// steps rather than the step's, are left out. Contacts open and close
/// inside steps; with the kink correction ([`step::Substeps`]) the methods
/// above order 2 keep more of their order (kahanli6 fell as h^1.6 without
/// it), and a kink's error depends on where in its step the contact
/// crosses: the errors scatter up to ~10× about the trend, which the
/// envelope covers.
pub fn chain_error_model(m: crate::scene::Method) -> (f64, f64) {
    use crate::scene::Method::*;
    match m {
        Verlet => (0.8, 2.0),
        Yoshida4 => (11.7, 3.52),
        Suzuki4 => (0.199, 3.63),
        Yoshida6 => (0.0146, 2.87),
        KahanLi6 => (0.00412, 3.13),
    }
}

/// Steps per time scale from which the local refinement is on
/// ([`step::Refine`]): at coarser steps the decaying tail behind a solitary
/// wave has contacts near a crossing in every step (a region of 6–20 beads
/// redone each step; with the first, cubic, boundary interpolant 3–5× the
/// step's cost for no gain); from here on regions are rare on uniform
/// chains (< 0.1 per step) and the error falls at the method's order.
pub const REFINE_FROM: f64 = 90.0;

/// [`chain_error_model`] with the local refinement (h ≤ t_s/[`REFINE_FROM`];
/// docs/SPEC.md §9): (C, q), fitted as `chain_error_model` is, on the 25
/// steps where the refinement is on, errors below 5e-11 (where the
/// 1,000-bead chain's level off: round-off over its 10^5–10^6 steps) left
/// out (results/chain_error_fit.md). `None`: the method runs without it.
pub fn refined_error_model(m: crate::scene::Method) -> Option<(f64, f64)> {
    use crate::scene::Method::*;
    match m {
        // Yoshida4's error is its smooth part's (C is 10^3 times the
        // others'), and the refinement raised it; yoshida6's is dominated by
        // spikes at some steps (as built too), which leave a refined fit at
        // q ~ 1: both run without (results/chain_error_fit.md).
        Verlet | Yoshida4 | Yoshida6 => None,
        Suzuki4 => Some((0.00193, 2.71)),
        KahanLi6 => Some((13.0, 6.20)),
    }
}

/// The fixed step of a chain run (docs/SPEC.md §9): under a tolerance,
/// h = t_s·(tol/C)^{1/q} with the method's error model (C, q) of
/// [`chain_error_model`] and t_s = [`Beads::time_scale`], at most t_s/20;
/// where that is finer than t_s/[`REFINE_FROM`] and the method has a
/// [`refined_error_model`], h from that model instead, at most
/// t_s/`REFINE_FROM`, with the local refinement on ([`Plan::refine`]). A
/// given `dt` as is (the refinement on from t_s/`REFINE_FROM` down). A
/// pulse that ends within the run ends on a step
/// boundary (the step shrinks to τ/⌈τ/h⌉): its force's kink at τ is then
/// never inside a step ([`step::pulse_on`]), and the methods keep their
/// orders (kahanli6: 6, against 2 with τ inside a step). A trace's row
/// spacing `every` is made a whole number of steps (the step shrinks to
/// every/k), so rows fall on steps; with a pulse too, the smallest k from
/// ⌈every/h⌉ to 4·⌈every/h⌉ (at most 10^4 tried) that keeps τ on a boundary
/// as well, if there is one (else the rows win).
pub fn plan(beads: &Beads, solver: &Solver, every: Option<f64>) -> Plan {
    let (h, tolerance) = match solver.step {
        StepRule::Dt(dt) => (dt, None),
        StepRule::Tolerance(tol) => (first_step(beads, solver.method, tol), Some(tol)),
    };
    let h = h * solver.step_factor;
    let max_time = beads.duration.unwrap_or_else(|| {
        solver
            .max_time
            .min(TIME_CAP_TRANSITS * beads.length() / beads.wave_speed(0.01 * beads.v_scale()))
    });
    let kicks = (solver.method.order() > 2)
        .then(|| crate::engine::cradle::kick_weights(weights(solver.method)));
    let p = Plan {
        h,
        method: solver.method,
        weights: weights(solver.method),
        refine: None,
        kicks,
        duration: beads.duration,
        max_time,
        max_steps: solver.max_steps,
        every,
        precision: solver.precision,
        tolerance,
        damping_ends: beads.damped()
            && solver
                .damping_ends
                .unwrap_or_else(|| beads.auto_damping_ends()),
        stop: crate::engine::Stop::default(),
        tally: crate::engine::Tally::default(),
        rest: REST_BELOW * beads.v_scale(),
    };
    p.with_step(beads, h, false)
}

/// The step the fitted error models give for tolerance `tol` (the first
/// guess of the error control, [`control`]): h = t_s·(tol/C)^{1/q} with the
/// method's [`chain_error_model`], at most t_s/20; where that is finer than
/// t_s/[`REFINE_FROM`] and the method has a [`refined_error_model`], that
/// model's step instead, at most t_s/`REFINE_FROM`.
pub fn first_step(beads: &Beads, method: crate::scene::Method, tol: f64) -> f64 {
    let ts = beads.time_scale();
    let fine = ts / REFINE_FROM;
    let tol = tol / (beads.run_length() / ts).max(FIT_LENGTH);
    let at = |(c, q): (f64, f64)| ts * (tol / c).powf(1.0 / q);
    let coarse = at(chain_error_model(method)).min(ts / MIN_STEPS_PER_SCALE);
    match refined_error_model(method)
        .filter(|_| beads.refinable())
        .map(at)
    {
        // Refined steps meet the tolerance from some step at or below
        // t_s/REFINE_FROM (at most that step), and coarse ones need finer
        // than that: refine.
        Some(h) if coarse < fine => h.min(fine),
        _ => coarse,
    }
}

impl Plan {
    /// This plan with step `h` (before the alignments below), the local
    /// refinement on for the methods that have one at steps of
    /// t_s/[`REFINE_FROM`] and finer, or at any step if `refine`: a pulse that
    /// ends within the run ends on a step boundary, trace rows fall on
    /// steps ([`plan`]).
    pub fn with_step(mut self, beads: &Beads, mut h: f64, refine: bool) -> Plan {
        // τ, when the pulse ends before the run does.
        let kink = beads
            .pulse
            .as_ref()
            .map(|p| p.duration)
            .filter(|&tau| self.duration.is_none_or(|d| tau < d));
        // ⌈x⌉, x within a relative 1e-12 above a whole number taken as it:
        // a step already aligned (x/k) aligns to itself, bit for bit.
        let up = |x: f64| (x * (1.0 - 1e-12)).ceil();
        let on_boundary = |h: f64, tau: f64| {
            let n = tau / h;
            (n - n.round()).abs() <= 1e-9 * n.max(1.0)
        };
        match (self.every, kink) {
            (Some(e), Some(tau)) => {
                // At most 10^4 candidates: a search, not a hang, when every ≫ h.
                let k0 = up(e / h);
                let k = (0..=(3.0 * k0).min(1e4) as u64)
                    .map(|j| k0 + j as f64)
                    .find(|&k| on_boundary(e / k, tau))
                    .unwrap_or(k0);
                h = e / k;
            }
            (Some(e), None) => h = e / up(e / h),
            (None, Some(tau)) => h = tau / up(tau / h),
            (None, None) => {}
        }
        self.h = h;
        let fine = beads.time_scale() / REFINE_FROM;
        let on = (refine || h <= fine) && beads.refinable();
        self.refine = (on && refined_error_model(self.method).is_some()).then(|| step::Refine {
            reach: step::REFINE_REACH,
            steps: step::REFINE_STEPS,
            near: step::REFINE_NEAR,
            floor: step::REFINE_FLOOR * beads.v_scale() * beads.time_scale(),
        });
        self
    }

    /// A run of the same chain with step `h` (aligned as [`plan`] aligns
    /// it) that ends at `t_end` exactly: the error control's twins and
    /// reruns ([`control`]).
    pub fn rerun(&self, beads: &Beads, h: f64, t_end: f64, refine: bool) -> Plan {
        let mut p = self.clone();
        p.duration = Some(t_end);
        p.max_time = t_end;
        p.with_step(beads, h, refine)
    }
}
