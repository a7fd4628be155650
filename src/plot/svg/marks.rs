//! Marks: one series drawn as points, lines, steps, bars or error bars, clipped to the plot
//! area, with dense scatter series drawn one mark per cell.

use super::axes::ordered;
use super::text::{esc, n};
use super::{Chart, Layout, SeriesData};
use std::fmt::Write;

impl Chart {
    pub(super) fn render_series(&self, lay: &Layout, index: usize, out: &mut String) {
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
}

pub(super) fn point(out: &mut String, lay: &Layout, (x, y): (f64, f64), r: f64, color: &str) {
    let _ = write!(
        out,
        r#"<circle class="point" cx="{}" cy="{}" r="{}" fill="{color}" fill-opacity="0.8"/>"#,
        n(lay.px(x)),
        n(lay.py(y)),
        n(r)
    );
}

/// The bar `i` as `(left, right)` if its edges and height are finite.
pub(super) fn bar(edges: &[f64], heights: &[f64], i: usize) -> Option<(f64, f64)> {
    let (a, b) = (*edges.get(i)?, *edges.get(i + 1)?);
    (a.is_finite() && b.is_finite() && heights[i].is_finite()).then(|| ordered(a, b))
}

/// A line segment between two data points.
pub(super) type Segment = ((f64, f64), (f64, f64));

/// SVG path data for line segments in data units, clipped to the plot area; consecutive
/// segments that join are drawn as one polyline.
pub(super) fn path_data(lay: &Layout, segs: &[Segment]) -> String {
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
pub(super) fn clip(lay: &Layout, a: (f64, f64), b: (f64, f64)) -> Option<Segment> {
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

/// A scatter series with more finite points than this is density-drawn: at most one mark per
/// [`SCATTER_CELL_PX`]-pixel cell (the first point that falls in it), so a 35,000-row log draws
/// as many marks as the plot has occupied cells, not one per row.
pub(crate) const SCATTER_FULL_LIMIT: usize = 4000;

/// Cell size in pixels of a density-drawn scatter series (`SCATTER_FULL_LIMIT`). Markers are
/// 6 px across, so 3-px cells still draw a dense cloud solid; 2-px cells made the four-column
/// error figure of the 27,815-row pneumatic log 1.1 MB on its own.
pub const SCATTER_CELL_PX: f64 = 3.0;
