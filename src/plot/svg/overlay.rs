//! What is drawn over the series: reference bands and lines with their labels, and the legend.

use super::axes::ordered;
use super::series::{Reference, SeriesData};
use super::text::{esc, n, text_width};
use super::{Chart, Layout};
use std::fmt::Write;

impl Chart {
    pub(super) fn render_band(
        &self,
        lay: &Layout,
        lo: f64,
        hi: f64,
        label: &str,
        out: &mut String,
    ) {
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
    pub(super) fn render_reference_line(
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
            let horizontal = anchor == "end";
            let span = |tx: f64, anchor: &str| {
                if anchor == "end" {
                    (tx - w, tx)
                } else {
                    (tx, tx + w)
                }
            };
            let free = |(x0, x1): (f64, f64), y: f64, placed: &[(f64, f64, f64)]| {
                placed
                    .iter()
                    .all(|&(a, b, py)| b < x0 || a > x1 || (py - y).abs() >= 12.0)
            };
            // Horizontal lines: above, below, then further out, at the right end, then at the
            // left; the first place that covers no data, else the one covering the least;
            // vertical lines: step down.
            let sides: &[(f64, &str)] = if horizontal {
                &[(tx, "end"), (lay.left + 4.0, "start")]
            } else {
                &[(tx, anchor)]
            };
            let mut best: Option<(usize, f64, &str, f64)> = None;
            'search: for i in 0..12 {
                let k = f64::from(i);
                let y = if !horizontal {
                    ty + 12.0 * k
                } else if i % 2 == 0 {
                    ty - 6.0 * k
                } else {
                    ty + 16.0 + 6.0 * (k - 1.0)
                };
                for &(x, a) in sides {
                    let box_x = span(x, a);
                    if !free(box_x, y, placed) {
                        continue;
                    }
                    let covered = if horizontal {
                        self.data_in_box(lay, box_x, (y - 10.0, y + 2.0))
                    } else {
                        0
                    };
                    if best.is_none_or(|b| covered < b.0) {
                        best = Some((covered, x, a, y));
                    }
                    if covered == 0 {
                        break 'search;
                    }
                }
            }
            let (_, tx, anchor, ty) = best.unwrap_or((0, tx, anchor, ty));
            let (x0, x1) = span(tx, anchor);
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

    /// How many of the series' drawn points (markers, and points along each line segment)
    /// fall in the pixel box `x` × `y`: what a label placed there would cover.
    fn data_in_box(&self, lay: &Layout, x: (f64, f64), y: (f64, f64)) -> usize {
        let inside = |&(a, b): &(f64, f64)| {
            let (px, py) = (lay.px(a), lay.py(b));
            px >= x.0 - 3.0 && px <= x.1 + 3.0 && py >= y.0 - 3.0 && py <= y.1 + 3.0
        };
        let along = |pts: &[(f64, f64)]| {
            pts.windows(2)
                .flat_map(|w| {
                    (0..8).map(move |j| {
                        let t = f64::from(j) / 8.0;
                        (
                            w[0].0 + t * (w[1].0 - w[0].0),
                            w[0].1 + t * (w[1].1 - w[0].1),
                        )
                    })
                })
                .chain(pts.last().copied())
                .filter(|p| p.0.is_finite() && p.1.is_finite() && inside(p))
                .count()
        };
        self.series
            .iter()
            .map(|s| match &s.data {
                SeriesData::Line(p) | SeriesData::Step(p) => along(p),
                SeriesData::Scatter(p) => p.iter().filter(|p| inside(p)).count(),
                SeriesData::ErrorBars(p) => p.iter().filter(|p| inside(&(p.x, p.y))).count(),
                SeriesData::Bars { .. } => 0,
            })
            .sum()
    }

    pub(super) fn render_legend(&self, lay: &Layout, out: &mut String) {
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
