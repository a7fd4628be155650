//! Figures of library results: a fitted model's curves over a log, prediction errors, the Dahl
//! loop, a diagnosis, a ladder and a settle analysis, each turned into the data of a
//! [`super::figures`] builder. This is the one place in [`crate::plot`] that knows the model,
//! diagnose and settle types; the `plot` command and the report both draw through it.
//!
//! ```
//! use biasctl::{select::Ladder, select::LadderStep};
//! use biasctl::plot::views;
//! let l = Ladder { steps: vec![
//!     LadderStep { terms: vec!["poly2".into()], std: 20.0, reduction: 0.0,
//!         free_run_std: None, warnings: vec![] },
//!     LadderStep { terms: vec!["poly2".into(), "direction".into()], std: 10.0, reduction: 0.5,
//!         free_run_std: None, warnings: vec![] },
//! ] };
//! let svg = views::ladder(&l, &biasctl::Units::default());
//! assert!(svg.contains("+ direction") && svg.contains("error std (counts)"));
//! ```

use super::figures::{
    self, DahlLoop, FeatureResiduals, ModelErrors, ResidualBin, SettleBounds, SettleResponses,
};
use super::from_log;
use crate::control::settle::SettleReport;
use crate::diagnose::{Diagnosis, FeatureTable};
use crate::log::{Log, LogError, Units};
use crate::model::{FittedModel, ModelError, Prediction, Predictor};
use crate::select::Ladder;

/// Why a view of a fitted model could not be drawn.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ViewError {
    /// A log could not be read.
    #[error("reading the log")]
    Log(#[from] LogError),
    /// The model could not be replayed (for example a covariate it needs is missing).
    #[error("replaying the model")]
    Model(#[from] ModelError),
    /// A plot setting is out of range ([`PanelOptions::check`]).
    #[error("{field} {message}")]
    InvalidConfig {
        /// The setting.
        field: crate::field::Field,
        /// The value, what is wrong and what is allowed.
        message: String,
    },
}

/// Settings of [`diagnose_panel`], unchecked: [`PanelOptions::check`] makes the
/// [`CheckedPanelOptions`] it requires.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PanelOptions {
    /// How many of the strongest usable features get a panel (at least 1; default 6).
    pub top: usize,
}

/// The default [`PanelOptions::top`] (also the report's diagnosis table and panel).
pub const DEFAULT_TOP: usize = 6;

impl Default for PanelOptions {
    fn default() -> Self {
        PanelOptions { top: DEFAULT_TOP }
    }
}

impl PanelOptions {
    /// Checks every setting: `top` at least 1 (a panel of no feature shows nothing).
    pub fn check(self) -> Result<CheckedPanelOptions, ViewError> {
        if self.top == 0 {
            return Err(ViewError::InvalidConfig {
                field: crate::field::Field::PanelTop,
                message: "0: give at least 1".into(),
            });
        }
        Ok(CheckedPanelOptions(self))
    }
}

checked_settings! {
    /// Settings that passed [`PanelOptions::check`]; read them through `Deref`. `Default` is the
    /// checked default.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
    pub struct CheckedPanelOptions(PanelOptions);
}

/// A curve of `(position, bias)` points.
pub type Curve = Vec<(f64, f64)>;

/// Points on each fitted curve of [`model_curves`].
pub const CURVE_POINTS: usize = 41;

/// The model's inbound and outbound curves over the log's measured track range, the way
/// Table I measures them, from the model's own state at the end of the log: the log is replayed
/// causally with its measurements (so adaptive terms such as `drift` reach the level the data
/// hold them at), then, for each of [`CURVE_POINTS`] targets and from a copy of that state, an
/// unmeasured seek one full data span above the highest measured track, one a span below the
/// lowest (crossing every earlier rest position), and the target (inbound curve; the outbound one
/// visits the far ends in the other order). Unmeasured seeks leave adaptive terms frozen.
/// Covariate columns are held at their mean over the log; each seek takes 0.2 s after the log's
/// last time. Returns `(inbound, outbound)` as `(position, bias)` in position order, in the log's
/// units; both empty when the log has no measured row.
pub fn model_curves(model: &FittedModel, log: &Log) -> Result<(Curve, Curve), ViewError> {
    let Some([lo, hi]) = crate::numeric::stats::range(&log.measured_positions()) else {
        return Ok((Vec::new(), Vec::new()));
    };
    model.check_log(log)?;
    let span = (hi - lo).max(f64::EPSILON);
    let s = &log.schema;
    let means: Vec<f64> = (0..s.covariates.len())
        .map(|k| {
            let v: Vec<f64> = log
                .rows()
                .filter_map(|r| r.covariates.get(k))
                .filter(|v| v.is_finite())
                .collect();
            crate::numeric::stats::mean(&v).unwrap_or(0.0)
        })
        .collect();
    let mut replayed = Predictor::new(model, &s.covariates)?;
    let mut cov = Vec::new();
    for r in log.rows() {
        replayed.step(r.time_s, r.track, r.covariates.gather(&mut cov), r.bias)?;
    }
    let t_end = log.last().map_or(0.0, |r| r.time_s);
    let curve_point = |first: f64, second: f64, x: f64| {
        let mut p = replayed.clone();
        p.step(t_end + CURVE_DWELL_S, first, &means, None)?;
        p.step(t_end + 2.0 * CURVE_DWELL_S, second, &means, None)?;
        p.peek(t_end + 3.0 * CURVE_DWELL_S, x, &means)
    };
    let (below, above) = (lo - span, hi + span);
    let mut inbound = Vec::with_capacity(CURVE_POINTS);
    let mut outbound = Vec::with_capacity(CURVE_POINTS);
    for i in 0..CURVE_POINTS {
        let x = lo + (hi - lo) * i as f64 / (CURVE_POINTS - 1) as f64;
        let (a, b) = (curve_point(above, below, x)?, curve_point(below, above, x)?);
        if a.is_finite() && b.is_finite() {
            inbound.push((x, a));
            outbound.push((x, b));
        }
    }
    Ok((inbound, outbound))
}

/// Time at each track of the seeks that draw [`model_curves`], s.
pub const CURVE_DWELL_S: f64 = 0.2;

/// Fig. 3 of a log with the model's curves ([`model_curves`]) when a model is given.
pub fn position(log: &Log, model: Option<&FittedModel>) -> Result<String, ViewError> {
    let (inbound, outbound) = match model {
        Some(m) => model_curves(m, log)?,
        None => (Vec::new(), Vec::new()),
    };
    Ok(from_log::bias_vs_position_with_fit(log, inbound, outbound))
}

/// Figs. 10/11: each named prediction's error vs position and its histogram, side by side;
/// `units` are the log's the predictions replayed ([`crate::log::LogSchema::units`]).
pub fn errors(predictions: &[(&str, &Prediction)], units: &Units) -> String {
    let models: Vec<ModelErrors> = predictions
        .iter()
        .map(|(name, p)| ModelErrors {
            name: name.to_string(),
            position: p.positions.clone(),
            error: p.residual.clone(),
        })
        .collect();
    figures::prediction_errors(&models, units)
}

/// Figs. 13/14: measured `(position, bias)` in seek order and the prediction of the model named
/// `model` as a line, in the replayed log's `units`.
pub fn dahl_loop(p: &Prediction, units: &Units, model: &str) -> String {
    figures::dahl_loop(&DahlLoop {
        measured: p
            .positions
            .iter()
            .copied()
            .zip(p.measured.iter().copied())
            .collect(),
        predicted: p
            .positions
            .iter()
            .copied()
            .zip(p.predicted.iter().copied())
            .collect(),
        units: units.clone(),
        model: model.to_string(),
    })
}

/// The unit of a candidate feature, for an axis label: position-like features are in
/// `units.position`.
pub fn feature_unit(name: &str, units: &Units) -> String {
    match name {
        "position" | "seek_length" | "seek_abs" | "since_reversal" | "rest_distance_od"
        | "rest_distance_id" => units.position.clone(),
        "direction" => "+1 inbound, −1 outbound".into(),
        "direction_change" => "1 = reversal".into(),
        "dwell_s" | "elapsed_s" => "s".into(),
        "seek_index" => "seeks".into(),
        _ => "column units".into(),
    }
}

/// The diagnose panel: the residual against each of the `opts.top` strongest usable features of `d`
/// (binned mean ± standard error, marker size by bin count; raw residuals faint behind, taken
/// from `table` and `residuals`, the ones `d` was computed from). The note gives the
/// out-of-sample explained variance and the family-wise p-value. Axes are in the diagnosis'
/// units ([`Diagnosis::units`]).
pub fn diagnose_panel(
    d: &Diagnosis,
    table: &FeatureTable,
    residuals: &[f64],
    opts: &CheckedPanelOptions,
) -> String {
    let features: Vec<FeatureResiduals> = d
        .features
        .iter()
        .filter(|f| f.curve.iter().any(|b| b.centre.is_some()))
        .take(opts.top)
        .map(|f| {
            let raw = table
                .column(&f.name)
                .map(|c| {
                    c.iter()
                        .zip(residuals)
                        .filter_map(|(v, r)| v.map(|v| (v, *r)))
                        .collect()
                })
                .unwrap_or_default();
            let bins = f
                .curve
                .iter()
                .filter_map(|b| {
                    b.centre.map(|c| ResidualBin {
                        center: c,
                        mean: b.mean,
                        spread: b.std / (b.count.max(1) as f64).sqrt(),
                        count: b.count,
                    })
                })
                .collect();
            FeatureResiduals {
                feature: f.name.clone(),
                unit: feature_unit(&f.name, &d.units),
                raw,
                bins,
                note: format!(
                    "explains {:.0} %, p = {}",
                    100.0 * f.explained,
                    super::svg::fmt_num(f.p_value)
                ),
            }
        })
        .collect();
    figures::diagnose_panel(&features, &d.units)
}

/// The ladder's bars: the first step's terms, then `+ term` for each added term; the error std
/// is in `units.bias` (the test log's).
pub fn ladder(l: &Ladder, units: &Units) -> String {
    let mut previous = None;
    let steps: Vec<figures::LadderStep> = l
        .steps
        .iter()
        .map(|s| {
            let term = match previous {
                None => s.terms.join(" + "),
                Some(prev) => format!("+ {}", s.added_since(prev).join(" + ")),
            };
            previous = Some(s);
            figures::LadderStep {
                term,
                error_std: s.std,
            }
        })
        .collect();
    figures::ladder(&steps, units)
}

/// Plain-words name of a settle response (`zero_ff` → "zero feedforward").
pub fn choice_name(name: &str) -> &str {
    match name {
        "zero_ff" => "zero feedforward",
        "optimal" => "optimal (midpoint)",
        "paper_robust" => "paper's robust",
        "robust" => "worst-case robust",
        other => other,
    }
}

/// Samples of Fig. 15 worth drawing: up to the first sample after k* where the running bounds
/// leave ten times the scale of the chosen start values (they grow without limit towards the
/// end of the horizon, where the integrator's start no longer moves e(k)), and at least 2·k*.
pub fn bounds_extent(r: &SettleReport) -> usize {
    let b = &r.bounds;
    let n = b.upper_min().len();
    let Some(k_star) = r.k_star else { return n };
    let mut scale = r
        .responses
        .iter()
        .map(|x| x.ff.abs())
        .fold(0.0f64, f64::max);
    if let Some([lo, hi]) = r.ff_interval {
        scale = scale.max(lo.abs()).max(hi.abs());
    }
    if !(scale.is_finite() && scale > 0.0) {
        return n;
    }
    let leaves = |k: usize| {
        let m = b.upper_min()[k].abs().max(b.lower_max()[k].abs());
        m.is_nan() || m > 10.0 * scale
    };
    (k_star..n)
        .find(|&k| leaves(k))
        .map_or(n, |k| k.max(2 * k_star).min(n))
}

/// Fig. 15 of a settle analysis: bounds, running bounds, every chosen start value (zero
/// feedforward's 0 included), k*; drawn over [`bounds_extent`] samples.
pub fn settle_bounds(r: &SettleReport) -> String {
    let b = &r.bounds;
    let n = bounds_extent(r);
    figures::fig15_settle_bounds(&SettleBounds {
        sample_period_ms: r.ts_s * 1000.0,
        upper: b.upper()[..n].to_vec(),
        lower: b.lower()[..n].to_vec(),
        upper_running: b.upper_min()[..n].to_vec(),
        lower_running: b.lower_max()[..n].to_vec(),
        choices: r
            .responses
            .iter()
            .map(|x| (choice_name(x.name).to_string(), x.ff))
            .collect(),
        settle_ms: r.optimal_settle_ms,
        unit: "µm·samples".into(),
    })
}

/// Fig. 16 of a settle analysis: the position error of every start-value choice.
pub fn settle_responses(r: &SettleReport) -> String {
    let window = crate::control::settle::Window::new(r.window_um, r.hold).ok();
    figures::fig16_responses(&SettleResponses {
        sample_period_ms: r.ts_s * 1000.0,
        delta_um: r.window_um,
        responses: r
            .responses
            .iter()
            .map(|x| figures::Response {
                name: choice_name(x.name).to_string(),
                error_um: x.e_um.clone(),
                settle_ms: window
                    .as_ref()
                    .and_then(|w| crate::control::settle::settle_index(&x.e_um, w))
                    .map(|k| crate::control::settle::settle_ms(k, r.ts_s)),
            })
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{CheckedFitOptions, fit};
    use crate::log::ColumnMap;
    use crate::model::ModelSpec;
    use std::fmt::Write;

    /// A log whose bias sits at 60–110 (85 + 0.2·(x − 50) ± 12 by the seek direction, plus a
    /// deterministic ±2 scatter), 300 seeks over tracks 0..100.
    fn offset_log() -> String {
        let mut text = String::from("time_s,track,bias\n");
        let mut prev = 50.0;
        let mut state = 12345u64;
        for i in 0..300 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let x = ((state >> 33) % 101) as f64;
            let u = ((state >> 20) % 1000) as f64 / 1000.0 - 0.5;
            let dir = if x >= prev { 1.0 } else { -1.0 };
            let b = 85.0 + 0.2 * (x - 50.0) + 12.0 * dir + 4.0 * u;
            let _ = writeln!(text, "{},{x},{b:.4}", 0.3 * i as f64);
            prev = x;
        }
        text
    }

    /// The curves of a model with `drift` lie where the data are (the old synthetic replay with
    /// bias-0 rows pulled them towards 0), and each point equals a plain replay of the real rows
    /// followed by the curve's unmeasured seeks through the batch path (`predict_log` on the
    /// extended log: the reference).
    #[test]
    fn drift_model_curves_sit_on_the_data_and_match_a_replay_of_the_real_rows() {
        let text = offset_log();
        let log = Log::from_reader("o.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
        let spec = ModelSpec::parse("poly2,direction,drift").unwrap();
        let model = fit(&spec, &log, &CheckedFitOptions::default()).unwrap();
        let (inbound, outbound) = model_curves(&model, &log).unwrap();
        assert_eq!(
            (inbound.len(), outbound.len()),
            (CURVE_POINTS, CURVE_POINTS)
        );
        // The data's far curves: 85 + 0.2(x − 50) ± 12; the model's must be within 3 counts.
        for (&(x, a), &(_, b)) in inbound.iter().zip(&outbound) {
            let mid = 85.0 + 0.2 * (x - 50.0);
            assert!((a - (mid + 12.0)).abs() < 3.0, "inbound at {x}: {a}");
            assert!((b - (mid - 12.0)).abs() < 3.0, "outbound at {x}: {b}");
        }
        let t_end = log.last().unwrap().time_s;
        for (i, &(x, a)) in inbound.iter().enumerate().step_by(10) {
            let mut ext = text.clone();
            // The last row is measured (any value: a prediction never sees its own row's
            // measurement) so that `predict_log` reports it.
            for (k, (track, bias)) in [(200.0, ""), (-100.0, ""), (x, "0")]
                .into_iter()
                .enumerate()
            {
                let _ = writeln!(
                    ext,
                    "{},{track},{bias}",
                    t_end + CURVE_DWELL_S * (k + 1) as f64
                );
            }
            let ext = Log::from_reader("e.csv", ext.as_bytes(), &ColumnMap::default()).unwrap();
            let p = model.predict_log(&ext).unwrap();
            let want = *p.predicted.last().unwrap();
            assert!(
                (a - want).abs() < 1e-9 * want.abs().max(1.0),
                "point {i}: {a} vs {want}"
            );
        }
    }
}
