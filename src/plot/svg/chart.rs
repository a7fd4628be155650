//! The chart builder: a chart's settings and series, added with chained methods, and its
//! rendering into one SVG.

use super::panel::svg_open;
use super::series::{Annotation, GREY};
use super::text::{esc, n};
use super::{AxisRange, ErrorPoint, Layout, PALETTE, Reference, Series, SeriesData};
use std::fmt::Write;

/// A chart with linear axes. Build it with the chained methods, render with [`Chart::to_svg`].
#[derive(Debug, Clone, PartialEq)]
pub struct Chart {
    pub(super) title: String,
    pub(super) x_label: String,
    pub(super) y_label: String,
    pub(super) x_range: AxisRange,
    pub(super) y_range: AxisRange,
    pub(super) width: f64,
    pub(super) height: f64,
    pub(super) series: Vec<Series>,
    pub(super) references: Vec<Reference>,
    pub(super) annotations: Vec<Annotation>,
    pub(super) x_ticks: Option<Vec<(f64, String)>>,
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

    pub(super) fn color_of(&self, index: usize) -> &'static str {
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

    /// Renders the chart as a standalone SVG document.
    pub fn to_svg(&self) -> String {
        let lay = self.layout();
        let mut out = String::new();
        svg_open(&mut out, lay.width, lay.height);
        self.render(&lay, &mut out);
        out.push_str("</svg>\n");
        out
    }

    pub(super) fn render(&self, lay: &Layout, out: &mut String) {
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
}
