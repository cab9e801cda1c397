//! One sweep axis: a parameter (`mass[2]`, `gap`, `glue`, …) and its values,
//! computed as start + i·step (linspace) or start·ratio^(i/(n−1)) (logspace),
//! never accumulated; the last value is the given stop exactly.

use serde::Serialize;

use crate::scene::{
    DampingSpec, ImpuritySpec, LaunchSpec, PatternSpec, PendulumSpec, PerBall, PulseSpec, Scene,
    SceneSpec, SolverSpec, StopSpec, TaperSpec, WallsSpec,
};

/// Most values one axis may have.
pub const MAX_AXIS_VALUES: usize = 10_000_000;

/// What a parameter name refers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Kind {
    /// One value per ball; index optional.
    PerBall,
    /// One value per contact (`gap`); index optional.
    PerContact,
    /// One value per ball; index required (`velocity[0]`).
    Velocity,
    /// A string of N−1 `=`/`-` characters.
    Glue,
    /// An integer.
    Integer,
    /// A plain number.
    Number,
    /// One element of a granular chain's `[pattern]` period; index required
    /// (`pattern.radius[1]`), below the base scene's period length.
    Pattern,
}

/// Parameters a sweep axis may name, with their kind.
pub const PARAMS: &[(&str, Kind)] = &[
    ("balls", Kind::Integer),
    ("radius", Kind::PerBall),
    ("density", Kind::PerBall),
    ("mass", Kind::PerBall),
    ("young_modulus", Kind::PerBall),
    ("poisson_ratio", Kind::PerBall),
    ("gap", Kind::PerContact),
    ("glue", Kind::Glue),
    ("velocity", Kind::Velocity),
    ("launch.balls", Kind::Integer),
    ("launch.height", Kind::Number),
    ("launch.velocity", Kind::Number),
    ("restitution", Kind::Number),
    ("air_drag", Kind::Number),
    ("length", Kind::Number),
    ("gravity", Kind::Number),
    ("duration", Kind::Number),
    ("tolerance", Kind::Number),
    ("dt", Kind::Number),
    // Granular chains (docs/SPEC.md §9): the tables' keys by dotted name.
    ("walls.precompression", Kind::Number),
    ("walls.young_modulus", Kind::Number),
    ("walls.poisson_ratio", Kind::Number),
    ("pulse.bead", Kind::Integer),
    ("pulse.force", Kind::Number),
    ("pulse.duration", Kind::Number),
    ("pattern.radius", Kind::Pattern),
    ("pattern.density", Kind::Pattern),
    ("pattern.mass", Kind::Pattern),
    ("pattern.young_modulus", Kind::Pattern),
    ("pattern.poisson_ratio", Kind::Pattern),
    ("taper.ratio", Kind::Number),
    ("impurity.radius", Kind::Number),
    ("impurity.density", Kind::Number),
    ("impurity.mass", Kind::Number),
    ("impurity.young_modulus", Kind::Number),
    ("impurity.poisson_ratio", Kind::Number),
    ("gravity.g", Kind::Number),
    ("damping.viscosity", Kind::Number),
    ("damping.air_drag", Kind::Number),
    ("damping.restitution", Kind::Number),
    ("piston.velocity", Kind::Number),
    ("drive.bead", Kind::Integer),
    ("drive.force", Kind::Number),
    ("drive.frequency", Kind::Number),
    ("drive.duration", Kind::Number),
];

/// A parsed `param` string: name, kind and optional index.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Param {
    pub name: String,
    pub kind: Kind,
    pub index: Option<usize>,
}

impl Param {
    /// Parse `name` or `name[i]`; `Err` carries the allowed-values text.
    pub fn parse(s: &str) -> Result<Param, String> {
        let (name, index) = match s.split_once('[') {
            None => (s, None),
            Some((n, rest)) => {
                let i = rest
                    .strip_suffix(']')
                    .and_then(|i| i.trim().parse::<usize>().ok())
                    .ok_or_else(|| "an index written `name[i]` with i = 0, 1, …".to_string())?;
                (n, Some(i))
            }
        };
        let Some(&(_, kind)) = PARAMS.iter().find(|(n, _)| *n == name) else {
            let hint = crate::error::closest(name, PARAMS.iter().map(|p| p.0))
                .map_or(String::new(), |c| format!("did you mean `{c}`? "));
            return Err(format!(
                "{hint}one of: {}",
                PARAMS.iter().map(|p| p.0).collect::<Vec<_>>().join(", ")
            ));
        };
        match (kind, index) {
            (Kind::Velocity, None) => {
                Err("`velocity[i]`: the velocity of ball i needs an index".into())
            }
            (Kind::Pattern, None) => Err(format!(
                "`{name}[i]`: element i of the [pattern] period needs an index"
            )),
            (Kind::PerBall | Kind::PerContact | Kind::Velocity | Kind::Pattern, _) | (_, None) => {
                Ok(Param {
                    name: name.to_string(),
                    kind,
                    index,
                })
            }
            (_, Some(_)) => Err(format!("`{name}` takes no index")),
        }
    }

    /// Two axes that set the same scene quantity: the second would overwrite
    /// the first (or discard it: a `velocity[i]` axis replaces `[launch]`,
    /// `dt` and `tolerance` replace each other), so the table would show
    /// values that were never used.
    pub fn overlaps(&self, other: &Param) -> bool {
        fn group(p: &Param) -> &str {
            match p.name.as_str() {
                "density" | "mass" => "mass",
                "pattern.density" | "pattern.mass" => "pattern.mass",
                "impurity.density" | "impurity.mass" => "impurity.mass",
                "velocity" | "launch.height" | "launch.velocity" => "velocity",
                "tolerance" | "dt" => "step",
                n => n,
            }
        }
        // A [pattern] array replaces the whole chain's values of its key:
        // an axis of that key would label values never used.
        let plain = |p: &Param| group(p).strip_prefix("pattern.").map(str::to_string);
        if plain(self).as_deref() == Some(group(other))
            || plain(other).as_deref() == Some(group(self))
        {
            return true;
        }
        if group(self) != group(other) {
            // launch.balls decides which balls a launch speed applies to; a
            // velocity[i] axis removes the launch altogether.
            return matches!(
                (self.name.as_str(), other.name.as_str()),
                ("velocity", "launch.balls") | ("launch.balls", "velocity")
            );
        }
        match (self.name.as_str(), other.name.as_str()) {
            // Different balls' velocities are independent.
            ("velocity", "velocity") => self.index == other.index,
            _ => match (self.index, other.index) {
                (Some(i), Some(j)) => i == j,
                _ => true,
            },
        }
    }

    /// Largest index this parameter allows in a chain of `n` balls
    /// (`spec`: the base scene as written, whose `[pattern]` arrays bound a
    /// `pattern.*` index).
    pub fn index_limit(&self, n: usize, spec: &SceneSpec) -> Option<usize> {
        match self.kind {
            Kind::PerBall | Kind::Velocity => Some(n),
            Kind::PerContact => Some(n - 1),
            Kind::Pattern => Some(
                spec.pattern
                    .as_ref()
                    .and_then(|p| pattern_slot(p, &self.name))
                    .map_or(0, Vec::len),
            ),
            _ => None,
        }
    }

    /// Whether this parameter's index exists in a chain of `n` balls (`spec`
    /// as for [`Param::index_limit`]); `Err`: what is allowed.
    pub fn check_index(&self, n: usize, spec: &SceneSpec) -> Result<(), String> {
        let (Some(i), Some(lim)) = (self.index, self.index_limit(n, spec)) else {
            return Ok(());
        };
        match (i < lim, self.kind) {
            (true, _) => Ok(()),
            (false, Kind::Pattern) if lim == 0 => Err(format!(
                "an element of an array `{}` in the base scene's [pattern] table (it has none)",
                self.name.trim_start_matches("pattern.")
            )),
            (false, Kind::Pattern) => Err(format!(
                "an index in 0 ..= {} (the base scene's [pattern] period)",
                lim - 1
            )),
            (false, _) => Err(format!("an index in 0 ..= {} for {n} balls", lim - 1)),
        }
    }
}

/// One value of an axis.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Value {
    Num(f64),
    Text(String),
}

impl std::fmt::Display for Value {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Value::Num(x) => write!(f, "{x}"),
            Value::Text(s) => write!(f, "{s:?}"),
        }
    }
}

/// The values of one axis, computed on demand from their index (a
/// 10^7-value range costs nothing until a scene asks for one).
#[derive(Clone, Debug, PartialEq)]
pub enum Values {
    /// Written out in the sweep file.
    List(Vec<Value>),
    /// `linspace = [start, stop, num]`.
    Linspace { start: f64, stop: f64, num: usize },
    /// `logspace = [start, stop, num]` (start, stop > 0).
    Logspace { start: f64, stop: f64, num: usize },
    /// Coordinate `axis` of a sampling design's `num` points (`[sample]`),
    /// in `range = [lo, hi]`, log-scaled or not, integers for an integer
    /// param.
    Sample(Sample),
}

/// One axis of a sampling design.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Sample {
    pub design: super::design::Design,
    pub axis: usize,
    pub num: usize,
    pub seed: u64,
    pub lo: f64,
    pub hi: f64,
    pub log: bool,
    pub integer: bool,
}

impl Sample {
    pub fn at(&self, i: usize) -> f64 {
        let u = super::design::unit(self.design, i as u64, self.num as u64, self.axis, self.seed);
        if self.integer {
            (self.lo + (u * (self.hi - self.lo + 1.0)).floor()).min(self.hi)
        } else if self.log {
            (self.lo * (self.hi / self.lo).powf(u)).clamp(self.lo, self.hi)
        } else {
            (self.lo + u * (self.hi - self.lo)).clamp(self.lo, self.hi)
        }
    }
}

/// A sweep's axes as its sidecar records them: name and values.
pub fn from_sidecar(sc: &crate::output::sidecar::Sidecar) -> Option<Vec<(String, Values)>> {
    sc.sweep["axes"]
        .as_array()?
        .iter()
        .map(|a| {
            Some((
                a["name"].as_str()?.to_string(),
                Values::from_json(&a["values"])?,
            ))
        })
        .collect()
}

impl Values {
    /// The values as their `Serialize` wrote them (a sidecar's sweep).
    pub fn from_json(j: &serde_json::Value) -> Option<Values> {
        if let Some(list) = j.as_array() {
            return list
                .iter()
                .map(|v| match v {
                    serde_json::Value::String(s) => Some(Value::Text(s.clone())),
                    v => v.as_f64().map(Value::Num),
                })
                .collect::<Option<Vec<_>>>()
                .map(Values::List);
        }
        let o = j.as_object()?;
        let (key, r) = o.iter().next()?;
        let r = r.as_array()?;
        let (start, stop, num) = (
            r.first()?.as_f64()?,
            r.get(1)?.as_f64()?,
            r.get(2)?.as_u64()? as usize,
        );
        match key.as_str() {
            "linspace" => Some(Values::Linspace { start, stop, num }),
            "logspace" => Some(Values::Logspace { start, stop, num }),
            _ => None,
        }
    }

    pub fn len(&self) -> usize {
        match self {
            Values::List(v) => v.len(),
            Values::Linspace { num, .. } | Values::Logspace { num, .. } => *num,
            Values::Sample(d) => d.num,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Value `i` (< `len()`).
    pub fn get(&self, i: usize) -> Value {
        match self {
            Values::List(v) => v[i].clone(),
            Values::Linspace { start, stop, num } => {
                Value::Num(linspace_at(*start, *stop, *num, i))
            }
            Values::Logspace { start, stop, num } => {
                Value::Num(logspace_at(*start, *stop, *num, i))
            }
            Values::Sample(d) => Value::Num(d.at(i)),
        }
    }

    /// At most `max` (≥ 2) of the values, both ends included, evenly spaced
    /// in index: what validation looks at. A range's values lie between its
    /// ends, and every scene key's allowed set is an interval, so the ends
    /// decide; the rest is a cheap second look. Every scene is validated
    /// again when it runs (an invalid one gets status `invalid`).
    pub fn sample(&self, max: usize) -> Vec<Value> {
        if let Values::Sample(d) = self {
            // A design's values lie in its range: its ends, then draws.
            let mut v = vec![Value::Num(d.lo), Value::Num(d.hi)];
            v.extend((0..d.num.min(max.saturating_sub(2))).map(|i| Value::Num(d.at(i))));
            return v;
        }
        let n = self.len();
        if n <= max {
            return (0..n).map(|i| self.get(i)).collect();
        }
        (0..max)
            .map(|j| self.get(((j as u128 * (n - 1) as u128) / (max - 1) as u128) as usize))
            .collect()
    }
}

impl Serialize for Values {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        match self {
            Values::List(v) => v.serialize(s),
            Values::Sample(d) => {
                use serde::ser::SerializeMap;
                let mut m = s.serialize_map(Some(1))?;
                m.serialize_entry("sample", d)?;
                m.end()
            }
            Values::Linspace { start, stop, num } | Values::Logspace { start, stop, num } => {
                let key = if matches!(self, Values::Linspace { .. }) {
                    "linspace"
                } else {
                    "logspace"
                };
                let mut m = s.serialize_map(Some(1))?;
                m.serialize_entry(key, &(start, stop, num))?;
                m.end()
            }
        }
    }
}

/// Value `i` of `num` evenly spaced ones, start + i·step; the last is `stop`.
pub fn linspace_at(start: f64, stop: f64, num: usize, i: usize) -> f64 {
    // Both ends exactly as written, as in `logspace_at` (here only a start
    // of −0.0 would differ: −0.0 + 0·step is +0.0).
    if num == 1 || i == 0 {
        return start;
    }
    if i + 1 == num {
        return stop;
    }
    let step = (stop - start) / (num - 1) as f64;
    start + i as f64 * step
}

/// Value `i` of `num` geometrically spaced ones (start, stop > 0); the last is `stop`.
pub fn logspace_at(start: f64, stop: f64, num: usize, i: usize) -> f64 {
    // Both ends exactly as written (numpy's geomspace pins them too):
    // exp(ln(0.004)) is 0.004000000000000002, which a filter on 0.004 misses.
    if num == 1 || i == 0 {
        return start;
    }
    if i + 1 == num {
        return stop;
    }
    let (a, b) = (start.ln(), stop.ln());
    let step = (b - a) / (num - 1) as f64;
    (a + i as f64 * step).exp()
}

/// Apply `param = value` to a scene as written. `base` is the validated base
/// scene, used to turn `density` into masses or `[launch]` into velocities
/// before one element is changed.
/// Long (~125 lines) on purpose: one arm per sweepable key, a table a
/// reader scans for the key they sweep.
pub fn apply(spec: &mut SceneSpec, base: &Scene, p: &Param, value: &Value) {
    let n = spec.balls.map_or(base.n, |b| b.max(0) as usize);
    let num = match value {
        Value::Num(x) => *x,
        Value::Text(_) => f64::NAN,
    };
    match p.name.as_str() {
        "balls" => spec.balls = Some(num as i64),
        "radius" => set(&mut spec.radius, p.index, num, n, &base.radius),
        "density" => set(
            &mut spec.density,
            p.index,
            num,
            n,
            &vec![crate::scene::DEFAULT_DENSITY; base.n],
        ),
        "mass" => {
            spec.density = None;
            set(&mut spec.mass, p.index, num, n, &base.mass)
        }
        "young_modulus" => set(
            &mut spec.young_modulus,
            p.index,
            num,
            n,
            &base.young_modulus,
        ),
        "poisson_ratio" => set(
            &mut spec.poisson_ratio,
            p.index,
            num,
            n,
            &base.poisson_ratio,
        ),
        "gap" => set(&mut spec.gap, p.index, num, n.saturating_sub(1), &base.gap),
        "glue" => {
            spec.glue = Some(match value {
                Value::Text(s) => s.clone(),
                Value::Num(x) => x.to_string(),
            })
        }
        "velocity" => {
            // A scalar `velocity` is every ball's: broadcast it first.
            let mut v = match spec.velocity.take() {
                Some(PerBall::List(l)) => l,
                Some(PerBall::Scalar(x)) => vec![x; n],
                None => base.velocity.clone(),
            };
            spec.launch = None;
            let i = p.index.unwrap_or(0);
            if v.len() <= i {
                v.resize(i + 1, 0.0);
            }
            v[i] = num;
            spec.velocity = Some(PerBall::List(v));
        }
        "launch.balls" => {
            spec.launch.get_or_insert_with(LaunchSpec::default).balls = Some(num as i64)
        }
        "launch.height" => spec.launch.get_or_insert_with(LaunchSpec::default).height = Some(num),
        "launch.velocity" => {
            spec.launch.get_or_insert_with(LaunchSpec::default).velocity = Some(num)
        }
        "restitution" => {
            spec.damping
                .get_or_insert_with(DampingSpec::default)
                .restitution = Some(num)
        }
        "air_drag" => {
            spec.damping
                .get_or_insert_with(DampingSpec::default)
                .air_drag = Some(num)
        }
        "length" => {
            spec.pendulum
                .get_or_insert_with(PendulumSpec::default)
                .length = Some(num)
        }
        "gravity" => {
            spec.pendulum
                .get_or_insert_with(PendulumSpec::default)
                .gravity = Some(num)
        }
        "duration" => spec.stop.get_or_insert_with(StopSpec::default).duration = Some(num),
        "tolerance" => {
            let s = spec.solver.get_or_insert_with(SolverSpec::default);
            s.tolerance = Some(num);
            s.dt = None;
        }
        "dt" => {
            let s = spec.solver.get_or_insert_with(SolverSpec::default);
            s.dt = Some(num);
            s.tolerance = None;
        }
        "walls.precompression" => walls(spec).precompression = Some(num),
        "walls.young_modulus" => walls(spec).young_modulus = Some(num),
        "walls.poisson_ratio" => walls(spec).poisson_ratio = Some(num),
        "pulse.bead" => pulse(spec).bead = Some(num as i64),
        "pulse.force" => pulse(spec).force = Some(num),
        "pulse.duration" => pulse(spec).duration = Some(num),
        "taper.ratio" => spec.taper.get_or_insert_with(TaperSpec::default).ratio = Some(num),
        "impurity.radius" => impurity(spec).radius = Some(num),
        "impurity.density" => impurity(spec).density = Some(num),
        "impurity.mass" => {
            let i = impurity(spec);
            i.density = None;
            i.mass = Some(num)
        }
        "impurity.young_modulus" => impurity(spec).young_modulus = Some(num),
        "impurity.poisson_ratio" => impurity(spec).poisson_ratio = Some(num),
        "gravity.g" => {
            spec.gravity
                .get_or_insert_with(crate::scene::spec::GravitySpec::default)
                .g = Some(num)
        }
        "damping.viscosity" => {
            spec.damping
                .get_or_insert_with(DampingSpec::default)
                .viscosity = Some(num)
        }
        "damping.restitution" => {
            spec.damping
                .get_or_insert_with(DampingSpec::default)
                .restitution = Some(num)
        }
        "damping.air_drag" => {
            spec.damping
                .get_or_insert_with(DampingSpec::default)
                .air_drag = Some(num)
        }
        "drive.bead" => drive(spec).bead = Some(num as i64),
        "drive.force" => drive(spec).force = Some(num),
        "drive.frequency" => drive(spec).frequency = Some(num),
        "drive.duration" => drive(spec).duration = Some(num),
        "piston.velocity" => {
            spec.piston
                .get_or_insert_with(crate::scene::spec::PistonSpec::default)
                .velocity = Some(num)
        }
        name if p.kind == Kind::Pattern => {
            let pat = spec.pattern.get_or_insert_with(PatternSpec::default);
            if let Some(v) = pattern_slot_mut(pat, name) {
                let v = v.get_or_insert_with(Vec::new);
                let i = p.index.unwrap_or(0);
                if v.len() <= i {
                    v.resize(i + 1, f64::NAN);
                }
                v[i] = num;
            }
        }
        other => unreachable!("parameter {other} passed Param::parse"),
    }
}

fn walls(spec: &mut SceneSpec) -> &mut WallsSpec {
    spec.walls.get_or_insert_with(WallsSpec::default)
}

fn pulse(spec: &mut SceneSpec) -> &mut PulseSpec {
    spec.pulse.get_or_insert_with(PulseSpec::default)
}

fn drive(spec: &mut SceneSpec) -> &mut crate::scene::spec::DriveSpec {
    spec.drive.get_or_insert_with(Default::default)
}

fn impurity(spec: &mut SceneSpec) -> &mut ImpuritySpec {
    spec.impurity.get_or_insert_with(ImpuritySpec::default)
}

/// Set a per-ball quantity; a quantity the scene did not write starts from
/// the base scene's resolved values (`fallback`) — one value for every ball
/// when they are all equal, so that a `balls` axis can change N.
fn set(slot: &mut Option<PerBall>, index: Option<usize>, value: f64, n: usize, fallback: &[f64]) {
    let pb = slot.get_or_insert_with(|| match fallback.first() {
        Some(&x) if fallback.iter().all(|&y| y == x) => PerBall::Scalar(x),
        _ => PerBall::List(fallback.to_vec()),
    });
    pb.set(index, value, n);
}

/// The `[pattern]` array a `pattern.*` parameter names.
fn pattern_slot<'a>(p: &'a PatternSpec, name: &str) -> Option<&'a Vec<f64>> {
    match name {
        "pattern.radius" => p.radius.as_ref(),
        "pattern.density" => p.density.as_ref(),
        "pattern.mass" => p.mass.as_ref(),
        "pattern.young_modulus" => p.young_modulus.as_ref(),
        "pattern.poisson_ratio" => p.poisson_ratio.as_ref(),
        _ => None,
    }
}

fn pattern_slot_mut<'a>(p: &'a mut PatternSpec, name: &str) -> Option<&'a mut Option<Vec<f64>>> {
    match name {
        "pattern.radius" => Some(&mut p.radius),
        "pattern.density" => Some(&mut p.density),
        "pattern.mass" => Some(&mut p.mass),
        "pattern.young_modulus" => Some(&mut p.young_modulus),
        "pattern.poisson_ratio" => Some(&mut p.poisson_ratio),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_hit_both_ends_exactly() {
        let linspace = |a, b, n| {
            (0..n)
                .map(|i| linspace_at(a, b, n, i))
                .collect::<Vec<f64>>()
        };
        let logspace = |a, b, n| {
            (0..n)
                .map(|i| logspace_at(a, b, n, i))
                .collect::<Vec<f64>>()
        };
        let l = linspace(0.0, 2e-5, 100);
        assert_eq!((l[0], l[99], l.len()), (0.0, 2e-5, 100));
        assert_eq!(l[37], 37.0 * (2e-5 / 99.0));
        let g = logspace(0.1, 10.0, 5);
        assert_eq!(g[4], 10.0);
        for (x, want) in
            g.iter()
                .zip([0.1, 1.0 / 3.1622776601683795, 1.0, 3.1622776601683795, 10.0])
        {
            assert!((x / want - 1.0).abs() < 1e-14, "{x} {want}");
        }
    }

    #[test]
    fn params_parse_with_indices() {
        assert_eq!(Param::parse("mass[2]").unwrap().index, Some(2));
        assert_eq!(Param::parse("gap").unwrap().kind, Kind::PerContact);
        assert!(Param::parse("velocity").is_err());
        assert!(Param::parse("balls[1]").is_err());
        assert!(Param::parse("mass[x]").is_err());
        let p = |s: &str| Param::parse(s).unwrap();
        assert!(p("mass[2]").overlaps(&p("density")));
        assert!(p("mass").overlaps(&p("mass[1]")));
        assert!(!p("mass[1]").overlaps(&p("mass[2]")));
        assert!(!p("velocity[0]").overlaps(&p("velocity[1]")));
        assert!(p("velocity[0]").overlaps(&p("launch.height")));
        assert!(p("launch.balls").overlaps(&p("velocity[3]")));
        assert!(!p("launch.balls").overlaps(&p("launch.height")));
        assert!(p("dt").overlaps(&p("tolerance")));
        assert!(!p("gap").overlaps(&p("mass")));
        assert!(Param::parse("mas")
            .unwrap_err()
            .contains("did you mean `mass`"));
    }
}
