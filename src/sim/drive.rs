//! The drive description (TOML, validated on load) and the physics of every effect P1–P8.
//!
//! Each effect is one small struct with its own parameters and a pure "contribution" function;
//! [`Drive`] groups them with the servo parameters ([`ServoParams`]). Signs: tracks grow from the
//! OD (0) inwards; a positive seek is inbound; bias in counts (positive = current the driver must
//! supply to hold the head); times in seconds.
//!
//! ## The pivot (P2, P4, P5)
//! The pivot bearing is a parallel set of rate-independent hysteresis elements. Element `i` has a
//! normalised state `w_i ∈ [−1, 1]` and contributes `fc_i · w_i` counts (`fc_i` may be negative:
//! an element that pulls the other way, e.g. the cage lagging the balls). A move of `Δx` tracks in
//! direction `s = sgn Δx` updates it as
//! - **Dahl** element (paper eq. 8): `w ← s + (w − s)·exp(−|Δx| / length)`, i.e. `r = exp(−1/length)`;
//! - **slip** (Maxwell-slip, elasto-plastic) element: `w ← clamp(w + 2·Δx / length, −1, 1)`: it
//!   sticks and deflects linearly until it slips, reaching saturation after `length` tracks of
//!   reversal.
//!
//! The *main* element (effect `direction`, P2) is a Dahl element: its saturated values ±fc give the
//! two curves of Fig. 3 and, after a reversal, the loop of Fig. 5. The *overshoot* elements
//! (effect `overshoot`) are one opposite-sign slip element that saturates after ~130 tracks and a
//! weaker same-sign one that saturates after ~240 tracks: after a reversal their linear ramps
//! first lift the sum above the far curve (50–100 tracks), then leave it below (100–200 tracks),
//! and after > 240 tracks every element is saturated, so the bias lands on the far curve (P4).
//!
//! **Deceleration back-drive (P5).** At the end of every seek the actuator is decelerated by a
//! torque opposite to the motion; it back-drives the bearing partially: every element moves a
//! fraction `β(d) = backdrive · (1 − exp(−d / backdrive_length))` of the way towards the opposite
//! saturation, `w ← w − β(d)·(w + s)`, where `d` is the seek length (faster seeks decelerate
//! harder). Without a direction change at the source, this is the only thing that makes the bias
//! depend on the seek length: the short seek's smaller back-drive and the recovery of the source's
//! back-drive give a weaker overshoot than after a reversal, but not none.
//!
//! ## Why a position+direction model is bimodal on this drive (the paper's Fig. 10)
//! The built-in `paper1997` drive's ridge memory (P6) reaches far (`length` 87 tracks): random
//! seeks in a 250-track range nearly always stop short of some uncrossed earlier rest within
//! ~100 tracks, which pulls their bias ~12 counts inside the far curves, towards the other
//! direction's curve. Table I's far approaches (400 tracks, across every earlier rest) land on the
//! far curves. A position+direction model calibrated the 1997 way, from the two Table I curves,
//! therefore misses random seeks by about ±12–15 counts with the sign of the seek direction: two
//! humps, error std ≈ 19 (the paper's Fig. 10). The calibration model's `b_m` term (and the
//! preset's `memory` term) carries exactly this effect.
//!
//! ## The other effects
//! - P1 `position`: `c0 + c1·x + c2·x²` (flex cable, windage, gravity).
//! - P3 `time`: the lubricant flows back while the head sits at a track and relaxes the pivot's
//!   hysteresis: `−s · amplitude · (1 − exp(−t / tau_s))`, `s` the direction of the last move, `t` the
//!   time since the head arrived at the track (zero-length seeks do not move it).
//! - P6 `memory`: a lubricant ridge builds where the head rested; while it is not crossed it
//!   cushions an approach towards it: `−s · amplitude · exp(−d / length)`, `d` the distance from
//!   the target to the nearest uncrossed earlier rest position *ahead* of the approach
//!   ([`crate::history::SeekFeatures::rest_distance_ahead`]). Only that side counts (Fig. 9).
//! - P7 `drift`: an Ornstein–Uhlenbeck offset with stationary std `sigma` and correlation time
//!   `tau_s` (driver electronics), exact discretisation over each row's time step.
//! - P8 `scatter`: a force disturbance drawn per measurement (std `sigma` counts, constant over
//!   the measurement: turbulence, head/disk contact) plus position-sensor noise in the servo.
//! - `runout`: repeatable runout at spindle harmonics (a position disturbance the servo sees).
//! - `temperature` (covariate, off in `paper1997`): `coefficient · (T − t0_c)` with the ambient
//!   temperature `T(t) = t0_c + amplitude_c·sin(2πt/period_s) + OU wander`, logged as `temp_c`.

use serde::Deserialize;
use std::path::Path;

/// An error loading or validating a drive description.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DriveError {
    /// The file could not be read.
    #[error("{file}: cannot read drive file: {source}")]
    Io {
        /// The drive file.
        file: String,
        /// The operating-system error.
        #[source]
        source: std::io::Error,
    },
    /// The TOML is malformed, a field is missing or unknown, or a value has the wrong type.
    #[error("{file}: bad drive description: {message}")]
    Parse {
        /// The drive file.
        file: String,
        /// The TOML parser's message (names the field and line).
        message: String,
    },
    /// A value is out of its allowed range.
    #[error("{file}: field `{field}` = {value}: {reason}")]
    Invalid {
        /// The drive file.
        file: String,
        /// Dotted path of the field, e.g. `servo.bandwidth_hz`.
        field: String,
        /// The offending value.
        value: String,
        /// What the value must be.
        reason: String,
    },
}

/// P1: the smooth position trend `c0 + c1·x + c2·x²` (counts, x in tracks).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PositionParams {
    /// Constant, counts.
    pub c0: f64,
    /// Linear coefficient, counts per track.
    pub c1: f64,
    /// Quadratic coefficient, counts per track².
    pub c2: f64,
}

impl PositionParams {
    /// The position contribution at track `x`, counts.
    pub fn at(&self, x: f64) -> f64 {
        self.c0 + x * (self.c1 + x * self.c2)
    }
}

/// The law of one pivot hysteresis element.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ElementKind {
    /// Dahl element, eq. 8: exponential approach, `r = exp(−1/length)` per track.
    Dahl,
    /// Maxwell-slip (elasto-plastic) element: linear until saturation after `length` tracks.
    Slip,
}

/// One pivot hysteresis element: contributes `fc · w`, `w ∈ [−1, 1]`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Element {
    /// The element's law.
    pub kind: ElementKind,
    /// Saturated force, counts (signed: negative pulls against the main element).
    pub fc: f64,
    /// Characteristic length, tracks (Dahl: 1/e length; slip: full-reversal length).
    pub length: f64,
}

impl Element {
    /// The new state after a move of `dx` tracks from state `w`.
    pub fn step(&self, w: f64, dx: f64) -> f64 {
        if dx == 0.0 {
            return w;
        }
        let s = dx.signum();
        match self.kind {
            ElementKind::Dahl => s + (w - s) * (-dx.abs() / self.length).exp(),
            ElementKind::Slip => (w + 2.0 * dx / self.length).clamp(-1.0, 1.0),
        }
    }
}

/// P2: the pivot's main hysteresis element (Dahl). Its saturated values give the two curves of
/// Fig. 3, `2·fc` apart.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DirectionParams {
    /// Half the gap between the inbound and outbound curves, counts (> 0).
    pub fc: f64,
    /// Dahl length, tracks: `r = exp(−1/length)`, initial loop slope `σ = fc·(1 − r)` counts/track.
    pub length: f64,
}

/// P4/P5: the extra pivot elements and the deceleration back-drive.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OvershootParams {
    /// The extra elements.
    pub elements: Vec<Element>,
    /// Largest back-drive fraction at the end of a seek, in [0, 0.5).
    pub backdrive: f64,
    /// Seek length over which the back-drive builds up, tracks.
    pub backdrive_length: f64,
}

impl OvershootParams {
    /// Back-drive fraction `β(d)` after a seek of `d` tracks.
    pub fn backdrive_fraction(&self, d: f64) -> f64 {
        self.backdrive * (1.0 - (-d.abs() / self.backdrive_length).exp())
    }
}

/// P3: approach to a constant with time at track.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeParams {
    /// Size of the relaxation, counts (≥ 0).
    pub amplitude: f64,
    /// Time constant, s (> 0).
    pub tau_s: f64,
}

impl TimeParams {
    /// Contribution after `t` s at the track, last move direction `dir` (+1 inbound).
    pub fn at(&self, dir: i8, t: f64) -> f64 {
        -f64::from(dir) * self.amplitude * (1.0 - (-t.max(0.0) / self.tau_s).exp())
    }
}

/// P6: the lubricant ridge at uncrossed rest positions ahead of the approach.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MemoryParams {
    /// Reduction of the bias magnitude at zero distance, counts (≥ 0).
    pub amplitude: f64,
    /// Decay length, tracks (> 0).
    pub length: f64,
}

impl MemoryParams {
    /// Contribution for approach direction `dir` and distance `ahead` (tracks) to the nearest
    /// uncrossed rest position ahead of the approach, if any.
    pub fn at(&self, dir: i8, ahead: Option<f64>) -> f64 {
        match ahead {
            Some(d) => -f64::from(dir) * self.amplitude * (-d / self.length).exp(),
            None => 0.0,
        }
    }
}

/// P7: slow Ornstein–Uhlenbeck drift of the offset.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriftParams {
    /// Stationary standard deviation, counts (≥ 0).
    pub sigma: f64,
    /// Correlation time, s (> 0).
    pub tau_s: f64,
}

/// P8: scatter.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScatterParams {
    /// Force disturbance per measurement, std in counts (≥ 0).
    pub sigma: f64,
    /// Position-sensor noise per servo sample, std in tracks (≥ 0).
    pub pes_noise: f64,
}

/// One repeatable-runout harmonic of the spindle frequency.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Harmonic {
    /// Harmonic number (1 = once per revolution), ≥ 1.
    pub order: u32,
    /// Amplitude, tracks (≥ 0).
    pub amplitude: f64,
    /// Phase at spindle angle 0, degrees.
    pub phase_deg: f64,
}

/// Repeatable runout: a position disturbance at spindle harmonics.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunoutParams {
    /// The harmonics.
    pub harmonics: Vec<Harmonic>,
}

/// The ambient-temperature covariate (logged as `temp_c`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TemperatureParams {
    /// Whether the drive has this effect at all (off in `paper1997`).
    pub enabled: bool,
    /// Reference temperature, °C.
    pub t0_c: f64,
    /// Amplitude of the slow daily-like cycle, °C (≥ 0).
    pub amplitude_c: f64,
    /// Period of the cycle, s (> 0).
    pub period_s: f64,
    /// Stationary std of the random wander, °C (≥ 0).
    pub wander_c: f64,
    /// Correlation time of the wander, s (> 0).
    pub wander_tau_s: f64,
    /// Bias per degree, counts/°C.
    pub coefficient: f64,
}

impl TemperatureParams {
    /// The deterministic part of the temperature at time `t` s, °C.
    pub fn cycle(&self, t: f64) -> f64 {
        self.t0_c + self.amplitude_c * (std::f64::consts::TAU * t / self.period_s).sin()
    }
}

/// The closed-loop track-following servo that measures the bias.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServoParams {
    /// Servo sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Spindle speed, rpm; one revolution is the averaging window.
    pub spindle_rpm: f64,
    /// Closed-loop bandwidth, Hz: the PID places a triple pole at `−2π·bandwidth`.
    pub bandwidth_hz: f64,
    /// Samples between handoff and the start of the one-revolution average.
    pub settle_samples: u32,
    /// Std of the position error at handoff, tracks (≥ 0).
    pub handoff_std: f64,
}

impl ServoParams {
    /// Samples in one revolution, rounded down (5400 rpm at 10 kHz: 111).
    pub fn window_samples(&self) -> usize {
        (self.sample_rate_hz * 60.0 / self.spindle_rpm).floor() as usize
    }
}

/// A complete, validated drive description. Build it with [`Drive::paper1997`],
/// [`Drive::from_toml_str`] or [`Drive::from_toml_file`]; all of them validate.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Drive {
    /// Name written to the log metadata.
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Number of tracks; positions run 0 (OD) ..= tracks − 1 (ID).
    pub tracks: u32,
    /// A seek this long (tracks) puts the pivot on its far curve; the tables use it.
    pub far_tracks: u32,
    /// P1.
    pub position: PositionParams,
    /// P2.
    pub direction: DirectionParams,
    /// P4/P5.
    pub overshoot: OvershootParams,
    /// P3.
    pub time: TimeParams,
    /// P6.
    pub memory: MemoryParams,
    /// P7.
    pub drift: DriftParams,
    /// P8.
    pub scatter: ScatterParams,
    /// Repeatable runout.
    pub runout: RunoutParams,
    /// Temperature covariate.
    pub temperature: TemperatureParams,
    /// Measuring servo.
    pub servo: ServoParams,
}

/// The built-in drive's description (also in `data/paper1997.toml`).
pub(crate) const PAPER1997_TOML: &str = include_str!("../../data/paper1997.toml");

impl Drive {
    /// The built-in drive tuned to the paper's figures and headline numbers.
    pub fn paper1997() -> Drive {
        // The embedded file is validated by a unit test; failing here is a build defect.
        Drive::from_toml_str("paper1997 (built in)", PAPER1997_TOML)
            .expect("the embedded paper1997.toml is valid")
    }

    /// Reads and validates a drive file.
    pub fn from_toml_file(path: &Path) -> Result<Drive, DriveError> {
        let file = path.display().to_string();
        let text = crate::log::limits::read_text(path).map_err(|source| DriveError::Io {
            file: file.clone(),
            source,
        })?;
        Drive::from_toml_str(&file, &text)
    }

    /// Parses and validates a drive description; `file` names it in messages.
    pub fn from_toml_str(file: &str, text: &str) -> Result<Drive, DriveError> {
        crate::log::limits::check_toml_numbers(text).map_err(|message| DriveError::Parse {
            file: file.into(),
            message,
        })?;
        let drive: Drive = toml::from_str(text).map_err(|e| DriveError::Parse {
            file: file.into(),
            message: e.to_string().trim_end().to_string(),
        })?;
        drive.validate(file)?;
        Ok(drive)
    }

    /// Checks every value; the error names the field.
    pub fn validate(&self, file: &str) -> Result<(), DriveError> {
        let bad = |field: &str, value: String, reason: &str| DriveError::Invalid {
            file: file.into(),
            field: field.into(),
            value,
            reason: reason.into(),
        };
        let finite = |field: &str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(bad(field, v.to_string(), "must be a finite number"))
            }
        };
        let positive = |field: &str, v: f64| {
            finite(field, v)?;
            if v > 0.0 {
                Ok(())
            } else {
                Err(bad(field, v.to_string(), "must be > 0"))
            }
        };
        let nonneg = |field: &str, v: f64| {
            finite(field, v)?;
            if v >= 0.0 {
                Ok(())
            } else {
                Err(bad(field, v.to_string(), "must be ≥ 0"))
            }
        };
        if self.tracks < 2 {
            return Err(bad("tracks", self.tracks.to_string(), "must be ≥ 2"));
        }
        if self.far_tracks == 0 || 2 * u64::from(self.far_tracks) >= u64::from(self.tracks) {
            return Err(bad(
                "far_tracks",
                self.far_tracks.to_string(),
                "must be > 0 and less than half of `tracks`",
            ));
        }
        finite("position.c0", self.position.c0)?;
        finite("position.c1", self.position.c1)?;
        finite("position.c2", self.position.c2)?;
        positive("direction.fc", self.direction.fc)?;
        positive("direction.length", self.direction.length)?;
        for (i, e) in self.overshoot.elements.iter().enumerate() {
            finite(&format!("overshoot.elements[{i}].fc"), e.fc)?;
            positive(&format!("overshoot.elements[{i}].length"), e.length)?;
        }
        nonneg("overshoot.backdrive", self.overshoot.backdrive)?;
        if self.overshoot.backdrive >= 0.5 {
            return Err(bad(
                "overshoot.backdrive",
                self.overshoot.backdrive.to_string(),
                "must be < 0.5 (a fraction of the way to the opposite saturation)",
            ));
        }
        positive(
            "overshoot.backdrive_length",
            self.overshoot.backdrive_length,
        )?;
        nonneg("time.amplitude", self.time.amplitude)?;
        positive("time.tau_s", self.time.tau_s)?;
        nonneg("memory.amplitude", self.memory.amplitude)?;
        positive("memory.length", self.memory.length)?;
        nonneg("drift.sigma", self.drift.sigma)?;
        positive("drift.tau_s", self.drift.tau_s)?;
        nonneg("scatter.sigma", self.scatter.sigma)?;
        nonneg("scatter.pes_noise", self.scatter.pes_noise)?;
        for (i, h) in self.runout.harmonics.iter().enumerate() {
            if h.order == 0 {
                return Err(bad(
                    &format!("runout.harmonics[{i}].order"),
                    "0".into(),
                    "must be ≥ 1",
                ));
            }
            nonneg(&format!("runout.harmonics[{i}].amplitude"), h.amplitude)?;
            finite(&format!("runout.harmonics[{i}].phase_deg"), h.phase_deg)?;
        }
        let t = &self.temperature;
        finite("temperature.t0_c", t.t0_c)?;
        nonneg("temperature.amplitude_c", t.amplitude_c)?;
        positive("temperature.period_s", t.period_s)?;
        nonneg("temperature.wander_c", t.wander_c)?;
        positive("temperature.wander_tau_s", t.wander_tau_s)?;
        finite("temperature.coefficient", t.coefficient)?;
        let s = &self.servo;
        positive("servo.sample_rate_hz", s.sample_rate_hz)?;
        positive("servo.spindle_rpm", s.spindle_rpm)?;
        positive("servo.bandwidth_hz", s.bandwidth_hz)?;
        nonneg("servo.handoff_std", s.handoff_std)?;
        if s.window_samples() < 8 || s.window_samples() > 100_000 {
            return Err(bad(
                "servo.spindle_rpm",
                s.spindle_rpm.to_string(),
                "one revolution must last 8 to 100000 servo samples",
            ));
        }
        if s.settle_samples > 100_000 {
            return Err(bad(
                "servo.settle_samples",
                s.settle_samples.to_string(),
                "must be ≤ 100000",
            ));
        }
        // ωT ≤ 0.5 keeps the Euler-discretised PID with its backward-difference velocity stable
        // (checked against the closed-loop impulse response in measure.rs's tests).
        let wt = std::f64::consts::TAU * s.bandwidth_hz / s.sample_rate_hz;
        if wt > 0.5 {
            return Err(bad(
                "servo.bandwidth_hz",
                s.bandwidth_hz.to_string(),
                "must be ≤ 0.08 × servo.sample_rate_hz for a stable loop",
            ));
        }
        Ok(())
    }

    /// Highest track number (ID end of the stroke).
    pub fn max_track(&self) -> f64 {
        f64::from(self.tracks - 1)
    }

    /// Middle of the stroke, rounded down to a whole track.
    pub fn mid_track(&self) -> f64 {
        f64::from((self.tracks - 1) / 2)
    }
}
