//! What a chart draws: axis ranges, series and their data, reference lines and bands,
//! annotations, and the palette.

use super::AXIS_PADDING;
use super::text::esc;

/// A fixed colour-blind-safe palette (Okabe–Ito order, yellow last because it is faint on white).
pub const PALETTE: [&str; 8] = [
    "#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000", "#F0E442",
];

/// Colour of faint background points and reference lines.
pub(crate) const GREY: &str = "#8c8c8c";

/// The range of one axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AxisRange {
    /// From the smallest to the largest value drawn on this axis, widened by
    /// [`AXIS_PADDING`] of the span on each side so extreme marks are not clipped by the frame.
    Auto,
    /// A fixed range; data outside it is clipped. A non-finite or empty range falls back to
    /// [`AxisRange::Auto`].
    Fixed {
        /// Lower end, axis units.
        lo: f64,
        /// Upper end, axis units.
        hi: f64,
    },
}

impl AxisRange {
    /// A fixed range widened by [`AXIS_PADDING`] of its span on each side, as an automatic
    /// range is: for a range computed from the data itself (a range shared by several charts),
    /// so the extreme points are drawn whole inside the frame. [`AxisRange::Auto`] and invalid
    /// ranges are returned as they are.
    pub fn padded(self) -> Self {
        match self {
            AxisRange::Fixed { lo, hi } if lo.is_finite() && hi.is_finite() && hi > lo => {
                let pad = AXIS_PADDING * (hi - lo);
                AxisRange::Fixed {
                    lo: lo - pad,
                    hi: hi + pad,
                }
            }
            other => other,
        }
    }
}

/// One point of an error-bar series: a binned mean with its spread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorPoint {
    /// Position on the x axis (for example the bin centre).
    pub x: f64,
    /// The mean.
    pub y: f64,
    /// Half-length of the bar: the bar runs from `y − spread` to `y + spread`.
    pub spread: f64,
    /// Marker weight (for example the bin count); marker area grows with it. Non-positive or
    /// non-finite weights draw the smallest marker.
    pub weight: f64,
}

/// The data of a series, by kind.
#[derive(Debug, Clone, PartialEq)]
pub enum SeriesData {
    /// Points `(x, y)` joined by straight lines, in the given order.
    Line(Vec<(f64, f64)>),
    /// Markers at `(x, y)`.
    Scatter(Vec<(f64, f64)>),
    /// A staircase: from each point horizontally to the next point's x, then vertically.
    Step(Vec<(f64, f64)>),
    /// Bars between consecutive `edges` with the given `heights` (a histogram); `edges` has one
    /// more entry than `heights` (extra entries on either side are ignored). Bars start at 0.
    Bars {
        /// Bar edges, x units, increasing.
        edges: Vec<f64>,
        /// Bar heights, y units.
        heights: Vec<f64>,
    },
    /// Binned means with error bars and weighted markers.
    ErrorBars(Vec<ErrorPoint>),
}

impl SeriesData {
    pub(super) fn kind(&self) -> &'static str {
        match self {
            SeriesData::Line(_) => "line",
            SeriesData::Scatter(_) => "scatter",
            SeriesData::Step(_) => "step",
            SeriesData::Bars { .. } => "bars",
            SeriesData::ErrorBars(_) => "errorbars",
        }
    }
}

/// A named series with its style.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Name shown in the legend and in `data-name`; an empty name keeps it out of the legend.
    pub name: String,
    /// The data.
    pub data: SeriesData,
    /// Palette index (wraps around); `None` takes the next free palette colour in series order.
    pub color: Option<usize>,
    /// Dashed line (lines and steps): `6 4` unless [`Series::dash_pattern`] says otherwise.
    pub dashed: bool,
    /// An SVG `stroke-dasharray` (for example `"2 3"`) for lines and steps; takes precedence
    /// over [`Series::dashed`]. Distinguishes curves that lie on top of each other.
    pub dash_pattern: Option<&'static str>,
    /// Faint grey marks for background data (for example raw residuals behind binned means).
    pub faint: bool,
    /// Also draw a marker at every point of a line or step series.
    pub markers: bool,
    /// Width of each bar as a fraction of its bin (bars series), in (0, 1]; 1 fills the bin.
    pub bar_width: f64,
}

impl Series {
    /// A series with automatic colour, solid and not faint.
    pub fn new(name: impl Into<String>, data: SeriesData) -> Self {
        Series {
            name: name.into(),
            data,
            color: None,
            dashed: false,
            dash_pattern: None,
            faint: false,
            markers: false,
            bar_width: 1.0,
        }
    }

    /// Uses palette colour `index` (wraps around).
    pub fn color(mut self, index: usize) -> Self {
        self.color = Some(index);
        self
    }

    /// Draws lines and steps dashed.
    pub fn dashed(mut self) -> Self {
        self.dashed = true;
        self
    }

    /// Draws lines and steps with the SVG dash pattern `pattern` (`stroke-dasharray`, for
    /// example `"2 3"`: 2 px drawn, 3 px gap).
    pub fn dash(mut self, pattern: &'static str) -> Self {
        self.dash_pattern = Some(pattern);
        self
    }

    /// The `stroke-dasharray` attribute of the series' lines (empty for solid lines).
    pub(super) fn dash_attr(&self) -> String {
        match (self.dash_pattern, self.dashed) {
            (Some(p), _) => format!(r#" stroke-dasharray="{}""#, esc(p)),
            (None, true) => r#" stroke-dasharray="6 4""#.to_string(),
            (None, false) => String::new(),
        }
    }

    /// Draws the series in faint grey.
    pub fn faint(mut self) -> Self {
        self.faint = true;
        self
    }

    /// Narrows bars to `fraction` of their bin (bars series); values outside (0, 1) fill the bin.
    pub fn bar_width(mut self, fraction: f64) -> Self {
        self.bar_width = fraction;
        self
    }

    /// Draws a marker at every point of a line or step series as well.
    pub fn markers(mut self) -> Self {
        self.markers = true;
        self
    }
}

/// A reference line or band, drawn behind (bands) or over (lines) the data.
#[derive(Debug, Clone, PartialEq)]
pub enum Reference {
    /// A horizontal line at `y`.
    HLine {
        /// Height, y units.
        y: f64,
        /// Label written at the right end of the line (may be empty).
        label: String,
    },
    /// A vertical line at `x`.
    VLine {
        /// Position, x units.
        x: f64,
        /// Label written at the top of the line (may be empty).
        label: String,
    },
    /// A shaded horizontal band between `lo` and `hi` (for example the ±δ settle window).
    HBand {
        /// Lower edge, y units.
        lo: f64,
        /// Upper edge, y units.
        hi: f64,
        /// Label written inside the band at its left end (may be empty).
        label: String,
    },
}

/// A text placed at a data position (centred, just above it).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Annotation {
    /// x, data units.
    pub x: f64,
    /// y, data units.
    pub y: f64,
    /// The text.
    pub text: String,
}
