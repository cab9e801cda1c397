//! Scenes: one cradle, as written ([`SceneSpec`]) and as checked ([`Scene`]).
//!
//! Data flow: scene TOML → [`SceneSpec`] (serde) → [`Scene`] (validated, SI,
//! one value per ball) → [`crate::engine::Chain`] (rigid bodies) → backend.

pub mod builtin;
mod check;
mod granular;
pub(crate) mod spec;
mod validate;

pub use spec::{
    DampingSpec, ImpuritySpec, LaunchSpec, PatternSpec, PendulumSpec, PerBall, ProbesSpec,
    PulseSpec, RecordSpec, SceneSpec, SolverSpec, StopSpec, TaperSpec, WallsSpec,
};

use std::path::Path;

use serde::Serialize;

use crate::choice::Choice;
use crate::error::{InputError, Source};

/// Defaults of docs/SPEC.md §2: steel balls of 25 mm diameter.
pub const DEFAULT_RADIUS: f64 = 0.0125;
pub const DEFAULT_DENSITY: f64 = 7850.0;
pub const DEFAULT_YOUNG: f64 = 200e9;
pub const DEFAULT_POISSON: f64 = 0.3;
/// Standard gravity (m/s²), used for `[launch] height` without a pendulum.
pub const STANDARD_GRAVITY: f64 = 9.80665;
/// Cradles (the rigid-body engine: glue, pendulum, damping, exact onsets)
/// have at most this many balls (the GPU keeps a cradle in registers).
/// Longer scenes are granular chains ([`ChainSetup`]).
pub const MAX_BALLS: usize = 64;
/// Longest granular chain (beads).
pub const MAX_CHAIN: usize = 10_000;
/// A taper may not shrink a bead below this fraction of the first bead's radius.
pub const MIN_TAPER_FRACTION: f64 = 1e-6;

/// Integration methods (`--method`, `[solver] method`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Velocity Verlet (kick-drift-kick), order 2, symplectic.
    Verlet,
    /// Yoshida's triple jump: 3 Verlet substeps, order 4, graded near contact kinks.
    Yoshida4,
    /// Suzuki's fractal: 5 Verlet substeps, order 4 with a smaller error
    /// constant, graded near contact kinks.
    Suzuki4,
    /// Yoshida's 7-substep composition (solution A), order 6, graded near kinks.
    Yoshida6,
    /// Kahan and Li's 9-substep composition (s9odr6a), order 6 with a much
    /// smaller error constant; every substep lands inside the step. Graded
    /// near kinks.
    KahanLi6,
}

impl Method {
    pub const ALL: [Method; 5] = [
        Method::Verlet,
        Method::Yoshida4,
        Method::Suzuki4,
        Method::Yoshida6,
        Method::KahanLi6,
    ];
    pub fn name(self) -> &'static str {
        match self {
            Method::Verlet => "verlet",
            Method::Yoshida4 => "yoshida4",
            Method::Suzuki4 => "suzuki4",
            Method::Yoshida6 => "yoshida6",
            Method::KahanLi6 => "kahanli6",
        }
    }
    /// Order of convergence (kept across contact kinks by step grading).
    pub fn order(self) -> u32 {
        match self {
            Method::Verlet => 2,
            Method::Yoshida4 | Method::Suzuki4 => 4,
            Method::Yoshida6 | Method::KahanLi6 => 6,
        }
    }
}

impl crate::choice::Choice for Method {
    const ALL: &'static [Self] = &Method::ALL;
    fn name(self) -> &'static str {
        Method::name(self)
    }
}

/// Arithmetic precision of an integration (`--precision`, `[solver] precision`).
///
/// `df64`: double-single, each value a pair of f32 (≈ 48 bits), for GPUs
/// whose f64 is slow; the same results as f64 to ~1e-12·v_in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    F32,
    F64,
    Df64,
}

impl crate::choice::Choice for Precision {
    const ALL: &'static [Self] = &Precision::ALL;
    fn name(self) -> &'static str {
        Precision::name(self)
    }
}

impl Precision {
    pub const ALL: [Precision; 3] = [Precision::F32, Precision::F64, Precision::Df64];
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
            Precision::Df64 => "df64",
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Pendulum {
    /// String length L (m).
    pub length: f64,
    /// Gravity g (m/s²).
    pub gravity: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Damping {
    /// Coefficient of restitution e in (0, 1].
    pub restitution: f64,
    /// Linear air drag coefficient (1/s), ≥ 0.
    pub air_drag: f64,
}

/// Solver choices a scene makes; `None` = the CLI flag or the default decides.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct SolverChoice {
    pub method: Option<Method>,
    pub dt: Option<f64>,
    pub tolerance: Option<f64>,
    pub precision: Option<Precision>,
    /// `damping_split`: a damped chain's damping once a step, at its ends
    /// (`Some(true)`, "ends"), in every substep (`Some(false)`,
    /// "substeps"), or chosen per chain (`None`, "auto", the default).
    pub damping_ends: Option<bool>,
}

/// A fixed flat wall's material (Hertz sphere–flat contact, R* = the bead's radius).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Wall {
    pub young_modulus: f64,
    pub poisson_ratio: f64,
}

/// A half-sine force F·sin(π·t/τ) on one bead for 0 ≤ t ≤ τ.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Pulse {
    pub bead: usize,
    /// Peak force F (N).
    pub force: f64,
    /// Duration τ (s).
    pub duration: f64,
    /// A `[drive]`'s frequency f (Hz): F·sin(2π·f·t) for 0 ≤ t < τ; 0: a
    /// `[pulse]`, the half sine F·sin(πt/τ).
    #[serde(skip_serializing_if = "crate::scene::is_zero")]
    pub frequency: f64,
}

impl Pulse {
    /// ω (1/s): the force is F·sin(ωt); π/τ for a pulse, 2π·f for a drive.
    pub fn omega(&self) -> f64 {
        if self.frequency > 0.0 {
            std::f64::consts::TAU * self.frequency
        } else {
            std::f64::consts::PI / self.duration
        }
    }

    /// Whether it is a `[drive]` (a harmonic force over many periods).
    pub fn is_drive(&self) -> bool {
        self.frequency > 0.0
    }

    /// The impulse it gives its bead over its whole duration (N·s):
    /// 2Fτ/π for a pulse, F·(1 − cos ωτ)/ω for a drive.
    pub fn impulse(&self) -> f64 {
        let w = self.omega();
        if self.is_drive() {
            self.force * (1.0 - (w * self.duration).cos()) / w
        } else {
            2.0 * self.force * self.duration / std::f64::consts::PI
        }
    }
}

/// Bead histories for `cradle run --trace`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Record {
    pub beads: Vec<usize>,
    /// Row spacing (s).
    pub every: f64,
}

/// What makes a scene a granular chain (docs/SPEC.md §9): walls, a static
/// precompression, a force pulse, recorded and probed beads. Present when
/// the scene has any of `[walls]`, `[pulse]`, `[record]`, `[probes]`,
/// `[pattern]`, `[taper]`, `[impurity]`, or more than [`MAX_BALLS`] balls.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ChainSetup {
    pub left_wall: Option<Wall>,
    pub right_wall: Option<Wall>,
    /// Static force F0 (N) between the two walls; 0: none.
    pub precompression: f64,
    /// `[gravity] g` (m/s²) towards the left wall; 0: none.
    #[serde(skip_serializing_if = "crate::scene::is_zero")]
    pub gravity: f64,
    /// `[damping] viscosity` γ (N·s/m): a dashpot in parallel with each
    /// closed contact (issue #45); 0: none.
    #[serde(skip_serializing_if = "crate::scene::is_zero")]
    pub viscosity: f64,
    /// `[damping] air_drag` (1/s) on every bead; 0: none.
    #[serde(skip_serializing_if = "crate::scene::is_zero")]
    pub air_drag: f64,
    /// `[damping] restitution` e of every contact (Hunt–Crossley, as for
    /// cradles); 1: elastic (a chain without `[damping]` has 1, not the
    /// `Default`'s 0: `restitution()`).
    #[serde(skip_serializing_if = "crate::scene::is_elastic")]
    pub restitution: f64,
    /// `[piston] velocity` (m/s): the left wall moves into the chain at this
    /// speed from t = 0; 0: it stands still.
    #[serde(skip_serializing_if = "crate::scene::is_zero")]
    pub piston: f64,
    pub pulse: Option<Pulse>,
    pub record: Option<Record>,
    pub probes: Vec<usize>,
}

/// Whether `x` is zero (a field left out of a serialized scene when unset).
fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// Whether a restitution is elastic (1, or 0: unset; left out of a
/// serialized scene).
fn is_elastic(x: &f64) -> bool {
    *x == 1.0 || *x == 0.0
}

impl ChainSetup {
    /// The contacts' restitution: `restitution`, 1 when unset (0).
    pub fn restitution(&self) -> f64 {
        if self.restitution == 0.0 {
            1.0
        } else {
            self.restitution
        }
    }

    /// Whether the chain dissipates ([`dissipates`]).
    pub fn damped(&self) -> bool {
        dissipates(self.viscosity, self.air_drag, self.restitution())
    }
}

/// Whether a chain with dashpots `viscosity`, air drag `air_drag` and
/// contacts of restitution `restitution` dissipates (issue #45): the one
/// rule for a scene's setup and its engine's beads.
pub fn dissipates(viscosity: f64, air_drag: f64, restitution: f64) -> bool {
    viscosity > 0.0 || air_drag > 0.0 || restitution < 1.0
}

/// A checked scene in SI units, one value per ball (gaps and glue: per contact).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Scene {
    pub n: usize,
    pub radius: Vec<f64>,
    pub mass: Vec<f64>,
    pub young_modulus: Vec<f64>,
    pub poisson_ratio: Vec<f64>,
    pub gap: Vec<f64>,
    pub glue: Vec<bool>,
    pub velocity: Vec<f64>,
    /// Initial displacement of each ball (m, arc length): balls lifted by
    /// `[launch] height` on a pendulum start here, at rest.
    pub displacement: Vec<f64>,
    pub pendulum: Option<Pendulum>,
    pub damping: Option<Damping>,
    /// `[stop] duration` (s): the end of a pendulum run; a cap for a free line.
    pub duration: Option<f64>,
    pub max_steps: Option<u64>,
    pub solver: SolverChoice,
    /// A granular chain's walls, pulse, record and probes; `None` for a cradle.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub chain: Option<ChainSetup>,
}

impl Scene {
    /// Read and check a scene file.
    pub fn from_file(path: &Path) -> Result<Scene, InputError> {
        SceneSpec::parse(&Source::read(path)?)?.validate()
    }

    /// Parse and check a scene from TOML text; `name` is used in messages.
    pub fn from_toml_str(name: &str, text: &str) -> Result<Scene, InputError> {
        SceneSpec::parse(&Source::new(name, text))?.validate()
    }

    /// A file path, or else the name of a built-in scene.
    /// The `description` of the scene [`Scene::load`] loads: a file's key,
    /// a built-in's summary (`None` if it has none or cannot be read).
    pub fn description_of(name_or_path: &str) -> Option<String> {
        let path = Path::new(name_or_path);
        if path.exists() {
            let text = std::fs::read_to_string(path).ok()?;
            let t: toml::Table = text.parse().ok()?;
            return t.get("description")?.as_str().map(str::to_string);
        }
        builtin::find(name_or_path).map(|b| b.summary.to_string())
    }

    pub fn load(name_or_path: &str) -> Result<Scene, InputError> {
        let path = Path::new(name_or_path);
        if path.exists() {
            return Self::from_file(path);
        }
        match builtin::find(name_or_path) {
            Some(b) => b.spec()?.validate(),
            None => {
                // `cradle1` for `cradle-1`: the nearest built-in name, if near.
                let near = builtin::names()
                    .into_iter()
                    .map(|n| (strsim::levenshtein(name_or_path, n), n))
                    .min()
                    .filter(|(d, _)| *d <= 2)
                    .map_or(String::new(), |(_, n)| format!("did you mean `{n}`? "));
                Err(InputError::Read {
                    path: path.to_path_buf(),
                    error: std::io::Error::new(
                        std::io::ErrorKind::NotFound,
                        format!(
                            "no such file, nor a built-in scene ({near}built-ins: {})",
                            builtin::names().join(", ")
                        ),
                    ),
                })
            }
        }
    }

    /// Largest initial speed |v| (docs/SPEC.md §5), the scale of every reported error.
    pub fn v_in(&self) -> f64 {
        self.velocity.iter().fold(0.0, |m, v| m.max(v.abs()))
    }
}
