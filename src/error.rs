//! Typed errors for everything a person types: scene and sweep files, flags.
//! Every message names the file (and line where TOML gives one), the key, the
//! value and the allowed range. The CLI maps these to exit code 2.

use std::path::PathBuf;

/// An error in user input. Runtime failures (a GPU lost, a disk full) are not
/// `InputError`s; they travel as `anyhow` errors and exit with code 1.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    #[error("cannot read {}: {error}", path.display())]
    Read {
        path: PathBuf,
        /// Not a `#[source]`: the message already says it, once.
        error: std::io::Error,
    },
    #[error("{origin}:{line}:{col}: {message}")]
    Syntax {
        origin: String,
        line: usize,
        col: usize,
        message: String,
    },
    #[error(
        "{}: unknown key `{key}`{} (allowed: {allowed})",
        loc(origin, line),
        suggest(suggestion)
    )]
    UnknownKey {
        origin: String,
        line: Option<usize>,
        key: String,
        suggestion: Option<String>,
        allowed: String,
    },
    #[error("{}: `{key}` = {value}: {allowed}", loc(origin, line))]
    Invalid {
        origin: String,
        line: Option<usize>,
        key: String,
        value: String,
        allowed: String,
    },
    #[error("{}: missing key `{key}`: {help}", loc(origin, line))]
    Missing {
        origin: String,
        line: Option<usize>,
        key: String,
        help: String,
    },
    #[error("{}: `{key}`: {what}", loc(origin, line))]
    Unsupported {
        origin: String,
        line: Option<usize>,
        key: String,
        what: String,
    },
    #[error("{}: {what}", path.display())]
    Data { path: PathBuf, what: String },
    #[error(
        "{} is being written by another cradle ({holder}); wait for it to end or stop it, or choose another --out (lock: {})",
        path.display(),
        lock.display()
    )]
    Busy {
        path: PathBuf,
        holder: String,
        lock: PathBuf,
    },
    #[error("{flag} {value}: {allowed}")]
    Flag {
        flag: String,
        value: String,
        allowed: String,
    },
}

/// A bad flag value: `FLAG VALUE: allowed`.
pub fn flag(flag: &str, value: &str, allowed: &str) -> InputError {
    InputError::Flag {
        flag: flag.into(),
        value: value.into(),
        allowed: allowed.into(),
    }
}

fn loc(origin: &str, line: &Option<usize>) -> String {
    match line {
        Some(l) => format!("{origin}:{l}"),
        None => origin.to_string(),
    }
}

fn suggest(s: &Option<String>) -> String {
    match s {
        Some(s) => format!(" — did you mean `{s}`?"),
        None => String::new(),
    }
}

/// The closest of `allowed` to `key`, if it is close enough to be a typo.
pub fn closest<'a>(key: &str, allowed: impl IntoIterator<Item = &'a str>) -> Option<String> {
    allowed
        .into_iter()
        .map(|a| (strsim::normalized_damerau_levenshtein(key, a), a))
        .filter(|(score, _)| *score >= 0.5)
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, a)| a.to_string())
}

/// Text of a TOML document and the name to report it by (a path, or
/// `built-in scene NAME`). Turns byte offsets into line numbers.
#[derive(Clone, Debug)]
pub struct Source {
    pub name: String,
    pub text: String,
}

impl Source {
    pub fn new(name: impl Into<String>, text: impl Into<String>) -> Self {
        Source {
            name: name.into(),
            text: text.into(),
        }
    }

    /// A TOML input (a scene or a sweep file), through [`open_input`].
    pub fn read(path: &std::path::Path) -> Result<Self, InputError> {
        use std::io::Read;
        let read_err = |error| InputError::Read {
            path: path.to_path_buf(),
            error,
        };
        let mut text = String::new();
        open_input(path, MAX_TOML_BYTES)?
            .take(MAX_TOML_BYTES + 1)
            .read_to_string(&mut text)
            .map_err(read_err)?;
        if text.len() as u64 > MAX_TOML_BYTES {
            return Err(too_large(path, MAX_TOML_BYTES));
        }
        Ok(Source::new(path.display().to_string(), text))
    }

    /// 1-based (line, column) of a byte offset.
    pub fn line_col(&self, offset: usize) -> (usize, usize) {
        let offset = offset.min(self.text.len());
        let before = &self.text.as_bytes()[..offset];
        let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
        let col = offset
            - before
                .iter()
                .rposition(|&b| b == b'\n')
                .map_or(0, |p| p + 1)
            + 1;
        (line, col)
    }

    pub fn line(&self, offset: usize) -> usize {
        self.line_col(offset).0
    }

    /// A value this document gives (at `line`) that is not allowed.
    pub fn invalid(
        &self,
        line: Option<usize>,
        key: &str,
        value: String,
        allowed: String,
    ) -> InputError {
        InputError::Invalid {
            origin: self.name.clone(),
            line,
            key: key.to_string(),
            value,
            allowed,
        }
    }

    /// A key this document leaves out (in the table at `line`, if any).
    pub fn missing(&self, line: Option<usize>, key: &str, help: impl Into<String>) -> InputError {
        InputError::Missing {
            origin: self.name.clone(),
            line,
            key: key.to_string(),
            help: help.into(),
        }
    }

    /// Parse `self.text` into `T`, turning serde's "unknown field" into an
    /// [`InputError::UnknownKey`] with a suggestion, and other failures into
    /// [`InputError::Syntax`] with line and column.
    pub fn parse_toml<T: serde::de::DeserializeOwned>(&self) -> Result<T, InputError> {
        toml::from_str(&self.text).map_err(|e| self.toml_error(&e))
    }

    fn toml_error(&self, e: &toml::de::Error) -> InputError {
        let (line, col) = e.span().map_or((1, 1), |s| self.line_col(s.start));
        let msg = e.message();
        if let Some(rest) = msg.strip_prefix("unknown field ") {
            // serde: "unknown field `x`, expected one of `a`, `b`" / "expected `a` or `b`"
            let names: Vec<&str> = rest.split('`').skip(1).step_by(2).collect();
            if let Some((key, allowed)) = names.split_first() {
                return InputError::UnknownKey {
                    origin: self.name.clone(),
                    line: Some(line),
                    key: key.to_string(),
                    suggestion: closest(key, allowed.iter().copied()),
                    allowed: allowed.join(", "),
                };
            }
        }
        // Name the key of the offending line, when the line is `key = value`.
        let key = e
            .span()
            .and_then(|_| self.text.lines().nth(line - 1))
            .and_then(|l| {
                let (k, _) = l.split_once('=')?;
                let k = k.trim();
                (!k.is_empty() && !k.starts_with('[') && !k.starts_with('#')).then(|| k.to_string())
            });
        InputError::Syntax {
            origin: self.name.clone(),
            line,
            col,
            message: match key {
                Some(k) => format!("`{k}`: {}", msg.trim()),
                None => msg.trim().to_string(),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_col_counts_from_one() {
        let s = Source::new("f", "a = 1\nbb = 2\n");
        assert_eq!(s.line_col(0), (1, 1));
        assert_eq!(s.line_col(6), (2, 1));
        assert_eq!(s.line_col(8), (2, 3));
    }

    #[test]
    fn closest_finds_typos_only() {
        let keys = ["radius", "density", "mass"];
        assert_eq!(closest("radus", keys).as_deref(), Some("radius"));
        assert_eq!(closest("zzzzzzzz", keys), None);
    }
}

/// A run stopped on request (Ctrl-C in Python): the rows so far are kept in
/// the partial file, which `--resume` continues.
#[derive(Debug, thiserror::Error)]
#[error("interrupted")]
pub struct Interrupted;

/// Most bytes of a TOML input (a scene or sweep file, a sidecar).
pub const MAX_TOML_BYTES: u64 = 64 << 20;
/// Most bytes of a table or point list read as an input.
pub const MAX_TABLE_BYTES: u64 = 256 << 30;

fn too_large(path: &std::path::Path, cap: u64) -> InputError {
    InputError::Data {
        path: path.to_path_buf(),
        what: format!(
            "larger than the {} MB this kind of input may have",
            cap >> 20
        ),
    }
}

/// The one way an input file is opened: a regular file of at most `cap`
/// bytes. A FIFO, a device, a socket or a directory is refused before it
/// is opened (opening a FIFO blocks until a writer comes; a device such as
/// /dev/zero never ends), naming the path and what it is.
pub fn open_input(path: &std::path::Path, cap: u64) -> Result<std::fs::File, InputError> {
    let read_err = |error| InputError::Read {
        path: path.to_path_buf(),
        error,
    };
    let meta = std::fs::metadata(path).map_err(read_err)?;
    if !meta.is_file() {
        return Err(InputError::Data {
            path: path.to_path_buf(),
            what: format!(
                "{}, not a regular file: inputs are read from files",
                file_kind(&meta.file_type())
            ),
        });
    }
    if meta.len() > cap {
        return Err(too_large(path, cap));
    }
    std::fs::File::open(path).map_err(read_err)
}

/// Whether `path` is a regular file (following links), without opening it.
pub fn is_regular_file(path: &std::path::Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.is_file())
}

fn file_kind(t: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_dir() {
        "a directory"
    } else {
        "not a file"
    }
}
