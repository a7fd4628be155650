//! Axes and ticks: the frame, the "nice" (1-2-5) ticks and their labels, the axis titles.

use super::text::{FONT, esc, fmt_num, n, text_width};
use super::{Chart, Layout};
use crate::log::fmt_trimmed;
use std::fmt::Write;

impl Chart {
    pub(super) fn render_axes(&self, lay: &Layout, out: &mut String) {
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
}

/// The fraction of the data span added on each side of an automatic axis range.
pub const AXIS_PADDING: f64 = 0.03;

pub(super) fn ticks_for(length_px: f64, per_tick_px: f64) -> usize {
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

pub(super) fn tick_labels(lo: f64, hi: f64, target: usize) -> Vec<(f64, String)> {
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

/// The ends of an axis range in ascending order.
pub(super) fn ordered(a: f64, b: f64) -> (f64, f64) {
    if a <= b { (a, b) } else { (b, a) }
}
