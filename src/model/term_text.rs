//! One term's spec text as its parser sees it ([`TermText`]): the head, the argument and the
//! checks every parser shares.

use super::SpecError;
use super::term::TermSpec;
use std::sync::Arc;

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
