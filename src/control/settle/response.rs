//! Simulated responses: the deviation state of a handoff, the settle index of an error sequence
//! by definition, and settle index → settle time.

use super::{Handoff, Window};
use crate::control::Controller;
use nalgebra::DVector;
use serde::Serialize;

/// Settle index → settle time in ms for sample period `ts_s`.
pub(crate) fn settle_ms(k: usize, ts_s: f64) -> f64 {
    k as f64 * ts_s * 1e3
}

/// The settle index of a simulated error sequence by definition (naive reference): one plus the
/// last sample with |e(k)| > δ (0 if none); `None` ("not settled") unless at least `hold`
/// samples at the end lie in the window.
pub fn settle_index(e: &[f64], window: &Window) -> Option<usize> {
    let ks = e
        .iter()
        .rposition(|v| v.is_nan() || v.abs() > window.half_width_um)
        .map_or(0, |k| k + 1);
    (ks + window.hold <= e.len()).then_some(ks)
}

/// One simulated response (Fig. 16).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Response {
    /// Which choice (`zero_ff`, `optimal`, `paper_robust`, `robust`).
    pub name: &'static str,
    /// Start value relative to the converged value (µm·samples).
    pub ff: f64,
    /// Position error e(k) = y − r in µm, k = 0 .. N − 1.
    pub e_um: Vec<f64>,
}

/// The deviation state of a handoff with integrator start ζ (relative to converged).
pub fn handoff_state(ctl: &Controller, h: &Handoff, zeta: f64) -> DVector<f64> {
    let n = ctl.order();
    let mut x = DVector::zeros(n);
    x[0] = zeta;
    x[1] = h.e0_um;
    x[2] = h.v0_um_s;
    x[n - 1] = h.u_prev_counts - h.bias_counts;
    x
}
