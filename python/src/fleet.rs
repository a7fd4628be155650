//! `biasctl.fleet`'s per-drive work: one drive's row of the fleet table and the outliers of a
//! table, through the library's `fleet` functions (the ones `biasctl fleet` runs).

use crate::errors::{Failure, Kind, attached, detached, fail, on_threads};
use crate::log::PyLog;
use crate::model::{fit_options, model_spec};
use biasctl::fleet::{self, DriveFit, ReadSettings};
use pyo3::prelude::*;

/// How a worker reads each path, from the Python read arguments.
fn read_settings(
    time_col: Option<String>,
    track_col: Option<String>,
    bias_col: Option<String>,
    delimiter: Option<String>,
    bias_unit: Option<String>,
    track_unit: Option<String>,
) -> Result<ReadSettings, Failure> {
    Ok(ReadSettings {
        columns: crate::log::column_map(time_col, track_col, bias_col, delimiter.as_deref())?,
        bias_unit,
        track_unit,
    })
}

/// A drive's row: source, rows, terms, [(name, value, se)], std, warnings, error.
type Row = (
    String,
    Option<usize>,
    String,
    Vec<(String, f64, Option<f64>)>,
    Option<f64>,
    Vec<String>,
    Option<String>,
);

fn row(r: DriveFit) -> Row {
    let params = r
        .params
        .into_iter()
        .map(|p| (p.name, p.value, p.se))
        .collect();
    (
        r.source, r.rows, r.terms, params, r.std, r.warnings, r.error,
    )
}

/// One drive's row of the fleet table: `path` read with the column and unit settings (as
/// `read_log`), or `log` already read; `source` names it. A drive that cannot be read or
/// fitted gives a row with its error, never an exception; bad settings raise.
#[pyfunction]
#[pyo3(signature = (source, model, path=None, log=None, time_col=None, track_col=None, bias_col=None, bias_unit=None, track_unit=None, delimiter=None, deadband=None, velocity_col=None, rank_tolerance=None, grid=None, refine=None, threads=None, keep_model=false))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit_drive(
    py: Python<'_>,
    source: String,
    model: &str,
    path: Option<std::path::PathBuf>,
    log: Option<&PyLog>,
    time_col: Option<String>,
    track_col: Option<String>,
    bias_col: Option<String>,
    bias_unit: Option<String>,
    track_unit: Option<String>,
    delimiter: Option<String>,
    deadband: Option<f64>,
    velocity_col: Option<String>,
    rank_tolerance: Option<f64>,
    grid: Option<usize>,
    refine: Option<usize>,
    threads: Option<usize>,
    keep_model: bool,
) -> PyResult<(Row, Option<String>)> {
    let spec = attached(|| model_spec(model))?;
    let opts = attached(|| fit_options(deadband, velocity_col, rank_tolerance, grid, refine))?;
    let read = read_settings(
        time_col, track_col, bias_col, delimiter, bias_unit, track_unit,
    )?;
    detached(py, || {
        on_threads(threads, || {
            let read_log: Result<std::borrow::Cow<'_, biasctl::Log>, String> = match (path, log) {
                (Some(p), None) => read
                    .read(&p)
                    .map(std::borrow::Cow::Owned)
                    .map_err(|e| biasctl::io::message(&e)),
                (None, Some(l)) => l
                    .measured()
                    .map(std::borrow::Cow::Borrowed)
                    .map_err(|e| e.message().to_string()),
                _ => {
                    return Err(Failure::new(
                        Kind::Base,
                        "internal: give a path or a log, not both",
                    ));
                }
            };
            let log = match read_log {
                Ok(log) => log,
                Err(m) => return Ok((row(DriveFit::failed(&source, &m)), None)),
            };
            if !keep_model {
                return Ok((row(fleet::fit_log(&source, &log, &spec, &opts)), None));
            }
            // The row of `fleet::fit_log`, with the model kept (for `score_many`).
            Ok(match biasctl::fit(&spec, &log, &opts) {
                Ok(m) => {
                    let json = m.to_json().map_err(fail(Kind::Model))?;
                    (row(DriveFit::fitted(&source, &m)), Some(json))
                }
                Err(e) => {
                    let e = fleet::DriveError::from(e);
                    (
                        row(DriveFit::failed(&source, &biasctl::io::message(&e))),
                        None,
                    )
                }
            })
        })
    })
}

/// One outlier: source, parameter, value, median, sigma, z, rule.
type OutlierRow = (String, String, f64, f64, f64, f64, String);

/// The outliers of a fleet table (its CSV text, as `fleet outliers --fits` reads it):
/// (source, parameter, value, median, sigma, z, rule) for every deviating parameter.
#[pyfunction]
#[pyo3(signature = (csv, threshold=fleet::OUTLIER_THRESHOLD, name="<fits>"))]
pub(crate) fn fleet_outliers(csv: &str, threshold: f64, name: &str) -> PyResult<Vec<OutlierRow>> {
    attached(|| {
        let rows = fleet::read_fits(csv, name).map_err(fail(Kind::Base))?;
        let found = fleet::outliers(&rows, threshold).map_err(fail(Kind::Base))?;
        Ok(found
            .into_iter()
            .map(|o| {
                let rule = o.rule.name().to_string();
                (o.source, o.parameter, o.value, o.median, o.sigma, o.z, rule)
            })
            .collect())
    })
}

/// The fleet table's CSV text of rows (as `fleet fit --out` writes it).
#[pyfunction]
pub(crate) fn fits_csv(rows: Vec<Row>) -> String {
    let rows: Vec<DriveFit> = rows
        .into_iter()
        .map(
            |(source, rows, terms, params, std, warnings, error)| DriveFit {
                source,
                rows,
                terms,
                params: params
                    .into_iter()
                    .map(|(name, value, se)| biasctl::model::Param { name, value, se })
                    .collect(),
                std,
                warnings,
                error,
            },
        )
        .collect();
    fleet::fits_csv(&rows)
}

/// One drive's screen as the pooled screen reads it: (source, error, names, tested, observed,
/// explained, p_value, permutations, null, suggested, alternatives).
type Screen = (
    String,
    Option<String>,
    Vec<String>,
    Vec<bool>,
    Vec<f64>,
    Vec<f64>,
    Vec<f64>,
    usize,
    Vec<f64>,
    Vec<Option<String>>,
    Vec<Vec<String>>,
);

/// The checked diagnosis settings of the fleet's screen.
fn diagnose_config(
    seed: u64,
    alpha: f64,
    permutations: usize,
    folds: usize,
) -> Result<biasctl::CheckedDiagnoseConfig, Failure> {
    biasctl::DiagnoseConfig {
        seed,
        alpha,
        permutations,
        folds,
        ..biasctl::DiagnoseConfig::default()
    }
    .check()
    .map_err(fail(Kind::Base))
}

/// One drive fitted and its residual screened (`fleet::screen_path` / `fleet::screen_drive`):
/// `path` read with the column and unit settings, or `log` already read.
#[pyfunction]
#[pyo3(signature = (source, model, path=None, log=None, seed=1, alpha=0.01, permutations=199, folds=5, time_col=None, track_col=None, bias_col=None, bias_unit=None, track_unit=None, delimiter=None, deadband=None, velocity_col=None, threads=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn screen_drive(
    py: Python<'_>,
    source: String,
    model: &str,
    path: Option<std::path::PathBuf>,
    log: Option<&PyLog>,
    seed: u64,
    alpha: f64,
    permutations: usize,
    folds: usize,
    time_col: Option<String>,
    track_col: Option<String>,
    bias_col: Option<String>,
    bias_unit: Option<String>,
    track_unit: Option<String>,
    delimiter: Option<String>,
    deadband: Option<f64>,
    velocity_col: Option<String>,
    threads: Option<usize>,
) -> PyResult<Screen> {
    let spec = attached(|| model_spec(model))?;
    let opts = attached(|| fit_options(deadband, velocity_col, None, None, None))?;
    let config = attached(|| diagnose_config(seed, alpha, permutations, folds))?;
    let read = read_settings(
        time_col, track_col, bias_col, delimiter, bias_unit, track_unit,
    )?;
    detached(py, || {
        on_threads(threads, || {
            let d = match (path, log) {
                (Some(p), None) => fleet::screen_path(&p, &read, &spec, &opts, &config),
                (None, Some(l)) => match l.measured() {
                    Ok(log) => fleet::screen_drive(&source, log, &spec, &opts, &config),
                    Err(e) => fleet::DriveScreen {
                        source: source.clone(),
                        screen: Err(e.message().to_string()),
                    },
                },
                _ => {
                    return Err(Failure::new(
                        Kind::Base,
                        "internal: give a path or a log, not both",
                    ));
                }
            };
            Ok(match d.screen {
                Ok(s) => (
                    source,
                    None,
                    s.names,
                    s.tested,
                    s.observed,
                    s.explained,
                    s.p_value,
                    s.permutations,
                    s.null,
                    s.suggested,
                    s.alternatives,
                ),
                Err(e) => (
                    source,
                    Some(e),
                    Vec::new(),
                    Vec::new(),
                    Vec::new(),
                    Vec::new(),
                    Vec::new(),
                    permutations,
                    Vec::new(),
                    Vec::new(),
                    Vec::new(),
                ),
            })
        })
    })
}

/// One drive's refits with one candidate term (`fleet::verify_drive`): (source, term, error,
/// (rows, sse_before, sse_after, gain, gain_within_folds, loss_gain, loss_se, z),
/// (verified_alone, reason_alone, edit, terms)).
type Refit = (
    String,
    String,
    Option<String>,
    (usize, f64, f64, f64, f64, f64, f64, f64),
    (bool, String, String, String),
);

/// The checked settings of the verification refits (`fit`: the fleet's fit options).
fn verify_config(
    folds: usize,
    fit: biasctl::fit::CheckedFitOptions,
) -> Result<biasctl::select::CheckedVerifyConfig, Failure> {
    biasctl::VerifyConfig {
        folds,
        fit,
        ..biasctl::VerifyConfig::default()
    }
    .check()
    .map_err(fail(Kind::Base))
}

fn refit_row(v: fleet::DriveVerification) -> Refit {
    match v.result {
        Ok(e) => {
            let reason = serde_json::to_value(e.reason_alone)
                .ok()
                .and_then(|r| r.as_str().map(str::to_string))
                .unwrap_or_default();
            (
                v.source,
                v.term,
                None,
                (
                    e.rows,
                    e.sse_before,
                    e.sse_after,
                    e.gain,
                    e.gain_within_folds,
                    e.loss_gain,
                    e.loss_se,
                    e.z,
                ),
                (e.verified_alone, reason, e.edit, e.terms),
            )
        }
        Err(m) => (
            v.source,
            v.term,
            Some(m),
            (0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
            (false, String::new(), String::new(), String::new()),
        ),
    }
}

fn drive_verification(r: Refit) -> Result<fleet::DriveVerification, Failure> {
    let (source, term, error, figures, verdict) = r;
    let (rows, sse_before, sse_after, gain, within, loss_gain, loss_se, z) = figures;
    let (verified_alone, reason, edit, terms) = verdict;
    let result = match error {
        Some(m) => Err(m),
        None => {
            let reason_alone: biasctl::diagnose::Reason = serde_json::from_value(
                serde_json::Value::String(reason.clone()),
            )
            .map_err(|_| Failure::new(Kind::Base, format!("internal: unknown rule `{reason}`")))?;
            Ok(fleet::DriveEdit {
                source: source.clone(),
                edit,
                terms,
                rows,
                sse_before,
                sse_after,
                gain,
                gain_within_folds: within,
                loss_gain,
                loss_se,
                z,
                verified_alone,
                reason_alone,
            })
        }
    };
    Ok(fleet::DriveVerification {
        source,
        term,
        result,
    })
}

/// One drive refitted without and with each of `terms` on the verification's folds
/// (`fleet::verify_path` / `fleet::verify_drive`): `path` read with the column and unit
/// settings, or `log` already read; one row per term. A drive that cannot be read or refitted
/// gives its message, never an exception; bad settings raise.
#[pyfunction]
#[pyo3(signature = (source, model, terms, path=None, log=None, verify_folds=3, time_col=None, track_col=None, bias_col=None, bias_unit=None, track_unit=None, delimiter=None, deadband=None, velocity_col=None, threads=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn verify_drive(
    py: Python<'_>,
    source: String,
    model: &str,
    terms: Vec<String>,
    path: Option<std::path::PathBuf>,
    log: Option<&PyLog>,
    verify_folds: usize,
    time_col: Option<String>,
    track_col: Option<String>,
    bias_col: Option<String>,
    bias_unit: Option<String>,
    track_unit: Option<String>,
    delimiter: Option<String>,
    deadband: Option<f64>,
    velocity_col: Option<String>,
    threads: Option<usize>,
) -> PyResult<Vec<Refit>> {
    let spec = attached(|| model_spec(model))?;
    let opts = attached(|| fit_options(deadband, velocity_col, None, None, None))?;
    let verify = attached(|| verify_config(verify_folds, opts))?;
    let min_effect = biasctl::DiagnoseConfig::default().min_effect;
    let read = read_settings(
        time_col, track_col, bias_col, delimiter, bias_unit, track_unit,
    )?;
    detached(py, || {
        on_threads(threads, || {
            let v = match (path, log) {
                (Some(p), None) => {
                    fleet::verify_path(&p, &read, &spec, &terms, min_effect, &verify)
                }
                (None, Some(l)) => match l.measured() {
                    Ok(log) => {
                        fleet::verify_drive(&source, log, &spec, &terms, min_effect, &verify)
                    }
                    Err(e) => terms
                        .iter()
                        .map(|t| fleet::DriveVerification {
                            source: source.clone(),
                            term: t.clone(),
                            result: Err(e.message().to_string()),
                        })
                        .collect(),
                },
                _ => {
                    return Err(Failure::new(
                        Kind::Base,
                        "internal: give a path or a log, not both",
                    ));
                }
            };
            // The source as the caller names it (a path's display may differ).
            Ok(v.into_iter()
                .map(|v| {
                    let mut row = refit_row(v);
                    row.0 = source.clone();
                    row
                })
                .collect())
        })
    })
}

/// The pooled screen of the drives' screens (`fleet::pool`), and with `refits` the drives'
/// refits with its suggestion pooled (`fleet::pool_verifications`), as the JSON `biasctl
/// fleet diagnose --json` prints.
#[pyfunction]
#[pyo3(signature = (screens, seed=1, alpha=0.01, permutations=199, folds=5, verify_folds=3, refits=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn pool_screens(
    py: Python<'_>,
    screens: Vec<Screen>,
    seed: u64,
    alpha: f64,
    permutations: usize,
    folds: usize,
    verify_folds: usize,
    refits: Option<Vec<Refit>>,
) -> PyResult<String> {
    let config = attached(|| diagnose_config(seed, alpha, permutations, folds))?;
    let verify = attached(|| verify_config(verify_folds, Default::default()))?;
    detached(py, || {
        let screens: Vec<fleet::DriveScreen> = screens
            .into_iter()
            .map(|s| fleet::DriveScreen {
                source: s.0,
                screen: match s.1 {
                    Some(e) => Err(e),
                    None => Ok(fleet::DriveStatistics {
                        names: s.2,
                        tested: s.3,
                        observed: s.4,
                        explained: s.5,
                        p_value: s.6,
                        permutations: s.7,
                        null: s.8,
                        suggested: s.9,
                        alternatives: s.10,
                    }),
                },
            })
            .collect();
        let mut d = fleet::pool(&screens, &config, &verify).map_err(fail(Kind::Base))?;
        if let Some(refits) = refits {
            let drives = refits
                .into_iter()
                .map(drive_verification)
                .collect::<Result<Vec<_>, _>>()?;
            fleet::pool_verifications(&mut d, &drives);
        }
        biasctl::io::to_string_pretty(&d).map_err(fail(Kind::Base))
    })
}
