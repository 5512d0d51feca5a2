//! The tokio_util codec adapter: `FramedRead` over a chunked in-memory pipe,
//! a file and a pseudo-terminal pair yields exactly what the synchronous
//! decoder yields, and a trailing partial frame at EOF is counted, not an error.

use std::time::Duration;

use futures_util::StreamExt;
use sagnac::input::frame::codec::FrameCodec;
use sagnac::input::frame::inject::{FaultPlan, InjectorConfig, inject};
use sagnac::input::frame::{
    DecodeEvent, Decoded, DecoderConfig, FrameDecoder, FrameEncoder, encode_increments,
};
use tokio::io::{AsyncRead, AsyncWriteExt};
use tokio_util::codec::FramedRead;

/// A corrupted stream of 2001 frames ending in a 9-byte partial frame.
fn corrupted_stream() -> Vec<u8> {
    let incs: Vec<i64> = (0..2000).map(|k| (k * 37 % 11) - 5).collect();
    let frames = encode_increments(&mut FrameEncoder::new(65_000, 0xFFFF_F000), &incs).unwrap();
    let cfg = InjectorConfig {
        drop_prob: 0.02,
        flip_prob: 0.02,
        duplicate_prob: 0.01,
        garbage_prob: 0.02,
        ..InjectorConfig::default()
    };
    let mut plan = FaultPlan::random(frames.len(), &cfg, 42);
    plan.tail = frames[5][..9].to_vec();
    inject(&frames, &plan).bytes
}

async fn collect<R: AsyncRead + Unpin>(framed: &mut FramedRead<R, FrameCodec>) -> Vec<Decoded> {
    let mut items = Vec::new();
    while let Some(item) = framed.next().await {
        items.push(item.expect("frame decoding never fails"));
    }
    items
}

#[tokio::test]
async fn framed_read_over_a_chunked_pipe_matches_the_sync_decoder() {
    let bytes = corrupted_stream();
    let (expected, expected_stats) = FrameDecoder::decode_all(&bytes, DecoderConfig::default());
    assert!(expected_stats.crc_errors > 0 && expected_stats.gaps > 0);
    assert_eq!(expected_stats.trailing_bytes, 9);

    let (mut tx, rx) = tokio::io::duplex(37);
    let to_send = bytes.clone();
    let writer = tokio::spawn(async move {
        for chunk in to_send.chunks(13) {
            tx.write_all(chunk).await.unwrap();
        }
        // dropping tx is EOF
    });
    let mut framed = FramedRead::new(rx, FrameCodec::new());
    let items = collect(&mut framed).await;
    writer.await.unwrap();
    assert_eq!(items, expected);
    assert_eq!(*framed.decoder().stats(), expected_stats);
    assert!(matches!(
        items.last(),
        Some(Decoded::Event(DecodeEvent::EndOfStream {
            trailing_bytes: 9,
            ..
        }))
    ));
}

#[tokio::test]
async fn framed_read_on_a_file_counts_the_trailing_partial_frame() {
    let bytes = corrupted_stream();
    let (expected, expected_stats) = FrameDecoder::decode_all(&bytes, DecoderConfig::default());
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("capture.bin");
    std::fs::write(&path, &bytes).unwrap();
    let file = tokio::fs::File::open(&path).await.unwrap();
    let mut framed = FramedRead::new(file, FrameCodec::new());
    let items = collect(&mut framed).await;
    assert_eq!(items, expected);
    assert_eq!(*framed.decoder().stats(), expected_stats);
}

#[tokio::test]
async fn framed_read_over_a_pseudo_terminal_pair() {
    // The daemon's serial path: tokio-serial's in-process pty pair (raw mode).
    let (mut master, slave) = tokio_serial::SerialStream::pair().expect("pty pair");
    let incs: Vec<i64> = (0..3000)
        .map(|k| (k % 5) - 2 + if k % 97 == 0 { 1 << 20 } else { 0 })
        .collect();
    let frames = encode_increments(&mut FrameEncoder::new(1, 0), &incs).unwrap();
    let bytes = frames.concat();
    let writer = tokio::spawn(async move {
        for chunk in bytes.chunks(100) {
            master.write_all(chunk).await.unwrap();
        }
        master.flush().await.unwrap();
        master // keep the master open until the reader is done
    });
    let mut framed = FramedRead::new(slave, FrameCodec::new());
    let mut got = Vec::new();
    let read = async {
        while got.len() < incs.len() {
            match framed.next().await {
                Some(Ok(Decoded::Sample(s))) => got.push(s.increment),
                Some(Ok(Decoded::Event(_))) => {}
                other => panic!("unexpected end of pty stream: {other:?}"),
            }
        }
    };
    tokio::time::timeout(Duration::from_secs(20), read)
        .await
        .expect("pty delivered all frames within 20 s");
    let _master = writer.await.unwrap();
    assert_eq!(got, incs);
    let st = framed.decoder().stats();
    assert_eq!((st.bytes_skipped, st.crc_errors, st.gaps), (0, 0, 0));
}

/// The same adapter on the triad wire: a corrupted triad stream through a
/// chunked pipe yields exactly what the synchronous triad decoder yields.
#[tokio::test]
async fn triad_framed_read_over_a_chunked_pipe_matches_the_sync_decoder() {
    use sagnac::input::frame::inject::inject_wire;
    use sagnac::input::frame::triad::encode_triad_increments;
    use sagnac::input::frame::{Triad, TriadEncoder};
    let incs: Vec<[i64; 3]> = (0..2000)
        .map(|k| [(k * 37 % 11) - 5, k % 3, -(k % 7)])
        .collect();
    let frames = encode_triad_increments(
        &mut TriadEncoder::new(65_000, [0xFFFF_F000, 7, u32::MAX]),
        &incs,
    )
    .unwrap();
    let cfg = InjectorConfig {
        drop_prob: 0.02,
        flip_prob: 0.02,
        garbage_prob: 0.02,
        ..InjectorConfig::default()
    };
    let mut plan = FaultPlan::random_for::<Triad>(frames.len(), &cfg, 43);
    plan.tail = frames[5][..11].to_vec();
    let bytes = inject_wire::<Triad>(&frames, &plan).bytes;
    let (expected, expected_stats) =
        FrameDecoder::<Triad>::decode_all_wire(&bytes, DecoderConfig::default());
    assert!(
        expected_stats.crc_errors > 0
            && expected_stats.gaps > 0
            && expected_stats.trailing_bytes == 11
    );
    let (mut tx, rx) = tokio::io::duplex(41);
    let writer = tokio::spawn(async move {
        for chunk in bytes.chunks(17) {
            tx.write_all(chunk).await.unwrap();
        }
    });
    let mut framed = FramedRead::new(rx, FrameCodec::<Triad>::for_wire(DecoderConfig::default()));
    let mut items = Vec::new();
    while let Some(item) = framed.next().await {
        items.push(item.expect("frame decoding never fails"));
    }
    writer.await.unwrap();
    assert_eq!(items, expected);
    assert_eq!(*framed.decoder().stats(), expected_stats);
}
