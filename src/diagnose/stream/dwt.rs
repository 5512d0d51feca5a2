//! The decimated sym8 transform of a stream, level by level: the detail
//! coefficients' mean squares ([`super::super::stats::dwt_level_mean_squares`]
//! on a whole record) and, where asked, a level's approximation coefficients.
//! Each level keeps the 14 or 15 input values its next window still needs;
//! the coefficients and their squares are formed and summed in the batch
//! order, so the result is the whole-record one to the bit however the input
//! is split.

use crate::diagnose::stats::analysis_step_any;

#[derive(Debug, Clone, Default)]
struct Level {
    /// Input values not yet consumed by a window.
    buf: Vec<f64>,
    ss: f64,
    n: usize,
    /// The approximation coefficients, when kept.
    approx: Option<Vec<f64>>,
}

/// The valid-convolution transform of a stream down to a fixed depth.
#[derive(Debug, Clone)]
pub struct DwtStream {
    lo: Vec<f64>,
    hi: Vec<f64>,
    levels: Vec<Level>,
    carry: Vec<f64>,
}

impl DwtStream {
    /// Levels `1..=depth`, keeping the approximation coefficients of the
    /// levels in `keep` (level 0 is the input itself: not kept here).
    pub fn new(lo: &[f64], hi: &[f64], depth: u32, keep: &[u32]) -> DwtStream {
        let levels = (1..=depth)
            .map(|j| Level {
                approx: keep.contains(&j).then(Vec::new),
                ..Level::default()
            })
            .collect();
        DwtStream {
            lo: lo.to_vec(),
            hi: hi.to_vec(),
            levels,
            carry: Vec::new(),
        }
    }

    /// Add input samples.
    pub fn push(&mut self, x: &[f64]) {
        let l = self.lo.len();
        self.carry.clear();
        self.carry.extend_from_slice(x);
        for lev in &mut self.levels {
            lev.buf.extend_from_slice(&self.carry);
            self.carry.clear();
            let len = lev.buf.len();
            if len < l {
                break;
            }
            let n_out = (len - l) / 2 + 1;
            lev.ss = analysis_step_any(&mut lev.buf, n_out, &self.lo, &self.hi, lev.ss);
            lev.n += n_out;
            let out = &lev.buf[..n_out];
            if let Some(a) = &mut lev.approx {
                a.extend_from_slice(out);
            }
            self.carry.extend_from_slice(out);
            lev.buf.drain(..2 * n_out);
        }
    }

    /// `(coefficients, mean square)` of the details of each level.
    pub fn level_mean_squares(&self) -> Vec<(usize, f64)> {
        self.levels
            .iter()
            .map(|l| (l.n, if l.n > 0 { l.ss / l.n as f64 } else { f64::NAN }))
            .collect()
    }

    /// The kept approximation coefficients of `level` (empty if not kept).
    pub fn approximation(&self, level: u32) -> &[f64] {
        let i = level as usize;
        if i == 0 || i > self.levels.len() {
            return &[];
        }
        self.levels[i - 1].approx.as_deref().unwrap_or(&[])
    }
}
