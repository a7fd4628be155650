//! Plant → controller → settle: the sampled track-following loop of the paper's Section IV and
//! the settle-optimal integrator start value built on it.
//!
//! - `plant`: continuous rigid body (plus optional flexible modes) and its exact ZOH
//!   discretisation with a fractional computation delay τ.
//! - `expm`: the matrix exponential (scaling and squaring with a Padé approximant).
//! - `lqr`: the DARE solver (structured doubling) and the LQR gain.
//! - [`Controller`]: the loop state, the LQR design and the closed loop.
//! - `settle`: the settle-time analysis (eq. 14–16) and the allocation-free handoff table.
//!
//! Loop state (deviation from nothing; units in brackets):
//! x = [z (µm·samples), e (µm), v (µm/s), q_1, q̇_1, …, u_prev (counts)] with
//! - z(k+1) = z(k) + e_meas(k): the integrator of the measured position error e = y − r,
//! - the sampled plant of [`plant::DiscretePlant`],
//! - u_prev(k+1) = u(k): the control still acting during the first τ of the next period,
//! - u(k) = −K x(k), and the bias d entering as ë = Kp·(u − d).
//!
//! ```
//! use biasctl::{control::Controller, control::LqrWeights, control::Plant, control::PlantSpec};
//! let plant = Plant::new(&PlantSpec { ts_s: 1e-4, tau_s: 4e-5, kp: 1e6, modes: vec![] }).unwrap();
//! let w = LqrWeights::new(&[1e-4, 1.78e-3, 1e-9, 0.0], 1e-6, plant.order()).unwrap();
//! let c = Controller::design(&plant, &w).unwrap();
//! assert!(c.spectral_radius() < 1.0);
//! ```

pub(crate) mod expm;
/// The matrix exponential's error, part of [`plant::PlantError`].
pub use expm::ExpmError;
pub(crate) mod lqr;
pub(crate) mod plant;
pub(crate) mod settle;
mod start;
pub use start::StartValues;

use nalgebra::{DMatrix, DVector};
use {lqr::DareOptions, lqr::dare};

// The namespace's public items that live in its submodules (the crate root keeps only the
// names most users need; see `biasctl::prelude`).
pub use lqr::DareError;
pub use plant::{DiscretePlant, Mode, ModeSpec, Plant, PlantError, PlantSpec};
pub use settle::{
    AnalyseError, Bounds, ConfigError, Handoff, HandoffSolution, HandoffTable, Interval,
    PaperRobust, PlantFileError, Response, RobustChoice, Scenario, SettleConfig, SettleError,
    SettleReport, SettleSpec, Window, WorstCase, analyse, handoff_state, settle_index,
    worst_case_settle,
};

/// An error designing the controller.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ServoError {
    /// The plant could not be discretised.
    #[error("plant: {0}")]
    Plant(#[from] PlantError),
    /// A weight is invalid; names the field.
    #[error("{field}: {reason}")]
    Weights {
        /// The field (`q`, `q[2]`, `r`).
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// The Riccati equation could not be solved.
    #[error("LQR design: {0}")]
    Dare(#[from] DareError),
    /// The closed loop has no unique equilibrium (I − Acl singular).
    #[error("closed loop has no unique equilibrium for a constant bias")]
    NoEquilibrium,
}

/// Validated LQR weights: the diagonal of Q over the loop state and the scalar R (> 0).
#[derive(Debug, Clone, PartialEq)]
pub struct LqrWeights {
    q_diag: Vec<f64>,
    r: f64,
}

impl LqrWeights {
    /// Validates weights for a plant of continuous order `plant_order` (2 + 2·modes).
    ///
    /// `q` is either the 4 weights of [z, e, v, u_prev] (the modal states then get weight 0) or
    /// the full diagonal of the loop state (length plant_order + 2), all finite and ≥ 0.
    /// `r` weights u² and must be finite and > 0.
    pub fn new(q: &[f64], r: f64, plant_order: usize) -> Result<Self, ServoError> {
        let n = plant_order + 2;
        let bad = |field: String, reason: String| ServoError::Weights { field, reason };
        if q.len() != 4 && q.len() != n {
            return Err(bad(
                "q".into(),
                format!(
                    "needs 4 weights [z, e, v, u_prev] or {n} (the full loop state), got {}",
                    q.len()
                ),
            ));
        }
        for (i, v) in q.iter().enumerate() {
            if !v.is_finite() || *v < 0.0 {
                return Err(bad(
                    format!("q[{i}]"),
                    format!("must be finite and ≥ 0, got {v}"),
                ));
            }
        }
        if !r.is_finite() || r <= 0.0 {
            return Err(bad("r".into(), format!("must be finite and > 0, got {r}")));
        }
        let q_diag = if q.len() == n {
            q.to_vec()
        } else {
            let mut d = vec![0.0; n];
            d[0] = q[0];
            d[1] = q[1];
            d[2] = q[2];
            d[n - 1] = q[3];
            d
        };
        Ok(Self { q_diag, r })
    }

    /// The diagonal of Q over the loop state.
    pub fn q_diag(&self) -> &[f64] {
        &self.q_diag
    }
    /// The control weight R.
    pub fn r(&self) -> f64 {
        self.r
    }
}

/// The designed track-following loop: open-loop matrices, the LQR gain and the closed loop.
#[derive(Debug, Clone, PartialEq)]
pub struct Controller {
    ts_s: f64,
    a: DMatrix<f64>,
    b: DVector<f64>,
    bd: DVector<f64>,
    c: DVector<f64>,
    k: DVector<f64>,
    acl: DMatrix<f64>,
    poles_abs: Vec<f64>,
    dz_dbias: f64,
    dare_iterations: usize,
    dare_residual: f64,
    spectral_radius: f64,
}

impl Controller {
    /// Discretises `plant`, builds the loop state and designs the LQR gain u = −K x.
    pub fn design(plant: &Plant, weights: &LqrWeights) -> Result<Self, ServoError> {
        let dp = plant.discretise()?;
        let np = plant.order();
        let n = np + 2;
        if weights.q_diag.len() != n {
            return Err(ServoError::Weights {
                field: "q".into(),
                reason: format!(
                    "has {} weights for a loop state of {n}",
                    weights.q_diag.len()
                ),
            });
        }
        let mut a = DMatrix::zeros(n, n);
        let mut b = DVector::zeros(n);
        let mut bd = DVector::zeros(n);
        let mut c = DVector::zeros(n);
        a[(0, 0)] = 1.0;
        for j in 0..np {
            a[(0, 1 + j)] = dp.c[j];
            c[1 + j] = dp.c[j];
            for i in 0..np {
                a[(1 + i, 1 + j)] = dp.phi[(i, j)];
            }
        }
        for i in 0..np {
            a[(1 + i, n - 1)] = dp.gamma1[i];
            b[1 + i] = dp.gamma0[i];
            bd[1 + i] = -(dp.gamma0[i] + dp.gamma1[i]);
        }
        b[n - 1] = 1.0;
        let q = DMatrix::from_diagonal(&DVector::from_column_slice(&weights.q_diag));
        let r = DMatrix::from_element(1, 1, weights.r);
        let bm = DMatrix::from_column_slice(n, 1, b.as_slice());
        let sol = dare(&a, &bm, &q, &r, &DareOptions::default())?;
        let k = DVector::from_iterator(n, sol.k.row(0).iter().copied());
        let acl = &a - &b * k.transpose();
        let mut poles_abs: Vec<f64> = acl.complex_eigenvalues().iter().map(|l| l.norm()).collect();
        poles_abs.sort_by(f64::total_cmp);
        // Equilibrium for a unit bias: x_ss = (I − Acl)⁻¹ Bd.
        let eye = DMatrix::<f64>::identity(n, n);
        let x_ss = (eye - &acl)
            .lu()
            .solve(&bd)
            .ok_or(ServoError::NoEquilibrium)?;
        Ok(Self {
            ts_s: dp.ts_s,
            a,
            b,
            bd,
            c,
            k,
            acl,
            poles_abs,
            dz_dbias: x_ss[0],
            dare_iterations: sol.iterations,
            dare_residual: sol.residual,
            spectral_radius: sol.spectral_radius,
        })
    }

    /// Sample period Ts in s.
    pub fn ts_s(&self) -> f64 {
        self.ts_s
    }
    /// Loop-state dimension n (4 for the rigid body).
    pub fn order(&self) -> usize {
        self.a.nrows()
    }
    /// Open-loop A of the loop state (see the module docs for the ordering).
    pub fn a(&self) -> &DMatrix<f64> {
        &self.a
    }
    /// Input column B of u(k) (counts).
    pub fn b(&self) -> &DVector<f64> {
        &self.b
    }
    /// Column of the bias d (counts): x(k+1) = A x + B u + B_d d.
    pub fn b_bias(&self) -> &DVector<f64> {
        &self.bd
    }
    /// Output row of the measured position error e = y − r (µm).
    pub fn c(&self) -> &DVector<f64> {
        &self.c
    }
    /// LQR gain K (u = −K x), in counts per unit of each state.
    pub fn gain(&self) -> &DVector<f64> {
        &self.k
    }
    /// Closed loop Acl = A − B K.
    pub fn closed_loop(&self) -> &DMatrix<f64> {
        &self.acl
    }
    /// Closed-loop pole magnitudes, ascending.
    pub fn poles_abs(&self) -> &[f64] {
        &self.poles_abs
    }
    /// Spectral radius of Acl (< 1).
    pub fn spectral_radius(&self) -> f64 {
        self.spectral_radius
    }
    /// ∂z/∂d: change of the integrator's converged value per count of bias (µm·samples/count).
    pub fn dz_dbias(&self) -> f64 {
        self.dz_dbias
    }
    /// Doubling steps the DARE solve took.
    pub fn dare_iterations(&self) -> usize {
        self.dare_iterations
    }
    /// Relative residual of the DARE solution.
    pub fn dare_residual(&self) -> f64 {
        self.dare_residual
    }

    /// Simulates the closed loop in deviation coordinates (x − x_ss for a constant bias) from
    /// `x0` for `n` samples and writes the measured position error e(k) (µm) into `out`
    /// (cleared first).
    pub fn simulate_error(&self, x0: &DVector<f64>, n: usize, out: &mut Vec<f64>) {
        out.clear();
        let mut x = x0.clone();
        for _ in 0..n {
            out.push(self.c.dot(&x));
            x = &self.acl * &x;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use plant::PlantSpec;

    #[test]
    fn weights_are_validated() {
        assert!(LqrWeights::new(&[1.0, 1.0, 1.0], 1.0, 2).is_err());
        let e = LqrWeights::new(&[1.0, -1.0, 1.0, 0.0], 1.0, 2).unwrap_err();
        assert!(e.to_string().contains("q[1]"));
        let e = LqrWeights::new(&[1.0, 1.0, 1.0, 0.0], 0.0, 2).unwrap_err();
        assert!(e.to_string().starts_with("r:"));
    }

    /// The bias equilibrium agrees with the closed form z_ss = −(1 + K_u)/K_z per count for the
    /// rigid body (steady state e = v = 0, u = u_prev = d).
    #[test]
    fn dz_dbias_matches_closed_form() {
        let plant = Plant::new(&PlantSpec {
            ts_s: 1e-4,
            tau_s: 4e-5,
            kp: 1e6,
            modes: vec![],
        })
        .unwrap();
        let w = LqrWeights::new(&[1e-4, 1.78e-3, 1e-9, 0.0], 1e-6, 2).unwrap();
        let c = Controller::design(&plant, &w).unwrap();
        let k = c.gain();
        let want = -(1.0 + k[3]) / k[0];
        assert!((c.dz_dbias() - want).abs() < 1e-9 * want.abs());
    }
}
