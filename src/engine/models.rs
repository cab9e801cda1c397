//! Models to compare the Hertz engine with (`--model`), on a free line:
//!
//! - `hard-sphere`: instantaneous elastic binary collisions, event-driven — the
//!   textbook answer. Collisions are taken in time order; simultaneous ones
//!   (touching balls) from the left, so the impulse ripples down the chain.
//! - `closure`: the seed's section-4 model of a touching chain that separates
//!   all at once: momentum and energy conserved, and the separation speeds
//!   v_{c+1} − v_c proportional to each contact's reduced mass μ_c. With
//!   v_b = v̄ + K·(S_b − A/M), S_b = Σ_{c<b} μ_c, A = Σ m_b·S_b, M = Σ m_b,
//!   v̄ = P/M, momentum holds for every K and energy gives
//!   K² = (2E − P²/M) / Σ m_b·(S_b − A/M)², solved exactly.

use serde::Serialize;

use super::cradle::{End, Run};
use super::Chain;

/// Which physics answers a scene.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Model {
    /// Hertzian contacts, integrated (the engine).
    #[default]
    Hertz,
    HardSphere,
    Closure,
}

impl crate::choice::Choice for Model {
    const ALL: &'static [Self] = &Model::ALL;
    fn name(self) -> &'static str {
        Model::name(self)
    }
}

impl Model {
    pub const ALL: [Model; 3] = [Model::Hertz, Model::HardSphere, Model::Closure];

    pub fn name(self) -> &'static str {
        match self {
            Model::Hertz => "hertz",
            Model::HardSphere => "hard-sphere",
            Model::Closure => "closure",
        }
    }

    /// Why this model cannot answer `chain`, if it cannot.
    pub fn unsupported(self, chain: &Chain) -> Option<String> {
        let name = self.name();
        if self == Model::Hertz {
            return None;
        }
        if chain.needs_terms() {
            return Some(format!(
                "the {name} model is elastic and on a free line: remove [pendulum] and [damping]"
            ));
        }
        if self == Model::Closure && chain.gap.iter().any(|&g| g != 0.0) {
            return Some(
                "the closure model covers touching chains: every gap must be 0".to_string(),
            );
        }
        None
    }
}

/// Most collisions of a hard-sphere run (a chain that never settles is capped).
pub const MAX_COLLISIONS: u64 = 10_000_000;

/// Hard spheres: repeatedly collide the pair that closes its gap first.
pub fn hard_sphere(ch: &Chain) -> Run {
    let nb = ch.n_bodies();
    let mut v = ch.v0.clone();
    let mut gap: Vec<f64> = ch.initial_overlap().iter().map(|d| -d).collect();
    let (mut t, mut n, mut t_first, mut t_last) = (0.0f64, 0u64, None, None);
    let end = loop {
        // The first approaching pair to touch; ties go to the leftmost.
        let mut best: Option<(f64, usize)> = None;
        for c in 0..nb - 1 {
            let r = v[c] - v[c + 1];
            if r > 0.0 {
                let tau = gap[c].max(0.0) / r;
                if best.is_none_or(|(b, _)| tau < b) {
                    best = Some((tau, c));
                }
            }
        }
        let Some((tau, c)) = best else {
            break End::Settled;
        };
        if n >= MAX_COLLISIONS {
            break End::StepCap;
        }
        for (k, g) in gap.iter_mut().enumerate() {
            *g -= (v[k] - v[k + 1]) * tau;
        }
        gap[c] = 0.0;
        t += tau;
        let (m1, m2) = (ch.mass[c], ch.mass[c + 1]);
        let (u1, u2) = (v[c], v[c + 1]);
        v[c] = ((m1 - m2) * u1 + 2.0 * m2 * u2) / (m1 + m2);
        v[c + 1] = ((m2 - m1) * u2 + 2.0 * m1 * u1) / (m1 + m2);
        n += 1;
        t_first.get_or_insert(t);
        t_last = Some(t);
    };
    instant(ch, v, end, n, t, t_first, t_last)
}

/// The seed's simultaneous-separation closure, exactly (see the module doc).
pub fn closure(ch: &Chain) -> Run {
    let nb = ch.n_bodies();
    let m = &ch.mass;
    let big_m: f64 = m.iter().sum();
    let p: f64 = ch.momentum(&ch.v0);
    let e2: f64 = m.iter().zip(&ch.v0).map(|(m, v)| m * v * v).sum();
    let mut s = vec![0.0; nb];
    for c in 0..nb - 1 {
        s[c + 1] = s[c] + m[c] * m[c + 1] / (m[c] + m[c + 1]);
    }
    let a: f64 = m.iter().zip(&s).map(|(m, s)| m * s).sum::<f64>() / big_m;
    let b: f64 = m.iter().zip(&s).map(|(m, s)| m * (s - a) * (s - a)).sum();
    let k = ((e2 - p * p / big_m).max(0.0) / b).sqrt();
    let v = s.iter().map(|s| p / big_m + k * (s - a)).collect();
    instant(ch, v, End::Settled, 0, 0.0, Some(0.0), Some(0.0))
}

fn instant(
    ch: &Chain,
    v: Vec<f64>,
    end: End,
    steps: u64,
    t: f64,
    t_first: Option<f64>,
    t_last: Option<f64>,
) -> Run {
    let nc = ch.k.len();
    Run {
        end,
        v,
        overlap: vec![0.0; nc],
        steps,
        t,
        t_first_contact: t_first,
        t_last_release: t_last,
        max_overlap: 0.0,
        max_overlap_ratio: 0.0,
        x: vec![f64::NAN; nc + 1],
        contacts: steps,
    }
}
