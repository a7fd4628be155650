//! Choices for an uncertain bias: the worst-case settle of the robust choice and of zero
//! feedforward over ±Δb, and the paper's and our robust choices as reported.

use super::response::settle_ms;
use super::{Handoff, HandoffTable, SettleError, Window};
use serde::Serialize;

/// Worst-case settle for a bias known to ±Δb (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct WorstCase {
    /// Δb in counts.
    pub delta_b: f64,
    /// s = |∂z/∂d|·Δb in µm·samples.
    pub shift: f64,
    /// The robust start value (relative to the converged value), if any choice settles.
    pub robust_ff: Option<f64>,
    /// Worst-case settle index of the robust choice.
    pub robust_k: Option<usize>,
    /// Worst-case settle time of the robust choice in ms.
    pub robust_worst_settle_ms: Option<f64>,
    /// Worst-case settle index of zero feedforward.
    pub zero_ff_k: Option<usize>,
    /// Worst-case settle time of zero feedforward in ms.
    pub zero_ff_worst_settle_ms: Option<f64>,
}

/// The worst-case settle time when the bias is only known to ±`delta_b` counts (for example a
/// bias prediction and its error std), with the robust choice and with zero feedforward.
///
/// ```
/// use biasctl::control::Controller;
/// use biasctl::{HandoffTable, SettleSpec, control::worst_case_settle};
/// let cfg = SettleSpec::preset("paper1997").unwrap().check().unwrap();
/// let ctl = Controller::design(&cfg.plant, &cfg.weights).unwrap();
/// let table = HandoffTable::new(&ctl, cfg.scenario.horizon).unwrap();
/// let h = cfg.scenario.handoff();
/// let wc = worst_case_settle(&table, &h, &cfg.scenario.window, 8.0).unwrap();
/// assert!(wc.robust_k <= wc.zero_ff_k);
/// ```
pub fn worst_case_settle(
    table: &HandoffTable,
    handoff: &Handoff,
    window: &Window,
    delta_b: f64,
) -> Result<WorstCase, SettleError> {
    if !delta_b.is_finite() || delta_b < 0.0 {
        return Err(SettleError::Invalid {
            field: crate::field::Field::BiasUncertainty,
            what: "finite and ≥ 0",
            value: delta_b,
        });
    }
    let s = table.solve(handoff, window, delta_b);
    let ms = |k: usize| settle_ms(k, table.ts_s);
    Ok(WorstCase {
        delta_b,
        shift: s.shift,
        robust_ff: s.robust.map(|i| i.choice(s.shift)),
        robust_k: s.robust.map(|i| i.k),
        robust_worst_settle_ms: s.robust.map(|i| ms(i.k)),
        zero_ff_k: s.zero_ff_worst,
        zero_ff_worst_settle_ms: s.zero_ff_worst.map(ms),
    })
}

/// The paper's robust choice with its settle time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PaperRobust {
    /// Start value relative to the converged value (µm·samples).
    pub ff: f64,
    /// Sample of the first local minimum of U_k.
    pub k_min: usize,
    /// Settle time in ms (`None`: not settled within the horizon).
    pub settle_ms: Option<f64>,
}

/// Our robust choice for ±Δb.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RobustChoice {
    /// Start value relative to the converged value (µm·samples).
    pub ff: f64,
    /// Worst-case settle index over the bias range.
    pub k: usize,
    /// Worst-case settle time in ms (from the bounds).
    pub worst_settle_ms: f64,
    /// Worst settle time in ms found by simulating 41 biases across ±Δb (verification).
    pub simulated_worst_settle_ms: Option<f64>,
}
