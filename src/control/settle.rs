//! The settle-optimal integrator start value at the seek → track-following handoff (the paper's
//! Section IV, eq. 13–16) and our robust choice for an uncertain bias.
//!
//! ## Model
//! In deviation coordinates x̃ = x − x_ss(d) (x_ss the loop's equilibrium for the constant bias
//! d, see [`Controller`]) the loop is x̃(k+1) = Acl x̃(k) and the measured position error
//! (e = y − r, µm) is linear in the integrator start value ζ = z0 − z_ss(d), which is the start
//! value **relative to its converged value** (µm·samples; zero feedforward is ζ = 0):
//! e(k) = a_k·ζ + c_k, with c_k = ce_k·e0 + cv_k·v0 + cu_k·(u_prev − d)   (flexible modes at rest).
//!
//! ## Settling
//! The settle index is one plus the last sample k < N (horizon) with |e(k)| > δ, or 0 if there is
//! none; the response is *settled* only if at least `hold` samples (M ≥ 1) at the end of the
//! horizon lie in the window, so a response still outside the window at k = N − 1 is "not
//! settled". Settle time = settle index × Ts.
//!
//! Per sample (eq. 14): for a_k > 0, L_k = (−δ − c_k)/a_k ≤ ζ ≤ (δ − c_k)/a_k = U_k, reversed
//! for a_k < 0. For a_k = 0 the sample constrains nothing if |c_k| ≤ δ (U = +∞, L = −∞) and
//! makes every settle index ≤ k infeasible otherwise (U = −∞, L = +∞).
//! Backward running bounds (eq. 15): U*(k) = min_{j ≥ k} U_j, L*(k) = max_{j ≥ k} L_j. The
//! minimum settle index k* is the first k ≤ N − M with L*(k) ≤ U*(k); every ζ in
//! [L*(k*), U*(k*)] achieves it (eq. 16). The width U* − L* grows with k, so a start value ζ
//! settles at the first k with L*(k) ≤ ζ ≤ U*(k).
//!
//! ## Robust choice for an uncertain bias (ours)
//! If the bias is only known to ±Δb, the converged value the start is referenced to is off by
//! up to s = |∂z/∂d|·Δb, so the true ζ lies anywhere in [ζ_chosen − s, ζ_chosen + s]. The
//! worst-case settle index of ζ_chosen is the first k with [ζ − s, ζ + s] ⊂ [L*(k), U*(k)]; it is
//! minimised by the first k with U*(k) − L*(k) ≥ 2s, at that interval's midpoint. (Assumption:
//! u_prev − d is known at handoff, as for a step from rest where the previous control equals the
//! actual bias.) [`worst_case_settle`] reports it together with zero feedforward's worst case.
//!
//! ## Fast path
//! [`HandoffTable`] precomputes, per controller and horizon, −ce_k/a_k, −cv_k/a_k, −cu_k/a_k and
//! 1/|a_k| as four plain arrays, so at handoff each sample's bounds are three multiply-adds plus
//! ±δ/|a_k| in a loop the compiler vectorises, and [`HandoffTable::solve`] finds k*, the optimal
//! interval, the robust choice and zero feedforward's worst case in one backward pass over
//! blocks of 8 samples that stops at the block where the interval empties: no allocation.
//! [`HandoffTable::bounds_into`] fills caller-provided [`Bounds`] buffers with the full curves
//! (Fig. 15). Both are tested against a slow obvious implementation (every bound, the running
//! min/max sample by sample, linear searches): identical results.

use crate::control::plant::{ModeSpec, Plant, PlantError, PlantSpec};
use crate::control::{Controller, LqrWeights, ServoError};
use nalgebra::DVector;
use serde::{Deserialize, Serialize};

/// A settle window or handoff setting that is out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SettleError {
    /// A value is out of range; names the setting.
    #[error("{field} must be {what}, got {value}")]
    Invalid {
        /// The setting.
        field: crate::field::Field,
        /// The accepted range.
        what: &'static str,
        /// The value given.
        value: f64,
    },
    /// A caller-provided buffer does not fit the table's horizon.
    #[error("bounds buffer holds {got} samples, the table's horizon is {want}")]
    BufferLength {
        /// Buffer length.
        got: usize,
        /// Horizon of the table.
        want: usize,
    },
}

/// An invalid settle description (plant TOML or preset plus flags).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// Unknown preset name.
    #[error("unknown preset `{0}` (known: {names})", names = PRESETS.join(", "))]
    UnknownPreset(String),
    /// The plant part is invalid.
    #[error("invalid plant: {0}")]
    Plant(#[from] PlantError),
    /// The LQR weights are invalid.
    #[error("invalid weights: {0}")]
    Weights(ServoError),
    /// The settle part is invalid.
    #[error("invalid settle settings: {0}")]
    Settle(#[from] SettleError),
}

/// Names of the built-in presets.
pub(crate) const PRESETS: [&str; 2] = ["paper1997", "modern"];

/// A settle problem as written in a plant TOML file or built from a preset (unvalidated).
/// Units: s, µm, counts; `q` weights [z, e, v, u_prev] (or the full loop state), `r` weights u².
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SettleSpec {
    /// Sample period Ts in s.
    pub ts_s: f64,
    /// Computation delay τ in s (0 ≤ τ < Ts).
    pub tau_s: f64,
    /// Actuator gain Kp in µm/s² per count.
    pub kp: f64,
    /// Flexible modes (frequency Hz, damping ratio, gain relative to the rigid body).
    #[serde(default)]
    pub modes: Vec<ModeSpec>,
    /// Diagonal LQR state weights: [z, e, v, u_prev] or one per loop state.
    pub q: Vec<f64>,
    /// LQR control weight R (> 0).
    pub r: f64,
    /// Step length in µm: the handoff starts at e0 = −step, v0 = 0, u_prev = bias.
    pub step_um: f64,
    /// Half-width δ of the settle window in µm (> 0).
    pub window_um: f64,
    /// Horizon N in samples (≥ 1).
    pub horizon: usize,
    /// Samples M ≥ 1 that must lie in the window at the end of the horizon.
    #[serde(default = "one")]
    pub hold: usize,
    /// Bias d in counts (the response in deviation coordinates does not depend on it; it sets
    /// the integrator's converged value ∂z/∂d·d).
    #[serde(default)]
    pub bias: f64,
    /// Bias uncertainty Δb in counts (≥ 0) for the robust choice.
    #[serde(default)]
    pub bias_uncertainty: f64,
}

/// A horizon must be 1 ..= [`MAX_HORIZON`] samples.
fn check_horizon(horizon: usize) -> Result<(), SettleError> {
    if horizon == 0 || horizon > MAX_HORIZON {
        return Err(SettleError::Invalid {
            field: crate::field::Field::Horizon,
            what: "between 1 and 1000000 samples",
            value: horizon as f64,
        });
    }
    Ok(())
}

fn one() -> usize {
    1
}

/// Largest accepted horizon (samples).
pub(crate) const MAX_HORIZON: usize = 1_000_000;

impl SettleSpec {
    /// A built-in preset by name (see `PRESETS`):
    ///
    /// - `paper1997`: the paper's test bed. Ts = 100 µs, τ = 40 µs, Kp = 1e6 µm/s² per count,
    ///   Q = diag(1e-4, 1.78e-3, 1e-9, 0), R = 1e-6, 15 µm step from rest, ±0.5 µm window,
    ///   horizon 128, Δb = 8 counts (the paper's full-algorithm prediction error std, "just under 8").
    /// - `modern`: 50 kHz, τ = 10 µs (the HDD benchmark's input delay), 50 nm track pitch, a
    ///   one-track (0.05 µm) step, window ±0.005 µm (10 % of a track), horizon 256, Δb = 8 counts.
    ///   Kp = 9.512e5 µm/s² per count (benchmark Kf/m = 951.2 m/s²/A with 1 count = 1 mA).
    ///   Modes at the IEEJ/NSS HDD benchmark frequencies 3.0, 4.1, 5.0, 7.0, 12.3, 16.4 kHz. The
    ///   damping/gain pairs are our choice, taken from the benchmark's v1 parameter file
    ///   (hdd_plantparam_v1.m: 3.0 kHz ζ 0.005 g 0.01; 4.1 kHz 0.02, −1.0; 5.0 kHz 0.001→0.005,
    ///   0.03; 12.3 kHz 0.02, −1.0; 16.4 kHz 0.02, 1.0) with the 7.0 kHz mode set to ζ 0.02,
    ///   g 0.1 (not in v1). LQR weights: see the constants in this function.
    pub fn preset(name: &str) -> Result<Self, ConfigError> {
        match name {
            "paper1997" => Ok(Self {
                ts_s: 100e-6,
                tau_s: 40e-6,
                kp: 1e6,
                modes: vec![],
                q: vec![1e-4, 1.78e-3, 1e-9, 0.0],
                r: 1e-6,
                step_um: 15.0,
                window_um: 0.5,
                horizon: 128,
                hold: 1,
                bias: 0.0,
                bias_uncertainty: 8.0,
            }),
            "modern" => {
                let mode = |freq_hz: f64, damping: f64, gain: f64| ModeSpec {
                    freq_hz,
                    damping,
                    gain,
                };
                Ok(Self {
                    ts_s: 20e-6,
                    tau_s: 10e-6,
                    kp: 9.512e5,
                    modes: vec![
                        mode(3000.0, 0.005, 0.01),
                        mode(4100.0, 0.02, -1.0),
                        mode(5000.0, 0.005, 0.03),
                        mode(7000.0, 0.02, 0.1),
                        mode(12300.0, 0.02, -1.0),
                        mode(16400.0, 0.02, 1.0),
                    ],
                    q: MODERN_Q.to_vec(),
                    r: MODERN_R,
                    step_um: 0.05,
                    window_um: 0.005,
                    horizon: 256,
                    hold: 1,
                    bias: 0.0,
                    bias_uncertainty: 8.0,
                })
            }
            other => Err(ConfigError::UnknownPreset(other.to_string())),
        }
    }

    /// Validates everything before any numerics: the plant (Ts, τ, Kp, modes), the weights
    /// (Q ≥ 0, R > 0), the window (> 0), horizon (1 ..= `MAX_HORIZON`), hold (1 ..= horizon),
    /// a finite step and bias, and Δb ≥ 0.
    pub fn check(&self) -> Result<SettleConfig, ConfigError> {
        let plant = Plant::new(&PlantSpec {
            ts_s: self.ts_s,
            tau_s: self.tau_s,
            kp: self.kp,
            modes: self.modes.clone(),
        })?;
        let weights =
            LqrWeights::new(&self.q, self.r, plant.order()).map_err(ConfigError::Weights)?;
        let bounded = |field: crate::field::Field, v: f64, limit: f64, what: &'static str| {
            if v.is_finite() && v.abs() <= limit {
                Ok(v)
            } else {
                Err(SettleError::Invalid {
                    field,
                    what,
                    value: v,
                })
            }
        };
        let step_um = bounded(
            crate::field::Field::StepUm,
            self.step_um,
            MAX_STEP_UM,
            "within ±1e6 µm",
        )?;
        let bias = bounded(
            crate::field::Field::Bias,
            self.bias,
            MAX_BIAS,
            "within ±1e9 counts",
        )?;
        let db = bounded(
            crate::field::Field::BiasUncertainty,
            self.bias_uncertainty,
            MAX_BIAS,
            "within 0 … 1e9 counts",
        )?;
        if db < 0.0 {
            return Err(SettleError::Invalid {
                field: crate::field::Field::BiasUncertainty,
                what: "≥ 0",
                value: db,
            }
            .into());
        }
        check_horizon(self.horizon)?;
        if self.hold > self.horizon {
            return Err(SettleError::Invalid {
                field: crate::field::Field::Hold,
                what: "at most the horizon",
                value: self.hold as f64,
            }
            .into());
        }
        let window = Window::new(self.window_um, self.hold)?;
        Ok(SettleConfig {
            plant,
            weights,
            scenario: Scenario {
                step_um,
                window,
                horizon: self.horizon,
                bias,
                bias_uncertainty: db,
            },
        })
    }
}

/// Largest |step| of a settle scenario, µm (a metre: beyond any actuator's stroke; longer steps
/// make the start-value bounds overflow).
pub(crate) const MAX_STEP_UM: f64 = 1e6;
/// Largest |bias| and bias uncertainty of a settle scenario, counts.
pub(crate) const MAX_BIAS: f64 = 1e9;

/// LQR state weights of the `modern` preset over [z, e, v, u_prev] (modal states weight 0):
/// picked from a grid q_z ∈ {1e-4 … 1e-1}, q_e ∈ {0.1 … 100}, q_v ∈ {1e-9 … 1e-6} with R = 1e-6 as
/// the design meeting the paper's own specification scaled to this drive (zero-feedforward
/// one-track settle < 3 ms with < 30 % overshoot) with the shortest optimal settle. The modal
/// states are not weighted, so the lightly damped 3 kHz mode (ζ = 0.005) sets the slowest pole.
pub(crate) const MODERN_Q: [f64; 4] = [1e-2, 0.1, 1e-6, 0.0];
/// LQR control weight of the `modern` preset.
pub(crate) const MODERN_R: f64 = 1e-6;

/// A validated settle description: plant, weights and scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct SettleConfig {
    /// The continuous plant and its sampling.
    pub plant: Plant,
    /// The LQR weights.
    pub weights: LqrWeights,
    /// The handoff scenario.
    pub scenario: Scenario,
}

/// A validated handoff scenario.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scenario {
    /// Step length in µm (handoff e0 = −step).
    pub step_um: f64,
    /// The settle window.
    pub window: Window,
    /// Horizon N in samples.
    pub horizon: usize,
    /// Bias d in counts.
    pub bias: f64,
    /// Bias uncertainty Δb in counts (≥ 0).
    pub bias_uncertainty: f64,
}

impl Scenario {
    /// The handoff of a step from rest: e0 = −step, v0 = 0, u_prev holding the bias.
    pub fn handoff(&self) -> Handoff {
        Handoff {
            e0_um: -self.step_um,
            v0_um_s: 0.0,
            u_prev_counts: self.bias,
            bias_counts: self.bias,
        }
    }
}

/// A validated settle window: half-width δ (µm) and hold M (samples).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    half_width_um: f64,
    hold: usize,
}

impl Window {
    /// A window |e| ≤ `half_width_um` (0 < half width ≤ `MAX_STEP_UM`) that must hold for
    /// the last `hold` ≥ 1 samples of the horizon.
    pub fn new(half_width_um: f64, hold: usize) -> Result<Self, SettleError> {
        if !(half_width_um > 0.0 && half_width_um <= MAX_STEP_UM) {
            return Err(SettleError::Invalid {
                field: crate::field::Field::WindowUm,
                what: "> 0 and at most 1e6 µm",
                value: half_width_um,
            });
        }
        if hold == 0 {
            return Err(SettleError::Invalid {
                field: crate::field::Field::Hold,
                what: "≥ 1",
                value: 0.0,
            });
        }
        Ok(Self {
            half_width_um,
            hold,
        })
    }
    /// Half-width δ in µm.
    pub fn half_width_um(&self) -> f64 {
        self.half_width_um
    }
    /// Hold M in samples.
    pub fn hold(&self) -> usize {
        self.hold
    }
}

/// The loop's state at handoff (the seek controller's last values).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Handoff {
    /// Position error e0 = y − r in µm.
    pub e0_um: f64,
    /// Velocity v0 in µm/s.
    pub v0_um_s: f64,
    /// The control applied during the first τ of the first period, in counts.
    pub u_prev_counts: f64,
    /// The (predicted) bias d in counts.
    pub bias_counts: f64,
}

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

/// An interval of start values (µm·samples, relative to the converged integrator value) that
/// settles by sample `k`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Interval {
    /// Settle index reached by every start value in [lo, hi].
    pub k: usize,
    /// Lower bound L*(k) (may be −∞).
    pub lo: f64,
    /// Upper bound U*(k) (may be +∞).
    pub hi: f64,
}

impl Interval {
    /// The start value at least `margin` inside both ends: the midpoint when both ends are
    /// finite, otherwise the value closest to zero feedforward (0) that keeps the margin.
    #[inline]
    pub fn choice(&self, margin: f64) -> f64 {
        if self.lo.is_finite() && self.hi.is_finite() {
            0.5 * (self.lo + self.hi)
        } else {
            let lo = self.lo + margin;
            let hi = self.hi - margin;
            if lo > hi {
                0.5 * (lo + hi)
            } else {
                0.0f64.clamp(lo, hi)
            }
        }
    }
}

/// What the handoff fast path finds (start values relative to the converged value).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandoffSolution {
    /// The minimum settle index k* and the optimal interval; `None` if nothing settles.
    pub optimal: Option<Interval>,
    /// The first interval at least 2s wide (s = |∂z/∂d|·Δb); its [`Interval::choice`] with
    /// margin s (the midpoint when both ends are finite) is the robust choice and `k` its
    /// worst-case settle index.
    pub robust: Option<Interval>,
    /// Worst-case settle index of zero feedforward for the true start in [−s, s].
    pub zero_ff_worst: Option<usize>,
    /// s = |∂z/∂d|·Δb in µm·samples.
    pub shift: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct ZeroGain {
    k: usize,
    ce: f64,
    cv: f64,
    cu: f64,
}

/// min(a, b) as one `minsd`/`minpd`: `b` if `b < a`, else `a` (a NaN `b` is ignored).
#[inline(always)]
fn fmin(a: f64, b: f64) -> f64 {
    if b < a { b } else { a }
}

/// max(a, b) as one `maxsd`/`maxpd` (a NaN `b` is ignored).
#[inline(always)]
fn fmax(a: f64, b: f64) -> f64 {
    if b > a { b } else { a }
}

/// Samples per block of the blocked backward scans.
const BLOCK: usize = 8;

/// What every sample's bounds are linear in: the handoff state and the window half-width.
#[derive(Debug, Clone, Copy)]
struct Point {
    e0: f64,
    v0: f64,
    du: f64,
    delta: f64,
}

impl Point {
    /// U_k and L_k (eq. 14) from one sample's coefficients.
    #[inline(always)]
    fn bounds(&self, pe: f64, pv: f64, pu: f64, w: f64) -> (f64, f64) {
        let mid = pe * self.e0 + pv * self.v0 + pu * self.du;
        let half = w * self.delta;
        (mid + half, mid - half)
    }
}

/// A sample k with a_k = 0 and its coefficients `[ce, cv, cu]` ([`HandoffTable::export_rows`]).
pub(crate) type ZeroGainRow = (usize, [f64; 3]);

/// The running bounds of one block: `su[j] = min(umin, min_{i ≥ j} u[i])` and `sl[j] =
/// max(lmax, max_{i ≥ j} l[i])`, where `(umin, lmax)` are the bounds over the samples above the
/// block. The block's own suffix scan starts from ±∞, so it does not wait for the blocks above
/// and consecutive blocks overlap in the CPU; only the final combine depends on them.
#[inline(always)]
fn suffix_into(u: &[f64], l: &[f64], su: &mut [f64], sl: &mut [f64], umin: f64, lmax: f64) {
    let m = u.len();
    let (l, su, sl) = (&l[..m], &mut su[..m], &mut sl[..m]);
    let (mut a, mut b) = (f64::INFINITY, f64::NEG_INFINITY);
    for j in (0..m).rev() {
        a = fmin(a, u[j]);
        b = fmax(b, l[j]);
        su[j] = a;
        sl[j] = b;
    }
    for j in 0..m {
        su[j] = fmin(umin, su[j]);
        sl[j] = fmax(lmax, sl[j]);
    }
}

/// Four samples with lane-wise arithmetic: in a function compiled for AVX2 each operation is one
/// 256-bit instruction (the compiler keeps the lanes of the fixed-size array together, where a
/// loop over a block of 8 became 128-bit pairs of U and L).
#[derive(Debug, Clone, Copy)]
struct F4([f64; 4]);

impl F4 {
    #[inline(always)]
    fn splat(x: f64) -> Self {
        Self([x; 4])
    }
    #[inline(always)]
    fn load(s: &[f64]) -> Self {
        Self([s[0], s[1], s[2], s[3]])
    }
    #[inline(always)]
    fn zip(self, o: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        let (a, b) = (self.0, o.0);
        Self([f(a[0], b[0]), f(a[1], b[1]), f(a[2], b[2]), f(a[3], b[3])])
    }
    /// min over the lanes, as a tree (exact for NaN-free lanes).
    #[inline(always)]
    fn hmin(self) -> f64 {
        let a = self.0;
        fmin(fmin(a[0], a[2]), fmin(a[1], a[3]))
    }
    /// max over the lanes, as a tree (exact for NaN-free lanes).
    #[inline(always)]
    fn hmax(self) -> f64 {
        let a = self.0;
        fmax(fmax(a[0], a[2]), fmax(a[1], a[3]))
    }
}

/// The conditions of [`HandoffTable::solve`] on the running bounds (U*, L*), nested: 0, zero
/// feedforward's worst case inside (L* ≤ −s, U* ≥ s); 1, width ≥ 2s; 2, width ≥ 0.
#[inline(always)]
fn keep<const P: usize>(u: f64, l: f64, shift: f64) -> bool {
    match P {
        0 => l <= -shift && u >= shift,
        1 => u - l >= 2.0 * shift,
        _ => u - l >= 0.0,
    }
}

/// The backward scan of [`HandoffTable::solve`]: the next candidate k (samples k.. are in the
/// running bounds `umin` = U*(k), `lmax` = L*(k)), moving down towards `floor`.
struct Scan<'a> {
    table: &'a HandoffTable,
    p: Point,
    /// The handoff's point as lanes: e0, v0, du, δ.
    lanes: [F4; 4],
    floor: usize,
    /// No bound can be NaN: whole blocks may be reduced as trees.
    nan_free: bool,
    shift: f64,
    k: usize,
    umin: f64,
    lmax: f64,
    /// The samples k − `left` .. k of the block where the previous condition stopped holding,
    /// not yet walked, with their bounds in `u[..left]`, `l[..left]`: the next condition
    /// walks them first instead of computing a new (unaligned) block.
    left: usize,
    u: [f64; BLOCK],
    l: [f64; BLOCK],
}

impl Scan<'_> {
    /// U_k, L_k of the block of samples `lo .. lo + BLOCK`, four at a time.
    #[inline(always)]
    fn block(&self, lo: usize) -> ([F4; 2], [F4; 2]) {
        let t = self.table;
        let [e0, v0, du, delta] = self.lanes;
        let (pe, pv) = (&t.pe[lo..lo + BLOCK], &t.pv[lo..lo + BLOCK]);
        let (pu, w) = (&t.pu[lo..lo + BLOCK], &t.w[lo..lo + BLOCK]);
        let mut u = [F4::splat(0.0); 2];
        let mut l = [F4::splat(0.0); 2];
        for h in 0..2 {
            let o = 4 * h;
            let mul = |a: f64, b: f64| a * b;
            let add = |a: f64, b: f64| a + b;
            // Point::bounds, lane by lane, the same operations in the same order.
            let mid = F4::load(&pe[o..])
                .zip(e0, mul)
                .zip(F4::load(&pv[o..]).zip(v0, mul), add)
                .zip(F4::load(&pu[o..]).zip(du, mul), add);
            let half = F4::load(&w[o..]).zip(delta, mul);
            u[h] = mid.zip(half, add);
            l[h] = mid.zip(half, |a, b| a - b);
        }
        (u, l)
    }

    /// Moves down while condition `P` holds and returns (k, L*(k), U*(k)) for the lowest k at
    /// which it holds (k = the floor if it holds all the way; k above the last candidate if it
    /// never does). The samples the previous condition left in its last block come first,
    /// sample by sample; then whole blocks that keep it are taken from their tree min/max,
    /// and the block where it stops holding is walked sample by sample (its unwalked samples
    /// are left to the next condition).
    #[inline(always)]
    fn run<const P: usize>(&mut self) -> (usize, f64, f64) {
        let (mut k, mut umin, mut lmax) = (self.k, self.umin, self.lmax);
        let (mut u, mut l) = (self.u, self.l);
        // The running bounds ignore a NaN bound (fmin/fmax keep their first operand).
        let mut left = 0;
        for j in (0..self.left).rev() {
            let (a, b) = (fmin(umin, u[j]), fmax(lmax, l[j]));
            if !keep::<P>(a, b, self.shift) {
                left = j + 1;
                break;
            }
            (umin, lmax, k) = (a, b, k - 1);
        }
        if left == 0 {
            'blocks: while k > self.floor {
                let m = (k - self.floor).min(BLOCK);
                let lo = k - m;
                if m == BLOCK {
                    let (bu, bl) = self.block(lo);
                    if self.nan_free {
                        let bmin = bu[0].zip(bu[1], fmin).hmin();
                        let bmax = bl[0].zip(bl[1], fmax).hmax();
                        let (nu, nl) = (fmin(umin, bmin), fmax(lmax, bmax));
                        if keep::<P>(nu, nl, self.shift) {
                            (umin, lmax, k) = (nu, nl, lo);
                            continue;
                        }
                    }
                    for h in 0..2 {
                        u[4 * h..4 * h + 4].copy_from_slice(&bu[h].0);
                        l[4 * h..4 * h + 4].copy_from_slice(&bl[h].0);
                    }
                } else {
                    self.table.fill(lo, self.p, &mut u[..m], &mut l[..m]);
                }
                for j in (0..m).rev() {
                    let (a, b) = (fmin(umin, u[j]), fmax(lmax, l[j]));
                    if !keep::<P>(a, b, self.shift) {
                        left = j + 1;
                        break 'blocks;
                    }
                    (umin, lmax, k) = (a, b, lo + j);
                }
            }
        }
        (self.k, self.umin, self.lmax) = (k, umin, lmax);
        (self.left, self.u, self.l) = (left, u, l);
        (k, lmax, umin)
    }
}

/// Per-controller, per-horizon coefficients of the handoff bounds (see the module docs), laid
/// out as four plain arrays (one per coefficient) so the bound loops vectorise.
#[derive(Debug, Clone, PartialEq)]
pub struct HandoffTable {
    /// −ce_k/a_k (0 where a_k = 0).
    pe: Box<[f64]>,
    /// −cv_k/a_k (0 where a_k = 0).
    pv: Box<[f64]>,
    /// −cu_k/a_k (0 where a_k = 0).
    pu: Box<[f64]>,
    /// 1/|a_k| (+∞ where a_k = 0: unconstrained unless `zero` rules the sample out).
    w: Box<[f64]>,
    /// The samples with a_k = 0, latest first.
    zero: Vec<ZeroGain>,
    ts_s: f64,
    dz_dbias: f64,
    /// Largest |pe|, |pv|, |pu| and largest finite w: with them a handoff's bounds are known
    /// to be NaN-free before they are computed.
    coef_max: f64,
    w_max: f64,
    /// The CPU has AVX2: the same arithmetic runs four samples per instruction.
    avx2: bool,
}

/// Whether this CPU runs the AVX2 copies of the handoff loops.
fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// |a_k| below this fraction of max |a_k| counts as a_k = 0.
const ZERO_GAIN_REL: f64 = 1e-13;

impl HandoffTable {
    /// Precomputes a_k, c_k's coefficients for k = 0 .. horizon − 1 from C·Acl^k (the
    /// measured-error row). `horizon` must be ≥ 1.
    pub fn new(controller: &Controller, horizon: usize) -> Result<Self, SettleError> {
        check_horizon(horizon)?;
        let n = controller.order();
        let acl = controller.closed_loop();
        let mut row = controller.c().transpose();
        let mut raw = Vec::with_capacity(horizon);
        for _ in 0..horizon {
            raw.push((row[0], row[1], row[2], row[n - 1]));
            row = &row * acl;
        }
        let amax = raw.iter().fold(0.0f64, |m, r| m.max(r.0.abs()));
        let (mut pe, mut pv, mut pu, mut w) = (
            Vec::with_capacity(horizon),
            Vec::with_capacity(horizon),
            Vec::with_capacity(horizon),
            Vec::with_capacity(horizon),
        );
        let mut zero = Vec::new();
        for (k, &(a, ce, cv, cu)) in raw.iter().enumerate() {
            if a.abs() <= ZERO_GAIN_REL * amax || a.abs() == 0.0 {
                zero.push(ZeroGain { k, ce, cv, cu });
                pe.push(0.0);
                pv.push(0.0);
                pu.push(0.0);
                w.push(f64::INFINITY);
            } else {
                pe.push(-ce / a);
                pv.push(-cv / a);
                pu.push(-cu / a);
                w.push(1.0 / a.abs());
            }
        }
        zero.reverse();
        let abs_max = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let coef_max = abs_max(&pe).max(abs_max(&pv)).max(abs_max(&pu));
        let w_max = w
            .iter()
            .filter(|x| x.is_finite())
            .fold(0.0f64, |m, &x| m.max(x));
        Ok(Self {
            pe: pe.into(),
            pv: pv.into(),
            pu: pu.into(),
            w: w.into(),
            zero,
            ts_s: controller.ts_s(),
            dz_dbias: controller.dz_dbias(),
            coef_max,
            w_max,
            avx2: has_avx2(),
        })
    }

    /// Horizon N in samples.
    pub fn horizon(&self) -> usize {
        self.w.len()
    }
    /// Sample period Ts in s.
    pub fn ts_s(&self) -> f64 {
        self.ts_s
    }
    /// ∂z/∂d of the controller (µm·samples per count).
    pub fn dz_dbias(&self) -> f64 {
        self.dz_dbias
    }

    /// The table as the C export writes it: per sample k the bounds' coefficients
    /// `[−ce/a, −cv/a, −cu/a, 1/|a|]` (`[0, 0, 0, ∞]` where a_k = 0), and the samples with
    /// a_k = 0 as `(k, [ce, cv, cu])` in ascending k.
    pub fn export_rows(&self) -> (Vec<[f64; 4]>, Vec<ZeroGainRow>) {
        let rows = (0..self.w.len())
            .map(|k| [self.pe[k], self.pv[k], self.pu[k], self.w[k]])
            .collect();
        let mut zeros: Vec<ZeroGainRow> = self
            .zero
            .iter()
            .map(|z| (z.k, [z.ce, z.cv, z.cu]))
            .collect();
        zeros.sort_by_key(|z| z.0);
        (rows, zeros)
    }

    /// c_k of a sample with a_k = 0 rules out every settle index ≤ k when |c_k| > δ.
    #[inline]
    fn rules_out(z: &ZeroGain, p: Point) -> bool {
        let c = z.ce * p.e0 + z.cv * p.v0 + z.cu * p.du;
        c.is_nan() || c.abs() > p.delta
    }

    /// One plus the largest k with a_k = 0 and |c_k| > δ (0 if none): no settle index below it.
    #[inline]
    fn floor(&self, p: Point) -> usize {
        self.zero
            .iter()
            .find(|z| Self::rules_out(z, p))
            .map_or(0, |z| z.k + 1)
    }

    /// U_k, L_k (eq. 14) of samples `lo .. lo + u.len()` into `u` and `l`, zero-gain samples
    /// unconstrained (`floor` and `bounds_into` handle the ones that rule settling out).
    #[inline(always)]
    fn fill(&self, lo: usize, p: Point, u: &mut [f64], l: &mut [f64]) {
        let m = u.len();
        let l = &mut l[..m];
        let (pe, pv) = (&self.pe[lo..lo + m], &self.pv[lo..lo + m]);
        let (pu, w) = (&self.pu[lo..lo + m], &self.w[lo..lo + m]);
        for j in 0..m {
            (u[j], l[j]) = p.bounds(pe[j], pv[j], pu[j], w[j]);
        }
    }

    /// The handoff computation, allocation-free: a backward pass over the bounds of eq. 14
    /// with the running min/max of eq. 15, stopping as soon as the interval is empty. Returns
    /// k* with the optimal interval (eq. 16), the robust interval for a bias uncertainty
    /// `delta_b` (counts, ≥ 0; its absolute value is used) and zero feedforward's worst case.
    /// A non-finite handoff state settles nothing (all `None`).
    ///
    /// The three conditions (zero feedforward's worst case inside, width ≥ 2s, width ≥ 0) are
    /// nested and each holds on a suffix of settle indices (U* grows and L* falls with k), so
    /// one scan per condition continues where the previous one stopped, each with its
    /// condition fixed (no test of which condition is current in the loop). The scan runs over
    /// blocks of 8 samples: a block's bounds are computed four lanes at a time and reduced as a
    /// tree; only the block where the condition stops holding is walked sample by sample. On a
    /// CPU with AVX2 the same code runs compiled for it (the same operations in the same
    /// order: identical results).
    pub fn solve(&self, h: &Handoff, window: &Window, delta_b: f64) -> HandoffSolution {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is true only when `new` found AVX2 on this CPU.
            return unsafe { self.solve_avx2(h, window, delta_b) };
        }
        self.solve_portable(h, window, delta_b)
    }

    /// [`HandoffTable::solve`] compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn solve_avx2(&self, h: &Handoff, window: &Window, delta_b: f64) -> HandoffSolution {
        self.solve_portable(h, window, delta_b)
    }

    /// [`HandoffTable::solve`] for any CPU.
    #[inline(always)]
    fn solve_portable(&self, h: &Handoff, window: &Window, delta_b: f64) -> HandoffSolution {
        let n = self.w.len();
        let delta = window.half_width_um;
        let shift = (self.dz_dbias * delta_b).abs();
        let mut out = HandoffSolution {
            optimal: None,
            robust: None,
            zero_ff_worst: None,
            shift,
        };
        let du = h.u_prev_counts - h.bias_counts;
        let (e0, v0) = (h.e0_um, h.v0_um_s);
        if window.hold > n || !(e0.is_finite() && v0.is_finite() && du.is_finite()) {
            return out;
        }
        let p = Point { e0, v0, du, delta };
        let top = n - window.hold;
        let floor = self.floor(p);
        if floor > top {
            return out;
        }
        // Running bounds over samples [k, n): start with the samples after the last candidate.
        let mut umin = f64::INFINITY;
        let mut lmax = f64::NEG_INFINITY;
        for k in top + 1..n {
            let (u, l) = p.bounds(self.pe[k], self.pv[k], self.pu[k], self.w[k]);
            umin = fmin(umin, u);
            lmax = fmax(lmax, l);
        }
        // |U_k|, |L_k| ≤ bound: far from overflow, so no bound is NaN and whole blocks can be
        // reduced as trees; otherwise every block takes the per-sample path (NaN ignored).
        let bound = self.coef_max * (e0.abs() + v0.abs() + du.abs()) + self.w_max * delta;
        let mut scan = Scan {
            table: self,
            p,
            lanes: [e0, v0, du, delta].map(F4::splat),
            floor,
            nan_free: bound < f64::MAX / 16.0,
            shift,
            k: top + 1,
            umin,
            lmax,
            left: 0,
            u: [0.0; BLOCK],
            l: [0.0; BLOCK],
        };
        // The conditions are nested: each scan starts where the previous one stopped.
        let found = [scan.run::<0>(), scan.run::<1>(), scan.run::<2>()];
        let interval =
            |(k, lo, hi): (usize, f64, f64)| (k <= top).then_some(Interval { k, lo, hi });
        out.zero_ff_worst = interval(found[0]).map(|i| i.k);
        out.robust = interval(found[1]);
        out.optimal = interval(found[2]);
        out
    }

    /// Fills `buf` with the per-sample bounds (eq. 14) and the backward running min/max
    /// (eq. 15) of `h`, without allocating. `buf` must have been made for this horizon.
    pub fn bounds_into(
        &self,
        h: &Handoff,
        window: &Window,
        buf: &mut Bounds,
    ) -> Result<(), SettleError> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is true only when `new` found AVX2 on this CPU.
            return unsafe { self.bounds_into_avx2(h, window, buf) };
        }
        self.bounds_into_portable(h, window, buf)
    }

    /// [`HandoffTable::bounds_into`] compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn bounds_into_avx2(
        &self,
        h: &Handoff,
        window: &Window,
        buf: &mut Bounds,
    ) -> Result<(), SettleError> {
        self.bounds_into_portable(h, window, buf)
    }

    /// [`HandoffTable::bounds_into`] for any CPU.
    #[inline(always)]
    fn bounds_into_portable(
        &self,
        h: &Handoff,
        window: &Window,
        buf: &mut Bounds,
    ) -> Result<(), SettleError> {
        let n = self.w.len();
        if buf.upper.len() != n {
            return Err(SettleError::BufferLength {
                got: buf.upper.len(),
                want: n,
            });
        }
        let p = Point {
            e0: h.e0_um,
            v0: h.v0_um_s,
            du: h.u_prev_counts - h.bias_counts,
            delta: window.half_width_um,
        };
        self.fill(0, p, &mut buf.upper, &mut buf.lower);
        for z in &self.zero {
            if Self::rules_out(z, p) {
                buf.upper[z.k] = f64::NEG_INFINITY;
                buf.lower[z.k] = f64::INFINITY;
            }
        }
        // Blocks from the end: each block's suffix scan is independent of the blocks above.
        let mut run = (f64::INFINITY, f64::NEG_INFINITY);
        let mut hi = n;
        while hi >= BLOCK {
            run = buf.running_block(hi - BLOCK, hi, run);
            hi -= BLOCK;
        }
        if hi > 0 {
            buf.running_block(0, hi, run);
        }
        buf.hold = window.hold;
        Ok(())
    }
}

/// The bounds curves of one handoff (Fig. 15), start values in µm·samples relative to the
/// converged value. Make once per horizon with [`Bounds::new`] and refill with
/// [`HandoffTable::bounds_into`].
#[derive(Debug, Clone, PartialEq)]
pub struct Bounds {
    upper: Vec<f64>,
    lower: Vec<f64>,
    upper_min: Vec<f64>,
    lower_max: Vec<f64>,
    hold: usize,
}

impl Bounds {
    /// Buffers for a horizon of `n` samples.
    pub fn new(n: usize) -> Self {
        Self {
            upper: vec![f64::INFINITY; n],
            lower: vec![f64::NEG_INFINITY; n],
            upper_min: vec![f64::INFINITY; n],
            lower_max: vec![f64::NEG_INFINITY; n],
            hold: 1,
        }
    }
    /// Per-sample upper bounds U_k.
    pub fn upper(&self) -> &[f64] {
        &self.upper
    }
    /// Per-sample lower bounds L_k.
    pub fn lower(&self) -> &[f64] {
        &self.lower
    }
    /// Backward running minimum U*(k) = min_{j ≥ k} U_j.
    pub fn upper_min(&self) -> &[f64] {
        &self.upper_min
    }
    /// Backward running maximum L*(k) = max_{j ≥ k} L_j.
    pub fn lower_max(&self) -> &[f64] {
        &self.lower_max
    }

    /// Running bounds of samples `lo .. hi` from their bounds and the running bounds `run` =
    /// (U*, L*) of the samples from `hi` on; returns (U*(lo), L*(lo)).
    #[inline(always)]
    fn running_block(&mut self, lo: usize, hi: usize, run: (f64, f64)) -> (f64, f64) {
        suffix_into(
            &self.upper[lo..hi],
            &self.lower[lo..hi],
            &mut self.upper_min[lo..hi],
            &mut self.lower_max[lo..hi],
            run.0,
            run.1,
        );
        (self.upper_min[lo], self.lower_max[lo])
    }

    fn top(&self) -> Option<usize> {
        self.upper.len().checked_sub(self.hold)
    }

    /// The settle index of start value `zeta`: the first k ≤ N − M with L*(k) ≤ ζ ≤ U*(k).
    pub fn settle_index_of(&self, zeta: f64) -> Option<usize> {
        (0..=self.top()?).find(|&k| self.lower_max[k] <= zeta && zeta <= self.upper_min[k])
    }

    /// k* and the optimal interval (eq. 16), from the stored curves.
    pub fn optimal(&self) -> Option<Interval> {
        let top = self.top()?;
        self.lower_max[..=top]
            .iter()
            .zip(&self.upper_min[..=top])
            .position(|(lo, hi)| lo <= hi)
            .map(|k| Interval {
                k,
                lo: self.lower_max[k],
                hi: self.upper_min[k],
            })
    }

    /// The paper's robust choice: the first local minimum k of the per-sample upper bound U_k
    /// (finite neighbours, U_{k−1} > U_k ≤ U_{k+1}) and the average (U_k + L_k)/2 there.
    /// `None` when the curve has no such minimum.
    pub fn paper_robust(&self) -> Option<(usize, f64)> {
        let u = &self.upper;
        (1..u.len().saturating_sub(1))
            .find(|&k| {
                u[k - 1].is_finite()
                    && u[k].is_finite()
                    && u[k + 1].is_finite()
                    && u[k - 1] > u[k]
                    && u[k] <= u[k + 1]
            })
            .map(|k| (k, 0.5 * (u[k] + self.lower[k])))
    }
}

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

impl SettleReport {
    /// The absolute integrator start value (µm·samples) of a start value `relative` to the
    /// converged value: `z_converged + relative` (zero feedforward, relative 0, starts the
    /// integrator at its converged value for this bias).
    pub fn absolute(&self, relative: f64) -> f64 {
        self.z_converged + relative
    }

    /// The report as text, one fact a line (what `biasctl settle` prints): the LQR gain and
    /// DARE convergence, closed-loop poles, dz/dbias, the scenario, zero feedforward, the optimal
    /// start values (relative to the converged value, µm·samples), the paper's robust choice and
    /// the robust choice for ±Δb counts; settle times in ms.
    pub fn to_text(&self) -> String {
        let r = self;
        let mut out = String::new();
        let ms = settle_ms_text;
        let abs = |v: f64| format!("{v:.4} [{:.4}]", r.absolute(v));
        let gain: Vec<String> = r.gain.iter().map(|g| format!("{g:.6}")).collect();
        let poles: Vec<String> = r.poles_abs.iter().map(|p| format!("{p:.5}")).collect();
        push_line!(out, "LQR gain K = [{}]", gain.join(", "));
        push_line!(
            out,
            "  DARE: {} doubling steps, residual {:.1e}",
            r.dare_iterations,
            r.dare_residual
        );
        push_line!(out, "closed-loop |poles| = [{}]", poles.join(", "));
        push_line!(out, "dz/dbias = {:.5} (µm·samples per count)", r.dz_dbias);
        push_line!(
            out,
            "step {} µm, window ±{} µm, horizon {} samples, hold {}; start values (µm·samples) relative to the converged value {:.4}, absolute in brackets",
            r.step_um,
            r.window_um,
            r.horizon,
            r.hold,
            r.z_converged
        );
        push_line!(
            out,
            "zero feedforward: {} (overshoot {:.1} %), start value {}",
            r.zero_ff_settle_ms
                .map_or("does not settle within the horizon".to_string(), |m| {
                    format!("settles in {m:.2} ms")
                }),
            r.zero_ff_overshoot_pct,
            abs(0.0)
        );
        match (r.k_star, r.ff_interval) {
            (Some(k), Some([lo, hi])) => push_line!(
                out,
                "optimal: k* = {k}, {} for start values in [{lo:.4}, {hi:.4}] (choice {})",
                ms(r.optimal_settle_ms),
                r.ff_midpoint.map_or("none".to_string(), abs)
            ),
            _ => push_line!(out, "optimal: no start value settles within the horizon"),
        }
        match &r.paper_robust {
            Some(p) => push_line!(
                out,
                "paper's robust choice: {} (first local minimum of the upper bound at k = {}): {}",
                abs(p.ff),
                p.k_min,
                ms(p.settle_ms)
            ),
            None => push_line!(
                out,
                "paper's robust choice: the upper bound has no local minimum"
            ),
        }
        let w = &r.worst_case;
        match &r.robust {
            Some(c) => push_line!(
                out,
                "robust for ±{:.3} counts (shift ±{:.4}): {}, worst case {} (simulated {}); zero feedforward worst case {}",
                w.delta_b,
                w.shift,
                abs(c.ff),
                ms(Some(c.worst_settle_ms)),
                ms(c.simulated_worst_settle_ms),
                ms(w.zero_ff_worst_settle_ms)
            ),
            None => push_line!(
                out,
                "robust for ±{:.3} counts: no start value settles for every bias within the horizon",
                w.delta_b
            ),
        }
        out
    }

    /// The bounds of Fig. 15 as CSV: `k,time_s,upper,lower,upper_min,lower_max` (start values in
    /// µm·samples relative to the converged value; time in s). A bound that does not exist at a
    /// sample (at k = 0 no start value puts e(0) = −step in the window) is an empty cell.
    pub fn bounds_csv(&self) -> String {
        let b = &self.bounds;
        let header = ["k", "time_s", "upper", "lower", "upper_min", "lower_max"].map(String::from);
        let rows = (0..b.upper().len()).map(|k| {
            vec![
                k.to_string(),
                format!("{:.7}", k as f64 * self.ts_s),
                csv_cell(b.upper()[k]),
                csv_cell(b.lower()[k]),
                csv_cell(b.upper_min()[k]),
                csv_cell(b.lower_max()[k]),
            ]
        });
        csv_text(header.to_vec(), rows)
    }

    /// The responses of Fig. 16 as CSV: `k,time_s` and one `e_<choice>_um` column (µm) per
    /// start-value choice.
    pub fn responses_csv(&self) -> String {
        let mut header = vec!["k".to_string(), "time_s".to_string()];
        header.extend(self.responses.iter().map(|x| format!("e_{}_um", x.name)));
        let rows = (0..self.horizon).map(|k| {
            let mut row = vec![k.to_string(), format!("{:.7}", k as f64 * self.ts_s)];
            row.extend(
                self.responses
                    .iter()
                    .map(|x| x.e_um.get(k).map_or(String::new(), |e| csv_cell(*e))),
            );
            row
        });
        csv_text(header, rows)
    }
}

/// A header and rows as CSV text through [`crate::log::csv_writer`] (quoting where needed).
fn csv_text(header: Vec<String>, rows: impl Iterator<Item = Vec<String>>) -> String {
    let mut w = crate::log::csv_writer(Vec::new());
    // Writing to memory cannot fail.
    let _ = w.write_record(&header);
    for r in rows {
        let _ = w.write_record(&r);
    }
    w.into_inner()
        .ok()
        .and_then(|b| String::from_utf8(b).ok())
        .unwrap_or_default()
}

/// A CSV cell: the number, or an empty cell where it is not finite (no bound exists at that
/// sample, or the response overflowed), so the file never holds `inf` or `NaN`.
fn csv_cell(x: f64) -> String {
    if x.is_finite() {
        x.to_string()
    } else {
        String::new()
    }
}

/// The worst-case settle time when the bias is only known to ±`delta_b` counts (for example a
/// bias prediction and its error std), with the robust choice and with zero feedforward.
///
/// ```
/// use biasctl::Controller;
/// use biasctl::{HandoffTable, SettleSpec, worst_case_settle};
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

/// Everything `biasctl settle` reports. JSON keys as documented in the README.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SettleReport {
    /// LQR gain K over the loop state (u = −K x).
    pub gain: Vec<f64>,
    /// Closed-loop pole magnitudes, ascending.
    pub poles_abs: Vec<f64>,
    /// ∂z/∂d in µm·samples per count.
    pub dz_dbias: f64,
    /// Doubling steps of the DARE solve.
    pub dare_iterations: usize,
    /// Relative residual of the DARE solution.
    pub dare_residual: f64,
    /// Sample period in s.
    pub ts_s: f64,
    /// Horizon in samples.
    pub horizon: usize,
    /// Window half-width in µm.
    pub window_um: f64,
    /// Hold in samples.
    pub hold: usize,
    /// Step in µm.
    pub step_um: f64,
    /// Bias d in counts.
    pub bias: f64,
    /// The integrator's converged value ∂z/∂d·d (µm·samples); start values are relative to it.
    pub z_converged: f64,
    /// Minimum settle index k* (`None`: nothing settles in the horizon).
    pub k_star: Option<usize>,
    /// k*·Ts in ms.
    pub optimal_settle_ms: Option<f64>,
    /// [L*(k*), U*(k*)]: the optimal start values relative to the converged value.
    pub ff_interval: Option<[f64; 2]>,
    /// The start value chosen in the optimal interval ([`Interval::choice`] with no margin): its
    /// midpoint when both ends are finite, otherwise the value closest to zero feedforward (0)
    /// inside it. Relative to the converged value, µm·samples.
    pub ff_midpoint: Option<f64>,
    /// Settle time of zero feedforward in ms.
    pub zero_ff_settle_ms: Option<f64>,
    /// Overshoot of the zero-feedforward response in % of the step.
    pub zero_ff_overshoot_pct: f64,
    /// The paper's robust choice (`None`: U_k has no local minimum).
    pub paper_robust: Option<PaperRobust>,
    /// Our robust choice for ±Δb.
    pub robust: Option<RobustChoice>,
    /// Worst case of robust choice and zero feedforward over ±Δb.
    pub worst_case: WorstCase,
    /// The bounds curves (Fig. 15).
    #[serde(skip)]
    pub bounds: Bounds,
    /// The responses of each choice (Fig. 16).
    #[serde(skip)]
    pub responses: Vec<Response>,
}

/// Why a settle analysis failed after validation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum AnalyseError {
    /// The controller could not be designed (for example an unstabilisable plant).
    #[error(transparent)]
    Servo(#[from] ServoError),
    /// The settle computation rejected a setting.
    #[error(transparent)]
    Settle(#[from] SettleError),
}

/// Designs the controller and runs the full settle analysis of `cfg`'s scenario.
pub fn analyse(cfg: &SettleConfig) -> Result<SettleReport, AnalyseError> {
    let ctl = Controller::design(&cfg.plant, &cfg.weights)?;
    Ok(analyse_with(&ctl, &cfg.scenario)?)
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

/// `12.34 ms`, or `not settled` for `None`.
fn settle_ms_text(v: Option<f64>) -> String {
    v.map_or("not settled".to_string(), |m| format!("{m:.2} ms"))
}

/// Appends one formatted line to a `String`.
macro_rules! push_line {
    ($out:expr, $($t:tt)*) => {{
        $out.push_str(&format!($($t)*));
        $out.push('\n');
    }};
}
use push_line;

#[cfg(test)]
mod tests {
    //! The handoff fast paths ([`HandoffTable::solve`], [`HandoffTable::bounds_into`]) against
    //! the slow obvious implementation of the same definitions, over many random handoffs.
    use super::*;
    use crate::numeric::rng::SimRng;

    /// The reference: every sample's bounds U_k, L_k (eq. 14) into vectors, a zero-gain sample
    /// with |c_k| > δ ruling every k ≤ it out (U = −∞, L = +∞), the running bounds U*, L*
    /// (eq. 15) sample by sample from the end with `f64::min`/`max`, and each answer as the
    /// first k ≤ N − M where its condition holds. No floor, no blocks, no early exit.
    fn reference(
        t: &HandoffTable,
        h: &Handoff,
        window: &Window,
        delta_b: f64,
    ) -> ([Vec<f64>; 4], HandoffSolution) {
        let n = t.horizon();
        let p = Point {
            e0: h.e0_um,
            v0: h.v0_um_s,
            du: h.u_prev_counts - h.bias_counts,
            delta: window.half_width_um(),
        };
        let (mut upper, mut lower) = (vec![0.0; n], vec![0.0; n]);
        for k in 0..n {
            (upper[k], lower[k]) = p.bounds(t.pe[k], t.pv[k], t.pu[k], t.w[k]);
        }
        for z in &t.zero {
            let c = z.ce * p.e0 + z.cv * p.v0 + z.cu * p.du;
            if c.is_nan() || c.abs() > p.delta {
                upper[z.k] = f64::NEG_INFINITY;
                lower[z.k] = f64::INFINITY;
            }
        }
        let (mut upper_min, mut lower_max) = (vec![0.0; n], vec![0.0; n]);
        let (mut umin, mut lmax) = (f64::INFINITY, f64::NEG_INFINITY);
        for k in (0..n).rev() {
            umin = umin.min(upper[k]);
            lmax = lmax.max(lower[k]);
            upper_min[k] = umin;
            lower_max[k] = lmax;
        }
        let shift = (t.dz_dbias * delta_b).abs();
        let finite = p.e0.is_finite() && p.v0.is_finite() && p.du.is_finite();
        let first = |cond: &dyn Fn(f64, f64) -> bool| {
            if !finite || window.hold() > n {
                return None;
            }
            (0..=n - window.hold())
                .find(|&k| cond(upper_min[k], lower_max[k]))
                .map(|k| Interval {
                    k,
                    lo: lower_max[k],
                    hi: upper_min[k],
                })
        };
        let sol = HandoffSolution {
            optimal: first(&|u, l| u - l >= 0.0),
            robust: first(&|u, l| u - l >= 2.0 * shift),
            zero_ff_worst: first(&|u, l| l <= -shift && u >= shift).map(|i| i.k),
            shift,
        };
        ([upper, lower, upper_min, lower_max], sol)
    }

    /// Equal within 1e-12 relative; infinities and NaN must match exactly.
    fn same(a: f64, b: f64) -> bool {
        if a.is_finite() && b.is_finite() {
            (a - b).abs() <= 1e-12 * a.abs().max(b.abs())
        } else {
            a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
        }
    }

    fn same_interval(a: Option<Interval>, b: Option<Interval>) -> bool {
        match (a, b) {
            (None, None) => true,
            (Some(a), Some(b)) => a.k == b.k && same(a.lo, b.lo) && same(a.hi, b.hi),
            _ => false,
        }
    }

    /// A table with random coefficients and random zero-gain samples (a_k = 0), which a
    /// designed controller has only at k = 0, so the floor logic is exercised anywhere.
    fn synthetic(rng: &mut SimRng, n: usize) -> HandoffTable {
        let mut t = HandoffTable {
            pe: vec![0.0; n].into(),
            pv: vec![0.0; n].into(),
            pu: vec![0.0; n].into(),
            w: vec![f64::INFINITY; n].into(),
            zero: Vec::new(),
            ts_s: 1e-4,
            dz_dbias: rng.range(-2.0, 2.0),
            coef_max: 0.0,
            w_max: 0.0,
            avx2: has_avx2(),
        };
        for k in 0..n {
            if rng.uniform() < 0.05 {
                t.zero.push(ZeroGain {
                    k,
                    ce: rng.range(-1.0, 1.0),
                    cv: rng.range(-1e-3, 1e-3),
                    cu: rng.range(-1.0, 1.0),
                });
            } else {
                // Bounds that tighten with k, as a settling loop's do, plus noise.
                let a = rng.range(0.2, 2.0) * (1.0 + k as f64 / 8.0);
                t.pe[k] = rng.range(-3.0, 3.0) + 50.0 / (1.0 + k as f64);
                t.pv[k] = rng.range(-1e-3, 1e-3);
                t.pu[k] = rng.range(-2.0, 2.0);
                t.w[k] = 1.0 / a;
            }
        }
        t.zero.reverse();
        t.coef_max = [&t.pe, &t.pv, &t.pu]
            .iter()
            .flat_map(|v| v.iter())
            .fold(0.0f64, |m, x| m.max(x.abs()));
        t.w_max =
            t.w.iter()
                .filter(|x| x.is_finite())
                .fold(0.0f64, |m, &x| m.max(x));
        t
    }

    fn random_handoff(rng: &mut SimRng, scale: f64) -> Handoff {
        let mut h = Handoff {
            e0_um: scale * rng.range(-2.0, 2.0),
            v0_um_s: scale * rng.range(-2000.0, 2000.0),
            u_prev_counts: rng.range(-20.0, 20.0),
            bias_counts: rng.range(-20.0, 20.0),
        };
        match rng.below(10) {
            0 => h.u_prev_counts = h.bias_counts, // a step from rest
            1 => h.e0_um = 0.0,
            // Bounds that overflow (±∞, NaN): the exact per-sample path.
            2 if rng.uniform() < 0.2 => h.e0_um = 1e306 * h.e0_um.signum(),
            _ => {}
        }
        h
    }

    /// Checks one handoff: every curve of `bounds_into` and every answer of `solve` equal the
    /// reference's; returns the reference solution.
    fn check(
        t: &HandoffTable,
        h: &Handoff,
        window: &Window,
        db: f64,
        what: &str,
    ) -> HandoffSolution {
        let ([u, l, um, lm], want) = reference(t, h, window, db);
        let mut buf = Bounds::new(t.horizon());
        t.bounds_into(h, window, &mut buf).unwrap();
        for (name, got, want) in [
            ("upper", buf.upper(), &u),
            ("lower", buf.lower(), &l),
            ("upper_min", buf.upper_min(), &um),
            ("lower_max", buf.lower_max(), &lm),
        ] {
            for k in 0..want.len() {
                assert!(
                    same(got[k], want[k]),
                    "{what}: {name}[{k}] {} vs {}",
                    got[k],
                    want[k]
                );
            }
        }
        // Both compiled copies (AVX2 where the CPU has it, and the portable one) agree.
        let portable = HandoffTable {
            avx2: false,
            ..t.clone()
        };
        let mut buf2 = Bounds::new(t.horizon());
        portable.bounds_into(h, window, &mut buf2).unwrap();
        assert_eq!(
            format!("{buf:?}"),
            format!("{buf2:?}"),
            "{what}: portable bounds"
        );
        let got = t.solve(h, window, db);
        assert_eq!(
            format!("{got:?}"),
            format!("{:?}", portable.solve(h, window, db)),
            "{what}: portable solve"
        );
        assert!(
            same_interval(got.optimal, want.optimal),
            "{what}: optimal {got:?} vs {want:?}"
        );
        assert!(
            same_interval(got.robust, want.robust),
            "{what}: robust {got:?} vs {want:?}"
        );
        assert_eq!(got.zero_ff_worst, want.zero_ff_worst, "{what}: zero ff");
        assert!(same(got.shift, want.shift));
        let finite = h.e0_um.is_finite() && h.v0_um_s.is_finite() && h.u_prev_counts.is_finite();
        if finite && window.hold() <= t.horizon() {
            assert_eq!(
                buf.optimal().map(|i| i.k),
                want.optimal.map(|i| i.k),
                "{what}"
            );
        }
        want
    }

    /// Reference: [`reference`] (the definitions written out naively). 1500 random handoffs on
    /// the two presets' controllers at random horizons 1–300 (multiples of the block and not),
    /// random windows, holds and Δb; identical results within 1e-12 relative, the same k.
    #[test]
    fn fast_handoff_equals_reference_on_designed_controllers() {
        let mut rng = SimRng::new(16);
        for preset in PRESETS {
            let cfg = SettleSpec::preset(preset).unwrap().check().unwrap();
            let ctl = Controller::design(&cfg.plant, &cfg.weights).unwrap();
            let scale = cfg.scenario.step_um;
            let (mut settled, mut unsettled) = (0, 0);
            for case in 0..750 {
                let n = match case % 3 {
                    0 => 8 * (1 + rng.below(32) as usize),
                    _ => 1 + rng.below(300) as usize,
                };
                let t = HandoffTable::new(&ctl, n).unwrap();
                let hold = 1 + rng.below(4.min(n as u64) + 1) as usize;
                let window = Window::new(scale * rng.range(0.005, 0.3), hold).unwrap();
                let h = random_handoff(&mut rng, scale);
                let db = if case % 5 == 0 {
                    0.0
                } else {
                    rng.range(0.0, 30.0)
                };
                let sol = check(&t, &h, &window, db, &format!("{preset} case {case}"));
                if sol.optimal.is_some() {
                    settled += 1;
                } else {
                    unsettled += 1;
                }
            }
            assert!(
                settled > 100 && unsettled > 10,
                "{preset}: {settled} / {unsettled}"
            );
        }
    }

    /// Reference: [`reference`]. 1500 random handoffs on random tables with zero-gain samples
    /// anywhere (the floor), plus non-finite handoff states; identical results.
    #[test]
    fn fast_handoff_equals_reference_on_random_tables() {
        let mut rng = SimRng::new(61);
        let (mut floored, mut found) = (0, 0);
        for case in 0..1500 {
            let n = 1 + rng.below(200) as usize;
            let t = synthetic(&mut rng, n);
            let hold = 1 + rng.below(3) as usize;
            let window = Window::new(rng.range(0.05, 3.0), hold).unwrap();
            let mut h = random_handoff(&mut rng, 1.0);
            if case % 100 == 0 {
                h.v0_um_s = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][case / 100 % 3];
            }
            let db = rng.range(0.0, 5.0);
            let sol = check(&t, &h, &window, db, &format!("random case {case}"));
            let p = Point {
                e0: h.e0_um,
                v0: h.v0_um_s,
                du: h.u_prev_counts - h.bias_counts,
                delta: window.half_width_um(),
            };
            if let Some(o) = sol.optimal {
                found += 1;
                floored += usize::from(o.k > 0 && o.k == t.floor(p));
            }
        }
        assert!(
            found > 300 && floored > 10,
            "{found} settled, {floored} at the floor"
        );
    }
}
