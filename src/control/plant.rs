//! The continuous actuator plant and its exact zero-order-hold discretisation with a fractional
//! computation delay.
//!
//! Plant (units: position error e = y − r in µm, velocity in µm/s, control u and bias d in counts):
//! - rigid body: ë = Kp·(u − d), Kp in µm/s² per count;
//! - each flexible mode i adds an output q_i with q̈_i + 2ζ_iω_i q̇_i + ω_i² q_i = g_i·Kp·(u − d),
//!   ω_i = 2π·f_i (the modal-sum form P(s) = Kp·(1/s² + Σ g_i/(s² + 2ζ_iω_i s + ω_i²)) of the
//!   NSS/IEEEJ HDD benchmark);
//! - the measured position error is e_meas = e + Σ q_i.
//!
//! Continuous state order: [e, v, q_1, q̇_1, …, q_m, q̇_m].
//!
//! The control computed at sample k is applied τ seconds later (0 ≤ τ < Ts), so over one period
//! the plant sees u(k−1) for τ and u(k) for Ts − τ:
//! x(k+1) = Φ x(k) + Γ1 u(k−1) + Γ0 u(k) − (Γ0 + Γ1) d, with Φ = e^{A·Ts},
//! Γ0 = ∫_0^{Ts−τ} e^{As} ds B and Γ1 = e^{A(Ts−τ)} ∫_0^{τ} e^{As} ds B. Both integrals are the
//! top-right block of the exponential of the augmented matrix [[A, B], [0, 0]]·t.

use super::expm::{ExpmError, expm};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// One flexible mode as given by the user (unvalidated).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModeSpec {
    /// Natural frequency f in Hz (> 0).
    pub freq_hz: f64,
    /// Damping ratio ζ (≥ 0, dimensionless).
    pub damping: f64,
    /// Modal gain g relative to the rigid body (dimensionless, any sign; the residue κ of the
    /// benchmark's modal sum).
    pub gain: f64,
}

/// A continuous plant description as given by the user (unvalidated); see [`Plant::new`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlantSpec {
    /// Sample period Ts in s (> 0).
    pub ts_s: f64,
    /// Computation delay τ in s (0 ≤ τ < Ts).
    pub tau_s: f64,
    /// Actuator gain Kp in µm/s² per count (> 0).
    pub kp: f64,
    /// Flexible modes (may be empty: rigid body only).
    pub modes: Vec<ModeSpec>,
}

/// An invalid plant description; each variant names the offending field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PlantError {
    /// A parameter is NaN or infinite.
    #[error("{field} must be a finite number, got {value}")]
    NotFinite {
        /// The field name (as in the plant TOML).
        field: String,
        /// The value given.
        value: f64,
    },
    /// A parameter that must be positive is not.
    #[error("{field} must be > 0, got {value}")]
    NotPositive {
        /// The field name.
        field: String,
        /// The value given.
        value: f64,
    },
    /// A damping ratio is negative.
    #[error("{field} must be ≥ 0, got {value}")]
    Negative {
        /// The field name.
        field: String,
        /// The value given.
        value: f64,
    },
    /// A parameter lies outside the range the discretisation and the settle horizon can carry.
    #[error("{field} must be within {range}, got {value}")]
    OutOfRange {
        /// The field name.
        field: String,
        /// The value given.
        value: f64,
        /// The accepted range, as text.
        range: &'static str,
    },
    /// The delay is not within [0, Ts).
    #[error("tau_s must satisfy 0 ≤ tau_s < ts_s, got tau_s = {tau_s} s with ts_s = {ts_s} s")]
    DelayOutOfRange {
        /// The delay τ in s.
        tau_s: f64,
        /// The sample period Ts in s.
        ts_s: f64,
    },
    /// The discretisation failed numerically.
    #[error("discretisation failed: {0}")]
    Expm(#[from] ExpmError),
}

/// A validated flexible mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode {
    /// Natural frequency in Hz.
    pub freq_hz: f64,
    /// Damping ratio.
    pub damping: f64,
    /// Modal gain relative to the rigid body.
    pub gain: f64,
}

/// A validated continuous plant with its sampling (see the module docs for the equations).
#[derive(Debug, Clone, PartialEq)]
pub struct Plant {
    ts_s: f64,
    tau_s: f64,
    kp: f64,
    modes: Vec<Mode>,
}

fn finite(field: &str, v: f64) -> Result<f64, PlantError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(PlantError::NotFinite {
            field: field.to_string(),
            value: v,
        })
    }
}

fn positive(field: &str, v: f64) -> Result<f64, PlantError> {
    finite(field, v)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(PlantError::NotPositive {
            field: field.to_string(),
            value: v,
        })
    }
}

/// `v` if it lies in `[lo, hi]`, else [`PlantError::OutOfRange`] quoting `range`.
fn within(field: &str, v: f64, lo: f64, hi: f64, range: &'static str) -> Result<f64, PlantError> {
    if (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(PlantError::OutOfRange {
            field: field.to_string(),
            value: v,
            range,
        })
    }
}

/// Longest sample period, s: a servo sampled more slowly than once a second is not a servo, and
/// a longer period makes a settle horizon of samples span an absurd time.
pub(crate) const MAX_TS_S: f64 = 1.0;
/// Largest |modal gain|, largest damping ratio and largest Kp·Ts² the plant accepts: beyond them
/// the discretised matrices and the Riccati solution leave the range of f64 arithmetic.
pub(crate) const MAX_MODE_GAIN: f64 = 1e6;
/// See [`MAX_MODE_GAIN`].
pub(crate) const MAX_DAMPING: f64 = 1e3;
/// See [`MAX_MODE_GAIN`].
pub(crate) const MAX_KP_TS2: f64 = 1e9;

impl Plant {
    /// Validates a plant description: 0 < Ts ≤ `MAX_TS_S`, 0 ≤ τ < Ts, 0 < Kp with
    /// Kp·Ts² ≤ `MAX_KP_TS2`, every mode with 0 < f < the Nyquist frequency × 10⁶,
    /// 0 ≤ ζ ≤ `MAX_DAMPING` and |gain| ≤ `MAX_MODE_GAIN`.
    pub fn new(spec: &PlantSpec) -> Result<Self, PlantError> {
        let ts_s = positive("ts_s", spec.ts_s)?;
        within("ts_s", ts_s, 0.0, MAX_TS_S, "(0, 1] s")?;
        let tau_s = finite("tau_s", spec.tau_s)?;
        if !(0.0..ts_s).contains(&tau_s) {
            return Err(PlantError::DelayOutOfRange { tau_s, ts_s });
        }
        let kp = positive("kp", spec.kp)?;
        within("kp·ts_s²", kp * ts_s * ts_s, 0.0, MAX_KP_TS2, "(0, 1e9]")?;
        let mut modes = Vec::with_capacity(spec.modes.len());
        for (i, m) in spec.modes.iter().enumerate() {
            let freq_hz = positive(&format!("modes[{i}].freq_hz"), m.freq_hz)?;
            let f_ts = freq_hz * ts_s;
            within(
                &format!("modes[{i}].freq_hz·ts_s"),
                f_ts,
                0.0,
                5e5,
                "(0, 5e5]",
            )?;
            let field = format!("modes[{i}].damping");
            let damping = finite(&field, m.damping)?;
            if damping < 0.0 {
                return Err(PlantError::Negative {
                    field,
                    value: damping,
                });
            }
            within(&field, damping, 0.0, MAX_DAMPING, "[0, 1e3]")?;
            let gain = finite(&format!("modes[{i}].gain"), m.gain)?;
            let gain_field = format!("modes[{i}].gain");
            within(
                &gain_field,
                gain,
                -MAX_MODE_GAIN,
                MAX_MODE_GAIN,
                "[-1e6, 1e6]",
            )?;
            modes.push(Mode {
                freq_hz,
                damping,
                gain,
            });
        }
        Ok(Self {
            ts_s,
            tau_s,
            kp,
            modes,
        })
    }

    /// Sample period Ts in s.
    pub fn ts_s(&self) -> f64 {
        self.ts_s
    }
    /// Computation delay τ in s.
    pub fn tau_s(&self) -> f64 {
        self.tau_s
    }
    /// Actuator gain Kp in µm/s² per count.
    pub fn kp(&self) -> f64 {
        self.kp
    }
    /// The flexible modes.
    pub fn modes(&self) -> &[Mode] {
        &self.modes
    }
    /// Number of continuous states: 2 + 2·modes.
    pub fn order(&self) -> usize {
        2 + 2 * self.modes.len()
    }

    /// The continuous state matrix A (state [e, v, q_1, q̇_1, …]) and the input column B for
    /// u − d (counts).
    pub fn continuous(&self) -> (DMatrix<f64>, DVector<f64>) {
        let n = self.order();
        let mut a = DMatrix::zeros(n, n);
        let mut b = DVector::zeros(n);
        a[(0, 1)] = 1.0;
        b[1] = self.kp;
        for (i, m) in self.modes.iter().enumerate() {
            let j = 2 + 2 * i;
            let w = 2.0 * std::f64::consts::PI * m.freq_hz;
            a[(j, j + 1)] = 1.0;
            a[(j + 1, j)] = -w * w;
            a[(j + 1, j + 1)] = -2.0 * m.damping * w;
            b[j + 1] = m.gain * self.kp;
        }
        (a, b)
    }

    /// The measured-output row C: e_meas = e + Σ q_i (µm).
    pub fn output_row(&self) -> DVector<f64> {
        let mut c = DVector::zeros(self.order());
        c[0] = 1.0;
        for i in 0..self.modes.len() {
            c[2 + 2 * i] = 1.0;
        }
        c
    }

    /// Exact ZOH discretisation with the fractional delay τ (see the module docs).
    pub fn discretise(&self) -> Result<DiscretePlant, PlantError> {
        let (a, b) = self.continuous();
        let n = a.nrows();
        let ts = self.ts_s;
        let tau = self.tau_s;
        let phi = expm(&(&a * ts))?;
        // exp([[A, B], [0, 0]]·t) = [[e^{At}, ∫_0^t e^{As} ds B], [0, 1]].
        let integral = |t: f64| -> Result<(DMatrix<f64>, DVector<f64>), ExpmError> {
            let mut m = DMatrix::zeros(n + 1, n + 1);
            m.view_mut((0, 0), (n, n)).copy_from(&(&a * t));
            m.view_mut((0, n), (n, 1)).copy_from(&(&b * t));
            let e = expm(&m)?;
            Ok((
                e.view((0, 0), (n, n)).into_owned(),
                e.view((0, n), (n, 1)).column(0).into_owned(),
            ))
        };
        let (phi_rest, gamma0) = integral(ts - tau)?;
        let (_, int_tau) = integral(tau)?;
        let gamma1 = &phi_rest * int_tau;
        Ok(DiscretePlant {
            ts_s: ts,
            phi,
            gamma0,
            gamma1,
            c: self.output_row(),
        })
    }
}

/// The sampled plant: x(k+1) = Φ x(k) + Γ1 u(k−1) + Γ0 u(k) − (Γ0 + Γ1) d; e_meas(k) = C·x(k).
#[derive(Debug, Clone, PartialEq)]
pub struct DiscretePlant {
    /// Sample period Ts in s.
    pub ts_s: f64,
    /// State transition Φ = e^{A·Ts}.
    pub phi: DMatrix<f64>,
    /// Input column of the current control u(k) (acts for Ts − τ).
    pub gamma0: DVector<f64>,
    /// Input column of the previous control u(k−1) (acts for the first τ of the period).
    pub gamma1: DVector<f64>,
    /// Output row of the measured position error e = y − r (µm).
    pub c: DVector<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(ts: f64, tau: f64) -> PlantSpec {
        PlantSpec {
            ts_s: ts,
            tau_s: tau,
            kp: 1e6,
            modes: vec![],
        }
    }

    /// Reference: rigid body ë = Kp·u with input delay τ, closed form:
    /// Φ = [1 Ts; 0 1], Γ0 = Kp [(Ts−τ)²/2, Ts−τ], Γ1 = Kp [τ²/2 + τ(Ts−τ), τ]
    /// (Franklin, Powell & Workman, *Digital Control of Dynamic Systems*, §4.3.4).
    #[test]
    fn zoh_delay_rigid_body_closed_form() {
        for (ts, tau) in [(1e-4, 4e-5), (1e-4, 0.0), (2e-5, 1e-5)] {
            let d = Plant::new(&spec(ts, tau)).unwrap().discretise().unwrap();
            let kp = 1e6;
            let h = ts - tau;
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1e-12);
            assert!(close(d.phi[(0, 0)], 1.0) && close(d.phi[(0, 1)], ts));
            assert!(d.phi[(1, 0)].abs() <= 1e-15 && close(d.phi[(1, 1)], 1.0));
            assert!(close(d.gamma0[0], kp * h * h / 2.0), "{}", d.gamma0[0]);
            assert!(close(d.gamma0[1], kp * h));
            if tau > 0.0 {
                assert!(close(d.gamma1[0], kp * (tau * tau / 2.0 + tau * h)));
                assert!(close(d.gamma1[1], kp * tau));
            } else {
                assert!(d.gamma1.amax() <= 1e-15);
            }
        }
    }

    #[test]
    fn plant_validation_names_the_field() {
        let e = Plant::new(&spec(1e-4, 1e-4)).unwrap_err();
        assert!(matches!(e, PlantError::DelayOutOfRange { .. }));
        let e = Plant::new(&spec(f64::NAN, 0.0)).unwrap_err();
        assert!(e.to_string().contains("ts_s"));
        let mut s = spec(1e-4, 0.0);
        s.modes.push(ModeSpec {
            freq_hz: 3000.0,
            damping: -0.1,
            gain: 1.0,
        });
        assert!(
            Plant::new(&s)
                .unwrap_err()
                .to_string()
                .contains("modes[0].damping")
        );
    }
}
