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

use std::fmt::Write;

use crate::log::fmt_trimmed;

/// A fixed colour-blind-safe palette (Okabe–Ito order, yellow last because it is faint on white).
pub const PALETTE: [&str; 8] = [
    "#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000", "#F0E442",
];

/// Colour of faint background points and reference lines.
pub(crate) const GREY: &str = "#8c8c8c";

const FONT: f64 = 12.0;
const CHAR_W: f64 = 0.6 * FONT;

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
    fn kind(&self) -> &'static str {
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
    fn dash_attr(&self) -> String {
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

/// A chart with linear axes. Build it with the chained methods, render with [`Chart::to_svg`].
#[derive(Debug, Clone, PartialEq)]
pub struct Chart {
    title: String,
    x_label: String,
    y_label: String,
    x_range: AxisRange,
    y_range: AxisRange,
    width: f64,
    height: f64,
    series: Vec<Series>,
    references: Vec<Reference>,
    annotations: Vec<Annotation>,
    x_ticks: Option<Vec<(f64, String)>>,
}

/// Where a chart's plot area lies and how data maps to pixels (what [`Chart::to_svg`] uses).
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// Total width, px.
    pub width: f64,
    /// Total height, px.
    pub height: f64,
    /// Left edge of the plot area, px.
    pub left: f64,
    /// Right edge of the plot area, px.
    pub right: f64,
    /// Top edge of the plot area, px.
    pub top: f64,
    /// Bottom edge of the plot area, px.
    pub bottom: f64,
    /// x value at the left edge.
    pub x_lo: f64,
    /// x value at the right edge.
    pub x_hi: f64,
    /// y value at the bottom edge.
    pub y_lo: f64,
    /// y value at the top edge.
    pub y_hi: f64,
    /// Number of finite data marks (points, bars, error points) in all series.
    pub points: usize,
    /// Number of non-finite values skipped.
    pub skipped: usize,
    x_ticks: Vec<(f64, String)>,
    y_ticks: Vec<(f64, String)>,
    rotate_x_ticks: bool,
    title_size: f64,
    legend: Vec<LegendItem>,
}

#[derive(Debug, Clone, PartialEq)]
struct LegendItem {
    series: usize,
    x: f64,
    y: f64,
}

impl Layout {
    /// Pixel x of data value `x`.
    pub fn px(&self, x: f64) -> f64 {
        self.left + (x - self.x_lo) / (self.x_hi - self.x_lo) * (self.right - self.left)
    }

    /// Pixel y of data value `y` (SVG y grows downwards).
    pub fn py(&self, y: f64) -> f64 {
        self.bottom - (y - self.y_lo) / (self.y_hi - self.y_lo) * (self.bottom - self.top)
    }

    fn inside(&self, x: f64, y: f64) -> bool {
        let (xa, xb) = ordered(self.x_lo, self.x_hi);
        let (ya, yb) = ordered(self.y_lo, self.y_hi);
        x >= xa && x <= xb && y >= ya && y <= yb
    }
}

fn ordered(a: f64, b: f64) -> (f64, f64) {
    if a <= b { (a, b) } else { (b, a) }
}

impl Chart {
    /// An empty chart 640 × 400 px with the given title.
    pub fn new(title: impl Into<String>) -> Self {
        Chart {
            title: title.into(),
            x_label: String::new(),
            y_label: String::new(),
            x_range: AxisRange::Auto,
            y_range: AxisRange::Auto,
            width: 640.0,
            height: 400.0,
            series: Vec::new(),
            references: Vec::new(),
            annotations: Vec::new(),
            x_ticks: None,
        }
    }

    /// The x-axis label; give the unit, e.g. `"position (tracks)"`.
    pub fn x_label(mut self, label: impl Into<String>) -> Self {
        self.x_label = label.into();
        self
    }

    /// The y-axis label; give the unit, e.g. `"bias (counts)"`.
    pub fn y_label(mut self, label: impl Into<String>) -> Self {
        self.y_label = label.into();
        self
    }

    /// The x range (default [`AxisRange::Auto`]).
    pub fn x_range(mut self, range: AxisRange) -> Self {
        self.x_range = range;
        self
    }

    /// The y range (default [`AxisRange::Auto`]).
    pub fn y_range(mut self, range: AxisRange) -> Self {
        self.y_range = range;
        self
    }

    /// Total size in px (clamped to at least 200 × 150; the height grows if the legend needs it).
    pub fn size(mut self, width: f64, height: f64) -> Self {
        self.width = if width.is_finite() {
            width.max(200.0)
        } else {
            640.0
        };
        self.height = if height.is_finite() {
            height.max(150.0)
        } else {
            400.0
        };
        self
    }

    /// Replaces the automatic x ticks by labelled positions (categorical axes such as a ladder of
    /// terms). Long labels are drawn slanted.
    pub fn x_tick_labels(mut self, ticks: Vec<(f64, String)>) -> Self {
        self.x_ticks = Some(ticks);
        self
    }

    /// Adds a series.
    pub fn series(mut self, series: Series) -> Self {
        self.series.push(series);
        self
    }

    /// Adds a line series (automatic colour).
    pub fn line(self, name: impl Into<String>, points: &[(f64, f64)]) -> Self {
        self.series(Series::new(name, SeriesData::Line(points.to_vec())))
    }

    /// Adds a scatter series (automatic colour).
    pub fn scatter(self, name: impl Into<String>, points: &[(f64, f64)]) -> Self {
        self.series(Series::new(name, SeriesData::Scatter(points.to_vec())))
    }

    /// Adds a step series (automatic colour).
    pub fn step(self, name: impl Into<String>, points: &[(f64, f64)]) -> Self {
        self.series(Series::new(name, SeriesData::Step(points.to_vec())))
    }

    /// Adds a bar series (histogram) with `edges.len() == heights.len() + 1`.
    pub fn bars(self, name: impl Into<String>, edges: &[f64], heights: &[f64]) -> Self {
        self.series(Series::new(
            name,
            SeriesData::Bars {
                edges: edges.to_vec(),
                heights: heights.to_vec(),
            },
        ))
    }

    /// Adds an error-bar series (binned mean ± spread with weighted markers).
    pub fn error_bars(self, name: impl Into<String>, points: &[ErrorPoint]) -> Self {
        self.series(Series::new(name, SeriesData::ErrorBars(points.to_vec())))
    }

    /// Adds a reference line or band.
    pub fn reference(mut self, reference: Reference) -> Self {
        self.references.push(reference);
        self
    }

    /// Adds a horizontal reference line.
    pub fn hline(self, y: f64, label: impl Into<String>) -> Self {
        self.reference(Reference::HLine {
            y,
            label: label.into(),
        })
    }

    /// Adds a vertical reference line.
    pub fn vline(self, x: f64, label: impl Into<String>) -> Self {
        self.reference(Reference::VLine {
            x,
            label: label.into(),
        })
    }

    /// Adds a shaded horizontal band from `lo` to `hi`.
    pub fn hband(self, lo: f64, hi: f64, label: impl Into<String>) -> Self {
        self.reference(Reference::HBand {
            lo,
            hi,
            label: label.into(),
        })
    }

    /// Adds a text annotation at a data position.
    pub fn annotate(mut self, x: f64, y: f64, text: impl Into<String>) -> Self {
        self.annotations.push(Annotation {
            x,
            y,
            text: text.into(),
        });
        self
    }

    /// Number of series.
    pub fn series_count(&self) -> usize {
        self.series.len()
    }

    /// Number of non-finite values that are skipped when drawing (in series, references and
    /// annotations).
    pub fn non_finite_count(&self) -> usize {
        self.extents().skipped
    }

    fn color_of(&self, index: usize) -> &'static str {
        let s = &self.series[index];
        if s.faint {
            return GREY;
        }
        let slot = match s.color {
            Some(c) => c,
            None => self.series[..index]
                .iter()
                .filter(|s| s.color.is_none() && !s.faint)
                .count(),
        };
        PALETTE[slot % PALETTE.len()]
    }

    fn extents(&self) -> Extents {
        let mut e = Extents::default();
        for s in &self.series {
            match &s.data {
                SeriesData::Line(p) | SeriesData::Scatter(p) | SeriesData::Step(p) => {
                    for &(x, y) in p {
                        if x.is_finite() && y.is_finite() {
                            e.x.add(x);
                            e.y.add(y);
                            e.points += 1;
                        } else {
                            e.skipped += 1;
                        }
                    }
                }
                SeriesData::Bars { edges, heights } => {
                    for (i, &h) in heights.iter().enumerate() {
                        match bar(edges, heights, i) {
                            Some((a, b)) => {
                                e.x.add(a);
                                e.x.add(b);
                                e.y.add(h);
                                e.y.add(0.0);
                                e.points += 1;
                            }
                            None if i + 1 < edges.len() => e.skipped += 1,
                            None => {}
                        }
                    }
                }
                SeriesData::ErrorBars(p) => {
                    for q in p {
                        if q.x.is_finite() && q.y.is_finite() && q.spread.is_finite() {
                            e.x.add(q.x);
                            e.y.add(q.y - q.spread.abs());
                            e.y.add(q.y + q.spread.abs());
                            e.points += 1;
                        } else {
                            e.skipped += 1;
                        }
                    }
                }
            }
        }
        for r in &self.references {
            match r {
                Reference::HLine { y, .. } => e.y.add_or_skip(*y, &mut e.skipped),
                Reference::VLine { x, .. } => e.x.add_or_skip(*x, &mut e.skipped),
                Reference::HBand { lo, hi, .. } => {
                    e.y.add_or_skip(*lo, &mut e.skipped);
                    e.y.add_or_skip(*hi, &mut e.skipped);
                }
            }
        }
        for a in &self.annotations {
            if !(a.x.is_finite() && a.y.is_finite()) {
                e.skipped += 1;
            }
        }
        e
    }

    /// Computes the layout: ranges, ticks, plot-area position, legend placement.
    pub fn layout(&self) -> Layout {
        let ext = self.extents();
        let (x_lo, x_hi) = resolve(self.x_range, ext.x);
        let (y_lo, y_hi) = resolve(self.y_range, ext.y);
        let has_data = ext.points > 0;
        let x_ticks = match &self.x_ticks {
            Some(t) => t
                .iter()
                .filter(|(x, _)| x.is_finite() && *x >= x_lo.min(x_hi) && *x <= x_hi.max(x_lo))
                .cloned()
                .collect(),
            None if has_data => tick_labels(x_lo, x_hi, ticks_for(self.width, 90.0)),
            None => Vec::new(),
        };
        let y_ticks = if has_data {
            tick_labels(y_lo, y_hi, ticks_for(self.height, 50.0))
        } else {
            Vec::new()
        };
        let y_tick_w = y_ticks
            .iter()
            .map(|(_, s)| text_width(s, FONT))
            .fold(0.0, f64::max);
        let left = 8.0 + if self.y_label.is_empty() { 0.0 } else { 18.0 } + y_tick_w + 8.0;
        let right_pad = 18.0;
        let plot_w = (self.width - left - right_pad).max(60.0);
        let width = left + plot_w + right_pad;
        let spacing = plot_w / (x_ticks.len().max(1) as f64);
        let x_tick_w = x_ticks
            .iter()
            .map(|(_, s)| text_width(s, FONT))
            .fold(0.0, f64::max);
        let rotate_x_ticks = self.x_ticks.is_some() && x_tick_w + 6.0 > spacing;
        let x_tick_h = if rotate_x_ticks {
            x_tick_w * 0.6 + 14.0
        } else {
            18.0
        };
        let title_size = if self.title.is_empty() {
            0.0
        } else {
            (14.0f64).min((width - 16.0) / (self.title.chars().count().max(1) as f64 * 0.6))
        };
        let top = if self.title.is_empty() {
            12.0
        } else {
            title_size + 16.0
        };
        // Legend: items in rows below the x-axis label, never over the data.
        // A lone series needs no legend (the title and axis labels say what it is).
        let named = self.series.iter().filter(|s| !s.name.is_empty()).count();
        let mut legend = Vec::new();
        let (mut lx, mut row) = (0.0f64, 0usize);
        for (i, s) in self.series.iter().enumerate() {
            if s.name.is_empty() || named < 2 {
                continue;
            }
            let w = 28.0 + text_width(&s.name, FONT) + 16.0;
            if lx > 0.0 && lx + w > width - 16.0 {
                lx = 0.0;
                row += 1;
            }
            legend.push(LegendItem {
                series: i,
                x: lx,
                y: row as f64,
            });
            lx += w;
        }
        let legend_h = if legend.is_empty() {
            0.0
        } else {
            (row + 1) as f64 * 18.0 + 6.0
        };
        let x_label_h = if self.x_label.is_empty() { 0.0 } else { 20.0 };
        let bottom_pad = x_tick_h + x_label_h + legend_h + 8.0;
        let plot_h = (self.height - top - bottom_pad).max(60.0);
        let height = top + plot_h + bottom_pad;
        let (base_y, base_x) = (top + plot_h + x_tick_h + x_label_h + 14.0, 16.0);
        for item in &mut legend {
            item.x += base_x;
            item.y = base_y + item.y * 18.0;
        }
        Layout {
            width,
            height,
            left,
            right: left + plot_w,
            top,
            bottom: top + plot_h,
            x_lo,
            x_hi,
            y_lo,
            y_hi,
            points: ext.points,
            skipped: ext.skipped,
            x_ticks,
            y_ticks,
            rotate_x_ticks,
            title_size,
            legend,
        }
    }

    /// Renders the chart as a standalone SVG document.
    pub fn to_svg(&self) -> String {
        let lay = self.layout();
        let mut out = String::new();
        svg_open(&mut out, lay.width, lay.height);
        self.render(&lay, &mut out);
        out.push_str("</svg>\n");
        out
    }

    fn render(&self, lay: &Layout, out: &mut String) {
        let _ = writeln!(
            out,
            r##"<rect class="background" x="0" y="0" width="{}" height="{}" fill="#ffffff"/>"##,
            n(lay.width),
            n(lay.height)
        );
        if !self.title.is_empty() {
            let _ = writeln!(
                out,
                r#"<text class="title" x="{}" y="{}" text-anchor="middle" font-size="{}" font-weight="bold">{}</text>"#,
                n(lay.width / 2.0),
                n(lay.title_size + 6.0),
                n(lay.title_size),
                esc(&self.title)
            );
        }
        for r in &self.references {
            if let Reference::HBand { lo, hi, label } = r {
                self.render_band(lay, *lo, *hi, label, out);
            }
        }
        self.render_axes(lay, out);
        for i in 0..self.series.len() {
            self.render_series(lay, i, out);
        }
        let mut placed = Vec::new();
        for r in &self.references {
            self.render_reference_line(lay, r, &mut placed, out);
        }
        for a in &self.annotations {
            if a.x.is_finite() && a.y.is_finite() && lay.inside(a.x, a.y) {
                let _ = writeln!(
                    out,
                    r#"<text class="annotation" x="{}" y="{}" text-anchor="middle" font-size="11">{}</text>"#,
                    n(lay.px(a.x)),
                    n(lay.py(a.y) - 6.0),
                    esc(&a.text)
                );
            }
        }
        let cx = (lay.left + lay.right) / 2.0;
        let message = match lay.points {
            0 => Some("no data".to_string()),
            1 => Some("only one point".to_string()),
            _ => None,
        };
        if let Some(m) = message {
            let y = if lay.points == 0 {
                (lay.top + lay.bottom) / 2.0
            } else {
                lay.top + 20.0
            };
            let _ = writeln!(
                out,
                r##"<text class="message" x="{}" y="{}" text-anchor="middle" font-size="14" fill="#555555">{}</text>"##,
                n(cx),
                n(y),
                m
            );
        }
        // The count of skipped values is for tools and tests, not the reader: a `<desc>` is
        // not drawn.
        if lay.skipped > 0 {
            let _ = writeln!(
                out,
                r##"<desc class="skipped">{} non-finite value{} skipped</desc>"##,
                lay.skipped,
                if lay.skipped == 1 { "" } else { "s" }
            );
        }
        self.render_legend(lay, out);
    }

    fn render_axes(&self, lay: &Layout, out: &mut String) {
        out.push_str(r#"<g class="axes">"#);
        out.push('\n');
        for (v, label) in &lay.y_ticks {
            let y = lay.py(*v);
            let _ = writeln!(
                out,
                r##"<line class="grid" x1="{l}" y1="{y}" x2="{r}" y2="{y}" stroke="#e6e6e6"/><text class="tick" x="{}" y="{}" text-anchor="end">{}</text>"##,
                n(lay.left - 6.0),
                n(y + 4.0),
                esc(label),
                l = n(lay.left),
                r = n(lay.right),
                y = n(y),
            );
        }
        for (v, label) in &lay.x_ticks {
            let x = lay.px(*v);
            let ty = lay.bottom + 16.0;
            let text = if lay.rotate_x_ticks {
                format!(
                    r#"<text class="tick" x="{x}" y="{ty}" text-anchor="end" transform="rotate(-35 {x} {ty})">{}</text>"#,
                    esc(label),
                    x = n(x + 4.0),
                    ty = n(ty - 4.0),
                )
            } else {
                format!(
                    r#"<text class="tick" x="{}" y="{}" text-anchor="middle">{}</text>"#,
                    n(x),
                    n(ty),
                    esc(label)
                )
            };
            let _ = writeln!(
                out,
                r##"<line class="grid" x1="{x}" y1="{t}" x2="{x}" y2="{b}" stroke="#e6e6e6"/>{text}"##,
                x = n(x),
                t = n(lay.top),
                b = n(lay.bottom),
            );
        }
        let _ = writeln!(
            out,
            r##"<rect class="frame" x="{}" y="{}" width="{}" height="{}" fill="none" stroke="#333333"/>"##,
            n(lay.left),
            n(lay.top),
            n(lay.right - lay.left),
            n(lay.bottom - lay.top)
        );
        if !self.x_label.is_empty() {
            let tick_h = if lay.rotate_x_ticks {
                lay.x_ticks
                    .iter()
                    .map(|(_, s)| text_width(s, FONT))
                    .fold(0.0, f64::max)
                    * 0.6
                    + 14.0
            } else {
                18.0
            };
            let _ = writeln!(
                out,
                r#"<text class="xlabel" x="{}" y="{}" text-anchor="middle" font-size="13">{}</text>"#,
                n((lay.left + lay.right) / 2.0),
                n(lay.bottom + tick_h + 16.0),
                esc(&self.x_label)
            );
        }
        if !self.y_label.is_empty() {
            let (x, y) = (14.0, (lay.top + lay.bottom) / 2.0);
            let _ = writeln!(
                out,
                r#"<text class="ylabel" x="{x}" y="{y}" text-anchor="middle" font-size="13" transform="rotate(-90 {x} {y})">{}</text>"#,
                esc(&self.y_label),
                x = n(x),
                y = n(y),
            );
        }
        out.push_str("</g>\n");
    }

    fn render_series(&self, lay: &Layout, index: usize, out: &mut String) {
        let s = &self.series[index];
        let color = self.color_of(index);
        let mut body = String::new();
        let mut count = 0usize;
        let dash = s.dash_attr();
        match &s.data {
            SeriesData::Line(p) | SeriesData::Step(p) => {
                let step = matches!(s.data, SeriesData::Step(_));
                let finite = |(x, y): (f64, f64)| x.is_finite() && y.is_finite();
                let pts: Vec<(f64, f64)> = p.iter().copied().filter(|&q| finite(q)).collect();
                count = pts.len();
                let mut segs = Vec::with_capacity(p.len() * 2);
                // A non-finite point leaves a gap: only neighbours that are both finite join.
                for w in p.windows(2).filter(|w| finite(w[0]) && finite(w[1])) {
                    let (a, b) = (w[0], w[1]);
                    if step {
                        segs.push((a, (b.0, a.1)));
                        segs.push(((b.0, a.1), b));
                    } else {
                        segs.push((a, b));
                    }
                }
                let d = path_data(lay, &segs);
                if !d.is_empty() {
                    let _ = writeln!(
                        body,
                        r#"<path class="line" d="{d}" fill="none" stroke="{color}" stroke-width="{}"{dash}/>"#,
                        if s.faint { "1" } else { "1.8" }
                    );
                }
                for &p in &pts {
                    if (s.markers || pts.len() == 1) && lay.inside(p.0, p.1) {
                        point(&mut body, lay, p, 3.0, color);
                    }
                }
            }
            SeriesData::Scatter(p) => {
                let r = if s.faint { 2.0 } else { 3.0 };
                let dense = p.len() > SCATTER_FULL_LIMIT;
                let mut cells = std::collections::HashSet::new();
                for &(x, y) in p {
                    if x.is_finite() && y.is_finite() {
                        count += 1;
                        let cell = (
                            (lay.px(x) / SCATTER_CELL_PX).floor() as i64,
                            (lay.py(y) / SCATTER_CELL_PX).floor() as i64,
                        );
                        if lay.inside(x, y) && (!dense || cells.insert(cell)) {
                            point(&mut body, lay, (x, y), r, color);
                        }
                    }
                }
            }
            SeriesData::Bars { edges, heights } => {
                let (ya, yb) = ordered(lay.y_lo, lay.y_hi);
                let (xa, xb) = ordered(lay.x_lo, lay.x_hi);
                for i in 0..heights.len() {
                    let Some((a, b)) = bar(edges, heights, i) else {
                        continue;
                    };
                    count += 1;
                    let f = if s.bar_width > 0.0 && s.bar_width < 1.0 {
                        s.bar_width
                    } else {
                        1.0
                    };
                    let (mid, half) = ((a + b) / 2.0, (b - a) * f / 2.0);
                    let (a, b) = ((mid - half).max(xa), (mid + half).min(xb));
                    if a >= b {
                        continue;
                    }
                    let (h0, h1) = ordered(0.0f64.clamp(ya, yb), heights[i].clamp(ya, yb));
                    let (x0, x1) = ordered(lay.px(a), lay.px(b));
                    let (y0, y1) = ordered(lay.py(h1), lay.py(h0));
                    let _ = writeln!(
                        body,
                        r##"<rect class="bar" x="{}" y="{}" width="{}" height="{}" fill="{color}" fill-opacity="0.6" stroke="#ffffff" stroke-width="1"/>"##,
                        n(x0),
                        n(y0),
                        n(x1 - x0),
                        n(y1 - y0)
                    );
                }
            }
            SeriesData::ErrorBars(p) => {
                let wmax = p
                    .iter()
                    .map(|q| q.weight)
                    .filter(|w| w.is_finite())
                    .fold(0.0, f64::max);
                let (ya, yb) = ordered(lay.y_lo, lay.y_hi);
                for q in p {
                    if !(q.x.is_finite() && q.y.is_finite() && q.spread.is_finite()) {
                        continue;
                    }
                    count += 1;
                    if !lay.inside(q.x, q.y) {
                        continue;
                    }
                    let x = lay.px(q.x);
                    let s0 = lay.py((q.y - q.spread.abs()).clamp(ya, yb));
                    let s1 = lay.py((q.y + q.spread.abs()).clamp(ya, yb));
                    let _ = write!(
                        body,
                        r#"<line class="err" x1="{x}" y1="{}" x2="{x}" y2="{}" stroke="{color}" stroke-width="1.2"/>"#,
                        n(s0),
                        n(s1),
                        x = n(x)
                    );
                    let w = if q.weight.is_finite() && q.weight > 0.0 && wmax > 0.0 {
                        (q.weight / wmax).sqrt()
                    } else {
                        0.0
                    };
                    point(&mut body, lay, (q.x, q.y), 2.0 + 5.0 * w, color);
                }
            }
        }
        let _ = writeln!(
            out,
            r#"<g class="series" data-name="{}" data-kind="{}" data-points="{count}">"#,
            esc(&s.name),
            s.data.kind()
        );
        out.push_str(&body);
        out.push_str("</g>\n");
    }

    fn render_band(&self, lay: &Layout, lo: f64, hi: f64, label: &str, out: &mut String) {
        if !(lo.is_finite() && hi.is_finite()) || lay.points == 0 {
            return;
        }
        let (ya, yb) = ordered(lay.y_lo, lay.y_hi);
        let (lo, hi) = ordered(lo.clamp(ya, yb), hi.clamp(ya, yb));
        let (y0, y1) = ordered(lay.py(hi), lay.py(lo));
        let _ = writeln!(
            out,
            r##"<g class="reference" data-kind="band"><rect x="{}" y="{}" width="{}" height="{}" fill="#56B4E9" fill-opacity="0.22"/>"##,
            n(lay.left),
            n(y0),
            n(lay.right - lay.left),
            n((y1 - y0).max(1.0)),
        );
        if !label.is_empty() {
            let _ = write!(
                out,
                r##"<text x="{}" y="{}" text-anchor="end" font-size="11" fill="#33617d">{}</text>"##,
                n(lay.right - 4.0),
                n(y0 - 3.0),
                esc(label)
            );
        }
        out.push_str("</g>\n");
    }

    /// Draws a reference line; its label is moved off labels already `placed` (boxes
    /// `(x0, x1, baseline y)`) so that close lines keep readable labels.
    fn render_reference_line(
        &self,
        lay: &Layout,
        r: &Reference,
        placed: &mut Vec<(f64, f64, f64)>,
        out: &mut String,
    ) {
        if lay.points == 0 {
            return;
        }
        let (x1, y1, x2, y2, tx, ty, anchor, label) = match r {
            Reference::HLine { y, label } if y.is_finite() && lay.inside(lay.x_lo, *y) => {
                let py = lay.py(*y);
                (
                    lay.left,
                    py,
                    lay.right,
                    py,
                    lay.right - 4.0,
                    py - 4.0,
                    "end",
                    label,
                )
            }
            Reference::VLine { x, label } if x.is_finite() && lay.inside(*x, lay.y_lo) => {
                let px = lay.px(*x);
                (
                    px,
                    lay.top,
                    px,
                    lay.bottom,
                    px + 4.0,
                    lay.top + 12.0,
                    "start",
                    label,
                )
            }
            _ => return,
        };
        let _ = write!(
            out,
            r##"<g class="reference" data-kind="line"><line x1="{}" y1="{}" x2="{}" y2="{}" stroke="#555555" stroke-width="1.2" stroke-dasharray="3 3"/>"##,
            n(x1),
            n(y1),
            n(x2),
            n(y2)
        );
        if !label.is_empty() {
            let w = text_width(label, 11.0);
            let (x0, x1) = if anchor == "end" {
                (tx - w, tx)
            } else {
                (tx, tx + w)
            };
            let horizontal = anchor == "end";
            let free = |y: f64, placed: &[(f64, f64, f64)]| {
                placed
                    .iter()
                    .all(|&(a, b, py)| b < x0 || a > x1 || (py - y).abs() >= 12.0)
            };
            // Horizontal lines: above, below, then further out; vertical lines: step down.
            let ty = (0..12)
                .map(|i| {
                    let k = f64::from(i);
                    if horizontal {
                        if i % 2 == 0 {
                            ty - 6.0 * k
                        } else {
                            ty + 16.0 + 6.0 * (k - 1.0)
                        }
                    } else {
                        ty + 12.0 * k
                    }
                })
                .find(|&y| free(y, placed))
                .unwrap_or(ty);
            placed.push((x0, x1, ty));
            let _ = write!(
                out,
                r##"<text x="{}" y="{}" text-anchor="{anchor}" font-size="11" fill="#333333">{}</text>"##,
                n(tx),
                n(ty),
                esc(label)
            );
        }
        out.push_str("</g>\n");
    }

    fn render_legend(&self, lay: &Layout, out: &mut String) {
        if lay.legend.is_empty() {
            return;
        }
        out.push_str("<g class=\"legend\">\n");
        for item in &lay.legend {
            let s = &self.series[item.series];
            let color = self.color_of(item.series);
            let (x, y) = (item.x, item.y);
            let _ = write!(
                out,
                r#"<g class="legend-item" data-name="{}">"#,
                esc(&s.name)
            );
            match &s.data {
                SeriesData::Line(_) | SeriesData::Step(_) => {
                    let _ = write!(
                        out,
                        r#"<line x1="{}" y1="{}" x2="{}" y2="{}" stroke="{color}" stroke-width="2"{}/>"#,
                        n(x),
                        n(y - 4.0),
                        n(x + 22.0),
                        n(y - 4.0),
                        s.dash_attr()
                    );
                    if s.markers {
                        let _ = write!(
                            out,
                            r#"<circle cx="{}" cy="{}" r="3" fill="{color}"/>"#,
                            n(x + 11.0),
                            n(y - 4.0)
                        );
                    }
                }
                SeriesData::Bars { .. } => {
                    let _ = write!(
                        out,
                        r#"<rect x="{}" y="{}" width="16" height="10" fill="{color}" fill-opacity="0.55" stroke="{color}"/>"#,
                        n(x + 3.0),
                        n(y - 9.0)
                    );
                }
                SeriesData::Scatter(_) | SeriesData::ErrorBars(_) => {
                    let _ = write!(
                        out,
                        r#"<circle cx="{}" cy="{}" r="4" fill="{color}"/>"#,
                        n(x + 11.0),
                        n(y - 4.0)
                    );
                }
            }
            let _ = writeln!(
                out,
                r#"<text x="{}" y="{}">{}</text></g>"#,
                n(x + 28.0),
                n(y),
                esc(&s.name)
            );
        }
        out.push_str("</g>\n");
    }
}

fn point(out: &mut String, lay: &Layout, (x, y): (f64, f64), r: f64, color: &str) {
    let _ = write!(
        out,
        r#"<circle class="point" cx="{}" cy="{}" r="{}" fill="{color}" fill-opacity="0.8"/>"#,
        n(lay.px(x)),
        n(lay.py(y)),
        n(r)
    );
}

/// The bar `i` as `(left, right)` if its edges and height are finite.
fn bar(edges: &[f64], heights: &[f64], i: usize) -> Option<(f64, f64)> {
    let (a, b) = (*edges.get(i)?, *edges.get(i + 1)?);
    (a.is_finite() && b.is_finite() && heights[i].is_finite()).then(|| ordered(a, b))
}

/// A line segment between two data points.
type Segment = ((f64, f64), (f64, f64));

/// SVG path data for line segments in data units, clipped to the plot area; consecutive
/// segments that join are drawn as one polyline.
fn path_data(lay: &Layout, segs: &[Segment]) -> String {
    let mut d = String::new();
    let mut last: Option<(f64, f64)> = None;
    for &(a, b) in segs {
        let Some((a, b)) = clip(lay, a, b) else {
            last = None;
            continue;
        };
        let (pa, pb) = ((lay.px(a.0), lay.py(a.1)), (lay.px(b.0), lay.py(b.1)));
        let joined = last
            .is_some_and(|l: (f64, f64)| (l.0 - pa.0).abs() < 1e-9 && (l.1 - pa.1).abs() < 1e-9);
        if !joined {
            let _ = write!(
                d,
                "{}M{} {}",
                if d.is_empty() { "" } else { " " },
                n(pa.0),
                n(pa.1)
            );
        }
        let _ = write!(d, " L{} {}", n(pb.0), n(pb.1));
        last = Some(pb);
    }
    d
}

/// Liang–Barsky clipping of the segment a→b to the data range.
fn clip(lay: &Layout, a: (f64, f64), b: (f64, f64)) -> Option<Segment> {
    let (xa, xb) = ordered(lay.x_lo, lay.x_hi);
    let (ya, yb) = ordered(lay.y_lo, lay.y_hi);
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-dx, a.0 - xa),
        (dx, xb - a.0),
        (-dy, a.1 - ya),
        (dy, yb - a.1),
    ] {
        if p.abs() < f64::MIN_POSITIVE {
            if q < 0.0 {
                return None;
            }
        } else {
            let t = q / p;
            if p < 0.0 {
                t0 = t0.max(t);
            } else {
                t1 = t1.min(t);
            }
        }
    }
    (t0 <= t1).then_some((
        (a.0 + t0 * dx, a.1 + t0 * dy),
        (a.0 + t1 * dx, a.1 + t1 * dy),
    ))
}

/// A grid of charts in one SVG, filled row by row.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    title: String,
    columns: usize,
    charts: Vec<Chart>,
}

impl Panel {
    /// An empty panel with a title (may be empty) and three columns.
    pub fn new(title: impl Into<String>) -> Self {
        Panel {
            title: title.into(),
            columns: 3,
            charts: Vec::new(),
        }
    }

    /// Number of columns (at least 1).
    pub fn columns(mut self, columns: usize) -> Self {
        self.columns = columns.max(1);
        self
    }

    /// Adds a chart in the next cell.
    pub fn chart(mut self, chart: Chart) -> Self {
        self.charts.push(chart);
        self
    }

    /// Renders the panel as one SVG document; each chart is a `<g class="chart">`.
    pub fn to_svg(&self) -> String {
        let layouts: Vec<Layout> = self.charts.iter().map(Chart::layout).collect();
        let cols = self.columns.min(self.charts.len()).max(1);
        let cell_w = layouts.iter().map(|l| l.width).fold(200.0, f64::max);
        let title_h = if self.title.is_empty() { 0.0 } else { 30.0 };
        let mut row_tops = vec![title_h];
        for row in layouts.chunks(cols) {
            let h = row.iter().map(|l| l.height).fold(0.0, f64::max);
            let top = row_tops[row_tops.len() - 1];
            row_tops.push(top + h);
        }
        let width = cell_w * cols as f64;
        let height = if self.charts.is_empty() {
            title_h + 150.0
        } else {
            row_tops[row_tops.len() - 1]
        };
        let mut out = String::new();
        svg_open(&mut out, width, height);
        let _ = writeln!(
            out,
            r##"<rect class="background" x="0" y="0" width="{}" height="{}" fill="#ffffff"/>"##,
            n(width),
            n(height)
        );
        if !self.title.is_empty() {
            let size = 16.0f64.min((width - 16.0) / (self.title.chars().count() as f64 * 0.6));
            let _ = writeln!(
                out,
                r#"<text class="panel-title" x="{}" y="21" text-anchor="middle" font-size="{}" font-weight="bold">{}</text>"#,
                n(width / 2.0),
                n(size),
                esc(&self.title)
            );
        }
        if self.charts.is_empty() {
            let _ = writeln!(
                out,
                r##"<text class="message" x="{}" y="{}" text-anchor="middle" font-size="14" fill="#555555">no data</text>"##,
                n(width / 2.0),
                n(title_h + 75.0)
            );
        }
        for (i, (chart, lay)) in self.charts.iter().zip(&layouts).enumerate() {
            let (r, c) = (i / cols, i % cols);
            let _ = writeln!(
                out,
                r#"<g class="chart" transform="translate({} {})">"#,
                n(c as f64 * cell_w),
                n(row_tops[r])
            );
            chart.render(lay, &mut out);
            out.push_str("</g>\n");
        }
        out.push_str("</svg>\n");
        out
    }
}

fn svg_open(out: &mut String, width: f64, height: f64) {
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="{}">"#,
        n(FONT),
        w = n(width),
        h = n(height),
    );
}

#[derive(Debug, Clone, Copy, Default)]
struct Extent {
    lo: Option<f64>,
    hi: Option<f64>,
}

impl Extent {
    fn add(&mut self, v: f64) {
        self.lo = Some(self.lo.map_or(v, |l| l.min(v)));
        self.hi = Some(self.hi.map_or(v, |h| h.max(v)));
    }

    fn add_or_skip(&mut self, v: f64, skipped: &mut usize) {
        if v.is_finite() {
            self.add(v);
        } else {
            *skipped += 1;
        }
    }
}

#[derive(Debug, Clone, Copy, Default)]
struct Extents {
    x: Extent,
    y: Extent,
    points: usize,
    skipped: usize,
}

/// The drawn range of an axis: the fixed range if valid, else the data extent, widened when it
/// is a single value; `[0, 1]` with no data.
fn resolve(range: AxisRange, ext: Extent) -> (f64, f64) {
    if let AxisRange::Fixed { lo, hi } = range
        && lo.is_finite()
        && hi.is_finite()
        && hi > lo
    {
        return (lo, hi);
    }
    match (ext.lo, ext.hi) {
        (Some(lo), Some(hi)) if hi - lo > 1e-12 * lo.abs().max(hi.abs()) => {
            let pad = AXIS_PADDING * (hi - lo);
            (lo - pad, hi + pad)
        }
        (Some(v), Some(_)) => {
            let d = if v.abs() > 0.0 { v.abs() * 0.1 } else { 1.0 };
            (v - d, v + d)
        }
        _ => (0.0, 1.0),
    }
}

/// The fraction of the data span added on each side of an automatic axis range.
pub const AXIS_PADDING: f64 = 0.03;

/// A scatter series with more finite points than this is density-drawn: at most one mark per
/// [`SCATTER_CELL_PX`]-pixel cell (the first point that falls in it), so a 35,000-row log draws
/// as many marks as the plot has occupied cells, not one per row.
pub(crate) const SCATTER_FULL_LIMIT: usize = 4000;

/// Cell size in pixels of a density-drawn scatter series (`SCATTER_FULL_LIMIT`). Markers are
/// 6 px across, so 3-px cells still draw a dense cloud solid; 2-px cells made the four-column
/// error figure of the 27,815-row pneumatic log 1.1 MB on its own.
pub const SCATTER_CELL_PX: f64 = 3.0;

fn ticks_for(length_px: f64, per_tick_px: f64) -> usize {
    ((length_px / per_tick_px).round() as usize).clamp(3, 10)
}

/// A "nice" step (1, 2 or 5 times a power of ten) giving about `target` intervals over `span`.
pub(crate) fn nice_step(span: f64, target: usize) -> f64 {
    if !(span.is_finite() && span > 0.0) {
        return 1.0;
    }
    let raw = span / target.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let norm = raw / mag;
    let f = if norm < 1.5 {
        1.0
    } else if norm < 3.5 {
        2.0
    } else if norm < 7.5 {
        5.0
    } else {
        10.0
    };
    f * mag
}

/// Tick positions: multiples of a nice step inside `[lo, hi]`.
pub(crate) fn nice_ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    let (lo, hi) = ordered(lo, hi);
    let step = nice_step(hi - lo, target);
    let first = (lo / step - 1e-9).ceil();
    let mut out = Vec::new();
    let mut k = first;
    while k * step <= hi + step * 1e-9 && out.len() < 50 {
        let v = k * step;
        out.push(if v.abs() < step * 1e-9 { 0.0 } else { v });
        k += 1.0;
    }
    out
}

fn tick_labels(lo: f64, hi: f64, target: usize) -> Vec<(f64, String)> {
    let step = nice_step((hi - lo).abs(), target);
    let decimals = (-step.log10().floor()).clamp(0.0, 12.0) as usize;
    let big = lo.abs().max(hi.abs()) >= 1e6;
    nice_ticks(lo, hi, target)
        .into_iter()
        .map(|v| {
            let s = if big {
                fmt_num(v)
            } else {
                fmt_trimmed(v, decimals)
            };
            (v, s)
        })
        .collect()
}

/// A compact number: up to four significant digits, trailing zeros removed, exponent form for
/// magnitudes of a million and more or below 0.001; `"n/a"` for non-finite values.
pub fn fmt_num(x: f64) -> String {
    if !x.is_finite() {
        return "n/a".into();
    }
    let a = x.abs();
    if a < 1e-300 {
        return "0".into();
    }
    if !(1e-3..1e6).contains(&a) {
        let s = format!("{x:.3e}");
        let (mantissa, exp) = s.split_once('e').unwrap_or((&s, "0"));
        let mantissa = if mantissa.contains('.') {
            mantissa.trim_end_matches('0').trim_end_matches('.')
        } else {
            mantissa
        };
        return format!("{mantissa}e{exp}");
    }
    let decimals = (3.0 - a.log10().floor()).clamp(0.0, 6.0) as usize;
    fmt_trimmed(x, decimals)
}

/// A pixel coordinate: at most two decimals.
fn n(x: f64) -> String {
    fmt_trimmed(x, 2)
}

fn text_width(s: &str, size: f64) -> f64 {
    s.chars().count() as f64 * CHAR_W * size / FONT
}

/// Escapes text for XML/HTML content and attribute values.
pub(crate) fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c if (c as u32) < 0x20 && c != '\n' && c != '\t' => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_steps_are_1_2_5() {
        assert!((nice_step(10.0, 5) - 2.0).abs() < 1e-12);
        assert!((nice_step(100.0, 5) - 20.0).abs() < 1e-12);
        assert!((nice_step(0.7, 5) - 0.1).abs() < 1e-12);
        assert!((nice_step(37.0, 5) - 5.0).abs() < 1e-12);
        assert!((nice_step(0.0, 5) - 1.0).abs() < 1e-12);
        let t = nice_ticks(-3.2, 17.9, 5);
        let want = [0.0, 5.0, 10.0, 15.0];
        assert_eq!(t.len(), want.len(), "{t:?}");
        for (a, b) in t.iter().zip(want) {
            assert!((a - b).abs() < 1e-12);
        }
    }

    #[test]
    fn tick_labels_have_no_float_noise() {
        let t = tick_labels(0.0, 0.7, 7);
        let labels: Vec<&str> = t.iter().map(|(_, s)| s.as_str()).collect();
        assert_eq!(
            labels,
            ["0", "0.1", "0.2", "0.3", "0.4", "0.5", "0.6", "0.7"]
        );
    }

    #[test]
    fn numbers_are_compact() {
        assert_eq!(fmt_num(0.0), "0");
        assert_eq!(fmt_num(7.94321), "7.943");
        assert_eq!(fmt_num(-19.0), "-19");
        assert_eq!(fmt_num(1234.5678), "1235");
        assert_eq!(fmt_num(2.5e6), "2.5e6");
        assert_eq!(fmt_num(1.0e-4), "1e-4");
        assert_eq!(fmt_num(f64::NAN), "n/a");
        assert_eq!(fmt_num(f64::NEG_INFINITY), "n/a");
    }

    #[test]
    fn escaping_covers_markup() {
        assert_eq!(
            esc(r#"a<b & "c" 'd'>"#),
            "a&lt;b &amp; &quot;c&quot; &#39;d&#39;&gt;"
        );
    }

    #[test]
    fn clipping_cuts_segments_at_the_range() {
        let lay = Chart::new("").line("", &[(0.0, 0.0), (1.0, 1.0)]).layout();
        let (a, b) = clip(&lay, (-1.0, 0.5), (2.0, 0.5)).unwrap();
        // The automatic range is padded: the segment is cut at the padded ends.
        assert!((a.0 - lay.x_lo).abs() < 1e-12 && (b.0 - lay.x_hi).abs() < 1e-12);
        assert!((lay.x_lo + AXIS_PADDING).abs() < 1e-12);
        assert!(clip(&lay, (-1.0, 2.0), (2.0, 2.0)).is_none());
    }
}
