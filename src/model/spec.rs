//! An unfitted model ([`ModelSpec`]) and the one-term edits model selection makes to it.

use super::{SpecError, TermSpec, preset, terms};
use std::fmt;
use std::sync::Arc;

/// An unfitted model: the list of term specs (see [`terms::parse_term`] for the names).
#[derive(Debug, Clone, Default)]
pub struct ModelSpec {
    /// The terms, in order.
    pub terms: Vec<Arc<dyn TermSpec>>,
}

impl ModelSpec {
    /// Parses a comma-separated term list such as `poly2,dahl:4,col:temp_c`. An empty string is
    /// an empty model (only an intercept), useful to add user terms with [`ModelSpec::with_term`].
    pub fn parse(list: &str) -> Result<Self, SpecError> {
        let mut spec = ModelSpec::default();
        if list.trim().is_empty() {
            return Ok(spec);
        }
        for item in list.split(',') {
            if item.trim().is_empty() {
                return Err(SpecError::EmptyItem { list: list.into() });
            }
            spec = spec.try_with_term(terms::parse_term(item)?)?;
        }
        Ok(spec)
    }

    /// A named preset: `position-direction`, `calibration` or `dahl` (see `preset`).
    pub fn preset(name: &str) -> Result<Self, SpecError> {
        preset::preset(name)
    }

    /// This spec with one more term (a built-in or a user's [`TermSpec`]); panics never, but a
    /// duplicate name is kept as given (use [`ModelSpec::try_with_term`] to reject it).
    pub fn with_term(mut self, term: Arc<dyn TermSpec>) -> Self {
        self.terms.push(term);
        self
    }

    /// This spec with one more term; errors if a term of the same name is already there.
    pub fn try_with_term(self, term: Arc<dyn TermSpec>) -> Result<Self, SpecError> {
        let name = term.name();
        if self.terms.iter().any(|t| t.name() == name) {
            return Err(SpecError::Duplicate { term: name });
        }
        Ok(self.with_term(term))
    }
}

/// A typed change to a model: what diagnose suggests and `discover` applies. Terms are held as
/// [`TermSpec`] objects, never as strings, so a user's own term survives every edit.
///
/// ```
/// use biasctl::{model::ModelEdit, ModelSpec, model::terms::parse_term};
/// let spec = ModelSpec::parse("poly2,direction").unwrap();
/// let add = ModelEdit::Add(parse_term("col:temp_c").unwrap());
/// assert_eq!(spec.apply(&add).unwrap().to_string(), "poly2,direction,col:temp_c");
/// let swap = ModelEdit::Replace { old: "poly2".into(), new: parse_term("table:50").unwrap() };
/// assert_eq!(spec.apply(&swap).unwrap().to_string(), "table:50,direction");
/// assert_eq!(swap.to_string(), "replace poly2 by table:50");
/// assert!(spec.apply(&ModelEdit::Remove("seek".into())).is_err());
/// ```
#[derive(Debug, Clone)]
#[non_exhaustive]
pub enum ModelEdit {
    /// Add a term at the end of the model.
    Add(Arc<dyn TermSpec>),
    /// Replace the term named `old` by `new`, in place.
    Replace {
        /// Name of the term to replace (its spec string, e.g. `poly2`).
        old: String,
        /// The term that takes its place.
        new: Arc<dyn TermSpec>,
    },
    /// Remove the term with this name.
    Remove(String),
}

impl fmt::Display for ModelEdit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ModelEdit::Add(t) => write!(f, "add {}", t.name()),
            ModelEdit::Replace { old, new } => write!(f, "replace {old} by {}", new.name()),
            ModelEdit::Remove(name) => write!(f, "remove {name}"),
        }
    }
}

impl ModelSpec {
    /// The spec after `edit`; fails if an added or replacing term duplicates one already there,
    /// or if a term to replace or remove is not in the model.
    pub fn apply(&self, edit: &ModelEdit) -> Result<ModelSpec, SpecError> {
        let position = |name: &str| {
            self.terms
                .iter()
                .position(|t| t.name() == name)
                .ok_or_else(|| SpecError::NotInModel {
                    term: name.to_string(),
                    model: self.to_string(),
                })
        };
        match edit {
            ModelEdit::Add(t) => self.clone().try_with_term(t.clone()),
            ModelEdit::Replace { old, new } => {
                let i = position(old)?;
                let new_name = new.name();
                if new_name != *old && self.terms.iter().any(|t| t.name() == new_name) {
                    return Err(SpecError::Duplicate { term: new_name });
                }
                let mut spec = self.clone();
                spec.terms[i] = new.clone();
                Ok(spec)
            }
            ModelEdit::Remove(name) => {
                let i = position(name)?;
                let mut spec = self.clone();
                spec.terms.remove(i);
                Ok(spec)
            }
        }
    }
}

impl fmt::Display for ModelSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let names: Vec<String> = self.terms.iter().map(|t| t.name()).collect();
        f.write_str(&names.join(","))
    }
}
