//! The pipeline stage driven directly (vector style: config -> build() -> a task
//! taking its input channel and outputs): batches with gaps go in, the report,
//! the metrics and the MCAP messages come out.
//!
//! * chunking invariance: the same samples split into source batches in two
//!   random ways give bit-identical final estimates and identical recordings
//!   (the stage pushes canonical blocks into the pipeline);
//! * the batch reference: the final estimates equal the shared `Pipeline` fed
//!   the gap-filled series in one go, to a relative 1e-9 (the pipeline's sums
//!   are not bit-invariant to its block split);
//! * gaps: `/gyro/raw` keeps the samples and gaps as delivered, the pipeline sees
//!   `lost + 1` periods per gap, every pulse is kept;
//! * one estimator update per interval plus the final one, each in the metrics;
//! * a warm-up: reported `modelled` while it settles, then the statistics
//!   restart once and it is `excluded`, while the channels go on whole.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sagnac::daemon::batch::{Delivery, SourceBatch};
use sagnac::daemon::process::{Outputs, ProcessConfig, ProcessReport};
use sagnac::daemon::queue::QueueBound;
use sagnac::daemon::telemetry::Telemetry;
use sagnac::input::frame::spread_increment;
use sagnac::model::estimate::Coefficient;
use sagnac::model::{GyroModel, Simulator};
use sagnac::pipeline::{Pipeline, PipelineConfig, PipelineOutput};
use sagnac::recording::messages::{Gap, SinkMessage};
use sagnac::recording::reader::read_recording;
use sagnac::recording::writer::{Recorder, RecorderConfig};

use crate::support::PAPER_GYRO;

const N: usize = 60_000;

/// Decoded samples (gaps folded as the decoder does) and the gap-filled series.
fn stream() -> (Vec<(i64, u64)>, Vec<i64>) {
    let model = GyroModel::load(Path::new(PAPER_GYRO)).unwrap();
    let mut truth = Vec::new();
    Simulator::new(&model, 4, None)
        .unwrap()
        .next_block(N, &mut truth);
    // Lose runs of samples: the next sample carries their pulses (cumulative counter).
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let (mut decoded, mut carry, mut lost) = (Vec::new(), 0i64, 0u64);
    for (i, &c) in truth.iter().enumerate() {
        if i > 0 && i + 1 < N && rng.random_bool(0.002) {
            carry += c;
            lost += 1;
            continue;
        }
        decoded.push((c + carry, lost));
        carry = 0;
        lost = 0;
    }
    let mut uniform = Vec::new();
    for &(c, l) in &decoded {
        uniform.extend(spread_increment(c, l as u32 + 1));
    }
    assert_eq!(uniform.len(), N);
    assert_eq!(uniform.iter().sum::<i64>(), truth.iter().sum::<i64>());
    (decoded, uniform)
}

fn batches(decoded: &[(i64, u64)], seed: u64) -> Vec<SourceBatch> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::new();
    let mut i = 0;
    let mut seq = 1000u64;
    while i < decoded.len() {
        let n = rng.random_range(1..3000).min(decoded.len() - i);
        let mut b = SourceBatch::new(Instant::now());
        b.seq0 = seq;
        b.t0_ns = 1_000_000_000 + (seq - 1000) * 1_000_000;
        for (k, &(c, lost)) in decoded[i..i + n].iter().enumerate() {
            if lost > 0 {
                b.gaps.push(Gap {
                    index: k as u64,
                    lost,
                });
            }
            b.counts.push(c);
            seq += lost + 1;
        }
        b.temp_c = Some(25.0);
        b.status = Some(7);
        out.push(b);
        i += n;
    }
    out
}

fn run(batches: Vec<SourceBatch>, dir: &Path) -> (ProcessReport, Telemetry, std::path::PathBuf) {
    let cfg = ProcessConfig {
        pipeline: PipelineConfig::counts(1000.0, 1.21),
        interval_s: 7.0,
        batch_samples: 1000,
        delivery: Delivery::Lossless,
        update_budget: None,
    };
    run_with(cfg, batches, dir)
}

fn run_with(
    cfg: ProcessConfig,
    batches: Vec<SourceBatch>,
    dir: &Path,
) -> (ProcessReport, Telemetry, std::path::PathBuf) {
    let processor = cfg.build().unwrap();
    let recorder = Recorder::start(&RecorderConfig {
        record_dir: dir.to_path_buf(),
        ..RecorderConfig::default()
    })
    .unwrap();
    let telemetry = Telemetry::standalone().unwrap();
    let (mut tx, rx) = sagnac::daemon::batch::channel(QueueBound::Batches(4), &telemetry);
    let outputs = Outputs {
        recorder: Some(recorder.sender()),
        telemetry: telemetry.clone(),
        stop: None,
        status: None,
    };
    let h = std::thread::spawn(move || processor.run(rx, outputs));
    for b in batches {
        tx.blocking_send(b).unwrap();
    }
    drop(tx);
    let report = h.join().unwrap();
    let path = recorder.finish().unwrap().path;
    (report, telemetry, path)
}

#[test]
fn the_stage_is_chunking_invariant_keeps_gaps_and_matches_the_pipeline() {
    let (decoded, uniform) = stream();
    let lost: u64 = decoded.iter().map(|d| d.1).sum();
    assert!(lost > 50);
    let (d1, d2) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let (r1, t1, p1) = run(batches(&decoded, 1), d1.path());
    let (r2, _, p2) = run(batches(&decoded, 2), d2.path());

    assert_eq!(
        r1.analysis, r2.analysis,
        "bit-identical whatever the batching"
    );
    assert_eq!(
        (r1.samples, r1.periods, r1.lost),
        (decoded.len() as u64, N as u64, lost)
    );
    // 60 000 samples at 7 s per update: 8 updates, plus the final one
    assert_eq!(r1.updates, 9);
    assert_eq!(t1.estimator_updates.get(), 9);

    // The batch reference: one push of the whole gap-filled series, with the
    // filled samples marked.
    let mut series = sagnac::input::frame::FilledSeries::default();
    for &(c, l) in &decoded {
        series.push(c, l);
    }
    assert_eq!(series.counts, uniform);
    let mut p = Pipeline::new(&PipelineConfig::counts(1000.0, 1.21)).unwrap();
    let mut out = PipelineOutput::default();
    p.push_counts_filled(&series.counts, &series.filled, &mut out);
    p.finish(&mut out);
    let a = p.analysis();
    let pairs = [
        (
            a.estimates.quantization_arcsec,
            r1.analysis.estimates.quantization_arcsec,
        ),
        (a.estimates.arw_dpsh, r1.analysis.estimates.arw_dpsh),
        (
            a.estimates.bias_instability_dph,
            r1.analysis.estimates.bias_instability_dph,
        ),
    ];
    for (x, y) in pairs {
        let flat = |c: Coefficient| {
            [
                c.value,
                c.ci95.map(|c| c[0]),
                c.ci95.map(|c| c[1]),
                c.upper95,
            ]
        };
        for (u, v) in flat(x).into_iter().zip(flat(y)) {
            match (u, v) {
                (Some(u), Some(v)) => assert!((u - v).abs() <= 1e-9 * u.abs(), "{x:?} vs {y:?}"),
                (None, None) => {}
                _ => panic!("{x:?} vs {y:?}"),
            }
        }
    }
    assert_eq!(a.samples, N as u64);

    // The recordings: the same messages; /gyro/raw holds the samples and gaps as
    // delivered, clean/noise one value per period, times on the sample clock.
    let m1 = read_recording(&p1).unwrap().messages;
    let m2 = read_recording(&p2).unwrap().messages;
    // per channel (the interleaving of channels follows the batching)
    let by_topic = |ms: &[sagnac::recording::reader::RecordedMessage]| {
        let mut t: BTreeMap<&'static str, Vec<SinkMessage>> = BTreeMap::new();
        for m in ms {
            if !matches!(m.message, SinkMessage::Event(_)) {
                t.entry(m.message.topic().name())
                    .or_default()
                    .push(m.message.clone());
            }
        }
        t
    };
    let (t1m, t2m) = (by_topic(&m1), by_topic(&m2));
    assert_eq!(
        t1m.keys().collect::<Vec<_>>(),
        t2m.keys().collect::<Vec<_>>()
    );
    for (k, v) in &t1m {
        assert!(v == &t2m[k], "{k} differs between the batchings");
    }
    let mut counts = Vec::new();
    let mut per_topic: BTreeMap<&str, usize> = BTreeMap::new();
    let mut next_seq = 1000u64;
    for m in &m1 {
        match &m.message {
            SinkMessage::Raw(r) => {
                assert_eq!(r.seq0, next_seq, "raw batches tile the sequence");
                assert_eq!(r.t0_ns, 1_000_000_000 + (r.seq0 - 1000) * 1_000_000);
                next_seq += r.counts.len() as u64 + r.gaps.iter().map(|g| g.lost).sum::<u64>();
                let mut gi = r.gaps.iter().peekable();
                for (k, &c) in r.counts.iter().enumerate() {
                    let l = gi.next_if(|g| g.index == k as u64).map_or(0, |g| g.lost);
                    counts.push((c, l));
                }
            }
            SinkMessage::Clean(c) | SinkMessage::Noise(c) => {
                *per_topic.entry(m.message.topic().name()).or_default() += c.values.len()
            }
            _ => {}
        }
    }
    assert_eq!(counts, decoded);
    assert_eq!(per_topic["/gyro/clean"], N);
    assert_eq!(per_topic["/gyro/noise"], N);
    let text = t1.metrics.encode();
    assert!(
        text.contains("sagnac_qn_arcseconds{bound=\"estimate\",gyro=\"gyro\"}"),
        "{text}"
    );
    assert!(
        text.contains("sagnac_temperature_celsius{gyro=\"gyro\"} 25\n"),
        "{text}"
    );
}

/// A 3 deg/h warm-up settling with a 60 s time constant, 15 min at 200 Hz,
/// every estimator update published (no update budget): the updates report
/// it `modelled` while it settles (from the first assessment on, a minute of
/// samples in), then, once 5 time constants (at the upper
/// end of tau's interval) have passed, the statistics restart once (at an
/// assessment, a whole minute of samples) and every later update reports it
/// `excluded` with the seconds left out, and holds only the samples after
/// them. The clean and noise channels and the summary windows carry every
/// sample exactly once across the restart; the warm-up gauges end at 0
/// active with its amplitude and time constant; no glitch is counted.
#[test]
fn a_settled_warmup_restarts_the_statistics_once_and_the_channels_go_on() {
    const RATE: u64 = 200;
    const N: u64 = 15 * 60 * RATE;
    let model = GyroModel::from_toml_str(
        "[gyro]\nsample_rate_hz = 200.0\npulse_arcsec = 1.21\ninput_rate_dph = 10.0\n\
         [noise]\nquantization_arcsec = 0.4\narw_dpsh = 0.01\nbias_instability_dph = 0.005\n\
         [noise.warmup]\namplitude_dph = 3.0\ntau_s = 60.0\n",
        "warm-up model",
    )
    .unwrap();
    let mut counts = Vec::new();
    Simulator::new(&model, 1, None)
        .unwrap()
        .next_block(N as usize, &mut counts);
    let decoded: Vec<(i64, u64)> = counts.iter().map(|&c| (c, 0)).collect();
    let cfg = ProcessConfig {
        pipeline: PipelineConfig::counts(RATE as f64, 1.21),
        interval_s: 30.0,
        batch_samples: 1000,
        delivery: Delivery::Lossless,
        update_budget: None,
    };
    let dir = tempfile::tempdir().unwrap();
    let (report, telemetry, path) = run_with(cfg, batches(&decoded, 3), dir.path());
    assert_eq!(report.periods, N);
    // 30 updates plus the final one, every one published
    assert_eq!(report.updates, 31);
    let msgs = read_recording(&path).unwrap().messages;
    let mut handled = Vec::new();
    let (mut clean, mut noise, mut summary) = (0, 0, 0);
    for m in &msgs {
        match &m.message {
            SinkMessage::Estimates(e) => {
                let w = e.data_quality.as_ref().and_then(|d| d.warmup.as_ref());
                handled.push((e.samples, w.map(|w| (w.handled.clone(), w.excluded_s))));
            }
            SinkMessage::Clean(c) => clean += c.values.len() as u64,
            SinkMessage::Noise(c) => noise += c.values.len() as u64,
            SinkMessage::Summary(s) => summary += s.samples,
            _ => {}
        }
    }
    assert_eq!((clean, noise, summary), (N, N, N), "every sample once");
    let first_excluded = handled
        .iter()
        .position(|(_, w)| w.as_ref().is_some_and(|w| w.0 == "excluded"))
        .unwrap_or_else(|| panic!("never excluded: {handled:?}"));
    assert!(
        handled[..first_excluded]
            .iter()
            .any(|(_, w)| w.as_ref().is_some_and(|w| w.0 == "modelled")),
        "modelled before the restart: {handled:?}"
    );
    let excluded_s = handled[first_excluded].1.as_ref().unwrap().1;
    assert!(
        excluded_s >= 300.0 && excluded_s % 60.0 == 0.0 && excluded_s <= 600.0,
        "{handled:?}"
    );
    // `samples` are those through the statistics (the glitch filter holds a
    // window of 4096): they grow, start again after the restart, and end
    // with every sample after it
    let base = (excluded_s as u64) * RATE;
    for (i, (samples, w)) in handled.iter().enumerate() {
        if i < first_excluded {
            assert!(w.as_ref().is_none_or(|w| w.0 == "modelled"), "{handled:?}");
        } else {
            assert_eq!(
                w,
                &Some(("excluded".to_string(), excluded_s)),
                "{handled:?}"
            );
        }
        if i > 0 && i != first_excluded {
            assert!(*samples >= handled[i - 1].0, "update {i}: {handled:?}");
        }
    }
    assert!(handled[first_excluded].0 < handled[first_excluded - 1].0);
    assert!(handled[first_excluded - 1].0 <= base);
    assert_eq!(handled.last().unwrap().0, N - base);
    assert_eq!(report.analysis.samples, N - base);
    let dq = report.analysis.data_quality.as_ref().unwrap();
    assert_eq!(dq.outliers.count, 0);
    let text = telemetry.metrics.encode();
    let get = |name: &str| {
        let key = format!("{name}{{gyro=\"gyro\"}} ");
        text.lines()
            .find_map(|l| l.strip_prefix(&key))
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or_else(|| panic!("{name} in\n{text}"))
    };
    assert_eq!(get("sagnac_warmup_active"), 0.0);
    let w = dq.warmup.as_ref().unwrap();
    assert_eq!(get("sagnac_warmup_amplitude_dph"), w.amplitude_dph.value);
    assert_eq!(get("sagnac_warmup_tau_seconds"), w.tau_s.value);
    assert!((2.0..4.5).contains(&w.amplitude_dph.value), "{w:?}");
    assert_eq!(get("sagnac_outliers_total"), 0.0);
}
