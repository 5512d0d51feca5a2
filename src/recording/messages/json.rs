//! Direct JSON formatting of the sample batches: serde_json's output byte for
//! byte (rates to the milli-deg/h), several times faster, for the channels that
//! carry every sample.

use super::{RateBatch, RawBatch, SummaryUpdate, quantize_rate, rate_milli};

fn put_u64(out: &mut Vec<u8>, v: u64) {
    out.extend_from_slice(itoa::Buffer::new().format(v).as_bytes());
}

fn put_f64(out: &mut Vec<u8>, v: f64) {
    // serde_json writes a non-finite float as null
    if v.is_finite() {
        out.extend_from_slice(zmij::Buffer::new().format_finite(v).as_bytes());
    } else {
        out.extend_from_slice(b"null");
    }
}

/// `{"t0_ns":..,"dt_ns":..` (the start of every sample batch).
fn put_batch_head(out: &mut Vec<u8>, t0_ns: u64, dt_ns: u64) {
    out.extend_from_slice(b"{\"t0_ns\":");
    put_u64(out, t0_ns);
    out.extend_from_slice(b",\"dt_ns\":");
    put_u64(out, dt_ns);
}

pub(super) fn write_raw_batch(m: &RawBatch, out: &mut Vec<u8>) {
    out.reserve(96 + 32 * m.gaps.len());
    put_batch_head(out, m.t0_ns, m.dt_ns);
    out.extend_from_slice(b",\"seq0\":");
    put_u64(out, m.seq0);
    out.extend_from_slice(b",\"counts\":[");
    let mut buf = itoa::Buffer::new();
    put_slotted(out, &m.counts, |slot: &mut Slot, &c| {
        // a static gyro's increments are nearly all single digits
        if (0..10).contains(&c) {
            slot[0] = b'0' + c as u8;
            slot[1] = b',';
            2
        } else {
            put_text(slot, buf.format(c).as_bytes())
        }
    });
    out.extend_from_slice(b",\"gaps\":[");
    for (i, g) in m.gaps.iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        out.extend_from_slice(b"{\"index\":");
        put_u64(out, g.index);
        out.extend_from_slice(b",\"lost\":");
        put_u64(out, g.lost);
        out.push(b'}');
    }
    out.extend_from_slice(b"],\"temp_c\":");
    match m.temp_c {
        Some(t) => put_f64(out, t),
        None => out.extend_from_slice(b"null"),
    }
    out.extend_from_slice(b",\"status\":");
    put_u64(out, u64::from(m.status));
    out.push(b'}');
}

/// A `/gyro/summary` message, byte for byte as serde_json writes it (10 of
/// them a second per gyro: the recorder's most frequent message).
pub(super) fn write_summary(m: &SummaryUpdate, out: &mut Vec<u8>) {
    out.extend_from_slice(b"{\"timestamp\":{\"sec\":");
    put_u64(out, m.timestamp.sec);
    out.extend_from_slice(b",\"nsec\":");
    put_u64(out, u64::from(m.timestamp.nsec));
    out.extend_from_slice(b"},\"samples\":");
    put_u64(out, m.samples);
    out.extend_from_slice(b",\"lost_samples\":");
    put_u64(out, m.lost_samples);
    out.extend_from_slice(b",\"raw_rate_dph\":");
    put_f64(out, quantize_rate(m.raw_rate_dph));
    out.extend_from_slice(b",\"clean_rate_dph\":");
    put_f64(out, quantize_rate(m.clean_rate_dph));
    out.extend_from_slice(b",\"temp_c\":");
    match m.temp_c {
        Some(t) => put_f64(out, t),
        None => out.extend_from_slice(b"null"),
    }
    out.push(b'}');
}

pub(super) fn write_rate_batch(m: &RateBatch, out: &mut Vec<u8>) {
    put_batch_head(out, m.t0_ns, m.dt_ns);
    out.extend_from_slice(b",\"values\":[");
    let mut buf = zmij::Buffer::new();
    put_slotted(out, &m.values, |slot: &mut Slot, &v| match rate_milli(v) {
        Some(n) => put_milli(slot, n),
        None if v.is_finite() => put_text(slot, buf.format_finite(v).as_bytes()),
        None => put_text(slot, b"null"),
    });
    out.push(b'}');
}

/// Room for one value of a sample batch and its separator: the longest texts
/// are an `i64` (20 bytes) and a shortest-round-trip `f64` (24 bytes).
const SLOT: usize = 32;
type Slot = [u8; SLOT];

/// Values formatted per pass of [`put_slotted`] into its scratch.
const SLOTS_PER_CHUNK: usize = 256;

thread_local! {
    /// The formatting scratch of [`put_slotted`], zeroed once per thread: each
    /// value is written into a fixed-width slot of it, and only the bytes
    /// written are copied to the output (zero-filling a 32-byte slot in the
    /// output for each value cost more than formatting it).
    static SLOT_SCRATCH: std::cell::RefCell<Box<[u8]>> =
        std::cell::RefCell::new(vec![0u8; SLOT * SLOTS_PER_CHUNK].into_boxed_slice());
}

/// `values` as the elements of a JSON array (the `[` already written), and the
/// closing `]`. `put` writes one value and a `,` at the start of its slot and
/// returns the length written; a chunk of values is formatted into the
/// thread's scratch (no capacity check per value) and then appended to `out`.
#[inline(always)]
fn put_slotted<T>(out: &mut Vec<u8>, values: &[T], mut put: impl FnMut(&mut Slot, &T) -> usize) {
    SLOT_SCRATCH.with_borrow_mut(|scratch| {
        for chunk in values.chunks(SLOTS_PER_CHUNK) {
            let mut pos = 0;
            for v in chunk {
                let slot: &mut Slot = (&mut scratch[pos..pos + SLOT])
                    .try_into()
                    .expect("a chunk has a slot for each value");
                pos += put(slot, v);
            }
            out.extend_from_slice(&scratch[..pos]);
        }
    });
    // the last separator becomes the closing bracket
    match out.last_mut() {
        Some(c) if !values.is_empty() => *c = b']',
        _ => out.push(b']'),
    }
}

/// `text` and a `,` at the start of `slot` (`text` is at most 24 bytes).
#[inline]
fn put_text(slot: &mut Slot, text: &[u8]) -> usize {
    slot[..text.len()].copy_from_slice(text);
    slot[text.len()] = b',';
    text.len() + 1
}

/// Two-digit decimal table for the fixed-point rate formatter.
const DIGIT_PAIRS: &[u8; 200] = b"\
0001020304050607080910111213141516171819\
2021222324252627282930313233343536373839\
4041424344454647484950515253545556575859\
6061626364656667686970717273747576777879\
8081828384858687888990919293949596979899";

/// `.ddd` for every fraction 0..1000 (the three decimals of a milli-unit value).
const FRACTION3: [[u8; 4]; 1000] = {
    let mut t = [[0u8; 4]; 1000];
    let mut i = 0;
    while i < 1000 {
        t[i] = [
            b'.',
            b'0' + (i / 100) as u8,
            b'0' + (i / 10 % 10) as u8,
            b'0' + (i % 10) as u8,
        ];
        i += 1;
    }
    t
};

/// The decimal digits of every integer 0..1000, left-aligned, their count in
/// the last byte.
const INTEGER3: [[u8; 4]; 1000] = {
    let mut t = [[0u8; 4]; 1000];
    let mut i = 0;
    while i < 1000 {
        t[i] = if i < 10 {
            [b'0' + i as u8, 0, 0, 1]
        } else if i < 100 {
            [b'0' + (i / 10) as u8, b'0' + (i % 10) as u8, 0, 2]
        } else {
            [
                b'0' + (i / 100) as u8,
                b'0' + (i / 10 % 10) as u8,
                b'0' + (i % 10) as u8,
                3,
            ]
        };
        i += 1;
    }
    t
};

/// `n` milli-units as `[-]int.ddd` and a `,` at the start of `slot`
/// (`|n| < 2^51`: at most 13 integer digits, 19 bytes in all); returns the length.
/// Below 10^6 in magnitude (a static gyro's rates in deg/h, and a counter's
/// noise of about one pulse) the integer part takes one or two table entries
/// and the decimals one.
#[inline(always)]
fn put_milli(slot: &mut Slot, n: i64) -> usize {
    let a = n.unsigned_abs();
    let (int, f) = (a / 1000, (a % 1000) as usize);
    if int >= 1_000_000 {
        return put_milli_long(slot, n);
    }
    slot[0] = b'-';
    let mut k = usize::from(n < 0);
    let (high, low) = ((int / 1000) as usize, (int % 1000) as usize);
    let lead = if high > 0 { high } else { low };
    let digits = INTEGER3[lead];
    // the count byte lands where the next digits go
    slot[k..k + 4].copy_from_slice(&digits);
    k += usize::from(digits[3]);
    if high > 0 {
        // the low three digits, zero-padded
        slot[k..k + 3].copy_from_slice(&FRACTION3[low][1..]);
        k += 3;
    }
    slot[k..k + 4].copy_from_slice(&FRACTION3[f]);
    slot[k + 4] = b',';
    k + 5
}

/// [`put_milli`] for any magnitude, the integer part two digits at a time.
fn put_milli_long(slot: &mut Slot, n: i64) -> usize {
    let a = n.unsigned_abs();
    let (int, f) = (a / 1000, (a % 1000) as usize);
    let digits = int.checked_ilog10().map_or(1, |d| d as usize + 1);
    slot[0] = b'-';
    let dot = usize::from(n < 0) + digits;
    let (mut q, mut k) = (int, dot);
    while q >= 100 {
        let d = (q % 100) as usize;
        q /= 100;
        k -= 2;
        slot[k] = DIGIT_PAIRS[2 * d];
        slot[k + 1] = DIGIT_PAIRS[2 * d + 1];
    }
    if q >= 10 {
        slot[k - 2] = DIGIT_PAIRS[2 * q as usize];
        slot[k - 1] = DIGIT_PAIRS[2 * q as usize + 1];
    } else {
        slot[k - 1] = b'0' + q as u8;
    }
    slot[dot] = b'.';
    slot[dot + 1] = b'0' + (f / 100) as u8;
    slot[dot + 2] = DIGIT_PAIRS[2 * (f % 100)];
    slot[dot + 3] = DIGIT_PAIRS[2 * (f % 100) + 1];
    slot[dot + 4] = b',';
    dot + 5
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `[-]int.ddd,` written by `format!`, the reference for [`put_milli`].
    fn reference(n: i64) -> String {
        let a = n.unsigned_abs();
        let sign = if n < 0 { "-" } else { "" };
        format!("{sign}{}.{:03},", a / 1000, a % 1000)
    }

    #[test]
    fn milli_units_are_written_as_format_writes_them() {
        let mut values: Vec<i64> = (-2_000_000..=2_000_000).step_by(7).collect();
        values.extend([
            0, 1, -1, 999, -999, 1000, -1000, 999_999, -999_999, 1_000_000,
        ]);
        values.extend([-1_000_000, 123_456_789_012, (1 << 51) - 1, -((1 << 51) - 1)]);
        let mut slot = [0u8; SLOT];
        for n in values {
            let len = put_milli(&mut slot, n);
            assert_eq!(
                std::str::from_utf8(&slot[..len]).unwrap(),
                reference(n),
                "{n}"
            );
        }
    }
}
