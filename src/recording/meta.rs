//! The recording's own description: one MCAP Metadata record named `sagnac`,
//! written right after the header by the daemon's recorder and by
//! `sagnac simulate --format mcap`, so that a recording says at what rate it was
//! sampled and what one count weighs, and the offline commands and the replay
//! need no flag (and no default) to read it.
//!
//! | key | value |
//! |---|---|
//! | `sample_rate_hz` | sample rate, Hz (always) |
//! | `output` | `counts` (pulse increments) or `rate` (rate samples in LSB) |
//! | `pulse_arcsec` | angle of one pulse, arcsec (`output = counts`) |
//! | `rate_lsb_dps` | weight of one rate LSB, deg/s (`output = rate`, when known) |
//! | `model` | the gyro model TOML (simulated recordings) |
//! | `config` | the daemon configuration TOML (recordings of `sagnac run`) |
//! | `sagnac_version` | the version of sagnac that wrote the file |
//!
//! Numbers are written with Rust's shortest round-trip formatting, so they read
//! back bit for bit. Unknown keys are ignored (a newer writer may add some).
//! Reading is [`crate::recording::reader::read_metadata`] (and the `metadata` of a
//! full scan); this module only turns the record into [`RecordingMeta`] and back.
//! [`check_flag`] is the one rule for a flag that meets a recorded value.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

/// Name of the Metadata record sagnac writes and reads.
pub const METADATA_NAME: &str = "sagnac";

/// What the `/gyro/raw` counts of a recording are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GyroOutput {
    /// Pulse increments per sample (a ring laser gyro's up/down counter).
    Counts,
    /// Rate samples, in LSB (a FOG's or a MEMS gyro's digital rate output).
    Rate,
}

impl GyroOutput {
    /// The value of the `output` key.
    pub fn name(self) -> &'static str {
        match self {
            GyroOutput::Counts => "counts",
            GyroOutput::Rate => "rate",
        }
    }
}

impl fmt::Display for GyroOutput {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The `sagnac` Metadata record of a recording.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingMeta {
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// What the counts are.
    pub output: GyroOutput,
    /// Angle of one pulse, arcsec (counts).
    pub pulse_arcsec: Option<f64>,
    /// Weight of one rate LSB, deg/s (rate output, when known).
    pub rate_lsb_dps: Option<f64>,
    /// The gyro model TOML, for a simulated recording.
    pub model: Option<String>,
    /// The daemon configuration TOML, for a recording of `sagnac run`.
    pub config: Option<String>,
    /// Version of sagnac that wrote the file.
    pub sagnac_version: String,
}

/// A `sagnac` Metadata record that does not describe a recording.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MetaError {
    #[error("metadata key `{key}` is missing")]
    Missing { key: &'static str },
    #[error("metadata key `{key}` = {value:?}: {reason}")]
    Bad {
        key: &'static str,
        value: String,
        reason: &'static str,
    },
}

impl RecordingMeta {
    /// A recording of pulse counts at `sample_rate_hz`, `pulse_arcsec` per pulse,
    /// stamped with this sagnac's version.
    pub fn counts(sample_rate_hz: f64, pulse_arcsec: f64) -> Self {
        RecordingMeta {
            sample_rate_hz,
            output: GyroOutput::Counts,
            pulse_arcsec: Some(pulse_arcsec),
            rate_lsb_dps: None,
            model: None,
            config: None,
            sagnac_version: env!("CARGO_PKG_VERSION").to_string(),
        }
    }

    /// The MCAP Metadata record.
    pub fn to_record(&self) -> ::mcap::records::Metadata {
        let mut m = BTreeMap::new();
        m.insert(
            "sample_rate_hz".to_string(),
            self.sample_rate_hz.to_string(),
        );
        m.insert("output".to_string(), self.output.name().to_string());
        let optional = [
            ("pulse_arcsec", self.pulse_arcsec.map(|v| v.to_string())),
            ("rate_lsb_dps", self.rate_lsb_dps.map(|v| v.to_string())),
            ("model", self.model.clone()),
            ("config", self.config.clone()),
        ];
        for (k, v) in optional {
            if let Some(v) = v {
                m.insert(k.to_string(), v);
            }
        }
        m.insert("sagnac_version".to_string(), self.sagnac_version.clone());
        ::mcap::records::Metadata {
            name: METADATA_NAME.to_string(),
            metadata: m,
        }
    }

    /// The Metadata record of gyro `label` of a recording of several gyros
    /// (named `sagnac/<label>`, see [`gyro_metadata_name`]).
    pub fn to_record_for(&self, label: &str) -> ::mcap::records::Metadata {
        let mut r = self.to_record();
        r.name = gyro_metadata_name(label);
        r
    }

    /// Parse the key-value map of a `sagnac` Metadata record.
    pub fn from_map(m: &BTreeMap<String, String>) -> Result<Self, MetaError> {
        let number = |key: &'static str| -> Result<Option<f64>, MetaError> {
            let Some(text) = m.get(key) else {
                return Ok(None);
            };
            match text.trim().parse::<f64>() {
                Ok(v) if v.is_finite() && v > 0.0 => Ok(Some(v)),
                _ => Err(MetaError::Bad {
                    key,
                    value: text.clone(),
                    reason: "not a positive number",
                }),
            }
        };
        let sample_rate_hz = number("sample_rate_hz")?.ok_or(MetaError::Missing {
            key: "sample_rate_hz",
        })?;
        let output = match m.get("output").map(String::as_str) {
            Some("counts") => GyroOutput::Counts,
            Some("rate") => GyroOutput::Rate,
            Some(other) => {
                return Err(MetaError::Bad {
                    key: "output",
                    value: other.to_string(),
                    reason: "must be counts or rate",
                });
            }
            None => return Err(MetaError::Missing { key: "output" }),
        };
        let pulse_arcsec = number("pulse_arcsec")?;
        let rate_lsb_dps = number("rate_lsb_dps")?;
        if output == GyroOutput::Counts && pulse_arcsec.is_none() {
            return Err(MetaError::Missing {
                key: "pulse_arcsec",
            });
        }
        Ok(RecordingMeta {
            sample_rate_hz,
            output,
            pulse_arcsec,
            rate_lsb_dps,
            model: m.get("model").cloned(),
            config: m.get("config").cloned(),
            sagnac_version: m.get("sagnac_version").cloned().unwrap_or_default(),
        })
    }
}

/// Name of the Metadata record of gyro `label` in a recording of several gyros.
pub fn gyro_metadata_name(label: &str) -> String {
    format!("{METADATA_NAME}/{label}")
}

/// A command-line value that contradicts what a recording says about itself.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{flag} {given} contradicts {}: the recording says {recorded} {origin}; leave {flag} out to use it", path.display())]
pub struct Contradiction {
    /// The flag (or config key).
    pub flag: &'static str,
    /// The flag's value.
    pub given: f64,
    /// The recording.
    pub path: PathBuf,
    /// The recording's value.
    pub recorded: f64,
    /// Where the recording says it (e.g. "in its sagnac metadata record").
    pub origin: &'static str,
}

/// Relative difference below which a flag agrees with a value of the metadata
/// record (its numbers round-trip exactly; this forgives a rounded flag). A rate
/// inferred from a sample period in whole ns has a tolerance of 1 ns in the period.
pub const AGREE_REL: f64 = 1e-9;

/// The value to use when `flag` may give `given` and the recording `recorded`
/// (`origin` says where, `rel_tol` how closely they must agree): the
/// recording's when the flag is absent, the flag's when the recording says
/// nothing, an error naming the flag, the file and both values when they
/// differ. `None` when neither gives one.
pub fn check_flag(
    flag: &'static str,
    given: Option<f64>,
    recorded: Option<f64>,
    path: &Path,
    origin: &'static str,
    rel_tol: f64,
) -> Result<Option<f64>, Contradiction> {
    match (given, recorded) {
        (Some(g), Some(r)) if (g - r).abs() > rel_tol * r.abs() => Err(Contradiction {
            flag,
            given: g,
            path: path.to_path_buf(),
            recorded: r,
            origin,
        }),
        (Some(g), _) => Ok(Some(g)),
        (None, r) => Ok(r),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_bad_records() {
        let mut meta = RecordingMeta::counts(1000.0 / 3.0, 1.21);
        meta.model = Some("[gyro]\nsample_rate_hz = 333.3333333333333\n".into());
        let rec = meta.to_record();
        assert_eq!(rec.name, METADATA_NAME);
        assert_eq!(
            RecordingMeta::from_map(&rec.metadata).unwrap(),
            meta,
            "bit for bit"
        );
        let mut m = rec.metadata.clone();
        m.remove("pulse_arcsec");
        assert_eq!(
            RecordingMeta::from_map(&m),
            Err(MetaError::Missing {
                key: "pulse_arcsec"
            })
        );
        m.insert("output".into(), "rate".into());
        assert_eq!(
            RecordingMeta::from_map(&m).unwrap().output,
            GyroOutput::Rate
        );
        m.insert("sample_rate_hz".into(), "-3".into());
        let e = RecordingMeta::from_map(&m).unwrap_err().to_string();
        assert!(e.contains("sample_rate_hz") && e.contains("-3"), "{e}");
        m.insert("sample_rate_hz".into(), "100".into());
        m.insert("output".into(), "volts".into());
        assert!(
            RecordingMeta::from_map(&m)
                .unwrap_err()
                .to_string()
                .contains("volts")
        );
    }

    #[test]
    fn flags_meet_recorded_values() {
        let p = Path::new("r.mcap");
        let check =
            |given, recorded| check_flag("--sample-rate-hz", given, recorded, p, "in x", AGREE_REL);
        assert_eq!(check(None, Some(100.0)), Ok(Some(100.0)));
        assert_eq!(check(Some(50.0), None), Ok(Some(50.0)));
        assert_eq!(check(Some(100.0), Some(100.0)), Ok(Some(100.0)));
        assert_eq!(
            check(Some(100.0), Some(100.0 + 1e-8)),
            Ok(Some(100.0)),
            "within 1e-9"
        );
        assert_eq!(check(None, None), Ok(None));
        let e = check(Some(50.0), Some(100.0)).unwrap_err().to_string();
        assert!(
            e.contains("--sample-rate-hz 50 contradicts r.mcap") && e.contains("says 100 in x"),
            "{e}"
        );
        // a rate from a period of 333333 ns: 3000 Hz agrees within 1 ns
        let r = 1e9 / 333_333.0;
        assert_eq!(
            check_flag(
                "--sample-rate-hz",
                Some(3000.0),
                Some(r),
                p,
                "x",
                1.0 / 333_333.0
            ),
            Ok(Some(3000.0))
        );
    }
}
