//! Reading a sweep file (docs/SPEC.md §4) into a [`Sweep`]: the base scene,
//! a grid of `[[axis]]` tables, a `[points]` list or a `[sample]` design, and
//! `[refine]`. Each part has its own step; every error names the file, the
//! line, the key, the value and what is allowed.

mod axis_table;

use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use super::{axis, design, points, refine, Axis, Layout, Sweep, Value};
use super::{MAX_SCENES, VALIDATION_SAMPLES};
use crate::error::{InputError, Source};
use crate::scene::spec::RawScene;
use crate::scene::{Scene, SceneSpec};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSweep {
    #[allow(dead_code)]
    description: Option<String>,
    scene: Option<Spanned<toml::Value>>,
    axis: Option<Vec<Spanned<axis_table::RawAxis>>>,
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

/// The base scene of a sweep or problem file `src`: a scene file its
/// `scene` key names (relative to `dir`, added to `inputs`), or its inline
/// `[scene]` table.
pub(crate) fn base_scene(
    src: &Source,
    scene: Option<&Spanned<toml::Value>>,
    dir: &Path,
    inputs: &mut Vec<PathBuf>,
) -> Result<SceneSpec, InputError> {
    Ok(match scene {
        None => {
            return Err(src.missing(
                None,
                "scene",
                "`scene = \"file.toml\"` (relative to the sweep file) or an inline [scene] table",
            ))
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
                return Err(src.invalid(
                    Some(src.line(s.span().start)),
                    "scene",
                    other.to_string(),
                    "a scene file name (string) or a [scene] table".into(),
                ))
            }
        },
    })
}

/// A sweep file being read: its errors carry its name and lines.
struct Ctx<'a> {
    src: &'a Source,
}

impl Ctx<'_> {
    fn invalid(
        &self,
        line: Option<usize>,
        key: &str,
        value: String,
        allowed: String,
    ) -> InputError {
        self.src.invalid(line, key, value, allowed)
    }

    /// The base scene: a file the sweep names, or an inline `[scene]`.
    fn scene(
        &self,
        raw: &RawSweep,
        dir: &Path,
        inputs: &mut Vec<PathBuf>,
    ) -> Result<SceneSpec, InputError> {
        base_scene(self.src, raw.scene.as_ref(), dir, inputs)
    }

    /// `[sample]`: a sampling design's layout.
    fn sample(&self, raw: &RawSweep) -> Result<Option<Layout>, InputError> {
        let (cx, src) = (self, self.src);
        if let Some(sm) = &raw.sample {
            let line = Some(src.line(sm.span().start));
            let sm = sm.get_ref();
            let design = sm.design.as_deref().unwrap_or("(missing)");
            let Some(d) = design::Design::parse(design) else {
                return Err(cx.invalid(
                    line,
                    "sample.design",
                    format!("{design:?}"),
                    "\"sobol\", \"lhs\" or \"random\"".into(),
                ));
            };
            let points = match sm.points {
                Some(n) if n >= 1 && n as u64 <= axis::MAX_AXIS_VALUES as u64 => n as u64,
                other => {
                    return Err(cx.invalid(
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
                    return Err(cx.invalid(
                        line,
                        "sample.seed",
                        x.to_string(),
                        "an integer ≥ 0".into(),
                    ))
                }
            };
            if raw.points.is_some() {
                return Err(cx.invalid(
                    line,
                    "sample",
                    "with [points]".into(),
                    "one of [sample] and [points]".into(),
                ));
            }
            return Ok(Some(Layout::Sample {
                design: d,
                points,
                seed,
            }));
        }
        Ok(None)
    }

    /// `[points]`: the file's name and path and the axes read from it.
    fn points(
        &self,
        raw: &RawSweep,
        dir: &Path,
        scene_spec: &SceneSpec,
        base: &Scene,
    ) -> Result<Option<(String, PathBuf, Vec<Axis>)>, InputError> {
        let (cx, src) = (self, self.src);
        if let Some(pt) = &raw.points {
            let line = Some(src.line(pt.span().start));
            if raw.axis.is_some() {
                return Err(cx.invalid(
                    line,
                    "points",
                    "with [[axis]]".into(),
                    "either [points] (the params are the file's columns) or [[axis]] tables".into(),
                ));
            }
            let Some(file) = pt.get_ref().file.clone() else {
                return Err(src.missing(
                    line,
                    "points.file",
                    "a CSV table, relative to the sweep file: a header naming the params, one row per scene",
                ));
            };
            let path = dir.join(&file);
            let axes = points::read(&path, scene_spec, base)?;
            return Ok(Some((file, path, axes)));
        }
        Ok(None)
    }

    /// Scenes in the sweep: the product of the axes' lengths on a grid (at
    /// most `MAX_SCENES`), else the length of the point list or design.
    fn total(&self, axes: &[(Option<usize>, Axis)], layout: &Layout) -> Result<u64, InputError> {
        let cx = self;
        if *layout != Layout::Grid && axes.is_empty() {
            return Err(cx.invalid(
                None,
                "axis",
                "(none)".into(),
                "a [sample] needs `[[axis]]` tables with `range = [lo, hi]`".into(),
            ));
        }
        let mut total: u64 = 1;
        for (line, a) in axes.iter().filter(|_| *layout == Layout::Grid) {
            total = total
                .checked_mul(a.values.len() as u64)
                .filter(|t| *t <= MAX_SCENES)
                .ok_or_else(|| {
                    cx.invalid(
                        *line,
                        &a.name,
                        format!("{} values", a.values.len()),
                        format!("the product of all axes must stay ≤ {MAX_SCENES} scenes"),
                    )
                })?;
        }
        if *layout != Layout::Grid {
            total = axes[0].1.values.len() as u64;
        }
        Ok(total)
    }

    /// Every axis value must make a valid scene on its own: typos and
    /// out-of-range values fail now, before any work. Long ranges are
    /// checked at their ends and VALIDATION_SAMPLES evenly spaced values.
    fn check_values(
        &self,
        axes: &[(Option<usize>, Axis)],
        scene_spec: &SceneSpec,
        base: &Scene,
        width: usize,
    ) -> Result<(), InputError> {
        let cx = self;
        let balls_axis = axes.iter().find(|(_, a)| a.param.name == "balls");
        // Every axis value must make a valid scene on its own: typos and
        // out-of-range values fail now, before any work. Long ranges are
        // checked at their ends and VALIDATION_SAMPLES evenly spaced values.
        let samples: Vec<Vec<Value>> = axes
            .iter()
            .map(|(_, a)| a.values.sample(VALIDATION_SAMPLES))
            .collect();
        // A point list's rows were each checked whole when it was read.
        for (k, (line, a)) in axes.iter().enumerate() {
            for v in &samples[k] {
                let n = if balls_axis.is_some() { width } else { base.n };
                if let Err(allowed) = a.param.check_index(n, scene_spec) {
                    return Err(cx.invalid(
                        *line,
                        &a.name,
                        format!("index {}", a.param.index.unwrap_or(0)),
                        allowed,
                    ));
                }
                let mut spec = scene_spec.clone();
                axis::apply(&mut spec, base, &a.param, v);
                if let Ok(s) = spec.validate() {
                    if crate::model::kind(&s) != crate::model::kind(base) {
                        return Err(cx.invalid(
                            *line,
                            &a.name,
                            v.to_string(),
                            crate::model::mixed_sweep(base),
                        ));
                    }
                }
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
                                    axis::apply(&mut s2, base, &b.param, w);
                                    s2.validate().is_ok()
                                })
                        })
                };
                if let Err(e) = spec.validate() {
                    if valid_with_another(&spec) {
                        continue;
                    }
                    return Err(cx.invalid(
                        *line,
                        &a.name,
                        v.to_string(),
                        format!("makes an invalid scene: {e}"),
                    ));
                }
            }
            if let Some((v1, v2)) = unused(axes, k, scene_spec, base) {
                return Err(cx.invalid(
                    *line,
                    &a.name,
                    format!("{v1} and {v2}"),
                    "an axis whose values change the scene: these make the same scene (the base scene's [pattern], [taper] or [impurity] sets this quantity, or another key decides it), so the rows would be labelled with values never used; sweep the key that sets it (e.g. pattern.radius[0], impurity.mass)".to_string(),
                ));
            }
        }
        Ok(())
    }
}

/// Two distinct values of axis `k` (its first and last) when they make the
/// same checked scene wherever both are valid — at the base scene and at
/// the first and last value of each other axis — and are valid somewhere:
/// the axis would label rows with values that were never used.
fn unused(
    axes: &[(Option<usize>, Axis)],
    k: usize,
    spec: &SceneSpec,
    base: &Scene,
) -> Option<(Value, Value)> {
    let a = &axes[k].1;
    if a.param.name == "balls" || a.values.len() < 2 {
        return None;
    }
    let (v1, v2) = (a.values.get(0), a.values.get(a.values.len() - 1));
    if v1 == v2 {
        return None;
    }
    let mut contexts: Vec<Option<(&axis::Param, Value)>> = vec![None];
    for (j, (_, b)) in axes.iter().enumerate() {
        if j != k && !b.values.is_empty() {
            contexts.push(Some((&b.param, b.values.get(0))));
            contexts.push(Some((&b.param, b.values.get(b.values.len() - 1))));
        }
    }
    let mut compared = false;
    for c in contexts {
        let at = |v: &Value| {
            let mut s = spec.clone();
            if let Some((p, w)) = &c {
                axis::apply(&mut s, base, p, w);
            }
            axis::apply(&mut s, base, &a.param, v);
            s.validate().ok()
        };
        if let (Some(x), Some(y)) = (at(&v1), at(&v2)) {
            if x != y {
                return None;
            }
            compared = true;
        }
    }
    compared.then_some((v1, v2))
}

/// Largest chain length over the sweep: the number of `v_i` columns.
fn width(axes: &[(Option<usize>, Axis)], base: &Scene) -> usize {
    axes.iter()
        .find(|(_, a)| a.param.name == "balls")
        .and_then(|(_, a)| a.count_span())
        .map_or(base.n, |span| span.1.max(base.n))
}

impl Sweep {
    /// Parse a sweep document; `dir` resolves a relative `scene = "file"`.
    pub fn parse(src: &Source, dir: &Path) -> Result<Sweep, InputError> {
        let raw: RawSweep = src.parse_toml()?;
        let cx = Ctx { src };
        let mut inputs = Vec::new();
        let scene_spec = cx.scene(&raw, dir, &mut inputs)?;
        let base = scene_spec.validate()?;
        let mut layout = cx.sample(&raw)?.unwrap_or(Layout::Grid);
        let mut axes = Vec::new();
        if let Some((file, path, from_points)) = cx.points(&raw, dir, &scene_spec, &base)? {
            axes.extend(from_points.into_iter().map(|a| (None, a)));
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
            let axis = cx.axis(a, &axes, sample)?;
            axes.push(axis);
        }
        let total = cx.total(&axes, &layout)?;
        let width = width(&axes, &base);
        // A point list's rows were each checked whole when it was read.
        if !matches!(layout, Layout::Points { .. }) {
            cx.check_values(&axes, &scene_spec, &base, width)?;
        }
        let axes: Vec<Axis> = axes.into_iter().map(|(_, a)| a).collect();
        let model = crate::model::of(&base, &super::varied(&axes));
        let mut sweep = Sweep {
            origin: src.name.clone(),
            inputs,
            description: raw.description,
            scene: scene_spec,
            base,
            axes,
            total,
            width,
            refine: None,
            layout,
            model,
        };
        if let Some(r) = raw.refine {
            let line = Some(src.line(r.span().start));
            if sweep.layout != Layout::Grid {
                return Err(cx.invalid(
                    line,
                    "refine",
                    "with [points] or [sample]".into(),
                    "a grid of [[axis]] tables to refine".into(),
                ));
            }
            sweep.refine = Some(sweep.refine_spec(r.into_inner(), &|key, value, allowed| {
                cx.invalid(line, key, value, allowed)
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
        let header = self.header();
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
            Some(t)
                if matches!(
                    types[k],
                    crate::output::row::ColType::Text | crate::output::row::ColType::Status
                ) =>
            {
                return Err(invalid(
                    "refine.threshold",
                    t.to_string(),
                    format!("no threshold for `{column}`, a text column: its corners are compared as values (refined where they differ); a threshold is for a numeric column"),
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
}
