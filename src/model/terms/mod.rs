//! The built-in terms, one file per term (listed once in the registry, `model/registry.rs`), and
//! the parser and restorer of term spec strings derived from that registry.
//!
//! Public as the namespace `biasctl::model::terms` because a user needs it: a user writing their own
//! [`crate::Term`] composes or copies the built-in ones, and the Dahl and play predictors are
//! usable on their own (`terms::dahl::DahlPredictor`).

pub mod bins;
pub mod bump;
pub mod by;
pub mod covariate;
pub mod dahl;
pub mod direction;
pub mod drift;
pub mod intercept;
pub(crate) mod knots;
pub mod lag;
mod lag_filter;
pub mod memory;
pub mod memsum;
pub mod play;
pub mod poly;
pub mod preisach;
pub mod scale;
pub mod seek;
pub mod step;
pub mod stribeck;
pub mod table;
pub mod viscous;

use super::registry::{self, TermText};
use super::term::{Term, TermSpec};
use super::{ModelError, SpecError};
use std::sync::Arc;

mod common;
pub use common::covariate_position;

/// Parses one built-in term spec (`poly2`, `table:50`, `dahl:4`, `col:temp_c`, `bins:dwell_s`,
/// `dbins:dwell_s:6`…) through the registry (`super::registry::BUILTINS`).
pub fn parse_term(text: &str) -> Result<Arc<dyn TermSpec>, SpecError> {
    let t = TermText::new(text);
    match registry::lookup(t.head) {
        Some(b) => (b.parse)(&t),
        None => Err(SpecError::UnknownTerm {
            term: t.text.to_string(),
        }),
    }
}

/// Rebuilds a built-in fitted term from its name and saved settings (the model file), through
/// the registry ([`super::registry::BUILTINS`]).
pub(crate) fn restore_term(
    name: &str,
    settings: &serde_json::Value,
) -> Result<Arc<dyn Term>, ModelError> {
    match registry::lookup(name) {
        Some(b) => (b.restore)(name, settings),
        None => Err(ModelError::BadTerm {
            term: name.to_string(),
            why:
                "not a built-in term (load a model with user terms through FittedModel::load_with)"
                    .into(),
        }),
    }
}
