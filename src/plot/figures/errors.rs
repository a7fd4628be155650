//! Prediction errors of several models (Figs. 10, 11, 13, 14): time series and histograms on
//! common bins.

use super::{error_label, position_label};
use crate::log::Units;
use crate::numeric::stats;
use crate::plot::svg::{AxisRange, Chart, Panel, Series, SeriesData, fmt_num};

/// Prediction errors of one model (Figs. 10/11).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ModelErrors {
    /// Model name (for example "position + direction", "calibration").
    pub name: String,
    /// Position of each measured seek, position unit.
    pub position: Vec<f64>,
    /// Prediction error of each seek, measured − predicted, bias unit (same length as
    /// `position`; extra entries of the longer one are ignored).
    pub error: Vec<f64>,
}

/// Figs. 10/11: for each model one column with the error vs position (top) and the error
/// histogram (bottom); the error standard deviation is in each title. All columns share the
/// position range, and the error range and the histogram bins so they compare directly — unless
/// the models' errors hardly overlap ([`errors_overlap`]: one model far off would squash the
/// others to a line), when each column gets its own error range and bins. `units` are those of
/// every model's errors and positions.
pub fn prediction_errors(models: &[ModelErrors], units: &Units) -> String {
    let width = if models.len() > 2 { 420.0 } else { 520.0 };
    if models.len() > 1 && !errors_overlap(models) {
        // Each model on its own error axis, the position axis still shared.
        let all_pos: Vec<f64> = models
            .iter()
            .flat_map(|m| m.position.iter().copied())
            .filter(|v| v.is_finite())
            .collect();
        let pos = finite_range(&all_pos).padded();
        let charts: Vec<(Chart, Chart)> = models
            .iter()
            .flat_map(|m| error_columns(std::slice::from_ref(m), units, Some(pos), width))
            .collect();
        return error_panel(charts, models.len());
    }
    let charts = error_columns(models, units, None, width);
    error_panel(charts, models.len())
}

/// Whether the models' error ranges overlap enough to share one axis: the union of their
/// finite ranges is at most twice as wide as the widest model's own range.
pub fn errors_overlap(models: &[ModelErrors]) -> bool {
    let spans: Vec<[f64; 2]> = models
        .iter()
        .filter_map(|m| {
            let v: Vec<f64> = m.error.iter().copied().filter(|v| v.is_finite()).collect();
            stats::range(&v)
        })
        .collect();
    let widest = spans.iter().map(|[lo, hi]| hi - lo).fold(0.0, f64::max);
    let lo = spans.iter().map(|r| r[0]).fold(f64::INFINITY, f64::min);
    let hi = spans.iter().map(|r| r[1]).fold(f64::NEG_INFINITY, f64::max);
    spans.len() < 2 || hi - lo <= 2.0 * widest
}

/// The panel of Figs. 10/11: scatters on the first row, histograms on the second.
fn error_panel(charts: Vec<(Chart, Chart)>, columns: usize) -> String {
    let (scatters, histograms): (Vec<Chart>, Vec<Chart>) = charts.into_iter().unzip();
    let mut panel = Panel::new("Figs. 10/11 — prediction error vs position and its histogram")
        .columns(columns.max(1));
    for c in scatters.into_iter().chain(histograms) {
        panel = panel.chart(c);
    }
    panel.to_svg()
}

/// The (scatter, histogram) pair of each model, sharing the error range and bins of `models`
/// and the position range `pos` (or that of `models`).
fn error_columns(
    models: &[ModelErrors],
    units: &Units,
    pos: Option<AxisRange>,
    width: f64,
) -> Vec<(Chart, Chart)> {
    let all_err: Vec<f64> = models
        .iter()
        .flat_map(|m| m.error.iter().copied())
        .filter(|v| v.is_finite())
        .collect();
    let all_pos: Vec<f64> = models
        .iter()
        .flat_map(|m| m.position.iter().copied())
        .filter(|v| v.is_finite())
        .collect();
    // Shared by every chart (so they compare), padded like an automatic range.
    let err_range = finite_range(&all_err).padded();
    let pos_range = pos.unwrap_or_else(|| finite_range(&all_pos).padded());
    let edges = common_edges(&all_err);
    let mut scatters = Vec::new();
    let mut histograms = Vec::new();
    for m in models {
        let pairs: Vec<(f64, f64)> = m
            .position
            .iter()
            .copied()
            .zip(m.error.iter().copied())
            .collect();
        let errs: Vec<f64> = pairs
            .iter()
            .map(|p| p.1)
            .filter(|v| v.is_finite())
            .collect();
        let std = stats::std_dev(&errs).map_or("n/a".to_string(), fmt_num);
        let title = format!(
            "{}: error std {std} {} (n = {})",
            m.name,
            units.bias,
            errs.len()
        );
        let scatter = Chart::new(title.clone())
            .size(width, 320.0)
            .x_label(position_label(units))
            .y_label(format!("error ({})", units.bias))
            .x_range(pos_range)
            .y_range(err_range)
            .series(Series::new("error", SeriesData::Scatter(pairs)).color(0))
            .hline(0.0, "");
        scatters.push(scatter);
        // No finite errors: no bars (an all-zero histogram would pose as data).
        let counts = if errs.is_empty() {
            Vec::new()
        } else {
            bin_counts(&errs, &edges)
        };
        let histogram = Chart::new(title)
            .size(width, 300.0)
            .x_label(error_label(units))
            .y_label("seeks (count)")
            .x_range(err_range)
            .series(
                Series::new(
                    "error histogram",
                    SeriesData::Bars {
                        edges: edges.clone(),
                        heights: counts,
                    },
                )
                .color(0),
            );
        histograms.push(histogram);
    }
    scatters.into_iter().zip(histograms).collect()
}

/// The fixed range of the finite values, or automatic if there are none.
pub(super) fn finite_range(v: &[f64]) -> AxisRange {
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if lo.is_finite() && hi > lo {
        AxisRange::Fixed { lo, hi }
    } else {
        AxisRange::Auto
    }
}

/// Histogram edges shared by several data sets: Freedman–Diaconis bins over all finite values.
fn common_edges(all: &[f64]) -> Vec<f64> {
    stats::histogram(all, stats::fd_bins(all)).edges
}

/// Counts of the finite values of `x` in the bins `edges` (the last bin includes its right edge).
fn bin_counts(x: &[f64], edges: &[f64]) -> Vec<f64> {
    let bins = edges.len().saturating_sub(1);
    let mut counts = vec![0.0; bins];
    if bins == 0 {
        return counts;
    }
    let (lo, hi) = (edges[0], edges[bins]);
    let width = (hi - lo) / bins as f64;
    for &v in x {
        if v.is_finite() && v >= lo && v <= hi && width > 0.0 {
            let i = (((v - lo) / width) as usize).min(bins - 1);
            counts[i] += 1.0;
        }
    }
    counts
}
