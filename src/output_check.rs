//! The model-output checks: every number a fitted model's prediction or replay over a log
//! produces is finite, else the first non-finite one is named by row, line and column. They sit
//! above `model` (they replay a [`FittedModel`](crate::model::FittedModel)) and below the
//! commands that write predictions, scores and diagnoses.

use crate::io::NonFinite;
use crate::io::finite::check_finite;

/// Checks every number a model's replay over a log produced — `predicted`, `residual` and each
/// term's contribution — naming the first non-finite one by measured row (1-based), the log's
/// line and the column (term) it would be written under. What `predict`, `score` and
/// `diagnose` run before they write anything: a model file with a zero scale or an absurd rate
/// fails here instead of printing `NaN`.
pub fn check_prediction(
    pred: &crate::model::Prediction,
    log: &crate::log::Log,
) -> Result<(), NonFinite> {
    let columns = [("predicted", &pred.predicted), ("residual", &pred.residual)];
    let terms = pred
        .term_names
        .iter()
        .map(String::as_str)
        .zip(&pred.contributions);
    for (name, values) in columns.into_iter().chain(terms) {
        for (i, &v) in values.iter().enumerate() {
            check_finite(v, || {
                let line = pred.rows.get(i).and_then(|&r| log.get(r)).map(|r| r.line);
                format!(
                    "{}: row {} (line {}), column `{name}`",
                    log.schema.file,
                    i + 1,
                    line.unwrap_or(0)
                )
            })?;
        }
    }
    Ok(())
}

/// [`check_prediction`] of [`FittedModel::predict_log`](crate::model::FittedModel::predict_log)
/// without holding it: the model replayed over `log` once, streamed, and the same first
/// non-finite number named the same way (the first in `predicted`, else in `residual`, else in
/// each term's column in order). The outer error: the model cannot be replayed on the log.
pub fn check_replay(
    model: &crate::model::FittedModel,
    log: &crate::log::Log,
) -> Result<Result<(), NonFinite>, crate::model::ModelError> {
    let nt = model.terms.len();
    // Per column (predicted, residual, each term): the first non-finite value and its
    // measured row (0-based) and log row.
    let mut first: Vec<Option<(usize, usize, f64)>> = vec![None; 2 + nt];
    let mut i = 0;
    model.replay_measured(
        log,
        crate::model::Feedback::EveryRow,
        |row, pred, contrib| {
            let values = [pred, row.measured - pred]
                .into_iter()
                .chain(contrib.iter().copied());
            for (slot, v) in first.iter_mut().zip(values) {
                if slot.is_none() && !v.is_finite() {
                    *slot = Some((i, row.index, v));
                }
            }
            i += 1;
        },
    )?;
    let names = ["predicted".to_string(), "residual".to_string()]
        .into_iter()
        .chain(model.terms.iter().map(|t| t.term.name()));
    for (name, slot) in names.zip(first) {
        if let Some((i, r, v)) = slot {
            let checked = check_finite(v, || {
                format!(
                    "{}: row {} (line {}), column `{name}`",
                    log.schema.file,
                    i + 1,
                    log.line(r)
                )
            });
            return Ok(checked.map(|_| ()));
        }
    }
    Ok(Ok(()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: [`check_prediction`] of the whole `predict_log`. The streamed check must give
    /// the same answer, the same message: a finite model, and models with one coefficient made
    /// infinite or NaN (in a term's column first, or in the prediction).
    #[test]
    fn streamed_check_names_what_the_whole_prediction_check_names() {
        let log = crate::sim::random_log(500, 2);
        let spec = crate::model::ModelSpec::preset("calibration").unwrap();
        let model = crate::fit::fit(&spec, &log, &Default::default()).unwrap();
        let text = |r: Result<(), NonFinite>| r.map_err(|e| e.to_string());
        let whole = |m: &crate::model::FittedModel| {
            text(check_prediction(&m.predict_log(&log).unwrap(), &log))
        };
        assert_eq!(text(check_replay(&model, &log).unwrap()), Ok(()));
        for (t, c, v) in [
            (1, 0, f64::INFINITY),
            (3, 2, f64::NAN),
            (0, 1, f64::NEG_INFINITY),
        ] {
            let mut bad = model.clone();
            bad.terms[t].coefficients[c] = v;
            let want = whole(&bad);
            assert!(want.is_err(), "{t} {c}");
            assert_eq!(text(check_replay(&bad, &log).unwrap()), want, "{t} {c}");
        }
    }
}
