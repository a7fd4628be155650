//! `viscous` and `viscous:COL`: viscous friction, a force proportional to the velocity,
//! `F = b·v`.
//!
//! **Velocity.** With a column (`viscous:COL`) the velocity is that logged column, in its own
//! unit. Without one it is derived causally from the log's position and time, the backward
//! difference `v_k = (x_k − x_{k−1}) / (t_k − t_{k−1})` (the row's signed seek length over its
//! dwell: position units per s, positive inbound/increasing), using only the row and the one
//! before it; a row at the same time as the previous one (and the first row) has `v = 0`, and
//! a quotient that overflows is taken as 0. On a dense, noisy log the backward difference is
//! noisy too: log a filtered velocity and name it (`viscous:velocity_m_s`) when you have one.
//! [`velocity`] is that rule, shared with `stribeck`.
//!
//! `b` is a linear parameter, reported as `viscous.b` in bias units per velocity unit
//! (`N/(m/s)` for a log in N and m, or per unit of the column). Internally the basis is
//! `v / scale` with `scale` the root mean square of the training velocity, so the solve sees a
//! column of order one whatever the units; predictions do not depend on that scale.

use super::common::covariate_position;
use crate::codegen::{CContext, CTerm};
use crate::model::ModelError;
use crate::model::cue::{Answer, Cue, Law};
use crate::model::data::{FitData, FitError};
use crate::model::term::{Param, Seek, Term, TermSpec, TermState, se_from_cov};
use crate::model::term_text::TermText;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The head of the term's spec text (`viscous`).
pub(crate) const HEAD: &str = "viscous";

/// The velocity of a seek: the covariate at `column` (an index into [`Seek::covariates`]) or,
/// without one, the causal backward difference `seek_length / dwell_s` (position units per s;
/// 0 when `dwell_s` is 0 or the quotient is not finite). See the module docs.
#[inline]
pub fn velocity(seek: &Seek<'_>, column: Option<usize>) -> f64 {
    match column {
        Some(i) => seek.covariates[i],
        None => {
            let f = seek.features;
            if f.dwell_s > 0.0 {
                let v = f.seek_length / f.dwell_s;
                if v.is_finite() { v } else { 0.0 }
            } else {
                0.0
            }
        }
    }
}

/// C statements that declare `bias_real v_` as [`velocity`] computes it (`$X0` for a column).
pub(crate) fn c_velocity(column: bool) -> &'static str {
    if column {
        "bias_real v_ = $X0;\n"
    } else {
        "bias_real v_ = f->dwell_s > 0 ? f->seek_length / f->dwell_s : 0; if (!isfinite(v_)) v_ = 0;\n"
    }
}

/// The training velocities (measured rows) of a velocity term, and its column's index.
pub(crate) fn training_velocities(
    data: &FitData<'_>,
    column: Option<&str>,
    term: &str,
) -> Result<Vec<f64>, FitError> {
    let idx = column.map(|c| data.covariate(c, term)).transpose()?;
    Ok(data.measured_values(|s| Some(velocity(s, idx))))
}

/// Position of the velocity column (if any) among the log's covariates `names`, or the error
/// naming the term.
pub(crate) fn column_index(
    column: Option<&str>,
    names: &[String],
    term: &str,
) -> Result<Option<usize>, ModelError> {
    column
        .map(|c| covariate_position(names, c, term))
        .transpose()
}

/// The velocity source in a term name: `""` or `":COL"`.
fn suffix(column: &Option<String>) -> String {
    column.as_ref().map(|c| format!(":{c}")).unwrap_or_default()
}

/// Spec of the `viscous[:COL]` term.
#[derive(Debug, Clone)]
pub struct ViscousSpec {
    /// The velocity column; `None`: velocity derived from position and time.
    pub column: Option<String>,
}

impl TermSpec for ViscousSpec {
    fn name(&self) -> String {
        format!("viscous{}", suffix(&self.column))
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let v = training_velocities(data, self.column.as_deref(), &self.name())?;
        let ms = if v.is_empty() {
            0.0
        } else {
            v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64
        };
        let scale = ms.sqrt();
        Ok(Arc::new(ViscousTerm {
            column: self.column.clone(),
            scale: if scale.is_finite() && scale > 0.0 {
                scale
            } else {
                1.0
            },
        }))
    }
}

/// The fitted `viscous[:COL]` term.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ViscousTerm {
    /// The velocity column; `None`: derived from position and time.
    pub column: Option<String>,
    /// RMS of the training velocity (1 if it was all zero), in the velocity's unit; finite, > 0.
    #[serde(deserialize_with = "super::common::positive_finite")]
    pub scale: f64,
}

impl Term for ViscousTerm {
    fn name(&self) -> String {
        format!("viscous{}", suffix(&self.column))
    }
    fn param_names(&self) -> Vec<String> {
        vec!["b".into()]
    }
    fn covariates(&self) -> Vec<String> {
        self.column.iter().cloned().collect()
    }
    fn start(&self, covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        let column = column_index(self.column.as_deref(), covariates, &self.name())?;
        Ok(Box::new(ViscousState {
            column,
            scale: self.scale,
        }))
    }
    /// `viscous.b`: bias units per velocity unit.
    fn report(&self, coef: &[f64], cov: &[f64], _nl: Option<f64>) -> Vec<Param> {
        vec![Param {
            name: format!("{}.b", self.name()),
            value: coef[0] / self.scale,
            se: se_from_cov(cov, 1, 0).map(|s| s / self.scale),
        }]
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn export_c(&self, ctx: &CContext) -> Option<CTerm> {
        Some(CTerm {
            basis: format!(
                "{{ {}b[0] = v_ / {}; }}\n",
                c_velocity(self.column.is_some()),
                ctx.real(self.scale)
            ),
            ..CTerm::default()
        })
    }
}

#[derive(Debug, Clone)]
struct ViscousState {
    column: Option<usize>,
    scale: f64,
}

impl TermState for ViscousState {
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        out[0] = velocity(seek, self.column) / self.scale;
    }
    fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(self.clone())
    }
}

/// Parses `viscous` or `viscous:COL`; the registry's parser.
pub(crate) fn parse(t: &TermText<'_>) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    match t.arg {
        None => Ok(Arc::new(ViscousSpec { column: None })),
        Some(c) if !c.is_empty() && !c.contains(':') => Ok(Arc::new(ViscousSpec {
            column: Some(c.to_string()),
        })),
        Some(c) => Err(t.bad(format!(
            "`viscous` takes at most a velocity column name (`viscous:NAME`), got `{c}`"
        ))),
    }
}

/// The patterns `viscous` answers: a line in a signed velocity, named by its column or from
/// the derived velocity (first unless the curve falls off at low speed).
pub(crate) fn answers(cue: Cue) -> Option<Answer> {
    match cue {
        Cue::Covariate(Law::OddLinear, _) => Answer::named(0),
        Cue::DerivedVelocity(Law::Velocity) => Answer::fixed(1),
        Cue::DerivedVelocity(_) => Answer::fixed(0),
        _ => None,
    }
}

/// Logs with known friction laws for the tests of `viscous` and `stribeck`.
#[cfg(test)]
pub(crate) mod test_logs {
    use crate::fit::{FitOptions, fit};
    use crate::log::Log;
    use crate::model::{FittedModel, ModelSpec};
    use crate::numeric::rng::SimRng;

    /// A dense log of a moving stage: irregular sampling (0.5–1.5 ms), position
    /// `scale·(5·sin(2π·1.3·t) + 0.3·sin(2π·7·t))`, and bias `law(v, vel)` + N(0, noise²) where
    /// `v` is the backward difference of the positions and times as written (the rule of
    /// [`super::velocity`]) and `vel` the exact derivative, logged as column `vel`.
    pub(crate) fn stage(
        n: usize,
        seed: u64,
        scale: f64,
        noise: f64,
        law: impl Fn(f64, f64) -> f64,
    ) -> Log {
        let mut rng = SimRng::new(seed);
        let mut text = String::from("time_s,track,bias,vel\n");
        let w = (
            2.0 * std::f64::consts::PI * 1.3,
            2.0 * std::f64::consts::PI * 7.0,
        );
        let (mut t, mut prev): (f64, Option<(f64, f64)>) = (0.0, None);
        for _ in 0..n {
            let x = scale * (5.0 * (w.0 * t).sin() + 0.3 * (w.1 * t).sin());
            let vel = scale * (5.0 * w.0 * (w.0 * t).cos() + 0.3 * w.1 * (w.1 * t).cos());
            // As the log will read them back (Display round-trips exactly).
            let (t_r, x_r): (f64, f64) = (format!("{t}").parse().unwrap(), x);
            let v = prev.map_or(0.0, |(t0, x0)| {
                if t_r > t0 {
                    (x_r - x0) / (t_r - t0)
                } else {
                    0.0
                }
            });
            let y = law(v, vel) + noise * rng.normal();
            text += &format!("{t_r},{x_r},{y},{vel}\n");
            prev = Some((t_r, x_r));
            t += 0.001 * (0.5 + rng.uniform());
        }
        Log::from_reader("stage.csv", text.as_bytes(), &Default::default()).unwrap()
    }

    /// `spec` fitted on `log` with the default options.
    pub(crate) fn fitted(spec: &str, log: &Log) -> FittedModel {
        fit(
            &ModelSpec::parse(spec).unwrap(),
            log,
            &FitOptions::default().check().unwrap(),
        )
        .unwrap()
    }

    /// The model written to JSON and read back predicts what it predicted (relative 1e-12:
    /// other terms, such as `poly2`, keep a derived constant that may differ in the last bit).
    pub(crate) fn assert_round_trip(model: &FittedModel, log: &Log) {
        let back = FittedModel::from_json(
            &model.to_json().unwrap(),
            std::path::Path::new("m.json"),
            &|_, _| None,
        )
        .unwrap();
        let (a, b) = (
            model.predict_log(log).unwrap(),
            back.predict_log(log).unwrap(),
        );
        assert_eq!(a.predicted.len(), b.predicted.len());
        for (x, y) in a.predicted.iter().zip(&b.predicted) {
            assert!((x - y).abs() <= 1e-12 * x.abs().max(1.0), "{x} vs {y}");
            assert!(x.is_finite());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::test_logs::{assert_round_trip, fitted, stage};
    use crate::model::term_text::TermText;

    /// Reference: the closed-form truth b = 2.5 (bias per position unit per s) of a log made as
    /// `1 + 2.5·v` plus N(0, 0.3²) noise, with `v` the causal backward difference; recovered
    /// within 4 standard errors, the standard error itself below 0.2 % of b.
    #[test]
    fn recovers_b_from_the_derived_velocity() {
        let log = stage(3000, 11, 1.0, 0.3, |v, _| 1.0 + 2.5 * v);
        let m = fitted("viscous", &log);
        let b = m.param("viscous.b").unwrap();
        let se = b.se.unwrap();
        assert!((b.value - 2.5).abs() < 4.0 * se && se < 0.005, "{b:?}");
        assert_round_trip(&m, &log);
    }

    /// Reference: truth b = −0.7 against the logged exact velocity column `vel`.
    #[test]
    fn recovers_b_from_a_velocity_column() {
        let log = stage(2000, 12, 1.0, 0.1, |_, vel| 4.0 - 0.7 * vel);
        let m = fitted("poly2,viscous:vel", &log);
        let b = m.param("viscous:vel.b").unwrap();
        assert!((b.value + 0.7).abs() < 4.0 * b.se.unwrap(), "{b:?}");
        assert_eq!(m.columns.covariates, ["vel"]);
        assert_round_trip(&m, &log);
    }

    #[test]
    fn parse_accepts_a_column_and_refuses_the_rest() {
        assert!(super::parse(&TermText::new("viscous")).is_ok());
        assert_eq!(
            super::parse(&TermText::new("viscous:v_m_s"))
                .unwrap()
                .name(),
            "viscous:v_m_s"
        );
        for bad in ["viscous:", "viscous:a:b"] {
            assert!(super::parse(&TermText::new(bad)).is_err(), "{bad}");
        }
        // A model file with a zero or non-finite scale is refused at load.
        let bad = serde_json::json!({"column": null, "scale": 0.0});
        assert!(crate::model::terms::restore_term("viscous", &bad).is_err());
    }
}
