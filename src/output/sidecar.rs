//! `FILE.csv.json`: how a CSV was made — the resolved sweep, crate version,
//! git revision, backend and adapter, solver settings, wall time, scenes/s.

use std::path::{Path, PathBuf};

use serde::Serialize;

pub fn path(csv: &Path) -> PathBuf {
    let mut s = csv.as_os_str().to_owned();
    s.push(".json");
    PathBuf::from(s)
}

#[derive(Serialize)]
pub struct Sidecar<'a, S: Serialize> {
    pub tool: &'static str,
    pub version: &'static str,
    pub git_revision: &'static str,
    pub command: Vec<String>,
    pub sweep_file: &'a str,
    pub sweep: &'a S,
    pub backend: &'a str,
    pub adapter: &'a str,
    pub solver: serde_json::Value,
    /// The scene ids in this file: [first, end).
    pub ids: [u64; 2],
    pub total_scenes: u64,
    pub shard: Option<[u64; 2]>,
    pub scenes_ok: u64,
    pub scenes_not_ok: u64,
    /// Wall time of every run that wrote this file (s): a resumed run adds
    /// the earlier runs' time up to their last saved batch.
    pub wall_s: f64,
    pub scenes_per_s: f64,
    pub resumed_from_row: u64,
    /// Wall time of this run alone (s).
    pub wall_s_this_run: f64,
    /// Where this run's time went: thread-seconds per pipeline stage.
    pub stages_s: serde_json::Value,
    /// An adaptive refinement: the scenes each level computed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refine: Option<serde_json::Value>,
    /// What a `--resume` must agree with: sweep, shard, solver flags, version.
    pub fingerprint: &'a str,
}

pub const GIT_REVISION: &str = match option_env!("CRADLE_GIT_REV") {
    Some(r) => r,
    None => "unknown",
};

/// The sidecar's text.
pub fn text<S: Serialize>(s: &Sidecar<S>) -> anyhow::Result<String> {
    Ok(serde_json::to_string_pretty(s)? + "\n")
}

/// The fingerprint a sidecar records, if it can be read.
pub fn fingerprint(sidecar: &Path) -> Option<String> {
    let text = std::fs::read_to_string(sidecar).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    Some(v.get("fingerprint")?.as_str()?.to_string())
}
