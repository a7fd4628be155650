//! The fit's pipeline ([`fit_sharing`], behind [`fit`](fn@crate::fit::fit)): prepare the
//! terms, search the nonlinear parameters, solve, tune the causal offsets, assemble the model
//! and its statistics; taking what many refits of one log share ([`Refits`]) instead of
//! computing it again.

use super::assemble::{dropped_params, fit_report, fit_warnings, fitted_model, fitted_terms};
use super::design::{design_pass, offsets};
use super::options::CheckedFitOptions;
use super::search::{SearchMode, search_nonlinear};
use super::solve::{Solution, solve_chunk_rows, solve_marking};
use super::statistics::{Statics, adaptive_tail, set_statistics, static_predictions_chunked};
use crate::history::DirectionSource;
use crate::log::Log;
use crate::model::data::{FitData, FitError, STORED_FIXED_BYTES};
use crate::model::term::Term;
use crate::model::terms::intercept::InterceptTerm;
use crate::model::{FittedModel, ModelSpec};
use std::sync::Arc;

/// What many refits of one log's rows share (`diagnose`'s verification: every candidate on
/// every fold, the folds differing in which biases are blanked): the log's sampling and its
/// replayed features (a history reads times, positions and covariates, never the bias), and
/// the fixed-block budget of their variable-projection searches (several refits run at once).
#[derive(Debug, Clone)]
pub(crate) struct Refits {
    /// [`crate::history::log_sampling`] of the log.
    pub sampling: Option<crate::history::Sampling>,
    /// The log's history replayed with this direction source.
    pub history: Option<(
        crate::history::DirectionSource,
        crate::model::data::SharedHistory,
    )>,
    /// [`FitData::with_fixed_budget`].
    pub fixed_budget: usize,
    /// Whether the fitted model serves only its out-of-sample residuals (a verification's
    /// refit): then the standard errors of the searched nonlinear parameters are not computed
    /// (three full solves each, for the curvature of the RSS; `None` in the model's report),
    /// and a search over a parameter's whole interval refines the grid's best cell by
    /// [`crate::numeric::search::zoom_min_batched`] to [`super::search::WARM_TOLERANCE`] of the
    /// interval instead of 40 golden-section steps (about 4 batches of the projection's replay
    /// instead of 13; the value found moves within that tolerance).
    pub residuals_only: bool,
}

impl Default for Refits {
    /// Nothing shared, the default budget: [`fit`](fn@crate::fit::fit).
    fn default() -> Self {
        Self {
            sampling: None,
            history: None,
            fixed_budget: STORED_FIXED_BYTES,
            residuals_only: false,
        }
    }
}

/// [`fit`](fn@crate::fit::fit), taking what `shared` holds instead of computing it again: the
/// same model bit for bit (tested in `diagnose::tests_verify`). `warm` holds values of searched
/// nonlinear parameters found before, by term name (the value in the search coordinate,
/// [`crate::model::term::Nonlinear::value`]): a term of that name starts there and is searched
/// near it, to [`super::search::WARM_TOLERANCE`] of its interval, instead of over its whole
/// interval (`diagnose`'s verification: the values the refit of the model as it is found on the
/// same fold, for each edited model's refit of that fold). Empty: the cold search of `fit`.
pub(crate) fn fit_sharing(
    spec: &ModelSpec,
    log: &Log,
    opts: &CheckedFitOptions,
    shared: &Refits,
    warm: &[(String, f64)],
) -> Result<FittedModel, FitError> {
    let Prepared {
        mut data,
        mut terms,
        direction,
        reversal_warning,
        p,
        measured,
    } = prepare(spec, log, opts, shared)?;
    let nonlinear = search_nonlinear(
        &mut terms,
        &data,
        opts,
        (measured, p),
        SearchMode {
            se: !shared.residuals_only,
            zoom: shared.residuals_only,
        },
        warm,
    );

    // The prediction of every term before the adaptive ones, per measured row, where those
    // read nothing but the residuals (`drift`): then they are replayed over it below. The
    // solve marks where its chunks begin in its replay; the static predictions replay the
    // chunks from there in parallel.
    let tail = adaptive_tail(&terms);
    let mut starts = Vec::new();
    let sol = solve_marking(&terms, &data, opts, tail.map(|_| &mut starts))?;
    let mut statics = tail.map(|t| {
        static_predictions_chunked(
            &terms,
            t,
            std::mem::take(&mut starts),
            solve_chunk_rows(p),
            log,
            &sol.coef,
        )
    });
    let measured_stats = tune_offsets(&mut terms, &data, &sol, statics.as_ref())?;

    // The static residuals served the tuning alone: freed before the tail's replay, as are
    // the history columns (no replay of the history follows).
    if let Some(st) = statics.as_mut() {
        st.residual = Vec::new();
    }
    data.forget_history_columns();
    let (fitted, mut warnings) = fitted_terms(&terms, &sol, &nonlinear.se, p);
    let dropped = dropped_params(&terms, &sol);
    let bias_std = match measured_stats {
        Some((std, _)) => std,
        None => data.measured_bias_std(),
    };
    warnings.extend(fit_warnings(
        &terms,
        &sol,
        &dropped,
        nonlinear.converged,
        bias_std,
    ));
    warnings.extend(reversal_warning);
    let report = fit_report(&sol, dropped, &nonlinear);
    let mut model = fitted_model(spec, log, &terms, fitted, warnings, direction, report)?;
    set_statistics(&mut model, log, &terms, tail, statics, measured_stats)?;
    Ok(model)
}

/// What [`prepare`] gives the rest of the fit.
struct Prepared<'a> {
    /// The training data, reading the shared history where there is one.
    data: FitData<'a>,
    /// The prepared terms (an `intercept` first unless a term spans a constant).
    terms: Vec<Arc<dyn Term>>,
    /// How the direction of motion is read, resolved on the log.
    direction: DirectionSource,
    /// The direction's warning about its count of reversals, if any.
    reversal_warning: Option<String>,
    /// Design columns.
    p: usize,
    /// Measured rows.
    measured: usize,
}

/// The fit's first step: the direction resolved (on `shared`'s sampling where it holds one)
/// and the training data (reading `shared`'s history where it is this direction's), every
/// term prepared on it (knots, centring, …), an `intercept` added unless a term spans a
/// constant; an error where a term cannot start or the log has too few measured rows.
fn prepare<'a>(
    spec: &ModelSpec,
    log: &'a Log,
    opts: &CheckedFitOptions,
    shared: &Refits,
) -> Result<Prepared<'a>, FitError> {
    let sampling = shared
        .sampling
        .unwrap_or_else(|| crate::history::log_sampling(log));
    let direction = opts.direction.resolve_with(log, &sampling)?;
    let mut data = FitData::with_direction(log, &direction)?.with_fixed_budget(shared.fixed_budget);
    if let Some((d, h)) = &shared.history
        && *d == direction
    {
        data = data.sharing(h);
    }
    let reversals = reversal_count(&direction, &sampling, &data);
    let reversal_warning = direction.reversal_warning(reversals, log.len(), &sampling);
    // Each term prepares on its own replays (knots, centring, …), so they run in parallel;
    // the first error in spec order is the one reported, whatever the thread count.
    let mut terms = {
        use rayon::prelude::*;
        spec.terms
            .par_iter()
            .map(|t| t.prepare(&data))
            .collect::<Vec<_>>()
            .into_iter()
            .collect::<Result<Vec<_>, _>>()?
    };
    if !terms.iter().any(|t| t.caps().provides_intercept) {
        terms.insert(0, Arc::new(InterceptTerm));
    }
    if !terms.iter().any(|t| t.caps().reads_history) {
        // No later replay steps the history (`dahl`): the columns its preparation kept go.
        data.forget_history_columns();
    }
    let file = log.schema.file.clone();
    for t in &terms {
        t.start(&log.schema.covariates)?;
    }
    let (_, p) = offsets(&terms);
    let measured = log.measured_count();
    let needed = p + 2;
    if measured < needed {
        return Err(FitError::TooShort {
            file,
            measured,
            params: p,
            needed,
            spec: spec.to_string(),
        });
    }
    Ok(Prepared {
        data,
        terms,
        direction,
        reversal_warning,
        p,
        measured,
    })
}

/// Tunes the causal offsets (`drift`) on the static residuals (`statics`, where the adaptive
/// terms come last; else on the residuals of a design pass with the solution `sol`). Beside the
/// tuning (a sequential pass per zoom), the measured bias's statistics, which need no tuned
/// term (from the static predictions' copy of it: `FitData::measured_bias_std` and
/// `sum_sq_about_mean` of the same values in the same order, so the same bits; `None` where
/// there is none).
fn tune_offsets(
    terms: &mut [Arc<dyn Term>],
    data: &FitData<'_>,
    sol: &Solution,
    statics: Option<&Statics<'_>>,
) -> Result<Option<(f64, f64)>, FitError> {
    let tune = |terms: &mut [Arc<dyn Term>]| -> Result<(), FitError> {
        if terms.iter().any(|t| t.param_count() == 0) {
            let design_residuals;
            let residuals: &[f64] = match statics {
                Some(st) => &st.residual,
                None => {
                    let mut residuals = Vec::with_capacity(sol.n);
                    design_pass(terms, data, |x, y| {
                        residuals
                            .push(y - x.iter().zip(&sol.coef).map(|(a, b)| a * b).sum::<f64>());
                    })?;
                    design_residuals = residuals;
                    &design_residuals
                }
            };
            for t in terms.iter_mut() {
                if let Some(tuned) = t.tune_on_residuals(residuals) {
                    *t = tuned;
                }
            }
        }
        Ok(())
    };
    let (tuned, measured_stats) = match statics {
        Some(st) => {
            let (tuned, stats) = rayon::join(
                || tune(terms),
                || {
                    let b = &st.measured;
                    (
                        crate::numeric::stats::std_dev(b).unwrap_or(0.0),
                        crate::numeric::stats::sum_sq_about_mean(b),
                    )
                },
            );
            (tuned, Some(stats))
        }
        None => (tune(terms), None),
    };
    tuned?;
    Ok(measured_stats)
}

/// Direction changes in the fit's replay of the history. `sampling` has counted them already
/// (the same tracker over the same positions) when the direction comes from position steps
/// with its deadband: then no replay is needed (tested equal to [`FitData::reversals`]).
fn reversal_count(
    direction: &crate::history::DirectionSource,
    sampling: &crate::history::Sampling,
    data: &FitData<'_>,
) -> usize {
    use crate::history::DirectionSource;
    match direction {
        DirectionSource::Steps => sampling.raw_reversals,
        DirectionSource::Deadband { deadband }
            if deadband.to_bits() == sampling.deadband.to_bits() =>
        {
            sampling.reversals
        }
        _ => data.reversals(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{FitOptions, fit};
    use crate::numeric::rng::SimRng;

    /// Reference: [`FitData::reversals`], the count of the fit's own replay. The count taken
    /// from `sampling` must equal it on a seek log (raw steps) and on a dense noisy series (the
    /// estimated deadband), and an explicit deadband still replays.
    #[test]
    fn reversal_count_from_sampling_equals_the_replays() {
        use crate::history::DirectionSetting;
        let seeks = crate::sim::random_log(3000, 8);
        let mut rng = SimRng::new(4);
        let mut text = String::from("time_s,track,bias\n");
        for i in 0..4000 {
            let t = i as f64 * 1e-3;
            let x = 100.0 * (t * 7.0).sin() + 0.3 * rng.normal();
            text += &format!("{t},{x},{}\n", rng.normal());
        }
        let dense = Log::from_reader("d.csv", text.as_bytes(), &Default::default()).unwrap();
        let mut checked = 0;
        for log in [&seeks, &dense] {
            let sampling = crate::history::log_sampling(log);
            for setting in [
                DirectionSetting::Auto,
                DirectionSetting::Deadband(0.0),
                DirectionSetting::Deadband(0.5),
            ] {
                let direction = setting.resolve_with(log, &sampling).unwrap();
                let data = FitData::with_direction(log, &direction).unwrap();
                let want = data.reversals();
                assert_eq!(
                    reversal_count(&direction, &sampling, &data),
                    want,
                    "{setting:?}"
                );
                checked += usize::from(want >= 5);
            }
        }
        assert!(crate::history::log_sampling(&dense).deadband > 0.0);
        assert_eq!(checked, 6);
    }

    /// Reference: the same fit with the history stepped on every replay
    /// (`FitData`'s `STEP_HISTORY`, the path of a log of any length before the history
    /// columns). On a log longer than `FEATURE_CACHE_ROWS` (so the memory knots' replay builds
    /// the columns and the solve and the chunked static predictions read them), with a
    /// deadband direction source, the `calibration` fit gives the same model file byte for
    /// byte on 1, 2 and 3 threads; `dahl`, whose preparation's one full replay builds no
    /// columns, too.
    #[test]
    fn fit_reading_history_columns_equals_the_stepped_fit() {
        use crate::model::data::tests::{STEP_HISTORY, STEP_LOCK};
        use std::sync::atomic::Ordering;
        let _only = STEP_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        let log =
            crate::sim::random_log(crate::model::data::FEATURE_CACHE_ROWS as u64 + 40_000, 21);
        let opts = FitOptions {
            direction: crate::history::DirectionSetting::Deadband(3.0),
            ..FitOptions::default()
        }
        .check()
        .unwrap();
        for preset in ["calibration", "dahl"] {
            let spec = ModelSpec::preset(preset).unwrap();
            let json = |m: &FittedModel| m.to_json().unwrap();
            STEP_HISTORY.store(true, Ordering::Relaxed);
            let want = crate::with_threads(2, || fit(&spec, &log, &opts))
                .unwrap()
                .unwrap();
            STEP_HISTORY.store(false, Ordering::Relaxed);
            let threads: &[usize] = if preset == "dahl" { &[2] } else { &[1, 2, 3] };
            for &t in threads {
                let got = crate::with_threads(t, || fit(&spec, &log, &opts))
                    .unwrap()
                    .unwrap();
                assert_eq!(json(&got), json(&want), "{preset}, {t} threads");
            }
        }
    }

    #[test]
    fn a_one_row_log_is_refused_in_the_singular() {
        let text = "time_s,track,bias\n0,5,1\n";
        let log = Log::from_reader("one.csv", text.as_bytes(), &Default::default()).unwrap();
        let spec = ModelSpec::preset("calibration").unwrap();
        let e = fit(&spec, &log, &CheckedFitOptions::default()).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("one.csv: 1 measured row, but"), "{msg}");
    }
}
