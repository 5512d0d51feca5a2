//! What a file is, told by its content: the MCAP magic, the gyro frames' sync
//! pattern and CRC (single 16-byte or triad 24-byte frames, found wherever the
//! capture starts), gzip, and text (CSV with a header row, or one number per
//! line). Raw little-endian `f64` has no signature: it needs `--format f64le`
//! or a name ending in `.f64` / `.f64le`.
//!
//! [`detect`] looks at the first [`HEAD_BYTES`] bytes only (decompressed, for
//! gzip), so it costs the same on any file.

use std::fmt;
use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

use flate2::read::MultiGzDecoder;

use super::frame::{Single, Triad, Wire};

/// Bytes looked at.
pub const HEAD_BYTES: usize = 64 * 1024;
/// Valid frames a capture's head must hold to be taken for frames (fewer when
/// the whole file is shorter).
const MIN_FRAMES: usize = 3;

/// A sample file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Format {
    /// Header row, then rows; one column is selected by name.
    Csv,
    /// One number per line; `#` starts a comment.
    Text,
    /// Raw little-endian IEEE-754 doubles.
    F64le,
    /// A raw capture of the 16-byte single-gyro frames.
    Frames,
    /// A raw capture of the 24-byte triad frames (gyros x, y, z).
    TriadFrames,
    /// An MCAP recording made by `sagnac run`.
    Mcap,
    /// A ROS 2 bag: an MCAP file of profile `ros2` or a rosbag2 directory
    /// (an sqlite3 bag is recognised, to say how to convert it).
    Ros2,
    /// Samples handed over in memory (the Python package's arrays): never
    /// found in a file.
    Array,
}

impl Format {
    /// The name used on the command line and in the JSON's `input.format`.
    pub fn name(self) -> &'static str {
        match self {
            Format::Csv => "csv",
            Format::Text => "text",
            Format::F64le => "f64le",
            Format::Frames => "frames",
            Format::TriadFrames => "triad-frames",
            Format::Mcap => "mcap",
            Format::Ros2 => "ros2",
            Format::Array => "array",
        }
    }

    /// What the format is, in words.
    pub fn describe(self) -> &'static str {
        match self {
            Format::Csv => "CSV text with a header row",
            Format::Text => "text, one number per line",
            Format::F64le => "raw little-endian f64",
            Format::Frames => "a raw capture of 16-byte gyro frames",
            Format::TriadFrames => "a raw capture of 24-byte triad frames",
            Format::Mcap => "an MCAP recording",
            Format::Ros2 => "a ROS 2 bag",
            Format::Array => "an array in memory",
        }
    }

    /// Formats whose samples are pulse counts of a counter.
    pub fn holds_counts(self) -> bool {
        matches!(self, Format::Frames | Format::TriadFrames | Format::Mcap)
    }

    /// Two formats the same bytes can be read as: CSV and text are both text
    /// (a header row decides), single and triad frames both frames (the sync
    /// byte decides). A given format outside the detected one's kind
    /// contradicts the content.
    fn same_kind(self, other: Format) -> bool {
        let kind = |f: Format| match f {
            Format::Csv | Format::Text => 0,
            Format::Frames | Format::TriadFrames => 1,
            Format::Mcap => 2,
            Format::F64le => 3,
            Format::Ros2 => 4,
            Format::Array => 5,
        };
        kind(self) == kind(other)
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Format {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        [
            Format::Csv,
            Format::Text,
            Format::F64le,
            Format::Frames,
            Format::TriadFrames,
            Format::Mcap,
            Format::Ros2,
        ]
        .into_iter()
        .find(|f| f.name() == s)
        .ok_or_else(|| {
            format!(
                "unknown format {s:?} (expected csv, text, f64le, frames, triad-frames, mcap or ros2)"
            )
        })
    }
}

/// What [`detect`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Detected {
    /// The format, when the content (or a documented extension) says it.
    pub format: Option<Format>,
    /// The content is gzip-compressed (the format is that of what it holds).
    pub gzip: bool,
}

/// How the format of a file was settled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FormatOrigin {
    /// Found in the content.
    Content,
    /// Taken from the name's extension (`.f64`, `.f64le`).
    Extension,
    /// Given with `--format` (the content has no signature, or agrees).
    Given,
}

/// Look at the head of `path`.
pub fn detect(path: &Path) -> io::Result<Detected> {
    let mut head = Vec::with_capacity(HEAD_BYTES);
    File::open(path)?
        .take(HEAD_BYTES as u64)
        .read_to_end(&mut head)?;
    let gzip = head.starts_with(&[0x1f, 0x8b]);
    if gzip {
        let mut inner = Vec::with_capacity(HEAD_BYTES);
        // a damaged stream shows when it is read; here the head decides
        let _ = MultiGzDecoder::new(File::open(path)?)
            .take(HEAD_BYTES as u64)
            .read_to_end(&mut inner);
        head = inner;
    }
    let mut format = sniff(&head);
    if format.is_none() && has_f64_extension(path) {
        format = Some(Format::F64le);
    }
    Ok(Detected { format, gzip })
}

/// Whether the file name says raw `f64` (`x.f64`, `x.f64le`, also before `.gz`).
pub fn has_f64_extension(path: &Path) -> bool {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let name = name.strip_suffix(".gz").unwrap_or(&name);
    name.ends_with(".f64") || name.ends_with(".f64le")
}

/// The format `head` (a file's first bytes, decompressed) shows, if any.
pub fn sniff(head: &[u8]) -> Option<Format> {
    if head.starts_with(::mcap::MAGIC) {
        return Some(if mcap_profile(head) == Some("ros2") {
            Format::Ros2
        } else {
            Format::Mcap
        });
    }
    if head.starts_with(super::ros2::bag::SQLITE_MAGIC) {
        // a rosbag2 file in sqlite3 storage: opening it says how to convert it
        return Some(Format::Ros2);
    }
    let single = valid_frames::<Single>(head);
    let triad = valid_frames::<Triad>(head);
    let need = MIN_FRAMES.min(head.len() / Single::LEN).max(1);
    if single.max(triad) >= need {
        return Some(if triad > single {
            Format::TriadFrames
        } else {
            Format::Frames
        });
    }
    sniff_text(head)
}

/// The profile of an MCAP file's Header record (right after the magic).
fn mcap_profile(head: &[u8]) -> Option<&str> {
    let rest = head.get(::mcap::MAGIC.len()..)?;
    if *rest.first()? != ::mcap::records::op::HEADER {
        return None;
    }
    let len = u32::from_le_bytes(rest.get(9..13)?.try_into().ok()?) as usize;
    std::str::from_utf8(rest.get(13..13 + len)?).ok()
}

/// Positions in `head` where a whole frame of wire `W` with a valid CRC starts.
fn valid_frames<W: Wire>(head: &[u8]) -> usize {
    let mut n = 0;
    let mut i = 0;
    while i + W::LEN <= head.len() {
        if head[i] == W::SYNC[0] && head[i + 1] == W::SYNC[1] && W::check(&head[i..]).is_ok() {
            n += 1;
            i += W::LEN;
        } else {
            i += 1;
        }
    }
    n
}

/// Text: UTF-8 (a character cut by the head's end allowed) without control
/// bytes other than white space. One number per meaningful line is
/// [`Format::Text`]; a first meaningful line that is not a number is a
/// header, so [`Format::Csv`].
fn sniff_text(head: &[u8]) -> Option<Format> {
    let text = match std::str::from_utf8(head) {
        Ok(t) => t,
        Err(e) if e.error_len().is_none() => std::str::from_utf8(&head[..e.valid_up_to()]).ok()?,
        Err(_) => return None,
    };
    if text
        .bytes()
        .any(|b| b.is_ascii_control() && !b.is_ascii_whitespace())
    {
        return None;
    }
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    // the head may end inside a line: judge whole lines only when there are some
    let whole = match text.rfind('\n') {
        Some(i) if head.len() >= HEAD_BYTES => &text[..i],
        _ => text,
    };
    let mut lines = whole
        .lines()
        .map(|l| l.split('#').next().unwrap_or("").trim())
        .filter(|l| !l.is_empty());
    // no number at all (empty, or comments only): text, which will say it is empty
    let Some(first) = lines.next() else {
        return Some(Format::Text);
    };
    if first.parse::<f64>().is_err() {
        return Some(Format::Csv);
    }
    // numbers in several fields per row: a CSV without a header is not one we can read
    if lines
        .chain(std::iter::once(first))
        .all(|l| l.parse::<f64>().is_ok())
    {
        Some(Format::Text)
    } else {
        Some(Format::Csv)
    }
}

/// The format to read `path` as: the detected one, or `given` (`--format`)
/// when it agrees with the content or the content has no signature.
pub fn settle(
    path: &Path,
    detected: Detected,
    given: Option<Format>,
) -> Result<(Format, FormatOrigin), FormatError> {
    let origin = |f| {
        if has_f64_extension(path) && f == Format::F64le {
            FormatOrigin::Extension
        } else {
            FormatOrigin::Content
        }
    };
    match (detected.format, given) {
        (Some(d), None) => Ok((d, origin(d))),
        (None, Some(g)) => Ok((g, FormatOrigin::Given)),
        (Some(d), Some(g)) if g == d => Ok((g, FormatOrigin::Given)),
        (Some(d), Some(g)) if g.same_kind(d) || origin(d) == FormatOrigin::Extension => {
            Ok((g, FormatOrigin::Given))
        }
        (Some(d), Some(g)) => Err(FormatError::Contradiction {
            path: path.to_path_buf(),
            given: g,
            found: d,
        }),
        (None, None) => Err(FormatError::Unknown {
            path: path.to_path_buf(),
        }),
    }
}

/// The format cannot be settled.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    /// `--format` says one thing, the content another.
    #[error(
        "{}: --format {given} contradicts the content, which is {} (leave --format out to read it as that)",
        path.display(), found.describe()
    )]
    Contradiction {
        path: std::path::PathBuf,
        given: Format,
        found: Format,
    },
    /// Nothing in the content says what it is.
    #[error(
        "{}: cannot tell the format from the content (not an MCAP recording, no gyro frames, not text): \
         raw little-endian f64 has no signature, give --format f64le (or name the file .f64)",
        path.display()
    )]
    Unknown { path: std::path::PathBuf },
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::frame::{encode_frame, encode_triad_frame};

    fn frames(n: u16, skip: usize) -> Vec<u8> {
        let mut b: Vec<u8> = (0..n)
            .flat_map(|i| encode_frame(i, 1000 + u32::from(i), 2000, 7))
            .collect();
        b.drain(..skip);
        b
    }

    #[test]
    fn frames_are_found_wherever_the_capture_starts() {
        for skip in [0, 1, 7, 15] {
            assert_eq!(
                sniff(&frames(50, skip)),
                Some(Format::Frames),
                "skip {skip}"
            );
        }
        let triad: Vec<u8> = (0..50u16)
            .flat_map(|i| encode_triad_frame(i, [1, 2, 3], 2000, 7))
            .collect();
        for skip in [0, 5, 23] {
            assert_eq!(
                sniff(&triad[skip..]),
                Some(Format::TriadFrames),
                "skip {skip}"
            );
        }
        // garbage before and inside the frames
        let mut noisy = vec![0x5a, 0xa5, 0x00, 0xff, 0x13];
        noisy.extend(frames(10, 3));
        assert_eq!(sniff(&noisy), Some(Format::Frames));
    }

    #[test]
    fn mcap_text_csv_and_binary() {
        let mut m = ::mcap::MAGIC.to_vec();
        m.extend([0u8; 40]);
        assert_eq!(sniff(&m), Some(Format::Mcap));
        assert_eq!(sniff(b"# x\n1\n-2.5e3\n\n4\n"), Some(Format::Text));
        assert_eq!(sniff(b"counts,temp_c\n1,20\n"), Some(Format::Csv));
        assert_eq!(sniff(b"\xEF\xBB\xBFcounts\n1\n"), Some(Format::Csv));
        assert_eq!(sniff(b"1,2\n3,4\n"), Some(Format::Csv));
        let bin: Vec<u8> = (0..100)
            .flat_map(|i| (i as f64 * 0.1).to_le_bytes())
            .collect();
        assert_eq!(sniff(&bin), None);
    }

    #[test]
    fn a_given_format_must_agree_with_the_content() {
        let p = Path::new("run.bin");
        let d = |f| Detected {
            format: Some(f),
            gzip: false,
        };
        assert_eq!(
            settle(p, d(Format::Mcap), None).unwrap(),
            (Format::Mcap, FormatOrigin::Content)
        );
        assert_eq!(
            settle(p, d(Format::Csv), Some(Format::Text)).unwrap().0,
            Format::Text
        );
        let e = settle(p, d(Format::Mcap), Some(Format::Csv))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("--format csv contradicts") && e.contains("MCAP"),
            "{e}"
        );
        let none = Detected {
            format: None,
            gzip: false,
        };
        assert_eq!(
            settle(p, none, Some(Format::F64le)).unwrap(),
            (Format::F64le, FormatOrigin::Given)
        );
        let e = settle(p, none, None).unwrap_err().to_string();
        assert!(e.contains("--format f64le"), "{e}");
        let named = Path::new("x.f64");
        assert_eq!(
            settle(named, d(Format::F64le), None).unwrap().1,
            FormatOrigin::Extension
        );
    }
}
