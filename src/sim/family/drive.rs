//! The family's drives ([`FamilyDrive`]): pivot hysteresis, position trend and noise of each
//! member, and the covariate columns every log carries.

use super::FamilyError;

/// The logged covariate columns, in log order. Every log of the family carries all of them.
pub const COVARIATES: [&str; 9] = [
    "white",
    "walk",
    "warmup",
    "temp_fast",
    "temp_slow",
    "load",
    "temp_lag",
    "humid",
    "supply",
];

/// The three columns that never have an effect: white noise, a slow random walk and a warm-up
/// curve. A diagnosis that flags one of them has found nothing.
pub const NO_EFFECT_COLUMNS: [&str; 3] = ["white", "walk", "warmup"];

/// Pivot hysteresis of a family drive (the direction/overshoot physics).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Pivot {
    /// Bouc–Wen element in the position coordinate, `F = amplitude·z`, with
    /// `dz/dx = (1 − (beta·sgn(dx·z) + (1 − beta))·|z|^n)/length` (so |z| saturates at 1);
    /// integrated by RK4 in steps of at most `length/20` tracks.
    BoucWen {
        /// Saturated force, counts.
        amplitude: f64,
        /// Characteristic length of the loading branch, tracks.
        length: f64,
        /// Share β of the loading/unloading asymmetry, in (0.5, 1]: the unloading slope is
        /// `(1 + (2β − 1)·|z|^n)/length`.
        beta: f64,
        /// Exponent n of |z| (2: a tanh-like knee; 1: exponential loading).
        n: f64,
    },
    /// Prandtl–Ishlinskii: a weighted sum of stop operators
    /// `s_i ← clamp(s_i + dx, −r_i, r_i)`, `F = Σ w_i·s_i/r_i` (piecewise-linear loops).
    Prandtl {
        /// Thresholds r_i, tracks, each > 0.
        thresholds: Vec<f64>,
        /// Weights w_i, counts (the saturated force is their sum).
        weights: Vec<f64>,
    },
}

/// Position trend of a family drive (flex cable, windage), counts, as a function of
/// `u = (x − centre)/(span/2)` ∈ [−1, 1].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Trend {
    /// `offset + slope·u + amplitude·sin(cycles·π·u + phase)`.
    Sine {
        /// Counts.
        offset: f64,
        /// Counts per half span.
        slope: f64,
        /// Counts.
        amplitude: f64,
        /// Half-periods across the span.
        cycles: f64,
        /// Radians.
        phase: f64,
    },
    /// `c[0] + c[1]·u + c[2]·u² + c[3]·u³`, counts.
    Cubic {
        /// Coefficients, counts.
        c: [f64; 4],
    },
}

/// Measurement noise of a family drive: `e_k = rho·e_{k−1} + √(1 − rho²)·std·w_k`, with `w_k`
/// Student-t with `nu` degrees of freedom scaled to unit variance (Gaussian when `nu` is
/// `None`). The stationary std of `e` is `std` counts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// Stationary standard deviation, counts.
    pub std: f64,
    /// Degrees of freedom of the Student-t innovations (≥ 3), or `None` for Gaussian.
    pub nu: Option<u32>,
    /// AR(1) coefficient in [0, 1).
    pub rho: f64,
}

/// One independent drive of the family: its physics and its seek pattern.
#[derive(Debug, Clone, PartialEq)]
pub struct FamilyDrive {
    /// Name written in the log metadata (`member = …`).
    pub name: String,
    /// Pivot hysteresis.
    pub pivot: Pivot,
    /// Position trend.
    pub trend: Trend,
    /// Measurement noise.
    pub noise: Noise,
    /// Centre of the random seek range, tracks.
    pub centre: f64,
    /// Width of the random seek range, tracks (targets are whole tracks).
    pub span: f64,
    /// Time at each target before it is measured, uniform in `[min, max]`, s.
    pub dwell_s: [f64; 2],
    /// Amplitude of every hidden effect, in units of the noise std (see [`HiddenEffect`](super::HiddenEffect)).
    pub effect_scale: f64,
}

impl FamilyDrive {
    /// The three members used by the tests, the example and the bench:
    /// - `bw-sine-t`: Bouc–Wen (n = 2) pivot, sinusoidal flex bias, Student-t (ν = 3) noise;
    /// - `pi-cubic-ar1`: Prandtl–Ishlinskii pivot, cubic flex bias, Gaussian AR(1) noise (ρ = 0.6);
    /// - `bw1-sine-tar`: Bouc–Wen (n = 1, strongly asymmetric) pivot, another sinusoid, Student-t
    ///   (ν = 4) innovations with AR(1) ρ = 0.3.
    pub fn members() -> Vec<FamilyDrive> {
        vec![
            FamilyDrive {
                name: "bw-sine-t".into(),
                pivot: Pivot::BoucWen {
                    amplitude: 9.0,
                    length: 12.0,
                    beta: 0.75,
                    n: 2.0,
                },
                trend: Trend::Sine {
                    offset: 40.0,
                    slope: -6.0,
                    amplitude: 5.0,
                    cycles: 3.0,
                    phase: 0.4,
                },
                noise: Noise {
                    std: 2.0,
                    nu: Some(3),
                    rho: 0.0,
                },
                centre: 1500.0,
                span: 240.0,
                dwell_s: [0.05, 0.5],
                effect_scale: 1.0,
            },
            FamilyDrive {
                name: "pi-cubic-ar1".into(),
                pivot: Pivot::Prandtl {
                    thresholds: vec![2.0, 6.0, 15.0, 35.0],
                    weights: vec![3.0, 4.0, 3.0, 2.0],
                },
                trend: Trend::Cubic {
                    c: [-20.0, 8.0, -3.0, 4.0],
                },
                noise: Noise {
                    std: 1.5,
                    nu: None,
                    rho: 0.6,
                },
                centre: 600.0,
                span: 300.0,
                dwell_s: [0.1, 0.6],
                effect_scale: 1.0,
            },
            FamilyDrive {
                name: "bw1-sine-tar".into(),
                pivot: Pivot::BoucWen {
                    amplitude: 14.0,
                    length: 25.0,
                    beta: 0.95,
                    n: 1.0,
                },
                trend: Trend::Sine {
                    offset: 5.0,
                    slope: 10.0,
                    amplitude: 3.0,
                    cycles: 1.5,
                    phase: -0.8,
                },
                noise: Noise {
                    std: 2.5,
                    nu: Some(4),
                    rho: 0.3,
                },
                centre: 2400.0,
                span: 200.0,
                dwell_s: [0.05, 0.3],
                effect_scale: 1.0,
            },
        ]
    }

    /// The member called `name`.
    pub fn member(name: &str) -> Option<FamilyDrive> {
        Self::members().into_iter().find(|d| d.name == name)
    }

    pub(super) fn validate(&self) -> Result<(), FamilyError> {
        let bad = |what: &str| {
            Err(FamilyError::BadParameter {
                drive: self.name.clone(),
                what: what.to_string(),
            })
        };
        let pos = |x: f64| x.is_finite() && x > 0.0;
        if !pos(self.span) || !self.centre.is_finite() || self.centre - self.span / 2.0 < 0.0 {
            return bad("span must be positive and the range must start at track 0 or beyond");
        }
        if !(pos(self.dwell_s[0]) && self.dwell_s[1] >= self.dwell_s[0]) {
            return bad("dwell_s must be 0 < min ≤ max");
        }
        if !(pos(self.noise.std) && (0.0..1.0).contains(&self.noise.rho)) {
            return bad("noise std must be positive and rho in [0, 1)");
        }
        if self.noise.nu.is_some_and(|nu| nu < 3) {
            return bad("Student-t noise needs nu ≥ 3 (finite variance)");
        }
        if !(self.effect_scale.is_finite() && self.effect_scale >= 0.0) {
            return bad("effect_scale must be finite and ≥ 0");
        }
        match &self.pivot {
            Pivot::BoucWen {
                amplitude,
                length,
                beta,
                n,
            } => {
                if !(amplitude.is_finite()
                    && pos(*length)
                    && *beta > 0.5
                    && *beta <= 1.0
                    && pos(*n))
                {
                    return bad(
                        "Bouc–Wen needs a finite amplitude, length > 0, beta in (0.5, 1], n > 0",
                    );
                }
            }
            Pivot::Prandtl {
                thresholds,
                weights,
            } => {
                if thresholds.len() != weights.len()
                    || thresholds.is_empty()
                    || !thresholds.iter().all(|&r| pos(r))
                    || !weights.iter().all(|w| w.is_finite())
                {
                    return bad("Prandtl needs as many weights as thresholds, thresholds > 0");
                }
            }
        }
        Ok(())
    }

    pub(super) fn trend(&self, u: f64) -> f64 {
        match self.trend {
            Trend::Sine {
                offset,
                slope,
                amplitude,
                cycles,
                phase,
            } => offset + slope * u + amplitude * (cycles * std::f64::consts::PI * u + phase).sin(),
            Trend::Cubic { c } => c[0] + u * (c[1] + u * (c[2] + u * c[3])),
        }
    }
}
