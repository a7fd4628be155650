//! `bins:FEATURE[:KNOTS]` and `dbins:FEATURE[:KNOTS]`: generic continuous piecewise-linear
//! (hinge) terms in any built-in history feature ([`Feature::from_name`]: `dwell_s`,
//! `since_reversal`, …) or covariate column.
//!
//! `bins` basis: `u = (v − centre)/scale` plus hinges `(v − k_j)₊/scale` at `KNOTS` (default 4)
//! interior quantiles of the training values (fewer if the values have fewer distinct levels).
//! Where the feature is undefined (a rest distance with no rest position) the hinges are 0 and, if
//! the training data had both defined and undefined rows, an indicator column `missing` takes 1.
//! Coefficients in counts per scaled unit (the curve shape, not meant for reading one by one).
//!
//! `dbins` ("direction bins") is the same basis multiplied by the direction of the last move
//! (`direction`: +1 inbound, −1 outbound, 0 before any move), so it models an effect of the form
//! `direction × g(v)` with `g` piecewise linear — a hysteretic effect that changes sign with the
//! approach direction, such as P3 (time at track, `dbins:dwell_s`). Like `bins`, which leaves the
//! constant to the intercept, `dbins` has no `direction × constant` column: that is the
//! `direction` term (or the asymptote of `dahl`), so `g` is fitted up to a constant. Same knots,
//! scale and parameter names as `bins` on the same feature.

use super::common::covariate_position;
use super::knots::{interior_knots_owned, label};
use crate::codegen::{CContext, CTerm, zero};
use crate::history::Feature;
use crate::model::ModelError;
use crate::model::cue::{Answer, Cue, Law};
use crate::model::data::{FitData, FitError};
use crate::model::term::{Seek, Term, TermCaps, TermSpec, TermState};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Default number of interior knots.
pub const DEFAULT_KNOTS: usize = 4;

/// Spec of the `bins:FEATURE` and `dbins:FEATURE` terms.
#[derive(Debug, Clone)]
pub struct BinsSpec {
    /// A built-in feature name or a covariate column.
    pub source: String,
    /// Number of interior knots asked for.
    pub knots: usize,
    /// Whether the curve is multiplied by the direction of the last move (`dbins`).
    pub by_direction: bool,
}

impl BinsSpec {
    /// The spec of `bins:SOURCE[:KNOTS]` (`by_direction` false) or `dbins:SOURCE[:KNOTS]`.
    pub fn new(source: &str, knots: usize, by_direction: bool) -> Self {
        Self {
            source: source.to_string(),
            knots,
            by_direction,
        }
    }
}

impl TermSpec for BinsSpec {
    fn name(&self) -> String {
        let head = if self.by_direction { DBINS_HEAD } else { HEAD };
        if self.knots == DEFAULT_KNOTS {
            format!("{head}:{}", self.source)
        } else {
            format!("{head}:{}:{}", self.source, self.knots)
        }
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let covariate = Feature::from_name(&self.source).is_none();
        let values: Vec<Option<f64>> = if covariate {
            let idx = data.covariate(&self.source, &self.name())?;
            data.measured_positional(|s| Some(s.covariates[idx]))
                .into_iter()
                .map(Some)
                .collect()
        } else {
            let f = Feature::from_name(&self.source).unwrap_or(Feature::Position);
            data.measured_map(|s| s.features.value(f))
        };
        let defined: Vec<f64> = values.iter().flatten().copied().collect();
        let centre = crate::numeric::stats::mean(&defined).unwrap_or(0.0);
        let sd = crate::numeric::stats::std_dev(&defined).unwrap_or(0.0);
        Ok(Arc::new(BinsTerm {
            name: self.name(),
            source: self.source.clone(),
            covariate,
            centre,
            scale: if sd > 0.0 { sd } else { 1.0 },
            indicator: !defined.is_empty() && defined.len() < values.len(),
            knots: interior_knots_owned(defined, self.knots),
            by_direction: self.by_direction,
        }))
    }
}

/// The fitted `bins:FEATURE` / `dbins:FEATURE` term.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct BinsTerm {
    /// Spec string.
    pub name: String,
    /// Feature or covariate name.
    pub source: String,
    /// Whether `source` is a covariate column (else a built-in feature).
    pub covariate: bool,
    /// Centre of the linear part.
    pub centre: f64,
    /// Scale of the feature.
    pub scale: f64,
    /// Interior knots, increasing.
    pub knots: Vec<f64>,
    /// Whether the basis has a `missing` indicator column.
    pub indicator: bool,
    /// Whether the basis is multiplied by the direction of the last move (`dbins`).
    #[serde(default)]
    pub by_direction: bool,
}

impl Term for BinsTerm {
    fn name(&self) -> String {
        self.name.clone()
    }
    fn param_names(&self) -> Vec<String> {
        let mut v = vec!["linear".to_string()];
        v.extend(self.knots.iter().map(|&k| format!("hinge@{}", label(k))));
        if self.indicator {
            v.push("missing".into());
        }
        v
    }
    fn caps(&self) -> TermCaps {
        TermCaps {
            droppable: true,
            ..TermCaps::DEFAULT
        }
    }
    /// A `dbins` curve times the direction has no direction×constant column by design (it would
    /// duplicate `direction`); without a term that carries the inbound/outbound offset, that
    /// offset is not modelled at all.
    fn fit_warnings(&self, model: &[Arc<dyn Term>]) -> Vec<String> {
        if self.by_direction && !model.iter().any(|t| t.caps().spans_direction_offset) {
            vec![
                "`dbins` curves have no direction×constant column: add `direction` or `dahl` to model \
                 the constant inbound/outbound offset (the two curves of Fig. 3)"
                    .into(),
            ]
        } else {
            Vec::new()
        }
    }
    fn covariates(&self) -> Vec<String> {
        if self.covariate {
            vec![self.source.clone()]
        } else {
            Vec::new()
        }
    }
    fn start(&self, covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        let source = Source::resolve(self.covariate, &self.source, covariates, &self.name)?;
        Ok(Box::new(BinsState {
            term: self.clone(),
            source,
        }))
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn export_c(&self, ctx: &CContext) -> Option<CTerm> {
        let by_direction = self.name.split(':').next() == Some(DBINS_HEAD);
        let (defined, value) = if self.covariate {
            ("1", "$X0")
        } else {
            ctx.feature(&self.source)?
        };
        let k = self.knots.len();
        let n = 1 + k + usize::from(self.indicator);
        let mut t = CTerm::default();
        if k > 0 {
            t.constants = format!(
                "static const bias_real $K_KNOTS[{k}] = {};\n",
                ctx.array(&self.knots)
            );
        }
        t.basis = zero(n);
        t.basis += &format!(
            "if ({defined}) {{ bias_real v_ = {value}; b[0] = (v_ - {c}) / {s};",
            c = ctx.real(self.centre),
            s = ctx.real(self.scale)
        );
        if k > 0 {
            t.basis += &format!(
                " {{ int j_; for (j_ = 0; j_ < {k}; j_++) {{ bias_real h_ = v_ - $K_KNOTS[j_]; b[1 + j_] = (h_ > 0 ? h_ : 0) / {s}; }} }}",
                s = ctx.real(self.scale)
            );
        }
        t.basis += " }";
        if self.indicator {
            t.basis += &format!(" else {{ b[{}] = 1; }}", k + 1);
        }
        t.basis.push('\n');
        if by_direction {
            t.basis += &format!(
                "{{ int i_; for (i_ = 0; i_ < {n}; i_++) b[i_] *= (bias_real)f->direction; }}\n"
            );
        }
        Some(t)
    }
}

/// Where a term's input value comes from: a built-in history feature or a covariate column
/// (its position among the model's covariates). Shared by `bins`, `dbins` and `by`.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Source {
    /// A built-in history feature.
    Feature(Feature),
    /// A logged covariate, by position in the model's covariate list.
    Covariate(usize),
}

impl Source {
    /// Resolves `name` (a covariate column if `covariate`, else a built-in feature name) for
    /// term `term` against the model's `covariates`; an unknown name is a `BadTerm` error.
    pub(crate) fn resolve(
        covariate: bool,
        name: &str,
        covariates: &[String],
        term: &str,
    ) -> Result<Source, ModelError> {
        if covariate {
            Ok(Source::Covariate(covariate_position(
                covariates, name, term,
            )?))
        } else {
            Feature::from_name(name)
                .map(Source::Feature)
                .ok_or_else(|| ModelError::BadTerm {
                    term: term.to_string(),
                    why: format!("unknown feature `{name}`"),
                })
        }
    }

    /// The value at `seek` (`None` where a feature is undefined).
    pub(crate) fn value(self, seek: &Seek<'_>) -> Option<f64> {
        match self {
            Source::Feature(f) => seek.features.value(f),
            Source::Covariate(i) => Some(seek.covariates[i]),
        }
    }
}

#[derive(Debug, Clone)]
struct BinsState {
    term: BinsTerm,
    source: Source,
}

impl TermState for BinsState {
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        out.fill(0.0);
        let t = &self.term;
        match self.source.value(seek) {
            Some(v) => {
                out[0] = (v - t.centre) / t.scale;
                for (o, &k) in out[1..].iter_mut().zip(&t.knots) {
                    *o = (v - k).max(0.0) / t.scale;
                }
            }
            None if t.indicator => out[t.knots.len() + 1] = 1.0,
            None => {}
        }
        if t.by_direction {
            let dir = f64::from(seek.features.direction);
            out.iter_mut().for_each(|o| *o *= dir);
        }
    }
    fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(self.clone())
    }
}

/// Parses `bins:FEATURE[:KNOTS]` and `dbins:FEATURE[:KNOTS]`; the registry's parser.
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    let head = t.head;
    let missing = || {
        t.bad(format!(
            "`{head}` needs a feature or column name: `{head}:FEATURE`"
        ))
    };
    let Some(a) = t.arg.filter(|a| !a.is_empty()) else {
        return Err(missing());
    };
    let (source, knots) = match a.rsplit_once(':') {
        Some((s, k)) => (s, t.count(k, "the number of knots", 32)?),
        None => (a, DEFAULT_KNOTS),
    };
    if source.is_empty() {
        return Err(missing());
    }
    Ok(Arc::new(BinsSpec::new(source, knots, head == DBINS_HEAD)))
}

/// Rebuilds a fitted `bins`/`dbins` term (the head of `name` says which); the registry's
/// restorer.
pub(crate) fn restore(
    name: &str,
    settings: &serde_json::Value,
) -> Result<Arc<dyn Term>, ModelError> {
    let t: BinsTerm =
        serde_json::from_value(settings.clone()).map_err(|e| ModelError::BadTerm {
            term: name.to_string(),
            why: e.to_string(),
        })?;
    Ok(Arc::new(BinsTerm {
        by_direction: name.split(':').next() == Some(DBINS_HEAD),
        ..t
    }))
}

/// The patterns `bins:NAME` answers: an even curve in any history feature (after its
/// dedicated term) or in a covariate (its place set by the curve's law).
pub(crate) fn answers(cue: Cue) -> Option<Answer> {
    match cue {
        Cue::Feature(_, false) => Answer::named(9),
        Cue::Covariate(law, false) => Answer::named(match law {
            Law::OddLinear => 2,
            Law::Velocity | Law::Linear => 1,
            Law::Other => 0,
        }),
        _ => None,
    }
}

/// The patterns `dbins:NAME` answers: a curve that flips with the direction, in a history
/// feature without a dedicated term or in a covariate (after its velocity-friction terms).
pub(crate) fn answers_by_direction(cue: Cue) -> Option<Answer> {
    match cue {
        Cue::Feature(Feature::Position | Feature::DwellS, true) => Answer::named(0),
        Cue::Covariate(law, true) => Answer::named(match law {
            Law::OddLinear => 2,
            Law::Velocity => 1,
            Law::Linear | Law::Other => 0,
        }),
        _ => None,
    }
}

/// The head of the even term's spec text (`bins:NAME`), for the diagnosis.
pub(crate) const HEAD: &str = "bins";
/// The head of the direction-signed term's spec text (`dbins:NAME`).
pub(crate) const DBINS_HEAD: &str = "dbins";
