//! The synchronous `.bin` capture reader: blocks reproduce the one-shot decoder
//! output exactly for any read-chunk and block size; errors name the file and
//! the byte offset.

use std::io::{self, Read};

use sagnac::input::capture::{CaptureError, CaptureReader};
use sagnac::input::frame::inject::{FaultPlan, InjectorConfig, inject};
use sagnac::input::frame::{Decoded, DecoderConfig, FrameDecoder, FrameEncoder, encode_increments};

fn corrupted_stream(seed: u64) -> (Vec<u8>, i64) {
    let incs: Vec<i64> = (0..5000).map(|k| ((k * 7919) % 23) - 11).collect();
    let frames = encode_increments(&mut FrameEncoder::new(60_000, 0xFFFF_0000), &incs).unwrap();
    let cfg = InjectorConfig {
        drop_prob: 0.01,
        flip_prob: 0.01,
        duplicate_prob: 0.005,
        garbage_prob: 0.01,
        tail_max_len: 30,
        ..InjectorConfig::default()
    };
    let inj = inject(&frames, &FaultPlan::random(frames.len(), &cfg, seed));
    (inj.bytes, incs.iter().sum())
}

/// Rebuild the decoder's item sequence from the summary's samples and
/// positioned events.
fn interleave(sum: &sagnac::input::capture::CaptureSummary) -> Vec<Decoded> {
    let mut out = Vec::new();
    let mut ev = sum.events.iter().peekable();
    for (i, s) in sum.samples.iter().enumerate() {
        while let Some(e) = ev.next_if(|e| e.before_sample == i) {
            out.push(Decoded::Event(e.event));
        }
        out.push(Decoded::Sample(*s));
    }
    out.extend(ev.map(|e| Decoded::Event(e.event)));
    out
}

#[test]
fn blocks_reproduce_one_shot_decoding_for_any_chunking() {
    let (bytes, total) = corrupted_stream(7);
    let (expected, expected_stats) = FrameDecoder::decode_all(&bytes, DecoderConfig::default());
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.bin");
    std::fs::write(&path, &bytes).unwrap();
    for (chunk, block) in [(1usize, 1usize), (7, 100), (4096, 333), (1 << 20, 1 << 20)] {
        let mut rd = CaptureReader::open(&path)
            .unwrap()
            .with_read_chunk(chunk)
            .with_block_samples(block);
        let mut n_blocks = 0;
        let mut sum = sagnac::input::capture::CaptureSummary::default();
        while let Some(b) = rd.next_block().unwrap() {
            assert!(b.samples.len() <= block, "block size bound");
            assert!(!b.is_empty());
            let base = sum.samples.len();
            sum.events.extend(b.events.iter().map(|e| {
                let mut e = *e;
                e.before_sample += base;
                e
            }));
            sum.samples.extend(b.samples);
            n_blocks += 1;
        }
        assert!(rd.next_block().unwrap().is_none(), "stays at EOF");
        assert_eq!(interleave(&sum), expected, "chunk {chunk} block {block}");
        assert_eq!(*rd.stats(), expected_stats);
        assert!(n_blocks >= expected_stats.samples as usize / block);
        // No angle lost: the protected first and last frames bound the run.
        assert_eq!(sum.samples.iter().map(|s| s.increment).sum::<i64>(), total);
    }
    let all = CaptureReader::open(&path).unwrap().read_all().unwrap();
    assert_eq!(interleave(&all), expected);
    assert_eq!(all.stats, expected_stats);
    assert!(all.stats.crc_errors > 0 && all.stats.lost_samples > 0);
}

#[test]
fn missing_file_error_names_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("absent.bin");
    let err = CaptureReader::open(&path).unwrap_err();
    assert!(matches!(err, CaptureError::Open { .. }));
    let msg = err.to_string();
    assert!(msg.contains("absent.bin"), "{msg}");
}

#[test]
fn a_file_without_frames_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rates.csv");
    std::fs::write(&path, "time_s,rate_dph\n0.0,1.5\n0.01,1.25\n").unwrap();
    let err = CaptureReader::open(&path).unwrap().read_all().unwrap_err();
    match &err {
        CaptureError::NoFrames { bytes_read, .. } => assert_eq!(*bytes_read, 34),
        other => panic!("{other:?}"),
    }
    assert!(err.to_string().contains("rates.csv"), "{err}");
    // An empty file too.
    let empty = dir.path().join("empty.bin");
    std::fs::write(&empty, b"").unwrap();
    assert!(matches!(
        CaptureReader::open(&empty).unwrap().read_all(),
        Err(CaptureError::NoFrames { bytes_read: 0, .. })
    ));
}

/// A reader that fails after `ok` bytes.
struct FailAfter {
    data: Vec<u8>,
    pos: usize,
    ok: usize,
}

impl Read for FailAfter {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.pos >= self.ok {
            return Err(io::Error::other("device unplugged"));
        }
        let n = buf
            .len()
            .min(self.ok - self.pos)
            .min(self.data.len() - self.pos);
        buf[..n].copy_from_slice(&self.data[self.pos..self.pos + n]);
        self.pos += n;
        Ok(n)
    }
}

#[test]
fn read_error_names_file_and_byte_offset() {
    let (bytes, _) = corrupted_stream(1);
    let rd = CaptureReader::new(
        FailAfter {
            data: bytes,
            pos: 0,
            ok: 1000,
        },
        "bench-3.bin",
        DecoderConfig::default(),
    )
    .with_read_chunk(300);
    let err = rd.read_all().unwrap_err();
    assert!(
        matches!(err, CaptureError::Read { offset: 1000, .. }),
        "{err:?}"
    );
    let msg = err.to_string();
    assert!(msg.contains("bench-3.bin") && msg.contains("1000"), "{msg}");
}
