//! Error statistics of a model on a log (`biasctl score`): n, mean, std, RMS, median absolute
//! error, percentiles, a histogram, Sarle's bimodality coefficient and a trend test of the error
//! against position. All in counts (the trend slope in counts per track).
//!
//! ```
//! let e = [1.0, -1.0, 0.5, -0.5, 0.0, 0.25];
//! let x = [10.0, 20.0, 30.0, 40.0, 50.0, 60.0];
//! let s = biasctl::score::score(&e, &x).unwrap();
//! assert_eq!(s.n, 6);
//! assert!((s.mean - 0.041666).abs() < 1e-5);
//! ```

use crate::stats::{self, Histogram, Trend};
use serde::{Deserialize, Serialize};

/// An error computing a score.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScoreError {
    /// No residuals.
    #[error("no measured rows to score")]
    Empty,
    /// Residuals and positions differ in length.
    #[error("{residuals} residuals but {positions} positions")]
    Length {
        /// Number of residuals.
        residuals: usize,
        /// Number of positions.
        positions: usize,
    },
}

/// The score of a model's residuals (measured − predicted, counts). JSON keys are a contract:
/// `n`, `mean`, `std`, `rms`, `histogram`, `bimodality`, `trend` (plus the others below).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Score {
    /// Number of residuals.
    pub n: usize,
    /// Mean error, counts.
    pub mean: f64,
    /// Sample standard deviation, counts (0 for one value).
    pub std: f64,
    /// Root mean square, counts.
    pub rms: f64,
    /// Median of |error|, counts.
    pub median_abs: f64,
    /// Percentiles of the error: (p, value) for p = 1, 5, 25, 50, 75, 95, 99.
    pub percentiles: Vec<(f64, f64)>,
    /// Histogram of the error (Freedman–Diaconis bins).
    pub histogram: Histogram,
    /// Sarle's bimodality coefficient (`null` for fewer than 4 values or no spread).
    pub bimodality: Option<f64>,
    /// Whether `bimodality` exceeds [`stats::BIMODALITY_THRESHOLD`] (5/9).
    pub bimodal: bool,
    /// Least-squares trend of the error against position (`null` if undefined).
    pub trend: Option<Trend>,
}

/// Scores `residuals` (counts) at `positions` (tracks, same length).
pub fn score(residuals: &[f64], positions: &[f64]) -> Result<Score, ScoreError> {
    if residuals.is_empty() {
        return Err(ScoreError::Empty);
    }
    if residuals.len() != positions.len() {
        return Err(ScoreError::Length {
            residuals: residuals.len(),
            positions: positions.len(),
        });
    }
    let sorted = stats::sorted(residuals);
    let abs: Vec<f64> = stats::sorted(&residuals.iter().map(|e| e.abs()).collect::<Vec<_>>());
    let bimodality = stats::bimodality_coefficient(residuals);
    Ok(Score {
        n: residuals.len(),
        mean: stats::mean(residuals).unwrap_or(0.0),
        std: stats::std_dev(residuals).unwrap_or(0.0),
        rms: stats::rms(residuals).unwrap_or(0.0),
        median_abs: stats::percentile_sorted(&abs, 50.0).unwrap_or(0.0),
        percentiles: [1.0, 5.0, 25.0, 50.0, 75.0, 95.0, 99.0]
            .iter()
            .map(|&p| (p, stats::percentile_sorted(&sorted, p).unwrap_or(0.0)))
            .collect(),
        histogram: stats::histogram(residuals, stats::fd_bins(residuals)),
        bimodality,
        bimodal: bimodality.is_some_and(|b| b > stats::BIMODALITY_THRESHOLD),
        trend: stats::linear_trend(positions, residuals),
    })
}

impl Score {
    /// A human-readable summary.
    pub fn to_text(&self) -> String {
        let mut s = format!(
            "n {}\nmean {:.4}\nstd {:.4}\nrms {:.4}\nmedian |error| {:.4}\n",
            self.n, self.mean, self.std, self.rms, self.median_abs
        );
        s += "percentiles";
        for (p, v) in &self.percentiles {
            s += &format!(" p{p}={v:.4}");
        }
        s += "\n";
        match self.bimodality {
            Some(b) => {
                s += &format!(
                    "bimodality coefficient {b:.3} ({} threshold {:.3})\n",
                    if self.bimodal { "above" } else { "below" },
                    stats::BIMODALITY_THRESHOLD
                )
            }
            None => s += "bimodality coefficient undefined\n",
        }
        match &self.trend {
            Some(t) => {
                s += &format!(
                    "trend vs position: slope {:.4e} counts/track, t {:.2}, p {:.3e}\n",
                    t.slope, t.t, t.p_value
                )
            }
            None => s += "trend vs position: undefined\n",
        }
        s += "histogram\n";
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
