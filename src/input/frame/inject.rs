//! Corruption injector with an exact ledger, for the tests and the daemon's
//! bench emulator.
//!
//! Start from clean frames (see [`super::encode_increments`]; put the counter
//! near 2^32 and `seq` near 65535 with [`super::FrameEncoder::new`] to exercise
//! the wraps), describe the faults in a [`FaultPlan`] (by hand, or seeded random
//! with [`FaultPlan::random`]), and [`inject`] them. Faults, per frame:
//!
//! * garbage inserted before the frame (random bytes, optionally starting with
//!   the sync pattern to provoke a false sync);
//! * the frame dropped;
//! * one bit flipped (CRC-16/CCITT detects every single-bit error; a flip in
//!   the two sync bytes destroys the sync instead of failing the CRC);
//! * the frame sent twice (a duplicate);
//!
//! plus bytes appended after the last frame (garbage or a partial frame).
//!
//! The [`Ledger`] records what was injected and derives, from the corrupted
//! stream and the positions of the frames that arrived intact, the exact
//! [`DecoderStats`] a decoder must report. The derivation restates the
//! documented policy independently of the decoder's state machine: every byte
//! outside intact frames is skipped; each maximal run of skipped bytes ended by
//! an intact frame is one resync; inside a run, every position holding the sync
//! pattern with a frame length (16 bytes; 24 for the triad frame,
//! [`inject_wire`]) of stream left is one bad-CRC candidate, a CRC error when
//! its distance from the start of the run is a multiple of the frame length (on
//! the frame grid, where a frame was expected), a false sync otherwise; seq steps
//! between intact frames give gaps, lost samples and duplicates. It holds when `max_seq_step <= max_gap + 1` and no candidate
//! window happens to carry a valid CRC (`spurious_windows == 0`); both are
//! recorded so callers can check.

use std::collections::BTreeMap;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{DecoderStats, FRAME_LEN, Single, Wire};

/// What happens to one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FrameAction {
    /// Sent as is.
    #[default]
    Keep,
    /// Not sent.
    Drop,
    /// Sent with bit `n % (8 * LEN)` flipped (bit `n % 8` of byte `n / 8 % LEN`;
    /// `LEN` = 16 for the single frame, 24 for the triad frame).
    FlipBit(u8),
    /// Sent twice.
    Duplicate,
}

/// The faults applied at one frame.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct FrameFault {
    /// Bytes inserted before the frame.
    pub garbage_before: Vec<u8>,
    /// What happens to the frame itself.
    pub action: FrameAction,
}

/// Faults by frame index, plus bytes appended at the end.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct FaultPlan {
    /// Faults keyed by the index of the clean frame.
    pub faults: BTreeMap<usize, FrameFault>,
    /// Bytes appended after the last frame.
    pub tail: Vec<u8>,
}

/// Rates for [`FaultPlan::random`]. Probabilities are per frame and clamped to
/// `[0, 1]` (NaN counts as 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InjectorConfig {
    /// Probability that a frame is dropped.
    pub drop_prob: f64,
    /// Probability that a frame gets one bit flipped.
    pub flip_prob: f64,
    /// Probability that a frame is sent twice.
    pub duplicate_prob: f64,
    /// Probability of a garbage run before a frame.
    pub garbage_prob: f64,
    /// Maximum garbage run length (at least 1 byte per run).
    pub garbage_max_len: usize,
    /// Probability that a garbage run starts with the sync pattern.
    pub false_sync_prob: f64,
    /// Maximum length of the tail appended after the last frame (0: none).
    pub tail_max_len: usize,
    /// Never drop, flip or duplicate the first frame (keeps the baseline).
    pub protect_first: bool,
    /// Never drop, flip or duplicate the last frame (keeps the final counter).
    pub protect_last: bool,
}

impl Default for InjectorConfig {
    fn default() -> Self {
        InjectorConfig {
            drop_prob: 0.01,
            flip_prob: 0.01,
            duplicate_prob: 0.002,
            garbage_prob: 0.01,
            garbage_max_len: 40,
            false_sync_prob: 0.3,
            tail_max_len: 0,
            protect_first: true,
            protect_last: true,
        }
    }
}

fn prob(p: f64) -> f64 {
    if p.is_finite() {
        p.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

impl FaultPlan {
    /// No faults.
    pub fn none() -> Self {
        Self::default()
    }

    /// Set the action for frame `index`.
    pub fn set_action(&mut self, index: usize, action: FrameAction) -> &mut Self {
        self.faults.entry(index).or_default().action = action;
        self
    }

    /// Insert `bytes` before frame `index` (appends to garbage already there).
    pub fn add_garbage_before(&mut self, index: usize, bytes: &[u8]) -> &mut Self {
        self.faults
            .entry(index)
            .or_default()
            .garbage_before
            .extend_from_slice(bytes);
        self
    }

    /// A seeded random plan for `n_frames` single frames.
    pub fn random(n_frames: usize, cfg: &InjectorConfig, seed: u64) -> Self {
        Self::random_for::<Single>(n_frames, cfg, seed)
    }

    /// A seeded random plan for `n_frames` frames of wire format `W` (bit flips
    /// anywhere in its `W::LEN` bytes).
    pub fn random_for<W: Wire>(n_frames: usize, cfg: &InjectorConfig, seed: u64) -> Self {
        let bits = (8 * W::LEN).min(256) as u16;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let (p_drop, p_flip, p_dup) = (
            prob(cfg.drop_prob),
            prob(cfg.flip_prob),
            prob(cfg.duplicate_prob),
        );
        let mut plan = FaultPlan::none();
        for i in 0..n_frames {
            let mut ff = FrameFault::default();
            if rng.random_bool(prob(cfg.garbage_prob)) {
                let len = rng.random_range(1..=cfg.garbage_max_len.max(1));
                if rng.random_bool(prob(cfg.false_sync_prob)) {
                    ff.garbage_before.extend_from_slice(&W::SYNC);
                }
                ff.garbage_before
                    .extend((0..len).map(|_| rng.random::<u8>()));
            }
            let protected =
                (cfg.protect_first && i == 0) || (cfg.protect_last && i + 1 == n_frames);
            if !protected {
                let u: f64 = rng.random();
                ff.action = if u < p_drop {
                    FrameAction::Drop
                } else if u < p_drop + p_flip {
                    FrameAction::FlipBit(rng.random_range(0..bits) as u8)
                } else if u < p_drop + p_flip + p_dup {
                    FrameAction::Duplicate
                } else {
                    FrameAction::Keep
                };
            }
            if ff != FrameFault::default() {
                plan.faults.insert(i, ff);
            }
        }
        if cfg.tail_max_len > 0 {
            let len = rng.random_range(0..=cfg.tail_max_len);
            if len >= 2 && rng.random_bool(0.5) {
                plan.tail.extend_from_slice(&W::SYNC);
                plan.tail.extend((2..len).map(|_| rng.random::<u8>()));
            } else {
                plan.tail.extend((0..len).map(|_| rng.random::<u8>()));
            }
        }
        plan
    }
}

/// The counts a decoder must report for an injected stream (see the module
/// docs for the derivation and its two validity conditions).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Expected {
    /// Stream length.
    pub bytes_read: u64,
    /// Intact frames (including duplicate copies).
    pub frames_decoded: u64,
    /// Samples (intact frames after the first, duplicates excluded).
    pub samples: u64,
    /// Bytes outside intact frames.
    pub bytes_skipped: u64,
    /// Skipped runs ended by an intact frame.
    pub resyncs: u64,
    /// Bad-CRC candidates a multiple of 16 bytes into a skipped run.
    pub crc_errors: u64,
    /// Bad-CRC candidates elsewhere in skipped runs.
    pub false_syncs: u64,
    /// Seq steps greater than one between intact frames.
    pub gaps: u64,
    /// Samples missing inside those steps.
    pub lost_samples: u64,
    /// Intact frames repeating the previous seq.
    pub duplicates: u64,
    /// Length of the skipped run after the last intact frame (reported by
    /// `EndOfStream`).
    pub end_skip_run: u64,
    /// Largest seq step between intact frames (validity: `<= max_gap + 1`).
    pub max_seq_step: u32,
    /// Candidate windows with a valid CRC by chance (validity: 0).
    pub spurious_windows: u64,
}

impl Expected {
    /// Names and values (`expected`, `actual`) of every count that differs
    /// from `stats`; empty when all match.
    pub fn mismatches(&self, stats: &DecoderStats) -> Vec<(&'static str, u64, u64)> {
        let pairs = [
            ("bytes_read", self.bytes_read, stats.bytes_read),
            ("frames_decoded", self.frames_decoded, stats.frames_decoded),
            ("samples", self.samples, stats.samples),
            ("bytes_skipped", self.bytes_skipped, stats.bytes_skipped),
            ("resyncs", self.resyncs, stats.resyncs),
            ("crc_errors", self.crc_errors, stats.crc_errors),
            ("false_syncs", self.false_syncs, stats.false_syncs),
            ("gaps", self.gaps, stats.gaps),
            ("lost_samples", self.lost_samples, stats.lost_samples),
            ("duplicates", self.duplicates, stats.duplicates),
            ("out_of_sequence", 0, stats.out_of_sequence),
            ("discontinuities", 0, stats.discontinuities),
        ];
        pairs.into_iter().filter(|(_, e, a)| e != a).collect()
    }
}

/// What was injected, and what the decoder must therefore report.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Ledger {
    /// Clean frames given.
    pub frames_in: u64,
    /// Frames dropped.
    pub dropped: u64,
    /// Frames with a flipped bit.
    pub bit_flipped: u64,
    /// Of those, flips that hit the sync bytes.
    pub sync_flipped: u64,
    /// Frames sent twice.
    pub duplicated: u64,
    /// Garbage runs inserted before frames.
    pub garbage_runs: u64,
    /// Garbage bytes inserted before frames.
    pub garbage_bytes: u64,
    /// Bytes appended after the last frame.
    pub tail_bytes: u64,
    /// Clean-frame indices of the frames that arrived intact, in stream order
    /// (a duplicated frame appears twice).
    pub intact: Vec<usize>,
    /// The counts the decoder must report.
    pub expected: Expected,
}

/// A corrupted stream and its ledger.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Injected {
    /// The stream.
    pub bytes: Vec<u8>,
    /// What was done to it.
    pub ledger: Ledger,
}

/// Apply `plan` to single `frames` (frames that do not pass
/// [`super::check`] are never counted as intact).
pub fn inject(frames: &[[u8; FRAME_LEN]], plan: &FaultPlan) -> Injected {
    inject_wire::<Single>(frames, plan)
}

/// Apply `plan` to `frames` of wire format `W` (each `W::LEN` bytes; frames
/// that do not pass `W::check` are never counted as intact).
pub fn inject_wire<W: Wire>(frames: &[impl AsRef<[u8]>], plan: &FaultPlan) -> Injected {
    let mut out: Vec<u8> = Vec::with_capacity(frames.len() * W::LEN);
    let mut led = Ledger {
        frames_in: frames.len() as u64,
        ..Ledger::default()
    };
    // (offset in `out`, seq, clean index) of intact frames.
    let mut intact: Vec<(usize, u16, usize)> = Vec::new();
    let mut put_intact = |out: &mut Vec<u8>, f: &[u8], i: usize| {
        if W::check(f).is_ok()
            && let Some(raw) = W::parse(f)
        {
            intact.push((out.len(), raw.seq, i));
        }
        out.extend_from_slice(f);
    };
    let keep = FrameFault::default();
    for (i, f) in frames.iter().enumerate() {
        let f = f.as_ref();
        let ff = plan.faults.get(&i).unwrap_or(&keep);
        if !ff.garbage_before.is_empty() {
            led.garbage_runs += 1;
            led.garbage_bytes += ff.garbage_before.len() as u64;
            out.extend_from_slice(&ff.garbage_before);
        }
        match ff.action {
            FrameAction::Keep => put_intact(&mut out, f, i),
            FrameAction::Drop => led.dropped += 1,
            FrameAction::FlipBit(n) => {
                let bit = usize::from(n) % (8 * W::LEN);
                let mut g = f.to_vec();
                g[bit / 8] ^= 1 << (bit % 8);
                led.bit_flipped += 1;
                if bit / 8 < W::SYNC.len() {
                    led.sync_flipped += 1;
                }
                out.extend_from_slice(&g);
            }
            FrameAction::Duplicate => {
                led.duplicated += 1;
                put_intact(&mut out, f, i);
                put_intact(&mut out, f, i);
            }
        }
    }
    out.extend_from_slice(&plan.tail);
    led.tail_bytes = plan.tail.len() as u64;
    led.expected = derive_expected::<W>(&out, &intact);
    led.intact = intact.iter().map(|&(_, _, i)| i).collect();
    Injected {
        bytes: out,
        ledger: led,
    }
}

/// The counts implied by the stream and the intact-frame positions.
fn derive_expected<W: Wire>(bytes: &[u8], intact: &[(usize, u16, usize)]) -> Expected {
    let len = bytes.len();
    let mut e = Expected {
        bytes_read: len as u64,
        frames_decoded: intact.len() as u64,
        bytes_skipped: (len - W::LEN * intact.len()) as u64,
        ..Expected::default()
    };
    let scan = |e: &mut Expected, start: usize, end: usize| {
        for p in start..end {
            if p + W::LEN <= len && bytes[p] == W::SYNC[0] && bytes[p + 1] == W::SYNC[1] {
                if (p - start).is_multiple_of(W::LEN) {
                    e.crc_errors += 1;
                } else {
                    e.false_syncs += 1;
                }
                if W::check(&bytes[p..p + W::LEN]).is_ok() {
                    e.spurious_windows += 1;
                }
            }
        }
    };
    let mut prev_end = 0usize;
    for &(off, _, _) in intact {
        if off > prev_end {
            e.resyncs += 1;
        }
        scan(&mut e, prev_end, off);
        prev_end = off + W::LEN;
    }
    e.end_skip_run = (len - prev_end) as u64;
    scan(&mut e, prev_end, len);

    let mut last: Option<u16> = None;
    for &(_, seq, _) in intact {
        match last {
            None => last = Some(seq),
            Some(prev) => {
                let d = seq.wrapping_sub(prev);
                if d == 0 {
                    e.duplicates += 1;
                } else {
                    e.samples += 1;
                    if d > 1 {
                        e.gaps += 1;
                        e.lost_samples += u64::from(d - 1);
                    }
                    e.max_seq_step = e.max_seq_step.max(u32::from(d));
                    last = Some(seq);
                }
            }
        }
    }
    e
}
