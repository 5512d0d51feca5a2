//! PyWavelets golden data (written by `scripts/gen-golden-pywt` into `tests/data/`)
//! against the wavelet tables, the batch reference and the streaming bank.
//!
//! Alignment checked here: the streaming bank is PyWavelets `mode='zero'` with
//! index offset 0, for analysis coefficients at every level and for synthesis of
//! modified coefficients.

use sagnac::dsp::bank::AnalysisOutput;
use sagnac::dsp::dwt::{self, Mode};
use sagnac::dsp::{CoeffHook, StreamingAnalysis, StreamingBank, Wavelet};
use serde_json::Value;

fn load(name: &str) -> Value {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Floats are stored as repr strings: parse exactly.
fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|s| {
            s.as_str()
                .expect("float string")
                .parse::<f64>()
                .expect("float")
        })
        .collect()
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

/// max |a-b| <= rel * max|b| (and equal lengths).
fn assert_close(a: &[f64], b: &[f64], rel: f64, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    let scale = max_abs(b).max(1e-300);
    let err = a
        .iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    assert!(
        err <= rel * scale,
        "{what}: max abs error {err:e} > {rel:e} * {scale:e}"
    );
}

/// Our tables are the derived doubles bit for bit; PyWavelets' tables agree bit for
/// bit for haar/db4/db8 and within 1e-12 for sym4/sym8 (its symlet tables carry
/// ~9e-13 error; see `src/dsp/wavelet.rs`).
#[test]
fn filters_equal_derivation_and_pywt() {
    let g = load("pywt_filters.json");
    for name in Wavelet::NAMES {
        let w = Wavelet::by_name(name).unwrap();
        let p = &g["wavelets"][name];
        // Tolerance: none. The table must be the derived doubles.
        assert_eq!(
            w.dec_lo(),
            floats(&p["dec_lo_derived"]).as_slice(),
            "{name} vs derivation"
        );
        let tol = if name.starts_with("sym") { 1e-12 } else { 0.0 };
        for (key, ours) in [
            ("dec_lo", w.dec_lo()),
            ("dec_hi", w.dec_hi()),
            ("rec_lo", w.rec_lo()),
            ("rec_hi", w.rec_hi()),
        ] {
            let theirs = floats(&p[key]);
            assert_eq!(ours.len(), theirs.len(), "{name} {key}");
            let err = ours
                .iter()
                .zip(&theirs)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(
                err <= tol,
                "{name} {key}: max |ours - pywt| = {err:e} > {tol:e}"
            );
            if name.starts_with("sym") {
                // The difference is real (not a transcription slip): > 1e-14.
                assert!(err > 1e-14, "{name} {key}: pywt table unexpectedly exact");
            }
        }
        assert_eq!(
            w.vanishing_moments() as u64,
            p["vanishing_moments_psi"].as_u64().unwrap(),
            "{name}"
        );
        assert!(p["orthogonal"].as_bool().unwrap());
    }
}

/// With PyWavelets' own (slightly inexact) sym4/sym8 tables, `wavedec` differs from
/// ours by at most 1e-11 relative: the table difference is invisible in practice.
#[test]
fn streaming_analysis_close_to_pywt_builtin_symlets() {
    let g = load("pywt_transforms.json");
    let x = floats(&g["x"]);
    for case in g["builtin_cases"].as_array().unwrap() {
        let w = Wavelet::by_name(case["wavelet"].as_str().unwrap()).unwrap();
        let level = case["level"].as_u64().unwrap() as u32;
        let theirs: Vec<Vec<f64>> = case["wavedec"]
            .as_array()
            .unwrap()
            .iter()
            .map(floats)
            .collect();
        let mut ana = StreamingAnalysis::new(&w, level).unwrap();
        let mut out = AnalysisOutput::default();
        ana.push(&x, &mut out);
        ana.push(&vec![0.0; (w.len() + 2) << level], &mut out);
        for j in 1..=level as usize {
            let t = &theirs[theirs.len() - j];
            assert_close(
                &out.details[j - 1][..t.len()],
                t,
                1e-11,
                &format!("{} builtin cD{j}", w.name()),
            );
        }
        assert_close(
            &out.approx[..theirs[0].len()],
            &theirs[0],
            1e-11,
            &format!("{} builtin cA", w.name()),
        );
    }
}

fn mode_of(s: &str) -> Mode {
    match s {
        "zero" => Mode::Zero,
        "periodization" => Mode::Periodization,
        m => panic!("mode {m}"),
    }
}

#[test]
fn batch_reference_equals_pywt() {
    let g = load("pywt_transforms.json");
    let x = floats(&g["x"]);
    for case in g["cases"].as_array().unwrap() {
        let w = Wavelet::by_name(case["wavelet"].as_str().unwrap()).unwrap();
        let mode = mode_of(case["mode"].as_str().unwrap());
        let level = case["level"].as_u64().unwrap() as u32;
        let what = format!("{} {:?}", w.name(), mode);
        let theirs: Vec<Vec<f64>> = case["wavedec"]
            .as_array()
            .unwrap()
            .iter()
            .map(floats)
            .collect();
        let ours = dwt::wavedec(&x, &w, level, mode);
        assert_eq!(ours.len(), theirs.len());
        for (k, (a, b)) in ours.iter().zip(&theirs).enumerate() {
            // 1e-13 relative: same sums, possibly different association in pywt's C loop.
            assert_close(a, b, 1e-13, &format!("{what} wavedec[{k}]"));
        }
        // waverec of the detail-scaled list.
        let gains = floats(&case["detail_gains_finest_first"]);
        let mut scaled = theirs.clone();
        for j in 1..=level as usize {
            let idx = scaled.len() - j;
            scaled[idx].iter_mut().for_each(|c| *c *= gains[j - 1]);
        }
        let rec = dwt::waverec(&scaled, &w, mode).unwrap();
        assert_close(
            &rec,
            &floats(&case["waverec_scaled"]),
            1e-13,
            &format!("{what} waverec"),
        );
        // one-level idwt of independent random arrays.
        let y = dwt::idwt(
            &floats(&case["idwt_ca"]),
            &floats(&case["idwt_cd"]),
            &w,
            mode,
        )
        .unwrap();
        assert_close(&y, &floats(&case["idwt"]), 1e-13, &format!("{what} idwt"));
    }
}

/// Streaming analysis == pywt.wavedec(mode='zero'), offset 0, every coefficient,
/// including the tail ones obtained by pushing zeros; past pywt's length the
/// streaming coefficients are exactly zero.
#[test]
fn streaming_analysis_equals_pywt_zero_mode_offset_0() {
    let g = load("pywt_transforms.json");
    let x = floats(&g["x"]);
    for case in g["cases"].as_array().unwrap() {
        if case["mode"] != "zero" {
            continue;
        }
        let w = Wavelet::by_name(case["wavelet"].as_str().unwrap()).unwrap();
        let level = case["level"].as_u64().unwrap() as u32;
        let theirs: Vec<Vec<f64>> = case["wavedec"]
            .as_array()
            .unwrap()
            .iter()
            .map(floats)
            .collect();
        let mut ana = StreamingAnalysis::new(&w, level).unwrap();
        let mut out = AnalysisOutput::default();
        // uneven blocks
        for chunk in x.chunks(77) {
            ana.push(chunk, &mut out);
        }
        ana.push(&vec![0.0; (w.len() + 2) << level], &mut out);
        let check = |ours: &[f64], theirs: &[f64], what: String| {
            assert!(
                ours.len() > theirs.len(),
                "{what}: too few streaming coefficients"
            );
            // 1e-13 relative: the streaming kernel sums in polyphase order.
            assert_close(&ours[..theirs.len()], theirs, 1e-13, &what);
            assert!(
                ours[theirs.len()..].iter().all(|&c| c == 0.0),
                "{what}: tail not zero"
            );
        };
        for j in 1..=level as usize {
            check(
                &out.details[j - 1],
                &theirs[theirs.len() - j],
                format!("{} cD{j}", w.name()),
            );
        }
        check(&out.approx, &theirs[0], format!("{} cA{level}", w.name()));
    }
}

struct Scale(Vec<f64>);
impl CoeffHook for Scale {
    fn details(&mut self, level: u32, _first: u64, d: &mut [f64]) {
        let g = self.0[level as usize - 1];
        d.iter_mut().for_each(|c| *c *= g);
    }
}

/// Streaming synthesis of detail-scaled coefficients == pywt.waverec(mode='zero')
/// of the same scaled list, output index n == pywt index n.
#[test]
fn streaming_synthesis_equals_pywt_waverec_zero_mode() {
    let g = load("pywt_transforms.json");
    let x = floats(&g["x"]);
    for case in g["cases"].as_array().unwrap() {
        if case["mode"] != "zero" {
            continue;
        }
        let w = Wavelet::by_name(case["wavelet"].as_str().unwrap()).unwrap();
        let level = case["level"].as_u64().unwrap() as u32;
        let mut bank = StreamingBank::new(&w, level).unwrap();
        let mut hook = Scale(floats(&case["detail_gains_finest_first"]));
        let mut out = Vec::new();
        for chunk in x.chunks(5) {
            bank.push_with(chunk, &mut out, &mut hook);
        }
        bank.flush_with(&mut out, &mut hook);
        assert_eq!(out.len(), x.len());
        let theirs = floats(&case["waverec_scaled"]);
        // pywt returns at least len(x) samples for mode 'zero'.
        assert!(theirs.len() >= x.len());
        assert_close(
            &out,
            &theirs[..x.len()],
            1e-13,
            &format!("{} waverec", w.name()),
        );
    }
}
