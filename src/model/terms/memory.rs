//! `memory[:KNOTS]`: b_m of eq. 1, the rest-position memory (paper P6, Fig. 9).
//!
//! The feature is the distance `d` from the target to the nearest earlier rest position that no
//! later motion has crossed, on the side the head is moving towards
//! ([`SeekFeatures::rest_distance_ahead`](crate::history::SeekFeatures::rest_distance_ahead),
//! kept by the two-stack [`RestMemory`](crate::history::RestMemory), amortised O(1) per seek).
//! One curve per approach direction (outbound, inbound), each a sum of decaying hinges
//! `(k_j − d)₊` with knots at the interior quantiles `j/(K+1)` of the measured distances, so the
//! effect fades to exactly zero beyond the largest knot, and about 1/(K+1) of the training rows
//! (the farthest) pin that zero. (With the largest knot at the farthest distance, every training
//! row sees a non-zero curve that nearly duplicates the direction term: on a calibration run of
//! Tables I–VII plus 500 random seeks that gave opposing coefficients of ±500 counts and a test
//! error of 28 counts instead of 8.) **No rest position ahead is represented as an infinite
//! distance: the contribution is 0** (the same as a rest position too far away to matter).

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

/// The head of the term's spec text (`memory`).
pub(crate) const HEAD: &str = "memory";

/// Default number of knots per curve.
pub const DEFAULT_KNOTS: usize = 4;

/// Spec of the `memory` term.
#[derive(Debug, Clone, Copy)]
pub struct MemorySpec {
    /// Knots per curve.
    pub knots: usize,
}

impl TermSpec for MemorySpec {
    fn name(&self) -> String {
        spec_name(HEAD, self.knots, DEFAULT_KNOTS)
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let d = data.measured_rest_distances_ahead();
        Ok(Arc::new(MemoryTerm {
            name: self.name(),
            knots: interior_knots_owned(d, self.knots),
        }))
    }
}

/// The fitted `memory` term.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MemoryTerm {
    /// Spec string.
    pub name: String,
    /// Knots in rest distance, tracks, increasing.
    pub knots: Vec<f64>,
}

impl Term for MemoryTerm {
    fn name(&self) -> String {
        self.name.clone()
    }
    fn param_names(&self) -> Vec<String> {
        curve_param_names(&["out", "in"], &self.knots)
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
    /// The hinge curves of `knots::curve_hinges` in the distance to the rest position on the
    /// side the head moves towards (none without one).
    fn export_c(&self, ctx: &CContext) -> Option<CTerm> {
        let curve = format!(
            "((f->direction == 1 && f->has_rest_id) || (f->direction == -1 && f->has_rest_od) ? {SIDE} : -1)"
        );
        Some(c_curve_hinges(
            ctx,
            &self.knots,
            2,
            &curve,
            "(f->direction == 1 ? f->rest_id : f->rest_od)",
        ))
    }
}

impl TermState for MemoryTerm {
    fn constant(&self) -> bool {
        true
    }
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        let f = seek.features;
        let at = direction_side(f.direction).zip(f.rest_distance_ahead());
        curve_hinges(&self.knots, at, out);
    }
    fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(self.clone())
    }
}

/// Parses `memory[:KNOTS]`; the registry's parser.
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    Ok(Arc::new(MemorySpec {
        knots: t.knots_or(DEFAULT_KNOTS)?,
    }))
}

/// The patterns `memory` answers: the distance to the rest position ahead, and the summed
/// memory (first when it flips with the direction: the nearest rest ahead of the approach).
pub(crate) fn answers(cue: Cue) -> Option<Answer> {
    match cue {
        Cue::Feature(Feature::RestDistanceOd | Feature::RestDistanceId, _) => Answer::fixed(0),
        Cue::SummedMemory(signed) => Answer::fixed(if signed { 0 } else { 1 }),
        _ => None,
    }
}
