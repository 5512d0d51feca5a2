//! The one recording reader ([`sagnac::recording::reader`]) and its pull API:
//! * one gyro's raw batches come out the same whatever the recording's chunk
//!   boundaries and however the file arrives (reads of 1 to 97 bytes), equal to
//!   the `/gyro/raw` messages of a full decode, the other channels counted and
//!   skipped;
//! * the daemon's replay and `analyze` read identical samples through it: the
//!   batches the replay source sends, gap-filled, are the counts `analyze`
//!   pushes into its pipeline, and both equal what was recorded;
//! * a recording of several gyros yields each gyro's batches under its label.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sagnac::daemon::batch::SourceBatch;
use sagnac::daemon::queue::QueueBound;
use sagnac::daemon::replay::ReplayConfig;
use sagnac::daemon::telemetry::Telemetry;
use sagnac::input::frame::{DecoderConfig, FilledSeries, Single};
use sagnac::pipeline::PipelineConfig;
use sagnac::recording::messages::{Gap, RawBatch, SinkMessage};
use sagnac::recording::reader::{
    RawReader, RecordingReader, Selection, read_recording, recover_recording,
};
use sagnac::recording::writer::{Recorder, RecorderConfig};

use crate::support::sink;

const DT_NS: u64 = 1_000_000;

/// `n` contiguous raw batches of random lengths (some empty), with gaps inside
/// them (never after the last sample), interleaved with other channels.
fn stream(seed: u64, n: usize) -> Vec<SinkMessage> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut seq = 5_000u64;
    let mut out = Vec::new();
    for i in 0..n {
        let len = if i % 17 == 5 {
            0
        } else {
            rng.random_range(1..400)
        };
        let counts: Vec<i64> = (0..len).map(|_| rng.random_range(-40..=40)).collect();
        let mut gaps = Vec::new();
        if len > 2 && rng.random_bool(0.4) {
            let index = rng.random_range(1..len as u64);
            gaps.push(Gap {
                index,
                lost: rng.random_range(1..6),
            });
        }
        let periods = len as u64 + gaps.iter().map(|g| g.lost).sum::<u64>();
        let b = RawBatch {
            t0_ns: 1_800_000_000_000_000_000 + (seq - 5_000) * DT_NS,
            dt_ns: DT_NS,
            seq0: seq,
            counts,
            gaps,
            temp_c: Some(24.5),
            status: 0,
        };
        seq += periods;
        out.push(SinkMessage::Raw(b));
        out.push(SinkMessage::Clean(sink::rate_batch(&mut rng, i as u64, 50)));
        if i % 5 == 0 {
            out.push(SinkMessage::Event(sink::event(&mut rng, i as u64)));
        }
    }
    out
}

fn raws(msgs: &[SinkMessage]) -> Vec<RawBatch> {
    msgs.iter()
        .filter_map(|m| match m {
            SinkMessage::Raw(b) => Some(b.clone()),
            _ => None,
        })
        .collect()
}

/// Record `msgs` in `dir`, flushing (closing a chunk) every `every` messages.
fn record(dir: &Path, msgs: &[SinkMessage], every: usize) -> PathBuf {
    let cfg = RecorderConfig {
        record_dir: dir.to_path_buf(),
        flush_interval_s: 600.0,
        queue_capacity: 64,
        chunk_size: 1024 * 1024,
        zstd_level: 0,
    };
    let start =
        SystemTime::UNIX_EPOCH + Duration::from_secs(1_800_000_000 + every.min(1_000_000) as u64);
    let rec = Recorder::start_at(&cfg, start).unwrap();
    for (i, m) in msgs.iter().enumerate() {
        rec.send(m.clone()).unwrap();
        if (i + 1) % every == 0 {
            rec.flush().unwrap();
        }
    }
    rec.finish().unwrap().path
}

/// A reader that hands out the bytes in pieces of 1 to 97 bytes.
struct Trickle<'a> {
    data: &'a [u8],
    rng: ChaCha8Rng,
}

impl Read for Trickle<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self
            .rng
            .random_range(1..98)
            .min(buf.len())
            .min(self.data.len());
        buf[..n].copy_from_slice(&self.data[..n]);
        self.data = &self.data[n..];
        Ok(n)
    }
}

fn pull_all<R: Read>(mut r: RawReader<R>) -> Vec<RawBatch> {
    let mut v = Vec::new();
    while let Some(b) = r.next_batch().unwrap() {
        v.push(b);
    }
    assert!(r.report().break_at.is_none());
    v
}

#[test]
fn the_pull_api_is_invariant_to_chunks_and_read_sizes() {
    let dir = tempfile::tempdir().unwrap();
    let sent = stream(41, 300);
    let want = raws(&sent);
    assert_eq!(want.len(), 300);
    let others = sent.len() - want.len();
    // one chunk per message, a few per chunk, many per chunk, one chunk in all
    for every in [1usize, 7, 64, usize::MAX] {
        let path = record(dir.path(), &sent, every);
        let got = pull_all(RawReader::open(&path, None, true).unwrap());
        assert_eq!(got, want, "flush every {every}");
        let data = std::fs::read(&path).unwrap();
        let trickle = Trickle {
            data: &data,
            rng: ChaCha8Rng::seed_from_u64(every as u64),
        };
        let r = RawReader::from_reader(trickle, data.len() as u64, &path, None, true).unwrap();
        assert_eq!(pull_all(r), want, "flush every {every}, trickled");

        // the full decode holds the same raw batches; the raw reader decoded
        // nothing else and counted the rest
        let full = read_recording(&path).unwrap();
        let all: Vec<SinkMessage> = full.messages.into_iter().map(|m| m.message).collect();
        assert_eq!(raws(&all), want);
        let mut r = RawReader::open(&path, None, true).unwrap();
        while r.next_batch().unwrap().is_some() {}
        let rep = r.report();
        assert_eq!(
            (rep.messages, rep.unselected_messages, rep.foreign_messages),
            (300, others as u64, 0)
        );
        assert_eq!(rep.recovered_bytes, data.len() as u64);
        // Selection::All by pull equals the collected read
        let mut r = RecordingReader::open(&path, true)
            .unwrap()
            .select(Selection::All);
        let mut n = 0;
        while let Some(m) = r.next_message().unwrap() {
            assert_eq!(m.message, all[n]);
            n += 1;
        }
        assert_eq!(n, sent.len());
    }
}

#[test]
fn a_cut_recording_pulls_up_to_its_last_complete_chunk() {
    let dir = tempfile::tempdir().unwrap();
    let sent = stream(43, 120);
    let path = record(dir.path(), &sent, 10);
    let data = std::fs::read(&path).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &data[..data.len() * 2 / 3]).unwrap();
    let rec = recover_recording(&cut).unwrap();
    let recovered: Vec<SinkMessage> = rec.messages.into_iter().map(|m| m.message).collect();
    let mut r = RawReader::open(&cut, None, false).unwrap();
    let mut got = Vec::new();
    while let Some(b) = r.next_batch().unwrap() {
        got.push(b);
    }
    assert!(!got.is_empty() && got.len() < 120, "{}", got.len());
    assert_eq!(got, raws(&recovered));
    let b = r.report().break_at.clone().expect("a break");
    assert_eq!(Some(b.clone()), rec.break_at);
    assert!(b.reason.contains("cut.mcap"), "{}", b.reason);
    // strict: the same break is an error naming the file and the offset
    let mut r = RawReader::open(&cut, None, true).unwrap();
    let err = loop {
        match r.next_batch() {
            Ok(Some(_)) => continue,
            Ok(None) => panic!("a cut file read strictly must fail"),
            Err(e) => break e.to_string(),
        }
    };
    assert!(
        err.contains("cut.mcap") && err.contains(&format!("byte {}", b.offset)),
        "{err}"
    );
}

/// Gap-fill `(counts, gaps)` batches as the pipeline sees them.
fn filled(batches: impl IntoIterator<Item = (Vec<i64>, Vec<Gap>)>) -> Vec<i64> {
    let mut s = FilledSeries::default();
    for (counts, gaps) in batches {
        for (i, &c) in counts.iter().enumerate() {
            let lost: u64 = gaps
                .iter()
                .filter(|g| g.index == i as u64)
                .map(|g| g.lost)
                .sum();
            s.push(c, lost);
        }
    }
    s.counts
}

#[test]
fn replay_and_analyze_read_identical_samples() {
    let dir = tempfile::tempdir().unwrap();
    let sent = stream(47, 400);
    let path = record(dir.path(), &sent, 13);
    let recorded = raws(&sent);

    // the daemon's replay source, as fast as possible
    let telemetry = Telemetry::standalone().unwrap();
    let (tx, rx) = sagnac::daemon::batch::channel(QueueBound::Batches(4), &telemetry);
    let source = ReplayConfig {
        path: path.clone(),
        speed: 0.0,
        sample_rate_hz: 1000.0,
        limit_periods: None,
        decoder: DecoderConfig::default(),
    }
    .build()
    .unwrap();
    let (_trigger, shutdown) = sagnac::daemon::shutdown::channel();
    let t = telemetry.clone();
    let h = std::thread::spawn(move || source.run_blocking::<Single>(vec![(t, tx)], shutdown));
    let mut replayed: Vec<SourceBatch> = Vec::new();
    rx.for_each_blocking(|b| replayed.push(b));
    let report = h.join().unwrap().unwrap();
    let samples: usize = recorded.iter().map(|b| b.counts.len()).sum();
    assert_eq!(report.samples, samples as u64);
    // every recorded batch, as recorded (counts, gaps, sequence numbers, times)
    let replay_raw: Vec<_> = replayed
        .iter()
        .filter(|b| !b.counts.is_empty() || !b.gaps.is_empty())
        .map(|b| (b.seq0, b.t0_ns, b.counts.clone(), b.gaps.clone()))
        .collect();
    let want: Vec<_> = recorded
        .iter()
        .filter(|b| !b.counts.is_empty() || !b.gaps.is_empty())
        .map(|b| (b.seq0, b.t0_ns, b.counts.clone(), b.gaps.clone()))
        .collect();
    assert_eq!(replay_raw, want);

    // analyze: the counts pushed into its pipeline, through the tap
    let mut analyzed: Vec<i64> = Vec::new();
    let mut tap = |t: &sagnac::pipeline::feed::TapBlock<'_>| {
        // (the final flush carries no counts)
        analyzed.extend_from_slice(t.counts.unwrap_or_default());
    };
    let input = sagnac::input::Input::open(&path, &Default::default()).unwrap();
    let fed = sagnac::pipeline::feed::run(
        &input,
        &PipelineConfig::counts(1000.0, 1.21),
        &mut |_, _| {},
        Some(&mut tap),
    )
    .unwrap();
    assert!(fed.report.break_at.is_none());
    let pipe = fed.pipeline;
    let replay_filled = filled(replayed.into_iter().map(|b| (b.counts, b.gaps)));
    let lost: u64 = recorded.iter().flat_map(|b| &b.gaps).map(|g| g.lost).sum();
    assert!(lost > 100, "{lost}");
    assert_eq!(replay_filled.len() as u64, samples as u64 + lost);
    assert_eq!(analyzed, replay_filled);
    assert_eq!(pipe.samples(), samples as u64 + lost);
}
