//! `sagnac._sagnac`: the Rust side of the Python package. Each function is a
//! thin call into the `sagnac` library (the same code the command line runs);
//! the Python module `sagnac` (python/sagnac/__init__.py) gives them their
//! documented signatures, builds numpy arrays and dictionaries, and mirrors
//! AllanTools' argument handling.

use std::path::Path;

use numpy::{PyReadonlyArray1, ToPyArray};
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use sagnac::allan::{self, AllanOptions, DataKind, Phase, Stat, TauSet};
use sagnac::input::{Block, Input, Request, Unit};
use sagnac::model::GyroModel;
use sagnac::model::config::OutputKind;
use sagnac::model::sim::Simulator;
use sagnac::pipeline::feed;
use sagnac::sink::provenance::{InputSettings, analysis_json};

/// An error as Python sees it: the whole cause chain, one line.
fn value_error(e: impl std::error::Error) -> PyErr {
    let mut msg = e.to_string();
    let mut src = e.source();
    while let Some(s) = src {
        msg.push_str(": ");
        msg.push_str(&s.to_string());
        src = s.source();
    }
    PyValueError::new_err(msg)
}

fn stat_of(name: &str) -> PyResult<Stat> {
    Ok(match name {
        "adev" => Stat::Adev,
        "oadev" => Stat::Oadev,
        "mdev" => Stat::Mdev,
        "hdev" => Stat::Hdev,
        "ohdev" => Stat::Ohdev,
        "totdev" => Stat::Totdev,
        other => {
            return Err(PyValueError::new_err(format!(
                "stat {other:?}: expected adev, oadev, mdev, hdev, ohdev or totdev"
            )));
        }
    })
}

fn kind_of(name: &str) -> PyResult<DataKind> {
    Ok(match name {
        "phase" => DataKind::Phase,
        "freq" => DataKind::Freq,
        "counts" => DataKind::Counts,
        other => {
            return Err(PyValueError::new_err(format!(
                "data_type {other:?}: expected phase, freq or counts"
            )));
        }
    })
}

fn unit_of(name: &str) -> PyResult<Unit> {
    Ok(match name {
        "counts" => Unit::Counts,
        "dph" => Unit::Dph,
        "dps" => Unit::Dps,
        "rad_s" => Unit::RadS,
        "mps2" => Unit::Mps2,
        "g" => Unit::G,
        other => {
            return Err(PyValueError::new_err(format!(
                "unit {other:?}: expected counts, dph, dps, rad_s (gyro) or mps2, g (accelerometer)"
            )));
        }
    })
}

/// The phase of `data` (AllanTools' `input_to_phase`; counts exactly).
fn phase_of(data: &[f64], data_type: &str, tau0: f64) -> PyResult<Phase> {
    Phase::from_samples(data, kind_of(data_type)?, tau0).map_err(value_error)
}

/// Deviations of `stat` at the averaging factors `ms`: those with a value,
/// their deviations and term counts. Length of the phase first.
/// (phase length, averaging factors kept, deviations, term counts)
type Deviations = (usize, Vec<u64>, Vec<f64>, Vec<u64>);

#[pyfunction]
fn deviations(
    data: PyReadonlyArray1<'_, f64>,
    rate: f64,
    data_type: &str,
    stat: &str,
    ms: Vec<u64>,
) -> PyResult<Deviations> {
    let phase = phase_of(data.as_slice()?, data_type, 1.0 / rate)?;
    let stat = stat_of(stat)?;
    let (mut kept, mut devs, mut ns) = (Vec::new(), Vec::new(), Vec::new());
    for m in ms {
        if let Some((dev, n)) = allan::deviation(&phase, stat, 1.0 / rate, m) {
            kept.push(m);
            devs.push(dev);
            ns.push(n);
        }
    }
    Ok((phase.len(), kept, devs, ns))
}

/// The length of the phase `data` makes (AllanTools' rules: a frequency
/// series gains a leading zero).
#[pyfunction]
fn phase_len(n: usize, data_type: &str) -> PyResult<usize> {
    Ok(match kind_of(data_type)? {
        DataKind::Freq | DataKind::Counts => n + 1,
        DataKind::Phase => n,
    })
}

/// A curve with EDF-based intervals: `taus` is "octave", "decade", "all", or
/// the averaging factors.
#[pyfunction]
#[pyo3(signature = (data, tau0, data_type, stat, taus=None, ms=None, confidence=0.683))]
#[allow(clippy::too_many_arguments)]
fn allan_curve<'py>(
    py: Python<'py>,
    data: PyReadonlyArray1<'_, f64>,
    tau0: f64,
    data_type: &str,
    stat: &str,
    taus: Option<&str>,
    ms: Option<Vec<u64>>,
    confidence: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let phase = phase_of(data.as_slice()?, data_type, tau0)?;
    let stat = stat_of(stat)?;
    let opts = AllanOptions {
        confidence,
        alpha: None,
    };
    let r = match (taus, ms) {
        (_, Some(ms)) => allan::compute_at(&phase, stat, tau0, &ms, &opts),
        (t, None) => {
            let set = match t.unwrap_or("octave") {
                "octave" => TauSet::Octave,
                "decade" => TauSet::Decade,
                "all" => TauSet::All,
                other => {
                    return Err(PyValueError::new_err(format!(
                        "taus {other:?}: expected octave, decade, all or a list of taus"
                    )));
                }
            };
            allan::compute(&phase, stat, tau0, set, &opts)
        }
    }
    .map_err(value_error)?;
    let d = PyDict::new(py);
    let col = |f: fn(&allan::AllanPoint) -> f64| r.points.iter().map(f).collect::<Vec<f64>>();
    d.set_item("tau_s", col(|p| p.tau_s).to_pyarray(py))?;
    d.set_item("dev", col(|p| p.dev).to_pyarray(py))?;
    d.set_item("ci_lo", col(|p| p.ci_lo).to_pyarray(py))?;
    d.set_item("ci_hi", col(|p| p.ci_hi).to_pyarray(py))?;
    d.set_item("edf", col(|p| p.edf).to_pyarray(py))?;
    let n: Vec<u64> = r.points.iter().map(|p| p.n).collect();
    d.set_item("n", n.to_pyarray(py))?;
    let m: Vec<u64> = r.points.iter().map(|p| p.m).collect();
    d.set_item("m", m.to_pyarray(py))?;
    d.set_item("stat", stat.name())?;
    Ok(d)
}

/// `analyze --json` of one axis in memory, as JSON text.
#[pyfunction]
#[pyo3(signature = (values, sample_rate_hz, unit, pulse_arcsec=None, raw_statistics=false, name="array"))]
fn analyze_values(
    py: Python<'_>,
    values: PyReadonlyArray1<'_, f64>,
    sample_rate_hz: f64,
    unit: &str,
    pulse_arcsec: Option<f64>,
    raw_statistics: bool,
    name: &str,
) -> PyResult<String> {
    let unit = unit_of(unit)?;
    let input = Input::from_values(
        name,
        values.as_slice()?.to_vec(),
        unit,
        sample_rate_hz,
        pulse_arcsec,
    )
    .map_err(value_error)?;
    py.detach(|| analyze_input(&input, raw_statistics))
}

fn analyze_input(input: &Input, raw_statistics: bool) -> PyResult<String> {
    let mut cfg = feed::config_for(input).map_err(value_error)?;
    cfg.data_quality = !raw_statistics;
    let fed = feed::run(input, &cfg, &mut |_, _| {}, None).map_err(value_error)?;
    let analysis = fed.analysis();
    let m = input.meta();
    let mut settings = InputSettings::new(
        input.path(),
        m.format.name(),
        cfg.sample_rate_hz,
        if m.unit == Unit::Counts {
            m.pulse_arcsec
        } else {
            None
        },
    );
    settings.unit = Some(m.unit.name().into());
    settings.origin = Some(m.origin.clone());
    let v = analysis_json(&analysis, None, settings, m.unit.quantity()).map_err(value_error)?;
    Ok(v.to_string())
}

/// A simulated run of `model` (a TOML file's path or its text): the samples
/// (`counts` or `rate_dps`), the temperature, and the metadata as JSON.
#[pyfunction]
fn simulate<'py>(
    py: Python<'py>,
    model: &str,
    duration_s: f64,
    seed: u64,
) -> PyResult<Bound<'py, PyDict>> {
    let gm = if Path::new(model).is_file() {
        GyroModel::load(Path::new(model))
    } else {
        GyroModel::from_toml_str(model, "the model text")
    }
    .map_err(value_error)?;
    let mut sim = Simulator::new(&gm, seed, Some(duration_s)).map_err(value_error)?;
    let (mut counts, mut rates, mut temp) = (Vec::new(), Vec::new(), Vec::new());
    let rate_output = sim.output() == OutputKind::Rate;
    loop {
        let n = if rate_output {
            sim.next_block_rates(1 << 16, &mut rates, &mut temp)
        } else {
            sim.next_block_with_temp(1 << 16, &mut counts, &mut temp)
        };
        if n == 0 {
            break;
        }
    }
    let d = PyDict::new(py);
    if rate_output {
        d.set_item("rate_dps", rates.to_pyarray(py))?;
    } else {
        d.set_item("counts", counts.to_pyarray(py))?;
        d.set_item("pulse_arcsec", sim.pulse_arcsec())?;
    }
    if !temp.is_empty() {
        d.set_item("temp_c", temp.to_pyarray(py))?;
    }
    d.set_item("sample_rate_hz", sim.sample_rate_hz())?;
    d.set_item("duration_s", duration_s)?;
    d.set_item("seed", seed)?;
    Ok(d)
}

/// Anything the input layer opens, read whole: the samples (`counts` for
/// whole pulse counts, else `values` in `unit`), the filled samples, the
/// temperature and the metadata.
#[pyfunction]
#[pyo3(signature = (path, format=None, column=None, unit=None, sample_rate_hz=None, pulse_arcsec=None, gyro=None, topic=None))]
#[allow(clippy::too_many_arguments)]
fn read<'py>(
    py: Python<'py>,
    path: &str,
    format: Option<&str>,
    column: Option<String>,
    unit: Option<&str>,
    sample_rate_hz: Option<f64>,
    pulse_arcsec: Option<f64>,
    gyro: Option<String>,
    topic: Option<String>,
) -> PyResult<Bound<'py, PyDict>> {
    let req = Request {
        format: format
            .map(|f| f.parse())
            .transpose()
            .map_err(PyValueError::new_err)?,
        column,
        unit: unit.map(unit_of).transpose()?,
        sample_rate_hz,
        pulse_arcsec,
        gyro,
        topic,
        // read_all hands out every sample at once: the counts checked whole up front
        ..Request::default()
    };
    let input = Input::open(Path::new(path), &req).map_err(|e| match &e {
        sagnac::input::InputError::Open { .. } => PyOSError::new_err(e.to_string()),
        _ => value_error(e),
    })?;
    let (block, report): (Block, _) = py.detach(|| input.read_all()).map_err(value_error)?;
    let m = input.meta();
    let d = PyDict::new(py);
    if m.integral {
        d.set_item("counts", block.counts.to_pyarray(py))?;
    } else {
        d.set_item("values", block.values.to_pyarray(py))?;
    }
    let mut filled = vec![false; block.len()];
    for r in &block.filled {
        filled[r.clone()].iter_mut().for_each(|f| *f = true);
    }
    d.set_item("filled", filled.to_pyarray(py))?;
    if !block.temp_c.is_empty() {
        d.set_item("temp_c", block.temp_c.to_pyarray(py))?;
    }
    let meta = PyDict::new(py);
    meta.set_item("format", m.format.name())?;
    meta.set_item("unit", m.unit.name())?;
    meta.set_item("sample_rate_hz", m.sample_rate_hz)?;
    meta.set_item("pulse_arcsec", m.pulse_arcsec)?;
    meta.set_item("gyro", m.gyro.clone())?;
    meta.set_item("gyros", m.gyros.clone())?;
    meta.set_item("topic", m.bag.as_ref().map(|b| b.topic.clone()))?;
    meta.set_item("origin", m.origin.clone())?;
    meta.set_item("gaps", report.gaps)?;
    meta.set_item("lost_samples", report.lost_samples)?;
    d.set_item("meta", meta)?;
    Ok(d)
}

/// `sagnac diagnose ARGS --json OUT`, as the command runs it; the JSON text.
#[pyfunction]
fn diagnose_cli(py: Python<'_>, args: Vec<String>, json_out: &str) -> PyResult<String> {
    use clap::Parser;
    let mut argv = vec!["sagnac".to_string(), "diagnose".to_string()];
    argv.extend(args);
    argv.extend(["--json".to_string(), json_out.to_string()]);
    let cli =
        sagnac::cli::Cli::try_parse_from(argv).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let sagnac::cli::Command::Diagnose(a) = cli.command else {
        unreachable!("parsed as diagnose");
    };
    py.detach(|| sagnac::cli::diagnose::run(a))
        .map_err(|e| PyValueError::new_err(format!("{e:#}")))?;
    std::fs::read_to_string(json_out).map_err(|e| PyOSError::new_err(format!("{json_out}: {e}")))
}

#[pymodule]
fn _sagnac(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(deviations, m)?)?;
    m.add_function(wrap_pyfunction!(phase_len, m)?)?;
    m.add_function(wrap_pyfunction!(allan_curve, m)?)?;
    m.add_function(wrap_pyfunction!(analyze_values, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(read, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose_cli, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
