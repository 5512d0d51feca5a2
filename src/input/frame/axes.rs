//! Gyros per frame: a wire format's decoder output split into one stream per
//! gyro. The single frame carries one gyro; the triad frame three (`x`, `y`,
//! `z`), which share the frame's sequence number, gaps, temperature, status
//! and framing errors, and each have their own counter.

use super::{DecodeEvent, Decoded, Sample, Single, Triad, Wire, WireDecoded};

/// A wire format whose frames carry [`Axes::GYROS`] gyros.
pub trait Axes: Wire {
    /// Gyros per frame.
    const GYROS: usize;
    /// Their default labels, in frame order.
    const LABELS: &'static [&'static str];
    /// Gyro `axis`'s view of a decoder item.
    fn axis(item: &WireDecoded<Self>, axis: usize) -> Decoded;
    /// Gyro `axis`'s increments of a run from
    /// [`FrameDecoder::decode_run`](super::FrameDecoder::decode_run): the run
    /// itself when the frame carries one gyro (no copy), else split out into
    /// `scratch` (cleared first).
    fn axis_run<'a>(
        run: &'a [Self::Increment],
        axis: usize,
        scratch: &'a mut Vec<i64>,
    ) -> &'a [i64];
}

/// `ev` with its counter (a baseline's) mapped by `f`.
fn map_event<C: Copy>(ev: &DecodeEvent<C>, f: impl Fn(C) -> u32) -> DecodeEvent {
    match *ev {
        DecodeEvent::Baseline {
            seq,
            counter,
            status,
            offset,
        } => DecodeEvent::Baseline {
            seq,
            counter: f(counter),
            status,
            offset,
        },
        DecodeEvent::Resync {
            skipped_bytes,
            at_offset,
        } => DecodeEvent::Resync {
            skipped_bytes,
            at_offset,
        },
        DecodeEvent::CrcError {
            offset,
            computed,
            received,
        } => DecodeEvent::CrcError {
            offset,
            computed,
            received,
        },
        DecodeEvent::FalseSync { offset } => DecodeEvent::FalseSync { offset },
        DecodeEvent::Gap { after_seq, lost } => DecodeEvent::Gap { after_seq, lost },
        DecodeEvent::StatusChange { seq, from, to } => DecodeEvent::StatusChange { seq, from, to },
        DecodeEvent::Duplicate { seq, offset } => DecodeEvent::Duplicate { seq, offset },
        DecodeEvent::OutOfSequence {
            seq,
            expected,
            offset,
        } => DecodeEvent::OutOfSequence {
            seq,
            expected,
            offset,
        },
        DecodeEvent::Discontinuity {
            from_seq,
            to_seq,
            offset,
        } => DecodeEvent::Discontinuity {
            from_seq,
            to_seq,
            offset,
        },
        DecodeEvent::EndOfStream {
            skipped_bytes,
            trailing_bytes,
            at_offset,
        } => DecodeEvent::EndOfStream {
            skipped_bytes,
            trailing_bytes,
            at_offset,
        },
    }
}

impl Axes for Single {
    const GYROS: usize = 1;
    const LABELS: &'static [&'static str] = &["gyro"];

    fn axis(item: &WireDecoded<Self>, _axis: usize) -> Decoded {
        *item
    }

    fn axis_run<'a>(run: &'a [i64], _axis: usize, _scratch: &'a mut Vec<i64>) -> &'a [i64] {
        run
    }
}

impl Axes for Triad {
    const GYROS: usize = 3;
    const LABELS: &'static [&'static str] = &super::triad::AXES;

    fn axis(item: &WireDecoded<Self>, axis: usize) -> Decoded {
        match item {
            Decoded::Sample(s) => Decoded::Sample(Sample {
                seq: s.seq,
                counter: s.counter[axis],
                increment: s.increment[axis],
                lost_before: s.lost_before,
                temp_c: s.temp_c,
                status: s.status,
                offset: s.offset,
            }),
            Decoded::Event(ev) => Decoded::Event(map_event(ev, |c| c[axis])),
        }
    }

    fn axis_run<'a>(run: &'a [[i64; 3]], axis: usize, scratch: &'a mut Vec<i64>) -> &'a [i64] {
        scratch.clear();
        scratch.extend(run.iter().map(|inc| inc[axis]));
        scratch
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::frame::{DecoderConfig, FrameDecoder, TriadEncoder};
    use bytes::BytesMut;

    #[test]
    fn a_triad_stream_splits_into_the_three_single_streams() {
        // three counters with different increments, a gap and a wrap of x
        let incs: Vec<[i64; 3]> = (0..200)
            .map(|i| [i * 7 - 300, 3 - i % 5, 1_000_000])
            .collect();
        let mut enc = TriadEncoder::new(0, [u32::MAX - 50, 7, 0]);
        let mut bytes = enc.current_frame().to_vec();
        for (i, inc) in incs.iter().enumerate() {
            let f = enc.step(*inc).unwrap();
            if i != 40 {
                bytes.extend_from_slice(&f);
            }
        }
        let (items, _) = FrameDecoder::<Triad>::decode_all_wire(&bytes, DecoderConfig::default());
        for axis in 0..3 {
            let split: Vec<Decoded> = items.iter().map(|it| Triad::axis(it, axis)).collect();
            let samples: Vec<(i64, u16)> = split
                .iter()
                .filter_map(|d| match d {
                    Decoded::Sample(s) => Some((s.increment, s.lost_before)),
                    _ => None,
                })
                .collect();
            // after the baseline, frame 40 (the 41st increment) is lost: the next carries both
            assert_eq!(samples.len(), 199);
            let total: i64 = samples.iter().map(|s| s.0).sum();
            assert_eq!(
                total,
                incs.iter().map(|v| v[axis]).sum::<i64>(),
                "axis {axis}"
            );
            assert_eq!(
                samples[40],
                (incs[40][axis] + incs[41][axis], 1),
                "axis {axis}"
            );
            assert_eq!(samples[39], (incs[39][axis], 0), "axis {axis}");
            let mut scratch = vec![99];
            let run = Triad::axis_run(&incs, axis, &mut scratch);
            assert_eq!(run, incs.iter().map(|v| v[axis]).collect::<Vec<_>>());
            let single: Vec<i64> = incs.iter().map(|v| v[axis]).collect();
            let mut untouched = vec![7];
            let same = Single::axis_run(&single, 0, &mut untouched);
            assert!(
                std::ptr::eq(same, &single[..]),
                "a single frame's run is not copied"
            );
            assert_eq!(untouched, vec![7]);
        }
        let mut buf = BytesMut::from(&bytes[..]);
        let mut dec = FrameDecoder::<Triad>::for_wire(DecoderConfig::default());
        assert!(dec.decode(&mut buf).is_some());
    }
}
