//! One-dimensional search shared by the diagnosis's refinements.

/// Golden-section search for the maximum of a unimodal `f` on `[a, b]`:
/// `iters` shrinking steps, then the midpoint of the last bracket.
pub(crate) fn golden_max(f: &dyn Fn(f64) -> f64, mut a: f64, mut b: f64, iters: usize) -> f64 {
    let g = 0.618_033_988_749_895;
    let mut c = b - g * (b - a);
    let mut d = a + g * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iters {
        if fc > fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    0.5 * (a + b)
}
