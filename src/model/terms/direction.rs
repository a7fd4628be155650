//! `direction`: ±Fc by the direction of the last non-zero seek (+Fc after an inbound move,
//! −Fc after an outbound one, 0 before the head has moved). Fc in counts: half the gap between
//! the inbound and outbound curves of the paper's Fig. 3.

use crate::codegen::{CContext, CTerm};
use crate::model::ModelError;
use crate::model::cue::{Answer, Cue};
use crate::model::data::{FitData, FitError};
use crate::model::term::{Seek, Term, TermCaps, TermSpec, TermState};
use std::sync::Arc;

/// The head of the term's spec text (`direction`).
pub(crate) const HEAD: &str = "direction";

/// Spec of the `direction` term.
#[derive(Debug, Clone, Copy)]
pub struct DirectionSpec;

impl TermSpec for DirectionSpec {
    fn name(&self) -> String {
        HEAD.into()
    }
    fn prepare(&self, _data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        Ok(Arc::new(DirectionTerm))
    }
}

/// The fitted `direction` term: parameter `Fc` (counts).
#[derive(Debug, Clone, Copy)]
pub struct DirectionTerm;

impl Term for DirectionTerm {
    fn name(&self) -> String {
        HEAD.into()
    }
    fn param_names(&self) -> Vec<String> {
        vec!["Fc".into()]
    }
    fn caps(&self) -> TermCaps {
        TermCaps {
            spans_direction_offset: true,
            ..TermCaps::DEFAULT
        }
    }
    fn start(&self, _covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        Ok(Box::new(DirectionState))
    }
    fn export_c(&self, _ctx: &CContext) -> Option<CTerm> {
        Some(CTerm {
            basis: "b[0] = (bias_real)f->direction;\n".into(),
            ..CTerm::default()
        })
    }
}

#[derive(Debug, Clone, Copy)]
struct DirectionState;

impl TermState for DirectionState {
    fn constant(&self) -> bool {
        true
    }
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        out[0] = f64::from(seek.features.direction);
    }
    fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(*self)
    }
}

/// Parses `direction` (no argument); the registry's parser.
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    t.no_arg(Arc::new(DirectionSpec))
}

/// The fitted `direction` term (it has no saved settings); the registry's restorer.
pub(crate) fn restore(
    _name: &str,
    _settings: &serde_json::Value,
) -> Result<Arc<dyn Term>, ModelError> {
    Ok(Arc::new(DirectionTerm))
}

/// The pattern `direction` answers: a step with the direction of the last move.
pub(crate) fn answers(cue: Cue) -> Option<Answer> {
    match cue {
        Cue::Feature(crate::history::Feature::Direction, _) => Answer::fixed(0),
        _ => None,
    }
}
