//! Error statistics of a model on a log (`biasctl score`): n, mean, std, RMS, median absolute
//! error, percentiles, a histogram, Sarle's bimodality coefficient, Hartigans' dip test of
//! unimodality (does the error histogram really have two humps?) and a trend test of the error
//! against position. All in the log's bias unit (the trend slope in bias unit per position
//! unit), carried in [`Score::units`]: counts and tracks for the simulator, whatever the log
//! says for yours ([`score_with_units`]).
//!
//! ```
//! let e = [1.0, -1.0, 0.5, -0.5, 0.0, 0.25];
//! let x = [10.0, 20.0, 30.0, 40.0, 50.0, 60.0];
//! let s = biasctl::score(&e, &x).unwrap();
//! assert_eq!(s.n, 6);
//! assert!((s.mean - 0.041666).abs() < 1e-5);
//! ```

use crate::log::{Log, Units};
use crate::model::{Feedback, FittedModel, ModelError};
use crate::numeric::stats::{self, DipTest, Histogram, Trend};
use serde::{Deserialize, Serialize};

// The namespace's public items that live in its submodules (the crate root keeps only the
// names most users need; see `biasctl::prelude`).
pub use crate::output_check::{check_prediction, check_replay};

/// An error computing a score.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScoreError {
    /// No residuals.
    #[error("no measured rows to score")]
    Empty,
    /// A residual or position is not a finite number (`index` is 0-based).
    #[error("residual or position {index} is {value}, not a finite number")]
    NonFinite {
        /// Index of the value.
        index: usize,
        /// The value.
        value: f64,
    },
    /// A statistic overflowed: residuals so large (a model far off the log's scale) that their
    /// sums leave the range of f64.
    #[error(
        "the error statistics overflow (`{statistic}` is {value}); the model's predictions are far off this log's scale"
    )]
    Overflow {
        /// The statistic (`mean`, `std`, ...).
        statistic: &'static str,
        /// Its value.
        value: f64,
    },
    /// Residuals and positions differ in length.
    #[error("{residuals} residuals but {positions} positions")]
    Length {
        /// Number of residuals.
        residuals: usize,
        /// Number of positions.
        positions: usize,
    },
}

/// The score of a model's residuals (measured − predicted, in the bias unit of [`Score::units`]).
/// JSON keys are a contract: `n`, `mean`, `std`, `rms`, `histogram`, `bimodality`, `trend` (plus
/// the others below, among them `dip`, `bimodal` and `units`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Score {
    /// Number of residuals.
    pub n: usize,
    /// Mean error, bias unit.
    pub mean: f64,
    /// Sample standard deviation, bias unit (0 for one value).
    pub std: f64,
    /// Root mean square, bias unit.
    pub rms: f64,
    /// Median of |error|, bias unit.
    pub median_abs: f64,
    /// Percentiles of the error: (p, value) for p = 1, 5, 25, 50, 75, 95, 99.
    pub percentiles: Vec<(f64, f64)>,
    /// Histogram of the error (Freedman–Diaconis bins).
    pub histogram: Histogram,
    /// Sarle's bimodality coefficient (absent for fewer than 4 values or no spread: `score`
    /// never writes `null`); above
    /// `stats::BIMODALITY_THRESHOLD` (5/9) it suggests two modes. A heuristic: it misses
    /// overlapping humps and flags skewed single ones; `bimodal` uses the dip test instead.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bimodality: Option<f64>,
    /// Hartigans' dip test of unimodality of the error: `{"statistic", "p_value",
    /// "modal_interval": [lo, hi], "n"}` (absent for fewer than 4 values, no spread or a
    /// non-finite residual). See [`stats::dip_test`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dip: Option<DipTest>,
    /// Whether the error has two or more modes: the dip test rejects unimodality at the 5 %
    /// level (`stats::DIP_SIGNIFICANCE`, p-value below 0.05). `false` where `dip` is absent.
    /// Residuals that take few distinct values (quantised measurements and a model with few
    /// distinct predictions) are point masses to the test, which then rejects.
    pub bimodal: bool,
    /// Least-squares trend of the error against position (absent if undefined: fewer than three
    /// rows or positions without spread); its slope is in
    /// bias unit per position unit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trend: Option<Trend>,
    /// The units of the error and the positions: `{"bias": "N", "position": "m"}` (counts and
    /// tracks when absent).
    #[serde(default)]
    pub units: Units,
}

/// Scores `residuals` (counts) at `positions` (tracks, same length): the simulator's units. For
/// a log in other units use [`score_with_units`] with the log's [`crate::log::LogSchema::units`].
pub fn score(residuals: &[f64], positions: &[f64]) -> Result<Score, ScoreError> {
    score_with_units(residuals, positions, &Units::default())
}

/// Scores `residuals` (in `units.bias`) at `positions` (in `units.position`, same length); the
/// units label the text and the JSON.
pub fn score_with_units(
    residuals: &[f64],
    positions: &[f64],
    units: &Units,
) -> Result<Score, ScoreError> {
    if residuals.is_empty() {
        return Err(ScoreError::Empty);
    }
    if residuals.len() != positions.len() {
        return Err(ScoreError::Length {
            residuals: residuals.len(),
            positions: positions.len(),
        });
    }
    if let Some((index, &value)) = residuals
        .iter()
        .chain(positions)
        .enumerate()
        .find(|(_, v)| !v.is_finite())
    {
        return Err(ScoreError::NonFinite {
            index: index % residuals.len(),
            value,
        });
    }
    // One sorted copy at a time (8 bytes a row): the residuals, then their magnitudes.
    let sorted = stats::sorted(residuals);
    let dip = stats::dip_test_sorted(&sorted);
    let percentiles = [1.0, 5.0, 25.0, 50.0, 75.0, 95.0, 99.0]
        .iter()
        .map(|&p| (p, stats::percentile_sorted(&sorted, p).unwrap_or(0.0)))
        .collect();
    let bins = stats::fd_bins_sorted(&sorted);
    drop(sorted);
    let mut abs: Vec<f64> = residuals.iter().map(|e| e.abs()).collect();
    abs.sort_by(f64::total_cmp);
    let median_abs = stats::percentile_sorted(&abs, 50.0).unwrap_or(0.0);
    drop(abs);
    let bimodality = stats::bimodality_coefficient(residuals);
    let score = Score {
        n: residuals.len(),
        mean: stats::mean(residuals).unwrap_or(0.0),
        std: stats::std_dev(residuals).unwrap_or(0.0),
        rms: stats::rms(residuals).unwrap_or(0.0),
        median_abs,
        percentiles,
        histogram: stats::histogram(residuals, bins),
        bimodality,
        dip,
        bimodal: dip.is_some_and(|t| t.rejects_unimodality(stats::DIP_SIGNIFICANCE)),
        trend: stats::linear_trend(positions, residuals),
        units: units.clone(),
    };
    score.check_finite()?;
    Ok(score)
}

impl Score {
    /// Every number of the score is finite, or [`ScoreError::Overflow`] naming the first that
    /// is not: the JSON then never carries a `null` for a number.
    fn check_finite(&self) -> Result<(), ScoreError> {
        let mut named = vec![
            ("mean", self.mean),
            ("std", self.std),
            ("rms", self.rms),
            ("median_abs", self.median_abs),
        ];
        named.extend(self.percentiles.iter().map(|p| ("percentiles", p.1)));
        named.extend(self.bimodality.map(|b| ("bimodality", b)));
        named.extend(self.histogram.edges.iter().map(|&e| ("histogram.edges", e)));
        if let Some(t) = &self.trend {
            named.extend([
                ("trend.slope", t.slope),
                ("trend.intercept", t.intercept),
                ("trend.slope_se", t.slope_se),
                ("trend.t", t.t),
                ("trend.p_value", t.p_value),
                ("trend.r2", t.r2),
            ]);
        }
        match named.into_iter().find(|(_, v)| !v.is_finite()) {
            None => Ok(()),
            Some((statistic, value)) => Err(ScoreError::Overflow { statistic, value }),
        }
    }

    /// A human-readable summary, every value labelled with [`Score::units`].
    pub fn to_text(&self) -> String {
        let u = &self.units.bias;
        let mut s = format!(
            "n {}\nmean {:.4} {u}\nstd {:.4} {u}\nrms {:.4} {u}\nmedian |error| {:.4} {u}\n",
            self.n, self.mean, self.std, self.rms, self.median_abs
        );
        s += &format!("percentiles ({u})");
        for (p, v) in &self.percentiles {
            s += &format!(" p{p}={v:.4}");
        }
        s += "\n";
        match self.bimodality {
            Some(b) => {
                s += &format!(
                    "bimodality coefficient {b:.3} ({} threshold {:.3})\n",
                    if b > stats::BIMODALITY_THRESHOLD {
                        "above"
                    } else {
                        "below"
                    },
                    stats::BIMODALITY_THRESHOLD
                )
            }
            None => s += "bimodality coefficient undefined\n",
        }
        match &self.dip {
            Some(t) => {
                let p = if t.p_value < 1e-4 {
                    "< 0.0001".to_string()
                } else {
                    format!("{:.4}", t.p_value)
                };
                s += &format!(
                    "dip test D {:.4}, p {p}, modal interval [{:.4}, {:.4}] {u}: {}\n",
                    t.statistic,
                    t.modal_interval[0],
                    t.modal_interval[1],
                    if self.bimodal {
                        "bimodal (unimodality rejected at 5 %)"
                    } else {
                        "unimodal at 5 %"
                    }
                )
            }
            None => s += "dip test undefined\n",
        }
        match &self.trend {
            Some(t) => {
                s += &format!(
                    "trend vs position: slope {:.4e} {}, t {:.2}, p {:.3e}\n",
                    t.slope,
                    self.units.per_position(),
                    t.t,
                    t.p_value
                )
            }
            None => s += "trend vs position: undefined\n",
        }
        s += &format!("histogram of the error ({u})\n");
        for (i, c) in self.histogram.counts.iter().enumerate() {
            s += &format!(
                "  [{:>9.3}, {:>9.3}) {c}\n",
                self.histogram.edges[i],
                self.histogram.edges[i + 1]
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::rng::SimRng;

    fn positions(n: usize) -> Vec<f64> {
        (0..n).map(|i| i as f64).collect()
    }

    /// Reference: the grouped lines written out by hand. Per-coefficient warnings of one term
    /// and reason become one line with their count and first and last names; other warnings
    /// (another term, another reason, no `TERM.PARAM` head) stay; exact repeats are counted.
    #[test]
    fn fit_warnings_are_grouped_per_term_and_reason() {
        let s = |v: &[&str]| v.iter().map(|w| w.to_string()).collect::<Vec<_>>();
        let nid = |p: &str, se: &str| {
            format!(
                "play:4.{p}: standard error {se} exceeds |value| 1e0: not identifiable from this log"
            )
        };
        let w = vec![
            nid("w@r=1", "2e0"),
            "col:a.slope: its contribution swings 1e3× the std of the bias: blowing up".into(),
            nid("w@r=2", "3e0"),
            "a nonlinear parameter ended at the edge of its search interval".into(),
            nid("w@r=4", "5e0"),
            "a nonlinear parameter ended at the edge of its search interval".into(),
        ];
        assert_eq!(
            grouped_warnings(&w),
            s(&[
                &format!(
                    "{} (×3: the same for 3 coefficients of play:4, from w@r=1 to w@r=4)",
                    nid("w@r=1", "2e0")
                ),
                "col:a.slope: its contribution swings 1e3× the std of the bias: blowing up",
                "a nonlinear parameter ended at the edge of its search interval (×2)",
            ])
        );
        assert_eq!(grouped_warnings(&s(&["x", "y"])), s(&["x", "y"]));
        assert!(grouped_warnings(&[]).is_empty());
    }

    /// Reference: scoring `predict_log`'s residuals and positions (what `score_model` did
    /// before it streamed the replay): the same scores, bit for bit, one-step and free run.
    #[test]
    fn streamed_score_equals_scoring_predict_log() {
        use crate::model::{Feedback, ModelSpec};
        let log = crate::sim::random_log(3000, 6);
        let spec = ModelSpec::preset("calibration").unwrap();
        let model = crate::fit::fit(&spec, &log, &Default::default()).unwrap();
        let s = score_model(&model, &log, Feedback::Never).unwrap();
        let units = &log.schema.units;
        let p = model.predict_log(&log).unwrap();
        let q = model.predict_log_with(&log, Feedback::Never).unwrap();
        let json = |s: &Score| serde_json::to_string(s).unwrap();
        let want = score_with_units(&p.residual, &p.positions, units).unwrap();
        assert_eq!(json(&s.one_step), json(&want));
        let want = score_with_units(&q.residual, &q.positions, units).unwrap();
        assert_eq!(json(s.free_run.as_ref().unwrap()), json(&want));
    }

    #[test]
    fn bimodal_follows_the_dip_test() {
        // Two overlapping humps N(±1.5, 1) (n = 2000): Sarle's coefficient stays below 5/9 but
        // the dip test rejects one hump (see stats::dip_tests for its references).
        let mut r = SimRng::new(7);
        let two: Vec<f64> = (0..2000)
            .map(|_| if r.uniform() < 0.5 { -1.5 } else { 1.5 } + r.normal())
            .collect();
        let s = score(&two, &positions(two.len())).unwrap();
        let dip = s.dip.unwrap();
        assert!(s.bimodal && dip.p_value < 0.01 && dip.n == 2000, "{dip:?}");
        assert!(s.bimodality.unwrap() < stats::BIMODALITY_THRESHOLD);
        assert_eq!(Some(dip), stats::dip_test(&two));
        let text = s.to_text();
        assert!(text.contains("dip test D ") && text.contains("bimodal (unimodality rejected"));
        assert!(text.contains("bimodality coefficient") && text.contains("below threshold"));
        // One normal hump: not bimodal.
        let one: Vec<f64> = (0..2000).map(|_| r.normal()).collect();
        let s = score(&one, &positions(one.len())).unwrap();
        assert!(!s.bimodal && s.dip.unwrap().p_value > 0.05);
        assert!(s.to_text().contains("unimodal at 5 %"));
    }

    #[test]
    fn dip_is_null_where_undefined() {
        let s = score(&[1.0, 2.0, 3.0], &positions(3)).unwrap();
        assert!(s.dip.is_none() && !s.bimodal);
        assert!(s.to_text().contains("dip test undefined"));
        let s = score(&[2.0; 10], &positions(10)).unwrap();
        assert!(s.dip.is_none() && !s.bimodal);
        // Undefined statistics are absent from the JSON, never `null`.
        let json = crate::io::json::to_string_pretty(&s).unwrap();
        assert!(
            !json.contains("null") && !json.contains("\"dip\""),
            "{json}"
        );
        let back: Score = serde_json::from_str(&json).unwrap();
        assert!(back.dip.is_none() && back.bimodality.is_none());
    }

    #[test]
    fn text_and_json_carry_the_units() {
        let e: Vec<f64> = (0..100).map(|i| ((i * 37) % 100) as f64 / 10.0).collect();
        let s = score(&e, &positions(e.len())).unwrap();
        let text = s.to_text();
        assert!(text.contains(" counts\nrms ") && text.contains(" counts/track, t "));
        let units = Units {
            bias: "N".into(),
            position: "m".into(),
        };
        let s = score_with_units(&e, &positions(e.len()), &units).unwrap();
        let text = s.to_text();
        assert!(text.contains(&format!("std {:.4} N\n", s.std)), "{text}");
        assert!(
            text.contains(" N/m, t ") && !text.contains("count"),
            "{text}"
        );
        let v = serde_json::to_value(&s).unwrap();
        assert_eq!(
            v["units"],
            serde_json::json!({"bias": "N", "position": "m"})
        );
        // A score written before units existed reads back in counts and tracks.
        let mut old = v.clone();
        old.as_object_mut().unwrap().remove("units");
        let back: Score = serde_json::from_value(old).unwrap();
        assert_eq!(back.units, Units::default());
    }

    #[test]
    fn json_keys_of_the_dip() {
        let e: Vec<f64> = (0..100).map(|i| ((i * 37) % 100) as f64 / 10.0).collect();
        let s = score(&e, &positions(e.len())).unwrap();
        let v = serde_json::to_value(&s).unwrap();
        for key in [
            "n",
            "mean",
            "std",
            "rms",
            "histogram",
            "bimodality",
            "trend",
            "dip",
            "bimodal",
        ] {
            assert!(v.get(key).is_some(), "missing {key}");
        }
        let dip = &v["dip"];
        assert!(dip["statistic"].is_f64() && dip["p_value"].is_f64());
        assert_eq!(dip["n"], 100);
        let mi = dip["modal_interval"].as_array().unwrap();
        assert!(mi.len() == 2 && mi[0].as_f64().unwrap() <= mi[1].as_f64().unwrap());
        // And back.
        let back: Score = serde_json::from_value(v).unwrap();
        assert_eq!(back, s);
    }
}

/// A mean error larger than this fraction of the error std is warned about: the model is
/// biased on the log (an offset it did not learn, a column or unit mix-up, parameters that blew up).
pub(crate) const MEAN_WARNING_RATIO: f64 = 0.5;

/// The warning for a score whose |mean| is large against its std ([`MEAN_WARNING_RATIO`]),
/// naming the figure (`one-step`, `free run`); `None` otherwise.
pub(crate) fn mean_warning(s: &Score, figure: &str) -> Option<String> {
    (s.mean.abs() > MEAN_WARNING_RATIO * s.std && s.n >= 2).then(|| {
        format!(
            "{figure} mean error {} {} is {:.2}× the error std {}, above the {}× that is warned \
             about: the model is offset on this log (an offset it did not learn, a column or \
             unit mix-up, or parameters that blew up)",
            crate::log::fmt_trimmed(s.mean, 4),
            s.units.bias,
            s.mean.abs() / s.std.max(f64::MIN_POSITIVE),
            crate::log::fmt_trimmed(s.std, 4),
            MEAN_WARNING_RATIO,
        )
    })
}

/// A model's score on a log, honest about adaptive terms: the one-step figure (adaptive terms such
/// as `drift` see every measured bias) flattened into the top level as before, and, for a model
/// with an adaptive term, the free-run figure beside it. JSON: the [`Score`] keys, plus
/// `figure` (`"one-step"`), `free_run` (a [`Score`]) and `free_run_feedback` (its label), both left
/// out for a model with no adaptive term (the JSON never holds `null`), and `warnings`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelScore {
    /// The one-step score (every measured bias shown to the adaptive terms).
    #[serde(flatten)]
    pub one_step: Score,
    /// Which figure the top-level keys are: always `one-step`.
    pub figure: String,
    /// The free-run score (adaptive terms see the measured bias as `free_run_feedback` says);
    /// `None` (left out of the JSON) when the model has no adaptive term (then both figures
    /// are the same).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub free_run: Option<Score>,
    /// Label of the free run's feedback (`free run`, `free run, measured bias every N rows`);
    /// left out of the JSON with `free_run`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub free_run_feedback: Option<String>,
    /// Warnings: a mean error large against the std, a one-step figure much better than the
    /// free run, and the model's own fit warnings (prefixed `fit: `).
    pub warnings: Vec<String>,
}

impl ModelScore {
    /// The figure to rank models by: the free run where there is one, else the one-step score.
    pub fn honest(&self) -> &Score {
        self.free_run.as_ref().unwrap_or(&self.one_step)
    }
}

/// An error scoring a model on a log.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ModelScoreError {
    /// The model cannot be replayed on the log.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The residuals cannot be scored.
    #[error(transparent)]
    Score(#[from] ScoreError),
}

/// A fit's warnings for a person to read: each once, in order. An exact repeat is counted
/// ("(×n)", as the report's fit summary does); the warnings a multi-coefficient term gives per
/// coefficient for the same reason (`TERM.PARAM: …: REASON`, e.g. a `play:32` weight's
/// "not identifiable from this log") are one line: the first of them, with how many there
/// are and the first and last coefficient's name.
pub fn grouped_warnings(warnings: &[String]) -> Vec<String> {
    // (the group's key, its first warning, the coefficient names in it)
    let mut groups: Vec<(String, &str, Vec<&str>)> = Vec::new();
    for w in warnings {
        let (head, reason) = match (w.split_once(": "), w.rsplit_once(": ")) {
            (Some((head, _)), Some((_, reason))) => (head, reason),
            _ => (w.as_str(), ""),
        };
        let (key, param) = match head.split_once('.') {
            Some((term, param)) if !reason.is_empty() && !term.contains(' ') => {
                (format!("{term}\u{0}{reason}"), param)
            }
            _ => (w.clone(), ""),
        };
        match groups.iter_mut().find(|g| g.0 == key) {
            Some(g) => g.2.push(param),
            None => groups.push((key, w, vec![param])),
        }
    }
    groups
        .into_iter()
        .map(|(key, first, params)| {
            let n = params.len();
            match key.split_once('\u{0}') {
                _ if n == 1 => first.to_string(),
                Some((term, _)) if params.iter().any(|p| *p != params[0]) => format!(
                    "{first} (×{n}: the same for {n} coefficients of {term}, from {} to {})",
                    params[0],
                    params[n - 1]
                ),
                _ => format!("{first} (×{n})"),
            }
        })
        .collect()
}

/// Scores `model` on `log` (residuals in the log's bias unit): one-step, and for a model with an
/// adaptive term also in free run with `free_run` feedback ([`Feedback::Never`] by default).
pub fn score_model(
    model: &FittedModel,
    log: &Log,
    free_run: Feedback,
) -> Result<ModelScore, ModelScoreError> {
    let units = &log.schema.units;
    // The residuals and positions of `predict_log` (measured − predicted of every measured
    // row, in log order), streamed: 16 bytes a row instead of its eight columns. The free run
    // has the same rows, so the same positions.
    let m = log.measured_count();
    let (mut positions, mut residual) = (Vec::with_capacity(m), Vec::with_capacity(m));
    model.replay_measured(log, Feedback::EveryRow, |row, pred, _| {
        positions.push(row.position);
        residual.push(row.measured - pred);
    })?;
    let one_step = score_with_units(&residual, &positions, units)?;
    let mut warnings: Vec<String> = Vec::new();
    let (free, label) = if model.adaptive() && free_run != Feedback::EveryRow {
        residual.clear();
        model.replay_measured(log, free_run, |row, pred, _| {
            residual.push(row.measured - pred);
        })?;
        let f = score_with_units(&residual, &positions, units)?;
        if f.rms > 1.5 * one_step.rms {
            warnings.push(format!(
                "the one-step error ({} {} rms) lets the adaptive terms re-learn the offset from \
                 the measured bias of earlier rows; from the positions alone ({}) the model \
                 leaves {} {} rms: judge it by that",
                crate::log::fmt_trimmed(one_step.rms, 4),
                units.bias,
                free_run.label(),
                crate::log::fmt_trimmed(f.rms, 4),
                units.bias,
            ));
        }
        (Some(f), Some(free_run.label()))
    } else {
        (None, None)
    };
    warnings.extend(mean_warning(&one_step, "one-step"));
    if let Some(f) = &free {
        warnings.extend(mean_warning(f, "free-run"));
    }
    // The fit's own self-check travels with the model.
    warnings.extend(model.warnings.iter().map(|w| format!("fit: {w}")));
    Ok(ModelScore {
        one_step,
        figure: Feedback::EveryRow.label(),
        free_run: free,
        free_run_feedback: label,
        warnings,
    })
}
