//! The batch Allan engine against every trustworthy Stable32 result file in
//! the shared AllanTools reference data (`../shared/data/allantools`, see its
//! README), and the NBS14 published values.
//!
//! Per row: the term count `#` exactly; the deviation within 1e-4 relative
//! (Stable32 prints 5 significant digits; the ocxo octave files have the
//! README's looser tolerances); Min/Max Sigma within 1e-3 relative where
//! Stable32 printed them, using Greenhall's EDF with the file's Alpha column
//! (that is what Stable32 did). Separately, our own noise identification is
//! compared with the Alpha column: the lag-1 ACF method must agree on every
//! row where it applies (>= 30 decimated points); the B1/R(n) fallback's
//! agreement is measured and must stay above a floor.
//!
//! The data are third-party (LGPL) and read in place; without them these
//! tests print a notice and pass, except under CI=true.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use sagnac::allan::{self, AllanOptions, DataKind, NoiseIdMethod, Phase, Stat};
use sagnac::input::Format;
use sagnac::input::plain::read_all;

use crate::support;

const CONF: f64 = 0.683; // Stable32's confidence factor

struct Row {
    af: u64,
    tau_col: f64,
    n: u64,
    alpha: i32,
    lo: f64,
    dev: f64,
    hi: f64,
}

/// Parse a Stable32 result file: `#` comment rows (including commented-out
/// data rows), CRLF, 7 whitespace-separated columns; tau comes from AF.
fn parse_stable32(path: &Path) -> Vec<Row> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let text = String::from_utf8_lossy(&bytes); // Theo1 headers carry a Latin-1/UTF-8 'ê'
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let l = line.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let f: Vec<&str> = l.split_whitespace().collect();
        assert_eq!(
            f.len(),
            7,
            "{}:{}: expected 7 columns: {l:?}",
            path.display(),
            i + 1
        );
        let num = |k: usize| -> f64 {
            f[k].parse()
                .unwrap_or_else(|_| panic!("{}:{}: {:?}", path.display(), i + 1, f[k]))
        };
        rows.push(Row {
            af: num(0) as u64,
            tau_col: num(1),
            n: num(2) as u64,
            alpha: num(3) as i32,
            lo: num(4),
            dev: num(5),
            hi: num(6),
        });
    }
    assert!(!rows.is_empty(), "{}: no rows", path.display());
    rows
}

fn rel(a: f64, b: f64) -> f64 {
    ((a - b) / b).abs()
}

struct Dataset {
    dir: PathBuf,
    phase: Phase,
    tau0: f64,
}

impl Dataset {
    fn load(
        root: &Path,
        sub: &str,
        file: &str,
        kind: DataKind,
        tau0: f64,
        hz_to_fractional: bool,
    ) -> Dataset {
        let dir = root.join("allantools").join(sub);
        let path = dir.join(file);
        // our own reader: gz, CRLF, comment lines, `+2.7E-007` numbers
        let mut v = read_all(&path, Format::Text, None).unwrap_or_else(|e| panic!("{e}"));
        if hz_to_fractional {
            v.iter_mut().for_each(|f| *f = (*f - 1.0e7) / 1.0e7);
        }
        let phase = Phase::from_samples(&v, kind, tau0).unwrap();
        Dataset { dir, phase, tau0 }
    }
    fn n_phase(&self) -> u64 {
        self.phase.len() as u64
    }
}

#[derive(Clone, Copy)]
enum Ci {
    /// Compare Min/Max Sigma directly (relative tolerance).
    Direct(f64),
    /// Compare (Min/Max Sigma) / Sigma: the interval's width alone, for files
    /// whose Sigma is itself only good to ~1e-3 (ocxo octave).
    Ratio(f64),
    /// Not printed (all-tau runs).
    None,
}

#[derive(Default, Debug)]
struct Report {
    /// the file prints Min/Max Sigma (an octave/decade run)
    has_ci: bool,
    rows: usize,
    worst_dev: f64,
    worst_ci: f64,
    lag1_rows: usize,
    lag1_agree: usize,
    fb_rows: usize,
    fb_agree: usize,
    own_ci_rows: usize,
    own_ci_within_1e2: usize,
}

/// Stable32 TOTDEV runs whose Alpha column is a user setting (constant 0 for
/// "no bias correction"), not a noise identification: excluded from the
/// noise-id comparison (their CIs still use that alpha and are still checked).
const ALPHA_IS_A_SETTING: [&str; 3] = [
    "totdev_alpha0.txt",
    "totdev_decade.txt",
    "stable32_totdev_alltau.txt",
];

/// Check one Stable32 file; `exceptions` lists (AF, CI tolerance) overrides.
fn check(
    ds: &Dataset,
    file: &str,
    stat: Stat,
    tau0: f64,
    dev_tol: f64,
    ci: Ci,
    exceptions: &[(u64, f64)],
) -> Report {
    let alpha_fixed = ALPHA_IS_A_SETTING.contains(&file) && (stat == Stat::Totdev);
    let path = ds.dir.join(file);
    let rows = parse_stable32(&path);
    let n_phase = ds.n_phase();
    let mut rep = Report {
        has_ci: !matches!(ci, Ci::None),
        ..Report::default()
    };
    // the engine's own pipeline (noise id -> EDF -> interval) on the same AFs
    let afs: Vec<u64> = rows.iter().map(|r| r.af).collect();
    let engine = allan::compute_at(&ds.phase, stat, tau0, &afs, &AllanOptions::default()).unwrap();
    for (r, p) in rows.iter().zip(&engine.points) {
        let what = format!("{file} AF={}", r.af);
        let (dev, n) = (p.dev, p.n);
        assert_eq!((p.m, n), (r.af, r.n), "{what}: term count");
        assert_eq!(p.tau_s, r.af as f64 * tau0, "{what}: tau");
        assert!(
            rel(r.af as f64 * tau0, r.tau_col) < 1e-4,
            "{what}: Tau column {} vs AF*tau0",
            r.tau_col
        ); // 5 digits printed
        let e = rel(dev, r.dev);
        assert!(
            e < dev_tol,
            "{what}: dev {dev:.6e} vs Stable32 {:.5e} (rel {e:.2e}, tol {dev_tol:e})",
            r.dev
        );
        rep.worst_dev = rep.worst_dev.max(e);
        rep.rows += 1;

        // Stable32's CI: Greenhall EDF with the file's Alpha
        let printed = r.lo > 0.0 && r.hi > 0.0;
        let edf = allan::edf_for_stat(stat, r.alpha, r.af, n_phase);
        let (lo, hi) = allan::chi2_interval(dev, edf, CONF);
        let ci_err = match ci {
            Ci::Direct(_) => rel(lo, r.lo).max(rel(hi, r.hi)),
            Ci::Ratio(_) => rel(lo / dev, r.lo / r.dev).max(rel(hi / dev, r.hi / r.dev)),
            Ci::None => 0.0,
        };
        if let (true, Ci::Direct(tol) | Ci::Ratio(tol)) = (printed, ci) {
            let tol = exceptions.iter().find(|x| x.0 == r.af).map_or(tol, |x| x.1);
            assert!(
                ci_err < tol,
                "{what}: CI ({lo:.5e}, {hi:.5e}) vs Stable32 ({:.5e}, {:.5e}), alpha {} edf {edf:.3}: rel {ci_err:.2e} > {tol:e}",
                r.lo,
                r.hi,
                r.alpha
            );
            rep.worst_ci = rep.worst_ci.max(ci_err);
        }

        // our own noise identification against the Alpha column
        if alpha_fixed {
            continue;
        }
        let own = allan::noise_id(&ds.phase, stat, r.af);
        let agree = own.alpha == r.alpha;
        if !agree && std::env::var_os("SAGNAC_DEBUG_NOISE_ID").is_some() {
            eprintln!(
                "  mismatch {what}: file alpha {} own {} ({:?})",
                r.alpha, own.alpha, own.method
            );
        }
        match own.method {
            NoiseIdMethod::Lag1Acf => {
                rep.lag1_rows += 1;
                rep.lag1_agree += agree as usize;
            }
            _ => {
                rep.fb_rows += 1;
                rep.fb_agree += agree as usize;
            }
        }
        assert_eq!(p.alpha, own.alpha, "{what}: engine alpha");
        if printed && !matches!(ci, Ci::None) {
            // the engine's interval (own noise id) against Stable32's
            let (lo2, hi2) = (p.ci_lo, p.ci_hi);
            rep.own_ci_rows += 1;
            let e2 = match ci {
                Ci::Ratio(_) => rel(lo2 / dev, r.lo / r.dev).max(rel(hi2 / dev, r.hi / r.dev)),
                _ => rel(lo2, r.lo).max(rel(hi2, r.hi)),
            };
            if own.method == NoiseIdMethod::Lag1Acf {
                // README: intervals from a noise identification agree within 1e-2
                assert!(
                    e2 < 1e-2,
                    "{what}: engine CI ({lo2:.5e}, {hi2:.5e}) vs Stable32 ({:.5e}, {:.5e})",
                    r.lo,
                    r.hi
                );
            }
            rep.own_ci_within_1e2 += (e2 < 1e-2) as usize;
        }
    }
    rep
}

/// Assert the noise-id results and print the per-file summary.
///
/// * CI files (octave/decade runs): the lag-1 ACF identification must equal
///   the Alpha column on every row where it applies.
/// * All-tau runs: at least 93 % (tic_adev: 175/186; the misses sit on the rho = 0.25 or
///   2 rho = -0.5 decision boundaries).
/// * B1/R(n) fallback rows: Stable32's rule there is undocumented; the
///   measured agreement must not fall below `fallback_floor` (a regression
///   guard set just under what we measure, reported in the summary).
fn finish(label: &str, reports: Vec<(String, Report)>, fallback_floor: f64) {
    let (mut ci_l, mut all_l, mut fb) = ((0, 0), (0, 0), (0, 0));
    for (file, r) in &reports {
        eprintln!(
            "{label:8} {file:34} rows {:3}  dev<= {:.1e}  ci<= {:.1e}  lag1 {}/{}  b1rn {}/{}  engine CI<1e-2 {}/{}",
            r.rows,
            r.worst_dev,
            r.worst_ci,
            r.lag1_agree,
            r.lag1_rows,
            r.fb_agree,
            r.fb_rows,
            r.own_ci_within_1e2,
            r.own_ci_rows
        );
        let l = if r.has_ci { &mut ci_l } else { &mut all_l };
        l.0 += r.lag1_agree;
        l.1 += r.lag1_rows;
        fb.0 += r.fb_agree;
        fb.1 += r.fb_rows;
    }
    eprintln!(
        "{label:8} noise id vs Alpha column: lag-1 ACF {}/{} (CI files), {}/{} (all-tau files); B1/R(n) fallback {}/{}",
        ci_l.0, ci_l.1, all_l.0, all_l.1, fb.0, fb.1
    );
    assert_eq!(
        ci_l.0, ci_l.1,
        "{label}: lag-1 ACF noise id must reproduce the Alpha column of the CI files"
    );
    assert!(
        all_l.0 as f64 >= 0.93 * all_l.1 as f64,
        "{label}: all-tau lag-1 agreement {}/{}",
        all_l.0,
        all_l.1
    );
    if fb.1 > 0 {
        let frac = fb.0 as f64 / fb.1 as f64;
        assert!(
            frac >= fallback_floor,
            "{label}: B1/R(n) agreement {frac:.2} below floor {fallback_floor}"
        );
    }
}

fn stat_files(prefix: &str, suffix: &str, stats: &[(&str, Stat)]) -> Vec<(String, Stat)> {
    stats
        .iter()
        .map(|(s, st)| (format!("{prefix}{s}{suffix}"), *st))
        .collect()
}

const SIX: [(&str, Stat); 6] = [
    ("adev", Stat::Adev),
    ("oadev", Stat::Oadev),
    ("mdev", Stat::Mdev),
    ("hdev", Stat::Hdev),
    ("ohdev", Stat::Ohdev),
    ("totdev", Stat::Totdev),
];

#[test]
fn phasedat() {
    let Some(root) = support::shared_data() else {
        return;
    };
    let ds = Dataset::load(&root, "phasedat", "PHASE.DAT", DataKind::Phase, 1.0, false);
    assert_eq!(ds.n_phase(), 1001);
    let mut reps = Vec::new();
    for (f, st) in stat_files("phase_dat_", "_octave.txt", &SIX) {
        reps.push((
            f.clone(),
            check(&ds, &f, st, 1.0, 1e-4, Ci::Direct(1e-3), &[]),
        ));
    }
    for (f, st) in stat_files("phase_dat_", ".txt", &SIX) {
        reps.push((f.clone(), check(&ds, &f, st, 1.0, 1e-4, Ci::None, &[])));
    }
    finish("phasedat", reps, 0.55);
}

#[test]
fn pink_frequency() {
    let Some(root) = support::shared_data() else {
        return;
    };
    // tau0 = 42 s for every file except s32_oadev_octave.txt (run with 1 s)
    let ds42 = Dataset::load(
        &root,
        "pink_frequency",
        "pink_frequency.txt",
        DataKind::Freq,
        42.0,
        false,
    );
    assert_eq!(ds42.n_phase(), 10001);
    let mut reps = Vec::new();
    let files = [
        ("adev.txt", Stat::Adev),
        ("oadev.txt", Stat::Oadev),
        ("mdev.txt", Stat::Mdev),
        ("hdev.txt", Stat::Hdev),
        ("ohdev.txt", Stat::Ohdev),
        ("totdev_alpha0.txt", Stat::Totdev),
    ];
    for (f, st) in files {
        reps.push((
            f.to_string(),
            check(&ds42, f, st, ds42.tau0, 1e-4, Ci::None, &[]),
        ));
    }
    let ds1 = Dataset::load(
        &root,
        "pink_frequency",
        "pink_frequency.txt",
        DataKind::Freq,
        1.0,
        false,
    );
    reps.push((
        "s32_oadev_octave.txt".into(),
        check(
            &ds1,
            "s32_oadev_octave.txt",
            Stat::Oadev,
            1.0,
            1e-4,
            Ci::Direct(1e-3),
            &[],
        ),
    ));
    finish("pink", reps, 0.55);
}

#[test]
fn keysight_counter_noise_floor() {
    let Some(root) = support::shared_data() else {
        return;
    };
    let ds = Dataset::load(
        &root,
        "Keysight53230A_ti_noise_floor",
        "tic_phase.txt",
        DataKind::Phase,
        1.0,
        false,
    );
    assert_eq!(ds.n_phase(), 55688);
    let mut reps = Vec::new();
    reps.push((
        "tic_adev.txt".into(),
        check(&ds, "tic_adev.txt", Stat::Adev, 1.0, 1e-4, Ci::None, &[]),
    ));
    for (f, st) in stat_files("tic_", ".txt", &SIX[1..]) {
        reps.push((
            f.clone(),
            check(&ds, &f, st, 1.0, 1e-4, Ci::Direct(1e-3), &[]),
        ));
    }
    finish("tic", reps, 0.55);
}

#[test]
fn gps() {
    let Some(root) = support::shared_data() else {
        return;
    };
    let ds = Dataset::load(
        &root,
        "gps",
        "gps_1pps_phase_data.txt.gz",
        DataKind::Phase,
        1.0,
        false,
    );
    assert_eq!(ds.n_phase(), 241218);
    let mut reps = Vec::new();
    let files = [
        ("stable32_ADEV_decade.txt", Stat::Adev),
        ("stable32_OADEV_octave.txt", Stat::Oadev),
        ("stable32_MDEV_octave.txt", Stat::Mdev),
        ("stable32_HDEV_octave.txt", Stat::Hdev),
        ("stable32_OHDEV_octave.txt", Stat::Ohdev),
        ("stable32_TOTDEV_octave.txt", Stat::Totdev),
    ];
    for (f, st) in files {
        // Exception: TOTDEV AF 65536 (3.7 averages, alpha 1): Stable32's TOTVAR EDF for
        // flicker PM is undocumented; SP 1065's simple AVAR formula is 4.8 % low in EDF,
        // 3.2e-3 in the bounds. Every other alpha-1/2 TOTDEV row agrees within 5.4e-4.
        let exc: &[(u64, f64)] = if st == Stat::Totdev {
            &[(65536, 4e-3)]
        } else {
            &[]
        };
        reps.push((
            f.to_string(),
            check(&ds, f, st, 1.0, 1e-4, Ci::Direct(1e-3), exc),
        ));
    }
    finish("gps", reps, 0.55);
}

#[test]
fn cs5071a() {
    let Some(root) = support::shared_data() else {
        return;
    };
    let ds = Dataset::load(
        &root,
        "Cs5071A",
        "5071A_phase.txt.gz",
        DataKind::Phase,
        1.0,
        false,
    );
    assert_eq!(ds.n_phase(), 556990);
    let mut reps = Vec::new();
    for (f, st) in stat_files("", "_decade.txt", &SIX) {
        reps.push((
            f.clone(),
            check(&ds, &f, st, 1.0, 1e-4, Ci::Direct(1e-3), &[]),
        ));
    }
    for (f, st) in stat_files("", "_all.txt", &SIX) {
        reps.push((f.clone(), check(&ds, &f, st, 1.0, 1e-4, Ci::None, &[])));
    }
    finish("Cs5071A", reps, 0.25);
}

#[test]
fn ocxo() {
    let Some(root) = support::shared_data() else {
        return;
    };
    // Hz -> fractional frequency (the README's recipe); freq_to_phase removes the mean
    let ds = Dataset::load(
        &root,
        "ocxo",
        "ocxo_frequency.txt",
        DataKind::Freq,
        1.0,
        true,
    );
    assert_eq!(ds.n_phase(), 19983);
    let mut reps = Vec::new();
    for (f, st) in stat_files("stable32_", "_alltau.txt", &SIX) {
        reps.push((f.clone(), check(&ds, &f, st, 1.0, 1e-4, Ci::None, &[])));
    }
    // The octave files were computed by Stable32 from a copy normalised to ~1.0 and are
    // only good to ~1e-3 (README): dev tolerance 2e-4 for adev, 2e-3 for the others,
    // 1.5e-2 for totdev (measured 1.22e-2 at AF 1024). Their Sigma being off, the
    // intervals are compared as ratios to Sigma, at 1e-3.
    for (f, st) in stat_files("", "_octave.txt", &SIX) {
        let tol = match st {
            Stat::Adev => 2e-4,
            Stat::Totdev => 1.5e-2,
            _ => 2e-3,
        };
        reps.push((
            f.clone(),
            check(&ds, &f, st, 1.0, tol, Ci::Ratio(1e-3), &[]),
        ));
    }
    finish("ocxo", reps, 0.45);
}

#[test]
fn stable32_all_tau_lists_follow_the_progression_rule() {
    // AF lists of the "all tau" files: m += 1 + m / D (D per run), up to the stop ratio.
    let Some(root) = support::shared_data() else {
        return;
    };
    let a = root.join("allantools");
    let cases: [(&str, Stat, u64, bool); 8] = [
        ("phasedat/phase_dat_adev.txt", Stat::Adev, 1001, true),
        ("phasedat/phase_dat_oadev.txt", Stat::Oadev, 1001, true),
        ("phasedat/phase_dat_totdev.txt", Stat::Totdev, 1001, true),
        ("pink_frequency/adev.txt", Stat::Adev, 10001, true),
        ("pink_frequency/oadev.txt", Stat::Oadev, 10001, false), // last two rows commented out
        ("ocxo/stable32_totdev_alltau.txt", Stat::Totdev, 19983, true),
        ("Cs5071A/mdev_all.txt", Stat::Mdev, 556990, true),
        ("Cs5071A/hdev_all.txt", Stat::Hdev, 556990, true),
    ];
    for (f, stat, n, complete) in cases {
        let afs: Vec<u64> = parse_stable32(&a.join(f)).iter().map(|r| r.af).collect();
        let dense = afs
            .windows(2)
            .find(|w| w[1] - w[0] == 2)
            .map(|w| w[0])
            .expect("a step of 2");
        let want = allan::batch::all_tau_progression(allan::max_m(stat, n), dense);
        assert_eq!(&want[..afs.len()], &afs[..], "{f}");
        if complete {
            assert_eq!(want.len(), afs.len(), "{f}: stop ratio");
        }
    }
}

#[test]
fn nbs14_reference_values() {
    let Some(root) = support::shared_data() else {
        return;
    };
    let a = root.join("allantools");
    let text = std::fs::read_to_string(a.join("nbs14/nbs14_reference_values.txt")).unwrap();
    let load = |p: &str, kind: DataKind| {
        let v = read_all(&a.join(p), Format::Text, None).unwrap();
        Phase::from_samples(&v, kind, 1.0).unwrap()
    };
    let sets: BTreeMap<&str, Vec<Phase>> = BTreeMap::from([
        (
            "10pt",
            vec![
                load("nbs14/nbs14_10point_phase.txt", DataKind::Phase),
                load("nbs14/nbs14_10point_frequency.txt", DataKind::Freq),
            ],
        ),
        (
            "1000pt",
            vec![
                load("phasedat/PHASE.DAT", DataKind::Phase),
                load("nbs14/nbs14_1000point_frequency.txt", DataKind::Freq),
            ],
        ),
    ]);
    let mut checked = 0;
    for line in text.lines() {
        let f: Vec<&str> = line.split_whitespace().collect();
        if line.starts_with('#') || f.len() < 5 || f[4] != "TESTED" {
            continue;
        }
        let stat = match f[1] {
            "adev" => Stat::Adev,
            "oadev" => Stat::Oadev,
            "mdev" => Stat::Mdev,
            "hdev" => Stat::Hdev,
            "ohdev" => Stat::Ohdev,
            "totdev" => Stat::Totdev,
            _ => continue, // tdev, htotdev, theo1, pdev: not implemented here
        };
        let m: u64 = f[2].parse().unwrap();
        let want: f64 = f[3].parse().unwrap();
        let digits = f[3]
            .split(['e', 'E'])
            .next()
            .unwrap()
            .chars()
            .filter(|c| c.is_ascii_digit())
            .count();
        // 7 significant digits: 1e-6 relative; 5-6 digits: 1e-4
        let tol = if digits >= 7 { 1e-6 } else { 1e-4 };
        for phase in &sets[f[0]] {
            let (dev, _) = allan::deviation(phase, stat, 1.0, m).unwrap();
            assert!(
                rel(dev, want) < tol,
                "NBS14 {} {} m={m}: {dev} vs {want} (rel {:e})",
                f[0],
                f[1],
                rel(dev, want)
            );
            checked += 1;
        }
    }
    assert_eq!(
        checked,
        2 * 30,
        "NBS14 TESTED entries for our statistics, phase and frequency input"
    );
}
