//! Finite out: no writer emits `NaN`, `inf` or a JSON `null` standing for one. Numbers are
//! checked where they are made ([`check_finite`], naming the row and column) and, as a last
//! guard, whole texts before they are written ([`check_text`]).

/// A non-finite number met on its way out: an internal overflow (or a model or input that the
/// readers should have refused). Names what it was (row and column, or the file).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
#[error("{what} is {value}, not a finite number (the arithmetic overflowed); nothing was written")]
pub struct NonFinite {
    /// Where the number was: `row 12 (line 14), column `poly2``, or the output's name.
    pub what: String,
    /// The value (`NaN`, `inf` or `-inf`).
    pub value: f64,
}

/// `Ok(value)` if it is finite, else a [`NonFinite`] naming it by `what()` (called only then).
pub(crate) fn check_finite(value: f64, what: impl FnOnce() -> String) -> Result<f64, NonFinite> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(NonFinite {
            what: what(),
            value,
        })
    }
}

/// Checks a text about to be written (`what` names it: a file or `stdout`) for a number Rust
/// formats as `NaN`, `inf` or `-inf`: a whole word, so `info` or `Infinity` in prose pass.
pub fn check_text(text: &str, what: &str) -> Result<(), NonFinite> {
    let bad = text
        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .find_map(|w| match w {
            "NaN" => Some(f64::NAN),
            "inf" => Some(f64::INFINITY),
            _ => None,
        });
    match bad {
        None => Ok(()),
        Some(value) => Err(NonFinite {
            what: format!("a number in {what}"),
            value,
        }),
    }
}

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

    #[test]
    fn check_text_finds_formatted_non_finite_numbers_only() {
        // Reference: Rust's own formatting of the three non-finite values.
        for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let svg = format!("<circle cx=\"{v}\" cy=\"1\"/>");
            assert!(check_text(&svg, "fig.svg").is_err(), "{svg}");
            let csv = format!("1,{v:.4},2\n");
            assert!(check_text(&csv, "p.csv").is_err(), "{csv}");
        }
        check_text("info: Infinity and NaNa are words; 1e308 is a number", "x").unwrap();
        assert!(check_finite(1.0, || "x".into()).is_ok());
        let e = check_finite(f64::NAN, || "row 3, column `poly2`".into()).unwrap_err();
        assert!(
            e.to_string().contains("row 3, column `poly2` is NaN"),
            "{e}"
        );
    }
}
