//! Figures of a fitted memory and of a diagnosis: the Dahl loop, residuals against a feature, the
//! ladder of models.

use super::{bias_label, position_label};
use crate::log::Units;
use crate::plot::svg::{AxisRange, Chart, ErrorPoint, Panel, Series, SeriesData, fmt_num};

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
