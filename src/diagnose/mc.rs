//! Monte-Carlo reference: the model simulated with several seeds, each run
//! reduced to the same statistics as the recording ([`super::stream`]), as it
//! is simulated.
//!
//! The spread of the runs is the primary confidence band of every statistic:
//! it captures what closed forms miss (the counter's sawtooth quantization at a
//! slow input, lines, non-Gaussian terms, estimator details). Runs are spread
//! over threads; the result does not depend on the thread count (each run is
//! a pure function of its seed). A rate-output model's runs are its rate
//! words, counted in the recording's quantum ([`super::Recording`]).

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use super::stats::{StatLayout, StatSet};
use super::stream::refill::Refill;
use super::stream::{CHUNK, Extras, StatStream};
use super::two_level::TwoLevelProbe;
use crate::model::config::OutputKind;
use crate::model::{GyroModel, ModelError, Simulator};
use crate::units;

/// Told after each Monte-Carlo run: the phase, the runs done in it and the
/// runs it has (a terminal's progress bar; the numbers never depend on it).
pub type ProgressFn = dyn Fn(&str, usize, usize) + Send + Sync;

/// An optional [`ProgressFn`].
#[derive(Clone, Default)]
pub struct Progress(Option<Arc<ProgressFn>>);

impl std::fmt::Debug for Progress {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() {
            "Progress(..)"
        } else {
            "Progress(none)"
        })
    }
}

impl Progress {
    /// Report to `f`.
    pub fn new(f: impl Fn(&str, usize, usize) + Send + Sync + 'static) -> Self {
        Progress(Some(Arc::new(f)))
    }

    fn report(&self, phase: &str, done: usize, total: usize) {
        if let Some(f) = &self.0 {
            f(phase, done, total);
        }
    }
}

/// What to simulate and reduce.
#[derive(Debug, Clone, Copy)]
pub struct McJob<'a> {
    pub model: &'a GyroModel,
    pub layout: &'a StatLayout,
    /// Temperature regressor (the recording's), one value per sample.
    pub temp_c: Option<&'a [f64]>,
    /// Low-pass cut-offs for the kurtosis statistic.
    pub lp_cutoffs_hz: &'a [f64],
    /// Worker threads (at least 1).
    pub threads: usize,
    /// All statistics (`false`: only the kurtosis statistics, for the
    /// random-telegraph alternative).
    pub full: bool,
    /// A term to evaluate the two-level likelihood ratio for, in each run.
    pub two_level: Option<TwoLevelProbe>,
    /// What the runs are for, and whom to tell of each one done.
    pub phase: &'static str,
    pub progress: &'a Progress,
}

impl McJob<'_> {
    /// The same job, reported as `phase`.
    pub fn phase(self, phase: &'static str) -> Self {
        McJob { phase, ..self }
    }
}

/// Simulate `job.model` once per seed (each run as long as the recording)
/// and compute its statistics. Output order follows `seeds`.
pub fn run(job: &McJob, seeds: &[u64]) -> Result<Vec<StatSet>, ModelError> {
    let n = job.layout.n_samples;
    let fs = job.layout.fs_hz;
    // validate once up front so workers cannot fail on the model
    Simulator::new(job.model, 0, Some(n as f64 / fs))?;
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    job.progress.report(job.phase, 0, seeds.len());
    let slots: Mutex<Vec<Option<StatSet>>> = Mutex::new(vec![None; seeds.len()]);
    let err: Mutex<Option<ModelError>> = Mutex::new(None);
    let threads = job.threads.max(1).min(seeds.len().max(1));
    std::thread::scope(|sc| {
        for _ in 0..threads {
            sc.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= seeds.len() {
                        break;
                    }
                    match one_run(job, seeds[i]) {
                        Ok(s) => {
                            slots.lock().expect("no panics while holding the lock")[i] = Some(s);
                            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
                            job.progress.report(job.phase, d, seeds.len());
                        }
                        Err(e) => {
                            *err.lock().expect("no panics while holding the lock") = Some(e);
                            break;
                        }
                    }
                }
            });
        }
    });
    if let Some(e) = err.into_inner().expect("lock not poisoned") {
        return Err(e);
    }
    Ok(slots
        .into_inner()
        .expect("lock not poisoned")
        .into_iter()
        .map(|s| s.expect("every seed ran"))
        .collect())
}

/// One run, simulated and reduced in [`CHUNK`]s: its memory does not grow
/// with the record.
fn one_run(job: &McJob, seed: u64) -> Result<StatSet, ModelError> {
    let lay = job.layout;
    let n = lay.n_samples;
    let mut sim = Simulator::new(job.model, seed, Some(n as f64 / lay.fs_hz))?;
    let rate_output = sim.output() == OutputKind::Rate;
    let extras = Extras {
        temp_c: job.temp_c,
        lp_cutoffs_hz: job.lp_cutoffs_hz,
        two_level: job.two_level,
        full: job.full,
    };
    let mut stream = StatStream::new(lay, extras);
    let mut refill = Refill::new(&lay.filled, n, lay.rate_words);
    let (mut raw, mut out) = (Vec::with_capacity(CHUNK), Vec::with_capacity(CHUNK));
    let (mut made, mut last) = (0, 0);
    while made < n {
        let want = CHUNK.min(n - made);
        raw.clear();
        if rate_output {
            rate_words(&mut sim, want, lay.pulse_arcsec, &mut raw);
        } else {
            sim.next_block(want, &mut raw);
        }
        // duration rounding can in principle leave the run a sample short
        raw.resize(want, raw.last().copied().unwrap_or(last));
        last = raw[want - 1];
        made += want;
        out.clear();
        refill.push(&raw, &mut out);
        stream.push(&out);
    }
    Ok(stream.finish())
}

/// `n` rate words of a rate-output simulator in the recording's quantum
/// (`pulse_arcsec` = quantum x tau0, see [`super::Recording`]): exact when
/// the model's LSB is the recording's quantum.
fn rate_words(sim: &mut Simulator, n: usize, pulse_arcsec: f64, out: &mut Vec<i64>) {
    let quantum_dps = pulse_arcsec * sim.sample_rate_hz() / units::ARCSEC_PER_DEG;
    let (mut rates, mut temp) = (Vec::with_capacity(n), Vec::new());
    sim.next_block_rates(n, &mut rates, &mut temp);
    out.extend(rates.iter().map(|v| (v / quantum_dps).round() as i64));
}
