//! The candidate features of every measured row: the seek history replayed over the whole log,
//! plus every covariate column, aligned with the rows that carry a measured bias.

use crate::history::{Feature, replay};
use crate::log::{Log, Units};

use super::DiagnoseError;

/// Where a candidate feature comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FeatureOrigin {
    /// A built-in feature of the seek history.
    BuiltIn(Feature),
    /// A covariate column of the log (or any column added with [`FeatureTable::push_column`]).
    Covariate,
}

/// One candidate feature's values, one per measured row; `None` where it is undefined.
#[derive(Debug, Clone, PartialEq)]
pub struct FeatureColumn {
    /// The feature's name: a built-in name (`seek_length`, …) or the covariate's header name.
    pub name: String,
    /// Built-in or covariate.
    pub origin: FeatureOrigin,
    /// One value per measured row, in log order; `None` = undefined (missing).
    pub values: Vec<Option<f64>>,
}

/// Candidate features aligned with the measured rows of a log.
///
/// Built with [`FeatureTable::from_log`]: the [`History`](crate::history::History) is replayed over **all** rows (a move
/// that was not measured still changes direction, reversals and rest memory), and the values are
/// kept only for rows with a measured bias, so they line up with one residual per measured row.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FeatureTable {
    lines: Vec<u64>,
    columns: Vec<FeatureColumn>,
    units: Units,
}

impl FeatureTable {
    /// Replays the seek history over every row of `log` and collects, for every measured row,
    /// every built-in feature ([`Feature::ALL`]) and every covariate column under its header
    /// name. Non-finite covariate values are kept as missing. The log's units
    /// ([`crate::log::LogSchema::units`]) come along and label the diagnosis.
    pub fn from_log(log: &Log) -> FeatureTable {
        let measured = log.measured_count();
        let mut builtin: Vec<Vec<Option<f64>>> = Feature::ALL
            .iter()
            .map(|_| Vec::with_capacity(measured))
            .collect();
        let mut covariates: Vec<Vec<Option<f64>>> = log
            .schema
            .covariates
            .iter()
            .map(|_| Vec::with_capacity(measured))
            .collect();
        let mut lines = Vec::with_capacity(measured);
        for (_, row, f) in replay(log) {
            if row.bias.is_none() {
                continue;
            }
            lines.push(row.line);
            for (col, &feature) in builtin.iter_mut().zip(Feature::ALL.iter()) {
                col.push(f.value(feature));
            }
            for (k, col) in covariates.iter_mut().enumerate() {
                col.push(row.covariates.get(k).copied().filter(|v| v.is_finite()));
            }
        }
        let mut columns: Vec<FeatureColumn> = Feature::ALL
            .iter()
            .zip(builtin)
            .map(|(&feature, values)| FeatureColumn {
                name: feature.name().to_string(),
                origin: FeatureOrigin::BuiltIn(feature),
                values,
            })
            .collect();
        columns.extend(
            log.schema
                .covariates
                .iter()
                .zip(covariates)
                .map(|(name, values)| FeatureColumn {
                    name: name.clone(),
                    origin: FeatureOrigin::Covariate,
                    values,
                }),
        );
        FeatureTable {
            lines,
            columns,
            units: log.schema.units.clone(),
        }
    }

    /// A table without features for measured rows whose log lines are `lines` (one per row,
    /// used in messages); add features with [`FeatureTable::push_column`]. Its units are counts
    /// and tracks until [`FeatureTable::with_units`] says otherwise.
    pub fn with_lines(lines: Vec<u64>) -> FeatureTable {
        FeatureTable {
            lines,
            columns: Vec::new(),
            units: Units::default(),
        }
    }

    /// The table with the residual's and position's units set to `units`.
    pub fn with_units(mut self, units: Units) -> FeatureTable {
        self.units = units;
        self
    }

    /// The units of the residual (bias) and of the position-like features.
    pub fn units(&self) -> &Units {
        &self.units
    }

    /// Adds a covariate-like feature column. Errors if its length differs from the number of
    /// measured rows or its name is already taken. Non-finite values are kept as missing.
    pub fn push_column(
        &mut self,
        name: &str,
        values: Vec<Option<f64>>,
    ) -> Result<(), DiagnoseError> {
        if values.len() != self.len() {
            return Err(DiagnoseError::ColumnLength {
                name: name.to_string(),
                values: values.len(),
                rows: self.len(),
            });
        }
        if self.column(name).is_some() {
            return Err(DiagnoseError::DuplicateColumn {
                name: name.to_string(),
            });
        }
        let values = values
            .into_iter()
            .map(|v| v.filter(|x| x.is_finite()))
            .collect();
        self.columns.push(FeatureColumn {
            name: name.to_string(),
            origin: FeatureOrigin::Covariate,
            values,
        });
        Ok(())
    }

    /// Number of measured rows.
    pub fn len(&self) -> usize {
        self.lines.len()
    }

    /// Whether the table has no measured rows.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }

    /// The log line of each measured row.
    pub fn lines(&self) -> &[u64] {
        &self.lines
    }

    /// All feature columns: built-in features in [`Feature::ALL`] order, then covariates.
    pub fn columns(&self) -> &[FeatureColumn] {
        &self.columns
    }

    /// The column called `name`, if any.
    pub fn column(&self, name: &str) -> Option<&FeatureColumn> {
        self.columns.iter().find(|c| c.name == name)
    }
}
