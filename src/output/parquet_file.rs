//! Parquet output: the CSV's columns and values, typed (docs/SPEC.md §7).
//!
//! Rows become Arrow record batches ([`Columns`]); the writer encodes them
//! into *segments* of [`SEGMENT_ROWS`] rows, each a complete one-row-group
//! Parquet file in memory, and appends each to `FILE.partial` as a frame
//! (`output::partial`). A frame is whole or it is cut off at the end by a
//! kill: `--resume` keeps the whole ones and continues at the next segment
//! boundary, so segment boundaries (and the file's bytes) are the same
//! whether or not a run was interrupted. When every row is in, the row groups
//! are copied, still encoded, into `FILE` (no decoding: a byte copy of each
//! column chunk, as `parquet-concat` does).
//!
//! Types: `id`, `steps`, `contacts`, `ejected` and integer axes (`balls`,
//! `launch.balls`) are Int64; `status` a dictionary-encoded string; `glue`
//! a string; every other column Float64. A cell the CSV leaves empty is
//! null. Floats are the very values the CSV's text stands for (its text is
//! their shortest round-trip form), so the two files hold the same numbers
//! bit for bit.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, Result};
use arrow_array::builder::{Float64Builder, Int64Builder, StringBuilder, StringDictionaryBuilder};
use arrow_array::types::Int32Type;
use arrow_array::{ArrayRef, RecordBatch};
use arrow_schema::{DataType, Field as ArrowField, Schema, SchemaRef};
use bytes::Bytes;
use parquet::arrow::{add_encoded_arrow_schema_to_metadata, ArrowSchemaConverter, ArrowWriter};
use parquet::basic::Compression;
use parquet::column::writer::ColumnCloseResult;
use parquet::file::metadata::{ParquetMetaData, ParquetMetaDataReader};
use parquet::file::properties::{EnabledStatistics, WriterProperties};
use parquet::file::writer::SerializedFileWriter;

use super::row::{ColType, Field};

/// Rows of one segment (one row group of the final file). A power of two,
/// so that every pipeline batch (a power of two ≤ this) lies in one segment.
pub const SEGMENT_ROWS: u64 = 65_536;

/// The Arrow schema of a table with `header` columns of `types`.
pub fn schema(header: &[String], types: &[ColType]) -> SchemaRef {
    let fields: Vec<ArrowField> = header
        .iter()
        .zip(types)
        .enumerate()
        .map(|(k, (name, t))| {
            let dt = match t {
                ColType::Int => DataType::Int64,
                ColType::Num => DataType::Float64,
                ColType::Text => DataType::Utf8,
                ColType::Status => {
                    DataType::Dictionary(Box::new(DataType::Int32), Box::new(DataType::Utf8))
                }
            };
            // `id` and `status` are never missing.
            let nullable = !(k == 0 || *t == ColType::Status);
            ArrowField::new(name, dt, nullable)
        })
        .collect();
    Arc::new(Schema::new(fields))
}

/// The writer settings of every segment (and of the final file).
pub fn properties() -> WriterProperties {
    WriterProperties::builder()
        .set_compression(Compression::SNAPPY)
        .set_max_row_group_row_count(Some(SEGMENT_ROWS as usize))
        // Min/max per column chunk (copied with the chunk when segments are joined).
        .set_statistics_enabled(EnabledStatistics::Chunk)
        .build()
}

enum Builder {
    Int(Int64Builder),
    Num(Float64Builder),
    Text(StringBuilder),
    Status(StringDictionaryBuilder<Int32Type>),
}

/// Rows collected column by column: push every field of a row in order
/// ([`super::row::emit_fields`]), then [`Columns::finish`].
pub struct Columns {
    schema: SchemaRef,
    cols: Vec<Builder>,
    next: usize,
}

impl Columns {
    pub fn new(schema: &SchemaRef, types: &[ColType], rows: usize) -> Columns {
        let cols = types
            .iter()
            .map(|t| match t {
                ColType::Int => Builder::Int(Int64Builder::with_capacity(rows)),
                ColType::Num => Builder::Num(Float64Builder::with_capacity(rows)),
                ColType::Text => Builder::Text(StringBuilder::with_capacity(rows, 8 * rows)),
                ColType::Status => Builder::Status(StringDictionaryBuilder::new()),
            })
            .collect();
        Columns {
            schema: schema.clone(),
            cols,
            next: 0,
        }
    }

    /// The next field of the current row.
    pub fn push(&mut self, f: Field) {
        let n = self.cols.len();
        match (&mut self.cols[self.next], f) {
            (Builder::Int(b), Field::Int(x)) => b.append_value(x as i64),
            // An integer axis: its values are whole numbers (checked when the
            // sweep is read).
            (Builder::Int(b), Field::Num(x)) if x.is_finite() => b.append_value(x as i64),
            (Builder::Int(b), _) => b.append_null(),
            (Builder::Num(b), Field::Num(x)) if !x.is_nan() => b.append_value(x),
            (Builder::Num(b), Field::Int(x)) => b.append_value(x as f64),
            (Builder::Num(b), _) => b.append_null(),
            (Builder::Text(b), Field::Text(t)) => b.append_value(t),
            (Builder::Text(b), Field::Null) => b.append_null(),
            (Builder::Text(b), other) => {
                let mut s = String::new();
                match other {
                    Field::Num(x) => super::row::num_into(x, &mut s),
                    Field::Int(x) => s = x.to_string(),
                    _ => {}
                }
                b.append_value(s)
            }
            (Builder::Status(b), Field::Text(t)) => {
                b.append_value(t);
            }
            (Builder::Status(b), _) => b.append_null(),
        }
        self.next = (self.next + 1) % n;
    }

    pub fn finish(self) -> Result<RecordBatch> {
        let arrays: Vec<ArrayRef> = self
            .cols
            .into_iter()
            .map(|b| -> ArrayRef {
                match b {
                    Builder::Int(mut b) => Arc::new(b.finish()),
                    Builder::Num(mut b) => Arc::new(b.finish()),
                    Builder::Text(mut b) => Arc::new(b.finish()),
                    Builder::Status(mut b) => Arc::new(b.finish()),
                }
            })
            .collect();
        Ok(RecordBatch::try_new(self.schema, arrays)?)
    }
}

/// Bytes of a frame header: segment length, its rows, its `ok` rows (u64 LE).
pub const FRAME_HEADER: usize = 24;

/// The segment being filled: record batches encoded as they come.
pub struct Segment {
    schema: SchemaRef,
    writer: Option<ArrowWriter<Vec<u8>>>,
    rows: u64,
    ok: u64,
}

impl Segment {
    pub fn new(schema: SchemaRef) -> Segment {
        Segment {
            schema,
            writer: None,
            rows: 0,
            ok: 0,
        }
    }

    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Add `batch` (of which `ok` rows have status ok).
    pub fn write(&mut self, batch: &RecordBatch, ok: u64) -> Result<()> {
        if self.writer.is_none() {
            self.writer = Some(ArrowWriter::try_new(
                Vec::with_capacity(1 << 20),
                self.schema.clone(),
                Some(properties()),
            )?);
        }
        self.writer.as_mut().expect("created above").write(batch)?;
        self.rows += batch.num_rows() as u64;
        self.ok += ok;
        Ok(())
    }

    /// Close the segment: its frame (header and Parquet bytes), or `None`
    /// when it holds no rows. The segment is empty again afterwards.
    pub fn take_frame(&mut self) -> Result<Option<Vec<u8>>> {
        let Some(w) = self.writer.take() else {
            return Ok(None);
        };
        let body = w.into_inner()?;
        let mut frame = Vec::with_capacity(FRAME_HEADER + body.len());
        for x in [body.len() as u64, self.rows, self.ok] {
            frame.extend_from_slice(&x.to_le_bytes());
        }
        frame.extend_from_slice(&body);
        self.rows = 0;
        self.ok = 0;
        Ok(Some(frame))
    }
}

/// One whole frame found in a partial file: where its segment lies, its rows
/// and `ok` rows.
pub struct Frame {
    pub offset: u64,
    pub len: u64,
    pub rows: u64,
    pub ok: u64,
}

/// The whole frames of `file` after its first `start` bytes (a frame cut off
/// by a kill, and anything after it, is left out).
pub fn frames(file: &mut File, start: u64) -> Result<Vec<Frame>> {
    let size = file.seek(SeekFrom::End(0))?;
    let mut at = start;
    let mut found = vec![];
    let mut head = [0u8; FRAME_HEADER];
    while at + FRAME_HEADER as u64 <= size {
        file.seek(SeekFrom::Start(at))?;
        file.read_exact(&mut head)?;
        let word = |k: usize| u64::from_le_bytes(head[8 * k..8 * k + 8].try_into().unwrap());
        let (len, rows, ok) = (word(0), word(1), word(2));
        let offset = at + FRAME_HEADER as u64;
        if len < 12 || offset.checked_add(len).is_none_or(|end| end > size) {
            break;
        }
        // A whole segment starts and ends with Parquet's magic.
        let mut magic = [0u8; 4];
        file.seek(SeekFrom::Start(offset + len - 4))?;
        file.read_exact(&mut magic)?;
        if &magic != b"PAR1" {
            break;
        }
        found.push(Frame {
            offset,
            len,
            rows,
            ok,
        });
        at = offset + len;
    }
    Ok(found)
}

/// A segment's bytes and metadata.
fn read_segment(file: &mut File, f: &Frame) -> Result<(Bytes, ParquetMetaData)> {
    let mut buf = vec![0u8; f.len as usize];
    file.seek(SeekFrom::Start(f.offset))?;
    file.read_exact(&mut buf)?;
    let bytes = Bytes::from(buf);
    let meta = ParquetMetaDataReader::new().parse_and_finish(&bytes)?;
    Ok((bytes, meta))
}

/// Copies row groups, still encoded, into one Parquet file of `schema`.
pub struct Joiner<W: Write + Send> {
    writer: SerializedFileWriter<W>,
}

impl<W: Write + Send> Joiner<W> {
    pub fn new(out: W, schema: &Schema) -> Result<Joiner<W>> {
        let mut props = properties();
        add_encoded_arrow_schema_to_metadata(schema, &mut props);
        let descr = ArrowSchemaConverter::new().convert(schema)?;
        Ok(Joiner {
            writer: SerializedFileWriter::new(out, descr.root_schema_ptr(), Arc::new(props))?,
        })
    }

    /// Append every row group of the Parquet file `src` (metadata `meta`).
    pub fn append<R: parquet::file::reader::ChunkReader>(
        &mut self,
        src: &R,
        meta: &ParquetMetaData,
    ) -> Result<()> {
        for rg in meta.row_groups() {
            let mut out = self.writer.next_row_group()?;
            for column in rg.columns() {
                out.append_column(
                    src,
                    ColumnCloseResult {
                        bytes_written: column.compressed_size() as u64,
                        rows_written: rg.num_rows() as u64,
                        metadata: column.clone(),
                        bloom_filter: None,
                        column_index: None,
                        offset_index: None,
                    },
                )?;
            }
            out.close()?;
        }
        Ok(())
    }

    pub fn finish(self) -> Result<W> {
        Ok(self.writer.into_inner()?)
    }
}

/// Write the segments of the frames of `partial` (past its first `start`
/// bytes) as one Parquet file `out` of `schema`, synced.
pub fn join_partial(partial: &Path, start: u64, out: &Path, schema: &Schema) -> Result<()> {
    let mut src =
        File::open(partial).with_context(|| format!("cannot read {}", partial.display()))?;
    let dst = File::create(out).with_context(|| format!("cannot create {}", out.display()))?;
    let wrote = || format!("cannot write {}", out.display());
    let mut j = Joiner::new(std::io::BufWriter::new(dst), schema).with_context(wrote)?;
    for f in frames(&mut src, start)? {
        let (bytes, meta) = read_segment(&mut src, &f)
            .with_context(|| format!("cannot read {}", partial.display()))?;
        j.append(&bytes, &meta).with_context(wrote)?;
    }
    let w = j.finish().with_context(wrote)?;
    let file = w
        .into_inner()
        .map_err(|e| e.into_error())
        .with_context(|| format!("cannot write {}", out.display()))?;
    file.sync_all()
        .with_context(|| format!("cannot write {}", out.display()))?;
    Ok(())
}

/// Whether `path` is a Parquet file (its first bytes are Parquet's magic).
pub fn is_parquet(path: &Path) -> bool {
    let mut magic = [0u8; 4];
    // Never open a FIFO or a device to look (it could block or never end).
    crate::error::is_regular_file(path)
        && File::open(path)
            .and_then(|mut f| f.read_exact(&mut magic))
            .is_ok()
        && &magic == b"PAR1"
}

/// A Parquet table as the CSV's text: its column names and, per row, each
/// cell as the CSV would print it (null → empty). For readers of tables
/// (`cradle plot`) that take either format.
pub fn read_text(path: &Path) -> Result<(Vec<String>, Vec<Vec<String>>)> {
    use arrow_array::cast::AsArray;
    use arrow_array::types::{Float64Type, Int64Type};
    use arrow_array::Array;
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

    let file = crate::error::open_input(path, crate::error::MAX_TABLE_BYTES)?;
    let builder = ParquetRecordBatchReaderBuilder::try_new(file)?;
    let header: Vec<String> = builder
        .schema()
        .fields()
        .iter()
        .map(|f| f.name().clone())
        .collect();
    let reader = builder.build()?;
    let mut rows: Vec<Vec<String>> = vec![];
    let mut s = String::new();
    for batch in reader {
        let batch = batch?;
        let start = rows.len();
        rows.extend((0..batch.num_rows()).map(|_| Vec::with_capacity(header.len())));
        for col in batch.columns() {
            let col = match col.data_type() {
                DataType::Dictionary(_, _) => arrow_cast_dictionary(col)?,
                _ => col.clone(),
            };
            for (r, row) in rows[start..].iter_mut().enumerate() {
                if col.is_null(r) {
                    row.push(String::new());
                    continue;
                }
                row.push(match col.data_type() {
                    DataType::Int64 => col.as_primitive::<Int64Type>().value(r).to_string(),
                    DataType::Float64 => {
                        super::row::num_into(col.as_primitive::<Float64Type>().value(r), &mut s);
                        s.clone()
                    }
                    DataType::Utf8 => col.as_string::<i32>().value(r).to_string(),
                    other => anyhow::bail!(
                        "{}: column of type {other}, not one a cradle table has",
                        path.display()
                    ),
                });
            }
        }
    }
    Ok((header, rows))
}

/// A dictionary-encoded string column as a plain one.
fn arrow_cast_dictionary(col: &ArrayRef) -> Result<ArrayRef> {
    use arrow_array::cast::AsArray;
    let d = col
        .as_dictionary_opt::<Int32Type>()
        .context("a dictionary column with keys other than Int32")?;
    let values = d.values().as_string::<i32>();
    let mut b = StringBuilder::new();
    for k in d.keys() {
        match k {
            Some(k) => b.append_value(values.value(k as usize)),
            None => b.append_null(),
        }
    }
    Ok(Arc::new(b.finish()))
}

/// One part of a Parquet merge: a file and the ids it must hold.
pub struct PartFile<'a> {
    pub path: &'a Path,
    pub ids: (u64, u64),
    /// A shard of a refined sweep: some of its ids, ascending.
    pub sparse: bool,
}

/// Join Parquet `parts` (in id order) into `out`, their row groups copied
/// still encoded. Every part must have the first's schema and hold exactly
/// its ids, in order (only the `id` column is decoded to check). Returns the
/// number of rows; `bad` makes the error for a part.
pub fn merge(
    parts: &[PartFile],
    out: &Path,
    bad: &dyn Fn(&Path, String) -> anyhow::Error,
) -> Result<u64> {
    use arrow_array::cast::AsArray;
    use arrow_array::types::Int64Type;
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

    let dst = File::create(out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut joiner: Option<(Joiner<std::io::BufWriter<File>>, SchemaRef)> = None;
    let mut n = 0u64;
    for p in parts {
        let open =
            || File::open(p.path).with_context(|| format!("cannot read {}", p.path.display()));
        let builder = ParquetRecordBatchReaderBuilder::try_new(open()?)
            .map_err(|e| bad(p.path, format!("not a readable Parquet table ({e})")))?;
        let schema = builder.schema().clone();
        let (j, first_schema) = match &mut joiner {
            Some(j) => j,
            None => {
                let j = Joiner::new(std::io::BufWriter::new(dst.try_clone()?), &schema)
                    .with_context(|| format!("cannot write {}", out.display()))?;
                joiner.insert((j, schema.clone()))
            }
        };
        if schema.fields() != first_schema.fields() {
            return Err(bad(
                p.path,
                format!("its columns differ from {}'s", parts[0].path.display()),
            ));
        }
        let meta = builder.metadata().clone();
        let id_col = schema
            .index_of("id")
            .map_err(|_| bad(p.path, "no `id` column".into()))?;
        // Every column decoded (a damaged page fails here, naming the part,
        // not after its row groups were copied); the ids checked.
        let mut next = p.ids.0;
        let undecodable = |e: &dyn std::fmt::Display| {
            bad(
                p.path,
                format!("cannot be decoded ({e}): the file is damaged; run the shard again"),
            )
        };
        for b in builder.build().map_err(|e| undecodable(&e))? {
            let b = b.map_err(|e| undecodable(&e))?;
            let ids = b.column(id_col).as_primitive::<Int64Type>();
            for id in ids.iter() {
                let id = id.unwrap_or(-1);
                if p.sparse && id >= 0 && id as u64 >= next && (id as u64) < p.ids.1 {
                    next = id as u64;
                }
                if id as u64 != next || id < 0 || id as u64 >= p.ids.1 {
                    return Err(bad(
                        p.path,
                        format!(
                            "row with id {id} where its sidecar's range {} .. {} expects {next}: the file was changed after it was written; run the shard again",
                            p.ids.0, p.ids.1
                        ),
                    ));
                }
                next += 1;
            }
        }
        if next != p.ids.1 && !p.sparse {
            return Err(bad(
                p.path,
                format!(
                    "holds ids {} .. {next} but its sidecar says {} .. {}: the file was cut short after it was written; run the shard again",
                    p.ids.0, p.ids.0, p.ids.1
                ),
            ));
        }
        j.append(&open()?, &meta).with_context(|| {
            format!(
                "cannot write {} (copying {})",
                out.display(),
                p.path.display()
            )
        })?;
        n += meta.file_metadata().num_rows() as u64;
    }
    let Some((j, _)) = joiner else {
        anyhow::bail!("nothing to merge");
    };
    let file = j
        .finish()
        .with_context(|| format!("cannot write {}", out.display()))?
        .into_inner()
        .map_err(|e| e.into_error())
        .with_context(|| format!("cannot write {}", out.display()))?;
    file.sync_all()
        .with_context(|| format!("cannot write {}", out.display()))?;
    Ok(n)
}

/// A trace in Parquet (`--trace FILE.parquet`): the trace writers' CSV
/// text, taken line by line as it is written, as Float64 columns of the
/// same names and the very values (the text is each number's shortest
/// round-trip form). Row groups of about 64 MB, snappy-compressed: a
/// 1,000-bead trace is a fraction of its CSV. [`TraceParquet::close`]
/// ends the file.
pub struct TraceParquet<W: Write + Send> {
    out: Option<W>,
    writer: Option<ArrowWriter<W>>,
    schema: Option<SchemaRef>,
    cols: Vec<Float64Builder>,
    /// Bytes of a line not yet ended.
    line: Vec<u8>,
    /// Rows built and not yet written.
    rows: usize,
}

/// Rows of a trace gathered before they go to the writer as one batch.
const TRACE_BATCH_ROWS: usize = 4096;

impl<W: Write + Send> TraceParquet<W> {
    pub fn new(out: W) -> TraceParquet<W> {
        TraceParquet {
            out: Some(out),
            writer: None,
            schema: None,
            cols: vec![],
            line: vec![],
            rows: 0,
        }
    }

    fn bad(what: String) -> std::io::Error {
        std::io::Error::new(std::io::ErrorKind::InvalidData, what)
    }

    fn take_line(&mut self, line: &str) -> std::io::Result<()> {
        let Some(schema) = &self.schema else {
            let fields: Vec<ArrowField> = line
                .split(',')
                .map(|name| ArrowField::new(name, DataType::Float64, false))
                .collect();
            let n = fields.len();
            let schema: SchemaRef = Arc::new(Schema::new(fields));
            // A row group of about 64 MB whatever the width.
            let group = (64usize << 20) / (8 * n).max(1);
            let props = WriterProperties::builder()
                .set_compression(Compression::SNAPPY)
                .set_max_row_group_row_count(Some(group.max(1)))
                .build();
            let out = self.out.take().expect("the header comes first");
            self.writer = Some(
                ArrowWriter::try_new(out, schema.clone(), Some(props))
                    .map_err(|e| Self::bad(e.to_string()))?,
            );
            self.cols = (0..n).map(|_| Float64Builder::new()).collect();
            self.schema = Some(schema);
            return Ok(());
        };
        let mut k = 0;
        for cell in line.split(',') {
            let v: f64 = cell
                .parse()
                .map_err(|_| Self::bad(format!("a trace cell `{cell}` is not a number")))?;
            self.cols
                .get_mut(k)
                .ok_or_else(|| Self::bad("a trace row longer than its header".into()))?
                .append_value(v);
            k += 1;
        }
        if k != schema.fields().len() {
            return Err(Self::bad("a trace row shorter than its header".into()));
        }
        self.rows += 1;
        if self.rows == TRACE_BATCH_ROWS {
            self.write_batch()?;
        }
        Ok(())
    }

    fn write_batch(&mut self) -> std::io::Result<()> {
        let (Some(schema), Some(w)) = (&self.schema, &mut self.writer) else {
            return Ok(());
        };
        if self.rows == 0 {
            return Ok(());
        }
        let arrays: Vec<ArrayRef> = self
            .cols
            .iter_mut()
            .map(|c| Arc::new(c.finish()) as ArrayRef)
            .collect();
        let batch =
            RecordBatch::try_new(schema.clone(), arrays).map_err(|e| Self::bad(e.to_string()))?;
        w.write(&batch).map_err(std::io::Error::other)?;
        self.rows = 0;
        Ok(())
    }

    /// Write the last rows and the footer; the underlying writer back.
    pub fn close(mut self) -> std::io::Result<W> {
        if !self.line.is_empty() {
            return Err(Self::bad("a trace that ends inside a row".into()));
        }
        self.write_batch()?;
        match self.writer.take() {
            Some(w) => w.into_inner().map_err(std::io::Error::other),
            None => Err(Self::bad("a trace with no header".into())),
        }
    }
}

impl<W: Write + Send> Write for TraceParquet<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let mut rest = buf;
        while let Some(i) = rest.iter().position(|&b| b == b'\n') {
            self.line.extend_from_slice(&rest[..i]);
            let line = std::mem::take(&mut self.line);
            let text = std::str::from_utf8(&line).map_err(|e| Self::bad(e.to_string()))?;
            self.take_line(text)?;
            rest = &rest[i + 1..];
        }
        self.line.extend_from_slice(rest);
        Ok(buf.len())
    }

    /// Rows reach the file batch by batch ([`TraceParquet::close`] ends it).
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}
