//! The fitted model from the solve: every term's coefficients, covariance and parameters, the
//! warnings of the fit (parameters not identifiable, undetermined columns, a search ended at
//! its edge, the self-check against the spread of the measured bias) and the fit report.

use super::design::{offsets, param_label};
use super::search::NonlinearFit;
use super::solve::Solution;
use crate::history::DirectionSource;
use crate::log::Log;
use crate::model::data::{FitError, FitReport};
use crate::model::term::{Param, Term};
use crate::model::{ColumnsUsed, FittedModel, FittedTerm, ModelSpec};
use std::sync::Arc;

/// A coefficient whose share of the prediction swings more than this many times the spread of
/// the measured bias is "blowing up": neighbouring columns cancel each other.
const BLOW_UP_RATIO: f64 = 100.0;

/// A design column whose sine of angle to the columns before it is below this (1 − R² below its
/// square, a variance inflation above 10¹⁰) makes the fit ill-conditioned.
const ILL_CONDITIONED: f64 = 1e-5;

/// The fit's self-check: coefficients whose contribution swings far beyond the
/// measured bias (`|coef| × column spread > BLOW_UP_RATIO × bias std`, unit-free: both sides
/// are in the bias unit), and columns nearly a combination of the others. Dropped columns are
/// reported elsewhere.
fn self_check(terms: &[Arc<dyn Term>], sol: &Solution, bias_std: f64) -> Vec<String> {
    let mut out = Vec::new();
    for c in 0..sol.coef.len() {
        if sol.dropped.contains(&c) {
            continue;
        }
        let name = param_label(terms, c).0;
        let swing = sol.coef[c].abs() * sol.spread[c];
        if bias_std > 0.0 && swing > BLOW_UP_RATIO * bias_std {
            out.push(format!(
                "{name}: its contribution swings ±{:.3e} (coefficient × the column's spread), \
                 {:.0}× the spread of the measured bias ({:.3e}): neighbouring columns cancel \
                 each other (weights blowing up); drop or merge a term",
                swing,
                swing / bias_std,
                bias_std
            ));
        }
        if let Some(sin) = sol.independence[c].filter(|&s| s < ILL_CONDITIONED) {
            out.push(format!(
                "{name}: ill-conditioned: the column is all but a combination of the columns \
                 before it (1 − R² = {:.1e}); its coefficient and standard error are unreliable",
                sin * sin
            ));
        }
    }
    out
}

/// Every term as fitted: its coefficients and covariance from the solution `sol` of the
/// design's `p` columns, its parameters (`se`: the standard errors of the searched ones); and
/// the warnings of its parameters (a standard error beyond the value) and the terms' own.
pub(super) fn fitted_terms(
    terms: &[Arc<dyn Term>],
    sol: &Solution,
    se: &[Option<f64>],
    p: usize,
) -> (Vec<FittedTerm>, Vec<String>) {
    let nl_se = se;
    let (off, _) = offsets(terms);
    let mut warnings = Vec::new();
    let mut fitted = Vec::with_capacity(terms.len());
    for (k, t) in terms.iter().enumerate() {
        let w = t.param_count();
        let coef = sol.coef[off[k]..off[k] + w].to_vec();
        let mut cov = vec![0.0; w * w];
        for a in 0..w {
            for b in 0..w {
                cov[a * w + b] = sol.cov[(off[k] + a) * p + off[k] + b];
            }
        }
        let params: Vec<Param> = t.report(&coef, &cov, nl_se[k]);
        for prm in &params {
            if let Some(se) = prm.se
                && se > prm.value.abs()
                && !sol
                    .dropped
                    .iter()
                    .any(|&c| param_label(terms, c).0 == prm.name)
            {
                warnings.push(format!(
                    "{}: standard error {:.4e} exceeds |value| {:.4e}: not identifiable from this log",
                    prm.name,
                    se,
                    prm.value.abs()
                ));
            }
        }
        for w in t.fit_warnings(terms) {
            if !warnings.contains(&w) {
                warnings.push(w);
            }
        }
        fitted.push(FittedTerm {
            term: t.clone(),
            coefficients: coef,
            params,
        });
    }
    (fitted, warnings)
}

/// The names of the parameters the solve dropped (undetermined, fixed at 0).
pub(super) fn dropped_params(terms: &[Arc<dyn Term>], sol: &Solution) -> Vec<String> {
    sol.dropped
        .iter()
        .map(|&c| param_label(terms, c).0)
        .collect()
}

/// The warnings of the fit as a whole: the `dropped` parameters, a search that ended at its
/// edge (not `converged`), and the self-check against the measured bias's spread `bias_std`
/// ([`self_check`]).
pub(super) fn fit_warnings(
    terms: &[Arc<dyn Term>],
    sol: &Solution,
    dropped: &[String],
    converged: bool,
    bias_std: f64,
) -> Vec<String> {
    let mut warnings = Vec::new();
    for d in dropped {
        warnings.push(format!(
            "{d}: the log cannot determine this coefficient (no data, or a combination of others); fixed at 0"
        ));
    }
    if !converged {
        warnings.push("a nonlinear parameter ended at the edge of its search interval".into());
    }
    warnings.extend(self_check(terms, sol, bias_std));
    warnings
}

/// The fit report of the solution `sol` and the searches `nonlinear`, its residual statistics
/// zero (set by [`set_statistics`](super::statistics::set_statistics)).
pub(super) fn fit_report(
    sol: &Solution,
    dropped: Vec<String>,
    nonlinear: &NonlinearFit,
) -> FitReport {
    FitReport {
        rows_used: sol.n,
        parameters: sol.rank,
        residual_std: 0.0,
        residual_rms: 0.0,
        r2: 0.0,
        ls_rss: sol.rss,
        dropped,
        evaluations: nonlinear.evaluations,
        converged: nonlinear.converged,
        position_range: None,
    }
}

/// The fitted model of `spec` on `log`: its `fitted` terms (of `terms`), the columns it reads,
/// its `warnings`, its `direction` source and its fit report `fit`. An error where a parameter
/// is not finite.
pub(super) fn fitted_model(
    spec: &ModelSpec,
    log: &Log,
    terms: &[Arc<dyn Term>],
    fitted: Vec<FittedTerm>,
    warnings: Vec<String>,
    direction: DirectionSource,
    fit: FitReport,
) -> Result<FittedModel, FitError> {
    let mut covariates: Vec<String> = terms.iter().flat_map(|t| t.covariates()).collect();
    covariates.dedup();
    let map = &log.schema.map;
    let model = FittedModel {
        spec: spec.clone(),
        columns: ColumnsUsed {
            time: map.time.clone(),
            track: map.track.clone(),
            bias: map.bias.clone(),
            covariates,
            units: Some(log.schema.units.clone()),
        },
        terms: fitted,
        fit,
        warnings,
        direction,
    };
    if let Some(p) = model.params().find(|p| !p.value.is_finite()) {
        let (lo, hi) = log.rows().fold((f64::MAX, f64::MIN), |(lo, hi), r| {
            (lo.min(r.track), hi.max(r.track))
        });
        return Err(FitError::ParamOverflow {
            file: log.schema.file.clone(),
            param: p.name.clone(),
            value: p.value,
            spread: (hi - lo).max(0.0),
        });
    }
    Ok(model)
}
