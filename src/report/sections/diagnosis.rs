//! What diagnose finds in a model's residual: its summary, the strongest candidate features and
//! the residual against each of them.

use crate::diagnose::Diagnosis;
use crate::plot::views;
use crate::report::run::DiagnosedRun;
use crate::report::{Cell, Section, Table};

/// Features shown in the table and the panel.
pub(crate) const TOP: usize = views::DEFAULT_TOP;

/// The strongest `top` candidate features of `d`: share explained out of sample, family-wise
/// p-value, the verdict (the rule that decided whether it is flagged), shape, suggested term,
/// the error std once it is added (bias unit of `d`).
pub(crate) fn diagnosis_table(d: &Diagnosis, top: usize) -> Table {
    let std_once = format!("std once added ({})", d.units.bias);
    let mut t = Table::new(&[
        "feature",
        "explains (out of sample)",
        "p (family-wise)",
        "verdict",
        "shape",
        "suggested term",
        &std_once,
    ])
    .caption("Candidate features of the residual, strongest first");
    for f in d.features.iter().take(top) {
        t = t.row(vec![
            f.name.clone().into(),
            format!("{:.1} %", 100.0 * f.explained).into(),
            Cell::Number(f.p_value),
            f.reason.words().into(),
            f.shape.describe(&f.name, f.shape_at).into(),
            f.suggested_term
                .clone()
                .unwrap_or_else(|| "—".into())
                .into(),
            Cell::Fixed(f.expected_std, 2),
        ]);
    }
    t
}

/// The diagnosis' summary, its table of [`TOP`] features and the residual panel (figure
/// caption `caption`).
pub(crate) fn diagnosis(s: &mut Section, d: &DiagnosedRun, caption: &str) {
    s.paragraph(d.diagnosis.summary.clone())
        .table(diagnosis_table(&d.diagnosis, TOP))
        .figure(
            views::diagnose_panel(
                &d.diagnosis,
                &d.table,
                &d.residual,
                &views::CheckedPanelOptions::default(),
            ),
            caption,
        );
}
