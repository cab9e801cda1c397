//! What an output path may be, decided in one place for every command that
//! writes a file (`sweep --out`, `merge --out`, `run --trace`, `plot --out`),
//! before any work starts.
//!
//! Outputs are written beside their final name and renamed over it when
//! complete, so whatever the name points at is replaced. The rules:
//! - absent, or a regular file (replaced when the new one is complete);
//! - a symlink is written *through*: its final target obeys these rules and
//!   is what gets replaced; the link itself stays;
//! - never a directory, a FIFO, a socket or a device node (`/dev/null`);
//! - never one of the command's inputs (the sweep file, the scene file it
//!   names, a part being merged, the table being plotted), nor may one of the
//!   companion files written beside it (`.partial`, `.json`, `.lock`, …) be;
//! - never an input's companion (`merge --out part.csv.json` would replace
//!   the sidecar the part is checked against);
//! - its directory exists.

use std::fs;
use std::path::{Path, PathBuf};

use crate::error::InputError;

/// Every file written beside an output `FILE` (by a sweep or a merge): the
/// partial rows, the resume fingerprint, the sidecar, their temporaries
/// (`partial::write_atomic`) and the lock. [`output`] checks each of them.
pub const COMPANIONS: &[&str] = &[
    ".partial",
    ".partial.spec",
    ".partial.spec.tmp",
    ".json",
    ".json.tmp",
    ".lock",
    ".tmp",
];

/// `path` with `suffix` appended to its file name (`a.csv` → `a.csv.json`).
pub fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(suffix);
    PathBuf::from(s)
}

fn refuse(flag: &str, path: &Path, why: impl Into<String>) -> InputError {
    InputError::Flag {
        flag: flag.into(),
        value: path.display().to_string(),
        allowed: why.into(),
    }
}

/// Follow `p` through symlinks to the path that would really be written.
/// A dangling link resolves to the (absent) file it names.
fn resolve_links(flag: &str, p: &Path) -> Result<PathBuf, InputError> {
    let mut p = p.to_path_buf();
    for _ in 0..40 {
        match fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let target = fs::read_link(&p)
                    .map_err(|e| refuse(flag, &p, format!("cannot read this symlink: {e}")))?;
                p = match p.parent() {
                    Some(dir) if target.is_relative() => dir.join(target),
                    _ => target,
                };
            }
            _ => return Ok(p),
        }
    }
    Err(refuse(flag, &p, "too many levels of symlinks"))
}

/// Two paths name the same existing file (hard links included).
fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if let (Ok(x), Ok(y)) = (fs::metadata(a), fs::metadata(b)) {
            return x.dev() == y.dev() && x.ino() == y.ino();
        }
        false
    }
    #[cfg(not(unix))]
    {
        matches!((fs::canonicalize(a), fs::canonicalize(b)), (Ok(x), Ok(y)) if x == y)
    }
}

/// What kind of thing is at `p` (which exists and is not a symlink).
fn describe(m: &fs::Metadata) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = m.file_type();
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if t.is_socket() {
            return "a socket";
        }
        if t.is_block_device() || t.is_char_device() {
            return "a device node";
        }
    }
    if m.is_dir() {
        "a directory"
    } else {
        "not a regular file"
    }
}

/// Check that `out` (given with `flag`) may be written, with `companions`
/// (suffixes of files written beside it) and without touching `inputs`.
/// Returns the path to write: `out` itself, or the final target of a symlink.
pub fn output(
    flag: &str,
    out: &Path,
    inputs: &[PathBuf],
    companions: &[&str],
) -> Result<PathBuf, InputError> {
    if out.as_os_str().is_empty() {
        return Err(refuse(flag, out, "a file name"));
    }
    let path = resolve_links(flag, out)?;
    let shown = if path == out {
        String::new()
    } else {
        format!(" (the symlink's target {})", path.display())
    };
    match fs::metadata(&path) {
        Ok(m) if m.is_dir() => {
            return Err(refuse(
                flag,
                out,
                format!("is a directory{shown}: give a file name, e.g. {}", path.join("out.csv").display()),
            ))
        }
        Ok(m) if !m.is_file() => {
            return Err(refuse(
                flag,
                out,
                format!(
                    "is {}{shown}: an output must be a regular file or a new name (cradle replaces it when complete and would destroy it)",
                    describe(&m)
                ),
            ))
        }
        _ => {}
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(refuse(
            flag,
            out,
            format!(
                "its directory {} does not exist; create it first",
                dir.display()
            ),
        ));
    }
    for input in inputs {
        if same_file(&path, input) {
            return Err(refuse(
                flag,
                out,
                format!(
                    "is an input of this command ({}): choose another output name",
                    input.display()
                ),
            ));
        }
        let input = resolve_links(flag, input).unwrap_or_else(|_| input.clone());
        for suffix in COMPANIONS {
            let c = with_suffix(&input, suffix);
            if c == path || same_file(&c, &path) {
                return Err(refuse(
                    flag,
                    out,
                    format!(
                        "is written beside the input {} (its `{suffix}` companion, which cradle reads or keeps with it): choose another output name",
                        input.display()
                    ),
                ));
            }
        }
    }
    for suffix in companions {
        let c = with_suffix(&path, suffix);
        if let Ok(m) = fs::symlink_metadata(&c) {
            if !m.is_file() {
                return Err(refuse(
                    flag,
                    out,
                    format!(
                        "{} (written beside the output) is {}: move it away or choose another output name",
                        c.display(),
                        if m.file_type().is_symlink() { "a symlink" } else { describe(&m) }
                    ),
                ));
            }
            for input in inputs {
                if same_file(&c, input) {
                    return Err(refuse(
                        flag,
                        out,
                        format!("{} (written beside the output) is an input of this command: choose another output name", c.display()),
                    ));
                }
            }
        }
    }
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_inputs_dirs_and_devices_and_follows_links() {
        let d = tempfile::tempdir().unwrap();
        let input = d.path().join("in.toml");
        fs::write(&input, "x").unwrap();
        let ins = [input.clone()];
        assert!(output("--out", &input, &ins, &[]).is_err());
        assert!(output("--out", d.path(), &ins, &[]).is_err());
        assert!(output("--out", Path::new("/dev/null"), &ins, &[]).is_err());
        assert!(output("--out", &d.path().join("no/such/dir.csv"), &ins, &[]).is_err());
        let fresh = d.path().join("a.csv");
        assert_eq!(output("--out", &fresh, &ins, &[".json"]).unwrap(), fresh);
        #[cfg(unix)]
        {
            let link = d.path().join("link.csv");
            std::os::unix::fs::symlink("a.csv", &link).unwrap();
            assert_eq!(output("--out", &link, &ins, &[]).unwrap(), fresh);
            let to_input = d.path().join("link.toml");
            std::os::unix::fs::symlink(&input, &to_input).unwrap();
            assert!(output("--out", &to_input, &ins, &[]).is_err());
            // A companion that is an input: `--out in` would write `in.toml`.
            assert!(output("--out", &d.path().join("in"), &ins, &[".toml"]).is_err());
            // An input's companion: its sidecar, whether it exists or not.
            let sidecar = d.path().join("in.toml.json");
            assert!(output("--out", &sidecar, &ins, &[]).is_err());
            fs::write(&sidecar, "{}").unwrap();
            let e = output("--out", &sidecar, &ins, &[])
                .unwrap_err()
                .to_string();
            assert!(e.contains("beside the input"), "{e}");
        }
    }
}
