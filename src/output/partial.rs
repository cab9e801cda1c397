//! Crash-safe CSV output: rows go to `FILE.partial` (flushed after every
//! batch) and the file is renamed to `FILE` only when complete, so a killed
//! run never leaves a file that looks complete. `--resume` truncates the
//! partial file to its last complete row and continues after it; a
//! fingerprint file (`FILE.partial.spec`) refuses to resume another sweep.

use std::fs::{self, File, OpenOptions};
use std::io::{BufRead, BufReader, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

pub struct PartialCsv {
    pub path: PathBuf,
    partial: PathBuf,
    spec: PathBuf,
    file: File,
    /// Rows already in the file (from an earlier run, when resuming).
    pub rows_done: u64,
}

pub fn partial_path(out: &Path) -> PathBuf {
    let mut s = out.as_os_str().to_owned();
    s.push(".partial");
    PathBuf::from(s)
}

fn spec_path(out: &Path) -> PathBuf {
    let mut s = out.as_os_str().to_owned();
    s.push(".partial.spec");
    PathBuf::from(s)
}

/// What `open` found.
pub enum Opened {
    Writing(PartialCsv),
    /// `--resume` of a run whose output is already complete.
    AlreadyComplete,
}

impl PartialCsv {
    /// Start (or, with `resume`, continue) writing `out`. `header` is the CSV
    /// header line (with its newline) and `fingerprint` identifies the sweep.
    pub fn open(out: &Path, header: &[u8], fingerprint: &str, resume: bool) -> Result<Opened> {
        let partial = partial_path(out);
        let spec = spec_path(out);
        if resume && partial.exists() {
            let old = fs::read_to_string(&spec).unwrap_or_default();
            if old != fingerprint {
                bail!(
                    "cannot resume {}: it was written by a different sweep, solver or shard (see {}); run without --resume to start over",
                    partial.display(),
                    spec.display()
                );
            }
            let (keep, rows) = complete_prefix(&partial, header)?;
            let mut file = OpenOptions::new().read(true).write(true).open(&partial)?;
            file.set_len(keep)?;
            file.seek(SeekFrom::End(0))?;
            return Ok(Opened::Writing(PartialCsv {
                path: out.to_path_buf(),
                partial,
                spec,
                file,
                rows_done: rows,
            }));
        }
        if resume && out.exists() {
            return Ok(Opened::AlreadyComplete);
        }
        fs::write(&spec, fingerprint)
            .with_context(|| format!("cannot write {}", spec.display()))?;
        let mut file = File::create(&partial)
            .with_context(|| format!("cannot create {}", partial.display()))?;
        file.write_all(header)?;
        file.sync_data()?;
        Ok(Opened::Writing(PartialCsv {
            path: out.to_path_buf(),
            partial,
            spec,
            file,
            rows_done: 0,
        }))
    }

    /// Append complete rows and push them to disk.
    pub fn append(&mut self, rows: &[u8]) -> Result<()> {
        self.file.write_all(rows)?;
        self.file.flush()?;
        Ok(())
    }

    /// All rows written: make the file visible under its final name.
    pub fn finish(self) -> Result<()> {
        self.file.sync_all()?;
        drop(self.file);
        fs::rename(&self.partial, &self.path).with_context(|| {
            format!(
                "cannot rename {} to {}",
                self.partial.display(),
                self.path.display()
            )
        })?;
        let _ = fs::remove_file(&self.spec);
        Ok(())
    }
}

/// Length in bytes of the header plus every complete row, and the row count.
fn complete_prefix(partial: &Path, header: &[u8]) -> Result<(u64, u64)> {
    let mut r = BufReader::new(File::open(partial)?);
    let mut line = Vec::new();
    r.read_until(b'\n', &mut line)?;
    if line != header {
        bail!(
            "cannot resume {}: its header differs from this sweep's",
            partial.display()
        );
    }
    let mut keep = line.len() as u64;
    let mut rows = 0;
    loop {
        line.clear();
        let n = r.read_until(b'\n', &mut line)?;
        if n == 0 || line.last() != Some(&b'\n') {
            break;
        }
        keep += n as u64;
        rows += 1;
    }
    Ok((keep, rows))
}
