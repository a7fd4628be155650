//! One builder per paper figure. Each takes plain data (the structs below) and returns SVG text.
//!
//! Bias (and prediction errors) and positions (and seek lengths) are in the units of a
//! [`Units`]: the figure's data struct holds them (`units`, counts and tracks by default), or a
//! builder that takes a list of items takes them beside it; a log's units are
//! [`crate::log::LogSchema::units`]. The paper's calibration sweeps (Figs. 5–9, 12) are the
//! simulator's and stay in counts and tracks. Time is in s (Fig. 4) or ms (settle figures),
//! position error in µm. Points are `(x, y)` pairs in those units. Any data is accepted: empty
//! inputs give a "no data" chart, non-finite values are skipped and counted on the chart.
//!
//! ```
//! use biasctl::{plot::figures::BiasVsPosition, plot::figures::fig3_bias_vs_position};
//! let svg = fig3_bias_vs_position(&BiasVsPosition {
//!     inbound: vec![(0.0, 10.0), (500.0, 14.0), (1000.0, 12.0)],
//!     outbound: vec![(0.0, 4.0), (500.0, 8.0), (1000.0, 6.0)],
//!     ..Default::default()
//! });
//! assert!(svg.contains("bias (counts)"));
//! ```

use super::svg::{AxisRange, Chart, ErrorPoint, Panel, Series, SeriesData, fmt_num};
use crate::log::Units;
use crate::numeric::stats;

/// Axis label for bias in counts (the simulator's unit; see [`bias_label`]).
pub const BIAS: &str = "bias (counts)";
/// Axis label for position in tracks (the simulator's unit; see [`position_label`]).
pub const POSITION: &str = "position (tracks)";
/// Axis label for prediction errors and residuals in counts (see [`error_label`]).
pub const ERROR: &str = "prediction error, measured − predicted (counts)";

/// Axis label for bias in `units` (`bias (N)`).
pub fn bias_label(units: &Units) -> String {
    format!("bias ({})", units.bias)
}

/// Axis label for position in `units` (`position (m)`).
pub fn position_label(units: &Units) -> String {
    format!("position ({})", units.position)
}

/// Axis label for prediction errors in `units` (`prediction error, measured − predicted (N)`).
pub fn error_label(units: &Units) -> String {
    format!("prediction error, measured − predicted ({})", units.bias)
}

/// Palette index of inbound data (blue) and outbound data (vermillion), used by every figure
/// that splits by direction.
pub const INBOUND_COLOR: usize = 0;
/// See [`INBOUND_COLOR`].
pub const OUTBOUND_COLOR: usize = 1;

/// Data of Fig. 3: bias vs position after inbound and after outbound approaches.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BiasVsPosition {
    /// Measured `(track, bias)` after an inbound (towards ID) approach.
    pub inbound: Vec<(f64, f64)>,
    /// Measured `(track, bias)` after an outbound approach.
    pub outbound: Vec<(f64, f64)>,
    /// Fitted inbound curve `(track, bias)`, in track order; empty for none.
    pub inbound_fit: Vec<(f64, f64)>,
    /// Fitted outbound curve; empty for none.
    pub outbound_fit: Vec<(f64, f64)>,
    /// Units of bias and position (axis labels).
    pub units: Units,
}

/// The Fig. 3 chart, for callers that add series (for example [`super::from_log`]).
pub(crate) fn position_chart(d: &BiasVsPosition, title: &str) -> Chart {
    let mut c = Chart::new(title)
        .x_label(position_label(&d.units))
        .y_label(bias_label(&d.units))
        .series(Series::new("inbound", SeriesData::Scatter(d.inbound.clone())).color(INBOUND_COLOR))
        .series(
            Series::new("outbound", SeriesData::Scatter(d.outbound.clone())).color(OUTBOUND_COLOR),
        );
    for (name, fit, color) in [
        ("inbound fit", &d.inbound_fit, INBOUND_COLOR),
        ("outbound fit", &d.outbound_fit, OUTBOUND_COLOR),
    ] {
        if !fit.is_empty() {
            c = c.series(Series::new(name, SeriesData::Line(fit.clone())).color(color));
        }
    }
    c
}

/// Fig. 3: bias vs position, inbound and outbound points (blue, vermillion) with optional fitted
/// curves in the same colours.
pub fn fig3_bias_vs_position(d: &BiasVsPosition) -> String {
    position_chart(d, "Fig. 3 — bias vs position, by approach direction").to_svg()
}

/// Data of Fig. 4: bias vs time while the head stays at one track.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BiasVsTime {
    /// The position, in `units.position` (shown in the title).
    pub track: f64,
    /// Measured `(time s, bias)`.
    pub points: Vec<(f64, f64)>,
    /// A fitted curve `(time s, bias)`; empty for none.
    pub fit: Vec<(f64, f64)>,
    /// Units of bias and position (axis label and title).
    pub units: Units,
}

/// Fig. 4: bias vs time at one track (lubricant flow: a slow approach to a constant).
pub fn fig4_bias_vs_time(d: &BiasVsTime) -> String {
    let mut c = Chart::new(format!(
        "Fig. 4 — bias vs time at position {} ({})",
        fmt_num(d.track),
        d.units.position
    ))
    .x_label("time (s)")
    .y_label(bias_label(&d.units))
    .series(Series::new(
        "measured",
        SeriesData::Scatter(d.points.clone()),
    ));
    if !d.fit.is_empty() {
        c = c.series(Series::new("fit", SeriesData::Line(d.fit.clone())));
    }
    c.to_svg()
}

/// Which calibration-table figure a [`Sweep`] is; it fixes the title and the x axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SweepFigure {
    /// Fig. 5 (Table II): bias vs tracks moved since a reversal, one-track steps (the loop).
    Fig5SeekLength,
    /// Fig. 6 (Table III): bias at a fixed target vs source offset, direction change at the
    /// source every time (overshoot/undershoot).
    Fig6SourceOffset,
    /// Fig. 7 (Table IV): bias vs source offset, no direction change at the source.
    Fig7NoDirectionChange,
    /// Fig. 8 (Table V): bias vs source offset, direction change at the source.
    Fig8DirectionChange,
    /// Fig. 9 (Table VI): bias vs offset of an earlier rest position from the target.
    Fig9RestOffset,
    /// Fig. 12 (Table VII): one N-track seek vs N one-track seeks, bias vs N.
    Fig12SeekCount,
}

impl SweepFigure {
    /// The chart title.
    pub fn title(self) -> &'static str {
        match self {
            SweepFigure::Fig5SeekLength => "Fig. 5 — bias vs tracks moved since reversal",
            SweepFigure::Fig6SourceOffset => {
                "Fig. 6 — bias vs source offset (overshoot/undershoot)"
            }
            SweepFigure::Fig7NoDirectionChange => {
                "Fig. 7 — bias vs source offset, no direction change at source"
            }
            SweepFigure::Fig8DirectionChange => {
                "Fig. 8 — bias vs source offset, direction change at source"
            }
            SweepFigure::Fig9RestOffset => "Fig. 9 — bias vs rest-position offset",
            SweepFigure::Fig12SeekCount => "Fig. 12 — one N-track seek vs N one-track seeks",
        }
    }

    /// The x-axis label, with unit.
    pub fn x_label(self) -> &'static str {
        match self {
            SweepFigure::Fig5SeekLength => "tracks moved since reversal (tracks)",
            SweepFigure::Fig6SourceOffset
            | SweepFigure::Fig7NoDirectionChange
            | SweepFigure::Fig8DirectionChange => "source offset, source − target (tracks)",
            SweepFigure::Fig9RestOffset => "rest-position offset, rest − target (tracks)",
            SweepFigure::Fig12SeekCount => "seek length N (tracks)",
        }
    }
}

/// One series of a calibration sweep.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SweepSeries {
    /// Legend name (for example "inbound", "simulated", "one N-track seek").
    pub name: String,
    /// `(x, bias counts)` with x in the figure's unit (see [`SweepFigure::x_label`]).
    pub points: Vec<(f64, f64)>,
    /// Join the points by lines in the given order (a loop or a sweep); markers only otherwise.
    pub joined: bool,
}

/// Data of Figs. 5–9 and 12: several series against one calibration variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    /// Which figure.
    pub figure: SweepFigure,
    /// The series, drawn in palette order.
    pub series: Vec<SweepSeries>,
    /// Horizontal reference levels `(label, bias counts)`, for example the inbound and outbound
    /// asymptotic curves at the target.
    pub levels: Vec<(String, f64)>,
}

/// Figs. 5–9 and 12: bias vs the sweep variable, one series per entry, reference levels dashed.
pub fn calibration_sweep(s: &Sweep) -> String {
    let mut c = Chart::new(s.figure.title())
        .x_label(s.figure.x_label())
        .y_label(BIAS);
    for (i, ser) in s.series.iter().enumerate() {
        let data = if ser.joined {
            SeriesData::Line(ser.points.clone())
        } else {
            SeriesData::Scatter(ser.points.clone())
        };
        c = c.series(Series::new(ser.name.clone(), data).color(i).markers());
    }
    for (label, y) in &s.levels {
        c = c.hline(*y, label.clone());
    }
    c.to_svg()
}

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
fn finite_range(v: &[f64]) -> AxisRange {
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

/// Data of Figs. 13/14: a hysteresis loop, measured and as a model predicts it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DahlLoop {
    /// Measured `(position, bias)` in seek order.
    pub measured: Vec<(f64, f64)>,
    /// The model's predicted `(position, bias)` in seek order (drawn as a line).
    pub predicted: Vec<(f64, f64)>,
    /// Units of bias and position (axis labels).
    pub units: Units,
    /// The model's name for the title and legend (a preset such as `dahl`, a term list or a
    /// model file's name).
    pub model: String,
}

/// Figs. 13/14: a hysteresis loop, measured points and the loop the named model predicts.
pub fn dahl_loop(d: &DahlLoop) -> String {
    let model = format!("model `{}`", d.model);
    Chart::new(format!(
        "Figs. 13/14 — hysteresis loop: measured and {model}"
    ))
    .x_label(position_label(&d.units))
    .y_label(bias_label(&d.units))
    .series(Series::new("measured", SeriesData::Scatter(d.measured.clone())).color(0))
    .series(Series::new(model, SeriesData::Line(d.predicted.clone())).color(1))
    .to_svg()
}

/// One bin of residuals against a feature.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ResidualBin {
    /// Bin centre, in the feature's unit.
    pub center: f64,
    /// Mean residual in the bin, bias unit.
    pub mean: f64,
    /// Spread shown as the bar half-length (for example the standard error or the std), bias
    /// unit.
    pub spread: f64,
    /// Number of residuals in the bin (sets the marker size).
    pub count: usize,
}

/// Residuals against one candidate feature, for the diagnose panel.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FeatureResiduals {
    /// Feature name, e.g. `since_reversal`.
    pub feature: String,
    /// The feature's unit, e.g. `tracks` or `s`.
    pub unit: String,
    /// Raw `(feature value, residual)` drawn faintly behind the bins; may be empty.
    pub raw: Vec<(f64, f64)>,
    /// Binned means.
    pub bins: Vec<ResidualBin>,
    /// A short note added to the title (for example "p = 0.001, explains 31 %"); may be empty.
    pub note: String,
}

/// The diagnose panel: residual vs each top feature, binned mean ± spread with markers sized by
/// the bin count, raw residuals faint behind them; up to three charts per row. The residuals
/// are in `units.bias`.
pub fn diagnose_panel(features: &[FeatureResiduals], units: &Units) -> String {
    let mut panel =
        Panel::new("Residual vs the top candidate features").columns(features.len().clamp(1, 3));
    for f in features {
        let title = if f.note.is_empty() {
            f.feature.clone()
        } else {
            format!("{} — {}", f.feature, f.note)
        };
        let points: Vec<ErrorPoint> = f
            .bins
            .iter()
            .map(|b| ErrorPoint {
                x: b.center,
                y: b.mean,
                spread: b.spread,
                weight: b.count as f64,
            })
            .collect();
        let mut c = Chart::new(title)
            .size(420.0, 320.0)
            .x_label(format!("{} ({})", f.feature, f.unit))
            .y_label(format!("residual ({})", units.bias));
        if !f.raw.is_empty() {
            c = c.series(Series::new("residuals", SeriesData::Scatter(f.raw.clone())).faint());
        }
        c = c
            .series(Series::new("binned mean ± spread", SeriesData::ErrorBars(points)).color(0))
            .hline(0.0, "");
        panel = panel.chart(c);
    }
    panel.to_svg()
}

/// One rung of the model ladder.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LadderStep {
    /// The model at this rung, e.g. "position + direction" then "+ seek", "+ memory".
    pub term: String,
    /// Prediction-error standard deviation with this rung's terms, bias unit.
    pub error_std: f64,
}

/// The ladder: error std (in `units.bias`) after each added term as bars, each labelled with its
/// value and the reduction from the previous rung.
pub fn ladder(steps: &[LadderStep], units: &Units) -> String {
    let n = steps.len();
    let edges: Vec<f64> = (0..=n).map(|i| i as f64 - 0.5).collect();
    let heights: Vec<f64> = steps.iter().map(|s| s.error_std).collect();
    let top = heights
        .iter()
        .copied()
        .filter(|h| h.is_finite())
        .fold(0.0, f64::max);
    let mut c = Chart::new("Error std after each added term")
        .x_label("model terms, cumulative")
        .y_label(format!("error std ({})", units.bias))
        .x_tick_labels(
            steps
                .iter()
                .enumerate()
                .map(|(i, s)| (i as f64, s.term.clone()))
                .collect(),
        )
        .series(
            Series::new("", SeriesData::Bars { edges, heights })
                .color(0)
                .bar_width(0.6),
        );
    if n > 0 {
        c = c.x_range(AxisRange::Fixed {
            lo: -0.5,
            hi: n as f64 - 0.5,
        });
    }
    if top > 0.0 {
        c = c.y_range(AxisRange::Fixed {
            lo: 0.0,
            hi: top * 1.15,
        });
    }
    for (i, s) in steps.iter().enumerate() {
        let prev = if i > 0 {
            Some(steps[i - 1].error_std)
        } else {
            None
        };
        let label = match prev {
            Some(p) if p.is_finite() && p > 0.0 && s.error_std.is_finite() => format!(
                "{} ({}{} %)",
                fmt_num(s.error_std),
                if s.error_std <= p { "−" } else { "+" },
                fmt_num((100.0 * (p - s.error_std).abs() / p * 10.0).round() / 10.0)
            ),
            _ => fmt_num(s.error_std),
        };
        c = c.annotate(i as f64, s.error_std, label);
    }
    c.to_svg()
}

/// Data of Fig. 15: the settle bounds on the integrator start value (eqs. 14–16).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SettleBounds {
    /// Sample period, ms (0.1 at 10 kHz); sample k is drawn at `k · sample_period_ms`.
    pub sample_period_ms: f64,
    /// Upper bound U_k per sample.
    pub upper: Vec<f64>,
    /// Lower bound L_k per sample.
    pub lower: Vec<f64>,
    /// Running minimum of the upper bound from the end, U*(k).
    pub upper_running: Vec<f64>,
    /// Running maximum of the lower bound from the end, L*(k).
    pub lower_running: Vec<f64>,
    /// Chosen start values `(name, value)`, drawn as horizontal lines.
    pub choices: Vec<(String, f64)>,
    /// The minimum settle time, ms, drawn as a vertical line; `None` for none.
    pub settle_ms: Option<f64>,
    /// Unit of the start value, e.g. `counts`; it is relative to the converged integrator value.
    pub unit: String,
}

fn per_sample(period_ms: f64, v: &[f64]) -> Vec<(f64, f64)> {
    v.iter()
        .enumerate()
        .map(|(k, &y)| (k as f64 * period_ms, y))
        .collect()
}

/// Dash patterns that tell apart lines drawn on top of each other: solid first, then dashed,
/// dotted, dash-dot.
const DASHES: [Option<&str>; 4] = [None, Some("7 4"), Some("2 3"), Some("9 3 2 3")];

/// The sample at which start value `v` enters the running bounds, `L*(k) ≤ v ≤ U*(k)` (its
/// settle sample when the running bounds are those of a settle analysis).
fn entry_sample(b: &SettleBounds, v: f64) -> Option<usize> {
    b.lower_running
        .iter()
        .zip(&b.upper_running)
        .position(|(&lo, &hi)| lo <= v && v <= hi)
}

/// The four bound curves of Fig. 15 on chart `c` (thin U, L; dashed running U*, L*).
fn bound_series(c: Chart, b: &SettleBounds) -> Chart {
    let t = b.sample_period_ms;
    c.series(Series::new("upper bound U", SeriesData::Line(per_sample(t, &b.upper))).color(0))
        .series(Series::new("lower bound L", SeriesData::Line(per_sample(t, &b.lower))).color(1))
        .series(
            Series::new(
                "running min U*",
                SeriesData::Step(per_sample(t, &b.upper_running)),
            )
            .color(0)
            .dashed(),
        )
        .series(
            Series::new(
                "running max L*",
                SeriesData::Step(per_sample(t, &b.lower_running)),
            )
            .color(1)
            .dashed(),
        )
}

/// Fig. 15, two panels. Left, the whole horizon: the bounds U_k, L_k (thin) and their running
/// min/max U*, L* (dashed) vs time, the chosen start values as unlabelled grey lines; the y range
/// follows the running bounds and the choices (the raw bounds grow without limit near k = 0 and
/// are clipped). Right, the decision region: time up to a little past the last sample at which
/// a chosen start value enters the running bounds, values around the choices, each choice a
/// legend entry with its value (own colour and dash pattern, so values a few units apart stay
/// legible). With no finite choice the right panel repeats the left one's range.
pub fn fig15_settle_bounds(b: &SettleBounds) -> String {
    let t = b.sample_period_ms;
    let mut focus: Vec<f64> = b
        .upper_running
        .iter()
        .chain(&b.lower_running)
        .copied()
        .chain(b.choices.iter().map(|c| c.1))
        .filter(|v| v.is_finite())
        .collect();
    if focus.is_empty() {
        focus = b
            .upper
            .iter()
            .chain(&b.lower)
            .copied()
            .filter(|v| v.is_finite())
            .collect();
    }
    let y_range = match finite_range(&focus) {
        AxisRange::Fixed { lo, hi } => {
            let pad = 0.1 * (hi - lo);
            AxisRange::Fixed {
                lo: lo - pad,
                hi: hi + pad,
            }
        }
        auto => auto,
    };
    let y_label = format!("start value − converged ({})", b.unit);
    let mut whole = Chart::new("whole horizon")
        .size(520.0, 380.0)
        .x_label("time after handoff (ms)")
        .y_label(y_label.clone())
        .y_range(y_range);
    whole = bound_series(whole, b);
    for (_, v) in &b.choices {
        whole = whole.hline(*v, "");
    }
    // The decision region.
    let values: Vec<f64> = b
        .choices
        .iter()
        .map(|c| c.1)
        .filter(|v| v.is_finite())
        .collect();
    let last_entry = values
        .iter()
        .filter_map(|&v| entry_sample(b, v))
        .chain(b.settle_ms.map(|s| (s / t).round() as usize))
        .max();
    let n = b.upper.len().max(b.lower.len());
    let x_hi = last_entry.map_or(n as f64 * t, |k| {
        ((k as f64 * 1.3).ceil() + 2.0).min(n as f64) * t
    });
    let mut zoom = Chart::new("zoom on the decision region")
        .size(520.0, 380.0)
        .x_label("time after handoff (ms)")
        .y_label(y_label);
    zoom = match finite_range(&values) {
        AxisRange::Fixed { lo, hi } => {
            let pad = 0.3 * (hi - lo);
            zoom.y_range(AxisRange::Fixed {
                lo: lo - pad,
                hi: hi + pad,
            })
        }
        AxisRange::Auto => zoom.y_range(y_range),
    };
    if x_hi.is_finite() && x_hi > 0.0 {
        zoom = zoom.x_range(AxisRange::Fixed { lo: 0.0, hi: x_hi });
    }
    zoom = bound_series(zoom, b);
    for (i, (name, v)) in b.choices.iter().enumerate() {
        let mut s = Series::new(
            format!("{name}: {}", fmt_num(*v)),
            SeriesData::Line(vec![(0.0, *v), (x_hi, *v)]),
        )
        .color(2 + i);
        if let Some(d) = DASHES[i % DASHES.len()] {
            s = s.dash(d);
        }
        zoom = zoom.series(s);
    }
    if let Some(s) = b.settle_ms {
        whole = whole.vline(s, format!("settle {} ms", fmt_num(s)));
        zoom = zoom.vline(s, format!("settle {} ms", fmt_num(s)));
    }
    Panel::new("Fig. 15 — bounds on the integrator start value")
        .columns(2)
        .chart(whole)
        .chart(zoom)
        .to_svg()
}

/// The position-error response for one start-value choice.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Response {
    /// The choice, e.g. "zero feedforward", "robust optimal".
    pub name: String,
    /// Position error e(k) per sample, µm.
    pub error_um: Vec<f64>,
    /// Settle time, ms (shown in the legend and as a dashed vertical line); `None` if it does
    /// not settle.
    pub settle_ms: Option<f64>,
}

/// Data of Fig. 16: responses for each start-value choice and the settle window.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SettleResponses {
    /// Sample period, ms.
    pub sample_period_ms: f64,
    /// Half-width δ of the settle window, µm.
    pub delta_um: f64,
    /// One response per choice.
    pub responses: Vec<Response>,
}

/// Which earlier response each response lies on top of: `Some(j)` when its largest distance
/// from response `j < i` is under 3 % of the whole figure's error range (about 6 pixels of the
/// whole-response chart: the two curves cannot be told apart by position alone at that scale;
/// on paper1997 zero feedforward and the paper's robust choice are 1.8 % apart, the optimal and
/// the worst-case robust choice 1.4 %).
fn coinciding(r: &SettleResponses) -> Vec<Option<usize>> {
    let all: Vec<f64> = r
        .responses
        .iter()
        .flat_map(|x| x.error_um.iter().copied())
        .filter(|v| v.is_finite())
        .collect();
    let span = match finite_range(&all) {
        AxisRange::Fixed { lo, hi } => hi - lo,
        AxisRange::Auto => return vec![None; r.responses.len()],
    };
    let gap = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .map(|(x, y)| (x - y).abs())
            .fold(0.0f64, f64::max)
    };
    (0..r.responses.len())
        .map(|i| {
            (0..i).find(|&j| {
                r.responses[i].error_um.len() == r.responses[j].error_um.len()
                    && gap(&r.responses[i].error_um, &r.responses[j].error_um) < 0.03 * span
            })
        })
        .collect()
}

/// Fig. 16: e(k) for each start-value choice with the ±δ window as a band; left the whole
/// response, right zoomed to ±5δ around the window. A response that lies on top of an earlier
/// one (see `coinciding`) is drawn with a dash pattern over it, and its legend entry says which
/// one it coincides with.
pub fn fig16_responses(r: &SettleResponses) -> String {
    let on_top = coinciding(r);
    // Each response's dash pattern: the k-th curve of a group drawn on top of each other gets
    // the k-th pattern (the first stays solid).
    let mut roots: Vec<usize> = Vec::with_capacity(on_top.len());
    for (i, j) in on_top.iter().enumerate() {
        let root = j.map_or(i, |j| roots[j]);
        roots.push(root);
    }
    let dash_index: Vec<usize> = (0..roots.len())
        .map(|i| (0..i).filter(|&k| roots[k] == roots[i]).count())
        .collect();
    let chart = |title: &str, zoom: bool| {
        let mut c = Chart::new(title)
            .size(520.0, 360.0)
            .x_label("time after handoff (ms)")
            .y_label("position error e (µm)")
            .hband(
                -r.delta_um,
                r.delta_um,
                format!("±δ = {} µm", fmt_num(r.delta_um)),
            );
        if zoom && r.delta_um.is_finite() && r.delta_um > 0.0 {
            c = c.y_range(AxisRange::Fixed {
                lo: -5.0 * r.delta_um,
                hi: 5.0 * r.delta_um,
            });
        }
        for (i, resp) in r.responses.iter().enumerate() {
            let settles = match resp.settle_ms {
                Some(s) => format!("settles {} ms", fmt_num(s)),
                None => "does not settle".into(),
            };
            let name = match on_top[i] {
                Some(j) => format!(
                    "{} ({settles}; coincides with {})",
                    resp.name, r.responses[j].name
                ),
                None => format!("{} ({settles})", resp.name),
            };
            let pts = per_sample(r.sample_period_ms, &resp.error_um);
            let mut s = Series::new(name, SeriesData::Line(pts)).color(i);
            if let Some(d) = DASHES[dash_index[i] % DASHES.len()] {
                s = s.dash(d);
            }
            c = c.series(s);
            if let Some(s) = resp.settle_ms {
                c = c.vline(s, "");
            }
        }
        c
    };
    Panel::new("Fig. 16 — position error after handoff for each start value")
        .columns(2)
        .chart(chart("whole response", false))
        .chart(chart("zoom on the ±δ window", true))
        .to_svg()
}
