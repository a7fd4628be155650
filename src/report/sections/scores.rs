//! The fit summary (in sample: what each model saw while it was fitted), the scores (out of
//! sample: the causal replay over rows the model never saw), the error figures and a model's
//! curves. In-sample and out-of-sample numbers are never in one table.

use super::{Notes, figure_or_notice, p_cell};
use crate::log::{Log, Units};
use crate::model::Prediction;
use crate::plot::views;
use crate::report::run::ScoredModel;
use crate::report::{Cell, Section, Table};

/// The fit summary: for each model its terms, what it was fitted on, the rows and parameters,
/// the in-sample residual std (bias unit `units.bias`), whether the fit converged, and the
/// fit's own warnings (parameters the data cannot determine, …).
pub(crate) fn fit_summary_table<'a>(
    scored: impl IntoIterator<Item = &'a ScoredModel>,
    units: &Units,
) -> Table {
    let fit_std = format!("fit residual std, in sample ({})", units.bias);
    let mut t = Table::new(&[
        "model",
        "terms",
        "fitted on",
        "rows used",
        "parameters",
        &fit_std,
        "converged",
        "warnings",
    ])
    .caption("Fit summary (in sample: each model on the rows it was fitted on)");
    for s in scored {
        let f = &s.model.fit;
        t = t.row(vec![
            s.label.clone().into(),
            s.model.spec.to_string().into(),
            s.trained_on.clone().into(),
            f.rows_used.into(),
            f.parameters.into(),
            Cell::Fixed(f.residual_std, 2),
            if f.converged { "yes" } else { "no" }.into(),
            warnings_cell(&s.model.warnings).into(),
        ]);
    }
    t
}

/// A fit's warnings in one cell: "none", or each distinct warning once, in order, with "(×n)"
/// when the fit gave it n > 1 times (one per coefficient of a multi-coefficient term).
fn warnings_cell(warnings: &[String]) -> String {
    if warnings.is_empty() {
        return "none".into();
    }
    let mut distinct: Vec<(&str, usize)> = Vec::new();
    for w in warnings {
        match distinct.iter_mut().find(|(d, _)| *d == w.as_str()) {
            Some((_, n)) => *n += 1,
            None => distinct.push((w.as_str(), 1)),
        }
    }
    distinct
        .iter()
        .map(|(w, n)| {
            if *n > 1 {
                format!("{w} (×{n})")
            } else {
                w.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// The out-of-sample scores of `scored` (replayed causally over rows they were not fitted on,
/// or, for a user's model, the rows `caption` names): error std and mean in `units.bias`,
/// bimodality, the dip test's two humps, the trend against position.
pub(crate) fn score_table<'a>(
    scored: impl IntoIterator<Item = &'a ScoredModel>,
    caption: &str,
    units: &Units,
) -> Table {
    let test_std = format!("test error std ({})", units.bias);
    let test_mean = format!("test mean ({})", units.bias);
    let mut t = Table::new(&[
        "model",
        "scored on",
        &test_std,
        &test_mean,
        "bimodality",
        "two humps (dip test, p < 0.05)",
        "trend vs position (p < 0.01)",
    ])
    .caption(caption);
    for s in scored {
        let trend = s
            .score
            .trend
            .as_ref()
            .map(|t| {
                let verdict = if t.p_value < 0.01 { "yes" } else { "no" };
                format!("{verdict} ({})", p_cell(t.p_value))
            })
            .unwrap_or_else(|| "n/a".into());
        let humps = s
            .score
            .dip
            .as_ref()
            .map(|d| {
                let verdict = if s.score.bimodal { "yes" } else { "no" };
                format!("{verdict} ({})", p_cell(d.p_value))
            })
            .unwrap_or_else(|| "n/a".into());
        t = t.row(vec![
            s.label.clone().into(),
            s.scored_on.clone().into(),
            Cell::Fixed(s.score.std, 2),
            Cell::Fixed(s.score.mean, 2),
            s.score
                .bimodality
                .map_or(Cell::Text("n/a".into()), |b| Cell::Fixed(b, 2)),
            humps.into(),
            trend.into(),
        ]);
    }
    t
}

/// Figs. 10/11 of `scored`: each model's error vs position and its histogram.
pub(crate) fn errors_figure(
    s: &mut Section,
    scored: &[&ScoredModel],
    units: &Units,
    caption: &str,
) {
    let preds: Vec<(&str, &Prediction)> = scored
        .iter()
        .map(|x| (x.label.as_str(), &x.prediction))
        .collect();
    s.figure(views::errors(&preds, units), caption);
}

/// A model's label as a noun phrase: "the calibration model" for a preset or term list, the
/// label itself where it already says what it is ("your model (whole log)").
pub(crate) fn model_phrase(label: &str) -> String {
    if label.starts_with("your model") {
        label.to_string()
    } else {
        format!("the {label} model")
    }
}

/// Bias vs position of `log` with `m`'s inbound and outbound curves, or a notice of why they
/// could not be drawn.
pub(crate) fn curves_figure(
    s: &mut Section,
    log: &Log,
    m: &ScoredModel,
    caption: impl Into<String>,
    notes: &mut Notes,
) {
    figure_or_notice(
        s,
        views::position(log, Some(&m.model)),
        caption,
        &format!("The curves of {}", model_phrase(&m.label)),
        notes,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: the phrases written out by hand; a caption never reads "the your model".
    #[test]
    fn a_model_label_reads_as_a_phrase() {
        assert_eq!(model_phrase("calibration"), "the calibration model");
        assert_eq!(
            model_phrase("your model (whole log)"),
            "your model (whole log)"
        );
        assert_eq!(
            format!(
                "with the curves of {}.",
                model_phrase("your model (whole log)")
            ),
            "with the curves of your model (whole log)."
        );
    }

    /// Reference: the list written out by hand.
    #[test]
    fn repeated_warnings_are_counted_once() {
        assert_eq!(warnings_cell(&[]), "none");
        let w = [
            "a".to_string(),
            "b".to_string(),
            "a".to_string(),
            "a".to_string(),
        ];
        assert_eq!(warnings_cell(&w), "a (×3); b");
    }
}
