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
    /// The table's bytes as published ([`seal`]): every reader checks them
    /// ([`read_checked`]). Absent in sidecars of cradle before 0.1 #31.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub table: Option<Seal>,
}

/// What a sidecar promises of its table: its rows, its length and the
/// CRC-32 of its bytes, taken when the table was published.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Seal {
    pub rows: u64,
    pub bytes: u64,
    /// CRC-32 (IEEE) of the file's bytes, 8 hex digits.
    pub crc32: String,
}

/// Length and CRC-32 of `file` (its `rows` as the writer counted them).
pub fn seal(file: &Path, rows: u64) -> anyhow::Result<Seal> {
    use anyhow::Context;
    let mut f =
        std::fs::File::open(file).with_context(|| format!("cannot read {}", file.display()))?;
    let (bytes, crc) = crc_of(&mut f).with_context(|| format!("cannot read {}", file.display()))?;
    Ok(Seal {
        rows,
        bytes,
        crc32: format!("{crc:08x}"),
    })
}

fn crc_of(r: &mut dyn std::io::Read) -> std::io::Result<(u64, u32)> {
    let mut h = crc32fast::Hasher::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut n = 0u64;
    loop {
        let k = match r.read(&mut buf) {
            Ok(0) => break,
            Ok(k) => k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        h.update(&buf[..k]);
        n += k as u64;
    }
    Ok((n, h.finalize()))
}

/// Check `table` against its sidecar's [`Seal`]: the same length and CRC-32
/// as when it was published, or an error (exit 2) naming the file, what the
/// sidecar promises and what the file holds. A sidecar without a seal (an
/// older cradle's) passes.
pub fn check(table: &Path, sc: &Sidecar) -> Result<(), InputError> {
    let Some(want) = &sc.table else {
        return Ok(());
    };
    let mut f = crate::error::open_input(table, crate::error::MAX_TABLE_BYTES)?;
    let (bytes, crc) = crc_of(&mut f).map_err(|e| InputError::Data {
        path: table.to_path_buf(),
        what: format!("cannot be read ({e})"),
    })?;
    let crc = format!("{crc:08x}");
    if bytes != want.bytes || crc != want.crc32 {
        return Err(InputError::Data {
            path: table.to_path_buf(),
            what: format!(
                "is not the table its sidecar {} describes: {} rows in {} bytes with CRC-32 {} were published, the file has {bytes} bytes with CRC-32 {crc}{}; it was cut, edited or replaced since — run the command that made it again ({})",
                path(table).display(),
                want.rows,
                want.bytes,
                want.crc32,
                if bytes < want.bytes { " (shorter: rows are missing)" } else { "" },
                sc.command.join(" ")
            ),
        });
    }
    Ok(())
}

/// [`read`], then [`check`]: the sidecar of `table` with its promise kept,
/// `Ok(None)` when it has none.
pub fn read_checked(table: &Path) -> Result<Option<Sidecar>, InputError> {
    let sc = read(table)?;
    if let Some(sc) = &sc {
        check(table, sc)?;
    }
    Ok(sc)
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
    serde_json::from_str(&text).map(Some).map_err(|e| {
        // A trace's sidecar (`cradle run --trace`, request.rs) names its
        // scene: the file beside it is a trace, which a reader of tables
        // should say.
        let trace_of = serde_json::from_str::<serde_json::Value>(&text)
            .ok()
            .and_then(|v| v.get("trace_of")?.as_str().map(str::to_owned));
        match trace_of {
            Some(scene) => InputError::Data {
                path: table.to_path_buf(),
                what: format!(
                    "a trace (of {scene}), not a sweep's table: plot it with `cradle plot --trace {} --out FILE.png`",
                    table.display()
                ),
            },
            None => InputError::Data {
                path: sc,
                what: format!("not a cradle sidecar ({e})"),
            },
        }
    })
}

/// The solver flags a sweep ran with, as its sidecar records them
/// (`solver.flags`; read back by [`Sidecar::overrides`]).
pub fn flags(o: &crate::engine::Overrides) -> serde_json::Value {
    serde_json::json!({
        "method": o.method.map(|m| m.name()),
        "precision": o.precision.map(|p| p.name()),
        "tolerance": o.tolerance,
    })
}

impl Sidecar {
    /// The solver flags the sweep ran with ([`flags`]), as overrides.
    pub fn overrides(&self) -> crate::engine::Overrides {
        use crate::choice::Choice;
        let f = &self.solver["flags"];
        crate::engine::Overrides {
            method: f["method"]
                .as_str()
                .and_then(crate::scene::Method::from_name),
            precision: f["precision"]
                .as_str()
                .and_then(crate::scene::Precision::from_name),
            tolerance: f["tolerance"].as_f64(),
            ..Default::default()
        }
    }
}
