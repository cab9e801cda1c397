//! The keys of a granular chain (docs/SPEC.md §9): `[walls]`, `[pulse]`,
//! `[record]`, `[probes]`, and the compact descriptions of long chains,
//! `[pattern]`, `[taper]`, `[impurity]`, checked as every scene key is
//! (file:line, key, value, what is allowed).

use super::check::{finite_non_negative, non_negative, poisson, positive, Check, POISSON, POS};
use super::*;

/// The per-bead arrays `[pattern]`, `[taper]` and `[impurity]` rewrite.
pub(super) struct Beads<'a> {
    pub radius: &'a mut Vec<f64>,
    /// A given mass per bead, else `None` (the density decides).
    pub mass: &'a mut Vec<Option<f64>>,
    pub density: &'a mut Vec<f64>,
    pub young_modulus: &'a mut Vec<f64>,
    pub poisson_ratio: &'a mut Vec<f64>,
}

/// One `[pattern]` array: key, values, check, what is allowed.
type PatternList<'a> = (&'a str, &'a Option<Vec<f64>>, fn(f64) -> bool, &'a str);

/// Bead indices as written: each an integer in 0 ..= n−1, no repeats.
fn bead_list(c: &Check, key: &str, beads: &[i64], n: usize) -> Result<Vec<usize>, InputError> {
    let mut out = Vec::with_capacity(beads.len());
    let mut seen = vec![false; n];
    for (i, &b) in beads.iter().enumerate() {
        if !(0..n as i64).contains(&b) {
            return Err(c.err(
                &format!("{key}[{i}]"),
                b,
                format!("a bead index in 0 ..= {} (the chain has {n} beads)", n - 1),
            ));
        }
        if std::mem::replace(&mut seen[b as usize], true) {
            return Err(c.err(
                &format!("{key}[{i}]"),
                b,
                "each bead once (it is already listed)",
            ));
        }
        out.push(b as usize);
    }
    Ok(out)
}

impl SceneSpec {
    /// Whether the scene is a granular chain rather than a cradle.
    pub(super) fn is_chain(&self, n: usize) -> bool {
        n > MAX_BALLS
            || self.walls.is_some()
            || self.pulse.is_some()
            || self.record.is_some()
            || self.probes.is_some()
            || self.pattern.is_some()
            || self.taper.is_some()
            || self.impurity.is_some()
            || self.gravity.is_some()
            || self.piston.is_some()
            || self.drive.is_some()
    }

    /// Glue and a pendulum belong to the cradle engine: a chain refuses
    /// them rather than ignoring them.
    pub(super) fn cradle_only_keys(&self, c: &Check, n: usize) -> Result<(), InputError> {
        let why = if n > MAX_BALLS {
            format!("a chain of {n} beads (above {MAX_BALLS}: a granular chain)")
        } else {
            "a granular chain (a scene with [walls], [pulse], [record], [probes], [pattern], [taper], [impurity], [gravity], [piston] or [drive])".to_string()
        };
        if self.glue.as_deref().is_some_and(|g| g.contains('=')) {
            return Err(c.err(
                "glue",
                format!("{:?}", self.glue.as_deref().unwrap_or("")),
                format!("no glue in {why}; glue is for cradles of at most {MAX_BALLS} balls"),
            ));
        }
        if self.pendulum.is_some() {
            return Err(c.err(
                "pendulum",
                "[pendulum]",
                format!("no pendulum in {why}: beads lie on a frictionless line"),
            ));
        }
        Ok(())
    }

    /// `[pattern]`: arrays of one period, repeated from bead 0.
    pub(super) fn pattern(&self, c: &Check, b: &mut Beads) -> Result<(), InputError> {
        let Some(p) = &self.pattern else {
            return Ok(());
        };
        if p.mass.is_some() && p.density.is_some() {
            return Err(c.err(
                "pattern.density",
                "(also `pattern.mass`)",
                "give `mass` or `density`, not both",
            ));
        }
        let n = b.radius.len();
        let lists: [PatternList; 5] = [
            ("pattern.radius", &p.radius, positive, POS),
            ("pattern.density", &p.density, positive, POS),
            ("pattern.mass", &p.mass, positive, POS),
            ("pattern.young_modulus", &p.young_modulus, positive, POS),
            ("pattern.poisson_ratio", &p.poisson_ratio, poisson, POISSON),
        ];
        let mut any = false;
        for (key, list, ok, allowed) in lists {
            let Some(list) = list else { continue };
            any = true;
            if list.is_empty() || list.len() > n {
                return Err(c.err(
                    key,
                    format!("{list:?}"),
                    format!("one period of 1 ..= {n} values, repeated along the chain"),
                ));
            }
            for (i, &x) in list.iter().enumerate() {
                c.num(&format!("{key}[{i}]"), x, ok, allowed)?;
            }
            let at = |i: usize| list[i % list.len()];
            match key {
                "pattern.radius" => (0..n).for_each(|i| b.radius[i] = at(i)),
                "pattern.density" => (0..n).for_each(|i| {
                    b.density[i] = at(i);
                    b.mass[i] = None;
                }),
                "pattern.mass" => (0..n).for_each(|i| b.mass[i] = Some(at(i))),
                "pattern.young_modulus" => (0..n).for_each(|i| b.young_modulus[i] = at(i)),
                _ => (0..n).for_each(|i| b.poisson_ratio[i] = at(i)),
            }
        }
        if !any {
            return Err(c.err(
                "pattern",
                "[pattern] with no values",
                "at least one of radius, density, mass, young_modulus, poisson_ratio (arrays of one period)",
            ));
        }
        Ok(())
    }

    /// `[taper]`: radius_{i+1} = (1−q)·radius_i (`kind = "ratio"`, the
    /// default) or radius_i = radius_0·(1 − q·i) (`kind = "linear"`);
    /// masses follow from the density unless given.
    pub(super) fn taper(&self, c: &Check, b: &mut Beads) -> Result<(), InputError> {
        let Some(t) = &self.taper else {
            return Ok(());
        };
        let linear = match t.kind.as_deref() {
            None | Some("ratio") => false,
            Some("linear") => true,
            Some(k) => {
                return Err(c.err("taper.kind", format!("{k:?}"), "\"ratio\" or \"linear\""))
            }
        };
        let Some(q) = t.ratio else {
            return Err(InputError::Missing {
                origin: self.origin.clone(),
                line: self.line_of("taper"),
                key: "taper.ratio".into(),
                help: "the taper q in [0, 1): radius_{i+1} = (1−q)·radius_i".into(),
            });
        };
        let q = c.num(
            "taper.ratio",
            q,
            |q| (0.0..1.0).contains(&q),
            "must be in [0, 1)",
        )?;
        let n = b.radius.len();
        let r0 = b.radius[0];
        let factor = |i: usize| {
            if linear {
                1.0 - q * i as f64
            } else {
                (1.0 - q).powi(i as i32)
            }
        };
        let last = factor(n - 1);
        if last.is_nan() || last < MIN_TAPER_FRACTION {
            return Err(c.err(
                "taper.ratio",
                q,
                format!(
                    "a taper that keeps bead {} at ≥ {MIN_TAPER_FRACTION:e} of bead 0's radius (it would be {last:.3e} of it)",
                    n - 1
                ),
            ));
        }
        for i in 0..n {
            b.radius[i] = r0 * factor(i);
        }
        Ok(())
    }

    /// `[impurity]`: the listed beads take the given radius, mass (or
    /// density) and material.
    pub(super) fn impurity(&self, c: &Check, b: &mut Beads) -> Result<(), InputError> {
        let Some(imp) = &self.impurity else {
            return Ok(());
        };
        let n = b.radius.len();
        let Some(list) = &imp.beads else {
            return Err(InputError::Missing {
                origin: self.origin.clone(),
                line: self.line_of("impurity"),
                key: "impurity.beads".into(),
                help: format!("the impurity beads, indices in 0 ..= {}", n - 1),
            });
        };
        let beads = bead_list(c, "impurity.beads", list, n)?;
        if [
            imp.radius,
            imp.density,
            imp.mass,
            imp.young_modulus,
            imp.poisson_ratio,
        ]
        .iter()
        .all(Option::is_none)
        {
            return Err(c.err(
                "impurity",
                "[impurity] with beads and no values",
                "at least one of radius, density, mass, young_modulus, poisson_ratio for the listed beads",
            ));
        }
        if imp.mass.is_some() && imp.density.is_some() {
            return Err(c.err(
                "impurity.density",
                "(also `impurity.mass`)",
                "give `mass` or `density`, not both",
            ));
        }
        let radius = c.opt("impurity.radius", imp.radius, positive, POS)?;
        let density = c.opt("impurity.density", imp.density, positive, POS)?;
        let mass = c.opt("impurity.mass", imp.mass, positive, POS)?;
        let young = c.opt("impurity.young_modulus", imp.young_modulus, positive, POS)?;
        let nu = c.opt(
            "impurity.poisson_ratio",
            imp.poisson_ratio,
            poisson,
            POISSON,
        )?;
        for i in beads {
            if let Some(r) = radius {
                b.radius[i] = r;
            }
            if let Some(rho) = density {
                b.density[i] = rho;
                b.mass[i] = None;
            }
            if let Some(m) = mass {
                b.mass[i] = Some(m);
            }
            if let Some(e) = young {
                b.young_modulus[i] = e;
            }
            if let Some(v) = nu {
                b.poisson_ratio[i] = v;
            }
        }
        Ok(())
    }

    /// `[gravity] g` (m/s²; standard gravity when left out): at least 0;
    /// above 0 it needs a floor to stand on (the left wall) and touching
    /// beads (a column starts in its static equilibrium, which has no gaps).
    fn gravity_of(
        &self,
        c: &Check,
        g: &super::spec::GravitySpec,
        setup: &ChainSetup,
        gap: &[f64],
    ) -> Result<f64, InputError> {
        let g = c.num(
            "gravity.g",
            g.g.unwrap_or(STANDARD_GRAVITY),
            non_negative,
            "must be ≥ 0 (m/s²)",
        )?;
        if g > 0.0 {
            if setup.left_wall.is_none() {
                return Err(c.err(
                    "gravity.g",
                    g,
                    "a floor: [walls] left = true (gravity pulls every bead towards the left wall)",
                ));
            }
            if let Some(i) = gap.iter().position(|&x| x != 0.0) {
                return Err(c.err(
                    "gravity.g",
                    g,
                    format!(
                        "touching beads: gap[{i}] = {} m (a column under gravity starts in its static equilibrium, which has no gaps)",
                        gap[i]
                    ),
                ));
            }
        }
        Ok(g)
    }

    /// A chain's `[damping]` (issue #45): the contacts' dashpot γ (N·s/m),
    /// the beads' air drag (1/s), each ≥ 0, and Hunt–Crossley contacts of
    /// restitution e in (0, 1].
    fn chain_damping(
        c: &Check,
        d: &super::spec::DampingSpec,
    ) -> Result<(f64, f64, f64), InputError> {
        let e = c.opt(
            "damping.restitution",
            d.restitution,
            |e| e > 0.0 && e <= 1.0,
            "must be in (0, 1]",
        )?;
        let g = c.opt(
            "damping.viscosity",
            d.viscosity,
            finite_non_negative,
            "must be finite and ≥ 0 (N·s/m)",
        )?;
        let drag = c.opt(
            "damping.air_drag",
            d.air_drag,
            finite_non_negative,
            "must be finite and ≥ 0 (1/s)",
        )?;
        Ok((g.unwrap_or(0.0), drag.unwrap_or(0.0), e.unwrap_or(1.0)))
    }

    /// `[drive]`: F·sin(2π·f·t) on one bead for 0 ≤ t < `duration` (default
    /// and at most: the run's `[stop] duration`, which a drive needs).
    fn drive_of(
        &self,
        c: &Check,
        d: &super::spec::DriveSpec,
        n: usize,
        duration: Option<f64>,
    ) -> Result<Pulse, InputError> {
        let missing = |key: &str, help: &str| InputError::Missing {
            origin: self.origin.clone(),
            line: self.line_of("drive"),
            key: key.into(),
            help: help.into(),
        };
        let bead = match d.bead {
            None => 0,
            Some(b) if (0..n as i64).contains(&b) => b as usize,
            Some(b) => {
                return Err(c.err("drive.bead", b, format!("a bead index in 0 ..= {}", n - 1)))
            }
        };
        let force = match d.force {
            Some(f) => c.num(
                "drive.force",
                f,
                |f| f != 0.0 && f.is_finite(),
                "a finite force ≠ 0 (N)",
            )?,
            None => return Err(missing("drive.force", "the drive's amplitude (N)")),
        };
        let frequency = match d.frequency {
            Some(f) => c.num(
                "drive.frequency",
                f,
                |f| f > 0.0 && f.is_finite(),
                "a finite frequency > 0 (Hz)",
            )?,
            None => return Err(missing("drive.frequency", "the drive's frequency (Hz)")),
        };
        let Some(run) = duration else {
            return Err(missing(
                "stop.duration",
                "how long the run lasts (s): a drive's response is measured over its second half",
            ));
        };
        let tau = match d.duration {
            Some(t) => c.num("drive.duration", t, positive, "must be a time > 0 (s)")?,
            None => run,
        };
        if tau > run {
            return Err(c.err(
                "drive.duration",
                tau,
                format!("at most the run's `[stop] duration` = {run} s"),
            ));
        }
        Ok(Pulse {
            bead,
            force,
            duration: tau,
            frequency,
        })
    }

    /// `[piston] velocity` (m/s, finite, > 0): the left wall moves into the
    /// chain from t = 0; it needs that wall, and a `[stop] duration` (its
    /// push never ends, so no pulse reaching the far end ends the run).
    fn piston_of(
        &self,
        c: &Check,
        p: &super::spec::PistonSpec,
        setup: &ChainSetup,
        duration: Option<f64>,
    ) -> Result<f64, InputError> {
        let Some(u) = p.velocity else {
            return Err(InputError::Missing {
                origin: self.origin.clone(),
                line: self.line_of("piston"),
                key: "piston.velocity".into(),
                help: "the speed the left wall moves into the chain at (m/s, > 0)".into(),
            });
        };
        let u = c.num(
            "piston.velocity",
            u,
            |x| x > 0.0 && x.is_finite(),
            "must be finite and > 0 (m/s)",
        )?;
        if setup.left_wall.is_none() {
            return Err(c.err(
                "piston.velocity",
                u,
                "a left wall to move: [walls] left = true",
            ));
        }
        if duration.is_none() {
            return Err(InputError::Missing {
                origin: self.origin.clone(),
                line: self.line_of("piston"),
                key: "stop.duration".into(),
                help: "how long the piston pushes (s): it never stops, so the run needs an end"
                    .into(),
            });
        }
        Ok(u)
    }

    /// Walls, precompression, pulse, record and probes of a chain.
    pub(super) fn chain_setup(
        &self,
        c: &Check,
        n: usize,
        young: &[f64],
        nu: &[f64],
        gap: &[f64],
        duration: Option<f64>,
    ) -> Result<ChainSetup, InputError> {
        let mut setup = ChainSetup::default();
        if let Some(w) = &self.walls {
            Self::walls_of(c, w, &mut setup, n, young, nu, gap)?;
        }
        if let Some(g) = &self.gravity {
            setup.gravity = self.gravity_of(c, g, &setup, gap)?;
        }
        if let Some(d) = &self.damping {
            (setup.viscosity, setup.air_drag, setup.restitution) = Self::chain_damping(c, d)?;
        }
        if let Some(p) = &self.piston {
            setup.piston = self.piston_of(c, p, &setup, duration)?;
        }
        if let Some(p) = &self.pulse {
            setup.pulse = Some(self.pulse_of(c, p, n, duration)?);
        }
        if let Some(d) = &self.drive {
            if self.pulse.is_some() {
                return Err(c.err(
                    "drive",
                    "[drive] beside [pulse]",
                    "one force on a bead: a [pulse] or a [drive], not both",
                ));
            }
            setup.pulse = Some(self.drive_of(c, d, n, duration)?);
        }
        if let Some(r) = &self.record {
            setup.record = Some(self.record_of(c, r, n)?);
        }
        if let Some(p) = &self.probes {
            setup.probes = bead_list(c, "probes.beads", p.beads.as_deref().unwrap_or(&[]), n)?;
            if setup.probes.is_empty() {
                return Err(c.err(
                    "probes.beads",
                    "[]",
                    format!("one or more bead indices in 0 ..= {}", n - 1),
                ));
            }
            setup.probes.sort_unstable();
        }
        Ok(setup)
    }

    /// `[walls]`: which ends, their material (the end beads' unless
    /// given) and the precompression between them.
    fn walls_of(
        c: &Check,
        w: &super::spec::WallsSpec,
        setup: &mut ChainSetup,
        n: usize,
        young: &[f64],
        nu: &[f64],
        gap: &[f64],
    ) -> Result<(), InputError> {
        let e = c.opt("walls.young_modulus", w.young_modulus, positive, POS)?;
        let p = c.opt("walls.poisson_ratio", w.poisson_ratio, poisson, POISSON)?;
        let wall = |bead: usize| Wall {
            young_modulus: e.unwrap_or(young[bead]),
            poisson_ratio: p.unwrap_or(nu[bead]),
        };
        setup.left_wall = w.left.unwrap_or(false).then(|| wall(0));
        setup.right_wall = w.right.unwrap_or(false).then(|| wall(n - 1));
        if setup.left_wall.is_none() && setup.right_wall.is_none() {
            return Err(c.err(
                "walls",
                "[walls] with neither wall",
                "`left = true` and/or `right = true` (no [walls] table: free ends)",
            ));
        }
        if let Some(f0) = w.precompression {
            let f0 = c.num("walls.precompression", f0, non_negative, "must be ≥ 0 (N)")?;
            if f0 > 0.0 {
                if setup.left_wall.is_none() || setup.right_wall.is_none() {
                    return Err(c.err(
                        "walls.precompression",
                        f0,
                        "both walls (`left = true`, `right = true`): a static force needs two ends to push against",
                    ));
                }
                if let Some(i) = gap.iter().position(|&g| g != 0.0) {
                    return Err(c.err(
                        "walls.precompression",
                        f0,
                        format!(
                            "touching beads: gap[{i}] = {} m (a precompressed chain has no gaps)",
                            gap[i]
                        ),
                    ));
                }
            }
            setup.precompression = f0;
        }
        Ok(())
    }

    /// `[record]`: the recorded beads (a list, or every stride-th and the
    /// last) and the spacing of the trace's rows.
    fn record_of(
        &self,
        c: &Check,
        r: &super::spec::RecordSpec,
        n: usize,
    ) -> Result<Record, InputError> {
        let beads = match (&r.beads, r.stride) {
            (Some(_), Some(k)) => {
                return Err(c.err(
                    "record.stride",
                    k,
                    "either `beads` (a list) or `stride` (every stride-th bead), not both",
                ))
            }
            (None, Some(k)) => {
                if !(1..n as i64).contains(&k) {
                    return Err(c.err(
                        "record.stride",
                        k,
                        format!("a whole number in 1 ..= {} (beads 0, stride, 2·stride, … and the last)", n - 1),
                    ));
                }
                let mut b: Vec<usize> = (0..n).step_by(k as usize).collect();
                if b.last() != Some(&(n - 1)) {
                    b.push(n - 1);
                }
                b
            }
            (Some(b), None) if !b.is_empty() => bead_list(c, "record.beads", b, n)?,
            _ => {
                return Err(InputError::Missing {
                    origin: self.origin.clone(),
                    line: self.line_of("record"),
                    key: "record.beads".into(),
                    help: format!(
                    "the recorded beads, indices in 0 ..= {} (or `stride = k`: every k-th bead)",
                    n - 1
                ),
                })
            }
        };
        let every = match r.every {
            Some(e) => c.num("record.every", e, positive, "must be a time > 0 (s)")?,
            None => {
                return Err(InputError::Missing {
                    origin: self.origin.clone(),
                    line: self.line_of("record"),
                    key: "record.every".into(),
                    help: "the spacing of the trace's rows (s)".into(),
                })
            }
        };
        Ok(Record { beads, every })
    }

    fn pulse_of(
        &self,
        c: &Check,
        p: &PulseSpec,
        n: usize,
        duration: Option<f64>,
    ) -> Result<Pulse, InputError> {
        let bead = match p.bead {
            None => 0,
            Some(b) if (0..n as i64).contains(&b) => b as usize,
            Some(b) => {
                return Err(c.err("pulse.bead", b, format!("a bead index in 0 ..= {}", n - 1)))
            }
        };
        let missing = |key: &str, help: &str| InputError::Missing {
            origin: self.origin.clone(),
            line: self.line_of("pulse"),
            key: key.into(),
            help: help.into(),
        };
        let force = match p.force {
            Some(f) => c.num("pulse.force", f, |f| f != 0.0, "a finite force ≠ 0 (N)")?,
            None => return Err(missing("pulse.force", "the pulse's peak force (N)")),
        };
        let tau = match p.duration {
            Some(t) => c.num("pulse.duration", t, positive, "must be a time > 0 (s)")?,
            None => return Err(missing("pulse.duration", "the pulse's duration (s)")),
        };
        if let Some(d) = duration {
            if tau > d {
                return Err(c.err(
                    "pulse.duration",
                    tau,
                    format!("at most the run's `[stop] duration` = {d} s"),
                ));
            }
        }
        Ok(Pulse {
            bead,
            force,
            duration: tau,
            frequency: 0.0,
        })
    }
}
