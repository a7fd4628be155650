//! The fit's statistics of its residuals: the causal replay of the fitted model over the
//! training log ([`replay_residuals`]), or, where the adaptive terms come last and read nothing
//! but residuals ([`adaptive_tail`]), the static prediction of the others from the solve's
//! chunk starts ([`static_predictions_chunked`]) and a replay of the adaptive terms alone
//! ([`tail_stats`]); the standard deviation, RMS and R² of the residuals ([`set_statistics`]).

use super::design::{ChunkStart, offsets};
use crate::log::Log;
use crate::model::FittedModel;
use crate::model::data::FitError;
use crate::model::term::{Seek, Term};
use std::sync::Arc;

/// What [`replay_residuals`] returns: measured bias, residuals, position range.
type Residuals = (Vec<f64>, Vec<f64>, Option<[f64; 2]>);

/// The causal replay of `model` over `log` that the fit statistics need: the measured bias and
/// the residual of every measured row, and the range of their finite positions — what
/// [`FittedModel::predict_log`] gives in `measured`, `residual` and `range(positions)` (tested),
/// without holding its other columns (rows, positions, predictions, every term's contribution:
/// about 80 bytes per row).
fn replay_residuals(model: &FittedModel, log: &Log) -> Result<Residuals, FitError> {
    let m = log.measured_count();
    let (mut measured, mut residual) = (Vec::with_capacity(m), Vec::with_capacity(m));
    let mut range: Option<[f64; 2]> = None;
    model.replay_measured(log, crate::model::Feedback::EveryRow, |row, pred, _| {
        measured.push(row.measured);
        residual.push(row.measured - pred);
        let x = row.position;
        if x.is_finite() {
            range = Some(match range {
                None => [x, x],
                Some([lo, hi]) => [lo.min(x), hi.max(x)],
            });
        }
    })?;
    Ok((measured, residual, range))
}

/// Where the adaptive terms begin, if they all come after the others and read nothing but the
/// residuals ([`TermCaps::reads_only_residuals`](crate::model::TermCaps::reads_only_residuals); `terms.len()` when there are none): then the
/// fit's statistics replay only them ([`replay_tail`]) over the static prediction of the others
/// ([`static_predictions_chunked`]) instead of the whole model over the log.
pub(super) fn adaptive_tail(terms: &[Arc<dyn Term>]) -> Option<usize> {
    let first = terms
        .iter()
        .position(|t| t.caps().adaptive)
        .unwrap_or(terms.len());
    terms[first..]
        .iter()
        .all(|t| t.caps().adaptive && t.param_count() == 0 && t.caps().reads_only_residuals)
        .then_some(first)
}

/// What [`static_predictions_chunked`] gives per measured row, in log order.
pub(super) struct Statics<'l> {
    /// The prediction of the terms before the adaptive tail: per term, its basis times its
    /// coefficients plus its offset, summed in the order and arithmetic of
    /// `Predictor::evaluate`.
    pub(super) pred: Vec<f64>,
    /// The measured bias: the log's bias column itself where every row is measured (no copy).
    pub(super) measured: std::borrow::Cow<'l, [f64]>,
    /// `measured − pred` (for the adaptive terms' tuning; the fit frees it after that).
    pub(super) residual: Vec<f64>,
    /// The range of the measured rows' finite positions.
    pub(super) range: Option<[f64; 2]>,
}

/// The static predictions (`static_predictions`, the sequential replay the tests hold it to)
/// from [`solve_marking`](super::solve::solve_marking)'s chunk starts: each chunk of `per_chunk`
/// measured rows replayed from its [`ChunkStart`] on its own, the chunks in parallel on
/// rayon's pool (the same arithmetic per row as the one sequential replay, so the same bits;
/// the ranges of the chunks merged in log order by the same `min`/`max`; tested). `starts`
/// holds every term's state (of `terms`, the whole design); only those before `tail` are read.
pub(super) fn static_predictions_chunked<'l>(
    terms: &[Arc<dyn Term>],
    tail: usize,
    starts: Vec<ChunkStart<'_>>,
    per_chunk: usize,
    log: &'l Log,
    coef: &[f64],
) -> Statics<'l> {
    use rayon::prelude::*;
    let measured = log.measured_count();
    let (off, _) = offsets(terms);
    let widths: Vec<usize> = terms[..tail].iter().map(|t| t.param_count()).collect();
    let piecewise: Vec<bool> = terms[..tail]
        .iter()
        .map(|t| t.caps().piecewise_constant)
        .collect();
    let mut pred = vec![0.0; measured];
    // Every row measured: the bias column is the measured bias (no NaN in it), not copied.
    let all = (measured == log.len()).then(|| log.bias_raw());
    let mut meas = vec![0.0; if all.is_some() { 0 } else { measured }];
    let meas_parts: Vec<Option<&mut [f64]>> = match all {
        Some(_) => (0..measured.div_ceil(per_chunk)).map(|_| None).collect(),
        None => meas.chunks_mut(per_chunk).map(Some).collect(),
    };
    let mut residual = vec![0.0; measured];
    let ranges: Vec<(usize, Option<[f64; 2]>)> = pred
        .par_chunks_mut(per_chunk)
        .zip(meas_parts.into_par_iter())
        .zip(residual.par_chunks_mut(per_chunk))
        .zip(starts.into_par_iter())
        .map(|(((pred, mut meas), residual), start)| {
            let ChunkStart { replay, mut states } = start;
            states.truncate(tail);
            // Constant states add 0 and never change (`TermState::constant`): the same
            // `+ 0.0` without the call, and no update.
            let constant: Vec<bool> = states.iter().map(|s| s.constant()).collect();
            let moving: Vec<usize> = (0..states.len()).filter(|&k| !constant[k]).collect();
            let mut buf = vec![0.0; widths.iter().copied().max().unwrap_or(0)];
            // Per piecewise-constant term, its basis times its coefficients on the previous
            // row (if measured): kept where its state says the basis holds
            // (`TermState::same_basis`), the same bits without the basis.
            let mut last: Vec<Option<f64>> = vec![None; states.len()];
            let mut cov = Vec::new();
            let mut range: Option<[f64; 2]> = None;
            let mut n = 0;
            for (_, row, f) in replay {
                if n == pred.len() {
                    break;
                }
                let seek = Seek {
                    features: &f,
                    covariates: row.covariates.gather(&mut cov),
                };
                if let Some(y) = row.bias {
                    let mut total = 0.0;
                    for (k, s) in states.iter().enumerate() {
                        let dot = match last[k] {
                            Some(v) if s.same_basis(&seek) => v,
                            _ => {
                                let b = &mut buf[..widths[k]];
                                s.basis(&seek, b);
                                let c = &coef[off[k]..off[k] + widths[k]];
                                let v = b.iter().zip(c).map(|(b, c)| b * c).sum::<f64>();
                                if piecewise[k] {
                                    last[k] = Some(v);
                                }
                                v
                            }
                        };
                        let offset = if constant[k] { 0.0 } else { s.offset(&seek) };
                        total += dot + offset;
                    }
                    pred[n] = total;
                    if let Some(m) = meas.as_deref_mut() {
                        m[n] = y;
                    }
                    residual[n] = y - total;
                    n += 1;
                    let x = row.track;
                    if x.is_finite() {
                        range = Some(match range {
                            None => [x, x],
                            Some([lo, hi]) => [lo.min(x), hi.max(x)],
                        });
                    }
                } else {
                    last.fill(None);
                }
                for &k in &moving {
                    states[k].update(&seek, None);
                }
            }
            (n, range)
        })
        .collect();
    debug_assert!(ranges.iter().all(|&(n, _)| n > 0));
    let range = ranges
        .into_iter()
        .filter_map(|(_, r)| r)
        .reduce(|[lo, hi], [a, b]| [lo.min(a), hi.max(b)]);
    Statics {
        pred,
        measured: match all {
            Some(b) => std::borrow::Cow::Borrowed(b),
            None => std::borrow::Cow::Owned(meas),
        },
        residual,
        range,
    }
}

/// The residual of every measured row (measured bias `measured`) when the adaptive terms
/// `tail` (which read nothing but the residuals) follow the static prediction `statics` of the
/// others: each adds its offset to the running total and learns from the residual, as in
/// `Predictor::step_detailed` (what [`replay_residuals`] gives, bit for bit; tested).
fn replay_tail(
    tail: &[Arc<dyn Term>],
    log: &Log,
    statics: &[f64],
    measured: &[f64],
) -> Result<Vec<f64>, FitError> {
    let mut states = tail
        .iter()
        .map(|t| t.start(&log.schema.covariates))
        .collect::<Result<Vec<_>, _>>()?;
    // These states read no features and no covariates.
    let none = crate::history::SeekFeatures {
        seek_index: 0,
        time_s: 0.0,
        elapsed_s: 0.0,
        dwell_s: 0.0,
        source: 0.0,
        target: 0.0,
        seek_length: 0.0,
        direction: 0,
        direction_change: false,
        since_reversal: 0.0,
        rest_distance_od: None,
        rest_distance_id: None,
    };
    let seek = Seek {
        features: &none,
        covariates: &[],
    };
    let mut residual = Vec::with_capacity(measured.len());
    for (&s, &y) in statics.iter().zip(measured) {
        let mut total = s;
        for st in &states {
            total += crate::numeric::stats::sum_start() + st.offset(&seek);
        }
        let r = y - total;
        for st in &mut states {
            st.update(&seek, Some(r));
        }
        residual.push(r);
    }
    Ok(residual)
}

/// The fit's statistics of its residuals.
#[derive(Debug, Clone, Copy)]
struct ResidualStats {
    /// `stats::std_dev` (0 with fewer than two).
    std: f64,
    /// The sum of squares, summed in order.
    sse: f64,
    /// `stats::rms` (0 for none).
    rms: f64,
}

impl ResidualStats {
    /// The statistics of `residual`: one pass for its sum and sum of squares, one for the
    /// squares about the mean ([`ResidualStats::from_sums`]).
    fn of(residual: &[f64]) -> Self {
        let zero = crate::numeric::stats::sum_start();
        let (sum, sse) = residual
            .iter()
            .fold((zero, zero), |(s, q), &r| (s + r, q + r * r));
        Self::from_sums(residual, sum, sse)
    }

    /// The statistics of `residual` from its sum and its sum of squares, each added in row
    /// order from `stats::sum_start`: `std` as `stats::std_dev` (the mean `sum / n`, then the
    /// squares about it), `rms` as `stats::rms` (`sqrt(sse / n)`), the same bits (tested).
    fn from_sums(residual: &[f64], sum: f64, sse: f64) -> Self {
        let n = residual.len();
        let std = if n < 2 {
            0.0
        } else {
            let ss = crate::numeric::stats::sum_sq_about(residual, sum / n as f64);
            (ss / (n - 1) as f64).sqrt()
        };
        let rms = if n == 0 { 0.0 } else { (sse / n as f64).sqrt() };
        Self { std, sse, rms }
    }
}

/// [`ResidualStats::of`] the residuals [`replay_tail`] gives. Where the tail is one term of
/// exponential forgetting ([`Term::forgetting_factor`]: `drift`), its replay is one plain loop
/// that also sums the residuals and their squares as it goes, in the order and arithmetic of
/// the statistics' own passes ([`forgetting_tail_stats`]), which leaves one more pass (the
/// squares about the mean) instead of a replay of the term's state and four (the same bits;
/// tested against the replay and the three statistics).
fn tail_stats(
    tail: &[Arc<dyn Term>],
    log: &Log,
    statics: &[f64],
    measured: &[f64],
) -> Result<ResidualStats, FitError> {
    if let [t] = tail
        && let Some(alpha) = t.forgetting_factor()
    {
        return Ok(forgetting_tail_stats(alpha, statics, measured));
    }
    Ok(ResidualStats::of(&replay_tail(
        tail, log, statics, measured,
    )?))
}

/// [`tail_stats`] of a tail of one term of exponential forgetting with factor `alpha`: per
/// row the residual `r = y − (s + m)` and the update `m += alpha · r` (`drift`'s state, as
/// [`replay_tail`] runs it: its offset after the empty sum of no basis values), with the
/// running sums of `r` and `r²` that `stats::mean` and the sum of squares add in the same
/// order from the same start.
fn forgetting_tail_stats(alpha: f64, statics: &[f64], measured: &[f64]) -> ResidualStats {
    // Also the start of `replay_tail`'s empty basis sum.
    let zero = crate::numeric::stats::sum_start();
    let mut residual = Vec::with_capacity(statics.len());
    let (mut m, mut sum, mut sse) = (0.0, zero, zero);
    for (&s, &y) in statics.iter().zip(measured) {
        let r = y - (s + (zero + m));
        m += alpha * r;
        sum += r;
        sse += r * r;
        residual.push(r);
    }
    ResidualStats::from_sums(&residual, sum, sse)
}

/// Sets the residual statistics of the fit report of `model` (`residual_std`, `residual_rms`,
/// `r2`, `position_range`): from the replay of the adaptive terms from `tail` over the
/// static predictions `statics` where there are some ([`tail_stats`]), else from the causal
/// replay of the whole model over `log` ([`replay_residuals`]). `measured_stats`, where known,
/// is the measured bias's standard deviation and sum of squares about its mean. An error where
/// a statistic is not finite.
pub(super) fn set_statistics(
    model: &mut FittedModel,
    log: &Log,
    terms: &[Arc<dyn Term>],
    tail: Option<usize>,
    statics: Option<Statics<'_>>,
    measured_stats: Option<(f64, f64)>,
) -> Result<(), FitError> {
    let (measured_bias, stats, position_range) = match (tail, statics) {
        (Some(t), Some(st)) => {
            let stats = tail_stats(&terms[t..], log, &st.pred, &st.measured)?;
            (st.measured, stats, st.range)
        }
        _ => {
            let (m, r, range) = replay_residuals(model, log)?;
            (std::borrow::Cow::Owned(m), ResidualStats::of(&r), range)
        }
    };
    model.fit.position_range = position_range;
    let sst = match measured_stats {
        Some((_, sst)) => sst,
        None => crate::numeric::stats::sum_sq_about_mean(&measured_bias),
    };
    let ResidualStats {
        std: residual_std,
        sse,
        rms: residual_rms,
    } = stats;
    model.fit.residual_std = residual_std;
    model.fit.residual_rms = residual_rms;
    model.fit.r2 = if sst > 0.0 { 1.0 - sse / sst } else { 0.0 };
    let f = &model.fit;
    if ![f.residual_std, f.residual_rms, f.r2, sse, sst]
        .iter()
        .all(|v| v.is_finite())
    {
        let max_of = |v: &mut dyn Iterator<Item = f64>| v.fold(0.0_f64, |m, x| m.max(x.abs()));
        return Err(FitError::Overflow {
            file: log.schema.file.clone(),
            max_abs: max_of(&mut log.rows().filter_map(|r| r.bias)),
            max_pos: max_of(&mut log.rows().map(|r| r.track)),
        });
    }
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::fit::solve::{solve_chunk_rows, solve_marking};
    use crate::fit::{FitData, FitOptions, fit};
    use crate::model::ModelSpec;
    use crate::numeric::rng::SimRng;

    /// The measured bias of every measured row, in log order.
    fn measured_bias(log: &Log) -> impl Iterator<Item = f64> + '_ {
        log.bias_raw().iter().copied().filter(|b| !b.is_nan())
    }

    /// Per measured row, the prediction of `terms[..tail]` with coefficients `coef` (the whole
    /// design's), each term's basis times its coefficients plus its offset, summed term by term
    /// in the order and the arithmetic of `Predictor::evaluate` (so the same bits as the
    /// predictor's running total before term `tail`; tested); and the range of the measured rows'
    /// finite positions. One replay of the history: the reference for
    /// [`static_predictions_chunked`], which the fit uses.
    fn static_predictions(
        terms: &[Arc<dyn Term>],
        tail: usize,
        data: &FitData<'_>,
        coef: &[f64],
    ) -> Result<(Vec<f64>, Option<[f64; 2]>), FitError> {
        let head = &terms[..tail];
        let covs = &data.log().schema.covariates;
        let mut states = head
            .iter()
            .map(|t| t.start(covs))
            .collect::<Result<Vec<_>, _>>()?;
        let (off, _) = offsets(terms);
        let widths: Vec<usize> = head.iter().map(|t| t.param_count()).collect();
        let mut buf = vec![0.0; widths.iter().copied().max().unwrap_or(0)];
        let mut out = Vec::with_capacity(data.log().measured_count());
        let mut range: Option<[f64; 2]> = None;
        let mut cov = Vec::new();
        for (_, row, f) in data.replay_for(head) {
            let seek = Seek {
                features: &f,
                covariates: row.covariates.gather(&mut cov),
            };
            if row.bias.is_some() {
                let mut total = 0.0;
                for (k, s) in states.iter().enumerate() {
                    let b = &mut buf[..widths[k]];
                    s.basis(&seek, b);
                    let c = &coef[off[k]..off[k] + widths[k]];
                    total += b.iter().zip(c).map(|(b, c)| b * c).sum::<f64>() + s.offset(&seek);
                }
                out.push(total);
                let x = row.track;
                if x.is_finite() {
                    range = Some(match range {
                        None => [x, x],
                        Some([lo, hi]) => [lo.min(x), hi.max(x)],
                    });
                }
            }
            for s in &mut states {
                s.update(&seek, None);
            }
        }
        Ok((out, range))
    }

    /// Reference: `FittedModel::predict_log` (what `fit` replayed before) — the measured bias,
    /// the residuals and the position range must be the same bit for bit.
    #[test]
    fn fit_statistics_replay_equals_predict_log() {
        let log = crate::sim::random_log(3000, 4);
        for preset in ["calibration", "dahl"] {
            let spec = ModelSpec::preset(preset).unwrap();
            let model = fit(&spec, &log, &FitOptions::default().check().unwrap()).unwrap();
            let pred = model.predict_log(&log).unwrap();
            let (measured, residual, range) = replay_residuals(&model, &log).unwrap();
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&measured), bits(&pred.measured), "{preset}");
            assert_eq!(bits(&residual), bits(&pred.residual), "{preset}");
            let want = crate::numeric::stats::range(&pred.positions);
            assert_eq!(
                range.map(|r| r.map(f64::to_bits)),
                want.map(|r| r.map(f64::to_bits))
            );
            assert!(residual.len() > 2000, "{preset}");
        }
    }

    /// Reference: `FittedModel::predict_log` (the predictor replayed over the log). Where the
    /// adaptive terms come last and read only residuals, the fit's statistics come from the
    /// static prediction of the other terms and a replay of the adaptive ones alone: the
    /// measured bias, the residuals and the position range must be the predictor's bit for bit
    /// (drift last, no drift, a fixed drift; every fifth row unmeasured in the second log).
    /// Where drift is not last, or a term other than drift adapts, there is no such path.
    #[test]
    fn static_prediction_and_tail_replay_equal_predict_log() {
        let full = crate::sim::random_log(3000, 5);
        let mut gaps = full.clone();
        for i in (2..gaps.len()).step_by(5) {
            gaps.set_bias(i, None);
        }
        let opts = FitOptions::default().check().unwrap();
        let mut fast = 0;
        for log in [&full, &gaps] {
            for text in [
                "calibration",
                "dahl",
                "poly2,seek,drift:0.05",
                "poly2,direction,memory",
                "poly2,drift,seek",
            ] {
                let spec = ModelSpec::preset(text)
                    .or_else(|_| ModelSpec::parse(text))
                    .unwrap();
                let model = fit(&spec, log, &opts).unwrap();
                let terms: Vec<Arc<dyn Term>> =
                    model.terms.iter().map(|t| t.term.clone()).collect();
                let coef: Vec<f64> = model
                    .terms
                    .iter()
                    .flat_map(|t| t.coefficients.iter().copied())
                    .collect();
                let Some(tail) = adaptive_tail(&terms) else {
                    assert_eq!(text, "poly2,drift,seek");
                    continue;
                };
                fast += 1;
                let data = FitData::with_direction(log, &model.direction).unwrap();
                let (st, range) = static_predictions(&terms, tail, &data, &coef).unwrap();
                let measured: Vec<f64> = measured_bias(log).collect();
                let residual = replay_tail(&terms[tail..], log, &st, &measured).unwrap();
                let pred = model.predict_log(log).unwrap();
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&measured), bits(&pred.measured), "{text}");
                assert_eq!(bits(&residual), bits(&pred.residual), "{text}");
                let want = crate::numeric::stats::range(&pred.positions);
                assert_eq!(
                    range.map(|r| r.map(f64::to_bits)),
                    want.map(|r| r.map(f64::to_bits))
                );
            }
        }
        assert_eq!(fast, 8);
    }

    /// Reference: [`replay_tail`] of a `drift` term (its state replayed through the `Term`
    /// interface) and [`ResidualStats::of`] its residuals (`stats::std_dev`, the sum of
    /// squares, `stats::rms`). The one-loop replay of exponential forgetting gives the same
    /// three statistics bit for bit, for factors from 1e-4 to 1, on residuals with outliers
    /// and runs of zeros, and on 0, 1, 2 and many rows.
    #[test]
    fn forgetting_tail_stats_equal_the_replay_and_the_statistics() {
        let mut rng = SimRng::new(23);
        let log = crate::sim::random_log(10, 1);
        for (case, n) in [0usize, 1, 2, 3, 1000, 50_000].into_iter().enumerate() {
            let statics: Vec<f64> = (0..n).map(|i| 3.0 * (i as f64 * 1e-3).sin()).collect();
            let measured: Vec<f64> = (0..n)
                .map(|i| match i % 89 {
                    0 => 1e4 * rng.normal(),
                    1..=4 => 0.0,
                    _ => statics[i] + 0.5 + rng.normal(),
                })
                .collect();
            for alpha in [1e-4, 3.7e-3, 0.05, 0.5, 1.0] {
                let term: Arc<dyn Term> = Arc::new(crate::model::terms::drift::DriftTerm {
                    name: "drift".into(),
                    alpha,
                    fixed: false,
                });
                assert_eq!(term.forgetting_factor(), Some(alpha));
                let r =
                    replay_tail(std::slice::from_ref(&term), &log, &statics, &measured).unwrap();
                let want = [
                    crate::numeric::stats::std_dev(&r).unwrap_or(0.0),
                    r.iter().map(|e| e * e).sum(),
                    crate::numeric::stats::rms(&r).unwrap_or(0.0),
                ]
                .map(f64::to_bits);
                let got =
                    tail_stats(std::slice::from_ref(&term), &log, &statics, &measured).unwrap();
                let bits = |s: ResidualStats| [s.std, s.sse, s.rms].map(f64::to_bits);
                assert_eq!(bits(got), want, "case {case}, alpha {alpha}");
                assert_eq!(
                    bits(ResidualStats::of(&r)),
                    want,
                    "case {case}, alpha {alpha}"
                );
            }
        }
    }

    /// [`static_predictions_chunked`] against the one sequential replay of
    /// [`static_predictions`] (the slow reference) and the measured bias against
    /// [`measured_bias`]: bit for bit, on 1, 2 and 3 threads, on logs of several of
    /// [`solve`]'s chunks (every seventh row unmeasured, so chunks end before unmeasured rows
    /// and begin after them), for the head terms of three designs (with and without the
    /// history's direction and memory terms); the residual is the measured bias minus the
    /// prediction, the range the reference's, bit for bit.
    #[test]
    fn chunked_static_predictions_equal_the_sequential_replay() {
        let full = crate::sim::random_log(60_000, 11);
        let mut gaps = full.clone();
        for i in (3..gaps.len()).step_by(7) {
            gaps.set_bias(i, None);
        }
        // Every row measured (the bias column itself is the measured bias) for one design.
        for (log, designs) in [(&gaps, 3), (&full, 1)] {
            statics_case(log, &DESIGNS[..designs]);
        }
        // A Preisach term on a densely sampled log, with and without gaps: its relay states
        // hold over runs of rows, where the chunked replay keeps the previous row's product of
        // basis and coefficients (`TermState::same_basis`) and the reference computes it.
        let dense = dense_log(30_000);
        let mut gaps = dense.clone();
        for i in (3..gaps.len()).step_by(7) {
            gaps.set_bias(i, None);
        }
        for log in [&dense, &gaps] {
            statics_case(log, &["poly2,preisach:8"]);
        }
    }

    const DESIGNS: [&str; 3] = [
        "calibration",
        "poly2,seek,drift:0.05",
        "poly2,direction,memory",
    ];

    /// A smooth trajectory sampled at 1 kHz (relay states held over runs of tens of rows)
    /// through a play operator, a line and noise (the Preisach solve's test reads it too).
    pub(in crate::fit) fn dense_log(n: usize) -> Log {
        let mut rng = SimRng::new(5);
        let (mut x, mut v, mut target, mut z) = (0.0f64, 0.0f64, 1.0f64, 0.0f64);
        let mut text = String::from("time_s,track,bias\n");
        for k in 0..n {
            if (target - x).abs() < 1e-3 {
                target = 2.0 * rng.normal();
            }
            v = 0.99 * v + 0.01 * (target - x).signum() * 0.004;
            x += v;
            z = z.clamp(x - 0.4, x + 0.4);
            let y = 1.0 + 0.3 * x + 2.0 * (x - z) + 0.05 * rng.normal();
            text.push_str(&format!("{},{x},{y}\n", k as f64 * 1e-3));
        }
        Log::from_reader("dense.csv", text.as_bytes(), &Default::default()).unwrap()
    }

    fn statics_case(log: &Log, designs: &[&str]) {
        let opts = FitOptions::default().check().unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let measured: Vec<f64> = measured_bias(log).collect();
        for &text in designs {
            let spec = ModelSpec::preset(text)
                .or_else(|_| ModelSpec::parse(text))
                .unwrap();
            let model = fit(&spec, log, &opts).unwrap();
            let terms: Vec<Arc<dyn Term>> = model.terms.iter().map(|t| t.term.clone()).collect();
            let coef: Vec<f64> = model
                .terms
                .iter()
                .flat_map(|t| t.coefficients.iter().copied())
                .collect();
            let tail = adaptive_tail(&terms).unwrap();
            let data = FitData::with_direction(log, &model.direction).unwrap();
            let (want, want_range) = static_predictions(&terms, tail, &data, &coef).unwrap();
            let per_chunk = solve_chunk_rows(offsets(&terms).1);
            assert!(measured.len() > per_chunk, "{text}: two chunks at least");
            for threads in [1, 2, 3] {
                let got = crate::with_threads(threads, || {
                    let mut starts = Vec::new();
                    solve_marking(&terms, &data, &opts, Some(&mut starts)).unwrap();
                    assert_eq!(starts.len(), measured.len().div_ceil(per_chunk));
                    static_predictions_chunked(&terms, tail, starts, per_chunk, log, &coef)
                })
                .unwrap();
                assert_eq!(bits(&got.pred), bits(&want), "{text}, {threads} threads");
                assert_eq!(bits(&got.measured), bits(&measured), "{text}");
                let residual: Vec<f64> = measured.iter().zip(&want).map(|(y, s)| y - s).collect();
                assert_eq!(bits(&got.residual), bits(&residual), "{text}");
                assert_eq!(
                    got.range.map(|r| r.map(f64::to_bits)),
                    want_range.map(|r| r.map(f64::to_bits)),
                    "{text}"
                );
            }
        }
    }
}
