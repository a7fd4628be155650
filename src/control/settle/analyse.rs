//! The full settle analysis of a scenario: design, bounds, optimal and robust choices, and the
//! simulated responses of each choice.

use super::response::settle_ms;
use super::{
    AnalyseError, Bounds, HandoffTable, PaperRobust, Response, RobustChoice, Scenario,
    SettleConfig, SettleError, SettleReport, handoff_state, settle_index, worst_case_settle,
};
use crate::control::Controller;

/// Designs the controller and runs the full settle analysis of `cfg`'s scenario.
pub fn analyse(cfg: &SettleConfig) -> Result<SettleReport, AnalyseError> {
    let ctl = Controller::design(&cfg.plant, &cfg.weights)?;
    Ok(analyse_with(&ctl, &cfg.scenario)?)
}

/// The settle analysis of a scenario for a designed controller.
pub(crate) fn analyse_with(ctl: &Controller, sc: &Scenario) -> Result<SettleReport, SettleError> {
    let n = sc.horizon;
    let ts = ctl.ts_s();
    let ms = |k: usize| settle_ms(k, ts);
    let h = sc.handoff();
    let table = HandoffTable::new(ctl, n)?;
    let mut bounds = Bounds::new(n);
    table.bounds_into(&h, &sc.window, &mut bounds)?;
    let optimal = bounds.optimal();
    let worst = worst_case_settle(&table, &h, &sc.window, sc.bias_uncertainty)?;
    let sol = table.solve(&h, &sc.window, sc.bias_uncertainty);
    let simulate = |zeta: f64| {
        let mut e = Vec::with_capacity(n);
        ctl.simulate_error(&handoff_state(ctl, &h, zeta), n, &mut e);
        e
    };
    let mut responses = Vec::new();
    let zero = simulate(0.0);
    let zero_ff_settle_ms = settle_index(&zero, &sc.window).map(ms);
    let sign = if sc.step_um < 0.0 { -1.0 } else { 1.0 };
    let peak = zero.iter().fold(0.0f64, |m, v| m.max(sign * v));
    let zero_ff_overshoot_pct = if sc.step_um.abs() > 0.0 {
        100.0 * peak / sc.step_um.abs()
    } else {
        0.0
    };
    responses.push(Response {
        name: "zero_ff",
        ff: 0.0,
        e_um: zero,
    });
    if let Some(o) = optimal {
        let ff = o.choice(0.0);
        responses.push(Response {
            name: "optimal",
            ff,
            e_um: simulate(ff),
        });
    }
    let paper_robust = bounds.paper_robust().map(|(k_min, ff)| {
        let e = simulate(ff);
        let settle = settle_index(&e, &sc.window).map(ms);
        responses.push(Response {
            name: "paper_robust",
            ff,
            e_um: e,
        });
        PaperRobust {
            ff,
            k_min,
            settle_ms: settle,
        }
    });
    let robust = sol.robust.map(|i| {
        let ff = i.choice(sol.shift);
        // Verification: the true start is ff + ∂z/∂d·(d̂ − d) for biases across ±Δb.
        let mut worst_k = Some(0usize);
        for j in 0..=40 {
            let db = sc.bias_uncertainty * (j as f64 / 20.0 - 1.0);
            let k = settle_index(&simulate(ff + ctl.dz_dbias() * db), &sc.window);
            worst_k = match (worst_k, k) {
                (Some(a), Some(b)) => Some(a.max(b)),
                _ => None,
            };
        }
        responses.push(Response {
            name: "robust",
            ff,
            e_um: simulate(ff),
        });
        RobustChoice {
            ff,
            k: i.k,
            worst_settle_ms: ms(i.k),
            simulated_worst_settle_ms: worst_k.map(ms),
        }
    });
    Ok(SettleReport {
        gain: ctl.gain().iter().copied().collect(),
        poles_abs: ctl.poles_abs().to_vec(),
        dz_dbias: ctl.dz_dbias(),
        dare_iterations: ctl.dare_iterations(),
        dare_residual: ctl.dare_residual(),
        ts_s: ts,
        horizon: n,
        window_um: sc.window.half_width_um(),
        hold: sc.window.hold(),
        step_um: sc.step_um,
        bias: sc.bias,
        z_converged: ctl.dz_dbias() * sc.bias + 0.0,
        k_star: optimal.map(|o| o.k),
        optimal_settle_ms: optimal.map(|o| ms(o.k)),
        ff_interval: optimal.map(|o| [o.lo, o.hi]),
        ff_midpoint: optimal.map(|o| o.choice(0.0)),
        zero_ff_settle_ms,
        zero_ff_overshoot_pct,
        paper_robust,
        robust,
        worst_case: worst,
        bounds,
        responses,
    })
}
