//! Fuzz target: frames built from fuzzer-chosen increments, corrupted by a
//! fuzzer-chosen fault plan; the decoder's counts must equal the injector's
//! ledger and no angle may be lost between the first and last intact frames.
#![no_main]

use libfuzzer_sys::fuzz_target;
use sagnac::input::frame::inject::{FaultPlan, FrameAction, inject};
use sagnac::input::frame::{Decoded, DecoderConfig, FrameDecoder, FrameEncoder, encode_increments};

fuzz_target!(|input: &[u8]| {
    // Layout: 2 bytes start seq, 4 bytes start counter, then 4-byte records
    // [increment i16 LE, fault byte, garbage byte].
    if input.len() < 6 {
        return;
    }
    let start_seq = u16::from_le_bytes([input[0], input[1]]);
    let start_counter = u32::from_le_bytes([input[2], input[3], input[4], input[5]]);
    let recs: Vec<&[u8]> = input[6..].chunks_exact(4).collect();
    let incs: Vec<i64> = recs
        .iter()
        .map(|r| i64::from(i16::from_le_bytes([r[0], r[1]])) << (r[3] & 0x0F))
        .collect();
    let Ok(frames) = encode_increments(&mut FrameEncoder::new(start_seq, start_counter), &incs)
    else {
        return;
    };
    let mut plan = FaultPlan::none();
    for (i, r) in recs.iter().enumerate() {
        let idx = i + 1; // frame 0 is the baseline
        match r[2] >> 5 {
            0 => {
                plan.set_action(idx, FrameAction::Drop);
            }
            1 => {
                plan.set_action(idx, FrameAction::FlipBit(r[2]));
            }
            2 => {
                plan.set_action(idx, FrameAction::Duplicate);
            }
            3 => {
                plan.add_garbage_before(idx, &[0xA5, 0x5A, r[3], r[1]]);
            }
            4 => {
                plan.add_garbage_before(idx, &r[..]);
            }
            _ => {}
        }
    }
    let inj = inject(&frames, &plan);
    let e = inj.ledger.expected;
    if e.spurious_windows != 0 || e.max_seq_step > 4097 {
        return; // outside the ledger's validity conditions
    }
    let (items, st) = FrameDecoder::decode_all(&inj.bytes, DecoderConfig::default());
    assert_eq!(e.mismatches(&st), vec![]);
    let got: i64 = items
        .iter()
        .map(|d| match d {
            Decoded::Sample(s) => s.increment,
            Decoded::Event(_) => 0,
        })
        .sum();
    // No angle lost, provided each step between intact frames carries fewer
    // than 2^31 pulses (beyond that a wrapping 32-bit difference is ambiguous).
    let fits = inj.ledger.intact.windows(2).all(|w| {
        let step: i64 = incs[w[0]..w[1]].iter().sum();
        i32::try_from(step).is_ok()
    });
    if let (Some(&first), Some(&last), true) =
        (inj.ledger.intact.first(), inj.ledger.intact.last(), fits)
    {
        assert_eq!(got, incs[first..last].iter().sum::<i64>());
    }
});
