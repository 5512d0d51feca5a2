//! The files of a ROS 2 bag: one MCAP file, or a rosbag2 directory whose
//! `metadata.yaml` lists its files in order (a recording split over several
//! files is read as one), each optionally zstd-compressed whole
//! (`compression_mode: file`). A bag in sqlite3 storage is refused with the
//! command that converts it.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::Ros2Error;

/// The start of an SQLite database file.
pub const SQLITE_MAGIC: &[u8] = b"SQLite format 3\0";

/// How to turn a sqlite3 bag into an MCAP one, for the error message.
pub const CONVERT_HINT: &str = "convert it to MCAP storage first: \
    `ros2 bag convert -i BAG -o out.yaml` with `storage_id: mcap` in out.yaml, or, without ROS, \
    `pip install rosbags && rosbags-convert --src BAG --dst BAG_MCAP --dst-storage mcap`";

/// A bag's files, in recording order.
#[derive(Debug, Clone, PartialEq)]
pub struct Bag {
    /// The path given (a file or a directory).
    pub path: PathBuf,
    /// Its MCAP files.
    pub files: Vec<PathBuf>,
    /// Each file is zstd-compressed whole.
    pub zstd_files: bool,
}

#[derive(Deserialize)]
struct MetadataFile {
    rosbag2_bagfile_information: BagInfo,
}

#[derive(Deserialize)]
struct BagInfo {
    storage_identifier: String,
    #[serde(default)]
    relative_file_paths: Vec<String>,
    #[serde(default)]
    compression_mode: Option<String>,
    #[serde(default)]
    compression_format: Option<String>,
}

impl Bag {
    /// The bag at `path`: an MCAP file, or a rosbag2 directory.
    pub fn open(path: &Path) -> Result<Bag, Ros2Error> {
        if !path.is_dir() {
            let mut head = [0u8; 16];
            let n = File::open(path)
                .and_then(|mut f| f.read(&mut head))
                .map_err(|e| Ros2Error::io(path, e))?;
            if head[..n] == *SQLITE_MAGIC {
                return Err(Ros2Error::Sqlite {
                    path: path.to_path_buf(),
                });
            }
            return Ok(Bag {
                path: path.to_path_buf(),
                files: vec![path.to_path_buf()],
                zstd_files: false,
            });
        }
        let meta_path = path.join("metadata.yaml");
        if !meta_path.is_file() {
            return Err(Ros2Error::NotABag {
                path: path.to_path_buf(),
            });
        }
        let text = std::fs::read_to_string(&meta_path).map_err(|e| Ros2Error::io(&meta_path, e))?;
        let info = serde_saphyr::from_str::<MetadataFile>(&text)
            .map_err(|e| Ros2Error::Metadata {
                path: meta_path.clone(),
                reason: e.to_string(),
            })?
            .rosbag2_bagfile_information;
        Bag::from_info(path, &meta_path, info)
    }

    fn from_info(path: &Path, meta_path: &Path, info: BagInfo) -> Result<Bag, Ros2Error> {
        let bad = |reason: String| Ros2Error::Metadata {
            path: meta_path.to_path_buf(),
            reason,
        };
        match info.storage_identifier.as_str() {
            "mcap" => {}
            "sqlite3" => {
                return Err(Ros2Error::Sqlite {
                    path: path.to_path_buf(),
                });
            }
            other => {
                return Err(bad(format!(
                    "storage_identifier {other:?}: sagnac reads mcap"
                )));
            }
        }
        let mode = info
            .compression_mode
            .unwrap_or_default()
            .to_ascii_lowercase();
        let format = info.compression_format.unwrap_or_default();
        let zstd_files = match (mode.as_str(), format.as_str()) {
            ("" | "none", _) => false,
            ("file", "zstd") => true,
            (m, f) => {
                return Err(bad(format!(
                    "compression_mode {m:?} with compression_format {f:?}: sagnac reads uncompressed \
                     or file-mode zstd bags (MCAP's own chunk compression is always read)"
                )));
            }
        };
        if info.relative_file_paths.is_empty() {
            return Err(bad("relative_file_paths lists no file".into()));
        }
        let mut files = Vec::new();
        for rel in &info.relative_file_paths {
            // rosbag2 has written these both relative to the directory and with its name in front
            let name = Path::new(rel)
                .file_name()
                .map(Path::new)
                .unwrap_or(Path::new(rel));
            let f = path.join(name);
            if !f.is_file() {
                return Err(bad(format!(
                    "relative_file_paths names {rel:?}, which is not in the directory"
                )));
            }
            files.push(f);
        }
        Ok(Bag {
            path: path.to_path_buf(),
            files,
            zstd_files,
        })
    }

    /// Open one of its files for reading (decompressed).
    pub fn reader(&self, file: &Path) -> Result<Box<dyn Read + Send>, Ros2Error> {
        let f = File::open(file).map_err(|e| Ros2Error::io(file, e))?;
        if self.zstd_files {
            let d = zstd::stream::read::Decoder::new(f).map_err(|e| Ros2Error::io(file, e))?;
            Ok(Box::new(d))
        } else {
            Ok(Box::new(BufReader::with_capacity(1 << 16, f)))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir_with(meta: &str, files: &[&str]) -> tempfile::TempDir {
        let d = tempfile::tempdir().unwrap();
        std::fs::write(d.path().join("metadata.yaml"), meta).unwrap();
        for f in files {
            std::fs::write(d.path().join(f), b"").unwrap();
        }
        d
    }

    #[test]
    fn metadata_lists_the_files_in_order() {
        let meta = "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: mcap\n  \
            relative_file_paths:\n    - run/run_0.mcap\n    - run/run_1.mcap\n  \
            compression_format: \"\"\n  compression_mode: \"\"\n  extra: {a: 1}\n";
        let d = dir_with(meta, &["run_0.mcap", "run_1.mcap"]);
        let b = Bag::open(d.path()).unwrap();
        let names: Vec<_> = b
            .files
            .iter()
            .map(|f| f.file_name().unwrap().to_owned())
            .collect();
        assert_eq!(names, ["run_0.mcap", "run_1.mcap"]);
        assert!(!b.zstd_files);
    }

    #[test]
    fn sqlite_missing_files_and_foreign_directories_are_named() {
        let d = dir_with(
            "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n  relative_file_paths: [b.db3]\n",
            &["b.db3"],
        );
        let e = Bag::open(d.path()).unwrap_err().to_string();
        assert!(
            e.contains("sqlite3") && e.contains("rosbags-convert"),
            "{e}"
        );
        let d = dir_with(
            "rosbag2_bagfile_information:\n  storage_identifier: mcap\n  relative_file_paths: [gone.mcap]\n",
            &[],
        );
        let e = Bag::open(d.path()).unwrap_err().to_string();
        assert!(
            e.contains("metadata.yaml") && e.contains("gone.mcap"),
            "{e}"
        );
        let d = tempfile::tempdir().unwrap();
        let e = Bag::open(d.path()).unwrap_err().to_string();
        assert!(e.contains("no metadata.yaml"), "{e}");
        let d = dir_with("rosbag2_bagfile_information: [", &[]);
        let e = Bag::open(d.path()).unwrap_err().to_string();
        assert!(e.contains("metadata.yaml"), "{e}");
    }
}
