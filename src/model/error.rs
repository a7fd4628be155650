//! The errors of a model spec and of a fitted model.

#[cfg(doc)]
use super::Predictor;
use super::{preset, registry};
use crate::io::OutputError;
use std::path::PathBuf;

/// An error in a model spec string (`--terms`, `--model`); nothing has been read or fitted.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SpecError {
    /// A term name that is not built in.
    #[error(
        "unknown term `{term}`{} (terms: {}; their arguments: `biasctl fit --help`)",
        registry::did_you_mean_term(.term),
        registry::builtin_heads().join(", ")
    )]
    UnknownTerm {
        /// The offending item.
        term: String,
    },
    /// A term's argument is malformed.
    #[error("term `{term}`: {why}")]
    BadArgument {
        /// The offending item.
        term: String,
        /// What is wrong.
        why: String,
    },
    /// The same term twice.
    #[error("term `{term}` appears twice in the model")]
    Duplicate {
        /// The repeated term.
        term: String,
    },
    /// A preset name that does not exist.
    #[error(
        "unknown model preset `{name}`{} (presets: {})",
        crate::io::words::did_you_mean(.name, preset::PRESETS),
        preset::PRESETS.join(", ")
    )]
    UnknownPreset {
        /// The name given.
        name: String,
    },
    /// An edit names a term the model does not have.
    #[error("term `{term}` is not in the model `{model}`")]
    NotInModel {
        /// The term named by the edit.
        term: String,
        /// The model's terms.
        model: String,
    },
    /// An empty item in a list (`poly2,,seek`).
    #[error("empty term in the list `{list}`")]
    EmptyItem {
        /// The whole list.
        list: String,
    },
}

/// An error loading, saving or applying a fitted model.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// The model file could not be read.
    #[error("{path}: cannot read the model file: {source}")]
    Io {
        /// The model file.
        path: PathBuf,
        /// The operating-system error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a valid model file.
    #[error("{path}: not a valid biasctl model file: {why}")]
    Corrupt {
        /// The model file.
        path: PathBuf,
        /// What is wrong.
        why: String,
    },
    /// A model file from another format version.
    #[error(
        "{path}: model format version {found}, but this biasctl reads version {expected}; refit the model"
    )]
    Version {
        /// The model file.
        path: PathBuf,
        /// The version in the file.
        found: u64,
        /// The version this build reads.
        expected: u32,
    },
    /// A term in the file cannot be rebuilt.
    #[error("model term `{term}`: {why}")]
    BadTerm {
        /// The term.
        term: String,
        /// What is wrong.
        why: String,
    },
    /// The log lacks a covariate column the model uses.
    #[error(
        "term `{term}` needs covariate column `{column}`, which this log lacks (covariates in the log: {available})"
    )]
    MissingCovariate {
        /// The term.
        term: String,
        /// The missing column.
        column: String,
        /// The log's covariates.
        available: String,
    },
    /// A [`Predictor`](crate::model::Predictor) was given another number of covariate values
    /// than the covariate names it was made with.
    #[error(
        "{given} covariate values given, but the predictor was made with {expected} covariate names: pass one value per name, in their order"
    )]
    CovariateCount {
        /// The number of names given to [`Predictor::new`](crate::model::Predictor::new).
        expected: usize,
        /// The number of values passed.
        given: usize,
    },
    /// A log is read in other units than the model was fitted in.
    #[error(
        "the model was fitted with {what} in `{model}`, but this log's {what} is in `{log}` ({field}); a model predicts in the units it was fitted in: read the log in `{model}`, or refit the model on this log"
    )]
    UnitMismatch {
        /// Which unit: `bias` or `position`.
        what: &'static str,
        /// The unit the model was fitted in.
        model: String,
        /// The log's unit.
        log: String,
        /// The setting that names the log's unit.
        field: crate::field::Field,
    },
    /// A term reads a covariate column that has empty cells in this log (missing values).
    #[error(
        "{file}: term `{term}` reads {cells}; the model needs a value on every row: fill the cells"
    )]
    EmptyCovariate {
        /// The log file.
        file: String,
        /// The term.
        term: String,
        /// The column and its empty cells.
        cells: crate::log::EmptyCells,
    },
    /// The log's required columns are named differently from the ones the model was fitted on.
    #[error(
        "the model was fitted with {what} column `{model}`, but this log is read with `{log}` ({field}); the names must match: read a log that has `{model}` with {field} {}, or refit the model on this log",
        crate::io::shell_quote(.model)
    )]
    ColumnMismatch {
        /// Which column (time, track, bias).
        what: &'static str,
        /// Name at fit time.
        model: String,
        /// Name now.
        log: String,
        /// The setting that renames it.
        field: crate::field::Field,
    },
    /// The log has no rows to predict from.
    #[error("{file}: the log has no rows")]
    EmptyLog {
        /// The log file.
        file: String,
    },
    /// A seek target to predict at that is not a position a log can hold (NaN, infinite, or
    /// beyond the reader's ±1e15).
    #[error("target {target}: give a finite position within ±1e15 (the log's position unit)")]
    BadTarget {
        /// The target given.
        target: f64,
    },
    /// Writing the model file failed.
    #[error(transparent)]
    Output(#[from] OutputError),
}
