//! Sweeps (docs/SPEC.md §4): a base scene and `[[axis]]` tables; the cartesian
//! product, scene id = row-major index with the first axis slowest. Scenes are
//! produced one id at a time, never materialised as a whole.

pub mod axis;
pub mod design;
pub mod pipeline;
pub mod points;
pub mod refine;
pub mod run;
pub mod session;
pub mod shard;

use std::path::Path;

use serde::{Deserialize, Serialize};
use toml::Spanned;

use crate::engine::{Overrides, Solver};
use crate::error::{InputError, Source};
use crate::output::row::{ColType, Field};
use crate::scene::spec::RawScene;
use crate::scene::{Scene, SceneSpec};
pub use axis::{Param, Value, Values};

/// Most scenes one sweep may have (refused before anything is allocated).
pub const MAX_SCENES: u64 = 1_000_000_000;

/// Values of one axis that sweep validation tries (all of a shorter axis).
pub const VALIDATION_SAMPLES: usize = 1024;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSweep {
    #[allow(dead_code)]
    description: Option<String>,
    scene: Option<Spanned<toml::Value>>,
    axis: Option<Vec<Spanned<RawAxis>>>,
    refine: Option<Spanned<RawRefine>>,
    points: Option<Spanned<RawPoints>>,
    sample: Option<Spanned<RawSample>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPoints {
    file: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSample {
    design: Option<String>,
    points: Option<i64>,
    seed: Option<i64>,
}

/// How scene ids map to axis values.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Layout {
    /// The cartesian product of the axes (first axis slowest).
    Grid,
    /// `[points]`: scene i is row i of the file (every axis at index i).
    Points { file: String },
    /// `[sample]`: scene i is point i of a design (every axis at index i).
    Sample {
        design: design::Design,
        points: u64,
        seed: u64,
    },
}

impl Layout {
    fn is_grid(&self) -> bool {
        *self == Layout::Grid
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRefine {
    column: Option<String>,
    threshold: Option<f64>,
    stride: Option<i64>,
}

/// Read again for an inline `[scene]`, so its spans point into the sweep file.
#[derive(Deserialize)]
struct InlineScene {
    scene: RawScene,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawAxis {
    param: Option<String>,
    values: Option<Vec<toml::Value>>,
    linspace: Option<Vec<f64>>,
    logspace: Option<Vec<f64>>,
    range: Option<Vec<f64>>,
    scale: Option<String>,
}

#[derive(Clone, Debug, Serialize)]
pub struct Axis {
    /// The `param` text as written: the CSV column name.
    pub name: String,
    pub param: Param,
    pub values: Values,
    /// Line of its `[[axis]]` table in the sweep file.
    #[serde(skip)]
    pub line: Option<usize>,
}

#[derive(Clone, Debug, Serialize)]
pub struct Sweep {
    #[serde(skip)]
    pub origin: String,
    /// Files this sweep was read from (the sweep file, a scene file it
    /// names): an output must never be one of them.
    #[serde(skip)]
    pub inputs: Vec<std::path::PathBuf>,
    pub description: Option<String>,
    /// The base scene as written (after defaults are known: see `base`).
    pub scene: SceneSpec,
    #[serde(skip)]
    pub base: Scene,
    pub axes: Vec<Axis>,
    pub total: u64,
    /// Largest chain length over the sweep: the number of `v_i` columns.
    pub width: usize,
    /// Adaptive refinement (`[refine]`): only the scenes a phase diagram of
    /// one column needs (`refine.rs`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refine: Option<refine::RefineSpec>,
    /// A grid, a point list or a sampling design.
    #[serde(skip_serializing_if = "Layout::is_grid")]
    pub layout: Layout,
}

impl Sweep {
    pub fn load(path: &Path) -> Result<Sweep, InputError> {
        let mut s = Self::parse(
            &Source::read(path)?,
            path.parent().unwrap_or(Path::new(".")),
        )?;
        s.inputs.insert(0, path.to_path_buf());
        Ok(s)
    }

    /// Parse a sweep document; `dir` resolves a relative `scene = "file"`.
    pub fn parse(src: &Source, dir: &Path) -> Result<Sweep, InputError> {
        let raw: RawSweep = src.parse_toml()?;
        let origin = src.name.clone();
        let mut inputs = Vec::new();
        let invalid =
            |line: Option<usize>, key: &str, value: String, allowed: String| InputError::Invalid {
                origin: origin.clone(),
                line,
                key: key.to_string(),
                value,
                allowed,
            };
        let scene_spec = match &raw.scene {
            None => {
                return Err(InputError::Missing {
                    origin: origin.clone(),
                    line: None,
                    key: "scene".into(),
                    help: "`scene = \"file.toml\"` (relative to the sweep file) or an inline [scene] table".into(),
                })
            }
            Some(s) => match s.get_ref() {
                toml::Value::String(file) => {
                    let p = dir.join(file);
                    let scene_src = Source::read(&p)?;
                    inputs.push(p);
                    SceneSpec::parse(&scene_src)?
                }
                toml::Value::Table(_) => {
                    let inline: InlineScene = src.parse_toml()?;
                    SceneSpec::from_raw(src, inline.scene)?
                }
                other => {
                    return Err(invalid(
                        Some(src.line(s.span().start)),
                        "scene",
                        other.to_string(),
                        "a scene file name (string) or a [scene] table".into(),
                    ))
                }
            },
        };
        let base = scene_spec.validate()?;

        let mut layout = Layout::Grid;
        if let Some(sm) = &raw.sample {
            let line = Some(src.line(sm.span().start));
            let sm = sm.get_ref();
            let design = sm.design.as_deref().unwrap_or("(missing)");
            let Some(d) = design::Design::parse(design) else {
                return Err(invalid(
                    line,
                    "sample.design",
                    format!("{design:?}"),
                    "\"sobol\", \"lhs\" or \"random\"".into(),
                ));
            };
            let points = match sm.points {
                Some(n) if n >= 1 && n as u64 <= axis::MAX_AXIS_VALUES as u64 => n as u64,
                other => {
                    return Err(invalid(
                        line,
                        "sample.points",
                        other.map_or("(missing)".into(), |n| n.to_string()),
                        format!(
                            "the number of scenes to draw, 1 ..= {}",
                            axis::MAX_AXIS_VALUES
                        ),
                    ))
                }
            };
            let seed = match sm.seed {
                None => 0,
                Some(x) if x >= 0 => x as u64,
                Some(x) => {
                    return Err(invalid(
                        line,
                        "sample.seed",
                        x.to_string(),
                        "an integer ≥ 0".into(),
                    ))
                }
            };
            if raw.points.is_some() {
                return Err(invalid(
                    line,
                    "sample",
                    "with [points]".into(),
                    "one of [sample] and [points]".into(),
                ));
            }
            layout = Layout::Sample {
                design: d,
                points,
                seed,
            };
        }
        let mut axes = Vec::new();
        if let Some(pt) = &raw.points {
            let line = Some(src.line(pt.span().start));
            if raw.axis.is_some() {
                return Err(invalid(
                    line,
                    "points",
                    "with [[axis]]".into(),
                    "either [points] (the params are the file's columns) or [[axis]] tables".into(),
                ));
            }
            let Some(file) = pt.get_ref().file.clone() else {
                return Err(InputError::Missing {
                    origin: origin.clone(),
                    line,
                    key: "points.file".into(),
                    help: "a CSV table, relative to the sweep file: a header naming the params, one row per scene".into(),
                });
            };
            let path = dir.join(&file);
            for a in points::read(&path, &scene_spec, &base)? {
                axes.push((None, a));
            }
            inputs.push(path);
            layout = Layout::Points { file };
        }
        let sample = match &layout {
            Layout::Sample {
                design,
                points,
                seed,
            } => Some((*design, *points, *seed)),
            _ => None,
        };
        for a in raw.axis.unwrap_or_default() {
            let line = Some(src.line(a.span().start));
            let a = a.into_inner();
            let Some(name) = a.param else {
                return Err(InputError::Missing {
                    origin: origin.clone(),
                    line,
                    key: "axis.param".into(),
                    help: "the scene key this axis varies, e.g. \"mass[2]\" or \"gap\"".into(),
                });
            };
            let param = Param::parse(&name)
                .map_err(|allowed| invalid(line, "axis.param", format!("{name:?}"), allowed))?;
            if let Some((l0, a0)) = axes
                .iter()
                .find(|(_, b): &&(Option<usize>, Axis)| b.param.overlaps(&param))
            {
                return Err(invalid(
                    line,
                    "axis.param",
                    format!("{name:?}"),
                    format!(
                        "sets what the axis {:?}{} already sets: each scene quantity may have one axis",
                        a0.name,
                        l0.map_or(String::new(), |l| format!(" (line {l})"))
                    ),
                ));
            }
            let values = if let Some((d, num, seed)) = sample {
                let bad = |allowed: &str| {
                    invalid(
                        line,
                        &name,
                        format!("{:?}", a.range.as_deref().unwrap_or_default()),
                        allowed.into(),
                    )
                };
                if a.values.is_some() || a.linspace.is_some() || a.logspace.is_some() {
                    return Err(bad("with [sample], each axis gives `range = [lo, hi]` (and optionally `scale = \"log\"`), not values/linspace/logspace"));
                }
                let log = match a.scale.as_deref() {
                    None | Some("linear") => false,
                    Some("log") => true,
                    Some(other) => {
                        return Err(invalid(
                            line,
                            "scale",
                            format!("{other:?}"),
                            "\"linear\" or \"log\"".into(),
                        ))
                    }
                };
                let (lo, hi) = match a.range.as_deref() {
                    Some([lo, hi]) if lo.is_finite() && hi.is_finite() && lo <= hi => (*lo, *hi),
                    _ => return Err(bad("range = [lo, hi] with finite lo ≤ hi")),
                };
                if log && lo <= 0.0 {
                    return Err(bad("lo > 0 for scale = \"log\""));
                }
                let integer = param.kind == axis::Kind::Integer;
                if integer && (lo.fract() != 0.0 || hi.fract() != 0.0) {
                    return Err(bad("whole numbers: this parameter is an integer"));
                }
                if param.kind == axis::Kind::Glue {
                    return Err(bad(
                        "a number: glue patterns are not sampled (list them with [points])",
                    ));
                }
                if d == design::Design::Sobol && axes.len() >= design::MAX_SOBOL_AXES {
                    return Err(bad(&format!(
                        "at most {} axes in a Sobol design",
                        design::MAX_SOBOL_AXES
                    )));
                }
                Values::Sample(axis::Sample {
                    design: d,
                    axis: axes.len(),
                    num: num as usize,
                    seed,
                    lo,
                    hi,
                    log,
                    integer,
                })
            } else {
                if a.range.is_some() || a.scale.is_some() {
                    return Err(invalid(
                        line,
                        &name,
                        "range/scale".into(),
                        "`range` and `scale` belong to a sampling design: add a [sample] table, or give values/linspace/logspace".into(),
                    ));
                }
                let kinds = [
                    a.values.is_some(),
                    a.linspace.is_some(),
                    a.logspace.is_some(),
                ];
                if kinds.iter().filter(|k| **k).count() != 1 {
                    return Err(invalid(
                        line,
                        &name,
                        format!("{} range kinds", kinds.iter().filter(|k| **k).count()),
                        "exactly one of `values`, `linspace`, `logspace`".into(),
                    ));
                }
                let range = |key: &str, r: &[f64]| -> Result<(f64, f64, usize), InputError> {
                    let bad = || {
                        invalid(line, key, format!("{r:?}"), format!("[start, stop, num] with finite start/stop and an integer num in 1 ..= {}", axis::MAX_AXIS_VALUES))
                    };
                    match r {
                        [a, b, n]
                            if a.is_finite()
                                && b.is_finite()
                                && n.fract() == 0.0
                                && *n >= 1.0
                                && *n <= axis::MAX_AXIS_VALUES as f64 =>
                        {
                            Ok((*a, *b, *n as usize))
                        }
                        [_, _, n] if *n < 1.0 => Err(invalid(
                            line,
                            key,
                            format!("{r:?}"),
                            "at least 1 point (num ≥ 1)".into(),
                        )),
                        _ => Err(bad()),
                    }
                };
                let values = if let Some(v) = &a.values {
                    if v.is_empty() {
                        return Err(invalid(
                            line,
                            "values",
                            "[]".into(),
                            "at least one value".into(),
                        ));
                    }
                    if v.len() > axis::MAX_AXIS_VALUES {
                        return Err(invalid(
                            line,
                            "values",
                            format!("{} values", v.len()),
                            format!("at most {}", axis::MAX_AXIS_VALUES),
                        ));
                    }
                    Values::List(
                        v.iter()
                            .map(|x| match x {
                                toml::Value::Float(f) => Ok(Value::Num(*f)),
                                toml::Value::Integer(i) => Ok(Value::Num(*i as f64)),
                                toml::Value::String(s) => Ok(Value::Text(s.clone())),
                                other => Err(invalid(
                                    line,
                                    "values",
                                    other.to_string(),
                                    "numbers, or strings for `glue`".into(),
                                )),
                            })
                            .collect::<Result<_, _>>()?,
                    )
                } else if let Some(r) = &a.linspace {
                    let (start, stop, num) = range("linspace", r)?;
                    Values::Linspace { start, stop, num }
                } else {
                    let r = a.logspace.as_deref().unwrap_or_default();
                    let (start, stop, num) = range("logspace", r)?;
                    if start <= 0.0 || stop <= 0.0 {
                        return Err(invalid(
                            line,
                            "logspace",
                            format!("{r:?}"),
                            "start and stop must be > 0 (they are values, not exponents)".into(),
                        ));
                    }
                    Values::Logspace { start, stop, num }
                };
                if param.kind == axis::Kind::Integer {
                    // An integer param run as something else under its own label
                    // would mislabel every row: only whole numbers.
                    for i in 0..values.len() {
                        if let Value::Num(x) = values.get(i) {
                            if x.fract() != 0.0 || !x.is_finite() {
                                return Err(invalid(
                                    line,
                                    &name,
                                    format!("{x} (value {i} of the axis)"),
                                    "whole numbers only: this parameter is an integer".into(),
                                ));
                            }
                        }
                    }
                }
                values
            };
            axes.push((
                line,
                Axis {
                    name,
                    param,
                    values,
                    line,
                },
            ));
        }

        if layout != Layout::Grid && axes.is_empty() {
            return Err(invalid(
                None,
                "axis",
                "(none)".into(),
                "a [sample] needs `[[axis]]` tables with `range = [lo, hi]`".into(),
            ));
        }
        let mut total: u64 = 1;
        for (line, a) in axes.iter().filter(|_| layout == Layout::Grid) {
            total = total
                .checked_mul(a.values.len() as u64)
                .filter(|t| *t <= MAX_SCENES)
                .ok_or_else(|| {
                    invalid(
                        *line,
                        &a.name,
                        format!("{} values", a.values.len()),
                        format!("the product of all axes must stay ≤ {MAX_SCENES} scenes"),
                    )
                })?;
        }
        if layout != Layout::Grid {
            total = axes[0].1.values.len() as u64;
        }
        let balls_axis = axes.iter().find(|(_, a)| a.param.name == "balls");
        let num = |v: &Value| if let Value::Num(x) = v { *x } else { 0.0 };
        let width = match balls_axis {
            Some((_, a)) => (0..a.values.len())
                .map(|i| num(&a.values.get(i)) as usize)
                .max()
                .unwrap_or(base.n)
                .max(base.n),
            None => base.n,
        };

        // Every axis value must make a valid scene on its own: typos and
        // out-of-range values fail now, before any work. Long ranges are
        // checked at their ends and VALIDATION_SAMPLES evenly spaced values.
        let samples: Vec<Vec<Value>> = axes
            .iter()
            .map(|(_, a)| a.values.sample(VALIDATION_SAMPLES))
            .collect();
        // A point list's rows were each checked whole when it was read.
        let per_axis = !matches!(layout, Layout::Points { .. });
        for (k, (line, a)) in axes.iter().enumerate().filter(|_| per_axis) {
            for v in &samples[k] {
                let n = if balls_axis.is_some() { width } else { base.n };
                if let (Some(i), Some(lim)) = (a.param.index, a.param.index_limit(n)) {
                    if i >= lim {
                        return Err(invalid(
                            *line,
                            &a.name,
                            format!("index {i}"),
                            format!("an index in 0 ..= {} for {} balls", lim - 1, n),
                        ));
                    }
                }
                let mut spec = scene_spec.clone();
                axis::apply(&mut spec, &base, &a.param, v);
                // A value may need another axis' value to be valid (glue "=---"
                // with two balls launched): it is refused only when no single
                // value of any other axis makes it valid.
                let valid_with_another = |spec: &SceneSpec| {
                    axes.iter()
                        .zip(&samples)
                        .enumerate()
                        .any(|(j, ((_, b), ws))| {
                            j != k
                                && ws.iter().any(|w| {
                                    let mut s2 = spec.clone();
                                    axis::apply(&mut s2, &base, &b.param, w);
                                    s2.validate().is_ok()
                                })
                        })
                };
                if let Err(e) = spec.validate() {
                    if valid_with_another(&spec) {
                        continue;
                    }
                    return Err(invalid(
                        *line,
                        &a.name,
                        v.to_string(),
                        format!("makes an invalid scene: {e}"),
                    ));
                }
            }
        }
        let mut sweep = Sweep {
            origin: origin.clone(),
            inputs,
            description: raw.description,
            scene: scene_spec,
            base,
            axes: axes.into_iter().map(|(_, a)| a).collect(),
            total,
            width,
            refine: None,
            layout,
        };
        if let Some(r) = raw.refine {
            let line = Some(src.line(r.span().start));
            if sweep.layout != Layout::Grid {
                return Err(invalid(
                    line,
                    "refine",
                    "with [points] or [sample]".into(),
                    "a grid of [[axis]] tables to refine".into(),
                ));
            }
            sweep.refine = Some(sweep.refine_spec(r.into_inner(), &|key, value, allowed| {
                invalid(line, key, value, allowed)
            })?);
        }
        Ok(sweep)
    }

    /// Check a `[refine]` table against this sweep's columns.
    fn refine_spec(
        &self,
        r: RawRefine,
        invalid: &dyn Fn(&str, String, String) -> InputError,
    ) -> Result<refine::RefineSpec, InputError> {
        let header = crate::output::row::header(&self.axis_names(), self.shape());
        let types = self.column_types();
        let Some(column) = r.column else {
            return Err(invalid(
                "refine.column",
                "(missing)".into(),
                "the column the diagram is about, e.g. \"ejected\" or \"status\"".into(),
            ));
        };
        let Some(k) = header.iter().position(|h| *h == column) else {
            return Err(invalid(
                "refine.column",
                format!("{column:?}"),
                format!("a column of this sweep's table: {}", header.join(", ")),
            ));
        };
        if k == 0 || k <= self.axes.len() {
            return Err(invalid(
                "refine.column",
                format!("{column:?}"),
                "an outcome column (not `id` or an axis)".into(),
            ));
        }
        match r.threshold {
            Some(t) if !(t.is_finite() && t >= 0.0) => {
                return Err(invalid(
                    "refine.threshold",
                    t.to_string(),
                    "a number ≥ 0: corners differing by more than it are refined".into(),
                ))
            }
            None if types[k] == crate::output::row::ColType::Num => {
                return Err(invalid(
                    "refine.column",
                    format!("{column:?}"),
                    "a continuous column needs `threshold` (corners differing by more than it are refined); without one, a categorical column: ejected, status, steps, contacts".into(),
                ))
            }
            _ => {}
        }
        if self.axes.iter().all(|a| a.values.len() < 2) {
            return Err(invalid(
                "refine",
                "(no axis with 2 or more values)".into(),
                "a grid to refine: at least one `[[axis]]` with 2 or more values".into(),
            ));
        }
        let dims = self.dims();
        let stride = match r.stride {
            None => refine::default_stride(&dims),
            Some(s) if s >= 1 && (s as u64).is_power_of_two() => s as u64,
            Some(s) => {
                return Err(invalid(
                    "refine.stride",
                    s.to_string(),
                    "a power of two ≥ 1: the coarse level's spacing in grid steps".into(),
                ))
            }
        };
        Ok(refine::RefineSpec {
            column,
            threshold: r.threshold,
            stride,
        })
    }

    /// Number of values of each axis (the grid's shape).
    pub fn dims(&self) -> Vec<u64> {
        self.axes.iter().map(|a| a.values.len() as u64).collect()
    }

    /// Flags against this sweep's file: an axis that varies what a flag sets
    /// is an error naming both (the CSV would show axis values never used),
    /// and so is a flag that disagrees with the base scene's `[solver]`.
    pub fn check_overrides(&self, o: &Overrides) -> Result<(), InputError> {
        if let Some(t) = o.tolerance {
            if let Some(a) = self
                .axes
                .iter()
                .find(|a| matches!(a.param.name.as_str(), "tolerance" | "dt"))
            {
                return Err(InputError::Flag {
                    flag: "--tolerance".into(),
                    value: format!("{t:e}"),
                    allowed: format!(
                        "{}{}: the axis `{}` varies the step, and the flag would replace every value it labels: remove the flag or the axis",
                        self.origin,
                        a.line.map_or(String::new(), |l| format!(":{l}")),
                        a.name
                    ),
                });
            }
        }
        let scene_origin = match self.inputs.get(1) {
            Some(p) => p.display().to_string(),
            None => self.origin.clone(),
        };
        Solver::check_flags_against(&self.base, o, &scene_origin)
    }

    /// The per-ball columns of this sweep's table: displacements when its
    /// scenes hang on strings (`[pendulum]`, or a `length`/`gravity` axis).
    pub fn shape(&self) -> crate::output::row::Shape {
        crate::output::row::Shape {
            width: self.width,
            pendulum: self.base.pendulum.is_some()
                || self
                    .axes
                    .iter()
                    .any(|a| matches!(a.param.name.as_str(), "length" | "gravity")),
        }
    }

    /// Each axis with its index in scene `id` (row-major, first axis
    /// slowest), without allocating: the one place ids become axis values.
    fn axis_indices(&self, id: u64) -> impl Iterator<Item = (&Axis, usize)> + '_ {
        let mut stride = self.total;
        let grid = self.layout == Layout::Grid;
        self.axes.iter().map(move |a| {
            if !grid {
                return (a, id as usize);
            }
            let n = a.values.len() as u64;
            stride /= n;
            (a, ((id / stride) % n) as usize)
        })
    }

    /// Index into each axis of scene `id` (first axis slowest).
    pub fn indices(&self, id: u64) -> Vec<usize> {
        self.axis_indices(id).map(|(_, i)| i).collect()
    }

    /// Scene `id` as written (the base scene with its axis values), for a
    /// scene file.
    pub fn scene_spec(&self, id: u64) -> anyhow::Result<SceneSpec> {
        anyhow::ensure!(
            id < self.total,
            "no scene {id}: the sweep has {}",
            self.total
        );
        let mut spec = self.scene.clone();
        for (a, i) in self.axis_indices(id) {
            axis::apply(&mut spec, &self.base, &a.param, &a.values.get(i));
        }
        Ok(spec)
    }

    /// The scene with id `id`, or why this combination of values is invalid.
    pub fn scene(&self, id: u64) -> Result<Scene, InputError> {
        if self.axes.is_empty() {
            return Ok(self.base.clone());
        }
        let mut spec = self.scene.clone();
        for (a, i) in self.axis_indices(id) {
            axis::apply(&mut spec, &self.base, &a.param, &a.values.get(i));
        }
        spec.validate()
    }

    /// The axis columns of scene `id`, as the CSV writes them.
    pub fn axis_fields(&self, id: u64) -> Vec<String> {
        let mut v = Vec::with_capacity(self.axes.len());
        let mut s = String::new();
        self.emit_axis_values(id, &mut |f| match f {
            Field::Num(x) => {
                crate::output::row::num_into(x, &mut s);
                v.push(s.clone())
            }
            Field::Text(t) => v.push(t.to_string()),
            Field::Int(x) => v.push(x.to_string()),
            Field::Null => v.push(String::new()),
        });
        v
    }

    /// The axis columns of scene `id` to `out`, typed (no allocation per row
    /// for numeric axes). Numbers are `Num` on every axis (an integer axis
    /// too: its CSV text is the number's), text `Text`.
    pub fn emit_axis_values(&self, id: u64, out: &mut dyn FnMut(Field)) {
        for (a, i) in self.axis_indices(id) {
            match a.values.get(i) {
                Value::Num(x) => out(Field::Num(x)),
                Value::Text(t) => out(Field::Text(&t)),
            }
        }
    }

    /// The type of each axis column: integer params are integers, `glue`
    /// text, every other param a number.
    pub fn axis_types(&self) -> Vec<ColType> {
        self.axes
            .iter()
            .map(|a| match a.param.kind {
                axis::Kind::Integer => ColType::Int,
                axis::Kind::Glue => ColType::Text,
                _ => ColType::Num,
            })
            .collect()
    }

    /// The type of every column, parallel to the header.
    pub fn column_types(&self) -> Vec<ColType> {
        crate::output::row::column_types(&self.axis_types(), self.shape())
    }

    pub fn axis_names(&self) -> Vec<String> {
        self.axes.iter().map(|a| a.name.clone()).collect()
    }
}
