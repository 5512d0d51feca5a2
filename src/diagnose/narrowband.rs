//! Phase 3b, narrowband excess: a peak of the whole record's spectrum a few
//! per cent of its frequency wide, far above its surroundings, that is not a
//! line (a resonance: a mechanical mode of the sense element, or a bench
//! vibration with a wandering frequency). It is reported (where, how wide,
//! how strong), and [`super::resonance`] fits a resonance term to it.
//!
//! It is judged after the refinement, against the updated model (so what its
//! terms explain, a moving average's side lobes included, is not an excess).
//! On the whitened periodogram (`psd / model_psd`, as the line search's) each
//! band of 1/8 octave is compared with its surroundings (the bands 3 to 6
//! eighths of an octave away on both sides): a power law or a filter's
//! roll-off, whitened or not, gives a ratio at or below one there (a
//! symmetric mean of a convex or log-symmetric curve), a peak a ratio above
//! it. A band counts when its ratio is at least [`MIN_RATIO`] and its log
//! ratio beyond the Bonferroni z over the bands searched (family-wise
//! [`super::ALPHA_LINES`]), with the Hann periodogram's 1.94 bins per
//! independent ordinate ([`BINS_PER_DOF`]). Bins within [`LINE_GUARD`] of a detected line are
//! left out, so a line is not counted twice. A band at a pulse counter's own
//! line (the fundamental at the mean pulse rate, or a harmonic), or next to
//! one, is not a candidate: the line's core is masked, but its Lorentzian
//! skirts (the rate's random walk of phase) are in the recording and not in
//! the model's spectrum, and would read as an excess of a few per cent.

use statrs::distribution::{ContinuousCDF, Normal};

use super::line_search::{Detection, LineSpectrum};

/// Bands per octave.
const PER_OCTAVE: f64 = 8.0;
/// A band's width relative to its lower edge, `2^(1/8) - 1`.
pub(crate) const BAND: f64 = 0.090_507_732_665_257_66;
/// Fewest usable bins in a band (a band of 1/8 octave at `f` holds about
/// `0.09 f T` bins, so the search starts near 350 cycles per record).
const MIN_BINS: usize = 32;
/// Smallest band-to-surroundings power ratio reported. Low, because a
/// resonance under a pulse counter's quantization noise stands only 10-20 %
/// above it in a band of 1/8 octave while being 6-9 sd strong; the z test
/// guards the family-wise rate, and the resonance fit is kept only where it
/// lowers chi2.
pub const MIN_RATIO: f64 = 1.05;
/// Smallest ratio an excess that nothing explains is noted at: the
/// spectrum of a real sensor against a model that does not fit it wanders
/// by 10-20 % from band to band (the ADIS16405 x and y axes against their
/// updated models), which is not worth a note; a resonance is still fitted
/// from [`MIN_RATIO`].
pub const NOTE_RATIO: f64 = 1.5;
/// Bins left out on each side of a detected line.
const LINE_GUARD: usize = 4;
/// Periodogram bins per independent ordinate when adjacent bins of a Hann
/// periodogram are averaged: the sum of the power correlations over lags
/// (the Hann spectral correlations are -2/3 at lag 1 and 1/6 at lag 2),
/// `1 + 2 (4/9 + 1/36)`.
pub(crate) const BINS_PER_DOF: f64 = 1.0 + 2.0 * (4.0 / 9.0 + 1.0 / 36.0);

/// A narrowband excess of the spectrum.
#[derive(Debug, Clone, PartialEq)]
pub struct Excess {
    /// Centre of the strongest band, Hz.
    pub f_hz: f64,
    /// Span of the contiguous bands that count, Hz.
    pub span_hz: (f64, f64),
    /// The strongest band's power over its surroundings.
    pub ratio: f64,
    /// Its log ratio in standard deviations, and the Bonferroni threshold.
    pub z: f64,
    pub z_crit: f64,
}

/// One band: its bins' mean whitened power and how many bins it holds.
#[derive(Debug, Clone, Copy)]
struct Band {
    lo_hz: f64,
    hi_hz: f64,
    mean: f64,
    n: usize,
}

/// The strongest narrowband excess of `spec` (None when no band counts);
/// `counter_hz` the frequencies of a pulse counter's own lines.
pub fn find(
    spec: &LineSpectrum,
    lines: &[Detection],
    counter_hz: &[f64],
    alpha: f64,
) -> Option<Excess> {
    let bands = bands(spec, lines);
    let step = 2f64.powf(1.0 / PER_OCTAVE);
    // the band that holds a counter line, and its neighbours
    let at_counter = |b: &Band| {
        counter_hz
            .iter()
            .any(|&f| b.lo_hz / step <= f && f <= b.hi_hz * step)
    };
    let scored: Vec<Option<(f64, f64)>> = (0..bands.len())
        .map(|b| score(&bands, b).filter(|_| !at_counter(&bands[b])))
        .collect();
    let tested = scored.iter().flatten().count();
    if tested == 0 {
        return None;
    }
    let z_crit = Normal::standard().inverse_cdf(1.0 - alpha / tested as f64);
    let counts = |s: &Option<(f64, f64)>| s.is_some_and(|(r, z)| r >= MIN_RATIO && z > z_crit);
    let best = (0..bands.len())
        .filter(|&b| counts(&scored[b]))
        .max_by(|&a, &b| scored[a].unwrap().1.total_cmp(&scored[b].unwrap().1))?;
    let (mut lo, mut hi) = (best, best);
    while lo > 0 && counts(&scored[lo - 1]) {
        lo -= 1;
    }
    while hi + 1 < bands.len() && counts(&scored[hi + 1]) {
        hi += 1;
    }
    let (ratio, z) = scored[best].unwrap();
    Some(Excess {
        f_hz: (bands[best].lo_hz * bands[best].hi_hz).sqrt(),
        span_hz: (bands[lo].lo_hz, bands[hi].hi_hz),
        ratio,
        z,
        z_crit,
    })
}

/// Bands of 1/8 octave from where they hold [`MIN_BINS`] bins up to Nyquist.
fn bands(spec: &LineSpectrum, lines: &[Detection]) -> Vec<Band> {
    let df = spec.df();
    let last = spec.bins() - 1;
    let mut keep = spec.usable.clone();
    for d in lines {
        let (a, b) = (
            d.bin.saturating_sub(LINE_GUARD),
            (d.bin + LINE_GUARD).min(last),
        );
        keep[a..=b].iter_mut().for_each(|k| *k = false);
    }
    let step = 2f64.powf(1.0 / PER_OCTAVE);
    let f_start = MIN_BINS as f64 * df / (step - 1.0);
    let nyquist = last as f64 * df;
    let mut out = Vec::new();
    let mut lo = f_start;
    while lo * step <= nyquist {
        let hi = lo * step;
        let (a, b) = (
            (lo / df).ceil() as usize,
            ((hi / df).floor() as usize).min(last),
        );
        let (sum, n) = (a..b)
            .filter(|&k| keep[k] && spec.white(k).is_finite())
            .fold((0.0, 0usize), |(s, n), k| (s + spec.white(k), n + 1));
        let mean = if n > 0 { sum / n as f64 } else { f64::NAN };
        out.push(Band {
            lo_hz: lo,
            hi_hz: hi,
            mean,
            n,
        });
        lo = hi;
    }
    out
}

/// Band `b`'s power over its surroundings and that ratio's log in standard
/// deviations; None without full surroundings or enough bins.
fn score(bands: &[Band], b: usize) -> Option<(f64, f64)> {
    if b < 6 || b + 6 >= bands.len() || bands[b].n < MIN_BINS {
        return None;
    }
    let around: Vec<&Band> = (3..=6)
        .flat_map(|o| [&bands[b - o], &bands[b + o]])
        .collect();
    if around.iter().any(|s| s.n < MIN_BINS || !s.mean.is_finite()) {
        return None;
    }
    // the surroundings' mean of band means (each band weighted alike, so the
    // wider upper bands do not tilt it towards one side)
    let level = around.iter().map(|s| s.mean).sum::<f64>() / around.len() as f64;
    let band = bands[b];
    if !(band.mean > 0.0 && level > 0.0) {
        return None;
    }
    let dof = |n: usize| n as f64 / BINS_PER_DOF;
    let var_band = 1.0 / dof(band.n);
    let var_level =
        around.iter().map(|s| 1.0 / dof(s.n)).sum::<f64>() / (around.len() as f64).powi(2);
    let ratio = band.mean / level;
    Some((ratio, ratio.ln() / (var_band + var_level).sqrt()))
}

/// The note of an excess, in words.
pub fn note(e: &Excess) -> String {
    format!(
        "Narrowband excess at {:.2} Hz ({:.2}-{:.2} Hz): {:.1} times the spectrum around it \
         (z {:.1} against {:.1} over the bands searched), not a line, and not explained by the \
         updated model: narrowband noise (a mechanical mode of the sense element, or a bench \
         vibration whose frequency wanders) that the broadband terms fitted here may be bent to \
         imitate.",
        e.f_hz, e.span_hz.0, e.span_hz.1, e.ratio, e.z, e.z_crit
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A spectrum of `n` samples at `fs` whose whitened power is `shape(f)`
    /// times a deterministic unit-mean pattern (a stand-in for the noise).
    fn spectrum(n: usize, fs: f64, shape: impl Fn(f64) -> f64) -> LineSpectrum {
        let half = n / 2;
        let df = fs / n as f64;
        let white: Vec<f64> = (0..=half)
            .map(|k| shape(k as f64 * df) * [0.5, 1.5, 0.8, 1.2][k % 4])
            .collect();
        LineSpectrum {
            fs_hz: fs,
            n,
            psd: std::sync::Arc::new(white),
            model_psd: vec![1.0; half + 1],
            usable: (0..=half).map(|k| k > 0).collect(),
        }
    }

    fn resonance(f: f64) -> f64 {
        // 12x the white level over 19-21 Hz
        1.0 + if (19.0..21.0).contains(&f) { 11.0 } else { 0.0 }
    }

    #[test]
    fn a_resonance_is_found_where_it_is() {
        let s = spectrum(1 << 20, 100.0, resonance);
        let e = find(&s, &[], &[], 1e-3).expect("found");
        assert!((19.0..21.0).contains(&e.f_hz), "{e:?}");
        assert!(e.span_hz.0 < 20.0 && e.span_hz.1 > 20.0, "{e:?}");
        assert!(e.ratio > 5.0 && e.z > e.z_crit, "{e:?}");
        assert!(note(&e).contains("Narrowband excess at"));
    }

    #[test]
    fn flat_power_laws_and_roll_offs_are_not_peaks() {
        type Shape = fn(f64) -> f64;
        let cases: [(&str, Shape); 4] = [
            ("flat", |_| 1.0),
            ("f^-2", |f| 1.0 / (f * f)),
            ("f^2", |f| f * f),
            ("one-pole roll-off", |f| 1.0 / (1.0 + (f / 15.0).powi(2))),
        ];
        for (name, shape) in cases {
            let s = spectrum(1 << 20, 100.0, shape);
            assert_eq!(find(&s, &[], &[], 1e-3), None, "{name}");
        }
    }

    #[test]
    fn a_detected_line_is_not_an_excess() {
        let mut s = spectrum(1 << 20, 100.0, |_| 1.0);
        let k = (20.0 / s.df()) as usize;
        let psd = std::sync::Arc::make_mut(&mut s.psd);
        for j in k - 2..=k + 2 {
            psd[j] = 1e5;
        }
        assert!(
            find(&s, &[], &[], 1e-3).is_some(),
            "a line alone raises its band"
        );
        let line = Detection {
            bin: k,
            f_hz: k as f64 * s.df(),
            ratio: 1e5,
            p: 0.0,
            n_searched: 1,
        };
        assert_eq!(find(&s, &[line], &[], 1e-3), None);
    }

    #[test]
    fn the_skirts_of_a_counter_line_are_not_an_excess() {
        // a Lorentzian of half-width 0.05 Hz at 20 Hz, its core masked
        let skirt = |f: f64| 1.0 + 2.0 / (1.0 + ((f - 20.0) / 0.05).powi(2));
        let mut s = spectrum(1 << 20, 100.0, skirt);
        let k = (20.0 / s.df()) as usize;
        s.usable[k - 20..=k + 20]
            .iter_mut()
            .for_each(|u| *u = false);
        assert!(
            find(&s, &[], &[], 1e-3).is_some(),
            "the skirts raise their band"
        );
        assert_eq!(find(&s, &[], &[20.0], 1e-3), None);
        // a resonance elsewhere is still found beside a counter line
        let mut s = spectrum(1 << 20, 100.0, |f| skirt(f) * resonance(f * 2.0));
        s.usable[k - 20..=k + 20]
            .iter_mut()
            .for_each(|u| *u = false);
        let e = find(&s, &[], &[20.0], 1e-3).expect("the resonance");
        assert!((9.5..10.5).contains(&e.f_hz), "{e:?}");
    }
}
