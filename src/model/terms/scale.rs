//! `scale:COL:TERM`: a covariate column scaling another term — an interaction such as a control
//! voltage scaling the friction force (`scale:voltage_v:dahl`, `scale:temp_c:play:8`,
//! `scale:supply:direction`).
//!
//! The basis is the inner term's basis, every column multiplied by the centred and scaled
//! covariate `z = (COL − mean)/std` (training mean and standard deviation of the measured rows;
//! a constant column gets std 1). The inner term's state is advanced exactly as the inner term
//! alone advances it (its `update` is called with every seek), so `scale:COL:dahl` multiplies
//! the Dahl element's state `G` by `z`. Its coefficients are a second set of the inner term's
//! parameters, one per inner basis column, and are **reported per unit of COL**: the parameters
//! are the inner term's own report (`Fc`, `sigma`, weights…) of the coefficients divided by the
//! std of COL, named `scale:COL:TERM.NAME`. With the truth
//! `bias = … + Fc·G + k·COL·G`, `scale:COL:dahl.Fc` is `k` (bias unit per unit of COL).
//!
//! **Main effects are not included**: the term models only how the inner term's contribution
//! changes with COL about its training mean. Add the inner term itself beside it (`dahl,
//! scale:voltage_v:dahl`); without it the fit warns. A covariate effect of its own needs
//! `col:COL`.
//!
//! **Nonlinear parameters of the inner term** (the Dahl rate of `dahl`, the Stribeck velocity,
//! a lag's time constant) are searched for the scaled copy by the same variable projection as
//! the inner term alone, as a parameter of its own (reported as `scale:COL:TERM.r` etc.). Why
//! not fixed at the inner term's default: the default of a searched term is only the start of
//! its search, not a physical value, and fixing it would leave the scaled copy with a shape the
//! data never chose. Why not refused: the motivating example, a voltage scaling the Dahl
//! friction force, has a searched rate. Why not tied to the main effect's fitted value: the
//! solver never matches terms by name. When the scaled amplitude is near 0 its rate is
//! undetermined; the fit then reports the standard errors that show it.
//!
//! Refused: a nested `scale` (scale a product by `scale:A:TERM` with another column instead,
//! or use `by:A:B`), and inner terms without linear parameters or that adapt to the measured
//! bias (`drift`): they have no basis to scale. Not exportable to C (`export c` refuses it by
//! name).

use super::common::covariate_position;
use super::covariate::ColTerm;
use crate::model::data::{FitData, FitError};
use crate::model::term::{Nonlinear, Param, Seek, Term, TermCaps, TermSpec, TermState};
use crate::model::{ModelError, SpecError};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The head of the term (`scale`).
pub(crate) const HEAD: &str = "scale";

/// Parses `scale:COL:TERM` (registry entry); `TERM` is any built-in term spec but `scale`.
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, SpecError> {
    let usage = "`scale` needs a covariate column and a term: `scale:COL:TERM` \
                 (e.g. `scale:voltage_v:dahl`, `scale:temp_c:play:8`)";
    let Some((column, inner)) = t.arg.and_then(|a| a.split_once(':')) else {
        return Err(t.bad(usage.into()));
    };
    if column.is_empty() || inner.is_empty() {
        return Err(t.bad(usage.into()));
    }
    let head = inner.split(':').next().unwrap_or("");
    if head == HEAD {
        return Err(t.bad(format!(
            "a `scale` term cannot scale another `scale` term (`{inner}`)"
        )));
    }
    let inner = super::parse_term(inner)
        .map_err(|e| t.bad(format!("the scaled term is not valid: {e}")))?;
    Ok(Arc::new(ScaleSpec {
        column: column.to_string(),
        inner,
    }))
}

/// The spec text of a scale term of column `column` and inner term `inner`.
fn term_name(column: &str, inner: &str) -> String {
    format!("{HEAD}:{column}:{inner}")
}

/// Spec of the `scale:COL:TERM` term.
#[derive(Debug, Clone)]
pub struct ScaleSpec {
    /// The covariate column that scales the inner term.
    pub column: String,
    /// The unfitted inner term.
    pub inner: Arc<dyn TermSpec>,
}

impl TermSpec for ScaleSpec {
    fn name(&self) -> String {
        term_name(&self.column, &self.inner.name())
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let name = self.name();
        let col = ColTerm::prepare(data, &self.column, &name)?;
        let inner = self.inner.prepare(data)?;
        if inner.caps().adaptive || inner.param_count() == 0 {
            return Err(FitError::Spec(SpecError::BadArgument {
                term: name,
                why: format!(
                    "`{}` has no linear basis to scale (it adapts to the measured bias)",
                    inner.name()
                ),
            }));
        }
        Ok(Arc::new(ScaleTerm {
            column: self.column.clone(),
            centre: col.centre,
            scale: col.scale,
            inner,
        }))
    }
}

/// The fitted `scale:COL:TERM` term: the prepared inner term and the centring of the column.
#[derive(Debug, Clone)]
pub struct ScaleTerm {
    /// The covariate column.
    pub column: String,
    /// Training mean of the column.
    pub centre: f64,
    /// Training standard deviation of the column (1 if it was constant), > 0.
    pub scale: f64,
    /// The fitted inner term.
    pub inner: Arc<dyn Term>,
}

/// The saved settings of a [`ScaleTerm`] in a model file.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ScaleSettings {
    /// The covariate column.
    column: String,
    /// Training mean of the column.
    centre: f64,
    /// Training standard deviation of the column.
    #[serde(deserialize_with = "super::common::positive_finite")]
    scale: f64,
    /// The inner term's name (its spec text).
    inner: String,
    /// The inner term's own saved settings.
    inner_settings: serde_json::Value,
}

/// Rebuilds a fitted `scale:COL:TERM` from its saved settings (the registry's restorer): the
/// inner term through the registry, the whole name checked against it.
pub(crate) fn restore(
    name: &str,
    settings: &serde_json::Value,
) -> Result<Arc<dyn Term>, ModelError> {
    let bad = |why: String| ModelError::BadTerm {
        term: name.to_string(),
        why,
    };
    let s: ScaleSettings =
        serde_json::from_value(settings.clone()).map_err(|e| bad(e.to_string()))?;
    if !s.centre.is_finite() {
        return Err(bad(format!("centre {} must be finite", s.centre)));
    }
    if s.inner.split(':').next() == Some(HEAD) {
        return Err(bad(
            "a `scale` term cannot scale another `scale` term".into()
        ));
    }
    let inner = super::restore_term(&s.inner, &s.inner_settings)?;
    let expected = term_name(&s.column, &inner.name());
    if expected != name {
        return Err(bad(format!("its settings describe `{expected}`")));
    }
    Ok(Arc::new(ScaleTerm {
        column: s.column,
        centre: s.centre,
        scale: s.scale,
        inner,
    }))
}

impl ScaleTerm {
    /// The same term with another fitted inner term.
    fn with_inner(&self, inner: Arc<dyn Term>) -> Arc<dyn Term> {
        Arc::new(ScaleTerm {
            inner,
            ..self.clone()
        })
    }

    /// `name` of the inner term's report (`dahl.Fc`) restated for this term (`scale:C:dahl.Fc`).
    fn rename(&self, name: &str) -> String {
        let inner = self.inner.name();
        let rest = name
            .strip_prefix(inner.as_str())
            .and_then(|r| r.strip_prefix('.'))
            .unwrap_or(name);
        format!("{}.{rest}", self.name())
    }
}

impl Term for ScaleTerm {
    fn name(&self) -> String {
        term_name(&self.column, &self.inner.name())
    }
    /// The inner term's parameter names (one per basis column).
    fn param_names(&self) -> Vec<String> {
        self.inner.param_names()
    }
    fn param_count(&self) -> usize {
        self.inner.param_count()
    }
    fn caps(&self) -> TermCaps {
        TermCaps {
            // A column the inner term may drop (an empty knot interval) is as undetermined scaled.
            droppable: self.inner.caps().droppable,
            ..TermCaps::DEFAULT
        }
    }
    /// The inner term's ridge (scale free, so the same on the scaled columns).
    fn ridge(&self) -> f64 {
        self.inner.ridge()
    }
    /// Warns when the inner term's main effect is not in the model.
    fn fit_warnings(&self, model: &[Arc<dyn Term>]) -> Vec<String> {
        let inner = self.inner.name();
        if model.iter().any(|t| t.name() == inner) {
            Vec::new()
        } else {
            vec![format!(
                "{}: the main effect `{inner}` is not in the model, so its contribution at the \
                 mean of `{}` is not modelled (add `{inner}` beside it)",
                self.name(),
                self.column
            )]
        }
    }
    fn covariates(&self) -> Vec<String> {
        let mut v = vec![self.column.clone()];
        for c in self.inner.covariates() {
            if !v.contains(&c) {
                v.push(c);
            }
        }
        v
    }
    fn start(&self, covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        Ok(Box::new(ScaleState {
            idx: covariate_position(covariates, &self.column, &self.name())?,
            centre: self.centre,
            scale: self.scale,
            inner: self.inner.start(covariates)?,
        }))
    }
    /// The inner term's nonlinear parameter, searched for this copy on its own (module docs).
    fn nonlinear(&self) -> Option<Nonlinear> {
        self.inner.nonlinear().map(|nl| Nonlinear {
            name: self.rename(&nl.name),
            ..nl
        })
    }
    fn with_nonlinear(&self, value: f64) -> Option<Arc<dyn Term>> {
        self.inner
            .with_nonlinear(value)
            .map(|inner| self.with_inner(inner))
    }
    /// The inner term's report of the coefficients per unit of the column (coefficients and
    /// their covariance divided by its std, once and twice), renamed `scale:COL:TERM.NAME`.
    fn report(&self, coef: &[f64], cov: &[f64], nonlinear_se: Option<f64>) -> Vec<Param> {
        let per_unit: Vec<f64> = coef.iter().map(|c| c / self.scale).collect();
        let s2 = self.scale * self.scale;
        let cov: Vec<f64> = cov.iter().map(|c| c / s2).collect();
        self.inner
            .report(&per_unit, &cov, nonlinear_se)
            .into_iter()
            .map(|p| Param {
                name: self.rename(&p.name),
                ..p
            })
            .collect()
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(ScaleSettings {
            column: self.column.clone(),
            centre: self.centre,
            scale: self.scale,
            inner: self.inner.name(),
            inner_settings: self.inner.settings(),
        })
        .unwrap_or_default()
    }
    /// Not exportable: `export c` refuses it by name.
    fn export_c(&self, _ctx: &crate::codegen::CContext) -> Option<crate::codegen::CTerm> {
        None
    }
}

/// The state of a [`ScaleTerm`]: the inner term's state and where the column is.
#[derive(Debug, Clone)]
struct ScaleState {
    /// Position of the column among the covariates.
    idx: usize,
    /// Training mean of the column.
    centre: f64,
    /// Training std of the column.
    scale: f64,
    /// The inner term's state, advanced exactly as the inner term alone advances it.
    inner: Box<dyn TermState>,
}

impl TermState for ScaleState {
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        self.inner.basis(seek, out);
        let z = (seek.covariates[self.idx] - self.centre) / self.scale;
        for o in out.iter_mut() {
            *o *= z;
        }
    }
    fn update(&mut self, seek: &Seek<'_>, residual: Option<f64>) {
        self.inner.update(seek, residual);
    }
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(self.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::{ColumnMap, Log};
    use crate::model::term_text::TermText;
    use crate::numeric::rng::SimRng;

    /// A random seek log with a covariate `volt` (values exact in the CSV).
    fn log(n: usize, seed: u64) -> Log {
        let mut rng = SimRng::new(seed);
        let mut text = String::from("time_s,track,bias,volt\n");
        let mut x = 500.0;
        for i in 0..n {
            x = (x + (rng.below(201) as f64) - 100.0).clamp(0.0, 1000.0);
            let v = 10.0 + rng.below(1000) as f64 / 100.0;
            text += &format!("{i},{x},{},{v}\n", rng.below(100));
        }
        Log::from_reader("s.csv", text.as_bytes(), &ColumnMap::default()).unwrap()
    }

    /// The spec parsed by the registry's parser of `scale`.
    fn spec(text: &str) -> Result<Arc<dyn TermSpec>, SpecError> {
        parse(&TermText::new(text))
    }

    /// Reference: the inner term prepared and replayed on its own, its basis multiplied by
    /// `(volt − mean)/std` computed here from the column (population std, as `ColTerm`): equal
    /// to the scale term's basis to 1e-12 on every row, through a save/restore of its settings.
    #[test]
    fn basis_is_the_inner_basis_times_the_centred_column() {
        let log = log(300, 3);
        let data = FitData::new(&log);
        let v: Vec<f64> = log.rows().map(|r| r.covariates[0]).collect();
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        let sd = crate::numeric::stats::std_dev(&v).unwrap();
        let covs = log.schema.covariates.clone();
        for inner in ["dahl:3", "play:4", "direction", "poly2"] {
            let s = spec(&format!("scale:volt:{inner}")).unwrap();
            assert_eq!(s.name(), format!("scale:volt:{inner}"));
            let term = s.prepare(&data).unwrap();
            let restored = restore(&term.name(), &term.settings()).unwrap();
            let reference = super::super::parse_term(inner)
                .unwrap()
                .prepare(&data)
                .unwrap();
            let n = reference.param_count();
            assert_eq!(term.param_count(), n);
            let (mut a, mut b, mut r) = (
                term.start(&covs).unwrap(),
                restored.start(&covs).unwrap(),
                reference.start(&covs).unwrap(),
            );
            let (mut oa, mut ob, mut or) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            let mut nonzero = 0;
            let mut cov = Vec::new();
            for (_, row, f) in data.replay() {
                let seek = Seek {
                    features: &f,
                    covariates: row.covariates.gather(&mut cov),
                };
                a.basis(&seek, &mut oa);
                b.basis(&seek, &mut ob);
                r.basis(&seek, &mut or);
                let z = (row.covariates[0] - mean) / sd;
                for j in 0..n {
                    let want = or[j] * z;
                    assert!(
                        (oa[j] - want).abs() <= 1e-12 * (1.0 + want.abs()),
                        "{inner}"
                    );
                    assert_eq!(oa[j].to_bits(), ob[j].to_bits(), "{inner} restored");
                    nonzero += usize::from(want.abs() > 1e-3);
                }
                a.update(&seek, None);
                b.update(&seek, None);
                r.update(&seek, None);
            }
            assert!(nonzero > 100, "{inner}: the reference basis is not trivial");
        }
    }

    /// Bad specs name the term and the problem.
    #[test]
    fn bad_specs_name_the_problem() {
        for (text, needle) in [
            ("scale", "needs a covariate column and a term"),
            ("scale:", "needs a covariate column and a term"),
            ("scale:volt", "needs a covariate column and a term"),
            ("scale::dahl", "needs a covariate column and a term"),
            ("scale:volt:", "needs a covariate column and a term"),
            ("scale:volt:nope", "unknown term `nope`"),
            ("scale:volt:dahl:99", "number of Dahl elements"),
            ("scale:a:scale:b:dahl", "cannot scale another `scale`"),
        ] {
            let e = spec(text).unwrap_err().to_string();
            assert!(
                e.contains(&format!("`{text}`")) && e.contains(needle),
                "{text}: {e}"
            );
        }
        let log = log(50, 1);
        let e = spec("scale:volt:drift")
            .unwrap()
            .prepare(&FitData::new(&log))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("scale:volt:drift") && e.contains("no linear basis"),
            "{e}"
        );
        let e = restore("scale:volt:dahl", &serde_json::json!({"column": "volt"}));
        assert!(e.is_err());
    }
}
