//! What [`crate::select::discover()`] did on the report's data: each verified edit (feature,
//! edit, reason, error std before → after) and why it stopped.

use crate::report::run::{DISCOVER_START, Step};
use crate::report::{Cell, Section, Table};
use crate::select::Discovery;

/// The steps of `d`: feature, edit, reason, std before → after (bias unit of `d`), terms after.
pub(crate) fn discover_table(d: &Discovery) -> Table {
    let before = format!("std before ({})", d.unit);
    let after = format!("std after ({})", d.unit);
    let mut t = Table::new(&[
        "step",
        "feature",
        "edit",
        "reason",
        &before,
        &after,
        "terms after",
    ])
    .caption(format!(
        "discover's verified edits, error std on {}",
        d.basis
    ));
    for (i, s) in d.steps.iter().enumerate() {
        t = t.row(vec![
            (i + 1).into(),
            s.feature.clone().into(),
            s.edit.clone().into(),
            s.reason.clone().into(),
            Cell::Fixed(s.std_before, 2),
            Cell::Fixed(s.std_after, 2),
            s.terms.clone().into(),
        ]);
    }
    t
}

/// The section body: what discover does, the steps table (or that no edit was verified), the
/// final terms and why it stopped; or why it could not run. `train` and `test` name the logs it
/// fitted on and scored on.
pub(crate) fn discover(s: &mut Section, d: &Step<Discovery>, train: &str, test: &str) {
    s.paragraph(format!(
        "discover starts from {DISCOVER_START} fitted on {train}, diagnoses its error, applies \
         the best edit whose gain is verified on held-out seeks (at least the practical minimum \
         out of sample and within folds, and significant), and repeats until no edit is; each \
         step's error std is measured on {test}."
    ));
    match d {
        Ok(d) => {
            s.paragraph(format!(
                "Starting error std: {} {} on {}.",
                crate::plot::svg::fmt_num(d.start_std),
                d.unit,
                d.basis
            ));
            if d.steps.is_empty() {
                s.paragraph("No edit was verified: the starting model is kept.");
            } else {
                s.table(discover_table(d));
            }
            s.paragraph(format!(
                "Final terms: {}. Stopped because {}.",
                d.final_terms.join(","),
                d.stopped_because
            ));
        }
        Err(e) => {
            s.paragraph(format!("discover could not run: {e}."));
        }
    }
}
