//! ROS 2 bags as an input: an MCAP file of profile `ros2`, or a rosbag2
//! directory (`metadata.yaml` and its `.mcap` files, read as one), with
//! `sensor_msgs/msg/Imu` messages in CDR.
//!
//! Opening reads the bag once for its topics and the `header.stamp`s of the
//! Imu topic read (`--topic`, needed when there are several): the sample
//! rate, the messages out of order, the duplicates and the holes
//! ([`timing`]). A stream then hands out one axis (`--gyro gyro_x`, ...,
//! `accel_z`; rad/s and m/s^2), or all six at once: sorted by stamp in a window as long as the latest message is late,
//! duplicates dropped, holes filled by linear interpolation and marked
//! filled, so the statistics leave them out.
//!
//! Layout: [`bag`] (the files), [`messages`] (reading them), [`imu`] (the
//! message and its schema), [`timing`] (the stamps).

use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub mod bag;
pub mod imu;
pub mod messages;
pub mod timing;

use super::{Block, InputError, MAX_GAP_SAMPLES, Meta, Request, Unit, pick_gyro};
use crate::recording::meta::check_flag;
use bag::{Bag, CONVERT_HINT};
use messages::{ImuMessages, TopicInfo};
use timing::{Place, Placer, Timing};

/// The axes of an Imu message, as labels (`--gyro`).
pub const AXES: [&str; 6] = [
    "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z",
];
/// The gyroscope's axes come first.
pub const GYRO_AXES: usize = 3;

/// The unit of an axis's samples: rad/s for the gyroscope, m/s^2 for the
/// accelerometer.
pub fn axis_unit(label: &str) -> Unit {
    match AXES.iter().position(|a| *a == label) {
        Some(i) if i >= GYRO_AXES => Unit::Mps2,
        _ => Unit::RadS,
    }
}
/// Samples per block handed out.
const BLOCK: usize = 1 << 14;
/// How far a flag may be from the rate of the stamps.
const RATE_REL_TOL: f64 = 1e-3;

/// Errors of a bag; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum Ros2Error {
    #[error("{}: cannot read", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: a ROS 2 bag in sqlite3 storage: sagnac reads MCAP bags; {CONVERT_HINT}", path.display())]
    Sqlite { path: PathBuf },
    #[error("{}: a directory, but not a rosbag2 bag (no metadata.yaml)", path.display())]
    NotABag { path: PathBuf },
    #[error("{}: {reason}", path.display())]
    Metadata { path: PathBuf, reason: String },
    #[error("{}: not an MCAP file (bad magic in the first 8 bytes)", path.display())]
    NotMcap { path: PathBuf },
    #[error("{}: unreadable after {offset} bytes: {reason}", path.display())]
    Broken {
        path: PathBuf,
        offset: u64,
        reason: String,
    },
    #[error("{}: schema {name}: {reason}", path.display())]
    Schema {
        path: PathBuf,
        name: String,
        reason: String,
    },
    #[error("{}: message #{sequence} on {topic}: {reason}", path.display())]
    Message {
        path: PathBuf,
        topic: String,
        sequence: u32,
        reason: String,
    },
    #[error("{}: {}", path.display(), topic_choice(topics))]
    ChooseTopic {
        path: PathBuf,
        topics: BTreeMap<String, TopicInfo>,
    },
    #[error("--topic {topic}: {}: {}", path.display(), no_such_topic(topic, topics))]
    NoSuchTopic {
        path: PathBuf,
        topic: String,
        topics: BTreeMap<String, TopicInfo>,
    },
    #[error("{}: message #{index} on {topic} (stamp {stamp_ns} ns): {axis} is not finite ({value})", path.display())]
    NonFinite {
        path: PathBuf,
        topic: String,
        index: u64,
        stamp_ns: i64,
        axis: &'static str,
        value: f64,
    },
    #[error("{}: topic {topic} has {messages} messages but fewer than two distinct stamps: no sample rate", path.display())]
    NoTiming {
        path: PathBuf,
        topic: String,
        messages: u64,
    },
}

impl Ros2Error {
    pub fn io(path: &Path, source: std::io::Error) -> Ros2Error {
        Ros2Error::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}

fn list(topics: &BTreeMap<String, TopicInfo>, imu: bool) -> String {
    let l: Vec<String> = topics
        .iter()
        .filter(|(_, t)| t.imu == imu)
        .map(|(n, t)| format!("{n} ({})", t.type_name))
        .collect();
    if l.is_empty() {
        "none".into()
    } else {
        l.join(", ")
    }
}

fn topic_choice(topics: &BTreeMap<String, TopicInfo>) -> String {
    if topics.values().any(|t| t.imu) {
        format!(
            "holds several sensor_msgs/msg/Imu topics: choose one with --topic ({})",
            list(topics, true)
        )
    } else {
        format!(
            "holds no sensor_msgs/msg/Imu topic in CDR (its topics: {})",
            list(topics, false)
        )
    }
}

fn no_such_topic(topic: &str, topics: &BTreeMap<String, TopicInfo>) -> String {
    match topics.get(topic) {
        Some(t) => format!(
            "is {}, not sensor_msgs/msg/Imu in CDR (Imu topics: {})",
            t.type_name,
            list(topics, true)
        ),
        None => format!("no such topic (Imu topics: {})", list(topics, true)),
    }
}

/// What opening a bag found: the topic read and its timing.
#[derive(Debug, Clone, PartialEq)]
pub struct BagMeta {
    pub topic: String,
    pub timing: Timing,
}

/// Settle the topic, the axis and the sample rate (see [`super::Input::open`]).
pub(super) fn open(path: &Path, req: &Request, meta: &mut Meta) -> Result<(), InputError> {
    for (flag, given) in [
        ("--column", req.column.is_some()),
        ("--pulse-arcsec", req.pulse_arcsec.is_some()),
    ] {
        if given {
            return Err(super::not_applicable(
                flag,
                path,
                meta.format,
                ", whose samples are rates in rad/s",
            ));
        }
    }
    if req.unit.is_some_and(|u| u != Unit::RadS) {
        return Err(super::not_applicable(
            "--unit",
            path,
            meta.format,
            ", whose gyro samples are in rad/s",
        ));
    }
    let bag = Bag::open(path)?;
    let mut msgs = ImuMessages::new(bag, req.topic.clone());
    let mut stamps: HashMap<Arc<str>, Vec<i64>> = HashMap::new();
    while let Some((topic, s)) = msgs.next_message()? {
        stamps.entry(topic).or_default().push(s.stamp_ns);
    }
    let topic = pick_topic(path, req.topic.as_deref(), &msgs.topics)?;
    let st = stamps.remove(topic.as_str()).unwrap_or_default();
    let timing = Timing::from_stamps(&st).ok_or_else(|| Ros2Error::NoTiming {
        path: path.to_path_buf(),
        topic: topic.clone(),
        messages: st.len() as u64,
    })?;
    meta.gyros = AXES.iter().map(|s| s.to_string()).collect();
    meta.gyro = pick_gyro(path, &meta.gyros, req)?;
    meta.unit = axis_unit(meta.gyro.as_deref().unwrap_or(AXES[0]));
    meta.integral = false;
    meta.len_hint = Some(timing.samples);
    let origin = "in the bag's header stamps";
    meta.sample_rate_hz = check_flag(
        "--sample-rate-hz",
        req.sample_rate_hz,
        Some(timing.sample_rate_hz),
        path,
        origin,
        RATE_REL_TOL,
    )?;
    meta.origin = format!("the sample rate {origin} (topic {topic})");
    meta.bag = Some(BagMeta { topic, timing });
    Ok(())
}

/// The Imu topic to read: `--topic`, or the only one.
fn pick_topic(
    path: &Path,
    want: Option<&str>,
    topics: &BTreeMap<String, TopicInfo>,
) -> Result<String, Ros2Error> {
    if let Some(w) = want {
        return match topics.get(w) {
            Some(t) if t.imu => Ok(w.to_string()),
            _ => Err(Ros2Error::NoSuchTopic {
                path: path.to_path_buf(),
                topic: w.to_string(),
                topics: topics.clone(),
            }),
        };
    }
    let mut imu = topics.iter().filter(|(_, t)| t.imu);
    match (imu.next(), imu.next()) {
        (Some((name, _)), None) => Ok(name.clone()),
        _ => Err(Ros2Error::ChooseTopic {
            path: path.to_path_buf(),
            topics: topics.clone(),
        }),
    }
}

/// A message waiting in the sorting window, ordered by stamp then arrival.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pending {
    stamp_ns: i64,
    arrival: u64,
    axes: [f64; 6],
}
impl Eq for Pending {}
impl Ord for Pending {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        (self.stamp_ns, self.arrival).cmp(&(other.stamp_ns, other.arrival))
    }
}
impl PartialOrd for Pending {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// What a pass over a bag's topic met.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct StampReport {
    /// The topic read.
    pub topic: String,
    /// Its messages.
    pub messages: u64,
    /// Messages that came after a later stamp (sorted back into place).
    pub out_of_order: u64,
    /// Messages dropped: less than half a period after the one before.
    pub duplicates: u64,
    /// Holes between stamps, and the samples missing in them (filled).
    pub gaps: u64,
    pub lost_samples: u64,
}

/// Axes of a bag's topic, sorted, deduplicated and gap-filled: one block
/// per axis read, all with the same samples filled.
pub struct Ros2Stream {
    path: PathBuf,
    msgs: ImuMessages,
    /// Indices into [`AXES`] of the axes handed out.
    axes: Vec<usize>,
    max_lateness_ns: i64,
    window: BinaryHeap<Reverse<Pending>>,
    newest: i64,
    arrivals: u64,
    placer: Placer,
    last: Option<[f64; 6]>,
    ended: bool,
    report: StampReport,
}

impl Ros2Stream {
    /// The axis `meta.gyro` of the bag, or every axis when none is chosen.
    pub fn open(path: &Path, meta: &Meta) -> Result<Ros2Stream, InputError> {
        let bm = meta
            .bag
            .as_ref()
            .expect("a bag's meta has its topic and timing");
        let axes = match &meta.gyro {
            Some(g) => vec![
                AXES.iter()
                    .position(|a| a == g)
                    .expect("one of the bag's axes"),
            ],
            None => (0..AXES.len()).collect(),
        };
        Ok(Ros2Stream {
            path: path.to_path_buf(),
            msgs: ImuMessages::new(Bag::open(path)?, Some(bm.topic.clone())),
            axes,
            max_lateness_ns: bm.timing.max_lateness_ns,
            window: BinaryHeap::new(),
            newest: i64::MIN,
            arrivals: 0,
            placer: Placer::new(bm.timing.period_ns),
            last: None,
            ended: false,
            report: StampReport {
                topic: bm.topic.clone(),
                ..StampReport::default()
            },
        })
    }

    /// What the pass met so far.
    pub fn report(&self) -> &StampReport {
        &self.report
    }

    /// The labels of the axes handed out, in the order of the blocks.
    pub fn labels(&self) -> Vec<&'static str> {
        self.axes.iter().map(|&a| AXES[a]).collect()
    }

    /// The next block of the one axis read; `false` once every message has
    /// been handed out.
    pub fn next_block(&mut self, block: &mut Block) -> Result<bool, InputError> {
        self.next_blocks(std::slice::from_mut(block))
    }

    /// The next block of each axis read (cleared first); `false` once every
    /// message has been handed out.
    pub fn next_blocks(&mut self, blocks: &mut [Block]) -> Result<bool, InputError> {
        assert_eq!(blocks.len(), self.axes.len(), "one block per axis read");
        blocks.iter_mut().for_each(Block::clear);
        while blocks[0].len() < BLOCK {
            if let Some(Reverse(p)) = self.window.peek()
                && (self.ended || p.stamp_ns <= self.newest.saturating_sub(self.max_lateness_ns))
            {
                let p = *p;
                self.window.pop();
                self.emit(p, blocks)?;
                continue;
            }
            if self.ended {
                break;
            }
            match self.msgs.next_message()? {
                None => self.ended = true,
                Some((_, s)) => {
                    if let Some(&a) = self.axes.iter().find(|&&a| !s.axes[a].is_finite()) {
                        return Err(Ros2Error::NonFinite {
                            path: self.path.clone(),
                            topic: self.report.topic.clone(),
                            index: self.report.messages,
                            stamp_ns: s.stamp_ns,
                            axis: AXES[a],
                            value: s.axes[a],
                        }
                        .into());
                    }
                    self.report.messages += 1;
                    if s.stamp_ns < self.newest {
                        self.report.out_of_order += 1;
                    }
                    self.newest = self.newest.max(s.stamp_ns);
                    self.window.push(Reverse(Pending {
                        stamp_ns: s.stamp_ns,
                        arrival: self.arrivals,
                        axes: s.axes,
                    }));
                    self.arrivals += 1;
                }
            }
        }
        Ok(!blocks[0].is_empty())
    }

    /// Place one sorted message: dropped, or after the samples its hole needs.
    fn emit(&mut self, p: Pending, blocks: &mut [Block]) -> Result<(), InputError> {
        match self.placer.place(p.stamp_ns) {
            Place::Duplicate => {
                self.report.duplicates += 1;
                return Ok(());
            }
            Place::After(k) if k > 1 => {
                let lost = k - 1;
                if lost > MAX_GAP_SAMPLES {
                    return Err(InputError::ImplausibleGap {
                        path: self.path.clone(),
                        t0_ns: p.stamp_ns.max(0) as u64,
                        lost,
                    });
                }
                let v0 = self.last.expect("a hole comes after a sample");
                for (block, &a) in blocks.iter_mut().zip(&self.axes) {
                    let start = block.values.len();
                    let (from, to) = (v0[a], p.axes[a]);
                    block
                        .values
                        .extend((1..k).map(|i| from + (to - from) * i as f64 / k as f64));
                    block.filled.push(start..block.values.len());
                    block.gaps += 1;
                    block.lost_samples += lost;
                }
                self.report.gaps += 1;
                self.report.lost_samples += lost;
            }
            _ => {}
        }
        for (block, &a) in blocks.iter_mut().zip(&self.axes) {
            block.values.push(p.axes[a]);
        }
        self.last = Some(p.axes);
        Ok(())
    }
}
