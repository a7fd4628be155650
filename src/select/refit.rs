//! The out-of-sample residuals of a refit: the log's measured rows cut into folds of
//! consecutive seeks, each fold blanked, the model fitted on the rest and replayed causally.

use rayon::prelude::*;

use crate::diagnose::ModelDiagnosisError;
use crate::fit::{CheckedFitOptions, Refits, fit_sharing};
use crate::log::Log;
use crate::model::{Feedback, ModelSpec};

/// Indices into `log` of the rows with a measured bias, in log order (the rows every
/// residual, fold and score of a diagnosis is counted over).
pub(super) fn measured_rows(log: &Log) -> Vec<usize> {
    log.rows()
        .enumerate()
        .filter(|(_, r)| r.bias.is_some())
        .map(|(i, _)| i)
        .collect()
}

/// Out-of-sample residuals of `spec` on `log`, one per measured row in log order: fitted with
/// each of `folds` contiguous stretches of measured rows blanked, replayed over the whole log,
/// scored on the blanked stretch (see the module docs).
// Shares nothing between the folds: the reference of the fast path in the tests, and the
// check that a named edit refits on every fold (`verify::name_verified`).
pub(super) fn cv_residuals(
    spec: &ModelSpec,
    log: &Log,
    folds: usize,
    opts: &CheckedFitOptions,
) -> Result<Vec<f64>, ModelDiagnosisError> {
    cv_residuals_sharing(spec, log, folds, opts, &Refits::default(), &[]).map(|r| r.residuals)
}

/// What [`cv_residuals_sharing`] gives: the out-of-sample residuals, and the values the folds'
/// fits found for the searched nonlinear parameters.
#[derive(Debug, Clone, Default)]
pub(super) struct Refitted {
    /// One per measured row, in log order.
    pub(super) residuals: Vec<f64>,
    /// Per fold, the values its fit found for the terms searched by the fit's golden-section
    /// search (not the terms that search themselves), by term name, in the search coordinate:
    /// where a later refit of the same fold starts those terms ([`fit_sharing`]'s `warm`).
    pub(super) searched: Vec<Vec<(String, f64)>>,
}

/// The searched nonlinear parameters of `model`'s terms (those the fit's golden-section search
/// sets: not the terms that search themselves), by term name, in the search coordinate.
fn searched_values(model: &crate::model::FittedModel) -> Vec<(String, f64)> {
    model
        .terms
        .iter()
        .filter(|t| !t.term.caps().searches_itself)
        .filter_map(|t| Some((t.term.name(), t.term.nonlinear()?.value)))
        .collect()
}

/// Most bytes one verification refit's variable-projection search stores of its fixed block
/// (`fit`'s own budget is 64 MiB): several refits run at once, and on a long log the stored
/// block was the largest part of `diagnose`'s peak (a fold of a 1M-row log, 11 fixed columns:
/// 53 MB per refit). Beyond it the block is replayed per pass — the same rows, the same bits
/// (`crate::fit`'s stored-against-streamed test) — so the budget moves only time and memory;
/// the 100k-row bench's blocks (≤ 6 MB) stay stored.
pub(crate) const REFIT_FIXED_BYTES: usize = 16 << 20;

/// What every refit of a round shares ([`Refits`]): `log`'s sampling, its replayed history
/// (a short log's features or a long log's history columns, read as `opts` reads direction;
/// the masked copies differ only in bias, which no history reads) and [`REFIT_FIXED_BYTES`];
/// no standard errors of searched parameters (nothing reads them from a refit).
pub(super) fn refits_of(log: &Log, opts: &CheckedFitOptions) -> Refits {
    let sampling = crate::history::log_sampling(log);
    // A short log's replayed features, or a long log's history columns (13 B/row once for
    // every refit, not once per refit in flight): one of the two, by the log's length.
    let history = opts
        .direction
        .resolve_with(log, &sampling)
        .ok()
        .and_then(|d| {
            let h = crate::model::data::FitData::with_direction(log, &d)
                .ok()?
                .shared_history()?;
            Some((d, h))
        });
    Refits {
        sampling: Some(sampling),
        history,
        fixed_budget: REFIT_FIXED_BYTES,
        // Only the refits' out-of-sample residuals are read: no standard errors, and the
        // whole-interval searches refined by zooming.
        residuals_only: true,
    }
}

/// The first log row of each of `folds` contiguous stretches of measured rows (cut as
/// [`cv_residuals`] cuts them: stretch `k` holds measured rows `k·n/folds .. (k+1)·n/folds`),
/// then `log.len()`: stretch `k`'s measured rows are the measured rows from `starts[k]` up to
/// `starts[k + 1]`. No index per row is kept (8 B a row per refit in flight).
pub(super) fn fold_starts(log: &Log, folds: usize) -> Vec<usize> {
    let n = log.measured_count();
    let mut starts = Vec::with_capacity(folds + 1);
    let mut next = 0usize;
    let mut m = 0usize;
    for i in 0..log.len() {
        if log.bias(i).is_none() {
            continue;
        }
        while starts.len() < folds && next == m {
            starts.push(i);
            next = (starts.len()) * n / folds;
        }
        m += 1;
    }
    starts.resize(folds + 1, log.len());
    starts
}

/// [`cv_residuals`] with what the refits share given (`shared`, from [`refits_of`]): the same
/// residuals bit for bit where `warm` is empty (tested against the reference that shares
/// nothing and keeps an index per row, `tests_verify`). `warm`: per fold, the values a refit of
/// the same fold found ([`Refitted::searched`]), where that fold's search starts
/// ([`fit_sharing`]'s `warm`); empty: cold searches. Also the folds' searched values.
pub(super) fn cv_residuals_sharing(
    spec: &ModelSpec,
    log: &Log,
    folds: usize,
    opts: &CheckedFitOptions,
    shared: &Refits,
    warm: &[Vec<(String, f64)>],
) -> Result<Refitted, ModelDiagnosisError> {
    let n = log.measured_count();
    let starts = fold_starts(log, folds);
    let terms = spec.to_string();
    // The folds are independent fits (no random draws): in parallel, in fold order.
    type Part = (Vec<f64>, Vec<(String, f64)>);
    let parts: Vec<Result<Part, ModelDiagnosisError>> = (0..folds)
        .into_par_iter()
        .map(|k| {
            let (a, b) = (k * n / folds, (k + 1) * n / folds);
            if a == b {
                return Ok((Vec::new(), Vec::new()));
            }
            let mut masked = log.clone();
            for i in starts[k]..starts[k + 1] {
                masked.set_bias(i, None);
            }
            // The fold's own warm values, where a refit of it gave some.
            let warm = warm.get(k).map_or(&[][..], Vec::as_slice);
            let model = fit_sharing(spec, &masked, opts, shared, warm).map_err(|source| {
                ModelDiagnosisError::Fit {
                    step: k,
                    terms: terms.clone(),
                    file: log.schema.file.clone(),
                    source: Box::new(source),
                }
            })?;
            // The masked copy served the fit only; the replay keeps this fold's residuals and
            // nothing else per row (`replay_model` would hold every row's prediction, the
            // terms' contributions and the residual of the whole log: the same subtraction,
            // so the same bits).
            drop(masked);
            let searched = searched_values(&model);
            // The replay is causal, so the rows after this stretch (from the next stretch's
            // first row on) change none of its predictions: replayed up to there only.
            let end = starts[k + 1];
            let mut part = Vec::with_capacity(b - a);
            let mut k = 0usize;
            model
                .replay_measured_until(log, end, Feedback::EveryRow, |row, predicted, _| {
                    if (a..b).contains(&k) {
                        part.push(row.measured - predicted);
                    }
                    k += 1;
                })
                .map_err(|source| ModelDiagnosisError::Replay {
                    file: log.schema.file.clone(),
                    source,
                })?;
            Ok((part, searched))
        })
        .collect();
    let mut residuals = Vec::with_capacity(n);
    let mut searched = Vec::with_capacity(folds);
    for p in parts {
        let (r, s) = p?;
        residuals.extend(r);
        searched.push(s);
    }
    Ok(Refitted {
        residuals,
        searched,
    })
}
