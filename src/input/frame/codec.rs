//! `tokio_util::codec::Decoder` adapter around the sans-IO [`FrameDecoder`], so
//! the daemon can use `FramedRead` on a serial port and on a file alike.
//!
//! The only difference from the core decoder is the trait plumbing:
//! `decode_eof` is overridden so that a trailing partial frame at end of stream
//! is counted (`trailing_bytes`, [`EndOfStream`](super::DecodeEvent::EndOfStream)) instead of
//! tokio-util's default "bytes remaining on stream" error. Decoding never
//! fails; the error type only carries I/O errors of the underlying reader.

use bytes::BytesMut;

use super::{DecoderConfig, DecoderStats, FrameDecoder, FrameError, Single, Wire, WireDecoded};

/// `FramedRead::new(reader, FrameCodec::new())` yields [`super::Decoded`]
/// items; `FrameCodec::<Triad>::for_wire(config)` decodes triad frames.
#[derive(Debug, Clone)]
pub struct FrameCodec<W: Wire = Single> {
    decoder: FrameDecoder<W>,
}

impl Default for FrameCodec<Single> {
    fn default() -> Self {
        FrameCodec {
            decoder: FrameDecoder::default(),
        }
    }
}

impl FrameCodec<Single> {
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
}

impl<W: Wire> FrameCodec<W> {
    /// A codec for wire format `W` with `config`.
    pub fn for_wire(config: DecoderConfig) -> Self {
        FrameCodec {
            decoder: FrameDecoder::for_wire(config),
        }
    }

    /// Counts so far (reach it through `FramedRead::decoder()`).
    pub fn stats(&self) -> &DecoderStats {
        self.decoder.stats()
    }

    /// The wrapped decoder.
    pub fn decoder(&self) -> &FrameDecoder<W> {
        &self.decoder
    }

    /// The wrapped decoder, mutably (e.g. `reset_sequence` after a reconnect).
    pub fn decoder_mut(&mut self) -> &mut FrameDecoder<W> {
        &mut self.decoder
    }
}

impl<W: Wire> tokio_util::codec::Decoder for FrameCodec<W> {
    type Item = WireDecoded<W>;
    type Error = FrameError;

    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<WireDecoded<W>>, FrameError> {
        Ok(self.decoder.decode(src))
    }

    fn decode_eof(&mut self, src: &mut BytesMut) -> Result<Option<WireDecoded<W>>, FrameError> {
        Ok(self.decoder.decode_eof(src))
    }
}
