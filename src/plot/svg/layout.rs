//! Where a chart's parts go: the data extents, the axis ranges, the plot area, the ticks and the
//! legend's place, and the data → pixel mapping.

use super::axes::{AXIS_PADDING, ordered, tick_labels, ticks_for};
use super::marks::bar;
use super::series::{Reference, SeriesData};
use super::text::{FONT, text_width};
use super::{AxisRange, Chart};

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
    pub(super) x_ticks: Vec<(f64, String)>,
    pub(super) y_ticks: Vec<(f64, String)>,
    pub(super) rotate_x_ticks: bool,
    pub(super) title_size: f64,
    pub(super) legend: Vec<LegendItem>,
}

#[derive(Debug, Clone, PartialEq)]
pub(super) struct LegendItem {
    pub(super) series: usize,
    pub(super) x: f64,
    pub(super) y: f64,
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

    pub(super) fn inside(&self, x: f64, y: f64) -> bool {
        let (xa, xb) = ordered(self.x_lo, self.x_hi);
        let (ya, yb) = ordered(self.y_lo, self.y_hi);
        x >= xa && x <= xb && y >= ya && y <= yb
    }
}
impl Chart {
    pub(super) fn extents(&self) -> Extents {
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
}

#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Extent {
    pub(super) lo: Option<f64>,
    pub(super) hi: Option<f64>,
}

impl Extent {
    pub(super) fn add(&mut self, v: f64) {
        self.lo = Some(self.lo.map_or(v, |l| l.min(v)));
        self.hi = Some(self.hi.map_or(v, |h| h.max(v)));
    }

    pub(super) fn add_or_skip(&mut self, v: f64, skipped: &mut usize) {
        if v.is_finite() {
            self.add(v);
        } else {
            *skipped += 1;
        }
    }
}

#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Extents {
    pub(super) x: Extent,
    pub(super) y: Extent,
    pub(super) points: usize,
    pub(super) skipped: usize,
}

/// The drawn range of an axis: the fixed range if valid, else the data extent, widened when it
/// is a single value; `[0, 1]` with no data.
pub(super) fn resolve(range: AxisRange, ext: Extent) -> (f64, f64) {
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
