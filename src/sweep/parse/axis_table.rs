//! One `[[axis]]` table of a sweep file: its parameter, checked against the
//! axes before it, and its values (a list, `linspace`, `logspace`, or a
//! `range` drawn by a `[sample]` design).

use serde::Deserialize;
use toml::Spanned;

use super::Ctx;
use crate::error::InputError;
use crate::sweep::{axis, design, Axis, Param, Value, Values};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawAxis {
    param: Option<String>,
    values: Option<Vec<toml::Value>>,
    linspace: Option<Vec<f64>>,
    logspace: Option<Vec<f64>>,
    range: Option<Vec<f64>>,
    scale: Option<String>,
}

impl Ctx<'_> {
    /// One `[[axis]]` table, checked against the axes before it; `sample`:
    /// the design when the sweep has a `[sample]`.
    pub(super) fn axis(
        &self,
        a: Spanned<RawAxis>,
        axes: &[(Option<usize>, Axis)],
        sample: Option<(design::Design, u64, u64)>,
    ) -> Result<(Option<usize>, Axis), InputError> {
        let (cx, src) = (self, self.src);
        let line = Some(src.line(a.span().start));
        let a = a.into_inner();
        let Some(name) = a.param.clone() else {
            return Err(src.missing(
                line,
                "axis.param",
                "the scene key this axis varies, e.g. \"mass[2]\" or \"gap\"",
            ));
        };
        let param = Param::parse(&name)
            .map_err(|allowed| cx.invalid(line, "axis.param", format!("{name:?}"), allowed))?;
        if let Some((l0, a0)) = axes
            .iter()
            .find(|(_, b): &&(Option<usize>, Axis)| b.param.overlaps(&param))
        {
            return Err(cx.invalid(
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
        let values = match sample {
            Some(design) => cx.sampled_values(&a, line, &name, &param, axes.len(), design)?,
            None => cx.listed_values(&a, line, &name, &param)?,
        };
        Ok((
            line,
            Axis {
                name,
                param,
                values,
                line,
            },
        ))
    }

    /// The values of an axis of a `[sample]` design: `range = [lo, hi]`
    /// (and `scale`), drawn as the design says.
    fn sampled_values(
        &self,
        a: &RawAxis,
        line: Option<usize>,
        name: &str,
        param: &Param,
        axis_index: usize,
        (d, num, seed): (design::Design, u64, u64),
    ) -> Result<Values, InputError> {
        let cx = self;
        let bad = |allowed: &str| {
            cx.invalid(
                line,
                name,
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
                return Err(cx.invalid(
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
        if d == design::Design::Sobol && axis_index >= design::MAX_SOBOL_AXES {
            return Err(bad(&format!(
                "at most {} axes in a Sobol design",
                design::MAX_SOBOL_AXES
            )));
        }
        Ok(Values::Sample(axis::Sample {
            design: d,
            axis: axis_index,
            num: num as usize,
            seed,
            lo,
            hi,
            log,
            integer,
        }))
    }

    /// The values of a grid axis: `values`, `linspace` or `logspace`.
    /// Long (~120 lines) on purpose: each form's checks, with the file,
    /// line, key and allowed range of its error, side by side.
    fn listed_values(
        &self,
        a: &RawAxis,
        line: Option<usize>,
        name: &str,
        param: &Param,
    ) -> Result<Values, InputError> {
        let cx = self;
        if a.range.is_some() || a.scale.is_some() {
            return Err(cx.invalid(
                    line,
                    name,
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
            return Err(cx.invalid(
                line,
                name,
                format!("{} range kinds", kinds.iter().filter(|k| **k).count()),
                "exactly one of `values`, `linspace`, `logspace`".into(),
            ));
        }
        let range = |key: &str, r: &[f64]| -> Result<(f64, f64, usize), InputError> {
            let bad = || {
                cx.invalid(
                    line,
                    key,
                    format!("{r:?}"),
                    format!(
                        "[start, stop, num] with finite start/stop and an integer num in 1 ..= {}",
                        axis::MAX_AXIS_VALUES
                    ),
                )
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
                [_, _, n] if *n < 1.0 => Err(cx.invalid(
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
                return Err(cx.invalid(line, "values", "[]".into(), "at least one value".into()));
            }
            if v.len() > axis::MAX_AXIS_VALUES {
                return Err(cx.invalid(
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
                        other => Err(cx.invalid(
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
                return Err(cx.invalid(
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
                        return Err(cx.invalid(
                            line,
                            name,
                            format!("{x} (value {i} of the axis)"),
                            "whole numbers only: this parameter is an integer".into(),
                        ));
                    }
                }
            }
        }
        Ok(values)
    }
}
