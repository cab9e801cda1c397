//! The scene file as written (docs/SPEC.md §4): parsed from TOML with serde, not yet
//! checked. A sweep edits a [`SceneSpec`] (`mass[2] = …`) before it is
//! validated into a [`super::Scene`].

use std::collections::BTreeMap;
use std::fmt;

use serde::{Deserialize, Serialize};
use toml::Spanned;

use crate::error::{InputError, Source};

/// A per-ball quantity: one value for every ball, or an array of N.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum PerBall {
    Scalar(f64),
    List(Vec<f64>),
}

impl PerBall {
    /// Set the whole quantity (`index = None`) or one element, broadcasting a
    /// scalar to `n` elements first.
    pub fn set(&mut self, index: Option<usize>, value: f64, n: usize) {
        match index {
            None => *self = PerBall::Scalar(value),
            Some(i) => {
                if let PerBall::Scalar(s) = *self {
                    *self = PerBall::List(vec![s; n]);
                }
                if let PerBall::List(v) = self {
                    if v.len() <= i {
                        v.resize(i + 1, f64::NAN);
                    }
                    v[i] = value;
                }
            }
        }
    }
}

impl fmt::Display for PerBall {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PerBall::Scalar(x) => write!(f, "{x}"),
            PerBall::List(v) => write!(f, "{v:?}"),
        }
    }
}

impl<'de> Deserialize<'de> for PerBall {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = PerBall;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or an array of numbers")
            }
            fn visit_f64<E>(self, x: f64) -> Result<PerBall, E> {
                Ok(PerBall::Scalar(x))
            }
            fn visit_i64<E>(self, x: i64) -> Result<PerBall, E> {
                Ok(PerBall::Scalar(x as f64))
            }
            fn visit_u64<E>(self, x: u64) -> Result<PerBall, E> {
                Ok(PerBall::Scalar(x as f64))
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut s: A,
            ) -> Result<PerBall, A::Error> {
                let mut v = Vec::new();
                while let Some(x) = s.next_element::<f64>()? {
                    v.push(x);
                }
                Ok(PerBall::List(v))
            }
        }
        d.deserialize_any(V)
    }
}

/// `[launch]`: the `balls` leftmost balls start with `velocity`, or with
/// √(2·g·height) (the speed at impact after falling from `height`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaunchSpec {
    pub balls: Option<i64>,
    pub height: Option<f64>,
    pub velocity: Option<f64>,
}

/// `[pendulum]`: string length (m) and gravity (m/s², default 9.80665).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PendulumSpec {
    pub length: Option<f64>,
    pub gravity: Option<f64>,
}

/// `[damping]`: coefficient of restitution and linear air drag (1/s); on a
/// granular chain also a dashpot at each contact (`viscosity`, N·s/m).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DampingSpec {
    pub restitution: Option<f64>,
    pub air_drag: Option<f64>,
    pub viscosity: Option<f64>,
}

/// `[stop]`: simulated duration (s) and the step cap.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StopSpec {
    pub duration: Option<f64>,
    pub max_steps: Option<i64>,
}

/// `[solver]`: method, and either a fixed `dt` (s) or a `tolerance` on the
/// outcome velocities relative to v_in; `precision` = "f32" | "f64" | "df64";
/// `damping_split` = "auto" | "substeps" | "ends" (a damped chain's damping
/// chosen per chain, in every substep, or once a step at its ends;
/// docs/SPEC.md §9, "Damping").
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverSpec {
    pub method: Option<String>,
    pub dt: Option<f64>,
    pub tolerance: Option<f64>,
    pub precision: Option<String>,
    pub damping_split: Option<String>,
}

/// `[walls]`: fixed flat walls at the ends of a chain and the static force
/// that squeezes it (docs/SPEC.md §9).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WallsSpec {
    pub left: Option<bool>,
    pub right: Option<bool>,
    pub young_modulus: Option<f64>,
    pub poisson_ratio: Option<f64>,
    pub precompression: Option<f64>,
}

/// `[gravity]`: a vertical chain (docs/SPEC.md §9): `g` (m/s², default
/// 9.80665) pulls every bead towards the left wall, the floor.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GravitySpec {
    pub g: Option<f64>,
}

/// `[piston]`: the left wall moves into the chain at `velocity` (m/s)
/// from t = 0 (issue #45).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PistonSpec {
    pub velocity: Option<f64>,
}

/// `[drive]`: a harmonic force F·sin(2π·f·t) (N) on one bead for
/// 0 ≤ t < `duration` (s; default: the whole run) (issue #45).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveSpec {
    pub bead: Option<i64>,
    pub force: Option<f64>,
    pub frequency: Option<f64>,
    pub duration: Option<f64>,
}

/// `[pulse]`: a half-sine force (N) on one bead for `duration` (s).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PulseSpec {
    pub bead: Option<i64>,
    pub force: Option<f64>,
    pub duration: Option<f64>,
}

/// `[record]`: the beads whose histories `cradle run --trace` writes, and
/// the spacing of its rows (s).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordSpec {
    pub beads: Option<Vec<i64>>,
    /// Instead of `beads`: every `stride`-th bead from bead 0, and the last.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stride: Option<i64>,
    pub every: Option<f64>,
}

/// `[probes]`: the beads whose pulse arrival, peak velocity and peak force
/// are outcome columns.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbesSpec {
    pub beads: Option<Vec<i64>>,
}

/// `[pattern]`: per-bead values repeated along the chain (a dimer:
/// `radius = [0.005, 0.0035]`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PatternSpec {
    pub radius: Option<Vec<f64>>,
    pub density: Option<Vec<f64>>,
    pub mass: Option<Vec<f64>>,
    pub young_modulus: Option<Vec<f64>>,
    pub poisson_ratio: Option<Vec<f64>>,
}

/// `[taper]`: radii shrinking along the chain, by a ratio
/// (radius_{i+1} = (1−q)·radius_i) or linearly (radius_i = radius_0·(1 − q·i)).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TaperSpec {
    pub ratio: Option<f64>,
    pub kind: Option<String>,
}

/// `[impurity]`: beads with their own radius, mass (or density) and material.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImpuritySpec {
    pub beads: Option<Vec<i64>>,
    pub radius: Option<f64>,
    pub density: Option<f64>,
    pub mass: Option<f64>,
    pub young_modulus: Option<f64>,
    pub poisson_ratio: Option<f64>,
}

/// The scene table exactly as serde reads it, with spans.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawScene {
    description: Option<String>,
    balls: Option<Spanned<i64>>,
    radius: Option<Spanned<PerBall>>,
    density: Option<Spanned<PerBall>>,
    mass: Option<Spanned<PerBall>>,
    young_modulus: Option<Spanned<PerBall>>,
    poisson_ratio: Option<Spanned<PerBall>>,
    gap: Option<Spanned<PerBall>>,
    glue: Option<Spanned<String>>,
    velocity: Option<Spanned<PerBall>>,
    launch: Option<Spanned<LaunchSpec>>,
    pendulum: Option<Spanned<PendulumSpec>>,
    damping: Option<Spanned<DampingSpec>>,
    stop: Option<Spanned<StopSpec>>,
    solver: Option<Spanned<SolverSpec>>,
    walls: Option<Spanned<WallsSpec>>,
    pulse: Option<Spanned<PulseSpec>>,
    record: Option<Spanned<RecordSpec>>,
    probes: Option<Spanned<ProbesSpec>>,
    pattern: Option<Spanned<PatternSpec>>,
    taper: Option<Spanned<TaperSpec>>,
    impurity: Option<Spanned<ImpuritySpec>>,
    gravity: Option<Spanned<GravitySpec>>,
    piston: Option<Spanned<PistonSpec>>,
    drive: Option<Spanned<DriveSpec>>,
}

/// A scene as written: every key optional until [`SceneSpec::validate`].
/// `lines` remembers where each key came from, for error messages.
#[derive(Clone, Debug, Default, Serialize)]
pub struct SceneSpec {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    pub balls: Option<i64>,
    pub radius: Option<PerBall>,
    pub density: Option<PerBall>,
    pub mass: Option<PerBall>,
    pub young_modulus: Option<PerBall>,
    pub poisson_ratio: Option<PerBall>,
    pub gap: Option<PerBall>,
    pub glue: Option<String>,
    pub velocity: Option<PerBall>,
    pub launch: Option<LaunchSpec>,
    pub pendulum: Option<PendulumSpec>,
    pub damping: Option<DampingSpec>,
    pub stop: Option<StopSpec>,
    pub solver: Option<SolverSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub walls: Option<WallsSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pulse: Option<PulseSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub record: Option<RecordSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub probes: Option<ProbesSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pattern: Option<PatternSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub taper: Option<TaperSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub impurity: Option<ImpuritySpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gravity: Option<GravitySpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub piston: Option<PistonSpec>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub drive: Option<DriveSpec>,
    /// Where the scene came from (a path, or `built-in scene NAME`).
    #[serde(skip)]
    pub origin: String,
    /// Line of each top-level key in `origin`.
    #[serde(skip)]
    pub lines: BTreeMap<&'static str, usize>,
}

fn take<T>(
    src: &Source,
    lines: &mut BTreeMap<&'static str, usize>,
    key: &'static str,
    v: Option<Spanned<T>>,
) -> Option<T> {
    v.map(|s| {
        lines.insert(key, src.line(s.span().start));
        s.into_inner()
    })
}

impl SceneSpec {
    /// Parse a scene document. Syntax errors, wrong types and unknown keys
    /// are reported here; physical checks happen in [`SceneSpec::validate`].
    pub fn parse(src: &Source) -> Result<Self, InputError> {
        let raw: RawScene = src.parse_toml()?;
        Self::from_raw(src, raw)
    }

    pub(crate) fn from_raw(src: &Source, r: RawScene) -> Result<Self, InputError> {
        let mut l = BTreeMap::new();
        Ok(SceneSpec {
            description: r.description,
            balls: take(src, &mut l, "balls", r.balls),
            radius: take(src, &mut l, "radius", r.radius),
            density: take(src, &mut l, "density", r.density),
            mass: take(src, &mut l, "mass", r.mass),
            young_modulus: take(src, &mut l, "young_modulus", r.young_modulus),
            poisson_ratio: take(src, &mut l, "poisson_ratio", r.poisson_ratio),
            gap: take(src, &mut l, "gap", r.gap),
            glue: take(src, &mut l, "glue", r.glue),
            velocity: take(src, &mut l, "velocity", r.velocity),
            launch: take(src, &mut l, "launch", r.launch),
            pendulum: take(src, &mut l, "pendulum", r.pendulum),
            damping: take(src, &mut l, "damping", r.damping),
            stop: take(src, &mut l, "stop", r.stop),
            solver: take(src, &mut l, "solver", r.solver),
            walls: take(src, &mut l, "walls", r.walls),
            pulse: take(src, &mut l, "pulse", r.pulse),
            record: take(src, &mut l, "record", r.record),
            probes: take(src, &mut l, "probes", r.probes),
            pattern: take(src, &mut l, "pattern", r.pattern),
            taper: take(src, &mut l, "taper", r.taper),
            impurity: take(src, &mut l, "impurity", r.impurity),
            gravity: take(src, &mut l, "gravity", r.gravity),
            piston: take(src, &mut l, "piston", r.piston),
            drive: take(src, &mut l, "drive", r.drive),
            origin: src.name.clone(),
            lines: l,
        })
    }

    /// Line of a key (by its top-level name: `mass[2]` → `mass`).
    pub fn line_of(&self, key: &str) -> Option<usize> {
        let top = key.split(['[', '.']).next().unwrap_or(key);
        self.lines.get(top).copied()
    }
}
