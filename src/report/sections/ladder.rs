//! The ladder: one term added at a time, each rung refitted on the training log and scored on
//! the test log.

use crate::log::Units;
use crate::plot::views;
use crate::report::{Cell, Section, Table};
use crate::select::Ladder;

/// Each rung's terms, test error std (`units.bias`) and reduction from the first rung.
pub(crate) fn ladder_table(l: &Ladder, units: &Units) -> Table {
    let test_std = format!("test error std ({})", units.bias);
    let mut t = Table::new(&["step", "terms", &test_std, "reduction vs step 0"])
        .caption("The ladder: fitted on the training run, scored on the test run");
    for (i, s) in l.steps.iter().enumerate() {
        t = t.row(vec![
            i.into(),
            s.terms.join(", ").into(),
            Cell::Fixed(s.std, 2),
            format!("{:.1} %", 100.0 * s.reduction).into(),
        ]);
    }
    t
}

/// The ladder's table and bar figure (caption `caption`).
pub(crate) fn ladder(s: &mut Section, l: &Ladder, units: &Units, caption: &str) {
    s.table(ladder_table(l, units))
        .figure(views::ladder(l, units), caption);
}
