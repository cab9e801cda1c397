//! One writer per output: `FILE.lock` beside the output, held with an
//! exclusive advisory lock (`flock` on Unix) for the whole run. A second
//! `cradle` that would write the same output (a resubmitted Slurm task that is
//! still running, a second terminal) is refused before it touches anything,
//! with the holder named. The kernel drops the lock when its holder dies, so a
//! killed run leaves no stale lock behind; the file itself is removed by the
//! holder when it ends.

use std::fs::{self, File, OpenOptions, TryLockError};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result};

use super::guard::with_suffix;
use crate::error::InputError;

/// Held while a run writes its output; released (and the file removed) on drop.
#[derive(Debug)]
pub struct OutputLock {
    path: PathBuf,
    file: Option<File>,
}

fn now_s() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}

fn hostname() -> String {
    fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|s| s.trim().to_string())
        .ok()
        .or_else(|| std::env::var("HOSTNAME").ok())
        .unwrap_or_else(|| "this machine".into())
}

/// The holder's description, as written into the lock file.
fn holder_text() -> String {
    let cmd: Vec<String> = std::env::args().collect();
    format!(
        "pid {} on {} since unix time {}: {}\n",
        std::process::id(),
        hostname(),
        now_s(),
        cmd.join(" ")
    )
}

impl OutputLock {
    pub fn path_for(out: &Path) -> PathBuf {
        with_suffix(out, ".lock")
    }

    /// Take the lock of `out`, or say who holds it.
    pub fn acquire(out: &Path) -> Result<OutputLock> {
        let path = Self::path_for(out);
        for _ in 0..100 {
            let file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(&path)
                .map_err(|e| InputError::Data {
                    path: path.clone(),
                    what: format!("cannot create this lock file beside the output ({e}): is its directory writable?"),
                })?;
            match file.try_lock() {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => {
                    let holder = fs::read_to_string(&path).unwrap_or_default();
                    let holder = holder.trim();
                    return Err(InputError::Busy {
                        path: out.to_path_buf(),
                        holder: if holder.is_empty() {
                            "another process".into()
                        } else {
                            holder.to_string()
                        },
                        lock: path,
                    }
                    .into());
                }
                Err(TryLockError::Error(e)) => {
                    return Err(e).with_context(|| format!("cannot lock {}", path.display()))
                }
            }
            // The previous holder may have removed the file between our open
            // and our lock: then we locked a file nobody else can see. Retry.
            if !still_there(&file, &path) {
                continue;
            }
            let mut lock = OutputLock {
                path,
                file: Some(file),
            };
            let f = lock.file.as_mut().expect("just set");
            f.set_len(0)?;
            f.write_all(holder_text().as_bytes())?;
            f.flush()?;
            return Ok(lock);
        }
        anyhow::bail!(
            "cannot lock {}: it keeps being replaced by another process",
            path.display()
        )
    }
}

#[cfg(unix)]
fn still_there(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), fs::metadata(path)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn still_there(_file: &File, path: &Path) -> bool {
    path.exists()
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        // Remove while still holding it, so nobody locks a file about to vanish.
        let _ = fs::remove_file(&self.path);
        drop(self.file.take());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn second_holder_is_refused_and_named_then_lock_is_free_again() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("a.csv");
        let first = OutputLock::acquire(&out).unwrap();
        let err = OutputLock::acquire(&out).unwrap_err().to_string();
        assert!(
            err.contains(&format!("pid {}", std::process::id())),
            "{err}"
        );
        drop(first);
        assert!(!OutputLock::path_for(&out).exists());
        OutputLock::acquire(&out).unwrap();
    }
}
