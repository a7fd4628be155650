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
