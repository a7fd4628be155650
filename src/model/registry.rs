//! The one table of built-in terms ([`BUILTINS`]): each entry gives the term's head (the spec
//! text before the first `:`), its syntax for help and error text, its parser and the function
//! that rebuilds its fitted form from a model file. [`parse_term`](super::terms::parse_term),
//! [`restore_term`](super::terms::restore_term) and [`builtin_names`] are derived from it.
//!
//! **Adding a built-in term** is one file and one line: write `src/model/terms/NAME.rs` with
//! the [`TermSpec`] (unfitted) and [`Term`] (fitted) types, a `parse` function
//! (`fn(&TermText) -> Result<Arc<dyn TermSpec>, SpecError>`) and, if its fitted form has saved
//! settings, `#[derive(Serialize, Deserialize)]` on the fitted type; declare the module in
//! `terms/mod.rs` (`pub mod NAME;`) and add its row to [`BUILTINS`]. Nothing in the solver
//! ([`crate::fit`](mod@crate::fit)) knows term names: a term reports its parameter count, whether it may drop
//! undetermined columns ([`Term::droppable`]) and its own fit warnings ([`Term::fit_warnings`]).
//!
//! ```
//! use biasctl::builtin_names;
//! assert!(builtin_names().starts_with("poly2, table[:SPACING], direction"));
//! ```

use super::term::{Term, TermSpec};
use super::terms::{
    bins, bump, by, covariate, dahl, direction, drift, intercept, lag, memory, memsum, play, poly,
    scale, seek, step, stribeck, table, viscous,
};
use super::{ModelError, SpecError};
use std::sync::Arc;

/// Parses the argument of a term (`None` for a bare head).
pub(crate) type ParseFn = fn(&TermText<'_>) -> Result<Arc<dyn TermSpec>, SpecError>;
/// Rebuilds a fitted term from its name and saved settings ([`Term::settings`]).
pub(crate) type RestoreBuiltinFn =
    fn(&str, &serde_json::Value) -> Result<Arc<dyn Term>, ModelError>;

/// One built-in term of the registry.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BuiltinTerm {
    /// The head of its spec text (`poly2`, `dbins`, …).
    pub head: &'static str,
    /// Its syntax for messages (`table[:SPACING]`); `None` hides it from the list (`intercept`,
    /// which the fit adds by itself).
    pub syntax: Option<&'static str>,
    /// The parser of its spec text.
    pub parse: ParseFn,
    /// The restorer of its fitted form.
    pub restore: RestoreBuiltinFn,
}

/// Every built-in term, in the order [`builtin_names`] lists them.
pub(crate) static BUILTINS: &[BuiltinTerm] = &[
    row(
        "poly2",
        Some("poly2"),
        poly::parse,
        restore_as::<poly::Poly2Term>,
    ),
    row(
        "table",
        Some("table[:SPACING]"),
        table::parse,
        restore_as::<table::TableTerm>,
    ),
    row(
        "direction",
        Some("direction"),
        direction::parse,
        direction::restore,
    ),
    row(
        "seek",
        Some("seek[:KNOTS]"),
        seek::parse,
        restore_as::<seek::SeekTerm>,
    ),
    row(
        "memory",
        Some("memory[:KNOTS]"),
        memory::parse,
        restore_as::<memory::MemoryTerm>,
    ),
    row(
        "drift",
        Some("drift[:ALPHA]"),
        drift::parse,
        restore_as::<drift::DriftTerm>,
    ),
    row(
        "dahl",
        Some("dahl, dahl:N"),
        dahl::parse,
        restore_as::<dahl::DahlTerm>,
    ),
    row(
        "play",
        Some("play[:N]"),
        play::parse,
        restore_as::<play::PlayTerm>,
    ),
    row(
        "col",
        Some("col:NAME"),
        covariate::parse,
        restore_as::<covariate::ColTerm>,
    ),
    row("lag", Some("lag:NAME"), lag::parse, lag::restore),
    row(
        "memsum",
        Some("memsum"),
        memsum::parse,
        restore_as::<memsum::MemsumTerm>,
    ),
    row(
        "viscous",
        Some("viscous[:COL]"),
        viscous::parse,
        restore_as::<viscous::ViscousTerm>,
    ),
    row(
        "stribeck",
        Some("stribeck[:COL][:DELTA]"),
        stribeck::parse,
        stribeck::restore,
    ),
    row(
        "bins",
        Some("bins:FEATURE[:KNOTS]"),
        bins::parse,
        bins::restore,
    ),
    row(
        "dbins",
        Some("dbins:FEATURE[:KNOTS]"),
        bins::parse,
        bins::restore,
    ),
    row(
        "bump",
        Some("bump[:CENTRE:WIDTH]"),
        bump::parse,
        restore_as::<bump::BumpTerm>,
    ),
    row(
        "step",
        Some("step:COL[:T]"),
        step::parse,
        restore_as::<step::StepTerm>,
    ),
    row("by", Some("by:A:B"), by::parse, restore_as::<by::ByTerm>),
    row(
        "scale",
        Some("scale:COL:TERM"),
        scale::parse,
        scale::restore,
    ),
    row("intercept", None, intercept::parse, intercept::restore),
];

const fn row(
    head: &'static str,
    syntax: Option<&'static str>,
    parse: ParseFn,
    restore: RestoreBuiltinFn,
) -> BuiltinTerm {
    BuiltinTerm {
        head,
        syntax,
        parse,
        restore,
    }
}

/// The built-in term of spec text or model-file name `text` (looked up by its head).
pub(crate) fn lookup(text: &str) -> Option<&'static BuiltinTerm> {
    let head = text.split(':').next().unwrap_or("");
    BUILTINS.iter().find(|b| b.head == head)
}

/// The syntax of every listed built-in term, comma-separated, for messages.
pub fn builtin_names() -> String {
    BUILTINS
        .iter()
        .filter_map(|b| b.syntax)
        .collect::<Vec<_>>()
        .join(", ")
}

/// A fitted term rebuilt by deserialising its saved settings into `T`.
pub(crate) fn restore_as<T: serde::de::DeserializeOwned + Term + 'static>(
    name: &str,
    settings: &serde_json::Value,
) -> Result<Arc<dyn Term>, ModelError> {
    let t: T = serde_json::from_value(settings.clone()).map_err(|e| ModelError::BadTerm {
        term: name.to_string(),
        why: e.to_string(),
    })?;
    Ok(Arc::new(t))
}

/// One term's spec text as a parser sees it: the whole text, its head and its argument (what
/// follows the first `:`), with the checks the parsers share.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TermText<'a> {
    /// The whole item, trimmed (`dbins:dwell_s:6`).
    pub text: &'a str,
    /// Before the first `:` (`dbins`).
    pub head: &'a str,
    /// After the first `:` (`dwell_s:6`), if any.
    pub arg: Option<&'a str>,
}

impl<'a> TermText<'a> {
    /// Splits `text` (trimmed) at its first `:`.
    pub(crate) fn new(text: &'a str) -> Self {
        let text = text.trim();
        let (head, arg) = match text.split_once(':') {
            Some((h, a)) => (h, Some(a)),
            None => (text, None),
        };
        Self { text, head, arg }
    }

    /// The error "term `TEXT`: `why`".
    pub(crate) fn bad(&self, why: String) -> SpecError {
        SpecError::BadArgument {
            term: self.text.to_string(),
            why,
        }
    }

    /// `a` as an integer in `1..=max`, or the error naming `what`.
    pub(crate) fn count(&self, a: &str, what: &str, max: usize) -> Result<usize, SpecError> {
        match a.parse::<usize>() {
            Ok(n) if (1..=max).contains(&n) => Ok(n),
            _ => Err(self.bad(format!(
                "{what} must be an integer from 1 to {max}, got `{a}`"
            ))),
        }
    }

    /// The optional argument as a knot count in `1..=32`, `default` without one.
    pub(crate) fn knots_or(&self, default: usize) -> Result<usize, SpecError> {
        Ok(self
            .arg
            .map(|a| self.count(a, "the number of knots", 32))
            .transpose()?
            .unwrap_or(default))
    }

    /// `spec`, or an error if the term was given an argument.
    pub(crate) fn no_arg(&self, spec: Arc<dyn TermSpec>) -> Result<Arc<dyn TermSpec>, SpecError> {
        match self.arg {
            None => Ok(spec),
            Some(a) => Err(self.bad(format!("`{}` takes no argument, got `{a}`", self.head))),
        }
    }
}
