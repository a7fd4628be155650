//! A panel: several charts side by side in one SVG, and the SVG header both use.

use super::Chart;
use super::layout::Layout;
use super::text::{FONT, esc, n};
use std::fmt::Write;

/// A grid of charts in one SVG, filled row by row.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    pub(super) title: String,
    pub(super) columns: usize,
    pub(super) charts: Vec<Chart>,
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

pub(super) fn svg_open(out: &mut String, width: f64, height: f64) {
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="{}">"#,
        n(FONT),
        w = n(width),
        h = n(height),
    );
}
