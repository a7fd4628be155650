//! `Model`: a fitted model ([`biasctl::FittedModel`]): fit, its file as JSON, predict, score,
//! the online predictor and the C export.

use crate::errors::{Failure, Kind, attached, detached, fail, on_threads};
use crate::log::{F64Array, PyLog};
use biasctl::export::CPrecision;
use biasctl::history::DirectionSetting;
use biasctl::model::{Feedback, IntegratorStart};
use biasctl::{COptions, FitOptions, FittedModel, ModelSpec, Predictor};
use numpy::PyArray1;
use pyo3::prelude::*;
use std::sync::Arc;

/// A fitted bias model, immutable.
#[pyclass(frozen, module = "biasctl._biasctl", name = "Model")]
pub(crate) struct PyModel {
    pub(crate) inner: Arc<FittedModel>,
}

/// A model spec: a preset name, else a term list.
pub(crate) fn model_spec(text: &str) -> Result<ModelSpec, Failure> {
    if let Ok(s) = ModelSpec::preset(text) {
        return Ok(s);
    }
    ModelSpec::parse(text).map_err(fail(Kind::Model))
}

/// The direction setting of `deadband=` / `velocity_col=`.
pub(crate) fn direction(
    deadband: Option<f64>,
    velocity_col: Option<String>,
) -> Result<DirectionSetting, Failure> {
    let s = match (deadband, velocity_col) {
        (Some(_), Some(_)) => {
            return Err(Failure::new(
                Kind::Fit,
                "give deadband or velocity_col, not both",
            ));
        }
        (Some(d), None) => DirectionSetting::Deadband(d),
        (None, Some(c)) => DirectionSetting::Velocity(c),
        (None, None) => DirectionSetting::Auto,
    };
    s.validate().map_err(fail(Kind::Fit))?;
    Ok(s)
}

/// The checked fit settings.
pub(crate) fn fit_options(
    deadband: Option<f64>,
    velocity_col: Option<String>,
    rank_tolerance: Option<f64>,
    grid: Option<usize>,
    refine: Option<usize>,
) -> Result<biasctl::CheckedFitOptions, Failure> {
    let d = FitOptions::default();
    FitOptions {
        direction: direction(deadband, velocity_col)?,
        rank_tolerance: rank_tolerance.unwrap_or(d.rank_tolerance),
        grid: grid.unwrap_or(d.grid),
        refine: refine.unwrap_or(d.refine),
    }
    .check()
    .map_err(fail(Kind::Fit))
}

/// `fit`: as `biasctl fit`, without the GIL.
#[pyfunction]
#[pyo3(signature = (log, model, deadband=None, velocity_col=None, rank_tolerance=None, grid=None, refine=None, threads=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit(
    py: Python<'_>,
    log: &PyLog,
    model: &str,
    deadband: Option<f64>,
    velocity_col: Option<String>,
    rank_tolerance: Option<f64>,
    grid: Option<usize>,
    refine: Option<usize>,
    threads: Option<usize>,
) -> PyResult<PyModel> {
    let spec = attached(|| model_spec(model))?;
    let opts = attached(|| fit_options(deadband, velocity_col, rank_tolerance, grid, refine))?;
    detached(py, || {
        let log = log.measured()?;
        let m = on_threads(threads, || {
            biasctl::fit(&spec, log, &opts).map_err(fail(Kind::Fit))
        })?;
        Ok(PyModel { inner: Arc::new(m) })
    })
}

/// The integrator start value of a handoff plan, as `predict --handoff` writes it.
struct Start(biasctl::StartValues);

impl IntegratorStart for Start {
    fn integrator_start(&self, bias: f64) -> Option<f64> {
        self.0.integrator_start(bias)
    }
}

#[pymethods]
impl PyModel {
    /// The model file: the bytes `biasctl fit --out` writes.
    fn to_json(&self) -> PyResult<String> {
        attached(|| self.inner.to_json().map_err(fail(Kind::Model)))
    }

    /// A model from its file's text (built-in terms).
    #[staticmethod]
    #[pyo3(signature = (text, name="<json>"))]
    fn from_json(text: &str, name: &str) -> PyResult<PyModel> {
        attached(|| {
            let m = FittedModel::from_json(text, std::path::Path::new(name), &|_, _| None)
                .map_err(fail(Kind::Model))?;
            Ok(PyModel { inner: Arc::new(m) })
        })
    }

    /// The spec as a term list (`poly2,direction`).
    #[getter]
    fn spec(&self) -> String {
        self.inner.spec.to_string()
    }

    /// The fitted terms' names (with an `intercept` the fit added).
    #[getter]
    fn terms(&self) -> Vec<String> {
        self.inner.terms.iter().map(|t| t.term.name()).collect()
    }

    /// The parameters the solve dropped (undetermined, fixed at 0).
    #[getter]
    fn dropped(&self) -> Vec<String> {
        self.inner.fit.dropped.clone()
    }

    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.inner.warnings.clone()
    }

    /// `(term, name, value, std_error or None)` of every parameter.
    fn param_rows(&self) -> Vec<(String, String, f64, Option<f64>)> {
        self.inner
            .terms
            .iter()
            .flat_map(|t| {
                let term = t.term.name();
                t.params
                    .iter()
                    .map(move |p| (term.clone(), p.name.clone(), p.value, p.se))
            })
            .collect()
    }

    /// The columns of the training log: time, position, bias, covariates the terms read.
    #[getter]
    fn columns(&self) -> (String, String, String, Vec<String>) {
        let c = &self.inner.columns;
        (
            c.time.clone(),
            c.track.clone(),
            c.bias.clone(),
            c.covariates.clone(),
        )
    }

    /// The residual std of the fit (the default Δb of a handoff).
    #[getter]
    fn residual_std(&self) -> f64 {
        self.inner.fit.residual_std
    }

    /// `predict`: the columns and values of `biasctl predict --out` (names, float64 arrays;
    /// an empty cell is NaN). `handoff`: a plant (preset or TOML file) for `integrator_start`.
    #[pyo3(signature = (log, handoff=None, bias_uncertainty=None))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        log: &PyLog,
        handoff: Option<String>,
        bias_uncertainty: Option<f64>,
    ) -> PyResult<(Vec<String>, Vec<F64Array<'py>>)> {
        let model = &self.inner;
        let (names, cols) = detached(py, || {
            let start = match &handoff {
                Some(h) => Some(Start(crate::settle::start_values(
                    h,
                    bias_uncertainty.unwrap_or(model.fit.residual_std),
                )?)),
                None => None,
            };
            log.units_for(model)?;
            let mut reader = log.reader()?;
            let s = reader.schema().clone();
            let mut names = vec![s.map.time.clone(), s.map.track.clone(), s.map.bias.clone()];
            names.extend(s.covariates.iter().cloned());
            names.extend(["predicted".to_string(), "residual".to_string()]);
            if start.is_some() {
                names.push("integrator_start".into());
            }
            names.extend(model.terms.iter().map(|t| t.term.name()));
            let mut cols: Vec<Vec<f64>> = (0..names.len())
                .map(|_| Vec::with_capacity(log.inner.len()))
                .collect();
            let nan = f64::NAN;
            biasctl::model::replay_stream(
                model,
                &mut reader,
                start.as_ref().map(|s| s as &dyn IntegratorStart),
                |row, p, contrib| {
                    let mut c = cols.iter_mut();
                    let mut put = |v: f64| {
                        if let Some(col) = c.next() {
                            col.push(v);
                        }
                    };
                    put(row.time_s);
                    put(row.track);
                    put(row.bias.unwrap_or(nan));
                    for &v in &row.covariates {
                        put(v);
                    }
                    put(p.predicted);
                    put(p.residual.unwrap_or(nan));
                    if start.is_some() {
                        put(p.integrator_start.unwrap_or(nan));
                    }
                    for &v in contrib {
                        put(v);
                    }
                    Ok(())
                },
            )
            .map_err(fail(Kind::Model))?;
            Ok((names, cols))
        })?;
        let arrays = cols
            .into_iter()
            .map(|c| PyArray1::from_vec(py, c))
            .collect();
        Ok((names, arrays))
    }

    /// `score`: the JSON `biasctl score --json` prints.
    #[pyo3(signature = (log, feedback_every=0))]
    fn score(&self, py: Python<'_>, log: &PyLog, feedback_every: u64) -> PyResult<String> {
        let model = &self.inner;
        detached(py, || {
            let log = log.measured_for(model)?;
            let log = log.as_ref();
            replay_check(model, log)?;
            let s = biasctl::score_model(model, log, Feedback::every(feedback_every))
                .map_err(fail(Kind::Model))?;
            biasctl::io::to_string_pretty(&s).map_err(fail(Kind::Base))
        })
    }

    /// Whether the model can be replayed over `log` and every prediction is finite (as the
    /// command line checks before `score` and `diagnose`).
    fn check(&self, py: Python<'_>, log: &PyLog) -> PyResult<()> {
        let model = &self.inner;
        detached(py, || replay_check(model, &log.inner))
    }

    /// The online predictor, at the start of a log.
    fn predictor(&self) -> PyResult<PyPredictor> {
        attached(|| {
            let covariates = self.inner.columns.covariates.clone();
            let p = Predictor::new(&self.inner, &covariates).map_err(fail(Kind::Model))?;
            Ok(PyPredictor {
                inner: p,
                covariates,
                last_time: 0.0,
            })
        })
    }

    /// `export c`: the C files into `out_dir`; `handoff` adds the handoff table.
    #[pyo3(signature = (out_dir, float32=false, handoff=None, bias_uncertainty=None))]
    fn export_c(
        &self,
        py: Python<'_>,
        out_dir: std::path::PathBuf,
        float32: bool,
        handoff: Option<String>,
        bias_uncertainty: Option<f64>,
    ) -> PyResult<Vec<String>> {
        let model = &self.inner;
        detached(py, || {
            let start = match &handoff {
                Some(h) => Some(crate::settle::start_values(
                    h,
                    bias_uncertainty.unwrap_or(model.fit.residual_std),
                )?),
                None => None,
            };
            let opts = COptions {
                precision: if float32 {
                    CPrecision::Float32
                } else {
                    CPrecision::Float64
                },
                handoff: start
                    .as_ref()
                    .map(|s| biasctl::export::CHandoff { start: s }),
            };
            let src = biasctl::c_source(model, &opts).map_err(fail(Kind::Model))?;
            src.write(&out_dir).map_err(fail(Kind::Base))?;
            Ok(biasctl::export::C_FILES
                .iter()
                .map(|f| out_dir.join(f).display().to_string())
                .collect())
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "<biasctl.Model `{}`: {} parameters, residual std {:.4}>",
            self.inner.spec, self.inner.fit.parameters, self.inner.fit.residual_std
        )
    }
}

/// The command line's check before a replay: the model applies to the log, every prediction
/// is finite.
pub(crate) fn replay_check(model: &FittedModel, log: &biasctl::Log) -> Result<(), Failure> {
    biasctl::score::check_replay(model, log)
        .map_err(fail(Kind::Model))?
        .map_err(fail(Kind::Model))
}

/// The online predictor: one seek at a time, what firmware runs.
#[pyclass(unsendable, module = "biasctl._biasctl", name = "Predictor")]
pub(crate) struct PyPredictor {
    inner: Predictor,
    covariates: Vec<String>,
    last_time: f64,
}

impl PyPredictor {
    fn covs(&self, covariates: Option<Vec<f64>>) -> Result<Vec<f64>, Failure> {
        let c = covariates.unwrap_or_default();
        if c.len() != self.covariates.len() {
            return Err(Failure::new(
                Kind::Model,
                format!(
                    "the model reads the covariates {:?}: give {} value(s), got {}",
                    self.covariates,
                    self.covariates.len(),
                    c.len()
                ),
            ));
        }
        if let Some(x) = c.iter().find(|x| !x.is_finite()) {
            return Err(Failure::new(
                Kind::Model,
                format!("covariate value {x} is not finite"),
            ));
        }
        Ok(c)
    }
}

fn finite(name: &str, x: f64) -> Result<(), Failure> {
    if x.is_finite() {
        Ok(())
    } else {
        Err(Failure::new(
            Kind::Model,
            format!("{name} {x} is not finite"),
        ))
    }
}

#[pymethods]
impl PyPredictor {
    /// Predicts the bias of a seek to `track` at `time_s`, then advances the history (with the
    /// measured `bias`, if any); returns the prediction.
    #[pyo3(signature = (track, time_s, bias=None, covariates=None))]
    fn step(
        &mut self,
        track: f64,
        time_s: f64,
        bias: Option<f64>,
        covariates: Option<Vec<f64>>,
    ) -> PyResult<f64> {
        let c = attached(|| {
            finite("track", track)?;
            finite("time_s", time_s)?;
            if let Some(b) = bias {
                finite("bias", b)?;
            }
            self.covs(covariates)
        })?;
        self.last_time = time_s;
        let inner = &mut self.inner;
        attached(|| {
            inner
                .step(time_s, track, &c, bias)
                .map_err(fail(Kind::Model))
        })
    }

    /// The bias a seek to `track` would need now, without advancing (time: `time_s`, else the
    /// last step's).
    #[pyo3(signature = (track, time_s=None, covariates=None))]
    fn peek(&self, track: f64, time_s: Option<f64>, covariates: Option<Vec<f64>>) -> PyResult<f64> {
        let t = time_s.unwrap_or(self.last_time);
        let c = attached(|| {
            finite("track", track)?;
            finite("time_s", t)?;
            self.covs(covariates)
        })?;
        attached(|| self.inner.peek(t, track, &c).map_err(fail(Kind::Model)))
    }
}
