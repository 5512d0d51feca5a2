//! `tokio_util::codec::Decoder` adapter around the sans-IO [`FrameDecoder`], so
//! the daemon can use `FramedRead` on a serial port and on a file alike.
//!
//! The only difference from the core decoder is the trait plumbing:
//! `decode_eof` is overridden so that a trailing partial frame at end of stream
//! is counted (`trailing_bytes`, [`EndOfStream`](super::DecodeEvent::EndOfStream)) instead of
//! tokio-util's default "bytes remaining on stream" error. Decoding never
//! fails; the error type only carries I/O errors of the underlying reader.

use bytes::BytesMut;

use super::{Decoded, DecoderConfig, DecoderStats, FrameDecoder, FrameError};

/// `FramedRead::new(reader, FrameCodec::new())` yields [`Decoded`] items.
#[derive(Debug, Clone, Default)]
pub struct FrameCodec {
    decoder: FrameDecoder,
}

impl FrameCodec {
    /// With the default decoder configuration.
    pub fn new() -> Self {
        Self::default()
    }

    /// With `config`.
    pub fn with_config(config: DecoderConfig) -> Self {
        FrameCodec {
            decoder: FrameDecoder::with_config(config),
        }
    }

    /// Counts so far (reach it through `FramedRead::decoder()`).
    pub fn stats(&self) -> &DecoderStats {
        self.decoder.stats()
    }

    /// The wrapped decoder.
    pub fn decoder(&self) -> &FrameDecoder {
        &self.decoder
    }

    /// The wrapped decoder, mutably (e.g. `reset_sequence` after a reconnect).
    pub fn decoder_mut(&mut self) -> &mut FrameDecoder {
        &mut self.decoder
    }
}

impl tokio_util::codec::Decoder for FrameCodec {
    type Item = Decoded;
    type Error = FrameError;

    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<Decoded>, FrameError> {
        Ok(self.decoder.decode(src))
    }

    fn decode_eof(&mut self, src: &mut BytesMut) -> Result<Option<Decoded>, FrameError> {
        Ok(self.decoder.decode_eof(src))
    }
}
