//! The model comparison's candidates on the concealed Gauss-Markov case of
//! tests/diagnose/compare.rs, seed by seed: the wavelet and MDEV points
//! against the model, and each catalog candidate's likelihood ratio and
//! fitted parameters with their intervals (docs/diagnose.md). A debugging
//! dump on stderr, with the test's gyro and simulation
//! (tests/diagnose/compare/shared.rs).

use sagnac::diagnose::candidates;
use sagnac::diagnose::compare::Family;
use sagnac::diagnose::stats::StatLayout;
use sagnac::diagnose::wvar_fit::{Basis, LevelData};
use sagnac::diagnose::{self, DiagnoseOptions};

#[path = "../../tests/diagnose/compare/shared.rs"]
mod shared;

use shared::{paper, simulate, summary};

/// The dump for each of `seeds`.
pub fn dump(seeds: &[u64]) {
    let model = paper("");
    let truth = paper("[[noise.gauss_markov]]\nsigma_dph = 0.03\ntau_c_s = 5.0\n");
    for &seed in seeds {
        eprintln!("=== seed {seed}");
        let rec = simulate(&truth, seed, 3600.0);
        let d = diagnose::diagnose(&model, &rec, &DiagnoseOptions::default()).unwrap();
        let layout = StatLayout::new(rec.counts.len(), 1000.0, 1.21);
        let w: Vec<_> = d
            .before
            .iter()
            .filter(|p| p.family == Family::Wavelet)
            .collect();
        for p in &w {
            eprintln!(
                "level {:>2} tau {:8.3}-{:8.3} obs/model {:.3} sd {:.3} z {:.2}",
                layout.levels[p.index],
                p.tau_lo_s,
                p.tau_hi_s,
                p.obs / p.model_mean,
                p.sd_log,
                p.z
            );
        }
        for p in d.before.iter().filter(|p| p.family == Family::Mdev) {
            eprintln!(
                "mdev tau {:8.3} obs/model {:.3} sd {:.3} z {:.2}",
                p.tau_lo_s,
                p.obs / p.model_mean,
                p.sd_log,
                p.z
            );
        }
        let data = LevelData {
            levels: layout.levels.clone(),
            y: w.iter().map(|p| p.obs).collect(),
            e0: w.iter().map(|p| p.model_mean).collect(),
            nu: w
                .iter()
                .map(|p| 2.0 / (p.sd_log * p.sd_log * (1.0 + 1.0 / p.runs as f64)))
                .collect(),
        };
        let basis = Basis::new(&layout.lo, &layout.hi, 1e-3, &layout.levels);
        let l0 = data.loglik(&data.e0);
        for c in candidates::candidates(&data, &basis, &model, 3600.0) {
            eprintln!(
                "{:30} LR {:7.2} theta {:.4e} ci {:?} shape {:?} {:?}",
                c.name,
                2.0 * (c.fit.loglik - l0),
                c.fit.theta,
                c.fit.theta_ci,
                c.fit.shape,
                c.fit.shape_ci
            );
        }
        eprintln!("{}", summary(&d));
        for n in &d.notes {
            eprintln!("note: {n}");
        }
    }
}
