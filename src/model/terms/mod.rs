//! The built-in terms, one file per term (listed once in [`super::registry`]), and the parser
//! and restorer of term spec strings derived from that registry.

pub mod bins;
pub mod covariate;
pub mod dahl;
pub mod direction;
pub mod drift;
pub mod intercept;
pub mod knots;
pub mod memory;
pub mod play;
pub mod poly;
pub mod seek;
pub mod table;

use super::registry::{self, TermText};
use super::term::{Term, TermSpec};
use super::{ModelError, SpecError};
use std::sync::Arc;

/// Parses one built-in term spec (`poly2`, `table:50`, `dahl:4`, `col:temp_c`, `bins:dwell_s`,
/// `dbins:dwell_s:6`…) through the registry ([`super::registry::BUILTINS`]).
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
pub fn restore_term(name: &str, settings: &serde_json::Value) -> Result<Arc<dyn Term>, ModelError> {
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

/// Position of covariate `column` among `names`, or the error a model reports for it.
pub fn covariate_position(names: &[String], column: &str, term: &str) -> Result<usize, ModelError> {
    names
        .iter()
        .position(|n| n == column)
        .ok_or_else(|| ModelError::MissingCovariate {
            term: term.to_string(),
            column: column.to_string(),
            available: if names.is_empty() {
                "none".into()
            } else {
                names.join(", ")
            },
        })
}
