//! File input for the offline commands (`sagnac allan`, `sagnac analyze`):
//! text (one number per line), CSV (one named column) and raw little-endian
//! `f64`, each optionally gzip-compressed.
//!
//! Role in the whole: the one place where recorded sample files become `f64`
//! samples. [`SampleReader`] streams fixed-size blocks so that the streaming
//! Allan engine and the wavelet bank can process files far larger than memory
//! (a 100 M-sample `f64le` file is read with a 1 MiB buffer); [`read_all`]
//! loads a whole file for the batch engine.
//!
//! Every error names the file and the 1-based line (or, for `f64le`, the byte
//! offset): empty input, a non-numeric line (quoted, truncated), NaN or
//! infinite values, a missing CSV column (listing the available ones), a
//! binary length that is not a multiple of 8.

use std::fmt;
use std::fs::File;
use std::io::{self, BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

use flate2::read::MultiGzDecoder;

use super::detect::Format;

/// Read buffer size for all formats.
const BUF_BYTES: usize = 1 << 20;
/// Longest quoted excerpt of an offending line.
const QUOTE_MAX: usize = 40;

/// Where in a file something happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Location {
    /// 1-based line number (text, CSV).
    Line(u64),
    /// Byte offset of the value (f64le; offset in the decompressed stream for .gz).
    Byte(u64),
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Location::Line(l) => write!(f, "line {l}"),
            Location::Byte(b) => write!(f, "byte offset {b}"),
        }
    }
}

/// Input errors; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum PlainError {
    #[error("{}: cannot open", path.display())]
    Open { path: PathBuf, source: io::Error },
    #[error("{}: read error at {at}", path.display())]
    Read {
        path: PathBuf,
        at: Location,
        source: io::Error,
    },
    #[error("{}: no samples in the file (empty, or only comments and blank lines)", path.display())]
    Empty { path: PathBuf },
    #[error("{}: {at}: not a number: \"{text}\"", path.display())]
    NotNumber {
        path: PathBuf,
        at: Location,
        text: String,
    },
    #[error("{}: {at}: value is not finite: \"{text}\"", path.display())]
    NonFinite {
        path: PathBuf,
        at: Location,
        text: String,
    },
    #[error(
        "{}: {at}: value \"{text}\" is out of range (|x| must be below 1e150: its square must not overflow the variances)",
        path.display()
    )]
    OutOfRange {
        path: PathBuf,
        at: Location,
        text: String,
    },
    #[error("{}: {at}: not an integer pulse count: \"{text}\"", path.display())]
    NotInteger {
        path: PathBuf,
        at: Location,
        text: String,
    },
    #[error("{}: no CSV column named \"{name}\"; available columns: {available}", path.display())]
    MissingColumn {
        path: PathBuf,
        name: String,
        available: String,
    },
    #[error("{}: the CSV file has several columns ({available}); choose one with --column", path.display())]
    ColumnNeeded { path: PathBuf, available: String },
    #[error(
        "{}: line {line}: row has {fields} field(s), the header has {expected} (column \"{column}\" is field {index})",
        path.display()
    )]
    RaggedRow {
        path: PathBuf,
        line: u64,
        fields: usize,
        expected: usize,
        column: String,
        index: usize,
    },
    #[error("{}: f64le input is {bytes} bytes, not a multiple of 8", path.display())]
    BadLength { path: PathBuf, bytes: u64 },
    #[error("{}: the name ends in .gz but the content is not gzip data", path.display())]
    NotGzip { path: PathBuf },
}

/// Streaming reader of samples from a file.
///
/// ```no_run
/// use sagnac::input::{Format, plain::SampleReader};
/// let mut r = SampleReader::open("run.f64".as_ref(), Format::F64le, None)?;
/// let mut block = Vec::new();
/// while r.next_block(&mut block, 65536)? > 0 {
///     // process `block`
/// }
/// # Ok::<(), sagnac::input::plain::PlainError>(())
/// ```
pub struct SampleReader {
    path: PathBuf,
    /// exact sample count when known up front (plain f64le files)
    len_hint: Option<u64>,
    inner: Inner,
    total: u64,
    require_integers: bool,
    finished: bool,
    /// The side column's values of the last block.
    side: Vec<f64>,
}

enum Inner {
    Lines(LineState),
    Binary(BinState),
}

struct LineState {
    reader: Box<dyn BufRead + Send>,
    line: u64,
    buf: Vec<u8>,
    /// The CSV layout (`None` for text).
    csv: Option<CsvLayout>,
}

/// Where the wanted fields are in a CSV row.
struct CsvLayout {
    /// Index of the sample column, and its name.
    index: usize,
    name: String,
    /// Index of the side column, read along in the same pass.
    side: Option<usize>,
    delim: u8,
    /// Fields per row (the header's).
    width: usize,
}

struct BinState {
    reader: Box<dyn Read + Send>,
    offset: u64,
    buf: Vec<u8>,
    /// bytes buf[start..end] are read but not yet converted
    start: usize,
    end: usize,
    eof: bool,
}

impl SampleReader {
    /// Open `path` in `format`; `column` selects the CSV column (optional when
    /// the CSV has a single column; ignored for other formats). Gzip content
    /// is recognised by its magic bytes and decompressed on the fly.
    pub fn open(
        path: &Path,
        format: Format,
        column: Option<&str>,
    ) -> Result<SampleReader, PlainError> {
        Self::open_with_side(path, format, column, None)
    }

    /// [`SampleReader::open`], also reading the CSV column `side` (when the
    /// header has it) in the same pass: its values of each block are in
    /// [`SampleReader::side`].
    pub fn open_with_side(
        path: &Path,
        format: Format,
        column: Option<&str>,
        side: Option<&str>,
    ) -> Result<SampleReader, PlainError> {
        let p = path.to_path_buf();
        let file = File::open(path).map_err(|source| PlainError::Open {
            path: p.clone(),
            source,
        })?;
        let mut raw = BufReader::with_capacity(BUF_BYTES, file);
        let head = raw.fill_buf().map_err(|source| PlainError::Read {
            path: p.clone(),
            at: Location::Byte(0),
            source,
        })?;
        let gz = head.len() >= 2 && head[0] == 0x1f && head[1] == 0x8b;
        let named_gz = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("gz"));
        if named_gz && !gz && !head.is_empty() {
            return Err(PlainError::NotGzip { path: p });
        }
        let mut len_hint = None;
        if !gz && format == Format::F64le {
            // plain file: check the length up front
            if let Ok(meta) = raw.get_ref().metadata()
                && meta.is_file()
            {
                if meta.len() % 8 != 0 {
                    return Err(PlainError::BadLength {
                        path: p,
                        bytes: meta.len(),
                    });
                }
                len_hint = Some(meta.len() / 8);
            }
        }
        let reader: Box<dyn BufRead + Send> = if gz {
            Box::new(BufReader::with_capacity(
                BUF_BYTES,
                MultiGzDecoder::new(raw),
            ))
        } else {
            Box::new(raw)
        };
        let inner = match format {
            Format::Text => Inner::Lines(LineState {
                reader,
                line: 0,
                buf: Vec::with_capacity(128),
                csv: None,
            }),
            Format::Csv => {
                let mut st = LineState {
                    reader,
                    line: 0,
                    buf: Vec::with_capacity(256),
                    csv: None,
                };
                st.csv = Some(read_csv_header(&mut st, &p, column, side)?);
                Inner::Lines(st)
            }
            Format::Frames | Format::TriadFrames | Format::Mcap | Format::Ros2 | Format::Array => {
                unreachable!("SampleReader reads text, CSV and f64le, not {format}")
            }
            Format::F64le => Inner::Binary(BinState {
                reader: Box::new(reader),
                offset: 0,
                buf: vec![0; BUF_BYTES],
                start: 0,
                end: 0,
                eof: false,
            }),
        };
        Ok(SampleReader {
            path: p,
            len_hint,
            inner,
            side: Vec::new(),
            total: 0,
            require_integers: false,
            finished: false,
        })
    }

    /// Require every value to be an integer (pulse counts): a fractional value
    /// is reported with its line or byte offset.
    pub fn require_integers(mut self, yes: bool) -> SampleReader {
        self.require_integers = yes;
        self
    }

    /// The file being read.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Total number of samples, when known without reading (plain `f64le` files).
    pub fn len_hint(&self) -> Option<u64> {
        self.len_hint
    }

    /// The CSV column read (`None` for text and f64le).
    pub fn column(&self) -> Option<&str> {
        match &self.inner {
            Inner::Lines(LineState { csv: Some(c), .. }) => Some(&c.name),
            _ => None,
        }
    }

    /// Whether a side column is read along (see [`SampleReader::open_with_side`]).
    pub fn has_side(&self) -> bool {
        matches!(&self.inner, Inner::Lines(LineState { csv: Some(c), .. }) if c.side.is_some())
    }

    /// The side column's values of the last block (empty without one).
    pub fn side(&self) -> &[f64] {
        &self.side
    }

    /// Samples delivered so far.
    pub fn samples_read(&self) -> u64 {
        self.total
    }

    /// Replace the contents of `out` with the next (up to) `max` samples and
    /// return how many were read; 0 means the end of the input. An input
    /// without any sample is an error ([`PlainError::Empty`]).
    pub fn next_block(&mut self, out: &mut Vec<f64>, max: usize) -> Result<usize, PlainError> {
        out.clear();
        self.side.clear();
        if self.finished || max == 0 {
            return Ok(0);
        }
        let ints = self.require_integers;
        match &mut self.inner {
            Inner::Lines(st) => read_lines(st, &self.path, out, &mut self.side, max, ints)?,
            Inner::Binary(st) => read_binary(st, &self.path, out, max, ints)?,
        }
        let n = out.len();
        if n == 0 {
            self.finished = true;
            if self.total == 0 {
                return Err(PlainError::Empty {
                    path: self.path.clone(),
                });
            }
        }
        self.total += n as u64;
        Ok(n)
    }

    /// Read everything that is left.
    pub fn read_to_end(&mut self) -> Result<Vec<f64>, PlainError> {
        let mut all = Vec::new();
        if let Some(n) = self.len_hint {
            all.reserve_exact((n - self.total.min(n)) as usize);
        }
        let mut block = Vec::with_capacity(1 << 16);
        while self.next_block(&mut block, 1 << 16)? > 0 {
            all.extend_from_slice(&block);
        }
        Ok(all)
    }
}

/// Read a whole file (see [`SampleReader::open`]).
pub fn read_all(path: &Path, format: Format, column: Option<&str>) -> Result<Vec<f64>, PlainError> {
    SampleReader::open(path, format, column)?.read_to_end()
}

/// Quote at most `QUOTE_MAX` characters of an offending text.
fn quote(text: &[u8]) -> String {
    let s = String::from_utf8_lossy(text);
    let s = s.trim();
    if s.chars().count() > QUOTE_MAX {
        let cut: String = s.chars().take(QUOTE_MAX).collect();
        format!("{cut}...")
    } else {
        s.to_string()
    }
}

/// Next meaningful line into `st.buf` (comment and surrounding blanks
/// removed); `false` at end of input.
fn next_line(st: &mut LineState, path: &Path) -> Result<bool, PlainError> {
    loop {
        st.buf.clear();
        let n = st
            .reader
            .read_until(b'\n', &mut st.buf)
            .map_err(|source| PlainError::Read {
                path: path.to_path_buf(),
                at: Location::Line(st.line + 1),
                source,
            })?;
        if n == 0 {
            return Ok(false);
        }
        st.line += 1;
        if let Some(h) = st.buf.iter().position(|&b| b == b'#') {
            st.buf.truncate(h);
        }
        let end = st
            .buf
            .iter()
            .rposition(|b| !b.is_ascii_whitespace())
            .map_or(0, |i| i + 1);
        st.buf.truncate(end);
        let start = st
            .buf
            .iter()
            .position(|b| !b.is_ascii_whitespace())
            .unwrap_or(st.buf.len());
        if start > 0 {
            st.buf.drain(..start);
        }
        if !st.buf.is_empty() {
            return Ok(true);
        }
    }
}

fn split_fields(line: &[u8], delim: u8) -> Vec<String> {
    line.split(|&b| b == delim)
        .map(|f| {
            let s = String::from_utf8_lossy(f);
            s.trim().trim_matches('"').trim().to_string()
        })
        .collect()
}

fn read_csv_header(
    st: &mut LineState,
    path: &Path,
    column: Option<&str>,
    side: Option<&str>,
) -> Result<CsvLayout, PlainError> {
    if !next_line(st, path)? {
        return Err(PlainError::Empty {
            path: path.to_path_buf(),
        });
    }
    // a UTF-8 byte-order mark (spreadsheet exports) is not part of the first name
    let line = st.buf.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&st.buf);
    let delim = [b',', b';', b'\t']
        .into_iter()
        .find(|d| line.contains(d))
        .unwrap_or(b',');
    let names = split_fields(line, delim);
    let available = names
        .iter()
        .map(|n| format!("\"{n}\""))
        .collect::<Vec<_>>()
        .join(", ");
    let find = |want: &str| {
        names.iter().position(|n| n == want).or_else(|| {
            let ci: Vec<usize> = (0..names.len())
                .filter(|&i| names[i].eq_ignore_ascii_case(want))
                .collect();
            (ci.len() == 1).then(|| ci[0])
        })
    };
    let idx = match column {
        Some(want) => find(want).ok_or_else(|| PlainError::MissingColumn {
            path: path.to_path_buf(),
            name: want.to_string(),
            available,
        })?,
        None if names.len() == 1 => 0,
        None => {
            return Err(PlainError::ColumnNeeded {
                path: path.to_path_buf(),
                available,
            });
        }
    };
    Ok(CsvLayout {
        index: idx,
        name: names[idx].clone(),
        side: side.and_then(find).filter(|&i| i != idx),
        delim,
        width: names.len(),
    })
}

fn parse_value(text: &[u8], path: &Path, at: Location, ints: bool) -> Result<f64, PlainError> {
    let v = std::str::from_utf8(text)
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .ok_or_else(|| PlainError::NotNumber {
            path: path.to_path_buf(),
            at,
            text: quote(text),
        })?;
    check_value(v, path, at, ints, || quote(text))
}

/// Largest magnitude accepted for an input value: squares and sums of squares
/// of such values stay far from overflow.
pub const MAX_ABS_VALUE: f64 = 1e150;

fn check_value(
    v: f64,
    path: &Path,
    at: Location,
    ints: bool,
    text: impl Fn() -> String,
) -> Result<f64, PlainError> {
    if !v.is_finite() {
        return Err(PlainError::NonFinite {
            path: path.to_path_buf(),
            at,
            text: text(),
        });
    }
    if v.abs() >= MAX_ABS_VALUE {
        return Err(PlainError::OutOfRange {
            path: path.to_path_buf(),
            at,
            text: text(),
        });
    }
    if ints && (v.fract() != 0.0 || v.abs() > 9_007_199_254_740_992.0) {
        return Err(PlainError::NotInteger {
            path: path.to_path_buf(),
            at,
            text: text(),
        });
    }
    Ok(v)
}

fn read_lines(
    st: &mut LineState,
    path: &Path,
    out: &mut Vec<f64>,
    side: &mut Vec<f64>,
    max: usize,
    ints: bool,
) -> Result<(), PlainError> {
    while out.len() < max {
        if !next_line(st, path)? {
            break;
        }
        let at = Location::Line(st.line);
        let Some(c) = &st.csv else {
            out.push(parse_value(&st.buf, path, at, ints)?);
            continue;
        };
        // one pass: the wanted fields, and the row's width
        let (mut field, mut side_field, mut fields) = (&st.buf[..0], &st.buf[..0], 0);
        for (i, f) in st.buf.split(|b| *b == c.delim).enumerate() {
            if i == c.index {
                field = f;
            } else if Some(i) == c.side {
                side_field = f;
            }
            fields += 1;
        }
        if fields != c.width {
            return Err(PlainError::RaggedRow {
                path: path.to_path_buf(),
                line: st.line,
                fields,
                expected: c.width,
                column: c.name.clone(),
                index: c.index + 1,
            });
        }
        out.push(parse_value(unquote(field), path, at, ints)?);
        if c.side.is_some() {
            side.push(parse_value(unquote(side_field), path, at, false)?);
        }
    }
    Ok(())
}

/// A field without its surrounding blanks and quotes.
fn unquote(field: &[u8]) -> &[u8] {
    let f = field.trim_ascii();
    let f = f.strip_prefix(b"\"").unwrap_or(f);
    let f = f.strip_suffix(b"\"").unwrap_or(f);
    f.trim_ascii()
}

fn read_binary(
    st: &mut BinState,
    path: &Path,
    out: &mut Vec<f64>,
    max: usize,
    ints: bool,
) -> Result<(), PlainError> {
    out.reserve(max.min(BUF_BYTES / 8));
    while out.len() < max {
        if cfg!(target_endian = "little") && st.end == st.start && !st.eof {
            // nothing pending: read the file's bytes straight into the values
            let base = out.len();
            let want = (max - base).min(BUF_BYTES / 8);
            out.resize(base + want, 0.0);
            let got = read_full(
                st,
                path,
                bytemuck::cast_slice_mut::<f64, u8>(&mut out[base..]),
            )?;
            let whole = got / 8;
            // a partial value at the end goes back to the byte buffer
            st.buf[..got - 8 * whole]
                .copy_from_slice(&bytemuck::cast_slice::<f64, u8>(&out[base..])[8 * whole..got]);
            st.start = 0;
            st.end = got - 8 * whole;
            out.truncate(base + whole);
            check_finite(&out[base..], st.offset, path, ints)?;
            st.offset += 8 * whole as u64;
            continue;
        }
        if st.end - st.start < 8 {
            if st.eof {
                if st.end > st.start {
                    return Err(PlainError::BadLength {
                        path: path.to_path_buf(),
                        bytes: st.offset + (st.end - st.start) as u64,
                    });
                }
                break;
            }
            // move the partial value to the front and refill
            st.buf.copy_within(st.start..st.end, 0);
            st.end -= st.start;
            st.start = 0;
            while st.end < st.buf.len() {
                let n = match st.reader.read(&mut st.buf[st.end..]) {
                    Ok(n) => n,
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                    Err(source) => {
                        return Err(PlainError::Read {
                            path: path.to_path_buf(),
                            at: Location::Byte(st.offset),
                            source,
                        });
                    }
                };
                if n == 0 {
                    st.eof = true;
                    break;
                }
                st.end += n;
                if st.end - st.start >= 8 * 4096 {
                    break; // enough for now; keeps latency low on slow (gzip) streams
                }
            }
            continue;
        }
        let avail = (st.end - st.start) / 8;
        let take = avail.min(max - out.len());
        let bytes = &st.buf[st.start..st.start + 8 * take];
        let base = out.len();
        if cfg!(target_endian = "little") {
            // the file's bytes are the values' memory: one copy, no per-value work
            out.resize(base + take, 0.0);
            bytemuck::cast_slice_mut::<f64, u8>(&mut out[base..]).copy_from_slice(bytes);
        } else {
            out.extend(
                bytes
                    .chunks_exact(8)
                    .map(|c| f64::from_le_bytes(c.try_into().expect("8-byte chunk"))),
            );
        }
        check_finite(&out[base..], st.offset, path, ints)?;
        st.start += 8 * take;
        st.offset += 8 * take as u64;
    }
    Ok(())
}

/// Read into `dst` until it is full, the stream ends (`st.eof`) or at least
/// 32 KiB came (low latency on slow gzip streams); the bytes read.
fn read_full(st: &mut BinState, path: &Path, dst: &mut [u8]) -> Result<usize, PlainError> {
    let mut got = 0;
    while got < dst.len() {
        let n = match st.reader.read(&mut dst[got..]) {
            Ok(n) => n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(source) => {
                return Err(PlainError::Read {
                    path: path.to_path_buf(),
                    at: Location::Byte(st.offset + got as u64),
                    source,
                });
            }
        };
        if n == 0 {
            st.eof = true;
            break;
        }
        got += n;
        if got >= 8 * 4096 {
            break;
        }
    }
    Ok(got)
}

/// Validate values just read, the first of them at byte `offset` (the rare
/// failure reports the exact offset of the bad one).
fn check_finite(new: &[f64], offset: u64, path: &Path, ints: bool) -> Result<(), PlainError> {
    let bad = if ints {
        new.iter()
            .position(|v| !v.is_finite() || v.fract() != 0.0 || v.abs() > 9_007_199_254_740_992.0)
    } else {
        new.iter().position(|v| !v.is_finite())
    };
    match bad {
        Some(k) => {
            let v = new[k];
            check_value(v, path, Location::Byte(offset + 8 * k as u64), ints, || {
                format!("{v}")
            })
            .map(|_| ())
        }
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn tmp(name: &str, bytes: &[u8]) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        (dir, p)
    }

    #[test]
    fn ragged_csv_rows_are_errors_naming_the_line() {
        for (name, text, line, fields, header) in [
            (
                "short.csv",
                &b"counts,temp_c\n1,20\n2\n3,20\n"[..],
                "line 3",
                1,
                2,
            ),
            ("long.csv", &b"counts\n1\n2,5\n"[..], "line 3", 2, 1),
            // the wanted column present, but a field missing after it
            ("tail.csv", &b"a,counts,b\n1,2,3\n4,5\n"[..], "line 3", 2, 3),
        ] {
            let (_d, p) = tmp(name, text);
            let e = read_all(&p, Format::Csv, Some("counts")).unwrap_err();
            assert!(matches!(e, PlainError::RaggedRow { .. }), "{name}: {e}");
            let e = e.to_string();
            assert!(
                e.contains(name)
                    && e.contains(line)
                    && e.contains(&format!(
                        "row has {fields} field(s), the header has {header}"
                    )),
                "{e}"
            );
        }
    }

    #[test]
    fn text_with_comments_blank_lines_crlf_and_exponents() {
        let (_d, p) = tmp(
            "a.txt",
            b"# header\r\n\r\n+2.76845904000198E-007\r\n  -1.5  \r\n3 # trailing comment\n\n4e2",
        );
        let v = read_all(&p, Format::Text, None).unwrap();
        assert_eq!(v, vec![2.76845904000198e-7, -1.5, 3.0, 400.0]);
    }

    #[test]
    fn text_errors_name_file_and_line() {
        let (_d, p) = tmp(
            "bad.txt",
            b"1\n2\n# c\nabc def ghi jkl mno pqr stu vwx yz0 123 456 789\n",
        );
        let e = read_all(&p, Format::Text, None).unwrap_err().to_string();
        assert!(
            e.contains("bad.txt") && e.contains("line 4") && e.contains("\"abc def"),
            "{e}"
        );
        assert!(e.contains("..."), "long text is truncated: {e}");
        let (_d, p) = tmp("nan.txt", b"1\nNaN\n");
        let e = read_all(&p, Format::Text, None).unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("not finite"), "{e}");
        let (_d, p) = tmp("empty.txt", b"# nothing\n\n");
        assert!(matches!(
            read_all(&p, Format::Text, None),
            Err(PlainError::Empty { .. })
        ));
        let (_d, p) = tmp("frac.txt", b"1\n2.5\n");
        let mut r = SampleReader::open(&p, Format::Text, None)
            .unwrap()
            .require_integers(true);
        let e = r.read_to_end().unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("integer"), "{e}");
    }

    #[test]
    fn csv_column_selection() {
        let (_d, p) = tmp("a.csv", b"t,rate,\"counts\"\n0,1.5,3\n1,2.5,4\r\n");
        assert_eq!(
            read_all(&p, Format::Csv, Some("rate")).unwrap(),
            vec![1.5, 2.5]
        );
        assert_eq!(
            read_all(&p, Format::Csv, Some("counts")).unwrap(),
            vec![3.0, 4.0]
        );
        let e = read_all(&p, Format::Csv, Some("nope"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("a.csv") && e.contains("\"t\", \"rate\", \"counts\""),
            "{e}"
        );
        let e = read_all(&p, Format::Csv, None).unwrap_err().to_string();
        assert!(e.contains("--column"), "{e}");
        let (_d, p) = tmp("short.csv", b"a,b\n1,2\n3\n");
        let e = read_all(&p, Format::Csv, Some("b"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 3"), "{e}");
        // a spreadsheet's UTF-8 byte-order mark before the first name
        let (_d, p) = tmp("bom.csv", b"\xEF\xBB\xBFcounts,t\n5,0\n-2,1\n");
        assert_eq!(
            read_all(&p, Format::Csv, Some("counts")).unwrap(),
            vec![5.0, -2.0]
        );
    }

    #[test]
    fn f64le_blocks_and_errors() {
        let vals: Vec<f64> = (0..10_000).map(|i| i as f64 * 0.25 - 7.0).collect();
        let bytes: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        let (_d, p) = tmp("a.f64", &bytes);
        let mut r = SampleReader::open(&p, Format::F64le, None).unwrap();
        let mut got = Vec::new();
        let mut block = Vec::new();
        let mut sizes = Vec::new();
        while r.next_block(&mut block, 3333).unwrap() > 0 {
            sizes.push(block.len());
            got.extend_from_slice(&block);
        }
        assert_eq!(got, vals);
        assert_eq!(sizes, vec![3333, 3333, 3333, 1]);
        let (_d, p) = tmp("odd.f64", &bytes[..8 * 5 + 3]);
        let e = read_all(&p, Format::F64le, None).unwrap_err().to_string();
        assert!(e.contains("43 bytes"), "{e}");
        let mut b2 = bytes.clone();
        b2[8 * 7..8 * 8].copy_from_slice(&f64::INFINITY.to_le_bytes());
        let (_d, p) = tmp("inf.f64", &b2);
        let e = read_all(&p, Format::F64le, None).unwrap_err().to_string();
        assert!(e.contains("byte offset 56"), "{e}");
    }

    #[test]
    fn block_size_does_not_change_the_samples() {
        // the same samples whatever the block size, for every format and gzip
        let vals: Vec<f64> = (0..2500)
            .map(|i| ((i * 7919) % 1000) as f64 / 8.0 - 60.0)
            .collect();
        let text: String = vals.iter().map(|v| format!("{v}\n")).collect();
        let csv: String = std::iter::once("k,v\n".to_string())
            .chain(vals.iter().map(|v| format!("1,{v}\n")))
            .collect();
        let bin: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        let gz = |b: &[u8]| {
            let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
            e.write_all(b).unwrap();
            e.finish().unwrap()
        };
        let cases = [
            ("t.txt", text.as_bytes().to_vec(), Format::Text),
            ("t.txt.gz", gz(text.as_bytes()), Format::Text),
            ("c.csv", csv.as_bytes().to_vec(), Format::Csv),
            ("b.f64", bin.clone(), Format::F64le),
            ("b.f64.gz", gz(&bin), Format::F64le),
        ];
        for (name, bytes, fmt) in cases {
            let (_d, p) = tmp(name, &bytes);
            for block in [1, 7, 64, 1000, 4096] {
                let mut r = SampleReader::open(&p, fmt, Some("v")).unwrap();
                let mut got = Vec::new();
                let mut buf = Vec::new();
                while r.next_block(&mut buf, block).unwrap() > 0 {
                    assert!(buf.len() <= block);
                    got.extend_from_slice(&buf);
                }
                assert_eq!(got, vals, "{name} block {block}");
                assert_eq!(r.samples_read(), vals.len() as u64);
                assert_eq!(
                    r.next_block(&mut buf, block).unwrap(),
                    0,
                    "stays at the end"
                );
            }
        }
    }

    #[test]
    fn gzip_detected_by_magic() {
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        enc.write_all(b"# gz\n1\n2\n3\n").unwrap();
        let gz = enc.finish().unwrap();
        let (_d, p) = tmp("data.txt.gz", &gz);
        assert_eq!(
            read_all(&p, Format::Text, None).unwrap(),
            vec![1.0, 2.0, 3.0]
        );
        let (_d, p) = tmp("nogz.bin", &gz); // magic bytes, no .gz name
        assert_eq!(
            read_all(&p, Format::Text, None).unwrap(),
            vec![1.0, 2.0, 3.0]
        );
        let (_d, p) = tmp("fake.gz", b"1\n2\n");
        assert!(matches!(
            read_all(&p, Format::Text, None),
            Err(PlainError::NotGzip { .. })
        ));
    }
}
