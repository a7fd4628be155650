//! The model's terms placed in the generated C: each term's [`CTerm`] from
//! [`crate::model::term::Term::export_c`] with its placeholders filled in.

use super::ExportError;
use crate::codegen::{CContext, CTerm};
use crate::model::FittedModel;
use std::fmt::Write as _;

/// One term as placed in the generated C.
#[derive(Debug)]
pub(super) struct Written {
    /// The term's name.
    pub(super) name: String,
    /// Its number of coefficients.
    pub(super) n: usize,
    /// Its C text, placeholders filled in.
    pub(super) term: CTerm,
    /// The prefix of its constants (`BM<k>`).
    pub(super) prefix: String,
}

/// Every term of `model` as C, in model order. Fails naming the first term that does not
/// describe itself or whose text is inconsistent.
pub(super) fn place_terms(
    model: &FittedModel,
    ctx: &CContext,
) -> Result<Vec<Written>, ExportError> {
    let covariates = &model.columns.covariates;
    let mut terms = Vec::new();
    for (k, t) in model.terms.iter().enumerate() {
        let name = t.term.name();
        let c = t
            .term
            .export_c(ctx)
            .ok_or_else(|| ExportError::NotExportable { term: name.clone() })?;
        let idx = t
            .term
            .covariates()
            .iter()
            .map(|c| {
                covariates
                    .iter()
                    .position(|n| n == c)
                    .ok_or_else(|| ExportError::BadTerm {
                        term: name.clone(),
                        why: format!("covariate `{c}` is not among the model's columns"),
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let member = format!("s->t{k}");
        let prefix = format!("BM{k}");
        let bad = |why: String| ExportError::BadTerm {
            term: name.clone(),
            why,
        };
        let term = CTerm {
            state: c.state.clone(),
            constants: fill(&c.constants, &member, &prefix, &idx).map_err(bad)?,
            init: fill(&c.init, &member, &prefix, &idx).map_err(bad)?,
            basis: fill(&c.basis, &member, &prefix, &idx).map_err(bad)?,
            offset: fill(&c.offset, &member, &prefix, &idx).map_err(bad)?,
            update: fill(&c.update, &member, &prefix, &idx).map_err(bad)?,
        };
        terms.push(Written {
            name,
            n: t.coefficients.len(),
            term,
            prefix,
        });
    }
    Ok(terms)
}

/// `s` safe inside a C comment.
pub(super) fn comment(s: &str) -> String {
    s.replace("*/", "* /")
}

/// Replaces `$S`, `$K` and `$X<i>` in a term's text.
fn fill(text: &str, state: &str, prefix: &str, covariates: &[usize]) -> Result<String, String> {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(i) = rest.find('$') {
        out.push_str(&rest[..i]);
        let after = &rest[i + 1..];
        if let Some(r) = after.strip_prefix('S') {
            out.push_str(state);
            rest = r;
        } else if let Some(r) = after.strip_prefix('K') {
            out.push_str(prefix);
            rest = r;
        } else if let Some(r) = after.strip_prefix('X') {
            let digits = r.bytes().take_while(u8::is_ascii_digit).count();
            let k: usize = r[..digits]
                .parse()
                .map_err(|_| "`$X` without a covariate number".to_string())?;
            let idx = covariates.get(k).ok_or_else(|| {
                format!(
                    "`$X{k}`: the term reads only {} covariates",
                    covariates.len()
                )
            })?;
            let _ = write!(out, "x[{idx}]");
            rest = &r[digits..];
        } else {
            return Err(format!(
                "unknown placeholder `${}`",
                after.chars().next().unwrap_or(' ')
            ));
        }
    }
    out.push_str(rest);
    Ok(out)
}
