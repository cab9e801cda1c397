//! Atomic publication, the one way every writer makes a file visible under
//! its final name: the bytes go to a temporary file beside it, which is
//! synced to disk (by the writer that wrote it: `publish` is told a finished
//! file) and then renamed over the name (rename is atomic within a
//! directory), and the directory is synced so the rename itself survives a
//! crash. A kill or a full disk at any point leaves the previous file (or
//! none) under the name, never a cut-off one.

use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::Path;

use anyhow::{Context, Result};

use super::guard::with_suffix;

/// Suffix of the temporary file [`write_with`] writes beside its target.
pub const TMP: &str = ".tmp";

/// Make the finished file `tmp` visible as `path`: renamed over `path`,
/// the directory synced. `tmp` must already be on disk: every writer syncs
/// the file it wrote where it finishes writing it ([`write_with`] does).
pub fn publish(tmp: &Path, path: &Path) -> Result<()> {
    super::failpoint::check("publish")
        .with_context(|| format!("cannot write {}", path.display()))?;
    fs::rename(tmp, path)
        .with_context(|| format!("cannot rename {} to {}", tmp.display(), path.display()))?;
    // The rename is durable once the directory is (not every filesystem
    // lets a directory be synced: best effort).
    if let Some(dir) = path.parent() {
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        if let Ok(d) = File::open(dir) {
            let _ = d.sync_all();
        }
    }
    Ok(())
}

/// Write `path` atomically: `write` fills a temporary file beside it
/// (`path` + [`TMP`]), which is then published; on any error the temporary
/// file is removed and `path` is untouched.
pub fn write_with<T>(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<T>,
) -> Result<T> {
    let tmp = with_suffix(path, TMP);
    let r = (|| -> Result<T> {
        let mut w = BufWriter::new(
            File::create(&tmp).with_context(|| format!("cannot create {}", tmp.display()))?,
        );
        let v = write(&mut w)?;
        w.flush()
            .and_then(|_| w.get_ref().sync_all())
            .with_context(|| format!("cannot write {}", tmp.display()))?;
        drop(w);
        publish(&tmp, path)?;
        Ok(v)
    })();
    if r.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    r
}

/// [`write_with`] holding the output's lock (`output::lock::OutputLock`,
/// `path` + `.lock`) throughout: a second writer of the same file (another
/// `fill`, `run --trace` or `plot` into it) is refused, exit 2 naming the
/// holder, instead of mixing its bytes into the same temporary file.
pub fn write_alone<T>(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<T>,
) -> Result<T> {
    let _lock = super::lock::OutputLock::acquire(path)?;
    write_with(path, write)
}

/// Suffixes of the files [`write_alone`] writes beside its target.
pub const ALONE_COMPANIONS: &[&str] = &[TMP, ".lock"];

/// Write `bytes` to `path` atomically.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_with(path, |w| {
        w.write_all(bytes)
            .with_context(|| format!("cannot write {}", path.display()))
    })
}
