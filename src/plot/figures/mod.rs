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

use crate::log::Units;

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

mod diagnosis;
mod errors;
mod measured;
mod settle;
mod sweep;

pub use diagnosis::{
    DahlLoop, FeatureResiduals, LadderStep, ResidualBin, dahl_loop, diagnose_panel, ladder,
};
pub use errors::{ModelErrors, errors_overlap, prediction_errors};
pub(crate) use measured::position_chart;
pub use measured::{BiasVsPosition, BiasVsTime, fig3_bias_vs_position, fig4_bias_vs_time};
pub use settle::{Response, SettleBounds, SettleResponses, fig15_settle_bounds, fig16_responses};
pub use sweep::{Sweep, SweepFigure, SweepSeries, calibration_sweep};
