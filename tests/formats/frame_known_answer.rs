//! Known-answer tests of the gyro frame format: CRC, field layout,
//! counter-wrap increments, encoder output.

use sagnac::input::frame::{
    self, FRAME_LEN, FrameEncoder, FrameError, NotAFrame, RawFrame, STATUS_ALL_OK, check, crc16,
    crc16_frame, encode_frame, increment_between, parse,
};

/// Textbook bitwise CRC-16/CCITT-FALSE (MSB first, poly 0x1021, init 0xFFFF,
/// no reflection, no final xor), written independently of the `crc` crate.
fn crc16_bitwise(data: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for &b in data {
        crc ^= u16::from(b) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
        }
    }
    crc
}

#[test]
fn crc_check_value_123456789_is_0x29b1() {
    // Catalogue check value of CRC-16/CCITT-FALSE (= CRC-16/IBM-3740); exact.
    assert_eq!(crc16(b"123456789"), 0x29B1);
    assert_eq!(crc16_bitwise(b"123456789"), 0x29B1);
}

#[test]
fn crc_matches_independent_bitwise_implementation() {
    // Deterministic pseudo-random inputs of every length 0..64; exact equality.
    let mut x: u32 = 0x1234_5678;
    for len in 0..64 {
        let data: Vec<u8> = (0..len)
            .map(|_| {
                x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (x >> 24) as u8
            })
            .collect();
        assert_eq!(crc16(&data), crc16_bitwise(&data), "len {len}");
    }
}

/// Frame bytes computed independently with Python's `binascii.crc_hqx`
/// (CRC-CCITT, init given as 0xFFFF = CCITT-FALSE):
/// ```text
/// body = bytes([0xA5,0x5A]) + struct.pack('<HIhHH', 0x1234, 0xFFFFFFFE, -1234, 7, 0)
/// body + struct.pack('<H', binascii.crc_hqx(body, 0xFFFF))
///   -> a55a3412feffffff2efb070000002001   (CRC 0x0120)
/// body = bytes([0xA5,0x5A]) + bytes(12) -> ... e728   (CRC 0x28E7)
/// ```
const GOLDEN_1: [u8; 16] = [
    0xa5, 0x5a, 0x34, 0x12, 0xfe, 0xff, 0xff, 0xff, 0x2e, 0xfb, 0x07, 0x00, 0x00, 0x00, 0x20, 0x01,
];
const GOLDEN_ZERO: [u8; 16] = [0xa5, 0x5a, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0xe7, 0x28];

#[test]
fn hand_built_frame_decodes_to_its_fields() {
    assert_eq!(check(&GOLDEN_1), Ok(()));
    let f = parse(&GOLDEN_1).expect("16 bytes");
    assert_eq!(
        f,
        RawFrame {
            seq: 0x1234,
            counter: 0xFFFF_FFFE,
            temp_raw: -1234,
            status: 0x0007,
            reserved: 0,
            crc: 0x0120,
        }
    );
    // -1234 * 0.01 deg C; tolerance 1e-12 (one multiplication).
    assert!((f.temp_c() - (-12.34)).abs() < 1e-12, "{}", f.temp_c());
    assert_eq!(check(&GOLDEN_ZERO), Ok(()));
    assert_eq!(parse(&GOLDEN_ZERO).map(|f| f.crc), Some(0x28E7));
}

#[test]
fn encoder_reproduces_the_golden_frames() {
    assert_eq!(encode_frame(0x1234, 0xFFFF_FFFE, -1234, 7), GOLDEN_1);
    assert_eq!(encode_frame(0, 0, 0, 0), GOLDEN_ZERO);
}

#[test]
fn check_classifies_the_front_of_a_buffer() {
    assert_eq!(check(&[]), Err(NotAFrame::Incomplete { have: 0 }));
    assert_eq!(check(&[0xA5]), Err(NotAFrame::Incomplete { have: 1 }));
    assert_eq!(
        check(&GOLDEN_1[..15]),
        Err(NotAFrame::Incomplete { have: 15 })
    );
    // Decided early: a wrong first or second byte is NoSync even when short.
    assert_eq!(check(&[0x00]), Err(NotAFrame::NoSync));
    assert_eq!(check(&[0xA5, 0x00]), Err(NotAFrame::NoSync));
    let mut bad = GOLDEN_1;
    bad[6] ^= 0x10;
    assert_eq!(
        check(&bad),
        Err(NotAFrame::BadCrc {
            computed: crc16_bitwise(&bad[..14]),
            received: 0x0120,
        })
    );
    // Extra bytes after the frame do not matter.
    let mut longer = GOLDEN_1.to_vec();
    longer.extend_from_slice(&[1, 2, 3]);
    assert_eq!(check(&longer), Ok(()));
    assert_eq!(parse(&GOLDEN_1[..15]), None);
}

#[test]
fn every_single_bit_flip_is_detected() {
    // CRC-16/CCITT detects all single-bit errors; flips in the sync bytes are
    // NoSync instead. Exhaustive over the 128 bits.
    for bit in 0..128 {
        let mut f = GOLDEN_1;
        f[bit / 8] ^= 1 << (bit % 8);
        let r = check(&f);
        if bit < 16 {
            assert_eq!(r, Err(NotAFrame::NoSync), "bit {bit}");
        } else {
            assert!(
                matches!(r, Err(NotAFrame::BadCrc { .. })),
                "bit {bit}: {r:?}"
            );
        }
    }
}

#[test]
fn counter_wrap_increments() {
    // Exact integer answers.
    assert_eq!(increment_between(0xFFFF_FFFE, 0x0000_0003), 5);
    assert_eq!(increment_between(0x0000_0003, 0xFFFF_FFFE), -5);
    assert_eq!(increment_between(0x0000_0002, 0xFFFF_FFFD), -5); // down across 0
    assert_eq!(increment_between(100, 100), 0);
    assert_eq!(increment_between(0, 0x7FFF_FFFF), i64::from(i32::MAX));
    assert_eq!(increment_between(0, 0x8000_0000), i64::from(i32::MIN));
    assert_eq!(increment_between(0x8000_0000, 0x7FFF_FFFF), -1);
}

#[test]
fn encoder_steps_wrap_counter_and_seq() {
    let mut enc = FrameEncoder::new(0xFFFF, 0xFFFF_FFFE);
    let f0 = parse(&enc.current_frame()).unwrap();
    assert_eq!(
        (f0.seq, f0.counter, f0.status),
        (0xFFFF, 0xFFFF_FFFE, STATUS_ALL_OK)
    );
    let f1 = parse(&enc.step(5).unwrap()).unwrap();
    assert_eq!((f1.seq, f1.counter), (0x0000, 0x0000_0003));
    let f2 = parse(&enc.step(-5).unwrap()).unwrap();
    assert_eq!((f2.seq, f2.counter), (0x0001, 0xFFFF_FFFE));
    enc.set_temp_c(-40.004);
    enc.set_status(0b010);
    let f3 = parse(&enc.step(0).unwrap()).unwrap();
    assert_eq!((f3.temp_raw, f3.status), (-4000, 0b010));
}

#[test]
fn encoder_rejects_increments_a_32_bit_counter_cannot_carry() {
    let mut enc = FrameEncoder::new(7, 0);
    assert!(enc.step(i64::from(i32::MAX)).is_ok());
    assert!(enc.step(i64::from(i32::MIN)).is_ok());
    let err = enc.step(1 << 31).unwrap_err();
    assert!(matches!(
        err,
        FrameError::IncrementOutOfRange { seq: 10, increment } if increment == 1 << 31
    ));
    // State unchanged by the failed step.
    assert_eq!(enc.seq(), 9);
    assert!(err.to_string().contains("seq 10"), "{err}");
}

#[test]
fn frame_writer_writes_baseline_then_one_frame_per_increment() {
    let mut w = frame::FrameWriter::new(Vec::new(), FrameEncoder::new(10, 1000));
    w.write_increments(&[3, -2, 0]).unwrap();
    assert_eq!(w.bytes_written(), 4 * FRAME_LEN as u64);
    let bytes = w.into_inner().unwrap();
    let counters: Vec<u32> = bytes
        .chunks(FRAME_LEN)
        .map(|c| parse(c).unwrap().counter)
        .collect();
    assert_eq!(counters, [1000, 1003, 1001, 1001]);
    let seqs: Vec<u16> = bytes
        .chunks(FRAME_LEN)
        .map(|c| parse(c).unwrap().seq)
        .collect();
    assert_eq!(seqs, [10, 11, 12, 13]);
}

#[test]
fn table_frame_crc_equals_the_bytewise_crc() {
    // The decoder's position-table CRC against the crate and the bitwise
    // reference, on pseudo-random 14-byte heads and on single set bits; exact.
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    for _ in 0..20_000 {
        let mut head = [0u8; 14];
        for b in &mut head {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            *b = x as u8;
        }
        assert_eq!(crc16_frame(&head), crc16(&head), "{head:02x?}");
        assert_eq!(crc16_frame(&head), crc16_bitwise(&head), "{head:02x?}");
    }
    for bit in 0..14 * 8 {
        let mut head = [0u8; 14];
        head[bit / 8] = 1 << (bit % 8);
        assert_eq!(crc16_frame(&head), crc16_bitwise(&head), "bit {bit}");
    }
    assert_eq!(crc16_frame(&[0; 14]), crc16_bitwise(&[0; 14]));
}
