//! The input flags every command that reads a recording shares (`analyze`,
//! `report`, `diagnose`): the file, the format override, the sample rate and
//! pulse weight, the gyro, the CSV column and its unit. They become an
//! [`input::Request`]; [`crate::input::Input::open`] does the rest.

use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};

use crate::input::{self, Format, Input, Unit};
use crate::sink::provenance::InputSettings;

/// The input flags.
#[derive(Debug, Clone, Args)]
pub struct InputArgs {
    /// The recording: CSV or text (plain or .gz), a raw frame capture (single
    /// or triad frames), an MCAP recording, or a ROS 2 bag (MCAP file or
    /// rosbag2 directory); the format is found by content.
    #[arg(long, value_name = "FILE", alias = "recording")]
    pub input: PathBuf,
    /// Read the file as this format (an error when the content says otherwise;
    /// needed for raw f64le, which has no signature).
    #[arg(long, value_enum)]
    pub format: Option<FormatArg>,
    /// Sample rate, Hz: required for CSV, text and frame captures; an MCAP
    /// recording carries its own (the flag must then agree with it).
    #[arg(
        long,
        value_name = "F",
        alias = "rate-hz",
        allow_negative_numbers = true
    )]
    pub sample_rate_hz: Option<f64>,
    /// Angle of one counter pulse, arcsec: required for pulse counts in CSV,
    /// text and frame captures; an MCAP recording carries its own (the flag must then agree).
    #[arg(long, value_name = "D", allow_negative_numbers = true)]
    pub pulse_arcsec: Option<f64>,
    /// Which gyro of an MCAP recording of several gyros or of a triad capture
    /// (its label, e.g. `x`), or which axis of a ROS 2 bag (`gyro_x`,
    /// `gyro_y`, `gyro_z`): required for such a file, refused for one gyro.
    #[arg(long, value_name = "LABEL")]
    pub gyro: Option<String>,
    /// The sensor_msgs/msg/Imu topic of a ROS 2 bag: required when the bag
    /// has several (the error lists them).
    #[arg(long, value_name = "TOPIC")]
    pub topic: Option<String>,
    /// CSV column to read (default `counts`, or the only column).
    #[arg(long, value_name = "NAME")]
    pub column: Option<String>,
    /// Unit of a CSV or text column (default counts): pulse counts per sample,
    /// deg/h, deg/s or rad/s for a gyro; m/s^2 or g (9.80665 m/s^2) for an
    /// accelerometer.
    #[arg(long, value_enum)]
    pub unit: Option<UnitArg>,
    /// Turn the data-quality stage off: no glitch exclusion, no warm-up, step
    /// or thermal handling (the raw statistics, for comparison).
    #[arg(long)]
    pub raw_statistics: bool,
}

/// `--format`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FormatArg {
    Csv,
    Text,
    F64le,
    Frames,
    TriadFrames,
    Mcap,
    Ros2,
}

impl From<FormatArg> for Format {
    fn from(f: FormatArg) -> Format {
        match f {
            FormatArg::Csv => Format::Csv,
            FormatArg::Text => Format::Text,
            FormatArg::F64le => Format::F64le,
            FormatArg::Frames => Format::Frames,
            FormatArg::TriadFrames => Format::TriadFrames,
            FormatArg::Mcap => Format::Mcap,
            FormatArg::Ros2 => Format::Ros2,
        }
    }
}

/// `--unit`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum UnitArg {
    Counts,
    Dph,
    Dps,
    #[value(name = "rad_s")]
    RadS,
    /// m/s^2 (an accelerometer column).
    Mps2,
    /// standard gravities, 9.80665 m/s^2 (an accelerometer column).
    G,
}

impl From<UnitArg> for Unit {
    fn from(u: UnitArg) -> Unit {
        match u {
            UnitArg::Counts => Unit::Counts,
            UnitArg::Dph => Unit::Dph,
            UnitArg::Dps => Unit::Dps,
            UnitArg::RadS => Unit::RadS,
            UnitArg::Mps2 => Unit::Mps2,
            UnitArg::G => Unit::G,
        }
    }
}

impl InputArgs {
    /// The request these flags make.
    pub fn request(&self) -> input::Request {
        input::Request {
            format: self.format.map(Format::from),
            column: self.column.clone(),
            unit: self.unit.map(Unit::from),
            sample_rate_hz: self.sample_rate_hz,
            pulse_arcsec: self.pulse_arcsec,
            gyro: self.gyro.clone(),
            topic: self.topic.clone(),
            all_axes: false,
            values_only: false,
            whole_on_first_samples: false,
        }
    }

    /// Open the input.
    pub fn open(&self) -> anyhow::Result<Input> {
        Ok(Input::open(&self.input, &self.request())?)
    }
}

/// What a JSON output says about its input ([`crate::sink::provenance`]).
pub fn settings(input: &Input, path: &Path) -> InputSettings {
    let m = input.meta();
    let counts = m.unit == Unit::Counts;
    let mut s = InputSettings::new(
        path,
        m.format.name(),
        m.sample_rate_hz.unwrap_or(f64::NAN),
        if counts { m.pulse_arcsec } else { None },
    );
    if !m.format.holds_counts() {
        s.column = m.column.clone();
        s.unit = Some(m.unit.name().into());
    }
    s.origin = Some(m.origin.clone());
    s.gyro = m.gyro.clone();
    s.topic = m.bag.as_ref().map(|b| b.topic.clone());
    s
}
