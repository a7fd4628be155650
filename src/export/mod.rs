//! Firmware export: a fitted model as C99 source that predicts exactly what
//! [`crate::model::Predictor`] predicts (`biasctl export c`).
//!
//! [`c_source`] writes three files:
//! - `bias_model.h`: `bias_real` (`double`, or `float` with [`CPrecision::Float32`]), the state
//!   struct `bias_model_state` (history, each term's state; no allocation, no globals) and the
//!   functions `bias_model_init`, `bias_model_step` and `bias_model_peek`, with the meaning of
//!   [`crate::model::Predictor::new`], [`crate::model::Predictor::step`] and
//!   [`crate::model::Predictor::peek`]; with a handoff plant, also
//!   `bias_model_integrator_start` ([`crate::control::StartValues::integrator_start`]);
//! - `bias_model.c`: the coefficients, scalings and the handoff table as `static const` data,
//!   and the functions;
//! - `replay.c`: a program that reads a log in biasctl's format on stdin (`#` metadata lines,
//!   a header naming the model's columns, then rows; an empty or missing bias column means not
//!   measured) and prints one predicted value per row (and `,integrator_start` when the model
//!   was exported with a handoff plant; an empty cell where no start value settles).
//!
//! `cc -std=c99 -O2 DIR/*.c -lm` builds the replay program.
//!
//! ## How a term describes itself
//! Every term is written by [`crate::model::term::Term::export_c`], implemented in the term's
//! own file, which returns a [`CTerm`]: C text with placeholders the generator fills in (see
//! `crate::codegen`). A term that does not describe itself is refused
//! with [`ExportError::NotExportable`] naming it.

pub use crate::codegen::{CContext, CPrecision, CTerm};
mod handoff;
mod header;
mod history_c;
mod place;
mod replay;
mod source;

use crate::io::{OutputError, StagedDir, write_string_atomic};
use crate::model::FittedModel;
use std::path::Path;

/// The handoff table to export with the model ([`crate::control::StartValues`]).
#[derive(Debug, Clone, Copy)]
pub struct CHandoff<'a> {
    /// The plant's start values for the model's Δb.
    pub start: &'a crate::control::StartValues,
}

/// Options of [`c_source`].
#[derive(Debug, Clone, Copy, Default)]
pub struct COptions<'a> {
    /// Precision of the generated code.
    pub precision: CPrecision,
    /// Emit the handoff table and `bias_model_integrator_start`.
    pub handoff: Option<CHandoff<'a>>,
}

/// Why a model cannot be exported or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportError {
    /// A term does not describe itself in C.
    #[error(
        "term `{term}` cannot be exported to C: it does not describe itself (implement Term::export_c)"
    )]
    NotExportable {
        /// The term's name.
        term: String,
    },
    /// A term's C description is inconsistent (for example a covariate it names is not among
    /// the model's columns).
    #[error("term `{term}`: {why}")]
    BadTerm {
        /// The term's name.
        term: String,
        /// What is wrong.
        why: String,
    },
    /// The output folder cannot be used.
    #[error("{path}: {why}")]
    Folder {
        /// The folder.
        path: String,
        /// What is wrong.
        why: String,
    },
    /// Writing a file failed.
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// The three generated files.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CSource {
    /// `bias_model.h`.
    pub header: String,
    /// `bias_model.c`.
    pub source: String,
    /// `replay.c`.
    pub replay: String,
}

/// The files [`CSource::write`] puts into its folder, in order: header, source, replay.
pub const C_FILES: [&str; 3] = ["bias_model.h", "bias_model.c", "replay.c"];

impl CSource {
    /// Writes `bias_model.h`, `bias_model.c` and `replay.c` into `dir` (created if missing):
    /// staged in one temporary folder and moved into place together (`StagedDir`), so a
    /// failure leaves `dir` as it was.
    pub fn write(&self, dir: &Path) -> Result<(), ExportError> {
        if dir.exists() && !dir.is_dir() {
            return Err(ExportError::Folder {
                path: dir.display().to_string(),
                why: "exists and is not a folder (the C files are written into a folder)".into(),
            });
        }
        // Staged beside `dir` and moved in whole: all three files or none.
        let staged = StagedDir::create(dir)?;
        for (name, text) in [
            (C_FILES[0], &self.header),
            (C_FILES[1], &self.source),
            (C_FILES[2], &self.replay),
        ] {
            write_string_atomic(&staged.path(name), text)?;
        }
        Ok(staged.commit()?)
    }
}

/// Generates the C export of `model` (see the module docs). Fails naming the first term that
/// does not describe itself.
pub fn c_source(model: &FittedModel, opts: &COptions<'_>) -> Result<CSource, ExportError> {
    let ctx = CContext::new(opts.precision);
    let terms = place::place_terms(model, &ctx)?;
    Ok(CSource {
        header: header::header(model, &terms, opts),
        source: source::source(model, &terms, &ctx, opts),
        replay: replay::replay(opts),
    })
}
