//! The streaming multi-level orthogonal wavelet filter bank.
//!
//! Role in the whole: [`StreamingBank`] is the engine under the QN splitter
//! ([`super::qn`]); [`StreamingAnalysis`] is its analysis half on its own (used by
//! tests against PyWavelets, and available to anything that wants coefficients).
//!
//! # Definitions, alignment, latency
//!
//! Level `j` (1 = finest, `J` = deepest) turns its input `a_{j-1}` (`a_0` = the
//! signal) into `a_j[i] = sum_k dec_lo[k] a_{j-1}[2i+1-k]` and
//! `d_j[i] = sum_k dec_hi[k] a_{j-1}[2i+1-k]`, with everything before the first
//! sample taken as zero. This is PyWavelets' `mode='zero'` exactly, **with index
//! offset 0**: the streaming coefficient `d_j[i]` equals
//! `pywt.wavedec(x, w, mode='zero', level=J)[-j][i]` for every `i` pywt returns
//! (the tail ones once the stream has been flushed with zeros), and `a_J[i]` equals
//! `[0][i]`. Coefficient `i` of level `j` is emitted as soon as input sample
//! `2^j (i+1) - 1` has been pushed. (`tests/numerics/dsp_pywt_golden.rs`.)
//!
//! Synthesis inverts each level with `rec_lo`/`rec_hi`. It runs once per *frame* of
//! `2^J` input samples (one deepest coefficient). The detail coefficients of level
//! `j` wait in a delay line of `S_{J-j}` coefficients, `S_k = (L-2)(2^k - 1)`, so
//! they meet the approximation synthesised from the deeper levels. Output sample
//! `n` (counting from 0) is the reconstruction of input sample `n`, and it is
//! released exactly when input sample `n + latency` has been pushed:
//!
//! ```text
//! latency = (L - 1) (2^J - 1) samples      (sym8, J = 10: 15345; J = 11: 30705)
//! ```
//!
//! i.e. after `N` pushed samples the bank has released exactly `max(0, N - latency)`
//! outputs, whatever the block sizes. [`StreamingBank::flush`] pushes `latency`
//! zeros so every input sample comes out. With unmodified coefficients the output
//! equals the input to rounding (perfect reconstruction). With coefficients
//! modified through a [`CoeffHook`], output sample `n` equals
//! `pywt.waverec(modified, w, mode='zero')[n]` (`tests/numerics/dsp_pywt_golden.rs`).
//!
//! # Cost
//! Per input sample, about `2L` multiply-adds for analysis and `2L` for synthesis
//! (levels shrink geometrically), no allocation after warm-up; memory is
//! `O(L 2^J)`, independent of the record length. Blocks are processed whole per
//! level by the vectorised kernels of `kernel`; each output value is the same
//! sequence of floating-point operations whatever the block split, so results are
//! bit-identical for any way of cutting the stream (tested).

use super::isa::Isa;
use super::kernel::Taps;
use super::wavelet::Wavelet;
use super::{DspError, Result};

/// Deepest decomposition the bank accepts (latency and memory grow as `2^J`).
pub const MAX_LEVELS: u32 = 18;

/// Receives coefficients between analysis and synthesis, and may modify them.
///
/// Calls come in stream order. Within one input block the bank calls `details`
/// for levels `1..=J`, then `approx`; whenever input sample `2^J (f+1) - 1` has
/// been analysed it calls `frame_end(f)` before synthesising that frame. A hook
/// that derives per-level gains from statistics and updates them only in
/// `frame_end` therefore gives results independent of the caller's block sizes.
pub trait CoeffHook {
    /// Detail coefficients `d_level[first .. first + d.len()]`, to inspect or modify.
    fn details(&mut self, level: u32, first: u64, d: &mut [f64]);
    /// Deepest approximation coefficients `a_J[first ..]`; default: untouched.
    fn approx(&mut self, _first: u64, _a: &mut [f64]) {}
    /// Frame `frame` (input samples `frame*2^J .. (frame+1)*2^J`) is fully analysed.
    fn frame_end(&mut self, _frame: u64) {}
}

/// The identity hook: coefficients pass unchanged.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoHook;
impl CoeffHook for NoHook {
    fn details(&mut self, _level: u32, _first: u64, _d: &mut [f64]) {}
}

fn check_levels(levels: u32) -> Result<()> {
    if levels == 0 || levels > MAX_LEVELS {
        return Err(DspError::InvalidLevels {
            levels,
            max: MAX_LEVELS,
            why: "latency and memory grow as 2^levels",
        });
    }
    Ok(())
}

/// Coefficients produced by [`StreamingAnalysis::push`], appended per call.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AnalysisOutput {
    /// Deepest approximation `a_J`.
    pub approx: Vec<f64>,
    /// `details[j-1]` holds level `j` (index 0 = finest).
    pub details: Vec<Vec<f64>>,
}

#[derive(Debug, Clone)]
struct AnaLevel {
    e: Vec<f64>,
    o: Vec<f64>,
    pending: Option<f64>,
}

/// Streaming multi-level analysis (`mode='zero'` semantics; see module docs).
#[derive(Debug, Clone)]
pub struct StreamingAnalysis {
    wavelet: Wavelet,
    taps: Taps,
    isa: Isa,
    levels: u32,
    /// Per level: the input deinterleaved (`e[q] = x[2q]`, `o[q] = x[2q+1]`), the
    /// first `P-1` entries being history, plus an unpaired trailing sample.
    st: Vec<AnaLevel>,
    /// Per level: outputs of the last processed block.
    lo: Vec<Vec<f64>>,
    hi: Vec<Vec<f64>>,
    /// Per level: coefficients emitted so far.
    produced: Vec<u64>,
    n_in: u64,
}

impl StreamingAnalysis {
    /// A bank of `levels` analysis stages of `wavelet`, zero pre-history.
    pub fn new(wavelet: &Wavelet, levels: u32) -> Result<Self> {
        check_levels(levels)?;
        let taps = Taps::new(
            wavelet.dec_lo(),
            wavelet.dec_hi(),
            wavelet.rec_lo(),
            wavelet.rec_hi(),
        );
        let hist = wavelet.len() / 2 - 1;
        let j = levels as usize;
        Ok(StreamingAnalysis {
            wavelet: wavelet.clone(),
            taps,
            isa: Isa::detect(),
            levels,
            st: (0..j)
                .map(|_| AnaLevel {
                    e: vec![0.0; hist],
                    o: vec![0.0; hist],
                    pending: None,
                })
                .collect(),
            lo: vec![Vec::new(); j],
            hi: vec![Vec::new(); j],
            produced: vec![0; j],
            n_in: 0,
        })
    }

    /// Decomposition depth J.
    pub fn levels(&self) -> u32 {
        self.levels
    }
    /// The wavelet.
    pub fn wavelet(&self) -> &Wavelet {
        &self.wavelet
    }
    /// Input samples pushed so far.
    pub fn samples_in(&self) -> u64 {
        self.n_in
    }
    /// Coefficients emitted so far by level `j` (0-based: 0 = finest level).
    pub fn produced(&self, j: usize) -> u64 {
        self.produced[j]
    }

    /// Push samples; append every coefficient they complete to `out`.
    pub fn push(&mut self, x: &[f64], out: &mut AnalysisOutput) {
        out.details.resize(self.levels as usize, Vec::new());
        self.process(x);
        for j in 0..self.levels as usize {
            out.details[j].extend_from_slice(&self.hi[j]);
        }
        out.approx
            .extend_from_slice(&self.lo[self.levels as usize - 1]);
    }

    /// Run one block through every level, leaving this block's outputs in
    /// `self.lo[j]` / `self.hi[j]`.
    pub(crate) fn process(&mut self, x: &[f64]) {
        self.n_in += x.len() as u64;
        let h = self.taps.p - 1;
        for j in 0..self.levels as usize {
            let (prev, rest) = self.lo.split_at_mut(j);
            let mut input: &[f64] = if j == 0 { x } else { &prev[j - 1] };
            let st = &mut self.st[j];
            if let Some(first) = st.pending
                && let Some((&x1, tail)) = input.split_first()
            {
                st.e.push(first);
                st.o.push(x1);
                st.pending = None;
                input = tail;
            }
            let np = input.len() / 2;
            if input.len() % 2 == 1 {
                st.pending = Some(input[input.len() - 1]);
            }
            let pairs = input[..2 * np].chunks_exact(2);
            st.e.extend(pairs.clone().map(|p| p[0]));
            st.o.extend(pairs.map(|p| p[1]));
            let r = st.e.len() - h;
            let lo = &mut rest[0];
            let hi = &mut self.hi[j];
            // the kernel overwrites all r outputs: resizing (not clearing) the
            // reused buffers zero-fills only what they grow by
            lo.resize(r, 0.0);
            hi.resize(r, 0.0);
            if r == 0 {
                continue;
            }
            self.isa.analysis(&self.taps, &st.e, &st.o, lo, hi);
            st.e.copy_within(r.., 0);
            st.e.truncate(h);
            st.o.copy_within(r.., 0);
            st.o.truncate(h);
            self.produced[j] += r as u64;
        }
    }

    pub(crate) fn set_isa(&mut self, isa: Isa) {
        self.isa = isa;
    }
}

/// A first-in first-out queue of samples with contiguous reads.
#[derive(Debug, Clone, Default)]
pub(crate) struct Fifo {
    buf: Vec<f64>,
    head: usize,
}

impl Fifo {
    pub(crate) fn len(&self) -> usize {
        self.buf.len() - self.head
    }
    /// The live samples, oldest first.
    pub(crate) fn as_slice(&self) -> &[f64] {
        &self.buf[self.head..]
    }
    /// Remove the `n` oldest samples.
    pub(crate) fn advance(&mut self, n: usize) {
        assert!(n <= self.len(), "Fifo::advance past the end");
        self.head += n;
    }
    pub(crate) fn capacity(&self) -> usize {
        self.buf.capacity()
    }
    /// Drop the consumed front once it is at least half the buffer: amortised O(1)
    /// per element, and the buffer stays within twice the live length.
    fn compact(&mut self) {
        if self.head > 0 && self.head >= self.buf.len() / 2 {
            self.buf.copy_within(self.head.., 0);
            self.buf.truncate(self.buf.len() - self.head);
            self.head = 0;
        }
    }
    pub(crate) fn push(&mut self, x: &[f64]) {
        self.compact();
        self.buf.extend_from_slice(x);
    }
    /// Append the `n` oldest samples to `dst` and remove them.
    fn pop_into(&mut self, n: usize, dst: &mut Vec<f64>) {
        debug_assert!(n <= self.len());
        dst.extend_from_slice(&self.buf[self.head..self.head + n]);
        self.head += n;
    }
}

/// A delay line that keeps the `h` samples read last in front of the read
/// position, so a synthesis window `[h history | m new]` is one contiguous slice.
#[derive(Debug, Clone)]
struct DelayLine {
    buf: Vec<f64>,
    head: usize,
    h: usize,
}

impl DelayLine {
    fn new(h: usize, delay: usize) -> DelayLine {
        DelayLine {
            buf: vec![0.0; h + delay],
            head: h,
            h,
        }
    }
    fn push(&mut self, x: &[f64]) {
        let dead = self.head - self.h;
        if dead > 0 && dead >= self.buf.len() / 2 {
            self.buf.copy_within(dead.., 0);
            self.buf.truncate(self.buf.len() - dead);
            self.head = self.h;
        }
        self.buf.extend_from_slice(x);
    }
    /// `[h samples read last | next m]`; advances the read position by `m`.
    fn window(&mut self, m: usize) -> &[f64] {
        let w = &self.buf[self.head - self.h..self.head + m];
        self.head += m;
        w
    }
    fn capacity(&self) -> usize {
        self.buf.capacity()
    }
}

/// Streaming analysis + synthesis with a fixed latency (see module docs).
#[derive(Debug, Clone)]
pub struct StreamingBank {
    ana: StreamingAnalysis,
    /// Per level `j` (index `j-1`): synthesis approximation input,
    /// `[P-1 history | this frame's 2^(J-j) samples]`.
    ubuf: Vec<Vec<f64>>,
    /// Per level `j` (index `j-1`): delayed detail coefficients.
    delay: Vec<DelayLine>,
    /// Deepest approximation coefficients not yet synthesised.
    apx: Fifo,
    /// Synthesised output samples not yet released.
    out: Fifo,
    /// Synthesised samples that precede input sample 0 (still to drop).
    discard: usize,
    latency: usize,
    frame: u64,
    n_out: u64,
}

impl StreamingBank {
    /// A bank of depth `levels` for `wavelet`, zero pre-history.
    pub fn new(wavelet: &Wavelet, levels: u32) -> Result<Self> {
        let ana = StreamingAnalysis::new(wavelet, levels)?;
        let l = wavelet.len();
        let p = l / 2;
        let jj = levels as usize;
        let s = |k: usize| (l - 2) * ((1usize << k) - 1);
        let delay = (1..=jj).map(|j| DelayLine::new(p - 1, s(jj - j))).collect();
        Ok(StreamingBank {
            ana,
            ubuf: (0..jj).map(|_| vec![0.0; p - 1]).collect(),
            delay,
            apx: Fifo::default(),
            out: Fifo::default(),
            discard: s(jj),
            latency: (l - 1) * ((1usize << jj) - 1),
            frame: 1u64 << jj,
            n_out: 0,
        })
    }

    /// Fixed latency in samples: `(L-1)(2^J-1)`.
    pub fn latency(&self) -> usize {
        self.latency
    }
    /// Frame length `2^J` (synthesis granularity).
    pub fn frame_len(&self) -> usize {
        self.frame as usize
    }
    /// Decomposition depth J.
    pub fn levels(&self) -> u32 {
        self.ana.levels
    }
    /// The wavelet.
    pub fn wavelet(&self) -> &Wavelet {
        &self.ana.wavelet
    }
    /// Input samples pushed so far (including any flush zeros).
    pub fn samples_in(&self) -> u64 {
        self.ana.n_in
    }
    /// Output samples released so far.
    pub fn samples_out(&self) -> u64 {
        self.n_out
    }

    /// Total capacity, in f64 values, of every internal buffer: the bank's memory.
    /// Bounded by `O(L 2^J)` whatever the record length (tested).
    #[doc(hidden)]
    pub fn state_capacity(&self) -> usize {
        let a = &self.ana;
        let ana: usize =
            a.st.iter()
                .map(|s| s.e.capacity() + s.o.capacity())
                .sum::<usize>()
                + a.lo.iter().chain(&a.hi).map(Vec::capacity).sum::<usize>();
        ana + self.ubuf.iter().map(Vec::capacity).sum::<usize>()
            + self.delay.iter().map(DelayLine::capacity).sum::<usize>()
            + self.apx.capacity()
            + self.out.capacity()
    }

    /// Run the kernel variant `name` (`baseline`, `avx2`, `avx512`) instead of the
    /// detected best; false (and no change) if this CPU cannot. Results are
    /// bit-identical across variants (tested); this exists for that test.
    #[doc(hidden)]
    pub fn force_kernels(&mut self, name: &str) -> bool {
        match Isa::by_name(name) {
            Some(isa) => {
                self.ana.set_isa(isa);
                true
            }
            None => false,
        }
    }

    /// Push samples; append released outputs (perfect reconstruction, delayed).
    pub fn push(&mut self, x: &[f64], out: &mut Vec<f64>) {
        self.push_with(x, out, &mut NoHook);
    }

    /// Push samples, letting `hook` see and modify every coefficient.
    pub fn push_with<H: CoeffHook + ?Sized>(
        &mut self,
        mut x: &[f64],
        out: &mut Vec<f64>,
        hook: &mut H,
    ) {
        let jj = self.ana.levels as usize;
        while !x.is_empty() {
            let room = (self.frame - self.ana.n_in % self.frame) as usize;
            let take = room.min(x.len());
            self.ana.process(&x[..take]);
            // Index of the first coefficient this block produced, per level.
            for (j, (d, delay)) in self.ana.hi.iter_mut().zip(&mut self.delay).enumerate() {
                if !d.is_empty() {
                    let first = self.ana.produced[j] - d.len() as u64;
                    hook.details(j as u32 + 1, first, d);
                    delay.push(d);
                }
            }
            let a = &mut self.ana.lo[jj - 1];
            if !a.is_empty() {
                let first = self.ana.produced[jj - 1] - a.len() as u64;
                hook.approx(first, a);
                self.apx.push(a);
            }
            if self.ana.n_in.is_multiple_of(self.frame) {
                hook.frame_end(self.ana.n_in / self.frame - 1);
                self.synthesize_frame();
            }
            x = &x[take..];
        }
        self.release(out);
    }

    /// Push `latency()` zeros so that every real input sample is released.
    pub fn flush(&mut self, out: &mut Vec<f64>) {
        self.flush_with(out, &mut NoHook);
    }

    /// [`StreamingBank::flush`] with a hook.
    pub fn flush_with<H: CoeffHook + ?Sized>(&mut self, out: &mut Vec<f64>, hook: &mut H) {
        let zeros = vec![0.0; self.frame as usize];
        let mut left = self.latency;
        while left > 0 {
            let n = left.min(zeros.len());
            self.push_with(&zeros[..n], out, hook);
            left -= n;
        }
    }

    fn synthesize_frame(&mut self) {
        let jj = self.ana.levels as usize;
        let taps = &self.ana.taps;
        let isa = self.ana.isa;
        let h = taps.p - 1;
        self.out.compact();
        self.apx.pop_into(1, &mut self.ubuf[jj - 1]);
        for j in (0..jj).rev() {
            let (lower, upper) = self.ubuf.split_at_mut(j);
            let u = &mut upper[0];
            let m = u.len() - h;
            let v = self.delay[j].window(m);
            // Level j+1 reconstructs 2m samples of a_j: into the next finer level's
            // input buffer, or, for level 1, straight into the output queue.
            let dst: &mut Vec<f64> = if j > 0 {
                &mut lower[j - 1]
            } else {
                &mut self.out.buf
            };
            let start = dst.len();
            dst.resize(start + 2 * m, 0.0);
            isa.synthesis(taps, u, v, &mut dst[start..]);
            u.copy_within(m.., 0);
            u.truncate(h);
        }
        let skip = self.discard.min(self.out.len());
        self.discard -= skip;
        self.out.head += skip;
    }

    fn release(&mut self, out: &mut Vec<f64>) {
        let target = self.ana.n_in.saturating_sub(self.latency as u64);
        let n = (target - self.n_out) as usize;
        debug_assert!(
            n <= self.out.len(),
            "bank released {n} > {} available",
            self.out.len()
        );
        self.out.pop_into(n, out);
        self.n_out = target;
    }
}
