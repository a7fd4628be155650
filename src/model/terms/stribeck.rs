//! `stribeck[:COL][:DELTA]`: Coulomb friction with the Stribeck effect (issue #11, 4),
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

use super::viscous::{c_velocity, training_velocities, velocity};
use super::{covariate_position, positive_finite};
use crate::export::{CContext, CTerm};
use crate::model::ModelError;
use crate::model::data::{FitData, FitError};
use crate::model::registry::TermText;
use crate::model::term::{Nonlinear, Param, Seek, Term, TermSpec, TermState, se_from_cov};
use crate::numeric::stats;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Default shape exponent δ.
pub const DEFAULT_DELTA: f64 = 2.0;
/// Allowed range of δ.
pub const DELTA_RANGE: (f64, f64) = (0.5, 4.0);

/// The term name: `stribeck`, then `:COL` and `:δ` where they differ from the default.
fn term_name(column: &Option<String>, delta: f64) -> String {
    let mut name = String::from("stribeck");
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
    fn fit_warnings(&self, model: &[Arc<dyn Term>]) -> Vec<String> {
        model
            .iter()
            .filter(|t| t.spans_direction_offset())
            .map(|t| {
                format!(
                    "{}: sign(velocity) is nearly the direction of motion, so its Fc shares the \
                     ±offset with `{}` (their Coulomb levels add up; each alone is poorly determined)",
                    self.name(),
                    t.name()
                )
            })
            .collect()
    }
    fn start(&self, covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        let column = self
            .column
            .as_ref()
            .map(|c| covariate_position(covariates, c, &self.name()))
            .transpose()?;
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
pub fn restore(name: &str, settings: &serde_json::Value) -> Result<Arc<dyn Term>, ModelError> {
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
pub fn parse(t: &TermText<'_>) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    let (mut column, mut delta) = (None, None);
    for item in t
        .arg
        .map(|a| a.split(':').collect())
        .unwrap_or_else(Vec::new)
    {
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
