//! `col:NAME`: bias linear in a covariate column of the log (for example `col:temp_c`).
//! Internally the column is centred and scaled by its training mean and standard deviation; the
//! reported `slope` is in counts per unit of the column. The same fitted term with a lag stage
//! is `lag:NAME` ([`super::lag`]): the column passed through a first-order lag first.

use super::common::covariate_position;
use super::lag_filter::{FirstOrderLag, LagSearch, LagStage};
use crate::codegen::{CContext, CTerm};
use crate::model::ModelError;
use crate::model::cue::{Answer, Cue, Law};
use crate::model::data::{FitData, FitError};
use crate::model::term::{
    Nonlinear, Param, PerRowSearch, SearchBasis, Seek, Term, TermCaps, TermSpec, TermState,
    se_from_cov,
};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The head of the term's spec text (`col`).
pub(crate) const HEAD: &str = "col";

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
        Ok(Arc::new(ColTerm::prepare(
            data,
            &self.column,
            &self.name(),
        )?))
    }
}

/// The fitted `col:NAME` term, or `lag:NAME` when it has a lag stage.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ColTerm {
    /// The covariate column.
    pub column: String,
    /// Training mean of the column.
    pub centre: f64,
    /// Training standard deviation of the column (1 if it was constant).
    pub scale: f64,
    /// The first-order lag the column passes through first (`lag:NAME`); `None` for `col:NAME`.
    /// Its fields sit beside the others in a model file (`tau`, `ln_lo`, `ln_hi`).
    #[serde(flatten, default, skip_serializing_if = "Option::is_none")]
    pub lag: Option<LagStage>,
}

impl ColTerm {
    /// The centred and scaled term in `column` (training mean and std of its measured rows; a
    /// constant column gets scale 1), without a lag stage; `name` labels errors.
    pub fn prepare(data: &FitData<'_>, column: &str, name: &str) -> Result<ColTerm, FitError> {
        let idx = data.covariate(column, name)?;
        let v = data.measured_positional(|s| Some(s.covariates[idx]));
        let centre = crate::numeric::stats::mean(&v).unwrap_or(0.0);
        let sd = crate::numeric::stats::std_dev(&v).unwrap_or(0.0);
        Ok(ColTerm {
            column: column.to_string(),
            centre,
            scale: if sd > 0.0 { sd } else { 1.0 },
            lag: None,
        })
    }
}

impl Term for ColTerm {
    fn caps(&self) -> TermCaps {
        TermCaps {
            // A lag's τ: the projected RSS and the search on it are tested against a full solve
            // per candidate (`fit::projection`'s memsum and lag test).
            search_by_projection: self.lag.is_some(),
            ..TermCaps::DEFAULT
        }
    }
    fn name(&self) -> String {
        let head = if self.lag.is_some() { "lag" } else { HEAD };
        format!("{head}:{}", self.column)
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
            lag: self.lag.map(|l| FirstOrderLag::new(l.tau)),
        }))
    }
    fn search_basis<'d>(&'d self, data: &'d FitData<'_>) -> Box<dyn SearchBasis + 'd> {
        let column = covariate_position(&data.log().schema.covariates, &self.column, "");
        match (self.lag, column) {
            (Some(stage), Ok(column)) => Box::new(LagSearch {
                data,
                column,
                centre: self.centre,
                scale: self.scale,
                stage,
            }),
            _ => Box::new(PerRowSearch { term: self, data }),
        }
    }
    fn nonlinear(&self) -> Option<Nonlinear> {
        self.lag.map(|l| Nonlinear {
            name: "ln_tau".into(),
            value: l.tau.ln(),
            lo: l.ln_lo,
            hi: l.ln_hi,
        })
    }
    fn with_nonlinear(&self, t: f64) -> Option<Arc<dyn Term>> {
        let l = self.lag?;
        Some(Arc::new(ColTerm {
            lag: Some(LagStage {
                tau: t.clamp(l.ln_lo, l.ln_hi).exp(),
                ..l
            }),
            ..self.clone()
        }))
    }
    /// `NAME.slope` (counts per unit of the column) and, with a lag stage, `lag:NAME.tau` (s;
    /// standard error by the delta method from that of `ln τ`).
    fn report(&self, coef: &[f64], cov: &[f64], nl_se: Option<f64>) -> Vec<Param> {
        let mut out = vec![Param {
            name: format!("{}.slope", self.name()),
            value: coef[0] / self.scale,
            se: se_from_cov(cov, 1, 0).map(|s| s / self.scale),
        }];
        if let Some(l) = self.lag {
            out.push(Param {
                name: format!("{}.tau", self.name()),
                value: l.tau,
                se: nl_se.map(|s| s * l.tau),
            });
        }
        out
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    /// `col:NAME` only: a lag stage is not exported.
    fn export_c(&self, ctx: &CContext) -> Option<CTerm> {
        if self.lag.is_some() {
            return None;
        }
        Some(CTerm {
            basis: format!(
                "b[0] = ($X0 - {}) / {};\n",
                ctx.real(self.centre),
                ctx.real(self.scale)
            ),
            ..CTerm::default()
        })
    }
}

#[derive(Debug, Clone)]
struct ColState {
    idx: usize,
    centre: f64,
    scale: f64,
    lag: Option<FirstOrderLag>,
}

impl ColState {
    fn input(&self, seek: &Seek<'_>) -> f64 {
        let c = seek.covariates[self.idx];
        match &self.lag {
            Some(lag) => lag.peek(seek.features.time_s, c),
            None => c,
        }
    }
}

impl TermState for ColState {
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        out[0] = (self.input(seek) - self.centre) / self.scale;
    }
    fn update(&mut self, seek: &Seek<'_>, _residual: Option<f64>) {
        if let Some(lag) = &mut self.lag {
            lag.step(seek.features.time_s, seek.covariates[self.idx]);
        }
    }
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(self.clone())
    }
}

/// Parses `col:NAME`; the registry's parser.
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    match t.arg {
        Some(name) if !name.is_empty() => Ok(Arc::new(ColSpec {
            column: name.to_string(),
        })),
        _ => Err(t.bad("`col` needs a column name: `col:NAME`".into())),
    }
}

/// The patterns `col:NAME` answers: a covariate's line (first when the curve is one), and
/// the column of a lagged covariate after `lag:NAME`.
pub(crate) fn answers(cue: Cue) -> Option<Answer> {
    match cue {
        Cue::Covariate(Law::OddLinear, _) => Answer::named(1),
        Cue::Covariate(Law::Velocity, false) => Answer::named(2),
        Cue::Covariate(Law::Linear, false) => Answer::named(0),
        Cue::Covariate(Law::Other, false) => Answer::named(1),
        Cue::Lagged => Answer::named(1),
        _ => None,
    }
}
