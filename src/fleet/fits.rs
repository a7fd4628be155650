//! One model fitted to every drive: each drive's row of the fleet table ([`DriveFit`]), read and
//! fitted on its own, a failure kept in its row.

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::fit::{CheckedFitOptions, FitError};
use crate::log::{ColumnMap, Log, LogError, UnitError, Units};
use crate::model::ModelSpec;
use crate::model::Param;

/// How every drive's log is read: the column names and unit labels of `read_log` (the
/// command line's `--time-col`, `--bias-unit`, …). A unit not given comes from the log's
/// metadata, else its column name, as for one log.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReadSettings {
    /// Column names and delimiter.
    pub columns: ColumnMap,
    /// The bias unit label, if given.
    pub bias_unit: Option<String>,
    /// The position unit label, if given.
    pub track_unit: Option<String>,
}

impl ReadSettings {
    /// Reads the whole log at `path` with these settings, as the command line reads `--data`.
    pub fn read(&self, path: &Path) -> Result<Log, DriveError> {
        let mut log = Log::read(path, &self.columns)?;
        log.schema.units = Units::resolve(
            self.bias_unit.as_deref(),
            self.track_unit.as_deref(),
            &log.schema,
        )?;
        Ok(log)
    }
}

/// Why one drive has no fit: its log could not be read, its units not resolved, or the model
/// not fitted. The message is the library's own, as the command line prints it for one log.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DriveError {
    /// Reading the log failed.
    #[error(transparent)]
    Log(#[from] LogError),
    /// A unit label could not be resolved.
    #[error(transparent)]
    Units(#[from] UnitError),
    /// The fit failed.
    #[error(transparent)]
    Fit(#[from] FitError),
}

/// One drive's row of the fleet table: the model's parameters fitted to that drive's log.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveFit {
    /// Where the log came from (its path, or the name given with it).
    pub source: String,
    /// Measured rows the fit used (`None`: no fit).
    pub rows: Option<usize>,
    /// The fitted model's term list (`poly2,direction`); empty without a fit.
    pub terms: String,
    /// Every parameter (`poly2.c1`, …) with its standard error where it has one.
    pub params: Vec<Param>,
    /// The residual std of the fit (`None`: no fit).
    pub std: Option<f64>,
    /// The fit's warnings.
    pub warnings: Vec<String>,
    /// Why this drive has no fit (the library's message); `None` for a fitted drive.
    pub error: Option<String>,
}

impl DriveFit {
    /// The row of a drive that could not be read or fitted: `message` says why
    /// ([`crate::io::message`] of the error, as the command line prints it).
    pub fn failed(source: &str, message: &str) -> DriveFit {
        DriveFit {
            source: source.to_string(),
            rows: None,
            terms: String::new(),
            params: Vec::new(),
            std: None,
            warnings: Vec::new(),
            error: Some(message.to_string()),
        }
    }

    /// The row of a fitted model.
    pub fn fitted(source: &str, model: &crate::model::FittedModel) -> DriveFit {
        DriveFit {
            source: source.to_string(),
            rows: Some(model.fit.rows_used),
            terms: model.spec.to_string(),
            params: model.params().cloned().collect(),
            std: Some(model.fit.residual_std),
            warnings: model.warnings.clone(),
            error: None,
        }
    }

    /// The parameter named `name`, if this drive has it.
    pub fn param(&self, name: &str) -> Option<&Param> {
        self.params.iter().find(|p| p.name == name)
    }
}

/// Fits `spec` to one drive's log (already read); `source` names it in the table.
pub fn fit_log(source: &str, log: &Log, spec: &ModelSpec, opts: &CheckedFitOptions) -> DriveFit {
    match crate::fit::fit(spec, log, opts) {
        Ok(model) => DriveFit::fitted(source, &model),
        Err(e) => DriveFit::failed(source, &crate::io::message(&DriveError::from(e))),
    }
}

/// Reads the log at `path` with `read` and fits `spec` to it; the row's source is the path as
/// given. A log that cannot be read gives a row with its message.
pub fn fit_path(
    path: &Path,
    read: &ReadSettings,
    spec: &ModelSpec,
    opts: &CheckedFitOptions,
) -> DriveFit {
    let source = path.display().to_string();
    match read.read(path) {
        Ok(log) => fit_log(&source, &log, spec, opts),
        Err(e) => DriveFit::failed(&source, &crate::io::message(&e)),
    }
}

/// [`fit_path`] for every path, the drives side by side on the current rayon pool; the rows in
/// the order of `paths`.
pub fn fit_paths(
    paths: &[PathBuf],
    read: &ReadSettings,
    spec: &ModelSpec,
    opts: &CheckedFitOptions,
) -> Vec<DriveFit> {
    paths
        .par_iter()
        .map(|p| fit_path(p, read, spec, opts))
        .collect()
}
