//! Sweeps (docs/SPEC.md §4): a base scene and `[[axis]]` tables; the cartesian
//! product, scene id = row-major index with the first axis slowest. Scenes are
//! produced one id at a time, never materialised as a whole.

pub mod axis;
pub mod design;
pub mod fill;
pub mod merge;
mod parse;
pub mod pipeline;
pub mod points;
pub mod refine;
pub mod run;
pub mod session;
pub mod shard;

use std::path::Path;

use serde::Serialize;

use crate::engine::{Overrides, Solver};
use crate::error::{InputError, Source};
use crate::output::row::{ColType, Field};
use crate::scene::{Scene, SceneSpec};
pub use axis::{Param, Value, Values};
pub(crate) use parse::base_scene;

/// Most scenes one sweep may have (refused before anything is allocated).
pub const MAX_SCENES: u64 = 1_000_000_000;

/// Values of one axis that sweep validation tries (all of a shorter axis).
pub const VALIDATION_SAMPLES: usize = 1024;

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

impl Axis {
    /// The fewest and most of its numeric values as counts (a `balls`
    /// axis: the shortest and longest chain it makes); `None` if it has none.
    pub(crate) fn count_span(&self) -> Option<(usize, usize)> {
        (0..self.values.len())
            .filter_map(|i| match self.values.get(i) {
                Value::Num(x) => Some(x as usize),
                Value::Text(_) => None,
            })
            .fold(None, |span, n| match span {
                None => Some((n, n)),
                Some((lo, hi)) => Some((lo.min(n), hi.max(n))),
            })
    }
}

/// What `axes` vary: their keys, and the fewest and most balls of a `balls`
/// axis.
fn varied(axes: &[Axis]) -> crate::model::Varied<'_> {
    crate::model::Varied {
        names: axes.iter().map(|a| a.param.name.as_str()).collect(),
        balls: axes
            .iter()
            .find(|a| a.param.name == "balls")
            .and_then(Axis::count_span),
    }
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
    /// What its scenes are (a cradle, a granular chain): their columns and
    /// how they run (`crate::model`, chosen from the base scene).
    #[serde(skip)]
    pub model: std::sync::Arc<dyn crate::model::Model>,
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

    /// What this sweep's scenes can ask of a backend (read from the base
    /// scene and which quantities the axes vary, without building a scene),
    /// for [`crate::backend::Backend::prepare`].
    pub fn needs(&self, o: &Overrides) -> Result<crate::backend::Needs, InputError> {
        let solver = Solver::resolve(&self.base, o)?;
        Ok(self.model.needs(&self.base, &varied(&self.axes), &solver))
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
        let mut t = vec![ColType::Int];
        t.extend(self.axis_types());
        t.extend(self.model.types());
        t
    }

    pub fn axis_names(&self) -> Vec<String> {
        self.axes.iter().map(|a| a.name.clone()).collect()
    }
}
