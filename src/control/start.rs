//! The settle-optimal integrator start value of every planned seek, from the seek's predicted
//! bias ([`StartValues`]).

use super::settle::{AnalyseError, HandoffTable, SettleConfig, Window};
use crate::model::IntegratorStart;

/// The settle-optimal integrator start value of every planned seek (`predict --handoff`): the
/// robust choice of eq. 14–16 for the plant's handoff (a step from rest) and a bias known to
/// ±Δb, made absolute with the seek's predicted bias.
///
/// `integrator_start(b̂) = ∂z/∂d·b̂ + ζ_robust` in µm·samples: the value the firmware loads into
/// the integrator, i.e. the converged value for the predicted bias b̂ (counts) plus the robust
/// start value relative to it, which `biasctl settle --bias B --bias-uncertainty DB` reports as
/// `z_converged` and `robust.ff`. Allocation-free per call.
///
/// ```
/// use biasctl::StartValues;
/// use biasctl::{SettleSpec, analyse};
/// let mut spec = SettleSpec::preset("paper1997").unwrap();
/// let starts = StartValues::new(&spec.check().unwrap(), 8.0).unwrap();
/// let z = starts.integrator_start(30.0).unwrap();
/// // What `biasctl settle --bias 30 --bias-uncertainty 8` reports:
/// spec.bias = 30.0;
/// spec.bias_uncertainty = 8.0;
/// let r = analyse(&spec.check().unwrap()).unwrap();
/// assert!((z - (r.z_converged + r.robust.unwrap().ff)).abs() < 1e-9);
/// ```
#[derive(Debug, Clone)]
pub struct StartValues {
    table: HandoffTable,
    window: Window,
    step_um: f64,
    delta_b: f64,
}

impl StartValues {
    /// Designs the controller of `cfg` (its plant, weights, step, window and horizon; its bias
    /// is ignored) for a bias uncertainty `delta_b` (counts, finite, ≥ 0: the model's error std).
    pub fn new(cfg: &SettleConfig, delta_b: f64) -> Result<Self, AnalyseError> {
        if !delta_b.is_finite() || delta_b < 0.0 {
            return Err(super::settle::SettleError::Invalid {
                field: crate::field::Field::BiasUncertainty,
                what: "finite and ≥ 0 (the model's residual_std when none is given)",
                value: delta_b,
            }
            .into());
        }
        let ctl = super::Controller::design(&cfg.plant, &cfg.weights)?;
        Ok(Self {
            table: HandoffTable::new(&ctl, cfg.scenario.horizon)?,
            window: cfg.scenario.window,
            step_um: cfg.scenario.step_um,
            delta_b,
        })
    }

    /// Δb in counts.
    pub fn delta_b(&self) -> f64 {
        self.delta_b
    }

    /// The precomputed handoff table.
    pub fn table(&self) -> &HandoffTable {
        &self.table
    }

    /// The settle window.
    pub fn window(&self) -> &Window {
        &self.window
    }

    /// Step length in µm (the handoff starts at e0 = −step from rest).
    pub fn step_um(&self) -> f64 {
        self.step_um
    }

    /// The absolute integrator start value (µm·samples) for a seek whose predicted bias is
    /// `bias` (counts); `None` when no start value settles every bias within ±Δb inside the
    /// horizon, or the bias is not finite.
    pub fn integrator_start(&self, bias: f64) -> Option<f64> {
        if !bias.is_finite() {
            return None;
        }
        let h = super::settle::Handoff {
            e0_um: -self.step_um,
            v0_um_s: 0.0,
            u_prev_counts: bias,
            bias_counts: bias,
        };
        let sol = self.table.solve(&h, &self.window, self.delta_b);
        let zeta = sol.robust?.choice(sol.shift);
        let z = self.table.dz_dbias() * bias + zeta;
        z.is_finite().then_some(z)
    }
}

impl IntegratorStart for StartValues {
    fn integrator_start(&self, bias: f64) -> Option<f64> {
        StartValues::integrator_start(self, bias)
    }
}
