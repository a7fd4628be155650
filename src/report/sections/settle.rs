//! Settling faster: the settle analysis of the demo's preset (Figs. 15 and 16, why the paper's
//! robust choice settles when it does) and the link from each model's prediction error to its
//! worst-case settle time.

use super::{ms, pct};
use crate::plot::svg::fmt_num;
use crate::plot::views;
use crate::report::run::{PaperRobustWhy, SettleRun};
use crate::report::{Cell, Report, Table};

/// Why the paper's robust choice settles when it does, in words, from the numbers of `w`;
/// `zero_ms` and `paper_ms` are the simulated settle times of zero feedforward and of the
/// paper's choice. Start values are relative to the converged integrator value, µm·samples.
pub(crate) fn paper_why_text(
    w: &PaperRobustWhy,
    zero_ms: Option<f64>,
    paper_ms: Option<f64>,
) -> String {
    let faster = matches!((paper_ms, zero_ms), (Some(p), Some(z)) if p < z);
    let mut t = if faster {
        format!(
            "Here the paper's robust choice settles faster than zero feedforward ({} against {}).",
            ms(paper_ms),
            ms(zero_ms)
        )
    } else {
        format!(
            "Why the paper's robust choice settles no faster than zero feedforward here ({} \
             against {}):",
            ms(paper_ms),
            ms(zero_ms)
        )
    };
    let [lo, hi] = w.bounds_at_k_min;
    t.push_str(&format!(
        " the paper takes the middle of the per-sample bounds [L, U] at the first local minimum \
         of U, sample {} ({} ms after handoff",
        w.k_min,
        fmt_num(w.k_min_ms)
    ));
    if let Some(z) = zero_ms
        && w.k_min_ms >= z
    {
        t.push_str(&format!(
            ", when zero feedforward has already settled at {} ms",
            fmt_num(z)
        ));
    }
    t.push_str(&format!(
        "). There [L, U] = [{}, {}], so the choice is {}",
        fmt_num(lo),
        fmt_num(hi),
        fmt_num(w.ff)
    ));
    if let (Some([a, b]), Some(o)) = (w.optimal_interval, w.optimal_ms) {
        let mid = 0.5 * (a + b);
        if mid.abs() > 0.0 {
            t.push_str(&format!(
                ", {} % of the optimal start value's distance from zero feedforward's 0 (the \
                 start values that settle fastest, at {} ms, are [L*, U*] = [{}, {}])",
                fmt_num((100.0 * w.ff.abs() / mid.abs()).round()),
                fmt_num(o),
                fmt_num(a),
                fmt_num(b)
            ));
        }
    }
    t.push_str(&format!(
        ". A start value settles at the first sample from which it stays between the running \
         bounds L* and U*: {} enters them at {}, zero feedforward's 0 at {}.",
        fmt_num(w.ff),
        ms(w.paper_entry_ms),
        ms(w.zero_entry_ms)
    ));
    t
}

/// The section "Settling faster: the integrator start value at handoff": the scenario, the
/// headline settle times, Figs. 15 and 16, and why the paper's robust choice settles when it
/// does.
pub(crate) fn settle(r: &mut Report, run: &SettleRun) {
    let settle = &run.report;
    let paper_ms = settle.paper_robust.as_ref().and_then(|p| p.settle_ms);
    let s = r.section("Settling faster: the integrator start value at handoff");
    s.paragraph(format!(
        "When the seek controller hands over to track following, the integrator's start \
         value decides how fast the head settles into the ±{} µm window after a {} µm \
         step. Zero feedforward starts it at its converged value (the bias); the optimum \
         (eqs. 14–16) is any value between the running bounds at the first sample where \
         they cross. The paper's robust choice takes the middle of the bounds at the first \
         local minimum of the upper bound; the worst-case robust choice settles fastest for \
         every bias within ±{} counts.",
        fmt_num(settle.window_um),
        fmt_num(settle.step_um),
        fmt_num(settle.worst_case.delta_b)
    ))
    .headline(&[
        ("zero feedforward", ms(settle.zero_ff_settle_ms)),
        ("optimal", ms(settle.optimal_settle_ms)),
        ("paper's robust", ms(paper_ms)),
        (
            "worst-case robust",
            ms(settle.robust.as_ref().map(|c| c.worst_settle_ms)),
        ),
        (
            "reduction (optimal)",
            pct(
                settle.zero_ff_settle_ms.unwrap_or(f64::NAN),
                settle.optimal_settle_ms.unwrap_or(f64::NAN),
            ),
        ),
    ])
    .figure(
        views::settle_bounds(settle),
        "Fig. 15: the bounds U, L on the start value at each sample (thin) and their running \
         min/max from the end U*, L* (dashed); left the whole horizon, right zoomed on the \
         decision region. Where the running bounds cross is the fastest possible settle; the \
         horizontal lines are the start values chosen, each with its value in the legend.",
    )
    .figure(
        views::settle_responses(settle),
        "Fig. 16: the position error after handoff for each choice, whole and zoomed on the \
         window; curves that lie on top of each other are dashed and say so in the legend.",
    );
    if let Some(w) = &run.paper_why {
        s.paragraph(paper_why_text(w, settle.zero_ff_settle_ms, paper_ms));
    }
}

/// The section "From prediction error to settle time": each model's test error std taken as
/// the bias uncertainty Δb and the worst-case settle it buys.
pub(crate) fn link(r: &mut Report, run: &SettleRun) {
    let mut t = Table::new(&[
        "model",
        "test error std = Δb (counts)",
        "worst-case settle, robust start (ms)",
        "worst-case settle, zero feedforward (ms)",
    ])
    .caption("If the bias is only known to ± the model's error std");
    for (label, std, wc) in &run.link {
        t = t.row(vec![
            label.clone().into(),
            Cell::Fixed(*std, 2),
            wc.robust_worst_settle_ms
                .map_or(Cell::Text("not settled".into()), |v| Cell::Fixed(v, 1)),
            wc.zero_ff_worst_settle_ms
                .map_or(Cell::Text("not settled".into()), |v| Cell::Fixed(v, 1)),
        ]);
    }
    r.section("From prediction error to settle time")
        .paragraph(
            "A start value is computed from a predicted bias. If the prediction may be off \
             by Δb counts, the start value may be off by ∂z/∂d·Δb, and the head must settle \
             for every bias in the range. Taking each model's test error std as Δb gives the \
             worst-case settle time that model buys: better prediction, faster settling.",
        )
        .table(t);
}
