//! `simulate`, `diagnose` (and its `Diagnosis`), `discover` and `ladder`: the command line's
//! calls with its defaults, without the GIL.

use crate::errors::{Failure, Kind, attached, detached, fail, on_threads};
use crate::log::F64Array;
use crate::log::PyLog;
use crate::model::{PyModel, model_spec};
use biasctl::diagnose::FeatureTable;
use biasctl::{
    DiagnoseConfig, Diagnosis, DiscoverConfig, Drive, FitOptions, FittedModel, SequenceOptions,
    SimConfig, VerifyConfig,
};
use numpy::PyArray1;
use pyo3::prelude::*;
use std::sync::Arc;

/// `simulate`: a log of the simulated drive, the rows `biasctl simulate --out` writes.
#[pyfunction]
#[pyo3(signature = (sequence="random", n=None, span=None, seed=1, drive="paper1997", center=None, dwell_min=None, dwell_max=None, disable=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn simulate(
    py: Python<'_>,
    sequence: &str,
    n: Option<u64>,
    span: Option<f64>,
    seed: u64,
    drive: &str,
    center: Option<f64>,
    dwell_min: Option<f64>,
    dwell_max: Option<f64>,
    disable: Option<Vec<String>>,
) -> PyResult<PyLog> {
    let sequence = sequence.to_string();
    let drive = drive.to_string();
    detached(py, move || {
        let drive = if drive == "paper1997" {
            Drive::paper1997()
        } else {
            Drive::from_toml_file(std::path::Path::new(&drive)).map_err(fail(Kind::Base))?
        };
        let opts = SequenceOptions {
            n,
            span,
            center,
            dwell_min_s: dwell_min,
            dwell_max_s: dwell_max,
            ..SequenceOptions::default()
        };
        let disabled: Vec<String> = disable.unwrap_or_default();
        let disabled: Vec<&str> = disabled.iter().map(String::as_str).collect();
        let cfg =
            SimConfig::new(drive, &sequence, &opts, seed, &disabled).map_err(fail(Kind::Base))?;
        let log = biasctl::simulate_log(&cfg).map_err(fail(Kind::Base))?;
        Ok(PyLog::from_log(log))
    })
}

/// A diagnosis of a model on a log, with what its figure needs.
#[pyclass(frozen, module = "biasctl._biasctl", name = "Diagnosis")]
pub(crate) struct PyDiagnosis {
    inner: Diagnosis,
    json: String,
    model: Arc<FittedModel>,
    log: Arc<biasctl::Log>,
}

/// `Model.diagnose`: as `biasctl diagnose` with its defaults (verified unless `verify=False`).
#[pyfunction]
#[pyo3(signature = (model, log, verify=true, seed=1, alpha=0.01, permutations=199, folds=5, verify_folds=3, threads=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn diagnose(
    py: Python<'_>,
    model: &PyModel,
    log: &PyLog,
    verify: bool,
    seed: u64,
    alpha: f64,
    permutations: usize,
    folds: usize,
    verify_folds: usize,
    threads: Option<usize>,
) -> PyResult<PyDiagnosis> {
    let model = model.inner.clone();
    detached(py, || {
        let config = DiagnoseConfig {
            alpha,
            permutations,
            seed,
            folds,
            ..DiagnoseConfig::default()
        }
        .check()
        .map_err(fail(Kind::Base))?;
        let fit_opts = FitOptions {
            direction: model.direction.setting(),
            ..FitOptions::default()
        }
        .check()
        .map_err(fail(Kind::Fit))?;
        let verify_cfg = VerifyConfig {
            folds: verify_folds,
            fit: fit_opts,
            ..VerifyConfig::default()
        }
        .check()
        .map_err(fail(Kind::Base))?;
        let log = log.measured_for(&model)?;
        let log = log.as_ref();
        let d = on_threads(threads, || {
            if verify {
                biasctl::diagnose_verified(&model, log, &config, &verify_cfg)
            } else {
                biasctl::diagnose_model(&model, log, &config)
            }
            .map_err(fail(Kind::Base))
        })?;
        let json = d.to_json().map_err(fail(Kind::Base))?;
        Ok(PyDiagnosis {
            inner: d,
            json,
            model,
            log: Arc::new(log.clone()),
        })
    })
}

#[pymethods]
impl PyDiagnosis {
    /// The JSON `biasctl diagnose --json` prints.
    fn to_json(&self) -> String {
        self.json.clone()
    }

    /// The model's terms after the best verified edit (`None`: no edit verified).
    #[getter]
    fn best_edit(&self) -> Option<String> {
        self.inner
            .verification
            .as_ref()
            .and_then(|v| v.best())
            .map(|e| e.terms.clone())
    }

    /// The best verified edit in words (`add play:8`).
    #[getter]
    fn best_edit_text(&self) -> Option<String> {
        self.inner
            .verification
            .as_ref()
            .and_then(|v| v.best())
            .map(|e| e.edit.clone())
    }

    /// The residual figure the report draws (SVG): the residual against the `top` strongest
    /// features.
    #[pyo3(signature = (top=6))]
    fn svg(&self, py: Python<'_>, top: usize) -> PyResult<String> {
        let (model, log, d) = (&self.model, &self.log, &self.inner);
        detached(py, || {
            let opts = biasctl::plot::views::PanelOptions { top }
                .check()
                .map_err(fail(Kind::Base))?;
            let residual = biasctl::diagnose::replay_model(model, log)
                .map_err(fail(Kind::Model))?
                .residual;
            let table = FeatureTable::from_log(log);
            Ok(biasctl::plot::views::diagnose_panel(
                d, &table, &residual, &opts,
            ))
        })
    }

    /// `(feature values, residuals)` of the measured rows where `feature` is defined.
    fn feature_residuals<'py>(
        &self,
        py: Python<'py>,
        feature: &str,
    ) -> PyResult<(F64Array<'py>, F64Array<'py>)> {
        let (model, log) = (&self.model, &self.log);
        let (x, r) = detached(py, || {
            let residual = biasctl::diagnose::replay_model(model, log)
                .map_err(fail(Kind::Model))?
                .residual;
            let table = FeatureTable::from_log(log);
            let col = table.column(feature).ok_or_else(|| {
                Failure::new(Kind::Base, format!("no feature `{feature}` in this log"))
            })?;
            let (x, r): (Vec<f64>, Vec<f64>) = col
                .iter()
                .zip(&residual)
                .filter_map(|(v, r)| v.map(|v| (v, *r)))
                .unzip();
            Ok((x, r))
        })?;
        Ok((PyArray1::from_vec(py, x), PyArray1::from_vec(py, r)))
    }
}

/// `discover`: (the JSON `biasctl discover --json` prints, its text, the final model).
#[pyfunction]
#[pyo3(signature = (train, test=None, start="poly2", max_steps=8, alpha=0.01, seed=1, verify_folds=3, threads=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn discover(
    py: Python<'_>,
    train: &PyLog,
    test: Option<&PyLog>,
    start: &str,
    max_steps: usize,
    alpha: f64,
    seed: u64,
    verify_folds: usize,
    threads: Option<usize>,
) -> PyResult<(String, String, PyModel)> {
    // As `discover --start`: a preset, else a model file (its terms), else a term list.
    let start = attached(|| {
        if let Ok(s) = biasctl::ModelSpec::preset(start) {
            return Ok(s);
        }
        if start.ends_with(".json") || std::path::Path::new(start).is_file() {
            let m = FittedModel::load(std::path::Path::new(start)).map_err(fail(Kind::Model))?;
            return biasctl::diagnose::model_spec(&m).map_err(fail(Kind::Model));
        }
        model_spec(start)
    })?;
    detached(py, || {
        let config = DiscoverConfig {
            diagnose: DiagnoseConfig {
                alpha,
                seed,
                ..DiagnoseConfig::default()
            }
            .check()
            .map_err(fail(Kind::Base))?,
            verify: VerifyConfig {
                folds: verify_folds,
                ..VerifyConfig::default()
            }
            .check()
            .map_err(fail(Kind::Base))?,
            max_steps,
        }
        .check()
        .map_err(fail(Kind::Base))?;
        let train = train.measured()?;
        let test = match test {
            Some(t) => Some(t.measured()?),
            None => None,
        };
        let (d, model) = on_threads(threads, || {
            biasctl::discover(&start, train, test, &config).map_err(fail(Kind::Base))
        })?;
        let json = d.to_json().map_err(fail(Kind::Base))?;
        Ok((
            json,
            d.to_string(),
            PyModel {
                inner: Arc::new(model),
            },
        ))
    })
}

/// `ladder`: the JSON `biasctl ladder --json` prints.
#[pyfunction]
#[pyo3(signature = (train, test, terms, deadband=None, velocity_col=None, threads=None))]
pub(crate) fn ladder(
    py: Python<'_>,
    train: &PyLog,
    test: &PyLog,
    terms: &str,
    deadband: Option<f64>,
    velocity_col: Option<String>,
    threads: Option<usize>,
) -> PyResult<String> {
    let terms = attached(|| biasctl::ladder_terms(terms).map_err(fail(Kind::Model)))?;
    let opts = attached(|| crate::model::fit_options(deadband, velocity_col, None, None, None))?;
    detached(py, || {
        let (train, test) = (train.measured()?, test.measured()?);
        let l = on_threads(threads, || {
            biasctl::ladder_fit(train, test, &terms, &opts).map_err(fail(Kind::Base))
        })?;
        l.to_json().map_err(fail(Kind::Base))
    })
}
