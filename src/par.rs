//! Independent evaluations split over the cores: the slow-effect analysis's
//! candidate regressors, noise-grid points and null replicas, the readout
//! filter search's candidates. Each item is computed exactly as it would be
//! alone, so the results do not depend on the number of threads.

/// `items.iter().map(f).collect()`, the items shared out in contiguous runs
/// over the available cores; the results in the items' order.
pub fn par_map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = threads().min(items.len());
    if threads <= 1 {
        return items.iter().map(f).collect();
    }
    let run = items.len().div_ceil(threads);
    let f = &f;
    std::thread::scope(|s| {
        let rest: Vec<_> = items
            .chunks(run)
            .skip(1)
            .map(|c| s.spawn(move || c.iter().map(f).collect::<Vec<R>>()))
            .collect();
        let mut out: Vec<R> = items[..run].iter().map(f).collect();
        for h in rest {
            out.extend(h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)));
        }
        out
    })
}

/// Run `a` and `b`, `b` on a second thread when there is a second core;
/// each computes exactly what it computes alone.
pub fn join(a: impl FnOnce() + Send, b: impl FnOnce() + Send) {
    if threads() <= 1 {
        a();
        b();
        return;
    }
    std::thread::scope(|s| {
        let h = s.spawn(b);
        a();
        h.join().unwrap_or_else(|p| std::panic::resume_unwind(p));
    });
}

/// The cores available to this process (looked up once).
fn threads() -> usize {
    static THREADS: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *THREADS.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_results_are_in_order_whatever_the_count() {
        for n in [0usize, 1, 2, 3, 7, 100] {
            let items: Vec<usize> = (0..n).collect();
            let got = par_map(&items, |&i| i * i + 1);
            let want: Vec<usize> = items.iter().map(|&i| i * i + 1).collect();
            assert_eq!(got, want, "{n} items");
        }
    }
}
