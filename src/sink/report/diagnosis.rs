//! The diagnosis part of the page: the diagnosis SVG
//! ([`super::diagnosis_fig`]) and its findings in words: the verdict,
//! where the recording leaves the model, and each changed or added term
//! named with what it means physically.

use std::fmt::Write;

use super::markup::{esc, inline_svg};
use super::{DiagnosisPart, ReportError, fmt_sig};
use crate::diagnose::Verdict;
use crate::model::Term;

/// The term a model-file key belongs to (`arw_dpsh`, `gauss_markov[0].tau_c_s`, ...),
/// with placeholder parameters: only its name and explanation are used.
pub fn term_of_key(key: &str) -> Option<Term> {
    let base = key.split(['[', '.']).next().unwrap_or(key);
    Some(match base {
        k if k.starts_with("quantization") || k.starts_with("pulse") => Term::Quantization {
            quantization_arcsec: 0.0,
        },
        k if k.starts_with("arw") => Term::AngleRandomWalk { arw_dpsh: 0.0 },
        k if k.starts_with("bias_instability") => Term::BiasInstability {
            bias_instability_dph: 0.0,
            f_lo_hz: 0.0,
            f_hi_hz: f64::INFINITY,
        },
        k if k.starts_with("rrw") => Term::RateRandomWalk { rrw_dphsh: 0.0 },
        k if k.starts_with("rate_ramp") => Term::RateRamp {
            rate_ramp_dphh: 0.0,
        },
        "gauss_markov" => Term::GaussMarkov {
            sigma_dph: 0.0,
            tau_c_s: 1.0,
        },
        "sinusoid" => Term::Sinusoid {
            amplitude_dph: 0.0,
            period_s: 1.0,
        },
        "random_telegraph" => Term::RandomTelegraph {
            amplitude_dph: 0.0,
            mean_dwell_s: 1.0,
        },
        "resonance" => Term::Resonance {
            sigma_dph: 0.0,
            centre_hz: 1.0,
            width_hz: 1.0,
            tau0_s: 0.1,
        },
        _ => return None,
    })
}

/// The section's HTML.
pub fn section(d: &DiagnosisPart<'_>) -> Result<String, ReportError> {
    let diag = d.diagnosis;
    let r = &diag.report;
    let mut h = String::new();
    let svg = super::diagnosis_fig::render(diag, &format!("diagnosis against {}", d.model))
        .map_err(|e| ReportError::Draw(e.to_string()))?;
    let _ = write!(
        h,
        "<section id=\"diagnosis\"><h2>Diagnosis against the model {}</h2>",
        esc(d.model)
    );
    let (class, verdict) = match r.verdict {
        Verdict::Consistent => ("ok", "consistent: the recording is what the model predicts"),
        Verdict::Mismatch => ("bad", "mismatch: the recording departs from the model"),
    };
    let _ = write!(
        h,
        "<p class=\"verdict {class}\">Verdict: <b>{verdict}</b>. Fit to the model's Monte-Carlo runs: \
         \u{3c7}\u{b2}/dof {} before, {} after the changes below.</p>",
        fmt_sig(r.fit_before.chi2_per_dof, 3),
        fmt_sig(r.fit_after.chi2_per_dof, 3)
    );
    if !r.mismatch_regions.is_empty() {
        h.push_str("<p>Where the recording leaves the model (shaded red in the figure):</p><ul>");
        for m in &r.mismatch_regions {
            let _ = write!(
                h,
                "<li>\u{3c4} from {} s to {} s, largest |z| {}</li>",
                fmt_sig(m.tau_min_s, 3),
                fmt_sig(m.tau_max_s, 3),
                fmt_sig(m.max_z, 3)
            );
        }
        h.push_str("</ul>");
    }
    if !r.parameter_changes.is_empty() {
        h.push_str("<h3>Terms the model has, with another value</h3><ul>");
        for c in &r.parameter_changes {
            let _ = write!(
                h,
                "<li><b>{}</b>: model {}, fitted {} (95 %: {} to {})",
                esc(&c.term),
                fmt_sig(c.model, 4),
                fmt_sig(c.fitted, 4),
                fmt_sig(c.ci95[0], 3),
                fmt_sig(c.ci95[1], 3)
            );
            if let Some(t) = term_of_key(&c.term) {
                let _ = write!(h, ". {}", esc(t.explanation()));
            }
            h.push_str("</li>");
        }
        h.push_str("</ul>");
    }
    if !r.added_terms.is_empty() {
        h.push_str("<h3>Terms the model lacks</h3><ul>");
        for a in &r.added_terms {
            let params: Vec<String> = a
                .params
                .iter()
                .map(|(k, v)| match a.ci95.get(k) {
                    Some(ci) => format!(
                        "{k} = {} (95 %: {} to {})",
                        fmt_sig(*v, 4),
                        fmt_sig(ci[0], 3),
                        fmt_sig(ci[1], 3)
                    ),
                    None => format!("{k} = {}", fmt_sig(*v, 4)),
                })
                .collect();
            let _ = write!(
                h,
                "<li><b>{}</b>: {}. {}</li>",
                esc(&a.term),
                esc(&params.join(", ")),
                esc(&a.explanation)
            );
        }
        h.push_str("</ul>");
    }
    if r.verdict == Verdict::Consistent
        && r.parameter_changes.is_empty()
        && r.added_terms.is_empty()
    {
        h.push_str("<p>No term needs changing.</p>");
    }
    if !diag.notes.is_empty() {
        h.push_str("<h3>Notes of the diagnosis</h3><ul>");
        for n in &diag.notes {
            let _ = write!(h, "<li>{}</li>", esc(n));
        }
        h.push_str("</ul>");
    }
    let _ = write!(
        h,
        "<figure>{}<figcaption>The recording (black) against the model's 95 % Monte-Carlo band (blue) and, \
         when the diagnosis changed the model, the updated model's band (green), on four statistics.\
         </figcaption></figure></section>",
        inline_svg(&svg)
    );
    Ok(h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn model_keys_name_their_terms() {
        assert_eq!(term_of_key("arw_dpsh").map(|t| t.name()), Some("arw"));
        assert_eq!(
            term_of_key("quantization_arcsec").map(|t| t.name()),
            Some("quantization")
        );
        assert_eq!(
            term_of_key("gauss_markov[1].tau_c_s").map(|t| t.name()),
            Some("gauss_markov")
        );
        assert_eq!(term_of_key("sinusoid").map(|t| t.name()), Some("sinusoid"));
        assert_eq!(term_of_key("rrw_dphsh").map(|t| t.name()), Some("rrw"));
        assert!(term_of_key("thermal.slope").is_none());
    }
}
