//! `cradle optimize` (docs/SPEC.md §10): designs found by an evolution
//! strategy over any sweepable key, each generation one batch of scenes on
//! the backend.
//!
//! A problem file is a base scene (as in a sweep file), `[[variable]]`
//! tables (a key, or a range of indices `radius[1..20]`, continuous in
//! [min, max] on a linear or log scale, or a choice from a list),
//! `[objective]` (minimize or maximize an outcome column), `[[constraint]]`
//! comparisons and `[optimizer]` (method, population, evaluations, seed).
//! The strategy works in the unit cube (`[0, 1]` per variable, mirrored
//! at its faces); a candidate's values are computed from its coordinates,
//! so every row is labelled with the values it ran with. A candidate is
//! *feasible* when its row is `ok` (so within its tolerance: a flagged row
//! never wins) and it meets every constraint; the strategy ranks feasible
//! candidates by the objective, then the others by how far they miss the
//! constraints, then the failed runs.

pub mod cmaes;
pub mod request;

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Deserialize;
use toml::Spanned;

use crate::backend::Backend;
use crate::choice::Choice;
use crate::engine::{Overrides, Status};
use crate::error::{InputError, Source};
use crate::model::Model;
use crate::output::parquet_file;
use crate::output::row::{self, Cell, ColType};
use crate::output::TableKind;
use crate::scene::{Scene, SceneSpec};
use crate::sweep::axis::{self, Kind, Param, Value};
use crate::sweep::design::{hash, unit_of};

/// The search methods (`[optimizer] method`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// CMA-ES (Hansen's tutorial; [`cmaes`]).
    CmaEs,
    /// Uniform random candidates in the variables' ranges: the baseline.
    Random,
}

impl Choice for Method {
    const ALL: &'static [Self] = &[Method::CmaEs, Method::Random];
    fn name(self) -> &'static str {
        match self {
            Method::CmaEs => "cma-es",
            Method::Random => "random",
        }
    }
}

/// What one variable may take.
#[derive(Clone, Debug, PartialEq)]
pub enum Domain {
    /// min ..= max; on a log scale the coordinate is ln x's; an integer key
    /// takes the nearest whole number.
    Range { min: f64, max: f64, log: bool },
    /// One of these (the coordinate's share of [0, 1)).
    Choices(Vec<Value>),
}

/// One variable: a sweepable key (one index of a range) and its domain.
#[derive(Clone, Debug)]
pub struct Variable {
    /// The column name (`radius[3]`).
    pub name: String,
    pub param: Param,
    pub domain: Domain,
}

impl Variable {
    /// The coordinate of `x`, if it is a value this variable takes.
    pub fn coordinate(&self, x: &Value) -> Option<f64> {
        match (&self.domain, x) {
            (Domain::Range { min, max, log }, Value::Num(x)) if (*min..=*max).contains(x) => {
                Some(if *log {
                    (x.ln() - min.ln()) / (max.ln() - min.ln())
                } else {
                    (x - min) / (max - min)
                })
            }
            (Domain::Choices(c), x) => c
                .iter()
                .position(|v| v == x)
                .map(|i| (i as f64 + 0.5) / c.len() as f64),
            _ => None,
        }
    }

    /// The value at coordinate `u` ∈ [0, 1].
    pub fn value(&self, u: f64) -> Value {
        match &self.domain {
            Domain::Range { min, max, log } => {
                let x = if *log {
                    (min.ln() + u * (max.ln() - min.ln())).exp()
                } else {
                    min + u * (max - min)
                };
                let x = x.clamp(*min, *max);
                Value::Num(if self.param.kind == Kind::Integer {
                    x.round()
                } else {
                    x
                })
            }
            Domain::Choices(c) => c[((u * c.len() as f64) as usize).min(c.len() - 1)].clone(),
        }
    }

    /// The distance between two neighbouring values in the coordinate, for
    /// a discrete variable (a choice: 1/k; an integer key: one unit, on a
    /// log scale at the top of the range, where it is smallest); `None` for
    /// a continuous one (CMA-ES keeps a discrete coordinate's step above a
    /// share of this: [`cmaes::Cmaes::with_steps`]).
    pub fn step(&self) -> Option<f64> {
        match &self.domain {
            Domain::Choices(c) => Some(1.0 / c.len() as f64),
            Domain::Range { min, max, log } if self.param.kind == Kind::Integer => {
                if max <= min {
                    return None;
                }
                Some(if *log {
                    (max.ln() - (max - 1.0).max(*min).ln()) / (max.ln() - min.ln())
                } else {
                    1.0 / (max - min)
                })
            }
            Domain::Range { .. } => None,
        }
    }
}

/// What `variables` vary: their keys, and the fewest and most balls a
/// `balls` variable gives.
fn varied(variables: &[Variable]) -> crate::model::Varied<'_> {
    let balls = variables
        .iter()
        .find(|v| v.param.name == "balls")
        .and_then(|v| {
            let values = match &v.domain {
                Domain::Range { .. } => vec![v.value(0.0), v.value(1.0)],
                Domain::Choices(c) => c.clone(),
            };
            values
                .iter()
                .filter_map(|x| match x {
                    Value::Num(n) => Some(*n as usize),
                    Value::Text(_) => None,
                })
                .fold(None, |span: Option<(usize, usize)>, n| match span {
                    None => Some((n, n)),
                    Some((lo, hi)) => Some((lo.min(n), hi.max(n))),
                })
        });
    crate::model::Varied {
        names: variables.iter().map(|v| v.param.name.as_str()).collect(),
        balls,
    }
}

/// The base scene's value of a per-ball key (`mass[2]`; a key without an
/// index when every ball has the same), `glue` or `balls`; `None` for the
/// others.
fn base_value(base: &Scene, p: &Param) -> Option<Value> {
    let per = |v: &[f64]| -> Option<Value> {
        match p.index {
            Some(i) => v.get(i).map(|&x| Value::Num(x)),
            None => v.iter().all(|&x| x == v[0]).then(|| Value::Num(v[0])),
        }
    };
    match p.name.as_str() {
        "radius" => per(&base.radius),
        "mass" => per(&base.mass),
        "young_modulus" => per(&base.young_modulus),
        "poisson_ratio" => per(&base.poisson_ratio),
        "velocity" => per(&base.velocity),
        "gap" => per(&base.gap),
        "glue" => Some(Value::Text(
            base.glue
                .iter()
                .map(|&g| if g { '=' } else { '-' })
                .collect(),
        )),
        "balls" => Some(Value::Num(base.n as f64)),
        _ => None,
    }
}

/// A constraint `lhs op rhs`: `lhs` an outcome column or `total_mass`.
#[derive(Clone, Debug, PartialEq)]
pub struct Constraint {
    pub lhs: String,
    pub op: Op,
    pub rhs: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Op {
    Le,
    Lt,
    Ge,
    Gt,
}

impl Constraint {
    /// How far `x` misses the bound (0: met; NaN misses by infinity).
    fn miss(&self, x: f64) -> f64 {
        if x.is_nan() {
            return f64::INFINITY;
        }
        let d = match self.op {
            Op::Le | Op::Lt => x - self.rhs,
            Op::Ge | Op::Gt => self.rhs - x,
        };
        let strict = matches!(self.op, Op::Lt | Op::Gt);
        if d > 0.0 || (strict && d == 0.0) {
            d.max(f64::MIN_POSITIVE)
        } else {
            0.0
        }
    }
}

/// A checked problem file.
#[derive(Debug)]
pub struct Problem {
    pub origin: String,
    /// Files it was read from (the problem file, a scene file it names).
    pub inputs: Vec<PathBuf>,
    pub scene: SceneSpec,
    pub base: Scene,
    pub variables: Vec<Variable>,
    /// The objective column and whether it is maximised.
    pub objective: (String, bool),
    pub constraints: Vec<Constraint>,
    pub method: Method,
    pub population: usize,
    pub generations: u64,
    pub seed: u64,
    pub model: std::sync::Arc<dyn Model>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawProblem {
    #[allow(dead_code)]
    description: Option<String>,
    scene: Option<Spanned<toml::Value>>,
    variable: Option<Vec<Spanned<RawVariable>>>,
    objective: Option<Spanned<RawObjective>>,
    constraint: Option<Vec<Spanned<RawConstraint>>>,
    optimizer: Option<Spanned<RawOptimizer>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawVariable {
    name: String,
    min: Option<f64>,
    max: Option<f64>,
    scale: Option<String>,
    choices: Option<Vec<toml::Value>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawObjective {
    minimize: Option<String>,
    maximize: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawConstraint {
    expr: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawOptimizer {
    method: Option<String>,
    population: Option<i64>,
    evaluations: Option<i64>,
    seed: Option<i64>,
}

/// Most variables a problem may have (CMA-ES keeps an n×n covariance).
pub const MAX_VARIABLES: usize = 200;
/// Most evaluations a problem may ask for.
pub const MAX_EVALUATIONS: i64 = 10_000_000;
/// Evaluations when `[optimizer] evaluations` is left out.
pub const DEFAULT_EVALUATIONS: i64 = 1000;

/// Columns every evaluation row starts with, before the variables.
const LEAD: [&str; 3] = ["generation", "candidate", "feasible"];

impl Problem {
    pub fn load(path: &Path) -> Result<Problem, InputError> {
        let src = Source::read(path)?;
        let mut p = Self::parse(&src, path.parent().unwrap_or(Path::new(".")))?;
        p.inputs.insert(0, path.to_path_buf());
        Ok(p)
    }

    /// Read and check a problem file's text (`dir`: where a scene file it
    /// names is looked for).
    pub fn parse(src: &Source, dir: &Path) -> Result<Problem, InputError> {
        let raw: RawProblem = src.parse_toml()?;
        let mut inputs = vec![];
        let scene = crate::sweep::base_scene(src, raw.scene.as_ref(), dir, &mut inputs)?;
        let base = scene.validate()?;
        let variables = variables(src, raw.variable.unwrap_or_default(), &scene, &base)?;
        let model = crate::model::of(&base, &varied(&variables));
        let columns = model.header();
        let objective = objective(src, raw.objective, &columns)?;
        let constraints = constraints(src, raw.constraint.unwrap_or_default(), &columns)?;
        let (method, population, evaluations, seed) = optimizer(src, raw.optimizer)?;
        let population = population.unwrap_or_else(|| cmaes::default_population(variables.len()));
        Ok(Problem {
            origin: src.name.clone(),
            inputs,
            scene,
            base,
            variables,
            objective,
            constraints,
            method,
            population,
            generations: (evaluations as u64 / population as u64).max(1),
            seed,
            model,
        })
    }

    /// The evaluation table's columns.
    pub fn header(&self) -> Vec<String> {
        let mut h: Vec<String> = LEAD.iter().map(|s| s.to_string()).collect();
        h.extend(self.variables.iter().map(|v| v.name.clone()));
        h.push("total_mass".into());
        h.extend(self.model.header());
        h
    }

    /// The type of each column, parallel to [`Problem::header`].
    pub fn types(&self) -> Vec<ColType> {
        let mut t = vec![ColType::Int, ColType::Int, ColType::Text];
        t.extend(self.variables.iter().map(|v| match &v.domain {
            Domain::Choices(c) if c.iter().any(|x| matches!(x, Value::Text(_))) => ColType::Text,
            _ if v.param.kind == Kind::Integer => ColType::Int,
            _ => ColType::Num,
        }));
        t.push(ColType::Num);
        t.extend(self.model.types());
        t
    }

    /// The evaluation table, header and `rows`, as CSV or Parquet to `w`.
    pub fn write_table<W: std::io::Write + Send>(
        &self,
        rows: &[Vec<Cell>],
        kind: TableKind,
        w: W,
    ) -> anyhow::Result<()> {
        match kind {
            TableKind::Csv => {
                let mut w = w;
                let mut h = csv::Writer::from_writer(&mut w);
                h.write_record(self.header())?;
                h.flush()?;
                drop(h);
                let mut bytes = Vec::new();
                csv_rows(rows, &mut bytes);
                w.write_all(&bytes)?;
                w.flush()?;
            }
            TableKind::Parquet => {
                let types = self.types();
                let schema = parquet_file::schema(&self.header(), &types);
                let mut cols = parquet_file::Columns::new(&schema, &types, rows.len());
                rows.iter().flatten().for_each(|c| cols.push(c.field()));
                let mut out = parquet::arrow::ArrowWriter::try_new(
                    w,
                    schema,
                    Some(parquet_file::properties()),
                )?;
                out.write(&cols.finish()?)?;
                out.close()?;
            }
        }
        Ok(())
    }

    /// What its variables vary (for the model's needs from a backend).
    pub fn varied(&self) -> crate::model::Varied<'_> {
        varied(&self.variables)
    }

    /// The coordinates of the base scene's own values, where the base scene
    /// has one a variable can take (else the cube's centre): where the
    /// search starts, and generation 0's candidate 0.
    pub fn base_coordinates(&self) -> Vec<f64> {
        self.variables
            .iter()
            .map(|v| {
                base_value(&self.base, &v.param)
                    .and_then(|x| v.coordinate(&x))
                    .unwrap_or(0.5)
            })
            .collect()
    }

    /// The scene at coordinates `u` (one per variable, in [0, 1]).
    pub fn spec_at(&self, u: &[f64]) -> SceneSpec {
        self.spec_of(&self.values_at(u))
    }

    /// Each variable's value at coordinates `u`.
    pub fn values_at(&self, u: &[f64]) -> Vec<Value> {
        self.variables
            .iter()
            .zip(u)
            .map(|(v, &x)| v.value(x))
            .collect()
    }

    /// The scene with each variable at its value in `values`.
    pub fn spec_of(&self, values: &[Value]) -> SceneSpec {
        let mut s = self.scene.clone();
        for (v, x) in self.variables.iter().zip(values) {
            axis::apply(&mut s, &self.base, &v.param, x);
        }
        s
    }

    /// `values` checked as a design of this problem: one per variable, each
    /// within its range (a whole number for an integer key) or one of its
    /// choices.
    pub fn check_design(&self, k: usize, values: &[Value]) -> Result<(), InputError> {
        let bad = |what: String| InputError::Data {
            path: PathBuf::from(&self.origin),
            what: format!("design {k}: {what}"),
        };
        if values.len() != self.variables.len() {
            return Err(bad(format!(
                "{} values for the problem's {} variables ({})",
                values.len(),
                self.variables.len(),
                self.header()[3..3 + self.variables.len()].join(", ")
            )));
        }
        for (v, x) in self.variables.iter().zip(values) {
            let whole = match x {
                Value::Num(n) => v.param.kind != Kind::Integer || n.fract() == 0.0,
                Value::Text(_) => true,
            };
            if v.coordinate(x).is_none() || !whole {
                let allowed = match &v.domain {
                    Domain::Range { min, max, .. } => format!(
                        "{}{min} to {max}",
                        if v.param.kind == Kind::Integer {
                            "a whole number from "
                        } else {
                            ""
                        }
                    ),
                    Domain::Choices(c) => format!(
                        "one of {}",
                        c.iter()
                            .map(|c| match c {
                                Value::Num(n) => n.to_string(),
                                Value::Text(t) => format!("\"{t}\""),
                            })
                            .collect::<Vec<_>>()
                            .join(", ")
                    ),
                };
                let shown = match x {
                    Value::Num(n) => n.to_string(),
                    Value::Text(t) => format!("\"{t}\""),
                };
                return Err(bad(format!("{} = {shown}: allowed {allowed}", v.name)));
            }
        }
        Ok(())
    }
}

/// `rows` as CSV lines (the table's text after its header), appended to `out`.
pub fn csv_rows(rows: &[Vec<Cell>], out: &mut Vec<u8>) {
    let mut scratch = String::new();
    for r in rows {
        for (i, c) in r.iter().enumerate() {
            if i > 0 {
                out.push(b',');
            }
            row::push_csv_field(out, row::field_text(c.field(), &mut scratch));
        }
        out.push(b'\n');
    }
}

/// `key[a..b]`: keys a ..= b (both ends included); anything else: itself.
fn expand(name: &str) -> Result<Vec<String>, String> {
    let Some((key, rest)) = name.split_once('[') else {
        return Ok(vec![name.to_string()]);
    };
    let Some((a, b)) = rest.strip_suffix(']').and_then(|r| r.split_once("..")) else {
        return Ok(vec![name.to_string()]);
    };
    match (a.trim().parse::<usize>(), b.trim().parse::<usize>()) {
        (Ok(a), Ok(b)) if a <= b => Ok((a..=b).map(|i| format!("{key}[{i}]")).collect()),
        _ => Err("a range of indices written `key[a..b]` with a ≤ b (both included)".into()),
    }
}

/// The `[[variable]]` tables, ranges of indices expanded: each a key the
/// model's sweeps take, setting a quantity no other variable sets, whose
/// every value alone (the others at the base scene's) makes a valid scene
/// of the base scene's kind.
fn variables(
    src: &Source,
    raw: Vec<Spanned<RawVariable>>,
    scene: &SceneSpec,
    base: &Scene,
) -> Result<Vec<Variable>, InputError> {
    let mut variables: Vec<Variable> = vec![];
    for v in raw {
        let span = v.span();
        let v = v.into_inner();
        let bad = |value: String, allowed: &str| {
            src.invalid(
                Some(src.line(span.start)),
                "variable",
                value,
                allowed.to_string(),
            )
        };
        let domain = domain(&v).map_err(|(value, allowed)| bad(value, &allowed))?;
        for name in expand(&v.name).map_err(|e| bad(v.name.clone(), &e))? {
            let param = Param::parse(&name).map_err(|e| bad(name.clone(), &e))?;
            if matches!(domain, Domain::Range { .. }) && param.kind == Kind::Glue {
                return Err(bad(name, "`choices` for glue (a pattern of `=` and `-`)"));
            }
            if variables.iter().any(|w| w.param.overlaps(&param)) {
                return Err(bad(name, "variables that set different quantities (this one sets one another variable sets)"));
            }
            let var = Variable {
                name,
                param,
                domain: domain.clone(),
            };
            let ends: Vec<Value> = match &var.domain {
                Domain::Range { .. } => vec![var.value(0.0), var.value(1.0)],
                Domain::Choices(c) => c.clone(),
            };
            for x in ends {
                let mut s = scene.clone();
                axis::apply(&mut s, base, &var.param, &x);
                let why = match s.validate() {
                    Ok(s) if crate::model::kind(&s) == crate::model::kind(base) => continue,
                    Ok(_) => crate::model::mixed_sweep(base),
                    Err(e) => format!("a value that makes a valid scene ({e})"),
                };
                return Err(bad(format!("{} = {x}", var.name), &why));
            }
            variables.push(var);
        }
    }
    if variables.is_empty() {
        return Err(src.missing(
            None,
            "variable",
            "at least one [[variable]] table: name = \"<key>\" with min/max or choices",
        ));
    }
    if variables.len() > MAX_VARIABLES {
        return Err(src.missing(
            None,
            "variable",
            format!(
                "at most {MAX_VARIABLES} variables ({} given)",
                variables.len()
            ),
        ));
    }
    Ok(variables)
}

/// One variable's domain: `min` and `max` (and `scale`), or `choices`;
/// an error as (value, allowed).
fn domain(v: &RawVariable) -> Result<Domain, (String, String)> {
    let bad = |value: String, allowed: &str| (value, allowed.to_string());
    match (&v.choices, v.min, v.max) {
        (Some(c), None, None) if v.scale.is_none() => {
            if c.is_empty() {
                return Err(bad(v.name.clone(), "`choices` with at least one value"));
            }
            Ok(Domain::Choices(
                c.iter()
                    .map(|x| match x {
                        toml::Value::Float(f) => Ok(Value::Num(*f)),
                        toml::Value::Integer(i) => Ok(Value::Num(*i as f64)),
                        toml::Value::String(s) => Ok(Value::Text(s.clone())),
                        other => Err(bad(
                            other.to_string(),
                            "choices that are numbers or strings",
                        )),
                    })
                    .collect::<Result<_, _>>()?,
            ))
        }
        (None, Some(min), Some(max)) => {
            let log = match v.scale.as_deref() {
                None | Some("linear") => false,
                Some("log") => true,
                Some(other) => {
                    return Err(bad(
                        format!("scale = {other:?}"),
                        "scale = \"linear\" (the default) or \"log\"",
                    ))
                }
            };
            if !(min.is_finite() && max.is_finite() && min < max) || (log && min <= 0.0) {
                return Err(bad(
                    format!("{} in [{min}, {max}]", v.name),
                    if log {
                        "finite 0 < min < max (a log scale)"
                    } else {
                        "finite min < max"
                    },
                ));
            }
            Ok(Domain::Range { min, max, log })
        }
        _ => Err(bad(
            v.name.clone(),
            "either `min` and `max` (and `scale`) or `choices`, not both",
        )),
    }
}

/// Whether `c` is a column an objective or a constraint may name.
fn known(columns: &[String], c: &str) -> bool {
    columns.iter().any(|h| h == c) || c == "total_mass"
}

fn allowed_columns(columns: &[String]) -> String {
    format!("an outcome column ({}) or total_mass", columns.join(", "))
}

/// `[objective]`: the column and whether it is maximised.
fn objective(
    src: &Source,
    raw: Option<Spanned<RawObjective>>,
    columns: &[String],
) -> Result<(String, bool), InputError> {
    let Some(obj) = raw else {
        return Err(src.missing(
            None,
            "objective",
            "an [objective] table: minimize = \"<column>\" or maximize = \"<column>\"",
        ));
    };
    let span = obj.span();
    let obj = obj.into_inner();
    let objective = match (obj.minimize, obj.maximize) {
        (Some(c), None) => (c, false),
        (None, Some(c)) => (c, true),
        _ => {
            return Err(src.invalid(
                Some(src.line(span.start)),
                "objective",
                "minimize and maximize".into(),
                "one of `minimize` or `maximize`".into(),
            ))
        }
    };
    if !known(columns, &objective.0) || objective.0 == "status" {
        return Err(src.invalid(
            Some(src.line(span.start)),
            "objective",
            objective.0,
            allowed_columns(columns),
        ));
    }
    Ok(objective)
}

/// The `[[constraint]]` comparisons, each of a known column.
fn constraints(
    src: &Source,
    raw: Vec<Spanned<RawConstraint>>,
    columns: &[String],
) -> Result<Vec<Constraint>, InputError> {
    let mut constraints = vec![];
    for c in raw {
        let span = c.span();
        let expr = c.into_inner().expr;
        match parse_constraint(&expr) {
            Some(c) if known(columns, &c.lhs) => constraints.push(c),
            Some(c) => {
                return Err(src.invalid(
                    Some(src.line(span.start)),
                    "constraint.expr",
                    expr.clone(),
                    format!("`{}`: {}", c.lhs, allowed_columns(columns)),
                ))
            }
            None => {
                return Err(src.invalid(
                    Some(src.line(span.start)),
                    "constraint.expr",
                    expr,
                    "`<column> <= <number>` (or <, >=, >)".into(),
                ))
            }
        }
    }
    Ok(constraints)
}

/// `[optimizer]`: method, population (None: the method's default),
/// evaluations and seed.
fn optimizer(
    src: &Source,
    raw: Option<Spanned<RawOptimizer>>,
) -> Result<(Method, Option<usize>, i64, u64), InputError> {
    let Some(o) = raw else {
        return Ok((Method::CmaEs, None, DEFAULT_EVALUATIONS, 0));
    };
    let span = o.span();
    let o = o.into_inner();
    let method = match o.method.as_deref() {
        None => Method::CmaEs,
        Some(m) => Method::from_name(m).ok_or_else(|| {
            src.invalid(
                Some(src.line(span.start)),
                "optimizer.method",
                m.into(),
                format!("one of {}", Method::names()),
            )
        })?,
    };
    if let Some(p) = o.population {
        if !(2..=100_000).contains(&p) {
            return Err(src.invalid(
                Some(src.line(span.start)),
                "optimizer.population",
                p.to_string(),
                "2 ..= 100000".into(),
            ));
        }
    }
    let e = o.evaluations.unwrap_or(DEFAULT_EVALUATIONS);
    if !(1..=MAX_EVALUATIONS).contains(&e) {
        return Err(src.invalid(
            Some(src.line(span.start)),
            "optimizer.evaluations",
            e.to_string(),
            format!("1 ..= {MAX_EVALUATIONS}"),
        ));
    }
    let seed = o.seed.unwrap_or(0);
    if seed < 0 {
        return Err(src.invalid(
            Some(src.line(span.start)),
            "optimizer.seed",
            seed.to_string(),
            "a whole number ≥ 0".into(),
        ));
    }
    Ok((method, o.population.map(|p| p as usize), e, seed as u64))
}

fn parse_constraint(expr: &str) -> Option<Constraint> {
    for (text, op) in [("<=", Op::Le), (">=", Op::Ge), ("<", Op::Lt), (">", Op::Gt)] {
        if let Some((l, r)) = expr.split_once(text) {
            let rhs: f64 = r.trim().parse().ok()?;
            return rhs.is_finite().then(|| Constraint {
                lhs: l.trim().to_string(),
                op,
                rhs,
            });
        }
    }
    None
}

/// Mirror `x` into [0, 1] (a coordinate the strategy put outside the cube).
fn mirror(x: f64) -> f64 {
    if !x.is_finite() {
        return 0.5;
    }
    let y = x.rem_euclid(2.0);
    if y > 1.0 {
        2.0 - y
    } else {
        y
    }
}

/// Where a run stands after a generation.
#[derive(Clone, Debug)]
pub struct Report {
    pub generation: u64,
    pub generations: u64,
    pub evaluations: u64,
    /// The best feasible objective so far.
    pub best: Option<f64>,
}

/// The best feasible candidate.
#[derive(Clone, Debug)]
pub struct Best {
    pub generation: u64,
    pub candidate: usize,
    pub objective: f64,
    pub spec: SceneSpec,
}

/// A finished run: its rows (the table's cells, in [`Problem::header`]'s
/// order) and its best design.
pub struct Finished {
    pub rows: Vec<Vec<Cell>>,
    pub best: Option<Best>,
    pub evaluations: u64,
    /// Seconds in the engine's batch runs, and in all.
    pub engine_s: f64,
    pub wall_s: f64,
}

/// Where a row's verdict is read: the table's status, objective and
/// constraint columns, found once per run.
struct Judge<'a> {
    p: &'a Problem,
    status: Option<usize>,
    objective: Option<usize>,
    constraints: Vec<Option<usize>>,
}

impl Judge<'_> {
    fn new(p: &Problem) -> Judge<'_> {
        let header = p.header();
        let at = |c: &str| header.iter().position(|h| h == c);
        Judge {
            p,
            status: at("status"),
            objective: at(&p.objective.0),
            constraints: p.constraints.iter().map(|c| at(&c.lhs)).collect(),
        }
    }

    /// A row's verdict: feasible, its rank key (lower first: feasible rows
    /// by the objective, then rows that miss a constraint by how far, then
    /// failed runs) and its objective.
    fn verdict(&self, row: &[Cell]) -> (bool, (u8, f64), f64) {
        let num = |i: Option<usize>| {
            i.and_then(|i| row.get(i))
                .and_then(Cell::as_f64)
                .unwrap_or(f64::NAN)
        };
        let ok = self
            .status
            .is_some_and(|i| row[i] == Cell::Text(Status::Ok.name().into()));
        let objective = num(self.objective);
        let miss: f64 = self
            .p
            .constraints
            .iter()
            .zip(&self.constraints)
            .map(|(c, &i)| c.miss(num(i)))
            .sum();
        let feasible = ok && miss == 0.0 && objective.is_finite();
        let sign = if self.p.objective.1 { -1.0 } else { 1.0 };
        let key = if feasible {
            (0, sign * objective)
        } else if ok {
            (1, miss)
        } else {
            (2, 0.0)
        };
        (feasible, key, objective)
    }
}

/// Candidates `values` (each variable's value, per candidate; their
/// scenes `specs`) run as one batch on `backend`: their rows (generation
/// `g`, candidate k, `feasible` not yet judged: null), and the engine's
/// seconds. A candidate whose values make no valid scene of the model is
/// `invalid`.
fn candidate_rows(
    p: &Problem,
    backend: &dyn Backend,
    o: &Overrides,
    g: u64,
    values: &[Vec<Value>],
    specs: &[SceneSpec],
) -> anyhow::Result<(Vec<Vec<Cell>>, f64)> {
    let scenes: Vec<Option<Scene>> = specs
        .iter()
        .map(|s| {
            s.validate()
                .ok()
                .filter(|sc| crate::model::kind(sc) == crate::model::kind(&p.base))
        })
        .collect();
    let scene_at = |k: usize| {
        scenes[k].clone().ok_or_else(|| InputError::Data {
            path: PathBuf::from(&p.origin),
            what: format!("candidate {k}: no valid scene"),
        })
    };
    let te = Instant::now();
    let mut built = te;
    let outcomes = p.model.run(
        backend,
        values.len(),
        &scene_at,
        o,
        p.model.takes_error_estimate(),
        &mut built,
    )?;
    let engine_s = te.elapsed().as_secs_f64();
    let rows = values
        .iter()
        .enumerate()
        .map(|(k, vals)| {
            let mut row: Vec<Cell> = vec![Cell::Int(g), Cell::Int(k as u64), Cell::Null];
            row.extend(vals.iter().map(|v| match v {
                Value::Num(x) => Cell::Num(*x),
                Value::Text(t) => Cell::Text(t.clone()),
            }));
            row.push(Cell::Num(
                scenes[k].as_ref().map_or(f64::NAN, |s| s.mass.iter().sum()),
            ));
            outcomes.emit(k, &mut |f| row.push(Cell::from(f)));
            row
        })
        .collect();
    Ok((rows, engine_s))
}

/// The rows of `designs` (each variable's value, in the problem's order),
/// run as one batch on `backend` with `feasible` judged: what `cradle
/// optimize` writes for them (generation 0, candidate k). The engine's
/// batched evaluation for an optimiser of the user's own (ask/tell: pycma,
/// Optuna, nevergrad ask for designs; these rows tell them the objective).
/// A value outside its variable's domain is refused, naming it.
pub fn evaluate(
    p: &Problem,
    backend: &dyn Backend,
    o: &Overrides,
    designs: &[Vec<Value>],
) -> anyhow::Result<Vec<Vec<Cell>>> {
    for (k, d) in designs.iter().enumerate() {
        p.check_design(k, d)?;
    }
    let specs: Vec<SceneSpec> = designs.iter().map(|v| p.spec_of(v)).collect();
    let (mut rows, _) = candidate_rows(p, backend, o, 0, designs, &specs)?;
    let judge = Judge::new(p);
    for row in &mut rows {
        row[2] = Cell::Text(judge.verdict(row).0.to_string());
    }
    Ok(rows)
}

/// Run the problem on `backend`. `earlier`: the rows of the generations a
/// previous run of the same problem finished (`--resume`), replayed, not
/// run again; `sink` is given each new generation's rows once they are
/// known; `report` is told after every generation; `cancel` stops the run
/// between generations (`error::Interrupted`).
pub fn run(
    p: &Problem,
    backend: &dyn Backend,
    o: &Overrides,
    earlier: Vec<Vec<Cell>>,
    sink: &mut dyn FnMut(&[Vec<Cell>]) -> anyhow::Result<()>,
    cancel: Option<&std::sync::atomic::AtomicBool>,
    report: &mut dyn FnMut(&Report),
) -> anyhow::Result<Finished> {
    let t0 = Instant::now();
    let n = p.variables.len();
    let lambda = p.population;
    let start = p.base_coordinates();
    let steps: Vec<Option<f64>> = p.variables.iter().map(Variable::step).collect();
    let mut es = cmaes::Cmaes::new(start.clone(), 0.3, lambda, p.seed).with_steps(&steps);
    let sign = if p.objective.1 { -1.0 } else { 1.0 };
    let judge = Judge::new(p);
    let replayed = (earlier.len() / lambda) as u64;
    let mut earlier = earlier.into_iter();
    let mut rows: Vec<Vec<Cell>> = Vec::with_capacity(p.generations as usize * lambda);
    let mut best: Option<Best> = None;
    let mut engine_s = 0.0;
    for g in 0..p.generations {
        if g >= replayed && cancel.is_some_and(|c| c.load(std::sync::atomic::Ordering::SeqCst)) {
            return Err(crate::error::Interrupted.into());
        }
        let mut xs: Vec<Vec<f64>> = match p.method {
            Method::CmaEs => es.ask(),
            Method::Random => (0..lambda)
                .map(|k| {
                    (0..n)
                        .map(|i| unit_of(hash(p.seed, g, k as u64, i as u64)))
                        .collect()
                })
                .collect(),
        };
        if g == 0 {
            // The base design is a candidate.
            xs[0] = start.clone();
        }
        let us: Vec<Vec<f64>> = xs
            .iter()
            .map(|x| x.iter().map(|&v| mirror(v)).collect())
            .collect();
        let values: Vec<Vec<Value>> = us.iter().map(|u| p.values_at(u)).collect();
        let specs: Vec<SceneSpec> = values.iter().map(|v| p.spec_of(v)).collect();
        let mut new: Vec<Vec<Cell>> = if g < replayed {
            earlier.by_ref().take(lambda).collect()
        } else {
            let (rows, s) = candidate_rows(p, backend, o, g, &values, &specs)?;
            engine_s += s;
            rows
        };
        let mut keys = Vec::with_capacity(lambda);
        for (k, row) in new.iter_mut().enumerate() {
            let (feasible, key, objective) = judge.verdict(row);
            row[2] = Cell::Text(feasible.to_string());
            keys.push(key);
            if feasible
                && best
                    .as_ref()
                    .is_none_or(|b| sign * objective < sign * b.objective)
            {
                best = Some(Best {
                    generation: g,
                    candidate: k,
                    objective,
                    spec: specs[k].clone(),
                });
            }
        }
        if g >= replayed {
            sink(&new)?;
        }
        rows.extend(new);
        if p.method == Method::CmaEs {
            let mut order: Vec<usize> = (0..lambda).collect();
            order.sort_by(|&a, &b| {
                keys[a]
                    .0
                    .cmp(&keys[b].0)
                    .then(keys[a].1.total_cmp(&keys[b].1))
                    .then(a.cmp(&b))
            });
            es.tell(&xs, &order);
        }
        report(&Report {
            generation: g,
            generations: p.generations,
            evaluations: (g + 1) * lambda as u64,
            best: best.as_ref().map(|b| b.objective),
        });
    }
    Ok(Finished {
        rows,
        best,
        evaluations: p.generations * lambda as u64,
        engine_s,
        wall_s: t0.elapsed().as_secs_f64(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_expand_and_mirror_stays_in_the_cube() {
        assert_eq!(
            expand("radius[1..3]").unwrap(),
            ["radius[1]", "radius[2]", "radius[3]"]
        );
        assert_eq!(expand("gap").unwrap(), ["gap"]);
        assert!(expand("radius[3..1]").is_err());
        for x in [-0.25, 0.3, 1.25, 2.5, -3.7] {
            let y = mirror(x);
            assert!((0.0..=1.0).contains(&y), "{x} → {y}");
        }
        assert_eq!(mirror(1.25), 0.75);
        assert_eq!(mirror(-0.25), 0.25);
        let c = parse_constraint("total_mass <= 0.2").unwrap();
        assert_eq!((c.lhs.as_str(), c.op, c.rhs), ("total_mass", Op::Le, 0.2));
        assert_eq!(c.miss(0.1), 0.0);
        assert!(c.miss(0.3) > 0.0);
        assert!(parse_constraint("total_mass == 1").is_none());
    }
}
