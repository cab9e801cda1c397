//! Crash-safe output: rows go to `FILE.partial` (flushed after every batch)
//! and `FILE` appears only when complete, so a killed run never leaves a
//! file that looks complete. `--resume` truncates the partial file to its
//! last complete row (CSV) or segment (Parquet) and continues after it.
//!
//! A CSV's partial file is the CSV so far; it is renamed to `FILE` at the
//! end. A Parquet's is a header line, the CSV header, then frames of encoded
//! segments (`output::parquet_file`); at the end they are joined into
//! `FILE.tmp`, which is renamed to `FILE`.
//!
//! What a run must share with the one it resumes is its fingerprint (sweep,
//! shard, solver flags, version). It is kept in `FILE.partial.spec` while the
//! run is unfinished and in the sidecar `FILE.json` once it is complete, and
//! it is checked on every `--resume`: a partial or complete file of another
//! sweep is refused, never continued and never taken as done. The spec file
//! also carries the wall time of the earlier runs, so the sidecar of a
//! resumed run covers the whole file. It is replaced atomically (write,
//! rename), so a kill never leaves half of it.
//!
//! The caller holds the output's lock (`output::lock`) for the whole run.

use std::fs::{self, File, OpenOptions};
use std::io::{BufRead, BufReader, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use super::sidecar::Seal;
use anyhow::{Context, Result};

use super::guard::with_suffix;
use crate::error::InputError;

/// What a table is written as.
#[derive(Clone, Debug)]
pub enum TableFormat {
    Csv,
    /// Parquet with this Arrow schema.
    Parquet(arrow_schema::SchemaRef),
}

/// First line of a Parquet output's partial file.
const PARQUET_PARTIAL_MAGIC: &[u8] = b"cradle parquet segments 1\n";

pub struct Partial {
    pub path: PathBuf,
    pub format: TableFormat,
    /// Bytes before the first row (CSV) or frame (Parquet).
    head_len: u64,
    partial: PathBuf,
    spec: PathBuf,
    fingerprint: String,
    file: File,
    /// Rows already in the file (from earlier runs, when resuming).
    pub rows_done: u64,
    /// Bytes a resume dropped after those rows: an incomplete last row, or
    /// a torn row and whatever followed it (a crash's zero-filled block).
    pub dropped_bytes: u64,
    /// Rows of earlier runs whose status is `ok`.
    pub ok_done: u64,
    /// Wall time of earlier runs (s), up to their last saved progress.
    pub wall_before: f64,
    /// Rows of each section (a refinement level), each in id order; the
    /// finished file interleaves them in id order. Empty: one section.
    pub sections: Vec<u64>,
    /// Only the rows with ids in [lo, hi) go into the finished file (a
    /// shard of a refined sweep computes a little beyond its ids).
    pub keep: Option<(u64, u64)>,
    /// The finished file is Parquet of this schema and these column types,
    /// made from the CSV rows of the partial file (a refined sweep).
    pub to_parquet: Option<(arrow_schema::SchemaRef, Vec<super::row::ColType>)>,
}

pub use super::guard::COMPANIONS;

pub fn partial_path(out: &Path) -> PathBuf {
    with_suffix(out, ".partial")
}

/// Rows a `--resume` of `out` would keep from its partial file: its whole
/// rows (CSV) or the rows of its whole segments (Parquet). `None` when there
/// is no readable partial file.
pub fn resumable_rows(out: &Path) -> Option<u64> {
    let partial = partial_path(out);
    // The head a resume expects is the file's own: its first line (the CSV
    // header), or the Parquet magic line and the CSV header after it.
    let mut r = BufReader::new(File::open(&partial).ok()?);
    let mut head = vec![];
    r.read_until(b'\n', &mut head).ok()?;
    let whole = if head == PARQUET_PARTIAL_MAGIC {
        r.read_until(b'\n', &mut head).ok()?;
        complete_frames(&partial, &head)
    } else {
        complete_prefix(&partial, &head)
    };
    whole.ok().map(|(_, rows, _)| rows)
}

fn spec_path(out: &Path) -> PathBuf {
    with_suffix(out, ".partial.spec")
}

/// What `open` found.
pub enum Opened {
    Writing(Box<Partial>),
    /// `--resume` of a run whose output is already complete, made by this
    /// same sweep (the sidecar's fingerprint agrees).
    AlreadyComplete,
}

use super::publish::write_atomic;
use super::publish::TMP;

fn mismatch(path: &Path, what: String) -> anyhow::Error {
    InputError::Data {
        path: path.to_path_buf(),
        what,
    }
    .into()
}

impl Partial {
    /// Start (or, with `resume`, continue) writing `out` as `format`.
    /// `header` is the CSV header line (with its newline) and `fingerprint`
    /// identifies the sweep.
    pub fn open(
        out: &Path,
        format: TableFormat,
        header: &[u8],
        fingerprint: &str,
        resume: bool,
    ) -> Result<Opened> {
        let mut head = vec![];
        if let TableFormat::Parquet(_) = format {
            head.extend_from_slice(PARQUET_PARTIAL_MAGIC);
        }
        head.extend_from_slice(header);
        let header = &head[..];
        let partial = partial_path(out);
        let spec = spec_path(out);
        if resume && partial.exists() {
            let text = fs::read_to_string(&spec).unwrap_or_default();
            let mut lines = text.lines();
            if lines.next() != Some(fingerprint) {
                return Err(mismatch(
                    &partial,
                    format!(
                        "cannot resume: it was written by a different sweep, solver or shard (or its {} is missing); run without --resume to start over",
                        spec.display()
                    ),
                ));
            }
            let wall_before = lines
                .next()
                .and_then(|w| w.trim().parse::<f64>().ok())
                .filter(|w| w.is_finite() && *w >= 0.0)
                .unwrap_or(0.0);
            let (keep, rows, ok) = match format {
                TableFormat::Csv => complete_prefix(&partial, header)?,
                TableFormat::Parquet(_) => complete_frames(&partial, header)?,
            };
            let mut file = OpenOptions::new()
                .read(true)
                .write(true)
                .open(&partial)
                .with_context(|| format!("cannot open {}", partial.display()))?;
            let dropped_bytes = file.metadata()?.len().saturating_sub(keep);
            file.set_len(keep)?;
            file.seek(SeekFrom::End(0))?;
            return Ok(Opened::Writing(Box::new(Partial {
                path: out.to_path_buf(),
                format,
                head_len: header.len() as u64,
                partial,
                spec,
                fingerprint: fingerprint.to_string(),
                file,
                rows_done: rows,
                dropped_bytes,
                ok_done: ok,
                wall_before,
                sections: vec![],
                keep: None,
                to_parquet: None,
            })));
        }
        if resume && out.exists() {
            let sidecar = super::sidecar::path(out);
            let sc = super::sidecar::read(out).ok().flatten();
            let recorded = sc.as_ref().map(|s| s.fingerprint.clone());
            return match recorded {
                Some(f) if f == fingerprint => {
                    // Complete only if it is still the table that was
                    // published (not cut, edited or replaced since).
                    super::sidecar::check(out, sc.as_ref().expect("read above")).map_err(
                        |e| {
                            let what = match e {
                                InputError::Data { what, .. } => what,
                                e => e.to_string(),
                            };
                            mismatch(
                                out,
                                format!("cannot resume: it {what}; run without --resume to make it again"),
                            )
                        },
                    )?;
                    Ok(Opened::AlreadyComplete)
                }
                found => Err(mismatch(
                    out,
                    format!(
                        "cannot resume: the file is complete but {}; run without --resume to replace it, or choose another --out",
                        if found.is_some() {
                            format!("was made by a different sweep, solver or shard (see {})", sidecar.display())
                        } else {
                            format!("its sidecar {} is missing or unreadable, so nothing says which sweep made it", sidecar.display())
                        }
                    ),
                )),
            };
        }
        write_atomic(&spec, format!("{fingerprint}\n0\n").as_bytes())?;
        let mut file = File::create(&partial)
            .with_context(|| format!("cannot create {}", partial.display()))?;
        file.write_all(header)
            .and_then(|_| file.sync_data())
            .with_context(|| format!("cannot write {}", partial.display()))?;
        Ok(Opened::Writing(Box::new(Partial {
            path: out.to_path_buf(),
            format,
            head_len: header.len() as u64,
            partial,
            spec,
            fingerprint: fingerprint.to_string(),
            file,
            rows_done: 0,
            dropped_bytes: 0,
            ok_done: 0,
            wall_before: 0.0,
            sections: vec![],
            keep: None,
            to_parquet: None,
        })))
    }

    /// Append complete rows (CSV) or a whole frame (Parquet) and push them
    /// to the file.
    pub fn append(&mut self, rows: &[u8]) -> Result<()> {
        crate::output::failpoint::check("append")
            .and_then(|_| self.file.write_all(rows))
            .and_then(|_| self.file.flush())
            .with_context(|| format!("cannot write {}", self.partial.display()))
    }

    /// Save the wall time of all runs so far (`wall` s), for the sidecar of
    /// a later resume.
    pub fn save_wall(&self, wall: f64) -> Result<()> {
        write_atomic(
            &self.spec,
            format!("{}\n{wall}\n", self.fingerprint).as_bytes(),
        )
    }

    /// All rows written (`rows` of them): write the sidecar (at `sidecar`,
    /// its text made by `text` from the final file's [`Seal`]), then make the
    /// table visible under its final name. The sidecar goes first: if the
    /// run dies before the final rename, the `.partial` is still there and
    /// `--resume` finishes it.
    pub fn finish(
        self,
        sidecar: &Path,
        rows: u64,
        text: impl FnOnce(Seal) -> Result<String>,
    ) -> Result<()> {
        self.file
            .sync_all()
            .with_context(|| format!("cannot write {}", self.partial.display()))?;
        drop(self.file);
        let done = match &self.format {
            TableFormat::Csv
                if self.sections.len() > 1 || self.keep.is_some() || self.to_parquet.is_some() =>
            {
                let tmp = with_suffix(&self.path, TMP);
                let r = rewrite(
                    &self.partial,
                    self.head_len,
                    &self.sections,
                    self.keep,
                    self.to_parquet.as_ref(),
                    &tmp,
                );
                if r.is_err() {
                    let _ = fs::remove_file(&tmp);
                }
                r?;
                tmp
            }
            TableFormat::Csv => self.partial.clone(),
            TableFormat::Parquet(schema) => {
                let tmp = with_suffix(&self.path, TMP);
                let r =
                    super::parquet_file::join_partial(&self.partial, self.head_len, &tmp, schema);
                if r.is_err() {
                    let _ = fs::remove_file(&tmp);
                }
                r?;
                tmp
            }
        };
        let text = text(super::sidecar::seal(&done, rows)?)?;
        crate::output::failpoint::check("sidecar")
            .with_context(|| format!("cannot write {}", sidecar.display()))?;
        write_atomic(sidecar, text.as_bytes())?;
        super::publish::publish(&done, &self.path)?;
        if done != self.partial {
            let _ = fs::remove_file(&self.partial);
        }
        let _ = fs::remove_file(&self.spec);
        Ok(())
    }
}

/// Length in bytes of the header plus every whole row, the row count and
/// how many of those rows have status `ok`. A row is whole when it ends in
/// a newline and reads as a row of this table ([`whole_row`]); the first
/// that does not ends the prefix, so a torn row followed by the zero-filled
/// block a power cut can leave (a "row" of NULs) is dropped with all after it.
fn complete_prefix(partial: &Path, header: &[u8]) -> Result<(u64, u64, u64)> {
    let mut r = BufReader::new(
        File::open(partial).with_context(|| format!("cannot read {}", partial.display()))?,
    );
    let mut line = Vec::new();
    r.read_until(b'\n', &mut line)?;
    if line != header {
        return Err(mismatch(
            partial,
            "cannot resume: its header differs from this sweep's; run without --resume to start over".into(),
        ));
    }
    let columns = fields(&line).map_or(0, |f| f.len());
    let status = String::from_utf8_lossy(&line)
        .trim_end()
        .split(',')
        .position(|c| c == "status");
    let mut keep = line.len() as u64;
    let (mut rows, mut ok) = (0, 0);
    loop {
        line.clear();
        let n = r.read_until(b'\n', &mut line)?;
        if n == 0 || line.last() != Some(&b'\n') {
            break;
        }
        let Some(row) = whole_row(&line, columns, status) else {
            break;
        };
        keep += n as u64;
        rows += 1;
        ok += row as u64;
    }
    Ok((keep, rows, ok))
}

/// The fields of one CSV line (with its newline), or `None` if it is not
/// one record of UTF-8 text.
fn fields(line: &[u8]) -> Option<csv::StringRecord> {
    let mut r = csv::ReaderBuilder::new()
        .has_headers(false)
        .from_reader(line);
    let rec = r.records().next()?.ok()?;
    r.records().next().is_none().then_some(rec)
}

/// `Some(is ok)` when `line` is a whole row of a table of `columns`
/// columns: no NUL byte, one record of that many fields, an integer id
/// first and a known status in the `status` column.
fn whole_row(line: &[u8], columns: usize, status: Option<usize>) -> Option<bool> {
    if line.contains(&0) {
        return None;
    }
    let rec = fields(line).filter(|r| r.len() == columns)?;
    rec.get(0)?.parse::<u64>().ok()?;
    match status {
        Some(i) => {
            use crate::choice::Choice;
            let s = crate::engine::Status::from_name(rec.get(i)?)?;
            Some(s == crate::engine::Status::Ok)
        }
        None => Some(false),
    }
}

/// Like [`complete_prefix`] for a Parquet partial file: the length of its
/// head and whole frames, their rows and `ok` rows.
fn complete_frames(partial: &Path, head: &[u8]) -> Result<(u64, u64, u64)> {
    let mut f =
        File::open(partial).with_context(|| format!("cannot read {}", partial.display()))?;
    let mut found = vec![0u8; head.len()];
    if std::io::Read::read_exact(&mut f, &mut found).is_err() || found != head {
        return Err(mismatch(
            partial,
            "cannot resume: its header differs from this sweep's; run without --resume to start over".into(),
        ));
    }
    let frames = super::parquet_file::frames(&mut f, head.len() as u64)?;
    let keep = frames
        .last()
        .map_or(head.len() as u64, |fr| fr.offset + fr.len);
    Ok((
        keep,
        frames.iter().map(|fr| fr.rows).sum(),
        frames.iter().map(|fr| fr.ok).sum(),
    ))
}

/// The finished file of a refined sweep at `out`: the rows of the
/// partial file's sections in id order (only `keep`'s), as CSV or as
/// Parquet (`to_parquet`).
fn rewrite(
    partial: &Path,
    head_len: u64,
    sections: &[u64],
    keep: Option<(u64, u64)>,
    to_parquet: Option<&(arrow_schema::SchemaRef, Vec<super::row::ColType>)>,
    out: &Path,
) -> Result<()> {
    let ctx = || format!("cannot write {}", out.display());
    let mut w = std::io::BufWriter::new(File::create(out).with_context(ctx)?);
    let keep = keep.unwrap_or((0, u64::MAX));
    match to_parquet {
        None => {
            let mut head = vec![0u8; head_len as usize];
            std::io::Read::read_exact(&mut File::open(partial)?, &mut head)?;
            w.write_all(&head).with_context(ctx)?;
            interleave(partial, head_len, sections, &mut |id, line| {
                if (keep.0..keep.1).contains(&id) {
                    w.write_all(line).with_context(ctx)?;
                }
                Ok(())
            })?;
            w.flush().with_context(ctx)?;
            w.get_ref().sync_all().with_context(ctx)?;
        }
        Some((schema, types)) => {
            use super::parquet_file::{Columns, SEGMENT_ROWS};
            let mut writer = parquet::arrow::ArrowWriter::try_new(
                w,
                schema.clone(),
                Some(super::parquet_file::properties()),
            )?;
            let mut cols = Columns::new(schema, types, SEGMENT_ROWS as usize);
            let mut n = 0u64;
            interleave(partial, head_len, sections, &mut |id, line| {
                if !(keep.0..keep.1).contains(&id) {
                    return Ok(());
                }
                let mut r = csv::ReaderBuilder::new()
                    .has_headers(false)
                    .from_reader(line);
                let rec = r
                    .records()
                    .next()
                    .transpose()?
                    .with_context(|| format!("an empty row in {}", partial.display()))?;
                for (f, t) in rec.iter().zip(types) {
                    cols.push(super::row::Field::parse(f, *t));
                }
                n += 1;
                if n.is_multiple_of(SEGMENT_ROWS) {
                    let full = std::mem::replace(
                        &mut cols,
                        Columns::new(schema, types, SEGMENT_ROWS as usize),
                    );
                    writer.write(&full.finish()?)?;
                }
                Ok(())
            })?;
            writer.write(&cols.finish()?)?;
            let w = writer.into_inner()?;
            w.into_inner()
                .map_err(|e| e.into_error())
                .with_context(ctx)?
                .sync_all()
                .with_context(ctx)?;
        }
    }
    Ok(())
}

/// The rows of `partial`'s `sections` (consecutive runs of rows after its
/// first `head_len` bytes, each in id order) to `sink` with their ids, the
/// rows of all sections in id order.
fn interleave(
    partial: &Path,
    head_len: u64,
    sections: &[u64],
    sink: &mut dyn FnMut(u64, &[u8]) -> Result<()>,
) -> Result<()> {
    let open = || File::open(partial).with_context(|| format!("cannot read {}", partial.display()));
    // One reader per section, at its first row.
    let mut readers = vec![];
    let mut r = BufReader::new(open()?);
    r.seek(SeekFrom::Start(head_len))?;
    let mut line = Vec::new();
    for &n in sections {
        let at = r.stream_position()?;
        let mut section = BufReader::new(open()?);
        section.seek(SeekFrom::Start(at))?;
        readers.push((section, n));
        for _ in 0..n {
            line.clear();
            r.read_until(b'\n', &mut line)?;
        }
    }
    let id_of = |l: &[u8]| super::row::line_id(l).unwrap_or(u64::MAX);
    // The next row of each section, merged by id.
    let mut heads: Vec<Option<Vec<u8>>> = vec![None; readers.len()];
    let mut advance = |k: usize, heads: &mut Vec<Option<Vec<u8>>>| -> Result<()> {
        let (rd, left) = &mut readers[k];
        heads[k] = if *left == 0 {
            None
        } else {
            *left -= 1;
            let mut l = Vec::new();
            rd.read_until(b'\n', &mut l)?;
            Some(l)
        };
        Ok(())
    };
    for k in 0..heads.len() {
        advance(k, &mut heads)?;
    }
    while let Some(k) = (0..heads.len())
        .filter(|&k| heads[k].is_some())
        .min_by_key(|&k| id_of(heads[k].as_deref().unwrap_or_default()))
    {
        let line = heads[k].take().unwrap_or_default();
        sink(id_of(&line), &line)?;
        advance(k, &mut heads)?;
    }
    Ok(())
}
