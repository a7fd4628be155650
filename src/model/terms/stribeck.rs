//! `stribeck[:COL][:DELTA]`: Coulomb friction with the Stribeck effect,
//!
//! `F = sign(v)·(Fc + (Fs − Fc)·exp(−(|v|/vs)^δ))`,
//!
//! the breakaway force `Fs` at low speed falling to the Coulomb level `Fc` over the Stribeck
//! velocity `vs`. The velocity `v` is a logged column (`stribeck:COL`) or derived causally from
//! position and time, exactly as for `viscous` ([`super::viscous::velocity`]); `sign(0) = 0`.
//! Add `viscous` for the full static friction curve (`viscous,stribeck`).
//!
//! - `Fc` and `Fs` are linear: the basis is `sign(v)` and `sign(v)·exp(−(|v|/vs)^δ)` with
//!   coefficients `Fc` and `Fs − Fc`; both are reported in bias units with standard errors.
//! - `vs` is the term's nonlinear parameter, searched by variable projection on
//!   `u = ln(vs / v_ref)`, with `v_ref` the median of the training log's non-zero |v| and `u`
//!   over `[ln(q5/v_ref), ln(q95/v_ref)]`, q5 and q95 the 5 % and 95 % quantiles of those |v|.
//!   Below q5 almost no row feels the Stribeck term, above q95 it is nearly `sign(v)` again
//!   (not separable from `Fc`), so the range covers what the log can determine, and it comes
//!   from the data, never from an absolute unit: the same log with positions in m or in µm
//!   gives the same predictions. `vs` is reported in the velocity's unit (position units per s,
//!   or the column's unit).
//! - `δ` (the shape exponent) is fixed, default 2 (the Gaussian Stribeck curve of
//!   Armstrong-Hélouvry); `stribeck:1` is the exponential (Tustin) form. A numeric argument is
//!   δ (from 0.5 to 4), any other is the velocity column: `stribeck:velocity_m_s:1`.

use super::common::positive_finite;
use super::viscous::{c_velocity, column_index, training_velocities, velocity};
use crate::codegen::{CContext, CTerm};
use crate::model::ModelError;
use crate::model::cue::{Answer, Cue, Law};
use crate::model::data::{FitData, FitError};
use crate::model::term::{Nonlinear, Param, Seek, Term, TermSpec, TermState, se_from_cov};
use crate::model::term_text::TermText;
use crate::numeric::stats;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The head of the term's spec text (`stribeck`).
pub(crate) const HEAD: &str = "stribeck";

/// Default shape exponent δ.
pub const DEFAULT_DELTA: f64 = 2.0;
/// Allowed range of δ.
pub const DELTA_RANGE: (f64, f64) = (0.5, 4.0);

/// The term name: `stribeck`, then `:COL` and `:δ` where they differ from the default.
fn term_name(column: &Option<String>, delta: f64) -> String {
    let mut name = String::from(HEAD);
    if let Some(c) = column {
        name += &format!(":{c}");
    }
    if (delta - DEFAULT_DELTA).abs() > 0.0 {
        name += &format!(":{delta}");
    }
    name
}

/// Spec of the `stribeck` term.
#[derive(Debug, Clone)]
pub struct StribeckSpec {
    /// The velocity column; `None`: derived from position and time.
    pub column: Option<String>,
    /// Shape exponent δ, in [`DELTA_RANGE`].
    pub delta: f64,
}

impl TermSpec for StribeckSpec {
    fn name(&self) -> String {
        term_name(&self.column, self.delta)
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let speeds: Vec<f64> = training_velocities(data, self.column.as_deref(), &self.name())?
            .into_iter()
            .map(f64::abs)
            .filter(|a| *a > 0.0)
            .collect();
        let sorted = stats::sorted(&speeds);
        let q = |p: f64| stats::percentile_sorted(&sorted, p).unwrap_or(0.0);
        let (q5, median, q95) = (q(5.0), q(50.0), q(95.0));
        if sorted.len() < 8 || !(q5 > 0.0 && q95 > q5 && median.is_finite()) {
            return Err(FitError::BadSetting {
                term: self.name(),
                why: format!(
                    "the velocity takes too few distinct non-zero magnitudes on the measured rows \
                     ({} non-zero, 5–95 % quantiles {q5:e} to {q95:e}) to place a Stribeck velocity",
                    sorted.len()
                ),
            });
        }
        let (u_lo, u_hi) = ((q5 / median).ln(), (q95 / median).ln());
        Ok(Arc::new(StribeckTerm {
            column: self.column.clone(),
            delta: self.delta,
            v_ref: median,
            u: 0.5 * (u_lo + u_hi),
            u_lo,
            u_hi,
        }))
    }
}

/// The fitted `stribeck` term.
#[derive(Debug, Clone, Serialize)]
pub struct StribeckTerm {
    /// The velocity column; `None`: derived from position and time.
    pub column: Option<String>,
    /// Shape exponent δ.
    pub delta: f64,
    /// Median non-zero |v| of the training log (velocity unit); the search's reference.
    pub v_ref: f64,
    /// `ln(vs / v_ref)`, the searched coordinate.
    pub u: f64,
    /// Lower end of the search interval of `u`.
    pub u_lo: f64,
    /// Upper end of the search interval of `u`.
    pub u_hi: f64,
}

/// The saved form, checked on load ([`restore`]).
#[derive(Deserialize)]
struct Saved {
    column: Option<String>,
    #[serde(deserialize_with = "positive_finite")]
    delta: f64,
    #[serde(deserialize_with = "positive_finite")]
    v_ref: f64,
    u: f64,
    u_lo: f64,
    u_hi: f64,
}

impl StribeckTerm {
    /// The Stribeck velocity `vs = v_ref·exp(u)`, in the velocity's unit.
    pub fn vs(&self) -> f64 {
        self.v_ref * self.u.exp()
    }
}

impl Term for StribeckTerm {
    fn name(&self) -> String {
        term_name(&self.column, self.delta)
    }
    fn param_names(&self) -> Vec<String> {
        vec!["Fc".into(), "dFs".into()]
    }
    fn covariates(&self) -> Vec<String> {
        self.column.iter().cloned().collect()
    }
    /// With the derived velocity, sign(v) is the direction of every non-zero seek: a term
    /// that carries the ±offset of the direction (`direction`, `dahl`) shares `Fc` with it.
    fn fit_warnings(&self, model: &[Arc<dyn Term>]) -> Vec<String> {
        if self.column.is_some() {
            return Vec::new();
        }
        model
            .iter()
            .filter(|t| t.caps().spans_direction_offset)
            .map(|t| {
                format!(
                    "{}: sign(velocity) is the direction of every move, so its Fc shares the \
                     ±offset with `{}` (their Coulomb levels add up; each alone is poorly determined)",
                    self.name(),
                    t.name()
                )
            })
            .collect()
    }
    fn start(&self, covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        let column = column_index(self.column.as_deref(), covariates, &self.name())?;
        Ok(Box::new(StribeckState {
            column,
            vs: self.vs(),
            delta: self.delta,
        }))
    }
    fn nonlinear(&self) -> Option<Nonlinear> {
        Some(Nonlinear {
            name: "ln_vs".into(),
            value: self.u,
            lo: self.u_lo,
            hi: self.u_hi,
        })
    }
    fn with_nonlinear(&self, u: f64) -> Option<Arc<dyn Term>> {
        u.is_finite().then(|| {
            Arc::new(StribeckTerm {
                u: u.clamp(self.u_lo, self.u_hi),
                ..self.clone()
            }) as Arc<dyn Term>
        })
    }
    /// `Fc` and `Fs` (bias units; `se(Fs)` from the covariance of `Fc` and `Fs − Fc`) and `vs`
    /// (velocity unit; its standard error by the delta method from that of `ln vs`).
    fn report(&self, coef: &[f64], cov: &[f64], nl_se: Option<f64>) -> Vec<Param> {
        let name = self.name();
        let var_fs = cov.first().copied().unwrap_or(f64::NAN)
            + cov.get(3).copied().unwrap_or(f64::NAN)
            + 2.0 * cov.get(1).copied().unwrap_or(f64::NAN);
        let vs = self.vs();
        vec![
            Param {
                name: format!("{name}.Fc"),
                value: coef[0],
                se: se_from_cov(cov, 2, 0),
            },
            Param {
                name: format!("{name}.Fs"),
                value: coef[0] + coef[1],
                se: Some(var_fs.max(0.0).sqrt()).filter(|s| s.is_finite()),
            },
            Param {
                name: format!("{name}.vs"),
                value: vs,
                se: nl_se.map(|s| s * vs).filter(|s| s.is_finite()),
            },
        ]
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn export_c(&self, ctx: &CContext) -> Option<CTerm> {
        Some(CTerm {
            basis: format!(
                "{{ {}bias_real s_ = v_ > 0 ? 1 : (v_ < 0 ? -1 : 0);\n  b[0] = s_; b[1] = s_ * exp(-pow(fabs(v_) / {}, {})); }}\n",
                c_velocity(self.column.is_some()),
                ctx.real(self.vs()),
                ctx.real(self.delta)
            ),
            ..CTerm::default()
        })
    }
}

#[derive(Debug, Clone)]
struct StribeckState {
    column: Option<usize>,
    vs: f64,
    delta: f64,
}

impl TermState for StribeckState {
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        let v = velocity(seek, self.column);
        let s = if v > 0.0 {
            1.0
        } else if v < 0.0 {
            -1.0
        } else {
            0.0
        };
        out[0] = s;
        out[1] = s * (-(v.abs() / self.vs).powf(self.delta)).exp();
    }
    fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(self.clone())
    }
}

/// Rebuilds a fitted `stribeck` term from a model file, refusing settings that would predict
/// NaN (δ outside its range, a non-finite or empty search interval, `u` outside it).
pub(crate) fn restore(
    name: &str,
    settings: &serde_json::Value,
) -> Result<Arc<dyn Term>, ModelError> {
    let bad = |why: String| ModelError::BadTerm {
        term: name.to_string(),
        why,
    };
    let s: Saved = serde_json::from_value(settings.clone()).map_err(|e| bad(e.to_string()))?;
    if !(DELTA_RANGE.0..=DELTA_RANGE.1).contains(&s.delta) {
        return Err(bad(format!("delta {} is not in [0.5, 4]", s.delta)));
    }
    if !(s.u_lo.is_finite() && s.u_hi.is_finite() && s.u_lo <= s.u && s.u <= s.u_hi) {
        return Err(bad(format!(
            "u {} must lie in the finite interval [{}, {}]",
            s.u, s.u_lo, s.u_hi
        )));
    }
    let term = StribeckTerm {
        column: s.column,
        delta: s.delta,
        v_ref: s.v_ref,
        u: s.u,
        u_lo: s.u_lo,
        u_hi: s.u_hi,
    };
    if !(term.vs().is_finite() && term.vs() > 0.0) {
        return Err(bad("the Stribeck velocity overflows".into()));
    }
    Ok(Arc::new(term))
}

/// Parses `stribeck`, `stribeck:COL`, `stribeck:DELTA` or `stribeck:COL:DELTA`; the registry's
/// parser. A numeric item is δ, any other the velocity column.
pub(crate) fn parse(t: &TermText<'_>) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    let (mut column, mut delta) = (None, None);
    let items: Vec<&str> = t.arg.map(|a| a.split(':').collect()).unwrap_or_default();
    for item in items {
        if item.is_empty() {
            return Err(t.bad("an empty item: use `stribeck[:COL][:DELTA]`".into()));
        }
        match item.parse::<f64>() {
            Ok(d) if delta.is_none() => {
                if !(DELTA_RANGE.0..=DELTA_RANGE.1).contains(&d) {
                    return Err(t.bad(format!(
                        "the Stribeck exponent δ must be from 0.5 to 4, got `{item}`"
                    )));
                }
                delta = Some(d);
            }
            Err(_) if column.is_none() && delta.is_none() => column = Some(item.to_string()),
            _ => {
                return Err(t.bad(format!(
                    "`{item}`: use `stribeck[:COL][:DELTA]` (at most one column, then at most one exponent)"
                )));
            }
        }
    }
    Ok(Arc::new(StribeckSpec {
        column,
        delta: delta.unwrap_or(DEFAULT_DELTA),
    }))
}

/// The patterns `stribeck` answers: velocity friction falling off from a breakaway level at
/// low speed, named by its column or from the derived velocity.
pub(crate) fn answers(cue: Cue) -> Option<Answer> {
    match cue {
        Cue::Covariate(Law::Velocity, _) => Answer::named(0),
        Cue::DerivedVelocity(Law::Velocity) => Answer::fixed(0),
        Cue::DerivedVelocity(_) => Answer::fixed(1),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::Log;
    use crate::model::terms::viscous::test_logs::{assert_round_trip, fitted, stage};
    use crate::numeric::rng::SimRng;

    /// The Stribeck law with sign(0) = 0.
    fn law(v: f64, fc: f64, fs: f64, vs: f64, delta: f64) -> f64 {
        let s = if v == 0.0 { 0.0 } else { v.signum() };
        s * (fc + (fs - fc) * (-(v.abs() / vs).powf(delta)).exp())
    }

    /// A log whose column `vel` has log-uniform speeds over 0.01–10 with random signs, and bias
    /// `0.5 + law(vel)` + N(0, 0.05²).
    fn speeds_log(seed: u64, fc: f64, fs: f64, vs: f64, delta: f64) -> Log {
        let mut rng = SimRng::new(seed);
        let mut text = String::from("time_s,track,bias,vel\n");
        for i in 0..4000 {
            let speed = 10f64.powf(rng.range(-2.0, 1.0));
            let v = if rng.uniform() < 0.5 { -speed } else { speed };
            let y = 0.5 + law(v, fc, fs, vs, delta) + 0.05 * rng.normal();
            text += &format!("{i},{},{y},{v}\n", rng.range(0.0, 100.0));
        }
        Log::from_reader("speeds.csv", text.as_bytes(), &Default::default()).unwrap()
    }

    /// Least-squares RSS of `[1, s, s·e(vs)]` on the log (nalgebra SVD): the slow, obvious
    /// reference of the variable-projection search.
    fn reference_rss(log: &Log, vs: f64, delta: f64) -> f64 {
        let vel = log
            .schema
            .covariates
            .iter()
            .position(|c| c == "vel")
            .unwrap();
        let rows: Vec<(f64, f64)> = log
            .rows()
            .map(|r| (r.covariates[vel], r.bias.unwrap()))
            .collect();
        let x = nalgebra::DMatrix::from_fn(rows.len(), 3, |i, j| {
            let v = rows[i].0;
            let s = v.signum();
            [1.0, s, s * (-(v.abs() / vs).powf(delta)).exp()][j]
        });
        let y = nalgebra::DVector::from_iterator(rows.len(), rows.iter().map(|r| r.1));
        let c = x.clone().svd(true, true).solve(&y, 1e-14).unwrap();
        (y - x * c).norm_squared()
    }

    /// Reference: the closed-form truth Fc = 1, Fs = 1.8, vs = 0.3 (δ = 2) of the generating
    /// law; Fc and Fs within 4 standard errors, vs within 5 %. And the searched optimum is at
    /// least as good as the best of a 600-point grid in ln vs over the same interval, each
    /// point solved by SVD (relative 1e-9): the fast search misses no better minimum.
    #[test]
    fn recovers_fc_fs_vs_and_matches_a_brute_force_search() {
        let log = speeds_log(5, 1.0, 1.8, 0.3, 2.0);
        let m = fitted("stribeck:vel", &log);
        let p = |n: &str| m.param(&format!("stribeck:vel.{n}")).unwrap().clone();
        let (fc, fs, vs) = (p("Fc"), p("Fs"), p("vs"));
        assert!((fc.value - 1.0).abs() < 4.0 * fc.se.unwrap(), "{fc:?}");
        assert!((fs.value - 1.8).abs() < 4.0 * fs.se.unwrap(), "{fs:?}");
        assert!((vs.value / 0.3 - 1.0).abs() < 0.05, "{vs:?}");
        assert!(
            vs.se.is_some_and(|s| s > 0.0 && s < 0.05 * vs.value),
            "{vs:?}"
        );
        let t = m.terms.iter().find(|t| t.term.name() == "stribeck:vel");
        let s = t.unwrap().term.settings();
        let (lo, hi, v_ref) = (
            s["u_lo"].as_f64().unwrap(),
            s["u_hi"].as_f64().unwrap(),
            s["v_ref"].as_f64().unwrap(),
        );
        let brute = (0..600)
            .map(|i| reference_rss(&log, v_ref * (lo + (hi - lo) * i as f64 / 599.0).exp(), 2.0))
            .fold(f64::INFINITY, f64::min);
        assert!(
            m.fit.ls_rss <= brute * (1.0 + 1e-9),
            "search {} vs grid {brute}",
            m.fit.ls_rss
        );
        assert!((reference_rss(&log, vs.value, 2.0) - m.fit.ls_rss).abs() < 1e-9 * brute);
        assert_round_trip(&m, &log);
    }

    /// Reference: truth of the exponential (Tustin) form, δ = 1: `stribeck:vel:1` recovers it.
    #[test]
    fn the_exponent_is_settable() {
        let log = speeds_log(6, 2.0, 1.2, 0.1, 1.0);
        let m = fitted("stribeck:vel:1", &log);
        let vs = m.param("stribeck:vel:1.vs").unwrap();
        assert!((vs.value / 0.1 - 1.0).abs() < 0.1, "{vs:?}");
        let fs = m.param("stribeck:vel:1.Fs").unwrap();
        assert!((fs.value - 1.2).abs() < 4.0 * fs.se.unwrap(), "{fs:?}");
        assert_round_trip(&m, &log);
    }

    /// The same stage log with positions in units 1e-6 … 1e6 times the original (velocity
    /// derived from position and time, so it scales too; the bias does not): `viscous,stribeck`
    /// predicts the same bias on every row, relative 1e-9 of the largest prediction.
    #[test]
    fn predictions_do_not_depend_on_the_position_unit() {
        let truth = |v: f64| 0.4 * v + law(v, 2.0, 3.0, 4.0, 2.0);
        let base = {
            let log = stage(3000, 21, 1.0, 0.05, |v, _| truth(v));
            fitted("viscous,stribeck", &log).predict_log(&log).unwrap()
        };
        let top = base.predicted.iter().fold(0.0, |a: f64, b| a.max(b.abs()));
        for scale in [1e-6, 1e-3, 1e3, 1e6] {
            let log = stage(3000, 21, scale, 0.05, |v, _| truth(v / scale));
            let p = fitted("viscous,stribeck", &log).predict_log(&log).unwrap();
            let worst = p
                .predicted
                .iter()
                .zip(&base.predicted)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(worst <= 1e-9 * top, "scale {scale}: {worst:e} of {top}");
        }
    }

    #[test]
    fn parse_and_restore_refuse_what_would_not_predict() {
        let name = |s: &str| parse(&TermText::new(s)).map(|t| t.name());
        assert_eq!(name("stribeck").unwrap(), "stribeck");
        assert_eq!(name("stribeck:2").unwrap(), "stribeck");
        assert_eq!(name("stribeck:v:1.5").unwrap(), "stribeck:v:1.5");
        assert_eq!(name("stribeck:0.5").unwrap(), "stribeck:0.5");
        for bad in [
            "stribeck:",
            "stribeck:9",
            "stribeck:nan",
            "stribeck:2:v",
            "stribeck:a:b",
            "stribeck:v:1:2",
        ] {
            assert!(parse(&TermText::new(bad)).is_err(), "{bad}");
        }
        let good = serde_json::json!({"column": null, "delta": 2.0, "v_ref": 1.0,
            "u": 0.0, "u_lo": -1.0, "u_hi": 1.0});
        assert!(restore("stribeck", &good).is_ok());
        for (key, value) in [
            ("delta", 7.0),
            ("v_ref", 0.0),
            ("u", 2.0),
            ("u_lo", f64::NAN),
        ] {
            let mut s = good.clone();
            s[key] = serde_json::json!(value);
            assert!(restore("stribeck", &s).is_err(), "{key} {value}");
        }
    }

    /// With the derived velocity, sign(v) is the direction of every move: on a log where every
    /// row moves, `direction,stribeck` is exactly collinear and the fit refuses it naming
    /// `stribeck.Fc`; where some rows stand still (quantised positions) it fits and warns that
    /// the two share the Coulomb offset. With a velocity column nothing is presumed.
    #[test]
    fn a_direction_companion_is_refused_or_warned_about() {
        let moving = stage(800, 31, 1.0, 0.05, |v, _| law(v, 1.0, 1.5, 2.0, 2.0));
        let err = crate::fit::fit(
            &crate::model::ModelSpec::parse("direction,stribeck").unwrap(),
            &moving,
            &crate::fit::FitOptions::default().check().unwrap(),
        )
        .unwrap_err();
        assert!(err.to_string().contains("stribeck.Fc"), "{err}");
        let shares = |m: crate::model::FittedModel| {
            m.warnings
                .iter()
                .any(|w| w.contains("shares the ±offset with `direction`"))
        };
        assert!(!shares(fitted("direction,stribeck:vel", &moving)));
        let mut text = String::from("time_s,track,bias\n");
        let mut rng = SimRng::new(32);
        for i in 0..600 {
            let t = 0.01 * i as f64;
            let x = (40.0 * (1.7 * t).sin() + 9.0 * (5.3 * t).sin()).round();
            text += &format!("{t},{x},{}\n", 0.3 * rng.normal() + (i % 7) as f64 * 0.01);
        }
        let still = Log::from_reader("q.csv", text.as_bytes(), &Default::default()).unwrap();
        assert!(shares(fitted("direction,stribeck", &still)));
    }

    /// A log whose velocity is zero on all but a few rows cannot place vs: an error, no panic.
    #[test]
    fn too_few_speeds_is_an_error() {
        let mut text = String::from("time_s,track,bias\n");
        for i in 0..50 {
            let x = if i < 4 { i } else { 3 };
            text += &format!("{i},{x},{}\n", i % 3);
        }
        let log = Log::from_reader("flat.csv", text.as_bytes(), &Default::default()).unwrap();
        let err = crate::fit::fit(
            &crate::model::ModelSpec::parse("stribeck").unwrap(),
            &log,
            &crate::fit::FitOptions::default().check().unwrap(),
        )
        .unwrap_err();
        assert!(err.to_string().contains("too few"), "{err}");
    }
}
