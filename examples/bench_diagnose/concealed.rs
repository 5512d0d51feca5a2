//! The concealed-effect table of `scripts/bench-diagnose`, on the cases the
//! tests assert (tests/diagnose/concealed/shared.rs).

#[path = "../../tests/diagnose/concealed/shared.rs"]
mod shared;

use shared::{cases, judge, run};

/// Each case is run with its own seed (the detail columns) and `seeds - 1`
/// further seeds; the last two columns count, over those seeds, the runs whose
/// named physics was right (with the truth in the widened intervals, as the
/// tests judge it) and the runs the raw Allan deviation alone missed.
pub fn table(seeds: u64) {
    let seeds = seeds.max(1);
    println!(
        "| case | effect | fs Hz | T s | raw-AV max|z| (5% thr) | verdict | named physics | fitted vs truth | chi2/dof before -> after | diagnose s | ok | correct / seeds | raw-AV concealed / seeds |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut misses = Vec::new();
    for mut case in cases() {
        let o = run(&case);
        let (named, fit, ok) = judge(&case, &o);
        let mut n_ok = ok as usize;
        let mut n_hid = (o.diag.raw_allan_max_z < o.raw_threshold) as usize;
        let base = case.seed;
        for k in 1..seeds {
            case.seed = base.wrapping_add(1000 * k);
            let ok_k = run(&case);
            let (named_k, fit_k, good) = judge(&case, &ok_k);
            n_ok += good as usize;
            n_hid += (ok_k.diag.raw_allan_max_z < ok_k.raw_threshold) as usize;
            if !good {
                misses.push(format!(
                    "{} seed {}: {:?}, {named_k} {fit_k} (detection max|z| {:.2}, threshold {:.2}; raw-AV max|z| {:.2})",
                    case.name,
                    case.seed,
                    ok_k.diag.report.verdict,
                    ok_k.diag.max_abs_z,
                    ok_k.diag.z_crit,
                    ok_k.diag.raw_allan_max_z
                ));
            }
        }
        case.seed = base;
        let r = &o.diag.report;
        println!(
            "| {} | {} | {} | {} | {:.2} ({:.2}) | {:?} | {} | {} | {:.2} -> {:.2} | {:.1} | {} | {n_ok}/{seeds} | {n_hid}/{seeds} |",
            case.name,
            case.what,
            case.fs,
            case.dur_s,
            o.diag.raw_allan_max_z,
            o.raw_threshold,
            r.verdict,
            named,
            fit,
            r.fit_before.chi2_per_dof,
            r.fit_after.chi2_per_dof,
            o.secs,
            if ok { "yes" } else { "NO" }
        );
    }
    for m in misses {
        println!("miss: {m}");
    }
}
