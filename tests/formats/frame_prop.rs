//! Property tests of the frame decoder, encoder, gap fill and injector.
//!
//! * any byte stream decodes without panic, with exact byte accounting;
//! * decoding is invariant under arbitrary chunking of the input;
//! * encode -> decode restores every increment (large ones and wraps included);
//! * with injected corruption the decoder's counts equal the injector's ledger
//!   and no angle is lost;
//! * the gap fill keeps the sum and stays within one pulse of the straight line.
//!
//! The proptest RNG seed is fixed (`RngSeed::Fixed`, ChaCha), so every run
//! explores the same cases; `PROPTEST_CASES` can raise the case count.

use bytes::BytesMut;
use proptest::prelude::*;
use sagnac::input::frame::inject::{FaultPlan, InjectorConfig, inject};
use sagnac::input::frame::{
    DecodeEvent, Decoded, DecoderConfig, DecoderStats, FRAME_LEN, FrameDecoder, FrameEncoder,
    GapFiller, Sample, encode_frame, encode_increments, fill_gap, spread_increment,
};

fn config() -> ProptestConfig {
    ProptestConfig {
        cases: std::env::var("PROPTEST_CASES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(256),
        failure_persistence: None,
        rng_algorithm: proptest::test_runner::RngAlgorithm::ChaCha,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x5A6_7AC5),
        ..ProptestConfig::default()
    }
}

/// One building block of an arbitrary stream.
#[derive(Debug, Clone)]
enum Piece {
    /// A valid frame continuing the running sequence with this increment.
    Next(i32),
    /// A valid frame with arbitrary seq and counter.
    Random(u16, u32, u16),
    /// A continuing frame with one bit flipped.
    Flipped(i32, u8),
    /// Arbitrary bytes.
    Garbage(Vec<u8>),
    /// The sync pattern alone.
    Sync,
    /// The first `n % 16` bytes of a continuing frame.
    Partial(u8),
}

fn piece() -> impl Strategy<Value = Piece> {
    prop_oneof![
        6 => any::<i32>().prop_map(|i| Piece::Next(i % 1000)),
        1 => any::<i32>().prop_map(Piece::Next),
        1 => (any::<u16>(), any::<u32>(), any::<u16>()).prop_map(|(s, c, st)| Piece::Random(s, c, st)),
        1 => (any::<i32>(), any::<u8>()).prop_map(|(i, b)| Piece::Flipped(i % 100, b)),
        1 => proptest::collection::vec(any::<u8>(), 1..24).prop_map(Piece::Garbage),
        1 => Just(Piece::Sync),
        1 => any::<u8>().prop_map(Piece::Partial),
    ]
}

fn build(pieces: &[Piece], start_seq: u16, start_counter: u32) -> Vec<u8> {
    let mut seq = start_seq;
    let mut counter = start_counter;
    let mut next = |inc: i32| {
        seq = seq.wrapping_add(1);
        counter = counter.wrapping_add(inc as u32);
        encode_frame(seq, counter, 2000, 7)
    };
    let mut out = Vec::new();
    for p in pieces {
        match p {
            Piece::Next(i) => out.extend_from_slice(&next(*i)),
            Piece::Random(s, c, st) => out.extend_from_slice(&encode_frame(*s, *c, -5, *st)),
            Piece::Flipped(i, b) => {
                let mut f = next(*i);
                let bit = usize::from(*b % 128);
                f[bit / 8] ^= 1 << (bit % 8);
                out.extend_from_slice(&f);
            }
            Piece::Garbage(g) => out.extend_from_slice(g),
            Piece::Sync => out.extend_from_slice(&[0xA5, 0x5A]),
            Piece::Partial(n) => out.extend_from_slice(&next(1)[..usize::from(*n % 16)]),
        }
    }
    out
}

/// Feed `bytes` in chunks of the given sizes (cycled), checking the byte
/// accounting identity after every call, then finish at EOF.
fn decode_chunked(
    bytes: &[u8],
    chunks: &[usize],
    cfg: DecoderConfig,
) -> Result<(Vec<Decoded>, DecoderStats), TestCaseError> {
    let mut dec = FrameDecoder::with_config(cfg);
    let mut buf = BytesMut::new();
    let mut out = Vec::new();
    let mut pos = 0;
    let mut k = 0;
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
            FRAME_LEN as u64 * st.frames_decoded + st.bytes_skipped + buf.len() as u64
        );
        prop_assert!(
            buf.len() < FRAME_LEN,
            "at most a partial candidate stays buffered"
        );
    }
    dec.finish(&mut buf, &mut out);
    prop_assert!(buf.is_empty());
    Ok((out, *dec.stats()))
}

fn check_event_accounting(items: &[Decoded], st: &DecoderStats) -> Result<(), TestCaseError> {
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
    prop_assert_eq!(n.samples, st.samples);
    prop_assert_eq!(n.resyncs, st.resyncs);
    prop_assert_eq!(n.trailing_bytes, st.trailing_bytes);
    prop_assert_eq!(n.crc_errors, st.crc_errors);
    prop_assert_eq!(n.false_syncs, st.false_syncs);
    prop_assert_eq!(n.gaps, st.gaps);
    prop_assert_eq!(n.lost_samples, st.lost_samples);
    prop_assert_eq!(n.duplicates, st.duplicates);
    prop_assert_eq!(n.out_of_sequence, st.out_of_sequence);
    prop_assert_eq!(n.discontinuities, st.discontinuities);
    prop_assert_eq!(n.status_changes, st.status_changes);
    Ok(())
}

fn samples(items: &[Decoded]) -> Vec<Sample> {
    items
        .iter()
        .filter_map(|d| match d {
            Decoded::Sample(s) => Some(*s),
            Decoded::Event(_) => None,
        })
        .collect()
}

proptest! {
    #![proptest_config(config())]

    /// Uniformly random bytes: no panic, exact accounting, events agree with counters.
    #[test]
    fn random_bytes_decode_without_panic(
        bytes in proptest::collection::vec(any::<u8>(), 0..3000),
        chunks in proptest::collection::vec(1usize..100, 1..8),
    ) {
        let (items, st) = decode_chunked(&bytes, &chunks, DecoderConfig::default())?;
        prop_assert_eq!(st.bytes_read, bytes.len() as u64);
        prop_assert_eq!(st.bytes_read, 16 * st.frames_decoded + st.bytes_skipped);
        check_event_accounting(&items, &st)?;
    }

    /// Structured streams (frames, corrupted frames, garbage, lone syncs,
    /// partial frames, out-of-sequence frames) split at arbitrary points decode
    /// identically to one-shot decoding, with exact accounting.
    #[test]
    fn chunking_invariance_and_accounting(
        pieces in proptest::collection::vec(piece(), 0..120),
        start_seq in any::<u16>(),
        start_counter in any::<u32>(),
        max_gap in prop_oneof![Just(4096u16), 0u16..20],
        chunks in proptest::collection::vec(1usize..40, 1..10),
    ) {
        let bytes = build(&pieces, start_seq, start_counter);
        let cfg = DecoderConfig { max_gap };
        let (one, st_one) = FrameDecoder::decode_all(&bytes, cfg);
        let (split, st_split) = decode_chunked(&bytes, &chunks, cfg)?;
        prop_assert_eq!(&one, &split);
        prop_assert_eq!(st_one, st_split);
        prop_assert_eq!(st_one.bytes_read, 16 * st_one.frames_decoded + st_one.bytes_skipped);
        check_event_accounting(&one, &st_one)?;
        // Byte-at-a-time too.
        let (bytewise, _) = decode_chunked(&bytes, &[1], cfg)?;
        prop_assert_eq!(&one, &bytewise);
    }

    /// encode -> decode restores every increment, including increments at the
    /// edges of the i32 range and wraps of both counters.
    #[test]
    fn roundtrip_restores_every_increment(
        incs in proptest::collection::vec(
            prop_oneof![
                4 => -50i64..50,
                1 => any::<i32>().prop_map(i64::from),
                1 => prop_oneof![Just(i64::from(i32::MAX)), Just(i64::from(i32::MIN))],
            ],
            0..400,
        ),
        start_seq in any::<u16>(),
        start_counter in any::<u32>(),
        chunks in proptest::collection::vec(1usize..64, 1..6),
    ) {
        let frames = encode_increments(&mut FrameEncoder::new(start_seq, start_counter), &incs)
            .expect("increments in i32 range");
        let bytes = frames.concat();
        let (items, st) = decode_chunked(&bytes, &chunks, DecoderConfig::default())?;
        let s = samples(&items);
        prop_assert_eq!(s.iter().map(|s| s.increment).collect::<Vec<_>>(), incs.clone());
        for (k, smp) in s.iter().enumerate() {
            prop_assert_eq!(smp.seq, start_seq.wrapping_add(k as u16 + 1));
            prop_assert_eq!(smp.lost_before, 0);
        }
        prop_assert_eq!(st.samples, incs.len() as u64);
        prop_assert_eq!(st.frames_decoded, incs.len() as u64 + 1);
        prop_assert_eq!(
            (st.bytes_skipped, st.crc_errors, st.false_syncs, st.gaps, st.resyncs),
            (0, 0, 0, 0, 0)
        );
    }

    /// Injected corruption: the decoder's counts equal the ledger exactly, and
    /// the increments (gap increments included) sum to the true pulses between
    /// the first and last intact frames; with both protected, to the total.
    #[test]
    fn injected_corruption_matches_ledger(
        incs in proptest::collection::vec(
            prop_oneof![4 => -30i64..30, 1 => any::<i32>().prop_map(|i| i64::from(i / 65536))],
            1..600,
        ),
        start_seq in prop_oneof![Just(65_500u16), any::<u16>()],
        start_counter in prop_oneof![Just(0xFFFF_FF00u32), any::<u32>()],
        drop_prob in 0.0f64..0.1,
        flip_prob in 0.0f64..0.1,
        duplicate_prob in 0.0f64..0.05,
        garbage_prob in 0.0f64..0.1,
        false_sync_prob in 0.0f64..1.0,
        tail_max_len in 0usize..40,
        protect in any::<bool>(),
        seed in any::<u64>(),
        chunks in proptest::collection::vec(1usize..80, 1..6),
    ) {
        let frames = encode_increments(&mut FrameEncoder::new(start_seq, start_counter), &incs)
            .expect("in range");
        let cfg = InjectorConfig {
            drop_prob, flip_prob, duplicate_prob, garbage_prob, garbage_max_len: 40,
            false_sync_prob, tail_max_len, protect_first: protect, protect_last: protect,
        };
        let plan = FaultPlan::random(frames.len(), &cfg, seed);
        let inj = inject(&frames, &plan);
        let e = inj.ledger.expected;
        // Validity conditions of the ledger's derivation (see inject docs).
        prop_assume!(e.spurious_windows == 0);
        prop_assume!(e.max_seq_step <= 4097);
        let (items, st) = decode_chunked(&inj.bytes, &chunks, DecoderConfig::default())?;
        prop_assert_eq!(e.mismatches(&st), vec![]);
        check_event_accounting(&items, &st)?;
        let end_run = items.iter().find_map(|d| match d {
            Decoded::Event(DecodeEvent::EndOfStream { skipped_bytes, .. }) => Some(*skipped_bytes),
            _ => None,
        }).unwrap_or(0);
        prop_assert_eq!(end_run, e.end_skip_run);
        let l = &inj.ledger;
        prop_assert_eq!(
            l.frames_in - l.dropped - l.bit_flipped + l.duplicated,
            l.intact.len() as u64
        );

        let s = samples(&items);
        let got: i64 = s.iter().map(|s| s.increment).sum();
        if let (Some(&first), Some(&last)) = (inj.ledger.intact.first(), inj.ledger.intact.last()) {
            // Frame k carries incs[k-1].
            let truth: i64 = incs[first..last].iter().sum();
            prop_assert_eq!(got, truth);
            if protect {
                prop_assert_eq!((first, last), (0, frames.len() - 1));
                prop_assert_eq!(got, incs.iter().sum::<i64>());
            }
            // Gap fill: one uniform sample per sample period, same total, the
            // synthetic ones are exactly the lost samples, seqs consecutive.
            let mut filler = GapFiller::new(s.iter().copied());
            let uni: Vec<_> = filler.by_ref().collect();
            prop_assert_eq!(uni.len(), last - first);
            prop_assert_eq!(uni.iter().map(|u| u.increment).sum::<i64>(), truth);
            prop_assert_eq!(filler.synthetic_count(), st.lost_samples);
            prop_assert_eq!(uni.iter().filter(|u| u.synthetic).count() as u64, st.lost_samples);
            for (k, u) in uni.iter().enumerate() {
                prop_assert_eq!(u.seq, start_seq.wrapping_add((first + k + 1) as u16));
            }
        } else {
            prop_assert_eq!(s.len(), 0);
        }
    }

    /// The fill spreads an increment as integers summing to it, each share
    /// floor(I/n) or floor(I/n)+1, running sums within one pulse below the
    /// straight line: n*partial_j <= I*j < n*(partial_j + 1).
    #[test]
    fn spread_is_exact_and_near_linear(total in any::<i64>(), n in 1u32..70_000) {
        let shares: Vec<i64> = spread_increment(total, n).collect();
        prop_assert_eq!(shares.len(), n as usize);
        let (t, m) = (i128::from(total), i128::from(n));
        let base = t.div_euclid(m);
        let mut partial: i128 = 0;
        for (j, &sh) in shares.iter().enumerate() {
            prop_assert!(i128::from(sh) == base || i128::from(sh) == base + 1, "share {sh}");
            partial += i128::from(sh);
            let tj = t * (j as i128 + 1);
            prop_assert!(m * partial <= tj && tj < m * (partial + 1), "j {j}");
        }
        prop_assert_eq!(partial, t);
    }
}

#[test]
fn fill_gap_numbers_the_synthetic_samples() {
    let s = Sample {
        seq: 1,
        counter: 0,
        increment: 10,
        lost_before: 3,
        temp_c: 0.0,
        status: 7,
        offset: 0,
    };
    let u: Vec<_> = fill_gap(&s)
        .map(|u| (u.seq, u.increment, u.synthetic))
        .collect();
    // floor(10*j/4) = 0, 2, 5, 7, 10 -> shares 2, 3, 2, 3.
    assert_eq!(
        u,
        [
            (65534, 2, true),
            (65535, 3, true),
            (0, 2, true),
            (1, 3, false)
        ]
    );
    let neg = Sample {
        increment: -7,
        lost_before: 1,
        ..s
    };
    // floor(-7/2) = -4, floor(-14/2) = -7 -> shares -4, -3.
    assert_eq!(
        fill_gap(&neg).map(|u| u.increment).collect::<Vec<_>>(),
        [-4, -3]
    );
    assert_eq!(spread_increment(5, 0).count(), 0);
}
