//! Every axis of a multi-axis input through its own pipeline at once: the
//! six axes of a ROS 2 bag in one pass over the bag (a reader thread fans
//! each block out to one thread per axis, through bounded channels, so
//! memory stays a few blocks per axis), and the gyros of a triad capture or
//! of a recording of several gyros each in its own pass, side by side. The
//! threads share the cores; each axis's numbers are those [`feed::run`]
//! gives for it alone.

use std::sync::mpsc::{Receiver, SyncSender, sync_channel};

use super::PipelineError;
use super::feed::{self, Fed};
use crate::input::{Block, BlockSource, Input, InputError, StreamReport};

/// Blocks in flight per axis.
const IN_FLIGHT: usize = 4;

/// One axis of the input, and what its pipeline made of it.
#[derive(Debug)]
pub struct AxisRun {
    /// The axis (`gyro_x`, `accel_z`, `x`, ...).
    pub label: String,
    /// The input read for this axis.
    pub input: Input,
    pub fed: Fed,
}

enum Msg {
    Block(Block),
    End(StreamReport),
}

/// One axis of the fan-out, as a [`BlockSource`].
struct Channel {
    rx: Receiver<Msg>,
    report: StreamReport,
}

impl BlockSource for Channel {
    fn next_block(&mut self, block: &mut Block) -> Result<bool, InputError> {
        match self.rx.recv() {
            Ok(Msg::Block(b)) => {
                *block = b;
                Ok(true)
            }
            Ok(Msg::End(r)) => {
                self.report = r;
                Ok(false)
            }
            // the reader stopped on an error: it is the one reported
            Err(_) => Ok(false),
        }
    }
    fn report(&self) -> StreamReport {
        self.report.clone()
    }
}

/// Run each of `input`'s axes ([`Input::axes`]) through a pipeline
/// (`data_quality`: with the data-quality stage), in the order of the axes.
pub fn run_axes(input: &Input, data_quality: bool) -> Result<Vec<AxisRun>, PipelineError> {
    let labels = input.axes();
    let inputs = labels
        .iter()
        .map(|l| input.for_axis(l))
        .collect::<Result<Vec<_>, _>>()?;
    let run_one = |one: &Input, first: Option<&mut dyn BlockSource>| {
        let mut cfg = feed::config_for(one)?;
        cfg.data_quality = data_quality;
        match first {
            Some(src) => feed::run_from(one, src, &cfg, &mut |_, _| {}, None),
            None => feed::run(one, &cfg, &mut |_, _| {}, None),
        }
    };
    let feds: Vec<Result<Fed, PipelineError>> = match input.stream_all_axes() {
        Some(all) => {
            let mut all = all?;
            let (txs, rxs): (Vec<SyncSender<Msg>>, Vec<Receiver<Msg>>) =
                labels.iter().map(|_| sync_channel(IN_FLIGHT)).unzip();
            std::thread::scope(|s| {
                let reader = s.spawn(move || fan_out(&mut all, &txs));
                let workers: Vec<_> = inputs
                    .iter()
                    .zip(rxs)
                    .map(|(one, rx)| {
                        s.spawn(move || {
                            let mut ch = Channel {
                                rx,
                                report: StreamReport::default(),
                            };
                            run_one(one, Some(&mut ch))
                        })
                    })
                    .collect();
                let feds: Vec<_> = workers
                    .into_iter()
                    .map(|w| w.join().expect("axis thread"))
                    .collect();
                reader.join().expect("reader thread")?;
                Ok::<_, PipelineError>(feds)
            })?
        }
        None => std::thread::scope(|s| {
            let workers: Vec<_> = inputs
                .iter()
                .map(|one| s.spawn(move || run_one(one, None)))
                .collect();
            workers
                .into_iter()
                .map(|w| w.join().expect("axis thread"))
                .collect()
        }),
    };
    labels
        .into_iter()
        .zip(inputs)
        .zip(feds)
        .map(|((label, input), fed)| {
            Ok(AxisRun {
                label,
                input,
                fed: fed?,
            })
        })
        .collect()
}

/// Read every axis at once and send each its blocks, then the pass's report.
fn fan_out(
    all: &mut crate::input::ros2::Ros2Stream,
    txs: &[SyncSender<Msg>],
) -> Result<(), InputError> {
    let mut blocks = vec![Block::default(); txs.len()];
    let mut report = StreamReport::default();
    while all.next_blocks(&mut blocks)? {
        report.samples += blocks[0].len() as u64;
        report.gaps += blocks[0].gaps;
        report.lost_samples += blocks[0].lost_samples;
        for (tx, b) in txs.iter().zip(&mut blocks) {
            // an axis that failed has hung up: the others go on
            let _ = tx.send(Msg::Block(std::mem::take(b)));
        }
    }
    report.stamps = Some(all.report().clone());
    for tx in txs {
        let _ = tx.send(Msg::End(report.clone()));
    }
    Ok(())
}
