//! The sums of squared differences behind each statistic at one averaging
//! factor, and the deviation they give: the inner loops shared by the batch
//! engine ([`super::batch`]) and the noise identification ([`super::noise_id`]).

use super::{Phase, Stat};

/// Deviation and term count of `stat` at averaging factor `m`
/// (`tau = m * tau0_s`), or `None` when `m` is 0 or leaves no term.
pub fn deviation(phase: &Phase, stat: Stat, tau0_s: f64, m: u64) -> Option<(f64, u64)> {
    let n = stat.n_terms(phase.len() as u64, m)?;
    let sum = match phase {
        Phase::F64(x) => sum_squares(x, stat, m as usize, n as usize),
        Phase::Counts(x) => sum_squares(x, stat, m as usize, n as usize),
    };
    let tau = m as f64 * tau0_s;
    let var = match stat {
        Stat::Adev | Stat::Oadev => sum / (2.0 * n as f64 * tau * tau),
        Stat::Mdev => sum / (2.0 * (m * m) as f64 * n as f64 * tau * tau),
        Stat::Hdev | Stat::Ohdev => sum / (6.0 * n as f64 * tau * tau),
        Stat::Totdev => sum / (2.0 * n as f64 * tau * tau),
    };
    Some((var.sqrt(), n))
}

/// A phase sample type. Differences are formed in `Self::D` (exact for i64)
/// and converted to `f64` only afterwards.
pub(crate) trait PhaseValue: Copy + Send + Sync {
    type D: Copy + std::ops::Add<Output = Self::D> + std::ops::Sub<Output = Self::D>;
    /// x2 - 2 x1 + x0
    fn d2(x0: Self, x1: Self, x2: Self) -> Self::D;
    /// x3 - 3 x2 + 3 x1 - x0
    fn d3(x0: Self, x1: Self, x2: Self, x3: Self) -> Self::D;
    fn to(d: Self::D) -> f64;
    /// 2 pivot - x (point reflection, for TOTDEV)
    fn reflect(pivot: Self, x: Self) -> Self;
}

impl PhaseValue for f64 {
    type D = f64;
    #[inline(always)]
    fn d2(x0: f64, x1: f64, x2: f64) -> f64 {
        x2 - 2.0 * x1 + x0
    }
    #[inline(always)]
    fn d3(x0: f64, x1: f64, x2: f64, x3: f64) -> f64 {
        x3 - 3.0 * x2 + 3.0 * x1 - x0
    }
    #[inline(always)]
    fn to(d: f64) -> f64 {
        d
    }
    #[inline(always)]
    fn reflect(pivot: f64, x: f64) -> f64 {
        2.0 * pivot - x
    }
}

impl PhaseValue for i64 {
    type D = i64;
    #[inline(always)]
    fn d2(x0: i64, x1: i64, x2: i64) -> i64 {
        x2 - 2 * x1 + x0
    }
    #[inline(always)]
    fn d3(x0: i64, x1: i64, x2: i64, x3: i64) -> i64 {
        x3 - 3 * x2 + 3 * x1 - x0
    }
    #[inline(always)]
    fn to(d: i64) -> f64 {
        d as f64
    }
    #[inline(always)]
    fn reflect(pivot: i64, x: i64) -> i64 {
        2 * pivot - x
    }
}

/// Sum of squared difference terms for `stat` (n terms, factor m).
pub(crate) fn sum_squares<T: PhaseValue>(x: &[T], stat: Stat, m: usize, n: usize) -> f64 {
    match stat {
        Stat::Oadev => sum_sq_d2_overlapped(x, m, n),
        Stat::Adev => {
            let mut acc = Acc4::default();
            for k in 0..n {
                let i = k * m;
                acc.add(T::to(T::d2(x[i], x[i + m], x[i + 2 * m])));
            }
            acc.sum()
        }
        Stat::Ohdev => sum_sq_d3_overlapped(x, m, n),
        Stat::Hdev => {
            let mut acc = Acc4::default();
            for k in 0..n {
                let i = k * m;
                acc.add(T::to(T::d3(x[i], x[i + m], x[i + 2 * m], x[i + 3 * m])));
            }
            acc.sum()
        }
        Stat::Mdev => sum_sq_mdev(x, m, n),
        Stat::Totdev => sum_sq_totdev(x, m),
    }
}

/// Four independent accumulators of squares: breaks the add dependency chain.
#[derive(Default)]
struct Acc4 {
    s: [f64; 4],
    i: usize,
}

impl Acc4 {
    #[inline(always)]
    fn add(&mut self, d: f64) {
        self.s[self.i & 3] += d * d;
        self.i = self.i.wrapping_add(1);
    }
    fn sum(&self) -> f64 {
        (self.s[0] + self.s[1]) + (self.s[2] + self.s[3])
    }
}

/// sum_{i<n} (x[i+2m] - 2 x[i+m] + x[i])^2, vectorisable (four lanes, no bounds checks).
fn sum_sq_d2_overlapped<T: PhaseValue>(x: &[T], m: usize, n: usize) -> f64 {
    let (a, b, c) = (&x[..n], &x[m..m + n], &x[2 * m..2 * m + n]);
    let mut s = [0.0_f64; 4];
    let (ac, bc, cc) = (a.chunks_exact(4), b.chunks_exact(4), c.chunks_exact(4));
    let (ar, br, cr) = (ac.remainder(), bc.remainder(), cc.remainder());
    for ((qa, qb), qc) in ac.zip(bc).zip(cc) {
        for l in 0..4 {
            let d = T::to(T::d2(qa[l], qb[l], qc[l]));
            s[l] += d * d;
        }
    }
    let mut tail = 0.0;
    for ((&p, &q), &r) in ar.iter().zip(br).zip(cr) {
        let d = T::to(T::d2(p, q, r));
        tail += d * d;
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

/// sum_{i<n} (x[i+3m] - 3 x[i+2m] + 3 x[i+m] - x[i])^2, four lanes.
fn sum_sq_d3_overlapped<T: PhaseValue>(x: &[T], m: usize, n: usize) -> f64 {
    let (a, b, c, d) = (
        &x[..n],
        &x[m..m + n],
        &x[2 * m..2 * m + n],
        &x[3 * m..3 * m + n],
    );
    let mut s = [0.0_f64; 4];
    let (ac, bc, cc, dc) = (
        a.chunks_exact(4),
        b.chunks_exact(4),
        c.chunks_exact(4),
        d.chunks_exact(4),
    );
    let (ar, br, cr, dr) = (
        ac.remainder(),
        bc.remainder(),
        cc.remainder(),
        dc.remainder(),
    );
    for (((qa, qb), qc), qd) in ac.zip(bc).zip(cc).zip(dc) {
        for l in 0..4 {
            let e = T::to(T::d3(qa[l], qb[l], qc[l], qd[l]));
            s[l] += e * e;
        }
    }
    let mut tail = 0.0;
    for (((&p, &q), &r), &t) in ar.iter().zip(br).zip(cr).zip(dr) {
        let e = T::to(T::d3(p, q, r, t));
        tail += e * e;
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

/// MDEV: sum over j < n of v_j^2 with v_j = sum_{i=j}^{j+m-1} d2(i), where
/// v_{j+1} = v_j + x[j+3m] - 3 x[j+2m] + 3 x[j+m] - x[j] (O(N) per m; the
/// third differences are formed in `T::D`, exact for pulse counts).
fn sum_sq_mdev<T: PhaseValue>(x: &[T], m: usize, n: usize) -> f64 {
    let mut v = T::d2(x[0], x[m], x[2 * m]);
    for i in 1..m {
        v = v + T::d2(x[i], x[i + m], x[i + 2 * m]);
    }
    let first = T::to(v);
    // steps j = 0..n-1 produce v_1..v_{n-1}
    let steps = n - 1;
    let (a, b, c, d) = (
        &x[..steps],
        &x[m..m + steps],
        &x[2 * m..2 * m + steps],
        &x[3 * m..3 * m + steps],
    );
    let mut s = [0.0_f64; 4];
    let (ac, bc, cc, dc) = (
        a.chunks_exact(4),
        b.chunks_exact(4),
        c.chunks_exact(4),
        d.chunks_exact(4),
    );
    let (ar, br, cr, dr) = (
        ac.remainder(),
        bc.remainder(),
        cc.remainder(),
        dc.remainder(),
    );
    for (((qa, qb), qc), qd) in ac.zip(bc).zip(cc).zip(dc) {
        for l in 0..4 {
            v = v + T::d3(qa[l], qb[l], qc[l], qd[l]);
            let f = T::to(v);
            s[l] += f * f;
        }
    }
    let mut tail = first * first;
    for (((&p, &q), &r), &t) in ar.iter().zip(br).zip(cr).zip(dr) {
        v = v + T::d3(p, q, r, t);
        let f = T::to(v);
        tail += f * f;
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

/// TOTDEV: sum over i = 1..=N-2 of (x*[i-m] - 2 x[i] + x*[i+m])^2 with
/// x*[-j] = 2 x[0] - x[j] and x*[N-1+j] = 2 x[N-1] - x[N-1-j].
fn sum_sq_totdev<T: PhaseValue>(x: &[T], m: usize) -> f64 {
    let n = x.len();
    let last = n - 1;
    let ext = |k: isize| -> T {
        if k < 0 {
            T::reflect(x[0], x[(-k) as usize])
        } else if k as usize > last {
            T::reflect(x[last], x[2 * last - k as usize])
        } else {
            x[k as usize]
        }
    };
    // middle: i - m >= 0 and i + m <= N - 1
    let lo = m.max(1);
    let hi = (n - 2).min(last.saturating_sub(m)); // inclusive
    let mut acc = Acc4::default();
    let edge = |i: usize, acc: &mut Acc4| {
        let ii = i as isize;
        let mi = m as isize;
        acc.add(T::to(T::d2(ext(ii - mi), x[i], ext(ii + mi))));
    };
    if lo <= hi {
        for i in 1..lo {
            edge(i, &mut acc);
        }
        let mid = sum_sq_d2_overlapped(&x[lo - m..], m, hi - lo + 1);
        for i in hi + 1..=n - 2 {
            edge(i, &mut acc);
        }
        acc.sum() + mid
    } else {
        for i in 1..=n - 2 {
            edge(i, &mut acc);
        }
        acc.sum()
    }
}
