//! `by:A:B`: the interaction of two features — the product of their centred and scaled values,
//! one parameter (counts per unit of the scaled product). `A` and `B` are built-in history
//! features ([`Feature::from_name`]: `position`, `direction`, `dwell_s`, …) or covariate
//! columns. It models an effect no single feature has a marginal of, such as a coil
//! temperature that tilts the position curve (`by:temp_c:position`). The main effects are left
//! to other terms (`col:A`, `poly2`); where either feature is undefined the basis is 0.

use super::bins::Source;
use crate::history::Feature;
use crate::model::ModelError;
use crate::model::data::{FitData, FitError};
use crate::model::term::{Seek, Term, TermSpec, TermState};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The head of the term's spec text (`by`).
pub(crate) const HEAD: &str = "by";

/// The spec text of the centred product of features or columns `a` and `b` (`by:A:B`).
pub(crate) fn spec(a: &str, b: &str) -> String {
    format!("{HEAD}:{a}:{b}")
}

/// Parses `by:A:B` (registry entry).
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    match t.arg.and_then(|a| a.split_once(':')) {
        Some((a, b)) if !a.is_empty() && !b.is_empty() && !b.contains(':') => {
            Ok(Arc::new(BySpec {
                sources: [a.to_string(), b.to_string()],
            }))
        }
        _ => Err(t.bad(
            "`by` needs two features or columns: `by:A:B` (e.g. `by:temp_c:position`)".into(),
        )),
    }
}

/// Spec of the `by:A:B` term.
#[derive(Debug, Clone)]
pub struct BySpec {
    /// The two features or covariate columns.
    pub sources: [String; 2],
}

impl TermSpec for BySpec {
    fn name(&self) -> String {
        format!("by:{}:{}", self.sources[0], self.sources[1])
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let mut centre = [0.0; 2];
        let mut scale = [1.0; 2];
        let mut covariate = [false; 2];
        for k in 0..2 {
            let src = &self.sources[k];
            let values: Vec<f64> = match Feature::from_name(src) {
                Some(f) => data
                    .measured_map(|s| s.features.value(f))
                    .into_iter()
                    .flatten()
                    .collect(),
                None => {
                    covariate[k] = true;
                    let idx = data.covariate(src, &self.name())?;
                    data.measured_positional(|s| Some(s.covariates[idx]))
                }
            };
            centre[k] = crate::numeric::stats::mean(&values).unwrap_or(0.0);
            let sd = crate::numeric::stats::std_dev(&values).unwrap_or(0.0);
            scale[k] = if sd > 0.0 { sd } else { 1.0 };
        }
        Ok(Arc::new(ByTerm {
            name: self.name(),
            sources: self.sources.clone(),
            covariate,
            centre,
            scale,
        }))
    }
}

/// The fitted `by:A:B` term.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ByTerm {
    /// Spec string.
    pub name: String,
    /// The two sources.
    pub sources: [String; 2],
    /// Whether each source is a covariate column (else a built-in feature).
    pub covariate: [bool; 2],
    /// Centres (training means).
    pub centre: [f64; 2],
    /// Scales (training standard deviations).
    pub scale: [f64; 2],
}

impl Term for ByTerm {
    fn name(&self) -> String {
        self.name.clone()
    }
    fn param_names(&self) -> Vec<String> {
        vec!["product".into()]
    }
    fn covariates(&self) -> Vec<String> {
        (0..2)
            .filter(|&k| self.covariate[k])
            .map(|k| self.sources[k].clone())
            .collect()
    }
    fn start(&self, covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        let mut src = [Source::Covariate(0); 2];
        for (k, s) in src.iter_mut().enumerate() {
            *s = Source::resolve(self.covariate[k], &self.sources[k], covariates, &self.name)?;
        }
        Ok(Box::new(ByState {
            term: self.clone(),
            src,
        }))
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
}

#[derive(Debug, Clone)]
struct ByState {
    term: ByTerm,
    src: [Source; 2],
}

impl TermState for ByState {
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        let value = |k: usize| self.src[k].value(seek);
        let t = &self.term;
        out[0] = match (value(0), value(1)) {
            (Some(a), Some(b)) => (a - t.centre[0]) / t.scale[0] * (b - t.centre[1]) / t.scale[1],
            _ => 0.0,
        };
    }
    fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(self.clone())
    }
}
