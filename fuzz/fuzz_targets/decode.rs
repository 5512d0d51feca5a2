//! Fuzz target: any byte stream decodes without panic; byte accounting is
//! exact; chunked decoding equals one-shot decoding. The first input byte picks
//! the chunk size and the decoder's `max_gap`.
#![no_main]

use bytes::BytesMut;
use libfuzzer_sys::fuzz_target;
use sagnac::input::frame::{DecodeEvent, Decoded, DecoderConfig, FRAME_LEN, FrameDecoder};

fuzz_target!(|input: &[u8]| {
    let Some((&knob, data)) = input.split_first() else {
        return;
    };
    let cfg = DecoderConfig {
        max_gap: if knob & 0x80 != 0 { u16::from(knob & 0x0F) } else { 4096 },
    };
    let (one, st) = FrameDecoder::decode_all(data, cfg);
    assert_eq!(st.bytes_read, data.len() as u64);
    assert_eq!(st.bytes_read, FRAME_LEN as u64 * st.frames_decoded + st.bytes_skipped);
    let skipped_in_events: u64 = one
        .iter()
        .map(|d| match d {
            Decoded::Event(DecodeEvent::Resync { skipped_bytes, .. })
            | Decoded::Event(DecodeEvent::EndOfStream { skipped_bytes, .. }) => *skipped_bytes,
            _ => 0,
        })
        .sum();
    assert_eq!(skipped_in_events, st.bytes_skipped);
    let n_samples = one.iter().filter(|d| matches!(d, Decoded::Sample(_))).count();
    assert_eq!(n_samples as u64, st.samples);

    let chunk = usize::from(knob & 0x3F).max(1);
    let mut dec = FrameDecoder::with_config(cfg);
    let mut buf = BytesMut::new();
    let mut out = Vec::new();
    for c in data.chunks(chunk) {
        buf.extend_from_slice(c);
        dec.decode_available(&mut buf, &mut out);
        let s = dec.stats();
        assert!(buf.len() < FRAME_LEN);
        assert_eq!(
            s.bytes_read,
            FRAME_LEN as u64 * s.frames_decoded + s.bytes_skipped + buf.len() as u64
        );
    }
    dec.finish(&mut buf, &mut out);
    assert!(buf.is_empty());
    assert_eq!(out, one);
    assert_eq!(*dec.stats(), st);
});
