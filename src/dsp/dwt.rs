//! Batch reference discrete wavelet transform: plain convolution and decimation,
//! exactly as PyWavelets defines `dwt`/`idwt`/`wavedec`/`waverec` for the modes
//! `zero` and `periodization`.
//!
//! Role in the whole: the slow, obviously-correct reference the streaming bank
//! ([`super::bank`]) is tested against (and PyWavelets golden data checks this).
//! Not used on the hot path.
//!
//! Definitions (`h` = `dec_lo` or `dec_hi`, `g` = `rec_lo` or `rec_hi`, L taps):
//!
//! - `zero`: the signal is zero outside `0..N`;
//!   `c[i] = sum_k h[k] x[2i+1-k]`, `i in 0..floor((N+L-1)/2)`;
//!   `idwt`: `x[n] = sum_i g[n+L-2-2i] cA[i] + ...`, `n in 0..2M-L+2`.
//! - `periodization`: odd `N` is first extended by repeating the last sample; then
//!   with `M` = the even length, `c[i] = sum_k h[k] x[(2i+L/2-k) mod M]`,
//!   `i in 0..M/2`; `idwt`: `x[n] = sum_k g[k] U[(n+L/2-1-k) mod 2M]` with
//!   `U[2i] = c[i]`, `U[2i+1] = 0`.
//!
//! `wavedec` returns PyWavelets' order `[cA_J, cD_J, cD_{J-1}, ..., cD_1]`;
//! `waverec` drops the last approximation sample when it is one longer than the
//! next detail array, as PyWavelets does.

use super::wavelet::Wavelet;
use super::{DspError, Result};

/// Signal extension mode of the batch reference (PyWavelets names).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Zero padding (`mode='zero'`). The streaming bank equals this exactly.
    Zero,
    /// Periodic, length-halving (`mode='periodization'`).
    Periodization,
}

/// Length of each `dwt` output for an input of length `n`.
pub fn dwt_len(n: usize, filter_len: usize, mode: Mode) -> usize {
    match mode {
        Mode::Zero => (n + filter_len - 1) / 2,
        Mode::Periodization => n.div_ceil(2),
    }
}

fn analysis_filter(x: &[f64], h: &[f64], mode: Mode) -> Vec<f64> {
    let l = h.len();
    match mode {
        Mode::Zero => {
            let n = x.len() as i64;
            (0..dwt_len(x.len(), l, mode))
                .map(|i| {
                    let mut s = 0.0;
                    for (k, &hk) in h.iter().enumerate() {
                        let m = 2 * i as i64 + 1 - k as i64;
                        if (0..n).contains(&m) {
                            s += hk * x[m as usize];
                        }
                    }
                    s
                })
                .collect()
        }
        Mode::Periodization => {
            let mut xe = x.to_vec();
            if xe.len() % 2 == 1 {
                xe.push(*x.last().expect("odd length is non-empty"));
            }
            let m = xe.len() as i64;
            (0..xe.len() / 2)
                .map(|i| {
                    let mut s = 0.0;
                    for (k, &hk) in h.iter().enumerate() {
                        let idx = (2 * i as i64 + (l / 2) as i64 - k as i64).rem_euclid(m);
                        s += hk * xe[idx as usize];
                    }
                    s
                })
                .collect()
        }
    }
}

/// One-level analysis: `(cA, cD)`.
pub fn dwt(x: &[f64], w: &Wavelet, mode: Mode) -> (Vec<f64>, Vec<f64>) {
    (
        analysis_filter(x, w.dec_lo(), mode),
        analysis_filter(x, w.dec_hi(), mode),
    )
}

/// One-level synthesis from `cA` and `cD` of equal length.
pub fn idwt(ca: &[f64], cd: &[f64], w: &Wavelet, mode: Mode) -> Result<Vec<f64>> {
    if ca.len() != cd.len() {
        return Err(DspError::LengthMismatch {
            what: "idwt",
            detail: format!("cA has {} coefficients, cD has {}", ca.len(), cd.len()),
        });
    }
    let (glo, ghi) = (w.rec_lo(), w.rec_hi());
    let l = glo.len();
    let m = ca.len();
    match mode {
        Mode::Zero => {
            let n_out = (2 * m + 2).saturating_sub(l);
            Ok((0..n_out)
                .map(|n| {
                    let mut s = 0.0;
                    for i in 0..m {
                        let k = (n + l - 2) as i64 - 2 * i as i64;
                        if (0..l as i64).contains(&k) {
                            s += glo[k as usize] * ca[i] + ghi[k as usize] * cd[i];
                        }
                    }
                    s
                })
                .collect())
        }
        Mode::Periodization => {
            let n_out = 2 * m;
            Ok((0..n_out)
                .map(|n| {
                    let mut s = 0.0;
                    for k in 0..l {
                        let u = (n as i64 + (l / 2) as i64 - 1 - k as i64).rem_euclid(n_out as i64)
                            as usize;
                        if u.is_multiple_of(2) {
                            s += glo[k] * ca[u / 2] + ghi[k] * cd[u / 2];
                        }
                    }
                    s
                })
                .collect())
        }
    }
}

/// Multi-level analysis to depth `level`: `[cA_level, cD_level, ..., cD_1]`.
pub fn wavedec(x: &[f64], w: &Wavelet, level: u32, mode: Mode) -> Vec<Vec<f64>> {
    let mut details = Vec::with_capacity(level as usize);
    let mut a = x.to_vec();
    for _ in 0..level {
        let (ca, cd) = dwt(&a, w, mode);
        details.push(cd);
        a = ca;
    }
    let mut out = vec![a];
    out.extend(details.into_iter().rev());
    out
}

/// Multi-level synthesis of `[cA_J, cD_J, ..., cD_1]`.
pub fn waverec(coeffs: &[Vec<f64>], w: &Wavelet, mode: Mode) -> Result<Vec<f64>> {
    let (first, rest) = coeffs.split_first().ok_or(DspError::LengthMismatch {
        what: "waverec",
        detail: "empty coefficient list".to_string(),
    })?;
    let mut a = first.clone();
    for d in rest {
        if a.len() == d.len() + 1 {
            a.pop();
        }
        a = idwt(&a, d, w, mode)?;
    }
    Ok(a)
}
