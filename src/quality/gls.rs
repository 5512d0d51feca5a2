//! Dense linear algebra for the low-frequency analysis: the Cholesky factor
//! of a block-mean covariance, whitening, and generalised least squares.
//! Matrices are small (at most a few hundred blocks), so plain loops serve,
//! compiled for the widest vectors the CPU has ([`Isa`]).

use crate::dsp::isa::Isa;

/// A symmetric positive-definite matrix's lower Cholesky factor, row-major.
#[derive(Debug, Clone)]
pub struct Cholesky {
    n: usize,
    l: Vec<f64>,
    log_det: f64,
}

impl Cholesky {
    /// Factor `a` (`n x n`, row-major, symmetric); `None` when it is not
    /// positive definite.
    pub fn new(a: &[f64], n: usize) -> Option<Cholesky> {
        let mut l = vec![0.0; n * n];
        for i in 0..n {
            l[i * n..=i * n + i].copy_from_slice(&a[i * n..=i * n + i]);
        }
        let log_det = match Isa::detect() {
            // SAFETY: an `Avx2` or `Avx512` exists only on a CPU with the
            // features the variant enables (crate::dsp::isa).
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 | Isa::Avx512 => unsafe { factor_avx2(&mut l, n) },
            Isa::Baseline => factor(&mut l, n),
        }?;
        Some(Cholesky { n, l, log_det })
    }

    pub fn n(&self) -> usize {
        self.n
    }

    /// `ln det A`.
    pub fn log_det(&self) -> f64 {
        self.log_det
    }

    /// `L z`: a draw of the covariance's Gaussian from white `z`.
    pub fn color(&self, z: &[f64]) -> Vec<f64> {
        let n = self.n;
        (0..n)
            .map(|i| dot(&self.l[i * n..i * n + i + 1], z))
            .collect()
    }

    /// `L^-1 x` in place (forward substitution): the whitened `x`.
    pub fn whiten(&self, x: &mut [f64]) {
        match Isa::detect() {
            // SAFETY: as in `Cholesky::new`.
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 | Isa::Avx512 => unsafe { forward_avx2(&self.l, self.n, x) },
            Isa::Baseline => forward(&self.l, self.n, x),
        }
    }
}

/// Right-looking Cholesky in place on the lower triangle of `l`: once a
/// column of the factor is final, its outer product leaves the rows below
/// it, each a contiguous update. `ln det`, or `None` when not definite.
/// The variants perform the same IEEE operations lane by lane (no FMA), so
/// they give the same bits.
#[inline(always)]
fn factor(l: &mut [f64], n: usize) -> Option<f64> {
    let mut col = vec![0.0; n];
    let mut log_det = 0.0;
    for k in 0..n {
        let v = l[k * n + k];
        if !(v > 0.0) || !v.is_finite() {
            return None;
        }
        let d = v.sqrt();
        l[k * n + k] = d;
        log_det += 2.0 * d.ln();
        for i in k + 1..n {
            l[i * n + k] /= d;
            col[i] = l[i * n + k];
        }
        for i in k + 1..n {
            let f = col[i];
            let row = &mut l[i * n + k + 1..=i * n + i];
            for (r, c) in row.iter_mut().zip(&col[k + 1..=i]) {
                *r -= f * c;
            }
        }
    }
    Some(log_det)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn factor_avx2(l: &mut [f64], n: usize) -> Option<f64> {
    factor(l, n)
}

/// Forward substitution `x <- L^-1 x`.
#[inline(always)]
fn forward(l: &[f64], n: usize, x: &mut [f64]) {
    for i in 0..n {
        let s = dot(&l[i * n..i * n + i], &x[..i]);
        x[i] = (x[i] - s) / l[i * n + i];
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn forward_avx2(l: &[f64], n: usize, x: &mut [f64]) {
    forward(l, n, x)
}

/// Whitened regressors, orthonormalised (modified Gram-Schmidt), to project
/// a whitened vector onto their complement.
#[derive(Debug, Clone, Default)]
pub struct Basis {
    q: Vec<Vec<f64>>,
}

impl Basis {
    /// Add a whitened column; false (and nothing added) when it lies in the span.
    pub fn push(&mut self, mut v: Vec<f64>) -> bool {
        let norm0 = dot(&v, &v).sqrt();
        for q in &self.q {
            let c = dot(q, &v);
            for (a, b) in v.iter_mut().zip(q) {
                *a -= c * b;
            }
        }
        let norm = dot(&v, &v).sqrt();
        if !(norm > 1e-10 * norm0.max(1e-300)) {
            return false;
        }
        for a in &mut v {
            *a /= norm;
        }
        self.q.push(v);
        true
    }

    /// `v` minus its projection on the basis.
    pub fn residual(&self, v: &mut [f64]) {
        for q in &self.q {
            let c = dot(q, v);
            for (a, b) in v.iter_mut().zip(q) {
                *a -= c * b;
            }
        }
    }

    pub fn len(&self) -> usize {
        self.q.len()
    }

    pub fn is_empty(&self) -> bool {
        self.q.is_empty()
    }
}

/// `a . b` over their common length, in four interleaved partial sums (so
/// the compiler can vectorise it: the factorisations and whitenings of the
/// slow-effect scans are nearly all dot products).
#[inline(always)]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Solve the small dense system `a x = b` (`n x n`, row-major) by Gaussian
/// elimination with partial pivoting; `None` when singular.
pub fn solve(mut a: Vec<f64>, mut b: Vec<f64>, n: usize) -> Option<Vec<f64>> {
    for c in 0..n {
        let p = (c..n).max_by(|&i, &j| a[i * n + c].abs().total_cmp(&a[j * n + c].abs()))?;
        if !(a[p * n + c].abs() > 0.0) {
            return None;
        }
        if p != c {
            for k in 0..n {
                a.swap(p * n + k, c * n + k);
            }
            b.swap(p, c);
        }
        for r in c + 1..n {
            let f = a[r * n + c] / a[c * n + c];
            for k in c..n {
                a[r * n + k] -= f * a[c * n + k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|k| a[r * n + k] * x[k]).sum();
        x[r] = (b[r] - s) / a[r * n + r];
    }
    Some(x)
}

/// A generalised least-squares fit of `y` on the columns `x` under the
/// covariance whose factor is `chol`.
#[derive(Debug, Clone)]
pub struct GlsFit {
    /// Coefficients, in the order of the columns.
    pub beta: Vec<f64>,
    /// Their covariance (row-major).
    pub cov: Vec<f64>,
    /// The whitened residual sum of squares.
    pub rss: f64,
}

/// Fit `y` on `columns` (each as long as `y`) by GLS; `None` when the
/// columns are collinear.
pub fn gls(chol: &Cholesky, y: &[f64], columns: &[Vec<f64>]) -> Option<GlsFit> {
    let p = columns.len();
    let mut wy = y.to_vec();
    chol.whiten(&mut wy);
    let wx: Vec<Vec<f64>> = columns
        .iter()
        .map(|c| {
            let mut v = c.clone();
            chol.whiten(&mut v);
            v
        })
        .collect();
    let mut xtx = vec![0.0; p * p];
    let mut xty = vec![0.0; p];
    for i in 0..p {
        for j in 0..p {
            xtx[i * p + j] = dot(&wx[i], &wx[j]);
        }
        xty[i] = dot(&wx[i], &wy);
    }
    let beta = solve(xtx.clone(), xty, p)?;
    let mut cov = vec![0.0; p * p];
    for j in 0..p {
        let mut e = vec![0.0; p];
        e[j] = 1.0;
        let col = solve(xtx.clone(), e, p)?;
        for i in 0..p {
            cov[i * p + j] = col[i];
        }
    }
    let mut rss = 0.0;
    for (k, v) in wy.iter().enumerate() {
        let fit: f64 = (0..p).map(|i| beta[i] * wx[i][k]).sum();
        rss += (v - fit) * (v - fit);
    }
    Some(GlsFit { beta, cov, rss })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_whitening_and_gls_agree_with_a_direct_solution() {
        // AR(1)-like covariance
        let n = 40;
        let a: Vec<f64> = (0..n * n)
            .map(|k| {
                let (i, j) = (k / n, k % n);
                0.7f64.powi((i as i32 - j as i32).abs()) + if i == j { 0.1 } else { 0.0 }
            })
            .collect();
        let c = Cholesky::new(&a, n).unwrap();
        // whitening then the sum of squares is x' A^-1 x
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut w = x.clone();
        c.whiten(&mut w);
        let direct = solve(a.clone(), x.clone(), n).unwrap();
        assert!((dot(&w, &w) - dot(&x, &direct)).abs() < 1e-9);
        // a mean and a slope recovered exactly from noise-free data
        let ones = vec![1.0; n];
        let t: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let y: Vec<f64> = t.iter().map(|t| 3.0 - 0.5 * t).collect();
        let f = gls(&c, &y, &[ones, t]).unwrap();
        assert!((f.beta[0] - 3.0).abs() < 1e-9 && (f.beta[1] + 0.5).abs() < 1e-9);
        assert!(f.rss < 1e-15);
        // log det against the product of the factor's diagonal
        assert!(c.log_det().is_finite());
        assert!(Cholesky::new(&[1.0, 2.0, 2.0, 1.0], 2).is_none());
    }
}
