//! MCAP recording end to end: file naming, exact read-back, recovery of files cut
//! at every byte, a real `kill -9` of a recording process, back-pressure, and an
//! independent reader (scripts/read-mcap.py, Python `mcap`) agreeing with what
//! was written.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant, SystemTime};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sagnac::recording::messages::{RateBatch, SinkMessage, Topic};
use sagnac::recording::reader::{
    ReadError, read_recording, read_recording_bytes, recover_recording, recover_recording_bytes,
    scan_recording,
};
use sagnac::recording::writer::{
    RecordError, Recorder, RecorderConfig, format_utc_compact, recording_file_name,
};

use crate::support::sink;

fn config(dir: &Path) -> RecorderConfig {
    RecorderConfig {
        record_dir: dir.to_path_buf(),
        // Long enough that only explicit flushes close chunks in these tests.
        flush_interval_s: 600.0,
        queue_capacity: 64,
        chunk_size: 1024 * 1024,
        zstd_level: 0,
    }
}

fn at(secs: u64) -> SystemTime {
    SystemTime::UNIX_EPOCH + Duration::from_secs(secs)
}

#[test]
fn utc_names_match_python_datetime() {
    // Reference: python3 datetime.fromisoformat(s).replace(tzinfo=utc).timestamp().
    for (secs, s) in [
        (1_795_291_381, "20261121T200301Z"),
        (0, "19700101T000000Z"),
        (951_868_799, "20000229T235959Z"),
        (951_868_800, "20000301T000000Z"),
        (4_107_499_200, "21000228T120000Z"),
        (4_107_542_400, "21000301T000000Z"),
        (94_694_399, "19721231T235959Z"),
        (2_147_483_648, "20380119T031408Z"),
        (13_574_585_228, "24000229T060708Z"),
        (253_402_300_799, "99991231T235959Z"),
    ] {
        assert_eq!(format_utc_compact(at(secs)).unwrap(), s, "{secs}");
    }
    // Sub-second parts are truncated.
    let t = at(1_795_291_381) + Duration::from_nanos(999_999_999);
    assert_eq!(
        recording_file_name(t).unwrap(),
        "sagnac-20261121T200301Z.mcap"
    );
    assert!(matches!(
        format_utc_compact(SystemTime::UNIX_EPOCH - Duration::from_secs(1)),
        Err(RecordError::ClockBeforeEpoch)
    ));
}

#[test]
fn utc_dates_advance_one_day_at_a_time() {
    // Every day from 1970 to 2600 follows the previous one under the Gregorian
    // rules (leap years: divisible by 4, except centuries not divisible by 400).
    let leap = |y: u32| y.is_multiple_of(4) && (!y.is_multiple_of(100) || y.is_multiple_of(400));
    let days_in = |y: u32, m: u32| match m {
        2 if leap(y) => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    };
    let (mut y, mut m, mut d) = (1970u32, 1u32, 1u32);
    for day in 0..(630 * 366) as u64 {
        let s = format_utc_compact(at(day * 86_400 + 86_399)).unwrap();
        assert_eq!(s, format!("{y:04}{m:02}{d:02}T235959Z"), "day {day}");
        d += 1;
        if d > days_in(y, m) {
            d = 1;
            m += 1;
            if m > 12 {
                m = 1;
                y += 1;
            }
        }
    }
}

#[test]
fn config_is_validated() {
    let dir = tempfile::tempdir().unwrap();
    let ok = config(dir.path());
    assert!(ok.validate().is_ok());
    assert!(RecorderConfig::default().validate().is_ok());
    for bad in [
        RecorderConfig {
            flush_interval_s: 0.0,
            ..ok.clone()
        },
        RecorderConfig {
            flush_interval_s: f64::NAN,
            ..ok.clone()
        },
        RecorderConfig {
            queue_capacity: 0,
            ..ok.clone()
        },
        RecorderConfig {
            chunk_size: 10,
            ..ok.clone()
        },
        RecorderConfig {
            zstd_level: 30,
            ..ok.clone()
        },
    ] {
        let err = Recorder::start(&bad).err().expect("refused");
        assert!(matches!(err, RecordError::Config { .. }), "{err}");
    }
    let parsed: RecorderConfig =
        toml::from_str("record_dir = \"runs\"\nflush_interval_s = 1.5\n").unwrap();
    assert_eq!(parsed.flush_interval_s, 1.5);
    assert_eq!(
        parsed.queue_capacity,
        RecorderConfig::default().queue_capacity
    );
    assert!(toml::from_str::<RecorderConfig>("flush_interval = 1.5\n").is_err());
}

#[test]
fn recording_reads_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let sent = sink::stream(21, 600);
    let rec = Recorder::start_at(&config(dir.path()), at(1_795_291_381)).unwrap();
    assert_eq!(rec.path(), dir.path().join("sagnac-20261121T200301Z.mcap"));
    // A second run in the same second gets a suffix instead of overwriting.
    let rec2 = Recorder::start_at(&config(dir.path()), at(1_795_291_381)).unwrap();
    assert_eq!(
        rec2.path(),
        dir.path().join("sagnac-20261121T200301Z-1.mcap")
    );
    let empty = rec2.finish().unwrap();
    assert_eq!(empty.messages(), 0);
    assert!(read_recording(&empty.path).unwrap().messages.is_empty());

    for (i, m) in sent.iter().enumerate() {
        rec.send(m.clone()).unwrap();
        if i % 100 == 99 {
            rec.flush().unwrap();
        }
    }
    let summary = rec.finish().unwrap();
    assert_eq!(summary.messages(), 600);
    let raw = sent
        .iter()
        .filter(|m| matches!(m, SinkMessage::Raw(_)))
        .count() as u64;
    assert_eq!(summary.messages_per_topic["/gyro/raw"], raw);
    let file_len = std::fs::metadata(&summary.path).unwrap().len();
    assert_eq!(summary.bytes, file_len);

    let read = read_recording(&summary.path).unwrap();
    assert_eq!(read.file_len, file_len);
    assert_eq!(read.foreign_messages, 0);
    let got: Vec<SinkMessage> = read.messages.iter().map(|r| r.message.clone()).collect();
    // exact, with the rates on the recorder's 1e-3 deg/h grid
    assert_eq!(got, sink::recorded(&sent));
    // Log and publish time are the sample time; sequences count per channel.
    let mut seq = std::collections::BTreeMap::new();
    for r in &read.messages {
        assert_eq!(r.log_time_ns, r.message.time_ns());
        assert_eq!(r.publish_time_ns, r.message.time_ns());
        let s = seq.entry(r.message.topic()).or_insert(0u32);
        assert_eq!(r.sequence, *s);
        *s += 1;
    }
    // The complete file recovers whole.
    let rec = recover_recording(&summary.path).unwrap();
    assert!(rec.is_complete(), "{:?}", rec.break_at);
    assert_eq!(rec.recovered_bytes, file_len);
    assert_eq!(rec.messages, read.messages);
    // The streaming scan sees the same messages.
    let mut n = 0;
    let report = scan_recording(&summary.path, true, &mut |m| {
        assert_eq!(m, read.messages[n]);
        n += 1;
    })
    .unwrap();
    assert_eq!((report.messages, n), (600, 600));
}

/// Writes `stream(seed, n)` with an explicit flush every `every` messages; returns
/// the file, the messages and (file size, messages so far) at each flush.
fn flushed_recording(
    dir: &Path,
    seed: u64,
    n: usize,
    every: usize,
) -> (PathBuf, Vec<SinkMessage>, Vec<(u64, usize)>) {
    let sent = sink::stream(seed, n);
    let rec = Recorder::start_at(&config(dir), at(1_000_000_000)).unwrap();
    let mut marks = vec![(rec.flush().unwrap(), 0)];
    for (i, m) in sent.iter().enumerate() {
        rec.send(m.clone()).unwrap();
        if (i + 1) % every == 0 {
            let bytes = rec.flush().unwrap();
            assert_eq!(bytes, rec.bytes_written());
            assert_eq!(
                bytes,
                std::fs::metadata(rec.path()).unwrap().len(),
                "flush reaches the OS"
            );
            marks.push((bytes, i + 1));
        }
    }
    let path = rec.finish().unwrap().path;
    // what the file holds: the messages with their rates on the 1e-3 deg/h grid
    (path, sink::recorded(&sent), marks)
}

#[test]
fn truncation_at_many_bytes_recovers_a_prefix() {
    let dir = tempfile::tempdir().unwrap();
    let (path, sent, marks) = flushed_recording(dir.path(), 22, 60, 7);
    let data = std::fs::read(&path).unwrap();
    let cut_path = dir.path().join("cut.mcap");
    let mut previous = 0;
    // Every byte up to the end of the second data chunk and around every chunk
    // boundary, every 7th byte elsewhere (a late cut costs ~2 ms of decoding).
    let near_mark = |c: u64| marks.iter().any(|(b, _)| c.abs_diff(*b) <= 24);
    let cuts = (0..=data.len()).filter(|&c| {
        c as u64 <= marks[2].0 + 24 || near_mark(c as u64) || c % 7 == 0 || c == data.len()
    });
    for cut in cuts {
        // In memory (rewriting a file costs ~3 ms here); through a file every 97 bytes.
        let r = if cut % 97 == 0 {
            std::fs::write(&cut_path, &data[..cut]).unwrap();
            recover_recording(&cut_path)
        } else {
            recover_recording_bytes(&data[..cut], &cut_path)
        }
        .unwrap_or_else(|e| panic!("cut {cut}: {e}"));
        let got: Vec<SinkMessage> = r.messages.iter().map(|m| m.message.clone()).collect();
        assert_eq!(got[..], sent[..got.len()], "cut {cut}: not a prefix");
        assert!(
            got.len() >= previous,
            "cut {cut}: fewer messages than a shorter cut"
        );
        previous = got.len();
        assert!(r.recovered_bytes <= cut as u64);
        assert_eq!(r.file_len, cut as u64);
        // At least everything flushed before the cut comes back.
        let flushed = marks
            .iter()
            .filter(|(b, _)| *b <= cut as u64)
            .map(|m| m.1)
            .max();
        if let Some(f) = flushed {
            assert!(
                got.len() >= f,
                "cut {cut}: {} < {f} flushed messages",
                got.len()
            );
        }
        if cut < data.len() {
            let b = r.break_at.as_ref().expect("a cut file is incomplete");
            assert_eq!(b.offset, r.recovered_bytes);
            // Strict reading refuses it, naming the file and the offset.
            let err = read_recording_bytes(&data[..cut], &cut_path).unwrap_err();
            let text = err.to_string();
            assert!(text.contains("cut.mcap"), "{text}");
            assert!(
                matches!(err, ReadError::Incomplete { .. }),
                "cut {cut}: {text}"
            );
        } else {
            assert!(r.is_complete());
            assert_eq!(got, sent);
        }
    }
    // Cut exactly at a flush boundary: exactly the flushed messages, and the
    // break is reported at that very offset.
    for &(bytes, count) in &marks {
        let r = recover_recording_bytes(&data[..bytes as usize], &cut_path).unwrap();
        assert_eq!(r.messages.len(), count, "cut at flush offset {bytes}");
        assert_eq!(r.recovered_bytes, bytes);
        assert_eq!(r.break_at.unwrap().offset, bytes);
    }
}

#[test]
fn damaged_bytes_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    // 240 messages: the chunks outweigh the summary's copy of the eight schemas
    let (path, sent, marks) = flushed_recording(dir.path(), 23, 240, 40);
    let data = std::fs::read(&path).unwrap();
    let bad_path = dir.path().join("bad.mcap");
    let mut rng = ChaCha8Rng::seed_from_u64(24);
    let mut damaged_chunks = 0;
    for _ in 0..400 {
        let mut d = data.clone();
        let pos = rng.random_range(8..d.len());
        d[pos] ^= 1 << rng.random_range(0..8);
        let _ = read_recording_bytes(&d, &bad_path); // must not panic
        let r = recover_recording_bytes(&d, &bad_path).unwrap();
        let got: Vec<SinkMessage> = r.messages.iter().map(|m| m.message.clone()).collect();
        assert_eq!(got[..], sent[..got.len()], "flip at {pos}: not a prefix");
        // Chunks wholly before the damaged byte are intact.
        let before = marks
            .iter()
            .filter(|(b, _)| *b <= pos as u64)
            .map(|m| m.1)
            .max()
            .unwrap_or(0);
        assert!(
            got.len() >= before,
            "flip at {pos}: {} < {before} messages flushed before it",
            got.len()
        );
        if got.len() < sent.len() {
            damaged_chunks += 1;
        }
    }
    // Most flips land in compressed chunk data and are caught by zstd or the CRC.
    assert!(
        damaged_chunks > 200,
        "only {damaged_chunks} of 400 flips detected"
    );
}

#[test]
fn not_mcap_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("x.mcap");
    std::fs::write(&p, b"hello, this is not MCAP").unwrap();
    assert!(matches!(
        recover_recording(&p),
        Err(ReadError::NotMcap { .. })
    ));
    let missing = dir.path().join("missing.mcap");
    let err = read_recording(&missing).unwrap_err();
    assert!(err.to_string().contains("missing.mcap"), "{err}");
}

#[test]
fn invalid_messages_are_refused_before_queueing() {
    let dir = tempfile::tempdir().unwrap();
    let rec = Recorder::start(&config(dir.path())).unwrap();
    let bad = SinkMessage::Clean(RateBatch {
        t0_ns: 1,
        dt_ns: 1,
        values: vec![f64::NAN],
    });
    let err = rec.send(bad.clone()).unwrap_err();
    assert!(matches!(err, RecordError::Invalid { .. }), "{err}");
    assert!(sagnac::chain::chain(&err).contains("values[0]"), "{err}");
    assert!(matches!(
        rec.try_send(bad),
        Err(RecordError::Invalid { .. })
    ));
    let summary = rec.finish().unwrap();
    assert_eq!(summary.messages(), 0);
}

#[test]
fn full_queue_drops_and_counts() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = RecorderConfig {
        queue_capacity: 1,
        ..config(dir.path())
    };
    let rec = Recorder::start(&cfg).unwrap();
    let sender = rec.sender();
    // 100k values per message take the writer far longer to encode than a
    // try_send takes, so a queue of one must overflow.
    let big = |i: u64| {
        SinkMessage::Noise(RateBatch {
            t0_ns: i,
            dt_ns: 1,
            values: (0..100_000)
                .map(|k| (k as f64 + 0.5) * 1e-3 + i as f64)
                .collect(),
        })
    };
    let mut accepted = Vec::new();
    let mut refused = 0;
    for i in 0..200 {
        match sender.try_send(big(i)) {
            Ok(()) => accepted.push(i),
            Err(RecordError::QueueFull { capacity: 1, .. }) => refused += 1,
            Err(e) => panic!("{e}"),
        }
    }
    assert!(refused > 0, "no message was dropped");
    assert_eq!(rec.dropped(), refused);
    assert_eq!(sender.dropped(), refused);
    let summary = rec.finish().unwrap();
    assert_eq!(summary.messages(), accepted.len() as u64);
    // The stopped recorder refuses further messages.
    assert!(matches!(
        sender.send(big(0)),
        Err(RecordError::Stopped { .. })
    ));
    let read = read_recording(&summary.path).unwrap();
    let times: Vec<u64> = read.messages.iter().map(|m| m.message.time_ns()).collect();
    assert_eq!(times, accepted);
}

/// Helper process for `kill_9_loses_nothing_older_than_the_flush_interval`: records
/// into $SAGNAC_MCAP_CHILD_DIR with a 0.3 s flush interval, prints each message
/// sent, then idles until killed.
#[test]
#[ignore = "helper process, run by kill_9_loses_nothing_older_than_the_flush_interval"]
fn child_recorder() {
    let dir = PathBuf::from(std::env::var_os("SAGNAC_MCAP_CHILD_DIR").expect("child dir"));
    let cfg = RecorderConfig {
        flush_interval_s: 0.3,
        ..config(&dir)
    };
    let rec = Recorder::start(&cfg).unwrap();
    println!("PATH {}", rec.path().display());
    for (i, m) in sink::stream(25, 90).into_iter().enumerate() {
        rec.send(m).unwrap();
        println!("SENT {}", i + 1);
        std::thread::sleep(Duration::from_millis(5));
    }
    println!("IDLE");
    std::thread::sleep(Duration::from_secs(120));
}

#[test]
fn kill_9_loses_nothing_older_than_the_flush_interval() {
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(std::env::current_exe().unwrap())
        .args([
            "--ignored",
            "--exact",
            "sink_mcap::child_recorder",
            "--nocapture",
            "--test-threads=1",
        ])
        .env("SAGNAC_MCAP_CHILD_DIR", dir.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut path = None;
    let mut sent = 0;
    for line in BufReader::new(child.stdout.take().unwrap()).lines() {
        let line = line.unwrap();
        // libtest prints "test sink_mcap::child_recorder ... " before the first line.
        if let Some((_, p)) = line.split_once("PATH ") {
            path = Some(PathBuf::from(p));
        } else if let Some(n) = line.strip_prefix("SENT ") {
            sent = n.parse().unwrap();
        } else if line == "IDLE" {
            break;
        }
    }
    // No message arrives any more: the timer alone must close the chunk within
    // 0.3 s. Wait 5x that, then kill -9 (SIGKILL: no destructor runs).
    let idle_since = Instant::now();
    std::thread::sleep(Duration::from_millis(1500));
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(idle_since.elapsed() >= Duration::from_millis(1500));
    assert_eq!(sent, 90);
    let r = recover_recording(&path.expect("child printed its path")).unwrap();
    assert!(!r.is_complete(), "killed recording has no footer");
    let got: Vec<SinkMessage> = r.messages.into_iter().map(|m| m.message).collect();
    assert_eq!(
        got,
        sink::recorded(&sink::stream(25, 90)),
        "all 90 messages survive kill -9"
    );
    // The strict reader calls it truncated.
    assert!(matches!(
        read_recording(
            &PathBuf::from(&dir.path()).join(
                std::fs::read_dir(dir.path())
                    .unwrap()
                    .next()
                    .unwrap()
                    .unwrap()
                    .file_name()
            )
        ),
        Err(ReadError::Incomplete { .. })
    ));
}

#[test]
fn timer_flush_without_new_messages() {
    // In-process version of the above: bytes grow past the first chunk with no
    // explicit flush and no further message.
    let dir = tempfile::tempdir().unwrap();
    let cfg = RecorderConfig {
        flush_interval_s: 0.2,
        ..config(dir.path())
    };
    let rec = Recorder::start(&cfg).unwrap();
    for m in sink::stream(26, 12) {
        rec.send(m).unwrap();
    }
    // (The file may grow before a chunk closes: the open chunk is streamed out.)
    let deadline = Instant::now() + Duration::from_secs(10);
    let r = loop {
        let r = recover_recording(rec.path()).unwrap();
        if !r.messages.is_empty() {
            break r;
        }
        assert!(Instant::now() < deadline, "no timed flush within 10 s");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(r.messages.len(), 12, "one chunk holds all 12");
    assert_eq!(rec.bytes_written(), r.file_len);
    let summary = rec.finish().unwrap();
    assert!(
        summary.flushes >= 3,
        "start, timer, finish: {}",
        summary.flushes
    );
}

#[test]
fn python_mcap_reader_agrees() {
    let dir = tempfile::tempdir().unwrap();
    let sent = sink::stream(27, 420);
    let rec = Recorder::start(&config(dir.path())).unwrap();
    for (i, m) in sent.iter().enumerate() {
        rec.send(m.clone()).unwrap();
        if i % 50 == 0 {
            rec.flush().unwrap();
        }
    }
    let summary = rec.finish().unwrap();

    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/read-mcap.py");
    let out = Command::new("python3")
        .arg(&script)
        .arg(&summary.path)
        .output()
        .unwrap_or_else(|e| panic!("python3 is required (scripts/install-peers): {e}"));
    assert!(
        out.status.success(),
        "read-mcap.py failed (python `mcap` + `zstandard` are installed by scripts/install-peers):\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();

    // Expected values, computed from the messages we sent.
    let mut raw_samples = 0u64;
    let mut raw_total = 0i64;
    let mut raw_lost = 0u64;
    let mut per_topic = std::collections::BTreeMap::new();
    let mut values = std::collections::BTreeMap::new();
    for m in &sent {
        *per_topic.entry(m.topic().name()).or_insert(0u64) += 1;
        match m {
            SinkMessage::Raw(b) => {
                raw_samples += b.counts.len() as u64;
                raw_total += b.counts.iter().sum::<i64>();
                raw_lost += b.gaps.iter().map(|g| g.lost).sum::<u64>();
            }
            SinkMessage::Clean(b) | SinkMessage::Noise(b) => {
                *values.entry(m.topic().name()).or_insert(0u64) += b.values.len() as u64;
            }
            _ => {}
        }
    }
    assert_eq!(j["messages"], 420);
    assert_eq!(j["statistics_messages"], 420);
    assert_eq!(j["raw_samples"], raw_samples);
    assert_eq!(j["raw_counts_total"], raw_total);
    assert_eq!(j["raw_lost_total"], raw_lost);
    assert!(raw_lost > 0, "the sample has gaps");
    assert_eq!(j["time_mismatches"], 0);
    for (topic, n) in &per_topic {
        assert_eq!(j["channels"][topic], *n, "{topic}");
    }
    for (topic, n) in &values {
        assert_eq!(j["values_total"][topic], *n, "{topic}");
    }
    assert_eq!(j["events_by_kind"].as_object().unwrap().len(), 7);
    for t in Topic::ALL {
        assert_eq!(
            j["encodings"][t.name()],
            serde_json::json!(["json", t.schema_name(), "jsonschema"]),
            "{}",
            t.name()
        );
    }
    // Schema validation by the `jsonschema` package, when present (not a
    // project peer; the structural check in tests/formats/sink_messages.rs always runs).
    match j["schema_valid"].as_u64() {
        Some(n) => {
            assert_eq!(j["schema_invalid"], serde_json::json!([]));
            assert_eq!(n, 420);
        }
        None => eprintln!("NOTICE: python jsonschema missing; schema validation by Python skipped"),
    }
}

/// The `sagnac` metadata record of `simulate --format mcap` is read by
/// the Python `mcap` reader too (through the summary's metadata index), with
/// the values the Rust reader gives.
#[test]
fn python_reads_the_metadata_record() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.toml");
    let text = "[gyro]\nsample_rate_hz = 400.0\npulse_arcsec = 0.9\n[noise]\narw_dpsh = 0.002\n";
    std::fs::write(&model, text).unwrap();
    let mcap = dir.path().join("sim.mcap");
    let sim = Command::new(env!("CARGO_BIN_EXE_sagnac"))
        .args(["simulate", "--model"])
        .arg(&model)
        .args([
            "--duration-s",
            "3",
            "--seed",
            "1",
            "--format",
            "mcap",
            "--out",
        ])
        .arg(&mcap)
        .output()
        .unwrap();
    assert!(
        sim.status.success(),
        "{}",
        String::from_utf8_lossy(&sim.stderr)
    );
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/read-mcap.py");
    let out = Command::new("python3")
        .arg(&script)
        .arg("--no-schema")
        .arg(&mcap)
        .output()
        .unwrap_or_else(|e| panic!("python3 is required (scripts/install-peers): {e}"));
    assert!(
        out.status.success(),
        "read-mcap.py: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let m = &j["metadata"]["sagnac"];
    assert_eq!(m["sample_rate_hz"], "400", "{j}");
    assert_eq!(m["output"], "counts");
    assert_eq!(m["pulse_arcsec"], "0.9");
    assert_eq!(m["model"], text);
    assert_eq!(m["sagnac_version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(j["raw_samples"], 1200);
    let meta = sagnac::recording::reader::read_metadata(&mcap)
        .unwrap()
        .unwrap();
    assert_eq!(
        meta.to_record().metadata,
        serde_json::from_value(m.clone()).unwrap()
    );
    // a full read returns the same record
    assert_eq!(read_recording(&mcap).unwrap().metadata, Some(meta));
}
