//! The input layer: every recorded file comes in here, whatever made it.
//!
//! [`Input::open`] tells the format by the content ([`detect`]: the MCAP
//! magic, the frame sync of single or triad frames, gzip, CSV or plain text;
//! raw `f64le` needs `--format` or a `.f64` name), reads what the file says
//! about itself (sample rate, pulse weight, gyros, units) and merges it with
//! what the command line gives ([`Request`]), a flag that contradicts the file
//! being an error. [`Input::stream`] then hands out the samples as a pull
//! stream of [`Block`]s: pulse increments or rate values, the samples made up
//! to fill gaps, and the temperature; it can be called again for a second pass.
//!
//! Formats and where their code lives:
//! - text, CSV and raw `f64le`, each optionally gzip-compressed: [`plain`];
//! - raw frame captures (single and triad frames) and their sans-IO decoder:
//!   [`capture`], [`frame`];
//! - MCAP recordings made by `sagnac run`: [`crate::recording`], read through
//!   `recorded` here;
//! - ROS 2 bags (an MCAP file of profile `ros2`, or a rosbag2 directory) of
//!   `sensor_msgs/msg/Imu`: [`ros2`].
//!
//! Nothing here imports the numerics, the sinks or the daemon; the daemon's
//! async sources (serial port, replay, simulated bench) are in
//! [`crate::daemon`] and use the frame decoder and [`detect`] from here.

use std::path::{Path, PathBuf};

pub mod capture;
pub mod detect;
pub mod frame;
pub mod plain;
mod prefetch;
mod recorded;
pub mod ros2;
mod stream;

pub use detect::{Format, FormatOrigin};
pub use prefetch::Prefetch;
pub use recorded::{RecordedGyro, recorded_gyros};
pub use stream::{Block, BlockSource, Stream, StreamReport};

use crate::recording::meta::Contradiction;
use crate::recording::reader::ReadError;
use crate::units;
use capture::CaptureError;
use plain::PlainError;

/// Longest gap (lost samples) a recording may hold: 4.7 h at 1 kHz. The frame
/// decoder never reports more than 4096; a gap this long would have to be
/// filled with that many made-up samples.
pub const MAX_GAP_SAMPLES: u64 = 1 << 24;

/// Unit of the samples of a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Unit {
    /// Pulse increments per sample (integers or decimals).
    Counts,
    /// deg/h.
    Dph,
    /// deg/s.
    Dps,
    /// rad/s.
    RadS,
    /// m/s^2 (an accelerometer).
    Mps2,
    /// Standard gravities, 9.80665 m/s^2 (an accelerometer).
    G,
}

impl Unit {
    /// The name used on the command line and in the JSON.
    pub fn name(self) -> &'static str {
        match self {
            Unit::Counts => "counts",
            Unit::Dph => "dph",
            Unit::Dps => "dps",
            Unit::RadS => "rad_s",
            Unit::Mps2 => "mps2",
            Unit::G => "g",
        }
    }

    /// The unit in words.
    pub fn describe(self) -> &'static str {
        match self {
            Unit::Counts => "pulse counts per sample",
            Unit::Dph => "deg/h",
            Unit::Dps => "deg/s",
            Unit::RadS => "rad/s",
            Unit::Mps2 => "m/s^2",
            Unit::G => "g (9.80665 m/s^2)",
        }
    }

    /// What a sample in this unit measures.
    pub fn quantity(self) -> units::Quantity {
        match self {
            Unit::Mps2 | Unit::G => units::Quantity::Acceleration,
            _ => units::Quantity::AngularRate,
        }
    }

    /// A sample in this unit as deg/h (`pulse_arcsec`, `tau0_s`: the
    /// counter's pulse weight and sample period, for `Counts`); an
    /// accelerometer's as m/s^2, which the numerics carry in deg/h's place
    /// ([`units::Quantity`]).
    pub fn to_dph(self, v: f64, pulse_arcsec: f64, tau0_s: f64) -> f64 {
        match self {
            Unit::Counts => units::counts_to_dph(v, pulse_arcsec, tau0_s),
            Unit::Dph | Unit::Mps2 => v,
            Unit::Dps => units::dps_to_dph(v),
            Unit::RadS => units::rad_s_to_dph(v),
            Unit::G => v * units::STANDARD_GRAVITY_MPS2,
        }
    }
}

/// What the command line says about an input; `None` leaves a setting to the
/// file (or to the default the file's format implies).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Request {
    /// `--format`: an override, an error when it contradicts the content.
    pub format: Option<Format>,
    /// `--column`: the CSV column (default `counts`, or the only column).
    pub column: Option<String>,
    /// `--unit` of a CSV or text column (default counts).
    pub unit: Option<Unit>,
    /// `--sample-rate-hz`.
    pub sample_rate_hz: Option<f64>,
    /// `--pulse-arcsec`.
    pub pulse_arcsec: Option<f64>,
    /// `--gyro`: one gyro of a recording of several, of a triad capture, or
    /// an axis of a ROS 2 bag (`gyro_x`, ...).
    pub gyro: Option<String>,
    /// `--topic`: the Imu topic of a ROS 2 bag (needed when it has several).
    pub topic: Option<String>,
    /// Open a multi-axis input (a ROS 2 bag, a triad capture, a recording of
    /// several gyros) without `--gyro`: its axes are then read one by one
    /// ([`Input::axes`], [`Input::for_axis`]) instead of the error asking for one.
    pub all_axes: bool,
    /// Hand out the numbers of a text, CSV or f64le file as they are, without
    /// checking up front whether they are whole pulse counts (`sagnac allan`
    /// on phase or frequency data). Counters still stream counts.
    pub values_only: bool,
    /// Judge whether the counts of a text, CSV or f64le file are whole
    /// numbers on its first samples instead of reading it all up front: a
    /// pass then stops at the first fraction ([`PlainError::NotInteger`]) and
    /// [`crate::pipeline::feed::run`] reads the file again as rates
    /// ([`Input::as_fractional`]). For the callers that read an input once.
    pub whole_on_first_samples: bool,
}

/// What an input is, and the settings it is read with.
#[derive(Debug, Clone, PartialEq)]
pub struct Meta {
    /// The format read.
    pub format: Format,
    /// How the format was settled.
    pub format_origin: FormatOrigin,
    /// Whether the content is gzip-compressed.
    pub gzip: bool,
    /// Sample rate, Hz (`None`: neither the file nor a flag says it).
    pub sample_rate_hz: Option<f64>,
    /// Angle of one pulse, arcsec (pulse counts).
    pub pulse_arcsec: Option<f64>,
    /// Weight of one rate LSB, deg/s, when the file says it.
    pub rate_lsb_dps: Option<f64>,
    /// Unit of the samples.
    pub unit: Unit,
    /// Where the sample rate and pulse weight came from, in words.
    pub origin: String,
    /// The gyros the file holds (empty: one gyro without a label).
    pub gyros: Vec<String>,
    /// The gyro read (`--gyro`).
    pub gyro: Option<String>,
    /// The CSV column read.
    pub column: Option<String>,
    /// The samples are whole pulse counts: they stream as integers
    /// ([`Block::counts`]), for the exact integer path.
    pub integral: bool,
    /// `integral` was judged on the first [`WHOLE_CHECK_SAMPLES`] samples
    /// only ([`Request::whole_on_first_samples`]); a pass stops with
    /// [`PlainError::NotInteger`] at a later fraction.
    pub integral_tentative: bool,
    /// Number of samples, when known without reading them all.
    pub len_hint: Option<u64>,
    /// A ROS 2 bag's topic and the timing of its stamps.
    pub bag: Option<ros2::BagMeta>,
}

/// An opened input: its [`Meta`], and a stream of its samples on demand.
#[derive(Debug, Clone)]
pub struct Input {
    path: PathBuf,
    meta: Meta,
    request: Request,
    /// The samples of an input in memory ([`Input::from_values`]).
    memory: Option<std::sync::Arc<Vec<f64>>>,
}

/// Errors of the input layer; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    #[error("{}: cannot read", path.display())]
    Open {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error(transparent)]
    Format(#[from] detect::FormatError),
    #[error(transparent)]
    Plain(#[from] PlainError),
    #[error(transparent)]
    Capture(#[from] CaptureError),
    #[error(transparent)]
    Recording(#[from] ReadError),
    #[error(transparent)]
    Contradiction(#[from] Contradiction),
    #[error(transparent)]
    Ros2(#[from] ros2::Ros2Error),
    /// A value the input does not carry and no flag gave.
    #[error("{flag} is required: {} carries no {what}", path.display())]
    FlagRequired {
        flag: &'static str,
        path: PathBuf,
        what: String,
    },
    /// A flag that does not apply to this format.
    #[error("{flag} does not apply to {}: it is {}{why}", path.display(), format.describe())]
    FlagNotApplicable {
        flag: &'static str,
        path: PathBuf,
        format: Format,
        why: &'static str,
    },
    /// A value out of range.
    #[error("{flag} must be a positive number (got {value})")]
    NotPositive { flag: &'static str, value: f64 },
    /// A recording of several gyros read without saying which.
    #[error("{}: holds several gyros ({}): choose one with --gyro LABEL", path.display(), labels.join(", "))]
    ChooseGyro { path: PathBuf, labels: Vec<String> },
    /// `--gyro` names a gyro the file does not have.
    #[error("--gyro {gyro}: {} has no such gyro ({})", path.display(),
        if labels.is_empty() { "it holds one gyro: leave --gyro out".to_string() }
        else { format!("its gyros: {}", labels.join(", ")) })]
    NoSuchGyro {
        path: PathBuf,
        gyro: String,
        labels: Vec<String>,
    },
    /// A recording of rate samples, which is not read yet.
    #[error("{}: its metadata says output = rate (rate samples, not pulse counts): not supported here yet", path.display())]
    RateOutput { path: PathBuf },
    #[error("{}: no samples", path.display())]
    Empty { path: PathBuf },
    #[error(
        "{}: /gyro/raw batches disagree on the sample period ({first_ns} ns, then {other_ns} ns at t = {t0_ns} ns)",
        path.display()
    )]
    MixedRate {
        path: PathBuf,
        first_ns: u64,
        other_ns: u64,
        t0_ns: u64,
    },
    #[error(
        "{}: the /gyro/raw batch at t0 = {t0_ns} ns has a gap of {lost} lost samples \
         (more than {MAX_GAP_SAMPLES}: not a recording of a gyro that kept running)",
        path.display()
    )]
    ImplausibleGap {
        path: PathBuf,
        t0_ns: u64,
        lost: u64,
    },
    #[error("{}: no samples before the file becomes unreadable at byte {offset}: {reason}", path.display())]
    BrokenBeforeSamples {
        path: PathBuf,
        offset: u64,
        reason: String,
    },
}

/// "given on the command line": where a flag's value comes from.
pub const GIVEN: &str = "given on the command line";

impl Input {
    /// Open `path`: settle its format, read what it says about itself, and
    /// merge that with `req`. Nothing of the samples is read, except for a
    /// CSV or text column of pulse counts, whose values are checked to be
    /// whole numbers (that decides the exact integer path).
    pub fn open(path: &Path, req: &Request) -> Result<Input, InputError> {
        for (flag, v) in [
            ("--sample-rate-hz", req.sample_rate_hz),
            ("--pulse-arcsec", req.pulse_arcsec),
        ] {
            if let Some(v) = v
                && !(v.is_finite() && v > 0.0)
            {
                return Err(InputError::NotPositive { flag, value: v });
            }
        }
        let detected = if path.is_dir() {
            // a directory can only be a rosbag2 bag (ros2 says when it is not)
            detect::Detected {
                format: Some(Format::Ros2),
                gzip: false,
            }
        } else {
            detect::detect(path).map_err(|source| InputError::Open {
                path: path.to_path_buf(),
                source,
            })?
        };
        let (format, format_origin) = detect::settle(path, detected, req.format)?;
        let mut meta = Meta {
            format,
            format_origin,
            gzip: detected.gzip,
            sample_rate_hz: req.sample_rate_hz,
            pulse_arcsec: req.pulse_arcsec,
            rate_lsb_dps: None,
            unit: req.unit.unwrap_or(Unit::Counts),
            origin: GIVEN.into(),
            gyros: Vec::new(),
            gyro: None,
            column: None,
            integral: false,
            integral_tentative: false,
            len_hint: None,
            bag: None,
        };
        if req.topic.is_some() && format != Format::Ros2 {
            return Err(not_applicable(
                "--topic",
                path,
                format,
                " (topics are a ROS 2 bag's)",
            ));
        }
        match format {
            Format::Csv | Format::Text | Format::F64le => open_plain(path, req, &mut meta)?,
            Format::Frames | Format::TriadFrames => open_frames(path, req, &mut meta)?,
            Format::Mcap => recorded::open(path, req, &mut meta)?,
            Format::Ros2 => ros2::open(path, req, &mut meta)?,
            Format::Array => {
                return Err(InputError::Format(detect::FormatError::Unknown {
                    path: path.to_path_buf(),
                }));
            }
        }
        Ok(Input {
            path: path.to_path_buf(),
            meta,
            request: req.clone(),
            memory: None,
        })
    }

    /// The axes still to choose: every gyro (or bag axis) of a multi-axis
    /// input opened with [`Request::all_axes`] and no `--gyro`; empty once one
    /// is chosen, or for an input of one axis.
    pub fn axes(&self) -> Vec<String> {
        if self.meta.gyro.is_some() {
            return Vec::new();
        }
        self.meta.gyros.clone()
    }

    /// This input read for one of its [`Input::axes`]: a bag's axis at once
    /// (its timing is the topic's), another input opened again for that gyro
    /// (each gyro of a recording has its own settings).
    pub fn for_axis(&self, label: &str) -> Result<Input, InputError> {
        if self.meta.format == Format::Ros2 {
            let mut one = self.clone();
            one.meta.gyro = pick_gyro(
                &self.path,
                &self.meta.gyros,
                &Request {
                    gyro: Some(label.to_string()),
                    ..Request::default()
                },
            )?;
            one.meta.unit = ros2::axis_unit(label);
            one.request.gyro = Some(label.to_string());
            return Ok(one);
        }
        let req = Request {
            gyro: Some(label.to_string()),
            all_axes: false,
            ..self.request.clone()
        };
        Input::open(&self.path, &req)
    }

    /// Samples in memory as an input (the Python package): `values` in
    /// `unit` at `sample_rate_hz` (`pulse_arcsec` for pulse counts, which
    /// take the exact integer path when every value is whole); `name` stands
    /// for the file in messages and the JSON.
    pub fn from_values(
        name: &str,
        values: Vec<f64>,
        unit: Unit,
        sample_rate_hz: f64,
        pulse_arcsec: Option<f64>,
    ) -> Result<Input, InputError> {
        for (flag, v) in [
            ("sample_rate_hz", Some(sample_rate_hz)),
            ("pulse_arcsec", pulse_arcsec),
        ] {
            if let Some(v) = v
                && !(v.is_finite() && v > 0.0)
            {
                return Err(InputError::NotPositive { flag, value: v });
            }
        }
        let path = PathBuf::from(name);
        if values.is_empty() {
            return Err(InputError::Empty { path });
        }
        if unit == Unit::Counts && pulse_arcsec.is_none() {
            return Err(InputError::FlagRequired {
                flag: "pulse_arcsec",
                path,
                what: "pulse weight (pulse counts)".into(),
            });
        }
        let integral =
            unit == Unit::Counts && values.iter().all(|v| v.fract() == 0.0 && v.abs() < 9e15);
        let meta = Meta {
            format: Format::Array,
            format_origin: FormatOrigin::Given,
            gzip: false,
            sample_rate_hz: Some(sample_rate_hz),
            pulse_arcsec,
            rate_lsb_dps: None,
            unit,
            origin: "given as arguments".into(),
            gyros: Vec::new(),
            gyro: None,
            column: None,
            integral,
            integral_tentative: false,
            len_hint: Some(values.len() as u64),
            bag: None,
        };
        Ok(Input {
            path,
            meta,
            request: Request::default(),
            memory: Some(std::sync::Arc::new(values)),
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What the input is, and the settings it is read with.
    pub fn meta(&self) -> &Meta {
        &self.meta
    }

    /// The sample rate, or the error naming the flag that must give it.
    pub fn sample_rate_hz(&self) -> Result<f64, InputError> {
        self.meta
            .sample_rate_hz
            .ok_or_else(|| self.required("--sample-rate-hz", "sample rate"))
    }

    /// The pulse weight, or the error naming the flag that must give it.
    pub fn pulse_arcsec(&self) -> Result<f64, InputError> {
        self.meta
            .pulse_arcsec
            .ok_or_else(|| self.required("--pulse-arcsec", "pulse weight"))
    }

    fn required(&self, flag: &'static str, what: &str) -> InputError {
        let why = match self.meta.format {
            Format::Mcap => " (no sagnac metadata record)".to_string(),
            f => format!(" ({})", f.describe()),
        };
        InputError::FlagRequired {
            flag,
            path: self.path.clone(),
            what: format!("{what}{why}"),
        }
    }

    /// The input read as rate values (its counts not whole): where a pass
    /// over an input whose counts were judged whole on their first samples
    /// met a fraction ([`Meta::integral_tentative`]).
    pub fn as_fractional(&self) -> Input {
        let mut input = self.clone();
        input.meta.integral = false;
        input.meta.integral_tentative = false;
        input
    }

    /// The input with its counts checked whole over the whole file, when they
    /// were judged on their first samples only.
    pub fn checked_whole(&self) -> Result<Input, InputError> {
        let mut input = self.clone();
        if input.meta.integral_tentative {
            let meta = &mut input.meta;
            (meta.integral, meta.integral_tentative) = whole_numbers(&self.path, meta, None)?;
        }
        Ok(input)
    }

    /// A new pass over the samples, from the first.
    pub fn stream(&self) -> Result<Stream, InputError> {
        match &self.memory {
            Some(values) => Ok(Stream::memory(
                &self.path,
                values.clone(),
                self.meta.integral,
            )),
            None => Stream::open(&self.path, &self.meta),
        }
    }

    /// Every axis of a bag opened with [`Request::all_axes`] in one pass (one
    /// block per axis at a time); `None` for other inputs, whose gyros are
    /// read each in its own pass.
    pub fn stream_all_axes(&self) -> Option<Result<ros2::Ros2Stream, InputError>> {
        (self.meta.format == Format::Ros2 && self.meta.gyro.is_none())
            .then(|| ros2::Ros2Stream::open(&self.path, &self.meta))
    }

    /// Every sample at once: one [`Block`] holding the whole input (its
    /// temperature only when every sample has one), and what the pass met.
    pub fn read_all(&self) -> Result<(Block, StreamReport), InputError> {
        let mut stream = self.stream()?;
        let mut all = Block::default();
        let mut block = Block::default();
        let mut temps_complete = true;
        while stream.next_block(&mut block)? {
            let base = all.len();
            all.counts.extend_from_slice(&block.counts);
            all.values.extend_from_slice(&block.values);
            all.filled
                .extend(block.filled.iter().map(|r| r.start + base..r.end + base));
            temps_complete &= block.temp_c.len() == block.len();
            if temps_complete {
                all.temp_c.extend_from_slice(&block.temp_c);
            }
            all.gaps += block.gaps;
            all.lost_samples += block.lost_samples;
        }
        if !temps_complete {
            all.temp_c = Vec::new();
        }
        // the vectors grew by doubling: give back what they will not use
        all.counts.shrink_to_fit();
        all.values.shrink_to_fit();
        all.temp_c.shrink_to_fit();
        Ok((all, stream.report()))
    }
}

pub(crate) fn not_applicable(
    flag: &'static str,
    path: &Path,
    format: Format,
    why: &'static str,
) -> InputError {
    InputError::FlagNotApplicable {
        flag,
        path: path.to_path_buf(),
        format,
        why,
    }
}

/// Text, CSV or f64le: the column, the unit, and whether the values are whole.
fn open_plain(path: &Path, req: &Request, meta: &mut Meta) -> Result<(), InputError> {
    if req.gyro.is_some() {
        return Err(not_applicable("--gyro", path, meta.format, ", of one gyro"));
    }
    if meta.format == Format::Csv {
        let column = req.column.clone().unwrap_or_else(|| "counts".into());
        // a CSV of one column is read whatever its name, when none is asked for
        let reader = match plain::SampleReader::open(path, Format::Csv, Some(&column)) {
            Err(PlainError::MissingColumn { .. }) if req.column.is_none() => {
                plain::SampleReader::open(path, Format::Csv, None)?
            }
            other => other?,
        };
        meta.column = reader.column().map(str::to_string);
    } else if req.column.is_some() {
        return Err(not_applicable(
            "--column",
            path,
            meta.format,
            " (one value per sample, no columns)",
        ));
    }
    if meta.unit == Unit::Counts && !req.values_only {
        let limit = req.whole_on_first_samples.then_some(WHOLE_CHECK_SAMPLES);
        (meta.integral, meta.integral_tentative) = whole_numbers(path, meta, limit)?;
    }
    if meta.format == Format::F64le && !meta.gzip {
        meta.len_hint = std::fs::metadata(path).ok().map(|m| m.len() / 8);
    }
    Ok(())
}

/// Samples [`Request::whole_on_first_samples`] judges the counts on.
pub const WHOLE_CHECK_SAMPLES: u64 = 1 << 16;

/// Whether every value of the column (or of its first `limit`) is a whole
/// number, and whether values are left unread after `limit`.
fn whole_numbers(
    path: &Path,
    meta: &mut Meta,
    limit: Option<u64>,
) -> Result<(bool, bool), InputError> {
    let mut r = plain::SampleReader::open(path, meta.format, meta.column.as_deref())?
        .require_integers(true);
    let mut block = Vec::new();
    loop {
        if limit.is_some_and(|l| r.samples_read() >= l) {
            return Ok((true, true));
        }
        match r.next_block(&mut block, 1 << 16) {
            Ok(0) => break,
            Ok(_) => {}
            Err(PlainError::NotInteger { .. }) => return Ok((false, false)),
            Err(e) => return Err(e.into()),
        }
    }
    meta.len_hint = Some(r.samples_read());
    Ok((true, false))
}

/// A raw frame capture: one gyro, or the `--gyro` of a triad.
fn open_frames(path: &Path, req: &Request, meta: &mut Meta) -> Result<(), InputError> {
    if req.column.is_some() {
        return Err(not_applicable(
            "--column",
            path,
            meta.format,
            ", which holds pulse counts",
        ));
    }
    if req.unit.is_some_and(|u| u != Unit::Counts) {
        return Err(not_applicable(
            "--unit",
            path,
            meta.format,
            ", which holds pulse counts",
        ));
    }
    meta.unit = Unit::Counts;
    meta.integral = true;
    let frame_len = if meta.format == Format::TriadFrames {
        meta.gyros = frame::triad::AXES.iter().map(|s| s.to_string()).collect();
        24
    } else {
        16
    };
    meta.gyro = pick_gyro(path, &meta.gyros, req)?;
    if !meta.gzip {
        meta.len_hint = std::fs::metadata(path).ok().map(|m| m.len() / frame_len);
    }
    Ok(())
}

/// Which of `labels` to read, given `--gyro`: none for a file of one gyro
/// (and no `--gyro`) or when every axis is read, the label for one of
/// several; an error naming the labels otherwise.
fn pick_gyro(path: &Path, labels: &[String], req: &Request) -> Result<Option<String>, InputError> {
    match req.gyro.as_deref() {
        None if labels.is_empty() || req.all_axes => Ok(None),
        None => Err(InputError::ChooseGyro {
            path: path.to_path_buf(),
            labels: labels.to_vec(),
        }),
        Some(g) if labels.iter().any(|l| l == g) => Ok(Some(g.to_string())),
        Some(g) => Err(InputError::NoSuchGyro {
            path: path.to_path_buf(),
            gyro: g.to_string(),
            labels: labels.to_vec(),
        }),
    }
}
