//! Chart primitives: a hand-written SVG line/scatter/bar chart with linear axes, and a panel that
//! places several charts side by side in one SVG.
//!
//! Text uses a generic `font-family="sans-serif"`, so the SVG renders the same anywhere without
//! font files. Every series is one group `<g class="series" data-name="…" data-kind="…"
//! data-points="n">` holding its marks (`<circle class="point">` for markers, `<path
//! class="line">` for lines and steps, `<rect class="bar">` for bars, `<line class="err">` for
//! error bars), so a test or a script can find and count them. Reference lines and bands are
//! `<g class="reference">`, the legend is `<g class="legend">`.
//!
//! Rules that hold for any input:
//! - non-finite values (NaN, ±∞) are skipped and counted ([`Chart::non_finite_count`]); the
//!   count is kept in an undrawn `<desc class="skipped">`, and the SVG never contains `NaN` or
//!   `inf`;
//! - a scatter series of more than [`SCATTER_FULL_LIMIT`] points is density-drawn (one mark per
//!   [`SCATTER_CELL_PX`]-pixel cell), `data-points` still counting every point;
//! - a chart with no finite data shows "no data" in its plot area, one with a single point says
//!   so; nothing panics;
//! - the same chart always gives the same bytes.
//!
//! Automatic ranges run from the smallest to the largest value (reference lines and bands
//! included) widened by [`AXIS_PADDING`] of the span on each side, so extreme points are drawn
//! whole inside the frame; ticks are "nice" (1-2-5 steps) inside the range.
//!
//! ```
//! use biasctl::plot::{AxisRange, Chart};
//! let svg = Chart::new("bias vs position")
//!     .x_label("position (tracks)")
//!     .y_label("bias (counts)")
//!     .scatter("inbound", &[(0.0, 1.0), (100.0, 3.0)])
//!     .line("fit", &[(0.0, 1.2), (100.0, 2.8)])
//!     .y_range(AxisRange::Fixed { lo: 0.0, hi: 4.0 })
//!     .to_svg();
//! assert!(svg.contains(r#"data-name="inbound""#));
//! ```

mod axes;
mod chart;
mod layout;
mod marks;
mod overlay;
mod panel;
mod series;
mod text;

pub use axes::AXIS_PADDING;
pub use chart::Chart;
pub use layout::Layout;
pub use marks::SCATTER_CELL_PX;
pub use panel::Panel;
pub use series::{AxisRange, ErrorPoint, PALETTE, Reference, Series, SeriesData};
pub(crate) use text::esc;
pub use text::fmt_num;

#[cfg(test)]
mod tests;
