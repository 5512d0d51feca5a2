//! The compared points of a recording against any model, without the rest of
//! the diagnosis: used to judge an effect against the band of the simulator
//! that made the recording (issue 14: an effect is "concealed" only when the
//! raw Allan deviation misses it against that band) and to measure how far an
//! effect moves each statistic (the power bench).

use super::{
    DiagnoseError, DiagnoseOptions, Recording, all_points, check_recording, kurtosis_scales, mask_counter_lines, mc,
    reference_model, stats,
};
use super::compare::Point;
use super::stats::StatLayout;
use crate::model::GyroModel;

/// The points (wavelet, MDEV, spectral bands, raw Allan, kurtosis) of `rec`
/// against `opts.runs` Monte-Carlo runs of `model` at the recording's rate,
/// pulse weight and mean input.
pub fn points_against(model: &GyroModel, rec: &Recording, opts: &DiagnoseOptions) -> Result<Vec<Point>, DiagnoseError> {
    check_recording(rec, opts)?;
    model.validate()?;
    let threads = if opts.threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        opts.threads
    };
    let n = rec.counts.len();
    let mut layout = StatLayout::new(n, rec.sample_rate_hz, rec.pulse_arcsec);
    let ks = kurtosis_scales(model);
    let cutoffs: Vec<f64> = ks.iter().map(|k| k.0).collect();
    let kurt_taus: Vec<(f64, f64)> = ks.iter().map(|k| k.1).collect();
    let temp = rec.temp_c.as_deref();
    let mut obs = stats::compute(&layout, &rec.counts, temp, &cutoffs);
    let ref_model = reference_model(model, rec, obs.mean_rate);
    mask_counter_lines(&mut layout, &ref_model, &obs);
    obs.band_psd = stats::band_means(&layout, &obs.psd);
    let seeds: Vec<u64> = (0..opts.runs as u64).map(|r| opts.seed.wrapping_add(r)).collect();
    let job = mc::McJob {
        model: &ref_model,
        layout: &layout,
        temp_c: temp,
        lp_cutoffs_hz: &cutoffs,
        threads,
        full: true,
        sine_probes: &[],
    };
    let runs = mc::run(&job, &seeds)?;
    Ok(all_points(&layout, &ref_model, &obs, &runs, &kurt_taus))
}
