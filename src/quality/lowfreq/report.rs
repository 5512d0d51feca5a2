//! Step 4 of the method: the shape parameters refined, every effect's
//! profile-likelihood intervals, and the correction of the rate.

use super::super::gls::{Cholesky, GlsFit, gls};
use super::model::{Fitted, golden_min};
use super::{
    Analysis, CHI2_95, Correction, Effect, Interval, LowFreq, StepFit, ThermalCorrection,
    ThermalFit, WarmupFit, Z_975, lag_grid, log_grid,
};

/// Points of a profile.
const PROFILE_POINTS: usize = 96;

/// One point of a profile: the shape parameter, the whitened residual sum of
/// squares, and the effect's amplitude with its standard error.
#[derive(Debug, Clone, Copy)]
struct Point {
    param: f64,
    rss: f64,
    amp: f64,
    se: f64,
}

impl Effect {
    fn param(self) -> f64 {
        match self {
            Effect::Warmup { tau_s } => tau_s,
            Effect::Step { at_s } => at_s,
            Effect::Thermal { lag_s } => lag_s,
        }
    }
    fn with(self, p: f64) -> Effect {
        match self {
            Effect::Warmup { .. } => Effect::Warmup { tau_s: p },
            Effect::Step { .. } => Effect::Step { at_s: p },
            Effect::Thermal { .. } => Effect::Thermal { lag_s: p.max(0.0) },
        }
    }
}

impl Analysis<'_> {
    pub(super) fn gls(&self, chol: &Cholesky, effects: &[Effect]) -> Option<GlsFit> {
        gls(chol, &self.c.y, &self.columns(effects))
    }

    /// The range a shape parameter is searched and profiled over.
    fn range(&self, e: Effect) -> (f64, f64, bool) {
        let t = self.c.block_s;
        match e {
            Effect::Warmup { .. } => (0.25 * t, self.span_s, true),
            Effect::Step { at_s } => (
                (at_s - 1.5 * t).max(t),
                (at_s + 1.5 * t).min(self.span_s - t),
                false,
            ),
            // the lag of a linear temperature's response is not identified: held at 0
            Effect::Thermal { .. } if self.temp_linear => (0.0, 0.0, false),
            Effect::Thermal { .. } => (0.0, self.lag_top(), false),
        }
    }

    /// The largest lag searched.
    fn lag_top(&self) -> f64 {
        *lag_grid(self.c.block_s, self.span_s).last().unwrap_or(&0.0)
    }

    /// The profile of effect `i` over its range, the others held.
    fn profile(&self, chol: &Cholesky, effects: &[Effect], i: usize) -> Vec<Point> {
        let (lo, hi, log) = self.range(effects[i]);
        let grid = if hi <= lo {
            vec![lo]
        } else if log {
            log_grid(lo, hi, PROFILE_POINTS)
        } else {
            (0..PROFILE_POINTS)
                .map(|k| lo + (hi - lo) * k as f64 / (PROFILE_POINTS - 1) as f64)
                .collect()
        };
        let mut es = effects.to_vec();
        grid.into_iter()
            .filter_map(|p| {
                es[i] = effects[i].with(p);
                let f = self.gls(chol, &es)?;
                let k = self.base(&es) + i;
                let p_all = f.beta.len();
                Some(Point {
                    param: p,
                    rss: f.rss,
                    amp: f.beta[k],
                    se: f.cov[k * p_all + k].max(0.0).sqrt(),
                })
            })
            .collect()
    }

    /// Golden-section refinement of effect `i`'s shape parameter about the
    /// best point of its profile.
    fn refine(&self, chol: &Cholesky, effects: &[Effect], i: usize) -> Effect {
        let prof = self.profile(chol, effects, i);
        let Some(k) = (0..prof.len()).min_by(|&a, &b| prof[a].rss.total_cmp(&prof[b].rss)) else {
            return effects[i];
        };
        let (a, b) = (
            prof[k.saturating_sub(1)].param,
            prof[(k + 1).min(prof.len() - 1)].param,
        );
        let mut es = effects.to_vec();
        let mut f = |p: f64| {
            es[i] = effects[i].with(p);
            self.gls(chol, &es).map_or(f64::INFINITY, |g| g.rss)
        };
        let (best, _) = golden_min(&mut f, a, b, 30);
        if f(best) <= prof[k].rss {
            effects[i].with(best)
        } else {
            effects[i].with(prof[k].param)
        }
    }

    /// Refine every effect's shape parameter in turn, twice, the noise
    /// refitted between the passes (starting from `chol`); `None` when it
    /// cannot be, the effects then as far as refined.
    pub(super) fn refine_all(&self, mut chol: Cholesky, effects: &mut [Effect]) -> Option<()> {
        for pass in 0..2 {
            if pass > 0 {
                chol = self.fit(effects)?.chol;
            }
            for i in 0..effects.len() {
                effects[i] = self.refine(&chol, effects, i);
            }
        }
        Some(())
    }

    /// Step 4: refine, fit, and report with intervals and the correction.
    ///
    /// When the rate ramp fails its test beside the effects
    /// ([`Correction::ramp_rejected`]), the effects' values and the
    /// correction are those refitted in the mean model without it: a ramp
    /// the data do not support is not left to trade against a warm-up's time
    /// constant or a step's size (a settling fitted beside a ramp leaves that
    /// ramp in the rate it corrects). A rejected ramp is not shown absent,
    /// so each interval spans both fits' (with the ramp and without). The
    /// ramp's standard-error factor stays that of the fit beside the ramp,
    /// so its bound is not read as if the effects were known.
    pub(super) fn report(&self, mut effects: Vec<Effect>, selected: Fitted) -> Option<LowFreq> {
        // `selected` is the noise beside the effects as found; without
        // effects nothing is refined and it is the fit
        let fitted = if effects.is_empty() {
            selected
        } else {
            self.refine_all(selected.chol, &mut effects)?;
            self.fit(&effects)?
        };
        let fit = self.gls(&fitted.chol, &effects)?;
        let ramp = self.ramp_beside_effects(&fitted.chol, &effects, &fit);
        let rejected = (self.test_ramp || !effects.is_empty()) && !self.ramp_passes(&effects);
        let beside = self.effects_report(&fitted, &effects, &fit)?;
        let without = (rejected && !effects.is_empty() && self.has_ramp(&effects))
            .then(|| self.without_ramp(fitted.chol.clone(), effects.clone()))
            .flatten();
        let mut out = match without {
            Some(mut out) => {
                out.widen_to(&beside);
                out
            }
            None => beside,
        };
        out.correction.ramp = ramp;
        out.correction.ramp_rejected = rejected;
        if out.thermal.is_none() && self.temp.is_some() {
            out.thermal = self.thermal_not_significant(&fitted.chol, &effects);
            out.correction.ramp_rejected |= self.temp_linear;
        }
        Some(out)
    }

    /// The effects refined, fitted and reported in the mean model without
    /// the ramp; `None` when that noise cannot be fitted.
    fn without_ramp(&self, chol: Cholesky, mut effects: Vec<Effect>) -> Option<LowFreq> {
        let null = self.without_ramp_column();
        null.refine_all(chol, &mut effects)?;
        let fitted = null.fit(&effects)?;
        let fit = null.gls(&fitted.chol, &effects)?;
        null.effects_report(&fitted, &effects, &fit)
    }

    /// Each effect's intervals and its part of the correction, under the
    /// noise `fitted` and the joint fit `fit`.
    fn effects_report(&self, fitted: &Fitted, effects: &[Effect], fit: &GlsFit) -> Option<LowFreq> {
        let chol = &fitted.chol;
        let mut out = LowFreq {
            bias_instability_dph: fitted.b2.sqrt(),
            rrw_dphsh: fitted.k2.sqrt(),
            ..LowFreq::default()
        };
        let base = self.base(effects);
        for (i, e) in effects.iter().enumerate() {
            let (param, amp) = intervals(&self.profile(chol, effects, i), *e, fit.beta[base + i]);
            match e {
                Effect::Warmup { .. } => {
                    out.warmup = Some(WarmupFit {
                        amplitude_dph: amp,
                        tau_s: param,
                    });
                    out.correction.warmup = Some((amp.value, param.value));
                }
                Effect::Step { .. } => {
                    out.steps.push(StepFit {
                        at_s: param,
                        amplitude_dph: amp,
                    });
                    out.correction.steps.push((param.value, amp.value));
                }
                Effect::Thermal { .. } => {
                    out.thermal = Some(ThermalFit {
                        bias_sensitivity_dph_per_c: amp,
                        lag_s: self.lag_interval(param),
                        compensated: true,
                        confounded_with_ramp: self.temp_linear,
                    });
                    out.correction.thermal = self.thermal_correction(amp.value, param.value);
                }
            }
        }
        out.steps
            .sort_by(|a, b| a.at_s.value.total_cmp(&b.at_s.value));
        Some(out)
    }

    /// The ramp beside the effects, from their joint fit `joint`:
    /// ([`Correction::ramp_se_factor`], [`Correction::ramp_joint_z`]).
    /// `None` without effects, or when a thermal response took the ramp's
    /// place (a linear temperature: the ramp is attributed to it).
    pub(super) fn ramp_beside_effects(
        &self,
        chol: &Cholesky,
        effects: &[Effect],
        joint: &GlsFit,
    ) -> Option<(f64, f64)> {
        if effects.is_empty() || !self.has_ramp(effects) {
            return None;
        }
        let alone = self.gls(chol, &[])?;
        let (pa, pj) = (alone.beta.len(), joint.beta.len());
        let (va, vj) = (alone.cov[pa + 1], joint.cov[pj + 1]);
        (va > 0.0 && vj > 0.0 && vj.is_finite())
            .then(|| ((vj / va).sqrt().max(1.0), joint.beta[1] / vj.sqrt()))
    }

    /// A temperature's response that did not pass its test: its estimate and
    /// intervals, for the report; the rate is not compensated.
    fn thermal_not_significant(&self, chol: &Cholesky, effects: &[Effect]) -> Option<ThermalFit> {
        let mut es = effects.to_vec();
        es.push(Effect::Thermal { lag_s: 0.0 });
        let i = es.len() - 1;
        // a linear temperature's response is tested in place of the ramp,
        // against the noise fitted without either (its random walk takes what
        // it can of a trend): its interval is read under that noise too
        let null = if self.temp_linear {
            let mut x = self.columns(&es);
            x.pop();
            Some(self.noise.fit(&self.c.y, &x, self.span_s)?.chol)
        } else {
            None
        };
        let prof = self.profile(null.as_ref().unwrap_or(chol), &es, i);
        let best = prof.iter().min_by(|a, b| a.rss.total_cmp(&b.rss))?;
        es[i] = Effect::Thermal { lag_s: best.param };
        let (lag, amp) = intervals(&prof, es[i], best.amp);
        Some(ThermalFit {
            bias_sensitivity_dph_per_c: amp,
            lag_s: self.lag_interval(lag),
            compensated: false,
            confounded_with_ramp: self.temp_linear,
        })
    }

    /// The lag's interval as reported: the whole range searched when the
    /// lag is not identified (a linear temperature).
    fn lag_interval(&self, lag: Interval) -> Interval {
        if self.temp_linear {
            Interval {
                value: lag.value,
                ci95: [0.0, self.lag_top()],
            }
        } else {
            lag
        }
    }

    fn thermal_correction(&self, sensitivity: f64, lag_s: f64) -> Option<ThermalCorrection> {
        let temp = self.temp.clone()?;
        let reference_c = temp.values.iter().sum::<f64>() / temp.values.len() as f64;
        let _ = self.series;
        Some(ThermalCorrection {
            sensitivity,
            lag_s,
            reference_c,
            temp,
        })
    }
}

/// The profile level of a change point's 95 % interval: the likelihood ratio
/// of a change point's location is not chi-square(1) (its argmax is that of
/// a two-sided random walk with drift), and the chi-square(2) level covers.
const CHANGE_POINT_95: f64 = 5.991_464_547_107_979;

/// The profile-likelihood intervals of a shape parameter and of the effect's
/// amplitude (the union over the parameter's interval of the amplitude's
/// conditional intervals at the level left).
fn intervals(prof: &[Point], e: Effect, amp: f64) -> (Interval, Interval) {
    let rss_min = prof.iter().map(|p| p.rss).fold(f64::INFINITY, f64::min);
    let level = if matches!(e, Effect::Step { .. }) {
        CHANGE_POINT_95
    } else {
        CHI2_95
    };
    let inside: Vec<&Point> = prof.iter().filter(|p| p.rss - rss_min < level).collect();
    let p = e.param();
    let (mut plo, mut phi) = crossings(prof, p, rss_min, level);
    let (mut alo, mut ahi) = (amp, amp);
    for q in &inside {
        plo = plo.min(q.param);
        phi = phi.max(q.param);
        let half = q.se * (level - (q.rss - rss_min)).max(0.0).sqrt();
        alo = alo.min(q.amp - half);
        ahi = ahi.max(q.amp + half);
    }
    // never narrower than the amplitude's own interval at the estimate
    if let Some(q) = prof.iter().min_by(|a, b| a.rss.total_cmp(&b.rss)) {
        alo = alo.min(amp - Z_975 * q.se);
        ahi = ahi.max(amp + Z_975 * q.se);
    }
    (
        Interval {
            value: p,
            ci95: [plo, phi],
        },
        Interval {
            value: amp,
            ci95: [alo, ahi],
        },
    )
}

/// The shape parameter's interval between the profile's grid points: where
/// the profile (ascending in the parameter) crosses `level` above its
/// minimum `rss_min`, between the outermost point inside on each side of the
/// estimate `p` (or `p` itself) and its neighbour outside, linearly in the
/// square root of the rise (exact for a quadratic profile); at a grid end
/// inside, that end. A profile that rises past the level within one grid
/// step of the estimate gets that part of a step, not an interval of zero
/// width.
fn crossings(prof: &[Point], p: f64, rss_min: f64, level: f64) -> (f64, f64) {
    let ins = |q: &Point| q.rss - rss_min < level;
    let cross = |(pa, ra): (f64, f64), q: &Point| {
        let (a, b) = ((ra - rss_min).max(0.0).sqrt(), (q.rss - rss_min).sqrt());
        let t = if b > a {
            ((level.sqrt() - a) / (b - a)).clamp(0.0, 1.0)
        } else {
            1.0
        };
        pa + t * (q.param - pa)
    };
    let end = |side: &mut dyn Iterator<Item = &Point>| {
        let mut last = (p, rss_min);
        for q in side {
            if !ins(q) {
                return cross(last, q);
            }
            last = (q.param, q.rss);
        }
        last.0
    };
    let lo = end(&mut prof.iter().rev().filter(|q| q.param < p));
    let hi = end(&mut prof.iter().filter(|q| q.param > p));
    (lo.min(p), hi.max(p))
}

impl Correction {
    /// Apply to block means (a test helper and the daemon's live view).
    pub fn apply_to_blocks(&self, t0: &[f64], block_s: f64, y: &mut [f64]) {
        for (v, &t) in y.iter_mut().zip(t0) {
            *v -= self.mean_dph(t, t + block_s);
        }
    }
}

impl Interval {
    /// Widened to hold `other`'s interval too; the value kept.
    fn widen_to(&mut self, other: &Interval) {
        self.ci95 = [
            self.ci95[0].min(other.ci95[0]),
            self.ci95[1].max(other.ci95[1]),
        ];
    }
}

impl LowFreq {
    /// Each effect's intervals widened to hold those of `other`, the same
    /// effects fitted under another mean model (matched in order; the steps
    /// by time).
    fn widen_to(&mut self, other: &LowFreq) {
        if let (Some(a), Some(b)) = (self.warmup.as_mut(), other.warmup.as_ref()) {
            a.amplitude_dph.widen_to(&b.amplitude_dph);
            a.tau_s.widen_to(&b.tau_s);
        }
        for (a, b) in self.steps.iter_mut().zip(&other.steps) {
            a.at_s.widen_to(&b.at_s);
            a.amplitude_dph.widen_to(&b.amplitude_dph);
        }
        if let (Some(a), Some(b)) = (self.thermal.as_mut(), other.thermal.as_ref()) {
            a.bias_sensitivity_dph_per_c
                .widen_to(&b.bias_sensitivity_dph_per_c);
            a.lag_s.widen_to(&b.lag_s);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quadratic(grid: &[f64], centre: f64, c: f64) -> Vec<Point> {
        grid.iter()
            .map(|&x| Point {
                param: x,
                rss: 100.0 + c * (x - centre).powi(2),
                amp: 1.0,
                se: 0.1,
            })
            .collect()
    }

    #[test]
    fn a_sharp_profile_has_an_interval_between_its_grid_points() {
        // rises by the 95 % level 4 away from the estimate 3, on a grid of step 10
        let c = CHI2_95 / 16.0;
        let grid: Vec<f64> = (0..10).map(|k| 10.0 * k as f64).collect();
        let prof = quadratic(&grid, 3.0, c);
        let (lo, hi) = crossings(&prof, 3.0, 100.0, CHI2_95);
        // the grid's first point (0) is inside: the interval ends there
        assert_eq!(lo, 0.0);
        assert!((hi - 7.0).abs() < 1e-9, "{hi}");
        // the estimate between two points both outside
        let prof = quadratic(&grid, 45.0, c);
        let (lo, hi) = crossings(&prof, 45.0, 100.0, CHI2_95);
        assert!(
            (lo - 41.0).abs() < 1e-9 && (hi - 49.0).abs() < 1e-9,
            "{lo} {hi}"
        );
        // through `intervals`, whose minimum is the grid's (here 25 c above
        // the estimate's): wider, within a grid step beyond the grid's
        // points inside (40 and 50)
        let (param, _) = intervals(&prof, Effect::Warmup { tau_s: 45.0 }, 1.0);
        let [lo, hi] = param.ci95;
        assert!(
            (30.0..41.0).contains(&lo) && hi > 49.0 && hi <= 60.0,
            "{lo} {hi}"
        );
        // a profile whose grid neighbours are both outside reads more than the estimate alone
        let sharp = quadratic(&[0.0, 10.0, 20.0], 10.0, 1.0);
        let (lo, hi) = crossings(&sharp, 10.0, 100.0, CHI2_95);
        assert!(
            (lo - (10.0 - CHI2_95.sqrt())).abs() < 1e-9
                && (hi - (10.0 + CHI2_95.sqrt())).abs() < 1e-9
        );
    }
}
