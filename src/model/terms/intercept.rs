//! `intercept`: a constant, counts. Added automatically when no other term spans a constant.

use crate::codegen::{CContext, CTerm};
use crate::model::ModelError;
use crate::model::data::{FitData, FitError};
use crate::model::term::{Seek, Term, TermCaps, TermSpec, TermState};
use std::sync::Arc;

/// The head of the term's spec text (`intercept`).
pub(crate) const HEAD: &str = "intercept";

/// Spec of the `intercept` term.
#[derive(Debug, Clone, Copy)]
pub struct InterceptSpec;

impl TermSpec for InterceptSpec {
    fn name(&self) -> String {
        HEAD.into()
    }
    fn prepare(&self, _data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        Ok(Arc::new(InterceptTerm))
    }
}

/// The fitted `intercept` term: one parameter `c` in counts.
#[derive(Debug, Clone, Copy)]
pub struct InterceptTerm;

impl Term for InterceptTerm {
    fn caps(&self) -> TermCaps {
        TermCaps {
            // Its state reads `target` / `seek_length` only.
            reads_history: false,
            provides_intercept: true,
            ..TermCaps::DEFAULT
        }
    }
    fn name(&self) -> String {
        HEAD.into()
    }
    fn param_names(&self) -> Vec<String> {
        vec!["c".into()]
    }
    fn start(&self, _covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        Ok(Box::new(Constant))
    }
    fn export_c(&self, _ctx: &CContext) -> Option<CTerm> {
        Some(CTerm {
            basis: "b[0] = 1;\n".into(),
            ..CTerm::default()
        })
    }
}

/// State of a term whose basis is the constant 1.
#[derive(Debug, Clone, Copy)]
pub struct Constant;

impl TermState for Constant {
    fn basis(&self, _seek: &Seek<'_>, out: &mut [f64]) {
        out[0] = 1.0;
    }
    fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(*self)
    }
}

/// Parses `intercept` (no argument); the registry's parser.
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    t.no_arg(Arc::new(InterceptSpec))
}

/// The fitted `intercept` term (it has no saved settings); the registry's restorer.
pub(crate) fn restore(
    _name: &str,
    _settings: &serde_json::Value,
) -> Result<Arc<dyn Term>, ModelError> {
    Ok(Arc::new(InterceptTerm))
}
