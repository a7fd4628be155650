//! `seek[:KNOTS]`: b_s of eq. 1, the seek-length effect (paper P4/P5, Figs. 7–8).
//!
//! A continuous piecewise-linear function of |seek length| `a`, fitted separately for four
//! cases: {no direction change at the source, direction change} × {outbound, inbound}. Each
//! curve is a sum of decaying hinges `(k_j − a)₊` with knots `k_j` at the interior quantiles
//! `j/(K+1)` of the measured |seek lengths| (K = `KNOTS`, default 4), so it is **zero for seeks
//! longer than the largest knot**: long seeks land on the position/direction curves (the paper
//! normalises the bias at the target to zero). About 1/(K+1) of the training seeks lie beyond the
//! largest knot; they pin the curves' zero. With the largest knot at the longest seek, a curve is
//! non-zero on every training row and nearly duplicates the direction and intercept terms, and a
//! training log dominated by a few far table seeks then gives wild, offsetting coefficients
//! (regression test: `calibration_preset_survives_a_table_dominated_training_run`). A
//! zero-length seek uses the "no change" curve of the current
//! direction at `a = 0`; the first seek (no direction yet) contributes 0. Coefficients in counts
//! (the curve's value at `a = 0` is the sum of its coefficients weighted by `k_j/k_max`).

use super::knots::{
    curve_hinges, curve_param_names, direction_side, interior_knots_owned, spec_name,
};
use crate::codegen::{CContext, CTerm, SIDE, c_curve_hinges};
use crate::history::Feature;
use crate::model::ModelError;
use crate::model::cue::{Answer, Cue};
use crate::model::data::{FitData, FitError};
use crate::model::term::{Seek, Term, TermCaps, TermSpec, TermState};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The head of the term's spec text (`seek`).
pub(crate) const HEAD: &str = "seek";

/// Default number of knots per curve.
pub const DEFAULT_KNOTS: usize = 4;

/// Spec of the `seek` term.
#[derive(Debug, Clone, Copy)]
pub struct SeekSpec {
    /// Knots per curve.
    pub knots: usize,
}

impl TermSpec for SeekSpec {
    fn name(&self) -> String {
        spec_name(HEAD, self.knots, DEFAULT_KNOTS)
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let a =
            data.measured_positional(|s| Some(s.features.seek_length.abs()).filter(|&a| a > 0.0));
        Ok(Arc::new(SeekTerm {
            name: self.name(),
            knots: interior_knots_owned(a, self.knots),
        }))
    }
}

/// The fitted `seek` term.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SeekTerm {
    /// Spec string.
    pub name: String,
    /// Knots in |seek length|, tracks, increasing.
    pub knots: Vec<f64>,
}

/// Names of the four curves, in basis order.
pub const CURVES: [&str; 4] = ["nochange.out", "nochange.in", "change.out", "change.in"];

impl SeekTerm {
    /// Which of the four curves a seek uses, or `None` before the first move.
    pub fn curve(seek: &Seek<'_>) -> Option<usize> {
        let f = seek.features;
        let side = direction_side(f.direction)?;
        Some(2 * usize::from(f.direction_change) + side)
    }
}

impl Term for SeekTerm {
    fn name(&self) -> String {
        self.name.clone()
    }
    fn param_names(&self) -> Vec<String> {
        curve_param_names(&CURVES, &self.knots)
    }
    fn caps(&self) -> TermCaps {
        TermCaps {
            droppable: true,
            ..TermCaps::DEFAULT
        }
    }
    fn fit_warnings(&self, _model: &[Arc<dyn Term>]) -> Vec<String> {
        super::knots::no_knots_warning(self)
    }
    fn start(&self, _covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        Ok(Box::new(self.clone()))
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    /// The hinge curves of `knots::curve_hinges`, the curve chosen from the side and the
    /// direction change.
    fn export_c(&self, ctx: &CContext) -> Option<CTerm> {
        let curve = format!("({SIDE} < 0 ? -1 : 2 * f->direction_change + {SIDE})");
        Some(c_curve_hinges(
            ctx,
            &self.knots,
            CURVES.len(),
            &curve,
            "fabs(f->seek_length)",
        ))
    }
}

impl TermState for SeekTerm {
    fn constant(&self) -> bool {
        true
    }
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        let at = Self::curve(seek).map(|c| (c, seek.features.seek_length.abs()));
        curve_hinges(&self.knots, at, out);
    }
    fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(self.clone())
    }
}

/// Parses `seek[:KNOTS]`; the registry's parser.
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    Ok(Arc::new(SeekSpec {
        knots: t.knots_or(DEFAULT_KNOTS)?,
    }))
}

/// The patterns `seek` answers: the seek curves, first for an even seek-length effect, after
/// the Dahl and play state terms for a reversal effect or one that flips with the direction.
pub(crate) fn answers(cue: Cue) -> Option<Answer> {
    use Feature::{DirectionChange, SeekAbs, SeekLength, SinceReversal};
    match cue {
        Cue::Feature(SeekLength | SeekAbs | DirectionChange, false) => Answer::fixed(0),
        Cue::Feature(SinceReversal, false) => Answer::fixed(2),
        Cue::Feature(SeekLength | SeekAbs | SinceReversal | DirectionChange, true) => {
            Answer::fixed(2)
        }
        _ => None,
    }
}
