//! `FILE.json` beside every table: how it was made (the resolved sweep,
//! crate version, git revision, backend and adapter, solver settings, wall
//! time, scenes/s), which ids it holds, and the fingerprint a resume or a
//! merge must agree with. One struct, [`Sidecar`], written by `sweep` and
//! `merge` and read by `merge`, `fill`, `plot`, `explore` and `--resume`.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::InputError;

pub fn path(csv: &Path) -> PathBuf {
    let mut s = csv.as_os_str().to_owned();
    s.push(".json");
    PathBuf::from(s)
}

/// A table's sidecar. `S` is the sweep: the `Sweep` itself when written,
/// its JSON when read (the fields a reader needs are read from it by
/// name: `axes[k].name`, `axes[k].values`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Sidecar<S = serde_json::Value> {
    pub tool: String,
    pub version: String,
    pub git_revision: String,
    pub command: Vec<String>,
    pub sweep_file: String,
    pub sweep: S,
    pub backend: String,
    pub adapter: String,
    pub solver: serde_json::Value,
    /// The scene ids in this file: [first, end).
    pub ids: [u64; 2],
    pub total_scenes: u64,
    pub shard: Option<[u64; 2]>,
    pub scenes_ok: u64,
    pub scenes_not_ok: u64,
    /// Wall time of every run that wrote this file (s): a resumed run adds
    /// the earlier runs' time up to their last saved batch; a merge, its
    /// parts' times.
    pub wall_s: f64,
    pub scenes_per_s: f64,
    /// Rows an earlier run had written when this one resumed (not in a merge).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resumed_from_row: Option<u64>,
    /// Wall time of this run alone (s; not in a merge).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wall_s_this_run: Option<f64>,
    /// Where this run's time went: thread-seconds per pipeline stage.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stages_s: Option<serde_json::Value>,
    /// An adaptive refinement: the scenes each level computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refine: Option<Refined>,
    /// What a `--resume` must agree with: sweep, shard, solver flags,
    /// version (`sweep::session::Fingerprint`).
    pub fingerprint: String,
    /// A merged table: its parts.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub merged_from: Option<Vec<String>>,
}

/// What a refined table's sidecar says of its refinement.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Refined {
    pub column: String,
    pub threshold: Option<f64>,
    pub coarse_stride: u64,
    /// The full grid's shape.
    pub grid: Vec<u64>,
    /// The first axis' indices a shard refined (not in a merge).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub region_first_axis: Option<[u64; 2]>,
    pub levels: Vec<Level>,
    pub scenes_computed: u64,
    pub fraction_computed: f64,
}

/// One refinement level: its stride (grid steps) and the scenes it computed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Level {
    pub stride: u64,
    pub scenes: u64,
}

pub const GIT_REVISION: &str = match option_env!("CRADLE_GIT_REV") {
    Some(r) => r,
    None => "unknown",
};

/// The sidecar's text.
pub fn text<S: Serialize>(s: &Sidecar<S>) -> anyhow::Result<String> {
    Ok(serde_json::to_string_pretty(s)? + "\n")
}

/// The sidecar of `table`: `Ok(None)` when it has none; an error naming
/// the sidecar when it cannot be read or is not a cradle sidecar.
pub fn read(table: &Path) -> Result<Option<Sidecar>, InputError> {
    let sc = path(table);
    if !sc.exists() {
        return Ok(None);
    }
    let mut text = String::new();
    std::io::Read::read_to_string(
        &mut crate::error::open_input(&sc, crate::error::MAX_TOML_BYTES)?,
        &mut text,
    )
    .map_err(|e| InputError::Data {
        path: sc.clone(),
        what: format!("cannot be read ({e})"),
    })?;
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|e| InputError::Data {
            path: sc,
            what: format!("not a cradle sidecar ({e})"),
        })
}

impl Sidecar {
    /// The sweep's axes as the sidecar records them: name and values.
    pub fn axes(&self) -> Option<Vec<(String, crate::sweep::axis::Values)>> {
        self.sweep["axes"]
            .as_array()?
            .iter()
            .map(|a| {
                Some((
                    a["name"].as_str()?.to_string(),
                    crate::sweep::axis::Values::from_json(&a["values"])?,
                ))
            })
            .collect()
    }
}
