//! A pass read ahead on a thread of its own: the input's reading and
//! decoding (CSV parsing, frame decoding, decompression) run on one core
//! while the caller's numerics run on another. The blocks, their order and
//! what the pass met are exactly the [`Stream`]'s.

use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, sync_channel};
use std::thread::JoinHandle;

use super::{Block, BlockSource, InputError, Stream, StreamReport};

/// Blocks read ahead at most (each up to 64 Ki samples).
const AHEAD: usize = 3;

/// A [`Stream`] read on its own thread; a [`BlockSource`].
pub struct Prefetch {
    blocks: Receiver<Result<Block, InputError>>,
    /// Blocks handed back for the reader to fill again.
    spent: SyncSender<Block>,
    reader: Option<JoinHandle<StreamReport>>,
    report: StreamReport,
    done: bool,
}

impl Prefetch {
    /// Start reading `stream` ahead.
    pub fn new(stream: Stream) -> Result<Prefetch, InputError> {
        let path = stream.path().to_path_buf();
        let (tx, blocks) = sync_channel(AHEAD);
        let (spent, spent_rx) = sync_channel(AHEAD + 2);
        let reader = std::thread::Builder::new()
            .name("sagnac-read".into())
            .spawn(move || read_ahead(stream, &tx, &spent_rx))
            .map_err(|source| InputError::Open { path, source })?;
        Ok(Prefetch {
            blocks,
            spent,
            reader: Some(reader),
            report: StreamReport::default(),
            done: false,
        })
    }

    fn finish(&mut self) {
        self.done = true;
        if let Some(reader) = self.reader.take() {
            // the reader has sent its last message and returns at once
            if let Ok(report) = reader.join() {
                self.report = report;
            }
        }
    }
}

/// The reader thread: every block of `stream` into `tx` (an error ends the
/// pass), refilling the blocks the consumer handed back; what the pass met.
fn read_ahead(
    mut stream: Stream,
    tx: &SyncSender<Result<Block, InputError>>,
    spent: &Receiver<Block>,
) -> StreamReport {
    loop {
        let mut block = match spent.try_recv() {
            Ok(b) => b,
            Err(TryRecvError::Empty | TryRecvError::Disconnected) => Block::default(),
        };
        let sent = match stream.next_block(&mut block) {
            Ok(true) => tx.send(Ok(block)),
            Ok(false) => break,
            Err(e) => {
                let _ = tx.send(Err(e));
                break;
            }
        };
        if sent.is_err() {
            // the consumer stopped reading
            break;
        }
    }
    stream.report()
}

impl BlockSource for Prefetch {
    fn next_block(&mut self, block: &mut Block) -> Result<bool, InputError> {
        if self.done {
            block.clear();
            return Ok(false);
        }
        match self.blocks.recv() {
            Ok(Ok(next)) => {
                let old = std::mem::replace(block, next);
                let _ = self.spent.try_send(old);
                Ok(true)
            }
            Ok(Err(e)) => {
                self.finish();
                Err(e)
            }
            Err(_) => {
                self.finish();
                block.clear();
                Ok(false)
            }
        }
    }

    /// What the pass met: complete once [`BlockSource::next_block`] returned
    /// `false` (or an error); empty before.
    fn report(&self) -> StreamReport {
        self.report.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::{Input, Request};

    fn blocks(source: &mut dyn BlockSource) -> Result<(Vec<Block>, StreamReport), InputError> {
        let mut out = Vec::new();
        let mut b = Block::default();
        while source.next_block(&mut b)? {
            out.push(b.clone());
        }
        Ok((out, source.report()))
    }

    fn csv(text: &str) -> (tempfile::TempDir, Input) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.csv");
        std::fs::write(&path, text).unwrap();
        let req = Request {
            sample_rate_hz: Some(100.0),
            pulse_arcsec: Some(1.0),
            // the bad line of the second test is past the first samples
            whole_on_first_samples: true,
            ..Request::default()
        };
        let input = Input::open(&path, &req).unwrap();
        (dir, input)
    }

    #[test]
    fn the_blocks_and_the_report_are_the_streams() {
        let mut text = String::from("counts,temp_c\n");
        for i in 0..200_000i64 {
            text.push_str(&format!("{},{}\n", (i * 7919) % 11 - 5, 20 + i % 3));
        }
        let (_dir, input) = csv(&text);
        let direct = blocks(&mut input.stream().unwrap()).unwrap();
        let ahead = blocks(&mut Prefetch::new(input.stream().unwrap()).unwrap()).unwrap();
        assert!(direct.0.len() >= 3, "several blocks: {}", direct.0.len());
        assert_eq!(direct, ahead);
        assert_eq!(ahead.1.samples, 200_000);
    }

    #[test]
    fn an_error_arrives_after_the_blocks_before_it() {
        let mut text = String::from("counts\n");
        for i in 0..100_000 {
            text.push_str(if i == 90_000 { "x\n" } else { "1\n" });
        }
        let (_dir, input) = csv(&text);
        let mut ahead = Prefetch::new(input.stream().unwrap()).unwrap();
        let mut b = Block::default();
        let mut seen = 0;
        let err = loop {
            match ahead.next_block(&mut b) {
                Ok(true) => seen += b.len(),
                Ok(false) => panic!("the bad line was not reported"),
                Err(e) => break e.to_string(),
            }
        };
        assert_eq!(seen, 1 << 16);
        assert!(err.contains("line 90002"), "{err}");
        assert!(!ahead.next_block(&mut b).unwrap());
    }
}
