//! Checking a [`SceneSpec`] into a [`Scene`] (docs/SPEC.md §2, §4): one
//! step per part of the scene file, each naming the key, the value and what
//! is allowed.

use super::*;

use super::check::{any, non_negative, poisson, positive, Check, POISSON, POS};

impl SceneSpec {
    /// Check every key (docs/SPEC.md §2, §4) and resolve defaults.
    pub fn validate(&self) -> Result<Scene, InputError> {
        let c = Check { spec: self };
        let n = self.balls()?;
        let chain = self.is_chain(n);
        if chain {
            self.cradle_only_keys(&c, n)?;
        }
        let (radius, mass, young_modulus, poisson_ratio) = self.materials(&c, n)?;
        let (gap, glue) = self.gaps_and_glue(&c, n)?;
        let pendulum = self.pendulum(&c)?;
        let (velocity, displacement) = self.launch(&c, n, pendulum.as_ref())?;
        check_glued_launch(&c, &glue, &velocity, &displacement)?;
        // A chain's [damping] is part of its setup (`chain_setup`).
        let damping = match chain {
            true => None,
            false => self.damping(&c, pendulum.as_ref())?,
        };
        let (duration, max_steps) = self.stop(&c, pendulum.as_ref())?;
        let solver = self.solver(&c, chain)?;
        let chain = match chain {
            true => {
                Some(self.chain_setup(&c, n, &young_modulus, &poisson_ratio, &gap, duration)?)
            }
            false => None,
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
            chain,
        })
    }

    fn balls(&self) -> Result<usize, InputError> {
        let c = Check { spec: self };
        Ok(match self.balls {
            None => {
                return Err(InputError::Missing {
                    origin: self.origin.clone(),
                    line: None,
                    key: "balls".into(),
                    help: format!(
                        "the number of balls, 2 ..= {MAX_BALLS} (a cradle) or ..= {MAX_CHAIN} (a granular chain)"
                    ),
                })
            }
            Some(b) if (2..=MAX_CHAIN as i64).contains(&b) => b as usize,
            Some(b) => {
                return Err(c.err(
                    "balls",
                    b,
                    format!(
                        "an integer in 2 ..= {MAX_CHAIN} (above {MAX_BALLS}: a granular chain, docs/SPEC.md §9)"
                    ),
                ))
            }
        })
    }

    /// Radius, mass (or density), Young's modulus and Poisson ratio per ball;
    /// a chain's `[pattern]`, `[taper]` and `[impurity]` applied in that
    /// order before masses come from densities.
    fn materials(&self, c: &Check, n: usize) -> Result<Materials, InputError> {
        let mut radius = c.per(
            "radius",
            self.radius.as_ref(),
            DEFAULT_RADIUS,
            n,
            "ball",
            positive,
            POS,
        )?;
        if self.mass.is_some() && self.density.is_some() {
            return Err(c.err(
                "density",
                "(also `mass`)",
                "give `mass` or `density`, not both",
            ));
        }
        // Per ball: a given mass, else a density (the default steel's).
        let mut mass: Vec<Option<f64>> = match &self.mass {
            Some(m) => c
                .per("mass", Some(m), 0.0, n, "ball", positive, POS)?
                .into_iter()
                .map(Some)
                .collect(),
            None => vec![None; n],
        };
        let mut density = c.per(
            "density",
            self.density.as_ref(),
            DEFAULT_DENSITY,
            n,
            "ball",
            positive,
            POS,
        )?;
        let mut young_modulus = c.per(
            "young_modulus",
            self.young_modulus.as_ref(),
            DEFAULT_YOUNG,
            n,
            "ball",
            positive,
            POS,
        )?;
        let mut poisson_ratio = c.per(
            "poisson_ratio",
            self.poisson_ratio.as_ref(),
            DEFAULT_POISSON,
            n,
            "ball",
            poisson,
            POISSON,
        )?;
        let mut beads = super::granular::Beads {
            radius: &mut radius,
            mass: &mut mass,
            density: &mut density,
            young_modulus: &mut young_modulus,
            poisson_ratio: &mut poisson_ratio,
        };
        self.pattern(c, &mut beads)?;
        self.taper(c, &mut beads)?;
        self.impurity(c, &mut beads)?;
        let mass = mass
            .iter()
            .zip(&density)
            .zip(&radius)
            .map(|((m, rho), r)| m.unwrap_or(rho * 4.0 / 3.0 * std::f64::consts::PI * r * r * r))
            .collect();
        Ok((radius, mass, young_modulus, poisson_ratio))
    }

    /// Gaps and glue per contact.
    fn gaps_and_glue(&self, c: &Check, n: usize) -> Result<(Vec<f64>, Vec<bool>), InputError> {
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

        Ok((gap, glue))
    }

    fn pendulum(&self, c: &Check) -> Result<Option<Pendulum>, InputError> {
        Ok(match &self.pendulum {
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
        })
    }

    /// Initial velocities and displacements: `velocity` or `[launch]`.
    fn launch(
        &self,
        c: &Check,
        n: usize,
        pendulum: Option<&Pendulum>,
    ) -> Result<(Vec<f64>, Vec<f64>), InputError> {
        let gravity = pendulum.map_or(STANDARD_GRAVITY, |p| p.gravity);
        let mut displacement = vec![0.0; n];
        let velocity = match (&self.velocity, &self.launch) {
            (Some(_), Some(_)) => {
                return Err(c.err(
                    "launch",
                    "(also `velocity`)",
                    "give `velocity` or `[launch]`, not both",
                ))
            }
            // A pulse, a drive or a piston excites a chain at rest.
            (None, None)
                if self.pulse.is_some() || self.piston.is_some() || self.drive.is_some() =>
            {
                vec![0.0; n]
            }
            (None, None) => {
                // A chain with nothing to move it would stay at rest: say
                // what can move it (a pulse, unlike a cradle).
                let help = if self.is_chain(n) {
                    "a chain needs something to move it: `velocity = [...]` (m/s, one per bead), a `[launch]` table, a `[pulse]`, a `[drive]` or a `[piston]` (with precompression alone it stays at rest)"
                } else {
                    "give `velocity = [...]` (m/s, one per ball) or a `[launch]` table"
                };
                return Err(InputError::Missing {
                    origin: self.origin.clone(),
                    line: None,
                    key: "velocity".into(),
                    help: help.into(),
                });
            }
            (Some(v), None) => c.per(
                "velocity",
                Some(v),
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
                        match pendulum {
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
        Ok((velocity, displacement))
    }

    fn damping(
        &self,
        c: &Check,
        pendulum: Option<&Pendulum>,
    ) -> Result<Option<Damping>, InputError> {
        if let Some(g) = self.damping.as_ref().and_then(|d| d.viscosity) {
            return Err(c.err(
                "damping.viscosity",
                g,
                "a granular chain's key (a dashpot at each bead contact); a cradle's contacts take `restitution`",
            ));
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
        if let (Some(d), None) = (&damping, pendulum) {
            if d.air_drag > 0.0 {
                return Err(c.err(
                    "damping.air_drag",
                    d.air_drag,
                    "0 without [pendulum] (air drag is modelled for pendulum runs; a free-line collision lasts microseconds)",
                ));
            }
        }
        Ok(damping)
    }

    /// `[stop]`: the duration (required for a pendulum) and the step cap.
    fn stop(
        &self,
        c: &Check,
        pendulum: Option<&Pendulum>,
    ) -> Result<(Option<f64>, Option<u64>), InputError> {
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
        Ok((duration, max_steps))
    }

    fn solver(&self, c: &Check, chain: bool) -> Result<SolverChoice, InputError> {
        let s = self.solver.clone().unwrap_or_default();
        let damping_ends = match s.damping_split.as_deref() {
            None => None,
            Some(x) if !chain => {
                return Err(c.err(
                    "solver.damping_split",
                    format!("{x:?}"),
                    "a granular chain's key (where its dashpots and air drag go in a step); a cradle's damping has no split",
                ))
            }
            Some("auto") => None,
            Some("substeps") => Some(false),
            Some("ends") => Some(true),
            Some(x) => {
                return Err(c.err(
                    "solver.damping_split",
                    format!("{x:?}"),
                    "\"auto\", \"substeps\" or \"ends\"",
                ))
            }
        };
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
        Ok(SolverChoice {
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
            damping_ends,
        })
    }
}

/// Radius, mass, Young's modulus, Poisson ratio: one value per ball each.
type Materials = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

/// Glued balls move as one body: launched alike, lifted alike.
fn check_glued_launch(
    c: &Check,
    glue: &[bool],
    velocity: &[f64],
    displacement: &[f64],
) -> Result<(), InputError> {
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

    Ok(())
}
