//! Fuzz target: triad frames built from fuzzer-chosen increments, corrupted by
//! a fuzzer-chosen fault plan; the triad decoder's counts must equal the
//! injector's ledger and no angle may be lost on any axis between the first
//! and last intact frames. Raw fuzzer bytes are also decoded directly (no
//! panic, exact byte accounting).
#![no_main]

use libfuzzer_sys::fuzz_target;
use sagnac::input::frame::inject::{FaultPlan, FrameAction, inject_wire};
use sagnac::input::frame::triad::encode_triad_increments;
use sagnac::input::frame::{Decoded, DecoderConfig, FrameDecoder, Triad, TriadEncoder};

fuzz_target!(|input: &[u8]| {
    let (_, st) = FrameDecoder::<Triad>::decode_all_wire(input, DecoderConfig::default());
    assert_eq!(st.bytes_read, 24 * st.frames_decoded + st.bytes_skipped);
    // Layout: 2 bytes start seq, 4 bytes start counter (all axes, offset per
    // axis), then 8-byte records [x i16, y i16, z i16, fault byte, garbage byte].
    if input.len() < 6 {
        return;
    }
    let start_seq = u16::from_le_bytes([input[0], input[1]]);
    let c0 = u32::from_le_bytes([input[2], input[3], input[4], input[5]]);
    let start = [c0, c0.wrapping_add(0x8000_0000), c0.wrapping_neg()];
    let recs: Vec<&[u8]> = input[6..].chunks_exact(8).collect();
    let incs: Vec<[i64; 3]> = recs
        .iter()
        .map(|r| {
            let shift = r[7] & 0x0F;
            [0, 2, 4].map(|k| i64::from(i16::from_le_bytes([r[k], r[k + 1]])) << shift)
        })
        .collect();
    let Ok(frames) = encode_triad_increments(&mut TriadEncoder::new(start_seq, start), &incs) else {
        return;
    };
    let mut plan = FaultPlan::none();
    for (i, r) in recs.iter().enumerate() {
        let idx = i + 1; // frame 0 is the baseline
        match r[6] >> 5 {
            0 => {
                plan.set_action(idx, FrameAction::Drop);
            }
            1 => {
                plan.set_action(idx, FrameAction::FlipBit(r[6].wrapping_mul(7)));
            }
            2 => {
                plan.set_action(idx, FrameAction::Duplicate);
            }
            3 => {
                plan.add_garbage_before(idx, &[0xA5, 0x5B, r[7], r[1]]);
            }
            4 => {
                plan.add_garbage_before(idx, &r[..]);
            }
            _ => {}
        }
    }
    let inj = inject_wire::<Triad>(&frames, &plan);
    let e = inj.ledger.expected;
    if e.spurious_windows != 0 || e.max_seq_step > 4097 {
        return; // outside the ledger's validity conditions
    }
    let (items, st) = FrameDecoder::<Triad>::decode_all_wire(&inj.bytes, DecoderConfig::default());
    assert_eq!(e.mismatches(&st), vec![]);
    let mut got = [0i64; 3];
    for d in &items {
        if let Decoded::Sample(s) = d {
            for k in 0..3 {
                got[k] += s.increment[k];
            }
        }
    }
    if let (Some(&first), Some(&last)) = (inj.ledger.intact.first(), inj.ledger.intact.last()) {
        for k in 0..3 {
            let fits = inj.ledger.intact.windows(2).all(|w| {
                let step: i64 = incs[w[0]..w[1]].iter().map(|i| i[k]).sum();
                i32::try_from(step).is_ok()
            });
            if fits {
                assert_eq!(got[k], incs[first..last].iter().map(|i| i[k]).sum::<i64>());
            }
        }
    }
});
