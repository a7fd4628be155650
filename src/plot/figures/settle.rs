//! The settle figures: the start-value bounds (Fig. 15) and the responses of each start-value
//! choice (Fig. 16).

use super::errors::finite_range;
use crate::plot::svg::{AxisRange, Chart, Panel, Series, SeriesData, fmt_num};

/// Data of Fig. 15: the settle bounds on the integrator start value (eqs. 14–16).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SettleBounds {
    /// Sample period, ms (0.1 at 10 kHz); sample k is drawn at `k · sample_period_ms`.
    pub sample_period_ms: f64,
    /// Upper bound U_k per sample.
    pub upper: Vec<f64>,
    /// Lower bound L_k per sample.
    pub lower: Vec<f64>,
    /// Running minimum of the upper bound from the end, U*(k).
    pub upper_running: Vec<f64>,
    /// Running maximum of the lower bound from the end, L*(k).
    pub lower_running: Vec<f64>,
    /// Chosen start values `(name, value)`, drawn as horizontal lines.
    pub choices: Vec<(String, f64)>,
    /// The minimum settle time, ms, drawn as a vertical line; `None` for none.
    pub settle_ms: Option<f64>,
    /// Unit of the start value, e.g. `counts`; it is relative to the converged integrator value.
    pub unit: String,
}

fn per_sample(period_ms: f64, v: &[f64]) -> Vec<(f64, f64)> {
    v.iter()
        .enumerate()
        .map(|(k, &y)| (k as f64 * period_ms, y))
        .collect()
}

/// Dash patterns that tell apart lines drawn on top of each other: solid first, then dashed,
/// dotted, dash-dot.
const DASHES: [Option<&str>; 4] = [None, Some("7 4"), Some("2 3"), Some("9 3 2 3")];

/// The sample at which start value `v` enters the running bounds, `L*(k) ≤ v ≤ U*(k)` (its
/// settle sample when the running bounds are those of a settle analysis).
fn entry_sample(b: &SettleBounds, v: f64) -> Option<usize> {
    b.lower_running
        .iter()
        .zip(&b.upper_running)
        .position(|(&lo, &hi)| lo <= v && v <= hi)
}

/// The four bound curves of Fig. 15 on chart `c` (thin U, L; dashed running U*, L*).
fn bound_series(c: Chart, b: &SettleBounds) -> Chart {
    let t = b.sample_period_ms;
    c.series(Series::new("upper bound U", SeriesData::Line(per_sample(t, &b.upper))).color(0))
        .series(Series::new("lower bound L", SeriesData::Line(per_sample(t, &b.lower))).color(1))
        .series(
            Series::new(
                "running min U*",
                SeriesData::Step(per_sample(t, &b.upper_running)),
            )
            .color(0)
            .dashed(),
        )
        .series(
            Series::new(
                "running max L*",
                SeriesData::Step(per_sample(t, &b.lower_running)),
            )
            .color(1)
            .dashed(),
        )
}

/// Fig. 15, two panels. Left, the whole horizon: the bounds U_k, L_k (thin) and their running
/// min/max U*, L* (dashed) vs time, the chosen start values as unlabelled grey lines; the y range
/// follows the running bounds and the choices (the raw bounds grow without limit near k = 0 and
/// are clipped). Right, the decision region: time up to a little past the last sample at which
/// a chosen start value enters the running bounds, values around the choices, each choice a
/// legend entry with its value (own colour and dash pattern, so values a few units apart stay
/// legible). With no finite choice the right panel repeats the left one's range.
pub fn fig15_settle_bounds(b: &SettleBounds) -> String {
    let t = b.sample_period_ms;
    let mut focus: Vec<f64> = b
        .upper_running
        .iter()
        .chain(&b.lower_running)
        .copied()
        .chain(b.choices.iter().map(|c| c.1))
        .filter(|v| v.is_finite())
        .collect();
    if focus.is_empty() {
        focus = b
            .upper
            .iter()
            .chain(&b.lower)
            .copied()
            .filter(|v| v.is_finite())
            .collect();
    }
    let y_range = match finite_range(&focus) {
        AxisRange::Fixed { lo, hi } => {
            let pad = 0.1 * (hi - lo);
            AxisRange::Fixed {
                lo: lo - pad,
                hi: hi + pad,
            }
        }
        auto => auto,
    };
    let y_label = format!("start value − converged ({})", b.unit);
    let mut whole = Chart::new("whole horizon")
        .size(520.0, 380.0)
        .x_label("time after handoff (ms)")
        .y_label(y_label.clone())
        .y_range(y_range);
    whole = bound_series(whole, b);
    for (_, v) in &b.choices {
        whole = whole.hline(*v, "");
    }
    // The decision region.
    let values: Vec<f64> = b
        .choices
        .iter()
        .map(|c| c.1)
        .filter(|v| v.is_finite())
        .collect();
    let last_entry = values
        .iter()
        .filter_map(|&v| entry_sample(b, v))
        .chain(b.settle_ms.map(|s| (s / t).round() as usize))
        .max();
    let n = b.upper.len().max(b.lower.len());
    let x_hi = last_entry.map_or(n as f64 * t, |k| {
        ((k as f64 * 1.3).ceil() + 2.0).min(n as f64) * t
    });
    let mut zoom = Chart::new("zoom on the decision region")
        .size(520.0, 380.0)
        .x_label("time after handoff (ms)")
        .y_label(y_label);
    zoom = match finite_range(&values) {
        AxisRange::Fixed { lo, hi } => {
            let pad = 0.3 * (hi - lo);
            zoom.y_range(AxisRange::Fixed {
                lo: lo - pad,
                hi: hi + pad,
            })
        }
        AxisRange::Auto => zoom.y_range(y_range),
    };
    if x_hi.is_finite() && x_hi > 0.0 {
        zoom = zoom.x_range(AxisRange::Fixed { lo: 0.0, hi: x_hi });
    }
    zoom = bound_series(zoom, b);
    for (i, (name, v)) in b.choices.iter().enumerate() {
        let mut s = Series::new(
            format!("{name}: {}", fmt_num(*v)),
            SeriesData::Line(vec![(0.0, *v), (x_hi, *v)]),
        )
        .color(2 + i);
        if let Some(d) = DASHES[i % DASHES.len()] {
            s = s.dash(d);
        }
        zoom = zoom.series(s);
    }
    if let Some(s) = b.settle_ms {
        whole = whole.vline(s, format!("settle {} ms", fmt_num(s)));
        zoom = zoom.vline(s, format!("settle {} ms", fmt_num(s)));
    }
    Panel::new("Fig. 15 — bounds on the integrator start value")
        .columns(2)
        .chart(whole)
        .chart(zoom)
        .to_svg()
}

/// The position-error response for one start-value choice.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Response {
    /// The choice, e.g. "zero feedforward", "robust optimal".
    pub name: String,
    /// Position error e(k) per sample, µm.
    pub error_um: Vec<f64>,
    /// Settle time, ms (shown in the legend and as a dashed vertical line); `None` if it does
    /// not settle.
    pub settle_ms: Option<f64>,
}

/// Data of Fig. 16: responses for each start-value choice and the settle window.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SettleResponses {
    /// Sample period, ms.
    pub sample_period_ms: f64,
    /// Half-width δ of the settle window, µm.
    pub delta_um: f64,
    /// One response per choice.
    pub responses: Vec<Response>,
}

/// Which earlier response each response lies on top of: `Some(j)` when its largest distance
/// from response `j < i` is under 3 % of the whole figure's error range (about 6 pixels of the
/// whole-response chart: the two curves cannot be told apart by position alone at that scale;
/// on paper1997 zero feedforward and the paper's robust choice are 1.8 % apart, the optimal and
/// the worst-case robust choice 1.4 %).
fn coinciding(r: &SettleResponses) -> Vec<Option<usize>> {
    let all: Vec<f64> = r
        .responses
        .iter()
        .flat_map(|x| x.error_um.iter().copied())
        .filter(|v| v.is_finite())
        .collect();
    let span = match finite_range(&all) {
        AxisRange::Fixed { lo, hi } => hi - lo,
        AxisRange::Auto => return vec![None; r.responses.len()],
    };
    let gap = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .map(|(x, y)| (x - y).abs())
            .fold(0.0f64, f64::max)
    };
    (0..r.responses.len())
        .map(|i| {
            (0..i).find(|&j| {
                r.responses[i].error_um.len() == r.responses[j].error_um.len()
                    && gap(&r.responses[i].error_um, &r.responses[j].error_um) < 0.03 * span
            })
        })
        .collect()
}

/// Fig. 16: e(k) for each start-value choice with the ±δ window as a band; left the whole
/// response, right zoomed to ±5δ around the window. A response that lies on top of an earlier
/// one (see `coinciding`) is drawn with a dash pattern over it, and its legend entry says which
/// one it coincides with.
pub fn fig16_responses(r: &SettleResponses) -> String {
    let on_top = coinciding(r);
    // Each response's dash pattern: the k-th curve of a group drawn on top of each other gets
    // the k-th pattern (the first stays solid).
    let mut roots: Vec<usize> = Vec::with_capacity(on_top.len());
    for (i, j) in on_top.iter().enumerate() {
        let root = j.map_or(i, |j| roots[j]);
        roots.push(root);
    }
    let dash_index: Vec<usize> = (0..roots.len())
        .map(|i| (0..i).filter(|&k| roots[k] == roots[i]).count())
        .collect();
    let chart = |title: &str, zoom: bool| {
        let mut c = Chart::new(title)
            .size(520.0, 360.0)
            .x_label("time after handoff (ms)")
            .y_label("position error e (µm)")
            .hband(
                -r.delta_um,
                r.delta_um,
                format!("±δ = {} µm", fmt_num(r.delta_um)),
            );
        if zoom && r.delta_um.is_finite() && r.delta_um > 0.0 {
            c = c.y_range(AxisRange::Fixed {
                lo: -5.0 * r.delta_um,
                hi: 5.0 * r.delta_um,
            });
        }
        for (i, resp) in r.responses.iter().enumerate() {
            let settles = match resp.settle_ms {
                Some(s) => format!("settles {} ms", fmt_num(s)),
                None => "does not settle".into(),
            };
            let name = match on_top[i] {
                Some(j) => format!(
                    "{} ({settles}; coincides with {})",
                    resp.name, r.responses[j].name
                ),
                None => format!("{} ({settles})", resp.name),
            };
            let pts = per_sample(r.sample_period_ms, &resp.error_um);
            let mut s = Series::new(name, SeriesData::Line(pts)).color(i);
            if let Some(d) = DASHES[dash_index[i] % DASHES.len()] {
                s = s.dash(d);
            }
            c = c.series(s);
            if let Some(s) = resp.settle_ms {
                c = c.vline(s, "");
            }
        }
        c
    };
    Panel::new("Fig. 16 — position error after handoff for each start value")
        .columns(2)
        .chart(chart("whole response", false))
        .chart(chart("zoom on the ±δ window", true))
        .to_svg()
}
