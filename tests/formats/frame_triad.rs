//! Property tests of the triad frame (24 bytes, three counters): the same
//! decoder guarantees as the single frame (`tests/formats/frame_prop.rs`).
//!
//! * any byte stream decodes without panic, with exact byte accounting
//!   (`bytes_read == 24 * frames_decoded + bytes_skipped + buffered`);
//! * decoding is invariant under arbitrary chunking of the input;
//! * encode -> decode restores every increment of every axis (wraps included);
//! * with injected corruption the decoder's counts equal the injector's ledger
//!   and no angle is lost on any axis;
//! * single frames in a triad stream are garbage (and vice versa).
//!
//! Seeds are fixed (`RngSeed::Fixed`); `PROPTEST_CASES` raises the case count.

use bytes::BytesMut;
use proptest::prelude::*;
use sagnac::input::frame::inject::{FaultPlan, InjectorConfig, inject_wire};
use sagnac::input::frame::triad::encode_triad_increments;
use sagnac::input::frame::{
    DecodeEvent, Decoded, DecoderConfig, DecoderStats, FrameDecoder, TRIAD_FRAME_LEN, Triad,
    TriadEncoder, WireDecoded, encode_frame, encode_triad_frame,
};

type Item = WireDecoded<Triad>;

fn config() -> ProptestConfig {
    ProptestConfig {
        cases: std::env::var("PROPTEST_CASES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(256),
        failure_persistence: None,
        rng_algorithm: proptest::test_runner::RngAlgorithm::ChaCha,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x7A1_AD5),
        ..ProptestConfig::default()
    }
}

const LEN: u64 = TRIAD_FRAME_LEN as u64;

fn decode_chunked(
    bytes: &[u8],
    chunks: &[usize],
    cfg: DecoderConfig,
) -> Result<(Vec<Item>, DecoderStats), TestCaseError> {
    let mut dec = FrameDecoder::<Triad>::for_wire(cfg);
    let mut buf = BytesMut::new();
    let mut out = Vec::new();
    let (mut pos, mut k) = (0, 0);
    while pos < bytes.len() {
        let n = chunks
            .get(k % chunks.len().max(1))
            .copied()
            .unwrap_or(1)
            .max(1);
        let end = (pos + n).min(bytes.len());
        buf.extend_from_slice(&bytes[pos..end]);
        pos = end;
        k += 1;
        dec.decode_available(&mut buf, &mut out);
        let st = dec.stats();
        prop_assert_eq!(st.bytes_read, pos as u64);
        prop_assert_eq!(
            st.bytes_read,
            LEN * st.frames_decoded + st.bytes_skipped + buf.len() as u64
        );
        prop_assert!(
            buf.len() < TRIAD_FRAME_LEN,
            "at most a partial candidate stays buffered"
        );
    }
    dec.finish(&mut buf, &mut out);
    prop_assert!(buf.is_empty());
    Ok((out, *dec.stats()))
}

fn check_event_accounting(items: &[Item], st: &DecoderStats) -> Result<(), TestCaseError> {
    let mut skipped = 0u64;
    let mut n = DecoderStats::default();
    for it in items {
        match it {
            Decoded::Sample(_) => n.samples += 1,
            Decoded::Event(e) => match e {
                DecodeEvent::Resync { skipped_bytes, .. } => {
                    n.resyncs += 1;
                    skipped += skipped_bytes;
                }
                DecodeEvent::EndOfStream {
                    skipped_bytes,
                    trailing_bytes,
                    ..
                } => {
                    skipped += skipped_bytes;
                    n.trailing_bytes += trailing_bytes;
                }
                DecodeEvent::CrcError { .. } => n.crc_errors += 1,
                DecodeEvent::FalseSync { .. } => n.false_syncs += 1,
                DecodeEvent::Gap { lost, .. } => {
                    n.gaps += 1;
                    n.lost_samples += u64::from(*lost);
                }
                DecodeEvent::Duplicate { .. } => n.duplicates += 1,
                DecodeEvent::OutOfSequence { .. } => n.out_of_sequence += 1,
                DecodeEvent::Discontinuity { .. } => n.discontinuities += 1,
                DecodeEvent::StatusChange { .. } => n.status_changes += 1,
                DecodeEvent::Baseline { .. } => {}
            },
        }
    }
    prop_assert_eq!(skipped, st.bytes_skipped);
    prop_assert_eq!(
        (
            n.samples,
            n.resyncs,
            n.trailing_bytes,
            n.crc_errors,
            n.false_syncs
        ),
        (
            st.samples,
            st.resyncs,
            st.trailing_bytes,
            st.crc_errors,
            st.false_syncs
        )
    );
    prop_assert_eq!(
        (
            n.gaps,
            n.lost_samples,
            n.duplicates,
            n.out_of_sequence,
            n.discontinuities,
            n.status_changes
        ),
        (
            st.gaps,
            st.lost_samples,
            st.duplicates,
            st.out_of_sequence,
            st.discontinuities,
            st.status_changes
        )
    );
    Ok(())
}

fn increments(items: &[Item]) -> Vec<[i64; 3]> {
    items
        .iter()
        .filter_map(|d| {
            if let Decoded::Sample(s) = d {
                Some(s.increment)
            } else {
                None
            }
        })
        .collect()
}

/// One building block of an arbitrary triad stream.
#[derive(Debug, Clone)]
enum Piece {
    Next([i32; 3]),
    Random(u16, [u32; 3], u16),
    Flipped([i32; 3], u8),
    Garbage(Vec<u8>),
    Sync,
    Partial(u8),
    /// A valid single frame (garbage to the triad decoder).
    SingleFrame(u16, u32),
}

fn piece() -> impl Strategy<Value = Piece> {
    let inc3 = || any::<[i32; 3]>();
    prop_oneof![
        6 => inc3().prop_map(|i| Piece::Next(i.map(|v| v % 1000))),
        1 => inc3().prop_map(Piece::Next),
        1 => (any::<u16>(), any::<[u32; 3]>(), any::<u16>()).prop_map(|(s, c, st)| Piece::Random(s, c, st)),
        1 => (inc3(), any::<u8>()).prop_map(|(i, b)| Piece::Flipped(i.map(|v| v % 100), b)),
        1 => proptest::collection::vec(any::<u8>(), 1..36).prop_map(Piece::Garbage),
        1 => Just(Piece::Sync),
        1 => any::<u8>().prop_map(Piece::Partial),
        1 => (any::<u16>(), any::<u32>()).prop_map(|(s, c)| Piece::SingleFrame(s, c)),
    ]
}

fn build(pieces: &[Piece], start_seq: u16, start: [u32; 3]) -> Vec<u8> {
    let (mut seq, mut c) = (start_seq, start);
    let mut next = |inc: [i32; 3]| {
        seq = seq.wrapping_add(1);
        for k in 0..3 {
            c[k] = c[k].wrapping_add(inc[k] as u32);
        }
        encode_triad_frame(seq, c, 2000, 7)
    };
    let mut out = Vec::new();
    for p in pieces {
        match p {
            Piece::Next(i) => out.extend_from_slice(&next(*i)),
            Piece::Random(s, c, st) => out.extend_from_slice(&encode_triad_frame(*s, *c, -5, *st)),
            Piece::Flipped(i, b) => {
                let mut f = next(*i);
                let bit = usize::from(*b) % (8 * TRIAD_FRAME_LEN);
                f[bit / 8] ^= 1 << (bit % 8);
                out.extend_from_slice(&f);
            }
            Piece::Garbage(g) => out.extend_from_slice(g),
            Piece::Sync => out.extend_from_slice(&[0xA5, 0x5B]),
            Piece::Partial(n) => {
                let f = next([1, 2, 3]);
                out.extend_from_slice(&f[..usize::from(*n) % TRIAD_FRAME_LEN]);
            }
            Piece::SingleFrame(s, c) => out.extend_from_slice(&encode_frame(*s, *c, 0, 7)),
        }
    }
    out
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn random_bytes_decode_without_panic(
        bytes in proptest::collection::vec(any::<u8>(), 0..3000),
        chunks in proptest::collection::vec(1usize..100, 1..8),
    ) {
        let (items, st) = decode_chunked(&bytes, &chunks, DecoderConfig::default())?;
        prop_assert_eq!(st.bytes_read, LEN * st.frames_decoded + st.bytes_skipped);
        check_event_accounting(&items, &st)?;
    }

    #[test]
    fn chunking_invariance_and_accounting(
        pieces in proptest::collection::vec(piece(), 0..120),
        start_seq in any::<u16>(),
        start in any::<[u32; 3]>(),
        max_gap in prop_oneof![Just(4096u16), 0u16..20],
        chunks in proptest::collection::vec(1usize..50, 1..10),
    ) {
        let bytes = build(&pieces, start_seq, start);
        let cfg = DecoderConfig { max_gap };
        let (one, st_one) = FrameDecoder::<Triad>::decode_all_wire(&bytes, cfg);
        let (split, st_split) = decode_chunked(&bytes, &chunks, cfg)?;
        prop_assert_eq!(&one, &split);
        prop_assert_eq!(st_one, st_split);
        check_event_accounting(&one, &st_one)?;
        let (bytewise, _) = decode_chunked(&bytes, &[1], cfg)?;
        prop_assert_eq!(&one, &bytewise);
    }

    #[test]
    fn roundtrip_restores_every_increment(
        incs in proptest::collection::vec(
            prop_oneof![
                4 => (-50i64..50, -50i64..50, -50i64..50).prop_map(|(a, b, c)| [a, b, c]),
                1 => any::<[i32; 3]>().prop_map(|v| v.map(i64::from)),
                1 => Just([i64::from(i32::MAX), i64::from(i32::MIN), 0]),
            ],
            0..400,
        ),
        start_seq in any::<u16>(),
        start in prop_oneof![Just([u32::MAX - 10, 5, u32::MAX]), any::<[u32; 3]>()],
        chunks in proptest::collection::vec(1usize..64, 1..6),
    ) {
        let frames = encode_triad_increments(&mut TriadEncoder::new(start_seq, start), &incs).expect("in range");
        let (items, st) = decode_chunked(&frames.concat(), &chunks, DecoderConfig::default())?;
        prop_assert_eq!(increments(&items), incs.clone());
        prop_assert_eq!(st.frames_decoded, incs.len() as u64 + 1);
        prop_assert_eq!((st.bytes_skipped, st.crc_errors, st.false_syncs, st.gaps, st.resyncs), (0, 0, 0, 0, 0));
    }

    #[test]
    fn injected_corruption_matches_ledger(
        incs in proptest::collection::vec(
            prop_oneof![
                4 => (-30i64..30, -30i64..30, -30i64..30).prop_map(|(a, b, c)| [a, b, c]),
                1 => any::<[i32; 3]>().prop_map(|v| v.map(|i| i64::from(i / 65536))),
            ],
            1..600,
        ),
        start_seq in prop_oneof![Just(65_500u16), any::<u16>()],
        start in prop_oneof![Just([0xFFFF_FF00u32, 0, 0x7FFF_FFF0]), any::<[u32; 3]>()],
        drop_prob in 0.0f64..0.1,
        flip_prob in 0.0f64..0.1,
        duplicate_prob in 0.0f64..0.05,
        garbage_prob in 0.0f64..0.1,
        false_sync_prob in 0.0f64..1.0,
        tail_max_len in 0usize..50,
        protect in any::<bool>(),
        seed in any::<u64>(),
        chunks in proptest::collection::vec(1usize..80, 1..6),
    ) {
        let frames = encode_triad_increments(&mut TriadEncoder::new(start_seq, start), &incs).expect("in range");
        let cfg = InjectorConfig {
            drop_prob, flip_prob, duplicate_prob, garbage_prob, garbage_max_len: 40,
            false_sync_prob, tail_max_len, protect_first: protect, protect_last: protect,
        };
        let plan = FaultPlan::random_for::<Triad>(frames.len(), &cfg, seed);
        let inj = inject_wire::<Triad>(&frames, &plan);
        let e = inj.ledger.expected;
        prop_assume!(e.spurious_windows == 0);
        prop_assume!(e.max_seq_step <= 4097);
        let (items, st) = decode_chunked(&inj.bytes, &chunks, DecoderConfig::default())?;
        prop_assert_eq!(e.mismatches(&st), vec![]);
        check_event_accounting(&items, &st)?;
        let got = increments(&items);
        if let (Some(&first), Some(&last)) = (inj.ledger.intact.first(), inj.ledger.intact.last()) {
            for axis in 0..3 {
                let truth: i64 = incs[first..last].iter().map(|i| i[axis]).sum();
                prop_assert_eq!(got.iter().map(|i| i[axis]).sum::<i64>(), truth, "axis {}", axis);
            }
        } else {
            prop_assert_eq!(got.len(), 0);
        }
    }
}

/// A known stream: a seq wrap, counter wraps on every axis, a dropped frame, a
/// flipped frame on the grid, garbage with a false sync: exact counts.
#[test]
fn known_stream_exact_counts() {
    let incs: Vec<[i64; 3]> = (0..50).map(|k| [5 + k, -7, 1_000_000]).collect();
    let frames = encode_triad_increments(
        &mut TriadEncoder::new(65_530, [u32::MAX - 20, 3, u32::MAX - 2_500_000]),
        &incs,
    )
    .unwrap();
    let mut plan = FaultPlan::none();
    plan.set_action(10, sagnac::input::frame::inject::FrameAction::Drop);
    plan.set_action(20, sagnac::input::frame::inject::FrameAction::FlipBit(100));
    plan.add_garbage_before(30, &[0x00, 0xA5, 0x5B, 1, 2, 3]);
    let inj = inject_wire::<Triad>(&frames, &plan);
    let (items, st) = FrameDecoder::<Triad>::decode_all_wire(&inj.bytes, DecoderConfig::default());
    assert_eq!(inj.ledger.expected.mismatches(&st), vec![]);
    assert_eq!(
        (
            st.gaps,
            st.lost_samples,
            st.crc_errors,
            st.false_syncs,
            st.resyncs
        ),
        (2, 2, 1, 1, 2)
    );
    assert_eq!(st.bytes_skipped, 24 + 6);
    let got = increments(&items);
    assert_eq!(got.len(), 48);
    for axis in 0..3 {
        assert_eq!(
            got.iter().map(|i| i[axis]).sum::<i64>(),
            incs.iter().map(|i| i[axis]).sum::<i64>()
        );
    }
}
