//! The report's sections: each turns part of a computed run ([`super::run`]) into blocks of a
//! [`super::Section`], and the demo report and the data report share them.
//!
//! - [`paper`]: what bias is — the phenomena, the simulated Tables I–VII and the true
//!   decomposition (the built-in drive only);
//! - [`scores`]: the fit summary (in sample), the scores (out of sample) and the error
//!   histograms, the model curves;
//! - [`diagnosis`], [`ladder`], [`discover`]: what is missing and what adding it is worth;
//! - [`settle`]: the settle analysis and the link from prediction error to settle time;
//! - [`data`]: a user's log and its views;
//! - [`files`]: the files behind the report.
//!
//! A figure that cannot be drawn is reported in the page in its place and collected in
//! [`Notes`] (the CLI prints them on stderr), never left blank.

pub(crate) mod data;
pub(crate) mod diagnosis;
pub(crate) mod discover;
pub(crate) mod files;
pub(crate) mod ladder;
pub(crate) mod paper;
pub(crate) mod scores;
pub(crate) mod settle;

use super::Section;
use crate::plot::svg::fmt_num;

/// What went wrong while drawing a report, one line each (a figure that could not be drawn and
/// why). The page says it in place; [`super::story::StoryOutcome::warnings`] carries these.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Notes(pub Vec<String>);

/// Adds figure `svg` with `caption` to `s`, or, when it could not be drawn, a paragraph saying
/// that `what` could not be drawn and why (also noted in `notes`).
pub(crate) fn figure_or_notice<E: std::error::Error>(
    s: &mut Section,
    svg: Result<String, E>,
    caption: impl Into<String>,
    what: &str,
    notes: &mut Notes,
) {
    match svg {
        Ok(svg) => {
            s.figure(svg, caption);
        }
        Err(e) => {
            let line = format!("{what} could not be drawn: {}", super::run::error_chain(&e));
            s.paragraph(format!("{line}."));
            notes.0.push(line);
        }
    }
}

/// A settle time in ms, or "not settled".
pub(crate) fn ms(v: Option<f64>) -> String {
    v.map_or("not settled".into(), |m| format!("{} ms", fmt_num(m)))
}

/// The reduction from `from` to `to` in whole percent ("n/a" when undefined).
pub(crate) fn pct(from: f64, to: f64) -> String {
    if from > 0.0 && from.is_finite() && to.is_finite() {
        format!("{:.0} %", 100.0 * (from - to) / from)
    } else {
        "n/a".into()
    }
}

/// A p-value in a table cell: `p < 0.0001` below 1e-4 (never `p = 0`), else `p = …`.
pub(crate) fn p_cell(p: f64) -> String {
    if p < 1e-4 {
        "p < 0.0001".into()
    } else {
        format!("p = {}", fmt_num(p))
    }
}
