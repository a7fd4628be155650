//! Figs. 3 and 4: measured bias against position (inbound and outbound) and against time.

use super::{INBOUND_COLOR, OUTBOUND_COLOR, bias_label, position_label};
use crate::log::Units;
use crate::plot::svg::{Chart, Series, SeriesData, fmt_num};

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
