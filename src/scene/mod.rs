//! Scenes: one cradle, as written ([`SceneSpec`]) and as checked ([`Scene`]).
//!
//! Data flow: scene TOML → [`SceneSpec`] (serde) → [`Scene`] (validated, SI,
//! one value per ball) → [`crate::engine::Chain`] (rigid bodies) → backend.

pub mod builtin;
pub(crate) mod spec;

pub use spec::{DampingSpec, LaunchSpec, PendulumSpec, PerBall, SceneSpec, SolverSpec, StopSpec};

use std::fmt::Display;
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
/// Chains longer than this are refused (the GPU keeps a chain in registers).
pub const MAX_BALLS: usize = 64;

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
    pub fn load(name_or_path: &str) -> Result<Scene, InputError> {
        let path = Path::new(name_or_path);
        if path.exists() {
            return Self::from_file(path);
        }
        match builtin::find(name_or_path) {
            Some(b) => b.spec()?.validate(),
            None => Err(InputError::Read {
                path: path.to_path_buf(),
                error: std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    format!(
                        "no such file, nor a built-in scene (built-ins: {})",
                        builtin::names().join(", ")
                    ),
                ),
            }),
        }
    }

    /// Largest initial speed |v| (docs/SPEC.md §5), the scale of every reported error.
    pub fn v_in(&self) -> f64 {
        self.velocity.iter().fold(0.0, |m, v| m.max(v.abs()))
    }
}

struct Check<'a> {
    spec: &'a SceneSpec,
}

impl Check<'_> {
    fn err(&self, key: &str, value: impl Display, allowed: impl Into<String>) -> InputError {
        InputError::Invalid {
            origin: self.spec.origin.clone(),
            line: self.spec.line_of(key),
            key: key.to_string(),
            value: value.to_string(),
            allowed: allowed.into(),
        }
    }

    fn num(
        &self,
        key: &str,
        x: f64,
        ok: fn(f64) -> bool,
        allowed: &str,
    ) -> Result<f64, InputError> {
        if x.is_finite() && ok(x) {
            Ok(x)
        } else {
            Err(self.err(key, x, allowed))
        }
    }

    fn opt(
        &self,
        key: &str,
        x: Option<f64>,
        ok: fn(f64) -> bool,
        allowed: &str,
    ) -> Result<Option<f64>, InputError> {
        x.map(|x| self.num(key, x, ok, allowed)).transpose()
    }

    /// A per-ball (or per-contact) array of `n` values, each passing `ok`.
    #[allow(clippy::too_many_arguments)]
    fn per(
        &self,
        key: &str,
        v: Option<&PerBall>,
        default: f64,
        n: usize,
        what: &str,
        ok: fn(f64) -> bool,
        allowed: &str,
    ) -> Result<Vec<f64>, InputError> {
        let values = match v {
            None => vec![default; n],
            Some(PerBall::Scalar(x)) => vec![*x; n],
            Some(PerBall::List(l)) if l.len() == n => l.clone(),
            Some(p @ PerBall::List(l)) => {
                return Err(self.err(
                    key,
                    p,
                    format!(
                        "an array of {n} values (one per {what}) or one number; got {}",
                        l.len()
                    ),
                ))
            }
        };
        // The key is only spelt out for an error (this runs for every scene).
        for (i, &x) in values.iter().enumerate() {
            if x.is_finite() && ok(x) {
                continue;
            }
            let k = if matches!(v, Some(PerBall::List(_))) {
                format!("{key}[{i}]")
            } else {
                key.to_string()
            };
            self.num(&k, x, ok, allowed)?;
        }
        Ok(values)
    }
}

fn positive(x: f64) -> bool {
    x > 0.0
}
fn non_negative(x: f64) -> bool {
    x >= 0.0
}
fn any(_: f64) -> bool {
    true
}

impl SceneSpec {
    /// Check every key (docs/SPEC.md §2, §4) and resolve defaults.
    pub fn validate(&self) -> Result<Scene, InputError> {
        let c = Check { spec: self };
        let n = match self.balls {
            None => {
                return Err(InputError::Missing {
                    origin: self.origin.clone(),
                    line: None,
                    key: "balls".into(),
                    help: format!("the number of balls, 2 ..= {MAX_BALLS}"),
                })
            }
            Some(b) if (2..=MAX_BALLS as i64).contains(&b) => b as usize,
            Some(b) => return Err(c.err("balls", b, format!("an integer in 2 ..= {MAX_BALLS}"))),
        };
        const POS: &str = "must be a finite number > 0";
        let radius = c.per(
            "radius",
            self.radius.as_ref(),
            DEFAULT_RADIUS,
            n,
            "ball",
            positive,
            POS,
        )?;
        let mass = match (&self.mass, &self.density) {
            (Some(_), Some(_)) => {
                return Err(c.err(
                    "density",
                    "(also `mass`)",
                    "give `mass` or `density`, not both",
                ))
            }
            (Some(m), None) => c.per("mass", Some(m), 0.0, n, "ball", positive, POS)?,
            (None, d) => {
                let rho = c.per(
                    "density",
                    d.as_ref(),
                    DEFAULT_DENSITY,
                    n,
                    "ball",
                    positive,
                    POS,
                )?;
                rho.iter()
                    .zip(&radius)
                    .map(|(rho, r)| rho * 4.0 / 3.0 * std::f64::consts::PI * r * r * r)
                    .collect()
            }
        };
        let young_modulus = c.per(
            "young_modulus",
            self.young_modulus.as_ref(),
            DEFAULT_YOUNG,
            n,
            "ball",
            positive,
            POS,
        )?;
        let poisson_ratio = c.per(
            "poisson_ratio",
            self.poisson_ratio.as_ref(),
            DEFAULT_POISSON,
            n,
            "ball",
            |x| (0.0..0.5).contains(&x),
            "must be in [0, 0.5)",
        )?;
        let gap = c.per(
            "gap",
            self.gap.as_ref(),
            0.0,
            n - 1,
            "pair of neighbours",
            non_negative,
            "must be ≥ 0 (m)",
        )?;
        let glue = match &self.glue {
            None => vec![false; n - 1],
            Some(g) => {
                let allowed = format!(
                    "a string of {} characters, `=` (glued) or `-` (free), e.g. \"={}\"",
                    n - 1,
                    "-".repeat(n - 2)
                );
                if g.chars().count() != n - 1 || g.chars().any(|ch| ch != '=' && ch != '-') {
                    return Err(c.err("glue", format!("{g:?}"), allowed));
                }
                g.chars().map(|ch| ch == '=').collect()
            }
        };

        let pendulum = match &self.pendulum {
            None => None,
            Some(p) => Some(Pendulum {
                length: match p.length {
                    Some(l) => c.num("pendulum.length", l, positive, POS)?,
                    None => {
                        return Err(InputError::Missing {
                            origin: self.origin.clone(),
                            line: self.line_of("pendulum"),
                            key: "pendulum.length".into(),
                            help: "the string length in m, > 0".into(),
                        })
                    }
                },
                gravity: c
                    .opt("pendulum.gravity", p.gravity, positive, POS)?
                    .unwrap_or(STANDARD_GRAVITY),
            }),
        };
        let gravity = pendulum.as_ref().map_or(STANDARD_GRAVITY, |p| p.gravity);

        let mut displacement = vec![0.0; n];
        let velocity = match (&self.velocity, &self.launch) {
            (Some(_), Some(_)) => {
                return Err(c.err(
                    "launch",
                    "(also `velocity`)",
                    "give `velocity` or `[launch]`, not both",
                ))
            }
            (None, None) => {
                return Err(InputError::Missing {
                    origin: self.origin.clone(),
                    line: None,
                    key: "velocity".into(),
                    help: "give `velocity = [...]` (m/s, one per ball) or a `[launch]` table"
                        .into(),
                })
            }
            (Some(v), None) => c.per(
                "velocity",
                Some(&PerBall::List(v.clone())),
                0.0,
                n,
                "ball",
                any,
                "must be a finite number (m/s)",
            )?,
            (None, Some(l)) => {
                let k = match l.balls {
                    Some(k) if (1..=n as i64).contains(&k) => k as usize,
                    Some(k) => {
                        return Err(c.err("launch.balls", k, format!("an integer in 1 ..= {n}")))
                    }
                    None => 1,
                };
                let speed = match (l.height, l.velocity) {
                    (Some(_), Some(_)) => {
                        return Err(c.err(
                            "launch.height",
                            "(also `launch.velocity`)",
                            "give `height` or `velocity`, not both",
                        ))
                    }
                    (Some(h), None) => {
                        let h = c.num(
                            "launch.height",
                            h,
                            positive,
                            "must be a finite height > 0 (m)",
                        )?;
                        match &pendulum {
                            // Free line: the speed at impact.
                            None => (2.0 * gravity * h).sqrt(),
                            // Pendulum: lifted along the arc, released from rest.
                            Some(p) => {
                                if h > p.length {
                                    return Err(c.err(
                                        "launch.height",
                                        h,
                                        format!(
                                            "at most the string length {} m (higher, the string goes slack)",
                                            p.length
                                        ),
                                    ));
                                }
                                let arc = p.length * (1.0 - h / p.length).acos();
                                for x in displacement.iter_mut().take(k) {
                                    *x = -arc;
                                }
                                0.0
                            }
                        }
                    }
                    (None, Some(v)) => {
                        c.num("launch.velocity", v, any, "must be a finite speed (m/s)")?
                    }
                    (None, None) => {
                        return Err(InputError::Missing {
                            origin: self.origin.clone(),
                            line: self.line_of("launch"),
                            key: "launch.height".into(),
                            help: "give `height` (m) or `velocity` (m/s)".into(),
                        })
                    }
                };
                (0..n).map(|i| if i < k { speed } else { 0.0 }).collect()
            }
        };
        for (i, w) in glue.iter().enumerate() {
            if *w && velocity[i] != velocity[i + 1] {
                return Err(c.err(
                    "velocity",
                    format!(
                        "{} and {} for balls {i} and {}",
                        velocity[i],
                        velocity[i + 1],
                        i + 1
                    ),
                    "glued balls must be launched with the same velocity",
                ));
            }
            if *w && displacement[i] != displacement[i + 1] {
                return Err(c.err(
                    "launch.balls",
                    format!("lifts ball {i} but not ball {}", i + 1),
                    "glued balls must be lifted together",
                ));
            }
        }

        let damping = match &self.damping {
            None => None,
            Some(d) => Some(Damping {
                restitution: c
                    .opt(
                        "damping.restitution",
                        d.restitution,
                        |e| e > 0.0 && e <= 1.0,
                        "must be in (0, 1]",
                    )?
                    .unwrap_or(1.0),
                air_drag: c
                    .opt(
                        "damping.air_drag",
                        d.air_drag,
                        non_negative,
                        "must be ≥ 0 (1/s)",
                    )?
                    .unwrap_or(0.0),
            }),
        };
        if let (Some(d), None) = (&damping, &pendulum) {
            if d.air_drag > 0.0 {
                return Err(c.err(
                    "damping.air_drag",
                    d.air_drag,
                    "0 without [pendulum] (air drag is modelled for pendulum runs; a free-line collision lasts microseconds)",
                ));
            }
        }
        let stop = self.stop.clone().unwrap_or_default();
        let duration = c.opt(
            "stop.duration",
            stop.duration,
            positive,
            "must be a finite time > 0 (s)",
        )?;
        if pendulum.is_some() && duration.is_none() {
            return Err(InputError::Missing {
                origin: self.origin.clone(),
                line: self.line_of("pendulum"),
                key: "stop.duration".into(),
                help: "a pendulum runs for a given simulated time: add `[stop] duration = ...` (s)"
                    .into(),
            });
        }
        let max_steps = match stop.max_steps {
            None => None,
            Some(s) if s >= 1 => Some(s as u64),
            Some(s) => return Err(c.err("stop.max_steps", s, "an integer ≥ 1")),
        };
        let s = self.solver.clone().unwrap_or_default();
        let method = match &s.method {
            None => None,
            Some(m) => Some(<Method as Choice>::from_name(m).ok_or_else(|| {
                c.err(
                    "solver.method",
                    format!("{m:?}"),
                    format!("one of: {}", <Method as Choice>::names()),
                )
            })?),
        };
        let precision = match &s.precision {
            None => None,
            Some(p) => Some(<Precision as Choice>::from_name(p).ok_or_else(|| {
                c.err(
                    "solver.precision",
                    format!("{p:?}"),
                    "\"f32\", \"f64\" or \"df64\"",
                )
            })?),
        };
        if s.dt.is_some() && s.tolerance.is_some() {
            return Err(c.err(
                "solver.dt",
                "(also `solver.tolerance`)",
                "give `dt` or `tolerance`, not both",
            ));
        }
        let solver = SolverChoice {
            method,
            dt: c.opt(
                "solver.dt",
                s.dt,
                positive,
                "must be a finite time step > 0 (s)",
            )?,
            tolerance: c.opt(
                "solver.tolerance",
                s.tolerance,
                |t| t > 0.0 && t < 1.0,
                "must be in (0, 1)",
            )?,
            precision,
        };
        Ok(Scene {
            n,
            radius,
            mass,
            young_modulus,
            poisson_ratio,
            gap,
            glue,
            velocity,
            displacement,
            pendulum,
            damping,
            duration,
            max_steps,
            solver,
        })
    }
}
