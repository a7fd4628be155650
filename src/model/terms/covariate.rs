//! `col:NAME`: bias linear in a covariate column of the log (for example `col:temp_c`).
//! Internally the column is centred and scaled by its training mean and standard deviation; the
//! reported `slope` is in counts per unit of the column.

use super::covariate_position;
use crate::model::ModelError;
use crate::model::data::{FitData, FitError};
use crate::model::term::{Param, Seek, Term, TermSpec, TermState, se_from_cov};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Spec of the `col:NAME` term.
#[derive(Debug, Clone)]
pub struct ColSpec {
    /// The covariate column.
    pub column: String,
}

impl TermSpec for ColSpec {
    fn name(&self) -> String {
        format!("col:{}", self.column)
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let idx = data.covariate(&self.column, &self.name())?;
        let v = data.measured_values(|s| Some(s.covariates[idx]));
        let centre = crate::numeric::stats::mean(&v).unwrap_or(0.0);
        let sd = crate::numeric::stats::std_dev(&v).unwrap_or(0.0);
        Ok(Arc::new(ColTerm {
            column: self.column.clone(),
            centre,
            scale: if sd > 0.0 { sd } else { 1.0 },
        }))
    }
}

/// The fitted `col:NAME` term.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ColTerm {
    /// The covariate column.
    pub column: String,
    /// Training mean of the column.
    pub centre: f64,
    /// Training standard deviation of the column (1 if it was constant).
    pub scale: f64,
}

impl Term for ColTerm {
    fn name(&self) -> String {
        format!("col:{}", self.column)
    }
    fn param_names(&self) -> Vec<String> {
        vec!["slope".into()]
    }
    fn covariates(&self) -> Vec<String> {
        vec![self.column.clone()]
    }
    fn start(&self, covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        Ok(Box::new(ColState {
            idx: covariate_position(covariates, &self.column, &self.name())?,
            centre: self.centre,
            scale: self.scale,
        }))
    }
    fn report(&self, coef: &[f64], cov: &[f64], _nl: Option<f64>) -> Vec<Param> {
        vec![Param {
            name: format!("{}.slope", self.name()),
            value: coef[0] / self.scale,
            se: se_from_cov(cov, 1, 0).map(|s| s / self.scale),
        }]
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
}

#[derive(Debug, Clone)]
struct ColState {
    idx: usize,
    centre: f64,
    scale: f64,
}

impl TermState for ColState {
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        out[0] = (seek.covariates[self.idx] - self.centre) / self.scale;
    }
    fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(self.clone())
    }
}

/// Parses `col:NAME`; the registry's parser.
pub fn parse(
    t: &crate::model::registry::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    match t.arg {
        Some(name) if !name.is_empty() => Ok(Arc::new(ColSpec {
            column: name.to_string(),
        })),
        _ => Err(t.bad("`col` needs a column name: `col:NAME`".into())),
    }
}
