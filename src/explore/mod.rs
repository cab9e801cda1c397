//! `cradle explore TABLE`: a local web page to explore a sweep's phase map
//! (axum on tokio; the page and its script embedded in the binary).
//!
//! Routes (nothing else is served; no path from a request reaches the file
//! system):
//! - `GET /`: the page (`page.html`).
//! - `GET /vendor/uPlot.js`, `GET /vendor/uPlot.css`: the plotting library
//!   the page draws with (uPlot 1.6.32, MIT, vendored in `vendor/`).
//! - `GET /api/meta`: the table's columns (with their units), its grid
//!   (axes, their values and units), the file's name; for an optimisation's
//!   table, `optimize` (objective, direction, variables: its sidecar's).
//! - `GET /api/map?x=AXIS&y=AXIS&z=COLUMN&at=I,J,…`: the z values of the
//!   x × y slice of the grid at the given indices of the other axes.
//! - `GET /api/points?x=COLUMN&y=COLUMN&z=COLUMN`: x, y, z and id of every
//!   row, for a table that is not a grid (a point list, a sampling design).
//! - `GET /api/row?id=N`: one row as text.
//! - `GET /api/scene?id=N`: that scene run again by the CPU engine from the
//!   sweep named in the sidecar (an optimisation's candidate: the problem
//!   file's base scene at the row's variable values): its outcome, its trace (at most
//!   [`MAX_TRACE_ROWS`] rows, said in the reply) and its outcome under the
//!   `hard-sphere` and `closure` models; for a sweep of granular chains,
//!   the chain's outcome columns and its bead histories (`histories`: beads,
//!   t, v and contact force per bead, at most [`HISTORY_BEADS`] beads ×
//!   2·[`HISTORY_ROWS`] rows) for a space-time image.
//! - `GET /api/scene.toml?id=N`: the scene as a scene TOML file.
//!
//! Every parameter is checked; a bad request gets a JSON error (400/404)
//! and the server goes on. At most [`MAX_RUNS`] scene runs at a time, each
//! given [`RUN_TIMEOUT_S`] seconds.

// Request checks return the error response itself (axum's `Response`).
#![allow(clippy::result_large_err)]

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use axum::extract::{Query, State};
use axum::http::{header, StatusCode};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use serde_json::{json, Value as Json_};

use crate::output::units::unit;
use crate::sweep::axis::{Value, Values};
use crate::sweep::Sweep;

pub use crate::model::cradle::MAX_TRACE_ROWS;
pub use crate::model::granular::{HISTORY_BEADS, HISTORY_ROWS};
/// Scene runs at the same time.
pub const MAX_RUNS: usize = 2;
/// Longest a scene run may take (s).
pub const RUN_TIMEOUT_S: u64 = 20;

const PAGE: &str = include_str!("page.html");
/// uPlot (<https://github.com/leeoniya/uPlot>, v1.6.32, MIT: `vendor/uPlot.LICENSE`).
const UPLOT_JS: &str = include_str!("vendor/uPlot.iife.min.js");
const UPLOT_CSS: &str = include_str!("vendor/uPlot.min.css");

/// One column: numbers (NaN where empty) or categories.
enum Col {
    Num(Vec<f64>),
    Cat(Vec<u32>, Vec<String>),
}

/// A loaded table.
struct Data {
    name: String,
    header: Vec<String>,
    cols: Vec<Col>,
    /// Rows in the table.
    rows: usize,
    /// The table's row of each scene id (its `id` column; without one, row
    /// i is scene i): a shard's or a refined table's rows are not its ids.
    row_of: HashMap<u64, usize>,
    /// The solver flags the sweep ran with (the sidecar's), applied when a
    /// scene is run again.
    overrides: crate::engine::Overrides,
    /// The grid: per axis, its name and values (empty when not a grid).
    axes: Vec<(String, Values)>,
    dims: Vec<u64>,
    /// The sweep that made the table, to run a scene again.
    sweep: Option<Sweep>,
    /// An optimisation's table: its sidecar's `optimize` (objective,
    /// direction, variables), and the problem file it ran (a candidate's
    /// scene is the problem's base scene at the row's variable values).
    optimize: Option<Json_>,
    problem: Option<Optimized>,
    /// Why scenes cannot be run again (when neither is there).
    sweep_problem: String,
    runs: Arc<tokio::sync::Semaphore>,
}

/// An optimisation's problem, as the table's sidecar recorded it.
struct Optimized {
    problem: crate::optimize::Problem,
    /// The table column of each variable, in the problem's order.
    columns: Vec<usize>,
}

fn err(code: StatusCode, msg: impl Into<String>) -> Response {
    (code, Json(json!({ "error": msg.into() }))).into_response()
}

/// A table's columns (a refined table filled to its grid, Parquet as the
/// CSV's text): numbers where every cell parses, else categories.
fn table(path: &Path) -> Result<(Vec<String>, Vec<Col>, usize)> {
    let mut r = csv::Reader::from_reader(crate::sweep::fill::full_csv(path)?);
    let header: Vec<String> = r
        .headers()
        .map_err(|e| bad(path, format!("not a readable table ({e})")))?
        .iter()
        .map(str::to_string)
        .collect();
    let n = header.len();
    let mut text: Vec<Vec<String>> = vec![vec![]; n];
    let mut nums: Vec<Vec<f64>> = vec![vec![]; n];
    let mut numeric = vec![true; n];
    let mut rows = 0;
    for rec in r.records() {
        let rec = rec.map_err(|e| bad(path, format!("not a readable table ({e})")))?;
        for (k, f) in rec.iter().enumerate().take(n) {
            if numeric[k] {
                match f.trim() {
                    "" => nums[k].push(f64::NAN),
                    t => match t.parse::<f64>() {
                        Ok(x) => nums[k].push(x),
                        Err(_) => {
                            numeric[k] = false;
                            // Keep the text of the rows so far.
                        }
                    },
                }
            }
            text[k].push(f.to_string());
        }
        rows += 1;
    }
    if rows == 0 {
        return Err(bad(
            path,
            "has no rows (an empty file, a header alone, or not a table)".into(),
        )
        .into());
    }
    let cols: Vec<Col> = (0..n)
        .map(|k| {
            if numeric[k] {
                Col::Num(std::mem::take(&mut nums[k]))
            } else {
                let mut labels: Vec<String> = vec![];
                let mut index: HashMap<String, u32> = HashMap::new();
                let codes = text[k]
                    .iter()
                    .map(|t| {
                        *index.entry(t.clone()).or_insert_with(|| {
                            labels.push(t.clone());
                            labels.len() as u32 - 1
                        })
                    })
                    .collect();
                Col::Cat(codes, labels)
            }
        })
        .collect();
    Ok((header, cols, rows))
}

/// Each id's row; without an `id` column, the row's index.
fn rows_by_id(
    path: &Path,
    header: &[String],
    cols: &[Col],
    rows: usize,
) -> Result<HashMap<u64, usize>> {
    Ok(match header.iter().position(|h| h == "id") {
        Some(k) => {
            let mut m = HashMap::with_capacity(rows);
            for (r, t) in ids_of(&cols[k], rows).into_iter().enumerate() {
                match t {
                    Some(id) if m.insert(id, r).is_none() => {}
                    _ => {
                        return Err(bad(
                            path,
                            format!(
                            "row {} has no id, or one an earlier row has: not one sweep's table",
                            r + 1
                        ),
                        )
                        .into())
                    }
                }
            }
            m
        }
        None => (0..rows).map(|r| (r as u64, r)).collect(),
    })
}

fn bad(path: &Path, what: String) -> crate::InputError {
    crate::InputError::Data {
        path: path.to_path_buf(),
        what,
    }
}

fn load(path: &Path) -> Result<Data> {
    let (header, cols, rows) = table(path)?;
    // The grid, from the sidecar's sweep.
    let sc = crate::output::sidecar::read(path).ok().flatten();
    let mut axes = vec![];
    if let Some(sc) = &sc {
        if sc.sweep.get("layout").is_none() {
            axes = crate::sweep::axis::from_sidecar(sc).unwrap_or_default();
        }
    }
    let dims: Vec<u64> = axes.iter().map(|(_, v)| v.len() as u64).collect();
    if dims.iter().product::<u64>() != rows as u64 {
        axes.clear();
    }
    // The sweep file, as named in the sidecar (from where it ran, or beside
    // the table); an optimisation's problem file likewise.
    let optimize = sc.as_ref().and_then(|s| s.sweep.get("optimize").cloned());
    let (sweep, problem, sweep_problem) = match &sc {
        Some(sc) if optimize.is_some() => match problem_of(path, sc, &header) {
            Ok(p) => (None, Some(p), String::new()),
            Err(why) => (None, None, why),
        },
        _ => {
            let (s, why) = sweep_of(path, sc.as_ref());
            (s, None, why)
        }
    };
    let row_of = rows_by_id(path, &header, &cols, rows)?;
    let overrides = sc.as_ref().map(|s| s.overrides()).unwrap_or_default();
    Ok(Data {
        row_of,
        overrides,
        name: path
            .file_name()
            .map_or(String::new(), |n| n.to_string_lossy().into_owned()),
        header,
        cols,
        rows,
        axes,
        dims,
        sweep,
        optimize,
        problem,
        sweep_problem,
        runs: Arc::new(tokio::sync::Semaphore::new(MAX_RUNS)),
    })
}

/// The file a sidecar names (`sweep_file`): as named (from where it ran),
/// from the table's folder, or by its file name beside the table (`cradle
/// sweep run/s.toml --out run/t.csv`, explored from inside run/).
fn named_file(path: &Path, f: &str) -> Option<PathBuf> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let beside = Path::new(f).file_name().map(|n| dir.join(n));
    [Some(PathBuf::from(f)), Some(dir.join(f)), beside]
        .into_iter()
        .flatten()
        .find(|p| p.is_file())
}

/// An optimisation table's problem file, found as [`named_file`] finds it
/// and still resolving to the problem the sidecar recorded (its
/// fingerprint: the problem, the solver flags, the version), with the table
/// column of each variable; else why not.
fn problem_of(
    path: &Path,
    sc: &crate::output::sidecar::Sidecar,
    header: &[String],
) -> Result<Optimized, String> {
    let f = &sc.sweep_file;
    let Some(file) = named_file(path, f) else {
        return Err(format!("the problem file {f} named in the sidecar is not found (as named, from the table's folder, or beside the table): run explore from where the optimisation ran"));
    };
    let problem =
        crate::optimize::Problem::load(&file).map_err(|e| format!("the problem file {f}: {e}"))?;
    if crate::optimize::request::fingerprint(&problem, &sc.overrides()) != sc.fingerprint {
        return Err(format!("the problem file {f} (or a scene file it names) changed since this table was made, or another cradle version made it: its candidates' scenes would not be this table's rows; restore it, or run the optimisation again"));
    }
    let columns = problem
        .variables
        .iter()
        .map(|v| {
            header
                .iter()
                .position(|h| *h == v.name)
                .ok_or_else(|| format!("the table has no column {:?} (a variable of {f})", v.name))
        })
        .collect::<Result<Vec<usize>, String>>()?;
    Ok(Optimized { problem, columns })
}

impl Data {
    /// Scene `id` of the table as a scene file's contents: the sweep's
    /// scene, or the optimisation's candidate (the problem's base scene at
    /// the row's variable values, each checked against its variable).
    fn scene_spec(&self, id: u64, row: usize) -> anyhow::Result<crate::scene::SceneSpec> {
        if let Some(o) = &self.problem {
            let values: Vec<Value> = o
                .columns
                .iter()
                .map(|&k| {
                    let t = self.cell(k, row);
                    match t.trim().parse::<f64>() {
                        Ok(x) => Value::Num(x),
                        Err(_) => Value::Text(t),
                    }
                })
                .collect();
            o.problem.check_design(row, &values)?;
            return Ok(o.problem.spec_of(&values));
        }
        match &self.sweep {
            Some(s) => s.scene_spec(id),
            None => anyhow::bail!("scenes cannot be run: {}", self.sweep_problem),
        }
    }

    /// Whether scenes can be run again (a sweep or a problem file found).
    fn runnable(&self) -> bool {
        self.sweep.is_some() || self.problem.is_some()
    }
}

/// The sweep a table's sidecar names, found as named (from where the sweep
/// ran), from the table's folder, or by its file name beside the table, and
/// still resolving to the sweep the sidecar recorded; else why not.
fn sweep_of(path: &Path, sc: Option<&crate::output::sidecar::Sidecar>) -> (Option<Sweep>, String) {
    match sc.map(|s| s.sweep_file.as_str()) {
        None => (
            None,
            "the table has no sidecar naming its sweep file".to_string(),
        ),
        Some(f) => {
            let found = named_file(path, f);
            let recorded = sc.map(|s| &s.sweep);
            match found.map(|p| Sweep::load(&p)) {
            // The file must still resolve to the sweep the sidecar
            // recorded (an edited sweep or scene file would run other
            // scenes under this table's rows).
            Some(Ok(s)) if serde_json::to_value(&s).ok().as_ref() == recorded => {
                (Some(s), String::new())
            }
            Some(Ok(_)) => (None, format!("the sweep file {f} (or a scene file it names) changed since this table was made: it no longer resolves to the sweep in the table's sidecar, so its scenes would not be this table's rows; restore it, or run the sweep again")),
            Some(Err(e)) => (None, format!("the sweep file {f}: {e}")),
            None => (
                None,
                format!("the sweep file {f} named in the sidecar is not found (as named, from the table's folder, or beside the table): run explore from where the sweep ran"),
            ),
        }
        }
    }
}

/// Each row's id (a whole number) from the `id` column, `None` where it is not one.
fn ids_of(col: &Col, rows: usize) -> Vec<Option<u64>> {
    match col {
        Col::Num(v) => v
            .iter()
            .map(|&x| (x >= 0.0 && x.fract() == 0.0 && x < 9.0e15).then_some(x as u64))
            .collect(),
        Col::Cat(..) => vec![None; rows],
    }
}

impl Data {
    fn col(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }

    fn cell(&self, k: usize, row: usize) -> String {
        match &self.cols[k] {
            Col::Num(v) => {
                let mut s = String::new();
                crate::output::row::num_into(v[row], &mut s);
                s
            }
            Col::Cat(c, l) => l[c[row] as usize].clone(),
        }
    }

    fn steps(&self) -> Vec<u64> {
        let mut steps = vec![1u64; self.dims.len()];
        for k in (0..self.dims.len().saturating_sub(1)).rev() {
            steps[k] = steps[k + 1] * self.dims[k + 1];
        }
        steps
    }
}

async fn meta(State(d): State<Arc<Data>>) -> Response {
    let columns: Vec<Json_> = d
        .header
        .iter()
        .zip(&d.cols)
        .map(|(h, c)| match c {
            Col::Num(_) => json!({"name": h, "kind": "number", "unit": unit(h)}),
            Col::Cat(_, l) => json!({"name": h, "kind": "category", "labels": l}),
        })
        .collect();
    let axes: Vec<Json_> = d
        .axes
        .iter()
        .map(|(name, v)| {
            let vals: Vec<Json_> = (0..v.len())
                .map(|i| match v.get(i) {
                    Value::Num(x) => json!(x),
                    Value::Text(t) => json!(t),
                })
                .collect();
            json!({"name": name, "values": vals, "log": matches!(v, Values::Logspace { .. }), "unit": unit(name)})
        })
        .collect();
    Json(json!({
        "file": d.name, "rows": d.rows, "columns": columns, "axes": axes, "steps": d.steps(),
        "scenes": d.runnable(), "scenes_problem": d.sweep_problem,
        "optimize": d.optimize,
        "max_trace_rows": MAX_TRACE_ROWS,
    }))
    .into_response()
}

async fn map(State(d): State<Arc<Data>>, Query(q): Query<HashMap<String, String>>) -> Response {
    if d.axes.len() < 2 {
        return err(
            StatusCode::BAD_REQUEST,
            "the table is not a grid of 2 or more axes (its sidecar names its axes)",
        );
    }
    let axis = |key: &str| -> Result<usize, Response> {
        let name = q
            .get(key)
            .ok_or_else(|| err(StatusCode::BAD_REQUEST, format!("`{key}` is required")))?;
        d.axes.iter().position(|(n, _)| n == name).ok_or_else(|| {
            err(
                StatusCode::BAD_REQUEST,
                format!("`{key}` = {name:?}: not an axis"),
            )
        })
    };
    let (ax, ay) = match (axis("x"), axis("y")) {
        (Ok(a), Ok(b)) if a != b => (a, b),
        (Err(e), _) | (_, Err(e)) => return e,
        _ => {
            return err(
                StatusCode::BAD_REQUEST,
                "`x` and `y` must be different axes",
            )
        }
    };
    let Some(z) = q.get("z").and_then(|z| d.col(z)) else {
        return err(StatusCode::BAD_REQUEST, "`z`: not a column of the table");
    };
    let mut at = vec![0u64; d.axes.len()];
    if let Some(s) = q.get("at") {
        let parts: Vec<&str> = s.split(',').collect();
        if parts.len() != d.axes.len() {
            return err(
                StatusCode::BAD_REQUEST,
                format!("`at`: {} indices, one per axis", d.axes.len()),
            );
        }
        for (k, p) in parts.iter().enumerate() {
            match p.parse::<u64>() {
                Ok(i) if i < d.dims[k] => at[k] = i,
                _ => {
                    return err(
                        StatusCode::BAD_REQUEST,
                        format!(
                            "`at`: index {p:?} of axis {k} outside 0 ..= {}",
                            d.dims[k] - 1
                        ),
                    )
                }
            }
        }
    }
    let steps = d.steps();
    let (nx, ny) = (d.dims[ax] as usize, d.dims[ay] as usize);
    let base: u64 = (0..d.axes.len())
        .filter(|&k| k != ax && k != ay)
        .map(|k| at[k] * steps[k])
        .sum();
    let (sx, sy) = (steps[ax], steps[ay]);
    let ids = (0..ny)
        .flat_map(|iy| (0..nx).map(move |ix| (base + ix as u64 * sx + iy as u64 * sy) as usize));
    // Serialized straight from typed values (a `Value` per cell would cost
    // more than the rest of the 10^6-cell reply).
    Json(MapReply {
        nx,
        ny,
        base,
        sx,
        sy,
        z: d.cols[z].at(ids),
    })
    .into_response()
}

/// `/api/map`'s reply: the x × y slice's z values, row by row (y
/// outermost), and where its cells are in the table (id = base + ix·sx +
/// iy·sy).
#[derive(serde::Serialize)]
struct MapReply {
    nx: usize,
    ny: usize,
    base: u64,
    sx: u64,
    sy: u64,
    z: Column,
}

/// A column's values at some rows, typed for serialization: numbers (null
/// where empty), category codes, or row numbers.
#[derive(serde::Serialize)]
#[serde(untagged)]
enum Column {
    Num(Vec<Option<f64>>),
    Cat(Vec<u32>),
    Whole(Vec<usize>),
}

impl Col {
    /// This column at `rows`, in their order.
    fn at(&self, rows: impl Iterator<Item = usize>) -> Column {
        match self {
            Col::Num(v) => Column::Num(rows.map(|r| v[r].is_finite().then_some(v[r])).collect()),
            Col::Cat(c, _) => Column::Cat(rows.map(|r| c[r]).collect()),
        }
    }
}

/// A table that is not a grid (a point list, a sampling design): x, y and
/// z of every row, for a scatter plot.
async fn points(State(d): State<Arc<Data>>, Query(q): Query<HashMap<String, String>>) -> Response {
    let col = |key: &str| -> Result<usize, Response> {
        let name = q
            .get(key)
            .ok_or_else(|| err(StatusCode::BAD_REQUEST, format!("`{key}` is required")))?;
        d.col(name).ok_or_else(|| {
            err(
                StatusCode::BAD_REQUEST,
                format!("`{key}` = {name:?}: not a column"),
            )
        })
    };
    let (x, y, z) = match (col("x"), col("y"), col("z")) {
        (Ok(x), Ok(y), Ok(z)) => (x, y, z),
        (Err(e), _, _) | (_, Err(e), _) | (_, _, Err(e)) => return e,
    };
    let values = |k: usize| d.cols[k].at(0..d.rows);
    let id = match d.col("id") {
        Some(k) => values(k),
        None => Column::Whole((0..d.rows).collect()),
    };
    Json(PointsReply {
        x: values(x),
        y: values(y),
        z: values(z),
        id,
    })
    .into_response()
}

/// `/api/points`' reply: every row's x, y and z and its id.
#[derive(serde::Serialize)]
struct PointsReply {
    x: Column,
    y: Column,
    z: Column,
    id: Column,
}

/// The scene id asked for and its row in the table.
fn id_param(d: &Data, q: &HashMap<String, String>) -> Result<(u64, usize), Response> {
    let s = q
        .get("id")
        .ok_or_else(|| err(StatusCode::BAD_REQUEST, "`id` is required"))?;
    match s.parse::<u64>() {
        Ok(id) => match d.row_of.get(&id) {
            Some(&row) => Ok((id, row)),
            None => Err(err(
                StatusCode::NOT_FOUND,
                format!("no scene {id} in this table ({} rows)", d.rows),
            )),
        },
        Err(_) => Err(err(
            StatusCode::BAD_REQUEST,
            format!("`id` = {s:?}: not a whole number"),
        )),
    }
}

async fn row(State(d): State<Arc<Data>>, Query(q): Query<HashMap<String, String>>) -> Response {
    let (id, row) = match id_param(&d, &q) {
        Ok(i) => i,
        Err(e) => return e,
    };
    // [name, text] pairs, in the table's column order.
    let fields: Vec<Json_> = d
        .header
        .iter()
        .enumerate()
        .map(|(k, h)| json!([h, d.cell(k, row)]))
        .collect();
    Json(json!({"id": id, "row": fields})).into_response()
}

/// Run scene `id` (row `row`) again for a closer look (its model's
/// [`crate::model::Model::look`]).
fn run_scene(d: &Data, id: u64, row: usize, stop: &crate::engine::Stop) -> Result<Json_> {
    let o = &d.overrides;
    match (&d.sweep, &d.problem) {
        (Some(sweep), _) => sweep.model.look(id, sweep.scene(id), o, stop),
        (None, Some(opt)) => {
            let scene = d.scene_spec(id, row)?.validate();
            opt.problem.model.look(id, scene, o, stop)
        }
        (None, None) => anyhow::bail!("scenes cannot be run: {}", d.sweep_problem),
    }
}

async fn scene(State(d): State<Arc<Data>>, Query(q): Query<HashMap<String, String>>) -> Response {
    let (id, row) = match id_param(&d, &q) {
        Ok(i) => i,
        Err(e) => return e,
    };
    if !d.runnable() {
        return err(
            StatusCode::NOT_FOUND,
            format!("scenes cannot be run: {}", d.sweep_problem),
        );
    }
    let Ok(permit) = d.runs.clone().try_acquire_owned() else {
        return err(
            StatusCode::SERVICE_UNAVAILABLE,
            format!("{MAX_RUNS} scenes are already running; try again in a moment"),
        );
    };
    let d2 = d.clone();
    let stop = crate::engine::Stop::new();
    let stop2 = stop.clone();
    let task = tokio::task::spawn_blocking(move || {
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            run_scene(&d2, id, row, &stop2)
        }));
        drop(permit);
        r
    });
    match tokio::time::timeout(Duration::from_secs(RUN_TIMEOUT_S), task).await {
        Ok(Ok(Ok(Ok(v)))) => Json(v).into_response(),
        Ok(Ok(Ok(Err(e)))) => err(StatusCode::BAD_REQUEST, format!("{e:#}")),
        Ok(_) => err(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("scene {id} failed"),
        ),
        Err(_) => {
            // Stop it: it would keep its slot for minutes (a 10^4-bead
            // chain), and every other scene would be refused meanwhile.
            stop.request();
            err(
                StatusCode::SERVICE_UNAVAILABLE,
                format!("scene {id} takes longer than {RUN_TIMEOUT_S} s: stopped"),
            )
        }
    }
}

async fn scene_toml(
    State(d): State<Arc<Data>>,
    Query(q): Query<HashMap<String, String>>,
) -> Response {
    let (id, row) = match id_param(&d, &q) {
        Ok(i) => i,
        Err(e) => return e,
    };
    if !d.runnable() {
        return err(
            StatusCode::NOT_FOUND,
            format!("scenes cannot be exported: {}", d.sweep_problem),
        );
    }
    // The sweep's solver flags go into the scene's [solver], so that
    // `cradle run` on it gives this row (they were left out: 18–21 cells
    // differed under --method/--tolerance/--precision).
    let o = &d.overrides;
    let with_flags = |mut s: crate::scene::SceneSpec| {
        use crate::choice::Choice;
        if o.method.is_some() || o.precision.is_some() || o.tolerance.is_some() {
            let solver = s.solver.get_or_insert_with(Default::default);
            if let Some(m) = o.method {
                solver.method = Some(Choice::name(m).to_string());
            }
            if let Some(p) = o.precision {
                solver.precision = Some(Choice::name(p).to_string());
            }
            if let Some(t) = o.tolerance {
                solver.tolerance = Some(t);
                solver.dt = None;
            }
        }
        s
    };
    let model = match o.model {
        Some(m) if m != crate::engine::Model::Hertz => {
            format!("# run it with --model {}\n", crate::choice::Choice::name(m))
        }
        _ => String::new(),
    };
    match d
        .scene_spec(id, row)
        .map(with_flags)
        .and_then(|s| toml::to_string(&s).map_err(|e| anyhow::anyhow!(e)))
    {
        Ok(text) => (
            [
                (header::CONTENT_TYPE, "application/toml".to_string()),
                (
                    header::CONTENT_DISPOSITION,
                    format!("attachment; filename=\"scene_{id}.toml\""),
                ),
            ],
            format!("# scene {id} of {}\n{model}{text}", d.name),
        )
            .into_response(),
        Err(e) => err(StatusCode::BAD_REQUEST, format!("{e:#}")),
    }
}

async fn page() -> Html<&'static str> {
    Html(PAGE)
}

/// A vendored file, cached by the browser for the server's life.
fn asset(kind: &'static str, body: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, kind),
            (header::CACHE_CONTROL, "max-age=3600"),
        ],
        body,
    )
        .into_response()
}

async fn uplot_js() -> Response {
    asset("text/javascript; charset=utf-8", UPLOT_JS)
}

async fn uplot_css() -> Response {
    asset("text/css; charset=utf-8", UPLOT_CSS)
}

async fn not_found() -> Response {
    err(
        StatusCode::NOT_FOUND,
        "no such page: the explorer serves /, /vendor/uPlot.{js,css} and /api/{meta,map,points,row,scene,scene.toml}",
    )
}

/// Serve `table` on `host:port` until the process ends; `ready` gets the URL.
pub fn serve(table: &Path, host: &str, port: u16, ready: &dyn Fn(&str)) -> Result<()> {
    let data = Arc::new(load(table)?);
    let app = Router::new()
        .route("/", get(page))
        .route("/vendor/uPlot.js", get(uplot_js))
        .route("/vendor/uPlot.css", get(uplot_css))
        .route("/api/meta", get(meta))
        .route("/api/map", get(map))
        .route("/api/points", get(points))
        .route("/api/row", get(row))
        .route("/api/scene", get(scene))
        .route("/api/scene.toml", get(scene_toml))
        .fallback(not_found)
        .with_state(data);
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    rt.block_on(async {
        let listener = tokio::net::TcpListener::bind((host, port))
            .await
            .with_context(|| format!("cannot listen on {host}:{port}"))?;
        let addr = listener.local_addr()?;
        ready(&format!("http://{addr}/"));
        axum::serve(listener, app).await?;
        Ok(())
    })
}
