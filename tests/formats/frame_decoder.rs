//! Scenario tests of the frame decoder: exact event sequences and exact
//! counts for hand-placed corruption, sequence anomalies and end of stream.

use bytes::BytesMut;
use sagnac::input::frame::inject::{FaultPlan, FrameAction, inject};
use sagnac::input::frame::{
    DecodeEvent, Decoded, DecoderConfig, DecoderStats, FRAME_LEN, FrameDecoder, FrameEncoder,
    Sample, encode_frame, encode_increments,
};

fn decode(bytes: &[u8]) -> (Vec<Decoded>, DecoderStats) {
    FrameDecoder::decode_all(bytes, DecoderConfig::default())
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

fn events(items: &[Decoded]) -> Vec<DecodeEvent> {
    items
        .iter()
        .filter_map(|d| match d {
            Decoded::Event(e) => Some(*e),
            Decoded::Sample(_) => None,
        })
        .collect()
}

fn concat(frames: &[[u8; FRAME_LEN]]) -> Vec<u8> {
    frames.concat()
}

#[test]
fn clean_stream_across_both_wraps() {
    let incs = [5, 7, -3, 0, 1000];
    let frames = encode_increments(&mut FrameEncoder::new(65533, 0xFFFF_FFF0), &incs).unwrap();
    let (items, st) = decode(&concat(&frames));
    assert_eq!(
        items[0],
        Decoded::Event(DecodeEvent::Baseline {
            seq: 65533,
            counter: 0xFFFF_FFF0,
            status: 7,
            offset: 0,
        })
    );
    let s = samples(&items);
    assert_eq!(s.iter().map(|s| s.increment).collect::<Vec<_>>(), incs);
    assert_eq!(
        s.iter().map(|s| s.seq).collect::<Vec<_>>(),
        [65534, 65535, 0, 1, 2]
    );
    assert_eq!(s[1].counter, 0xFFFF_FFF0u32.wrapping_add(12));
    assert_eq!(s[4].offset, 5 * 16);
    assert!(s.iter().all(|s| s.lost_before == 0));
    // 25.00 deg C from the encoder's default; tolerance 1e-12.
    assert!((s[0].temp_c - 25.0).abs() < 1e-12);
    assert_eq!(events(&items).len(), 1, "only the baseline");
    assert_eq!(
        st,
        DecoderStats {
            bytes_read: 96,
            frames_decoded: 6,
            samples: 5,
            ..DecoderStats::default()
        }
    );
}

#[test]
fn capture_starting_mid_frame_resyncs() {
    let frames = encode_increments(&mut FrameEncoder::new(0, 0), &[1, 2]).unwrap();
    let mut bytes = frames[0][9..].to_vec(); // 7-byte tail of an earlier frame
    bytes.extend(concat(&frames));
    let (items, st) = decode(&bytes);
    assert_eq!(
        items[0],
        Decoded::Event(DecodeEvent::Resync {
            skipped_bytes: 7,
            at_offset: 7,
        })
    );
    assert_eq!(samples(&items).len(), 2);
    assert_eq!(
        (st.bytes_skipped, st.resyncs, st.crc_errors, st.false_syncs),
        (7, 1, 0, 0)
    );
}

#[test]
fn bit_flip_is_a_crc_error_then_a_gap_with_the_whole_increment() {
    let frames = encode_increments(&mut FrameEncoder::new(100, 50), &[10, 20, 30, 40]).unwrap();
    let mut bytes = concat(&frames);
    bytes[2 * 16 + 5] ^= 0x01; // counter byte of frame 2 (seq 102)
    let (items, st) = decode(&bytes);
    let ev = events(&items);
    assert!(
        matches!(ev[1], DecodeEvent::CrcError { offset: 32, .. }),
        "{ev:?}"
    );
    assert_eq!(
        ev[2..],
        [
            DecodeEvent::Resync {
                skipped_bytes: 16,
                at_offset: 48,
            },
            DecodeEvent::Gap {
                after_seq: 101,
                lost: 1,
            },
        ]
    );
    let s = samples(&items);
    assert_eq!(
        s.iter().map(|s| s.increment).collect::<Vec<_>>(),
        [10, 50, 40]
    );
    assert_eq!(
        s.iter().map(|s| s.lost_before).collect::<Vec<_>>(),
        [0, 1, 0]
    );
    assert_eq!(
        (st.crc_errors, st.false_syncs, st.resyncs, st.bytes_skipped),
        (1, 0, 1, 16)
    );
    assert_eq!((st.gaps, st.lost_samples, st.samples), (1, 1, 3));
}

#[test]
fn sync_pattern_inside_garbage_is_a_false_sync() {
    let frames = encode_increments(&mut FrameEncoder::new(0, 0), &[1, 1]).unwrap();
    let mut bytes = frames[0].to_vec();
    bytes.extend_from_slice(&[0x00, 0xA5, 0x5A, 0x01, 0x02]);
    bytes.extend(concat(&frames[1..]));
    let (items, st) = decode(&bytes);
    let ev = events(&items);
    assert_eq!(
        ev[1..],
        [
            DecodeEvent::FalseSync { offset: 17 },
            DecodeEvent::Resync {
                skipped_bytes: 5,
                at_offset: 21,
            },
        ]
    );
    assert_eq!((st.crc_errors, st.false_syncs, st.bytes_skipped), (0, 1, 5));
    assert_eq!(samples(&items).iter().map(|s| s.increment).sum::<i64>(), 2);
}

#[test]
fn garbage_starting_with_sync_where_a_frame_was_due_is_a_crc_error() {
    // The decoder cannot tell it from a corrupted frame: a sync with a bad CRC
    // on the frame grid counts as a CRC error (documented).
    let frames = encode_increments(&mut FrameEncoder::new(0, 0), &[1]).unwrap();
    let mut bytes = frames[0].to_vec();
    bytes.extend_from_slice(&[0xA5, 0x5A, 0x00, 0x00]);
    bytes.extend_from_slice(&frames[1]);
    let (_, st) = decode(&bytes);
    assert_eq!(
        (st.crc_errors, st.false_syncs, st.bytes_skipped, st.resyncs),
        (1, 0, 4, 1)
    );
}

#[test]
fn burst_of_corrupted_frames_counts_one_crc_error_each() {
    // Frames 2, 3, 4 corrupted back to back: their sync bytes stay on the grid
    // of frame 1, so each is a CRC error. Counter 0x0101_0101 + small steps and
    // seq < 256 keep 0xA5 0x5A out of the frame interiors (checked below).
    let frames =
        encode_increments(&mut FrameEncoder::new(1, 0x0101_0101), &[1, 1, 1, 1, 1]).unwrap();
    let mut bytes = concat(&frames);
    for k in 2..5 {
        bytes[k * 16 + 8] ^= 0x40; // temperature byte
    }
    let interior_syncs = (0..bytes.len() - 1)
        .filter(|&p| p % 16 != 0 && bytes[p] == 0xA5 && bytes[p + 1] == 0x5A)
        .count();
    assert_eq!(interior_syncs, 0);
    let (items, st) = decode(&bytes);
    assert_eq!(
        events(&items)
            .iter()
            .filter_map(|e| match e {
                DecodeEvent::CrcError { offset, .. } => Some(*offset),
                _ => None,
            })
            .collect::<Vec<_>>(),
        [32, 48, 64]
    );
    assert_eq!(
        (st.crc_errors, st.false_syncs, st.resyncs, st.bytes_skipped),
        (3, 0, 1, 48)
    );
    assert_eq!((st.gaps, st.lost_samples), (1, 3));
    assert_eq!(samples(&items).iter().map(|s| s.increment).sum::<i64>(), 5);
}

#[test]
fn sync_off_the_grid_after_a_corrupted_frame_is_a_false_sync() {
    // One garbage byte shifts the next (corrupted) frame off the grid.
    let frames = encode_increments(&mut FrameEncoder::new(1, 0x0101_0101), &[1, 1, 1]).unwrap();
    let mut bytes = frames[0].to_vec();
    bytes.push(0x00);
    let mut bad = frames[1];
    bad[9] ^= 0x01;
    bytes.extend_from_slice(&bad);
    bytes.extend(concat(&frames[2..]));
    let (items, st) = decode(&bytes);
    assert!(events(&items).contains(&DecodeEvent::FalseSync { offset: 17 }));
    assert_eq!(
        (st.crc_errors, st.false_syncs, st.bytes_skipped),
        (0, 1, 17)
    );
}

#[test]
fn duplicate_is_dropped_and_counted() {
    let frames = encode_increments(&mut FrameEncoder::new(0, 0), &[3, 4]).unwrap();
    let bytes = concat(&[frames[0], frames[1], frames[1], frames[2]]);
    let (items, st) = decode(&bytes);
    assert!(events(&items).contains(&DecodeEvent::Duplicate { seq: 1, offset: 32 }));
    assert_eq!(
        samples(&items)
            .iter()
            .map(|s| s.increment)
            .collect::<Vec<_>>(),
        [3, 4]
    );
    assert_eq!(
        (st.duplicates, st.frames_decoded, st.samples, st.gaps),
        (1, 4, 2, 0)
    );
}

#[test]
fn stale_frame_is_ignored_without_double_counting() {
    let frames = encode_increments(&mut FrameEncoder::new(10, 0), &[1, 2, 4, 8]).unwrap();
    // 10 11 12 [11 again, stale] 13 14
    let bytes = concat(&[
        frames[0], frames[1], frames[2], frames[1], frames[3], frames[4],
    ]);
    let (items, st) = decode(&bytes);
    assert!(events(&items).contains(&DecodeEvent::OutOfSequence {
        seq: 11,
        expected: 13,
        offset: 48,
    }));
    assert_eq!(
        samples(&items)
            .iter()
            .map(|s| s.increment)
            .collect::<Vec<_>>(),
        [1, 2, 4, 8]
    );
    assert_eq!((st.out_of_sequence, st.discontinuities, st.gaps), (1, 0, 0));
}

#[test]
fn restart_with_a_new_sequence_rebaselines() {
    let old = encode_increments(&mut FrameEncoder::new(40_000, 123_456), &[1, 1]).unwrap();
    let new = encode_increments(&mut FrameEncoder::new(0, 0), &[5, 6]).unwrap();
    let bytes = concat(&[old[0], old[1], old[2], new[0], new[1], new[2]]);
    let (items, st) = decode(&bytes);
    let ev = events(&items);
    assert!(ev.contains(&DecodeEvent::OutOfSequence {
        seq: 0,
        expected: 40_003,
        offset: 48,
    }));
    assert!(ev.contains(&DecodeEvent::Discontinuity {
        from_seq: 40_002,
        to_seq: 0,
        offset: 48,
    }));
    // The jump of the counter across the restart is not an increment.
    assert_eq!(
        samples(&items)
            .iter()
            .map(|s| s.increment)
            .collect::<Vec<_>>(),
        [1, 1, 5, 6]
    );
    assert_eq!(
        (st.out_of_sequence, st.discontinuities, st.samples),
        (1, 1, 4)
    );
}

#[test]
fn jump_beyond_max_gap_is_not_a_gap() {
    let cfg = DecoderConfig { max_gap: 10 };
    let a = encode_frame(0, 0, 0, 7);
    let gap_ok = encode_frame(11, 100, 0, 7); // 10 lost: accepted
    let too_far = encode_frame(23, 200, 0, 7); // 11 lost: out of sequence
    let next = encode_frame(12, 101, 0, 7);
    let (items, st) = FrameDecoder::decode_all(&concat(&[a, gap_ok, too_far, next]), cfg);
    assert_eq!(
        samples(&items)
            .iter()
            .map(|s| (s.increment, s.lost_before))
            .collect::<Vec<_>>(),
        [(100, 10), (1, 0)]
    );
    assert_eq!((st.gaps, st.lost_samples, st.out_of_sequence), (1, 10, 1));
}

#[test]
fn status_changes_are_events() {
    let mut enc = FrameEncoder::new(0, 0);
    let f0 = enc.current_frame();
    let f1 = enc.step(1).unwrap();
    enc.set_status(0b101); // PLC unlocked
    let f2 = enc.step(1).unwrap();
    enc.set_status(0b111);
    let f3 = enc.step(1).unwrap();
    let (items, st) = decode(&concat(&[f0, f1, f2, f3]));
    let changes: Vec<_> = events(&items)
        .into_iter()
        .filter(|e| matches!(e, DecodeEvent::StatusChange { .. }))
        .collect();
    assert_eq!(
        changes,
        [
            DecodeEvent::StatusChange {
                seq: 2,
                from: 0b111,
                to: 0b101
            },
            DecodeEvent::StatusChange {
                seq: 3,
                from: 0b101,
                to: 0b111
            },
        ]
    );
    assert_eq!(st.status_changes, 2);
}

#[test]
fn trailing_partial_frame_is_counted_not_an_error() {
    let frames = encode_increments(&mut FrameEncoder::new(0, 0), &[1, 2]).unwrap();
    let mut bytes = concat(&frames);
    bytes.extend_from_slice(&frames[0][..5]);
    let (items, st) = decode(&bytes);
    assert_eq!(
        items.last(),
        Some(&Decoded::Event(DecodeEvent::EndOfStream {
            skipped_bytes: 5,
            trailing_bytes: 5,
            at_offset: 53,
        }))
    );
    assert_eq!((st.trailing_bytes, st.bytes_skipped, st.samples), (5, 5, 2));
}

#[test]
fn trailing_garbage_without_sync_is_skipped_before_eof() {
    let frames = encode_increments(&mut FrameEncoder::new(0, 0), &[1]).unwrap();
    let mut bytes = concat(&frames);
    bytes.extend_from_slice(&[1, 2, 3, 0xA5]);
    // Without EOF the lone 0xA5 stays buffered (it could start a frame).
    let mut dec = FrameDecoder::new();
    let mut buf = BytesMut::from(&bytes[..]);
    let mut out = Vec::new();
    dec.decode_available(&mut buf, &mut out);
    assert_eq!(buf.len(), 1);
    assert_eq!(dec.stats().bytes_skipped, 3);
    dec.finish(&mut buf, &mut out);
    assert_eq!(
        out.last(),
        Some(&Decoded::Event(DecodeEvent::EndOfStream {
            skipped_bytes: 4,
            trailing_bytes: 1,
            at_offset: 36,
        }))
    );
    assert!(buf.is_empty());
    // Calling again after the end yields nothing more.
    assert_eq!(dec.decode_eof(&mut buf), None);
}

#[test]
fn reset_sequence_makes_a_new_baseline() {
    let frames = encode_increments(&mut FrameEncoder::new(0, 0), &[1, 2, 3]).unwrap();
    let mut dec = FrameDecoder::new();
    let mut buf = BytesMut::from(&concat(&frames[..2])[..]);
    let mut out = Vec::new();
    dec.decode_available(&mut buf, &mut out);
    dec.reset_sequence();
    buf.extend_from_slice(&concat(&frames[3..]));
    dec.finish(&mut buf, &mut out);
    assert_eq!(
        out.last(),
        Some(&Decoded::Event(DecodeEvent::Baseline {
            seq: 3,
            counter: 6,
            status: 7,
            offset: 32,
        }))
    );
    assert_eq!(dec.stats().samples, 1);
}

#[test]
fn exact_counts_after_known_corruption() {
    // 1000 frames across the seq and counter wraps, with hand-placed faults.
    let incs: Vec<i64> = (0..999).map(|k| (k % 7) - 2).collect();
    let frames = encode_increments(&mut FrameEncoder::new(65_500, 0xFFFF_FF00), &incs).unwrap();
    let mut plan = FaultPlan::none();
    plan.set_action(10, FrameAction::Drop)
        .set_action(11, FrameAction::Drop)
        .set_action(12, FrameAction::Drop)
        .set_action(100, FrameAction::FlipBit(40)) // counter byte: CRC error
        .set_action(200, FrameAction::FlipBit(3)) // sync byte: no candidate
        .set_action(300, FrameAction::Duplicate)
        .add_garbage_before(400, &[0; 7])
        .add_garbage_before(500, &[0xA5, 0x5A, 0, 0]); // sync at a frame boundary
    let inj = inject(&frames, &plan);
    let (items, st) = decode(&inj.bytes);
    // Hand-derived counts (see the plan above).
    assert_eq!(st.bytes_read, 16_000 - 3 * 16 + 16 + 7 + 4);
    assert_eq!(st.frames_decoded, 1000 - 3 - 2 + 1);
    assert_eq!(st.samples, 1000 - 3 - 2 - 1);
    assert_eq!(st.bytes_skipped, 16 + 16 + 7 + 4);
    assert_eq!(st.crc_errors, 2);
    assert_eq!(st.false_syncs, 0);
    assert_eq!(st.resyncs, 4);
    assert_eq!(st.gaps, 3);
    assert_eq!(st.lost_samples, 3 + 1 + 1);
    assert_eq!(st.duplicates, 1);
    assert_eq!(
        (st.out_of_sequence, st.discontinuities, st.trailing_bytes),
        (0, 0, 0)
    );
    // The ledger derives the same numbers.
    assert_eq!(inj.ledger.expected.mismatches(&st), vec![]);
    assert_eq!(
        (
            inj.ledger.dropped,
            inj.ledger.bit_flipped,
            inj.ledger.sync_flipped
        ),
        (3, 2, 1)
    );
    // No angle lost: first and last frames intact, so the increments (gap
    // increments included) sum to the true total.
    let total: i64 = samples(&items).iter().map(|s| s.increment).sum();
    assert_eq!(total, incs.iter().sum::<i64>());
    // Event-level accounting matches the counters.
    let ev = events(&items);
    let skipped_in_events: u64 = ev
        .iter()
        .map(|e| match e {
            DecodeEvent::Resync { skipped_bytes, .. } => *skipped_bytes,
            DecodeEvent::EndOfStream { skipped_bytes, .. } => *skipped_bytes,
            _ => 0,
        })
        .sum();
    assert_eq!(skipped_in_events, st.bytes_skipped);
    let lost_in_events: u64 = ev
        .iter()
        .map(|e| match e {
            DecodeEvent::Gap { lost, .. } => u64::from(*lost),
            _ => 0,
        })
        .sum();
    assert_eq!(lost_in_events, st.lost_samples);
}

#[test]
fn reserved_field_nonzero_is_accepted_and_counted() {
    let mut f = encode_frame(1, 10, 0, 7);
    f[12] = 0x01;
    let crc = sagnac::input::frame::crc16(&f[..14]);
    f[14..].copy_from_slice(&crc.to_le_bytes());
    let g = encode_frame(2, 11, 0, 7);
    let (items, st) = decode(&concat(&[f, g]));
    assert_eq!(samples(&items).len(), 1);
    assert_eq!(st.reserved_nonzero, 1);
}

/// `decode_run` (bulk runs) interleaved with `decode`, fed in uneven chunks:
/// the same increments, the same events in the same places, the same last
/// sample of every run and the same counts as decoding frame by frame.
#[test]
fn bulk_runs_decode_exactly_like_frame_by_frame() {
    use sagnac::input::frame::inject::InjectorConfig;
    // temperature and status vary (a status change ends a run), the counter wraps
    let mut frames = Vec::new();
    let mut counter = 0xFFFF_F000u32;
    for k in 0..6000u32 {
        let status = if (2000..2500).contains(&k) {
            0b011
        } else {
            0b111
        };
        counter = counter.wrapping_add((k * 7919) % 41).wrapping_sub(20);
        frames.push(encode_frame(
            (65_000 + k) as u16,
            counter,
            (k % 300) as i16 - 150,
            status,
        ));
    }
    for seed in 0..6u64 {
        let cfg = InjectorConfig {
            tail_max_len: 20,
            ..InjectorConfig::default()
        };
        let bytes = inject(&frames, &FaultPlan::random(frames.len(), &cfg, seed)).bytes;
        let (reference, ref_stats) = decode(&bytes);
        let ref_samples = samples(&reference);
        for max in [1usize, 7, 100_000] {
            let mut dec = FrameDecoder::new();
            let mut buf = BytesMut::new();
            let (mut incs, mut evs, mut runs) = (Vec::new(), Vec::new(), 0usize);
            let mut run = Vec::new();
            let mut fed = 0;
            let mut step = 1 + seed as usize * 37;
            loop {
                let eof = fed == bytes.len();
                run.clear();
                if let Some(end) = dec.decode_run(&mut buf, max, &mut run) {
                    assert!(run.len() <= max && run.len() == end.samples);
                    incs.extend_from_slice(&run);
                    // the run's last sample is the reference's sample at that place
                    let last = ref_samples[incs.len() - 1];
                    assert_eq!(
                        (end.seq, end.status, end.temp_c.to_bits()),
                        (last.seq, last.status, last.temp_c.to_bits())
                    );
                    runs += 1;
                    continue;
                }
                let item = if eof {
                    dec.decode_eof(&mut buf)
                } else {
                    dec.decode(&mut buf)
                };
                match item {
                    Some(Decoded::Sample(s)) => {
                        assert_eq!(s, ref_samples[incs.len()]);
                        incs.push(s.increment);
                    }
                    Some(Decoded::Event(e)) => evs.push((incs.len(), e)),
                    None if eof => break,
                    None => {
                        step = (step * 7 + 13) % 3001 + 1;
                        let end = (fed + step).min(bytes.len());
                        buf.extend_from_slice(&bytes[fed..end]);
                        fed = end;
                    }
                }
            }
            assert!(runs > 0);
            let ref_incs: Vec<i64> = ref_samples.iter().map(|s| s.increment).collect();
            assert_eq!(incs, ref_incs, "seed {seed} max {max}");
            let mut n = 0;
            let ref_evs: Vec<(usize, DecodeEvent)> = reference
                .iter()
                .filter_map(|d| match d {
                    Decoded::Sample(_) => {
                        n += 1;
                        None
                    }
                    Decoded::Event(e) => Some((n, *e)),
                })
                .collect();
            assert_eq!(evs, ref_evs, "seed {seed} max {max}");
            assert_eq!(*dec.stats(), ref_stats, "seed {seed} max {max}");
        }
    }
}
