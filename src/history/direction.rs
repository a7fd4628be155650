//! The direction of motion: the deadband tracker, how a log's direction is read
//! (`DirectionSource`) and how the user asks for it (`DirectionSetting`).

use super::{History, Sampling, log_sampling};

/// The direction of motion with a deadband, a hysteretic detector: the direction reverses only
/// once the position has come back more than `deadband` (position unit) from the furthest point
/// reached in the current direction, so sensor noise on a densely sampled log does not fake
/// reversals. With deadband 0 (the default, for seek logs) every move against the direction is a
/// reversal. The *turning point* is that furthest point; `since_reversal` is the distance from it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct DirectionTracker {
    deadband: f64,
    direction: i8,
    anchor: Option<f64>,
    extreme: f64,
    turn: f64,
}

/// What [`DirectionTracker::peek`] says about one move.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct DirectionStep {
    /// Direction after the move: +1 inbound, −1 outbound, 0 before the first move out of the band.
    pub direction: i8,
    /// Whether the move reversed the direction.
    pub reversal: bool,
    /// Distance from the last turning point (or the first position) to the target.
    pub since_reversal: f64,
    pub(super) extreme: f64,
    pub(super) turn: f64,
}

impl DirectionTracker {
    /// A tracker with `deadband` ≥ 0 in the log's position unit (negative or non-finite counts as 0).
    pub(crate) fn new(deadband: f64) -> Self {
        Self {
            deadband: if deadband.is_finite() {
                deadband.max(0.0)
            } else {
                0.0
            },
            ..Self::default()
        }
    }

    /// The direction so far.
    pub(crate) fn direction(&self) -> i8 {
        self.direction
    }

    /// The outcome of a move to `target` without changing the tracker; `moved` is the signed
    /// direction the move's own sign suggests when the caller has a better source of it (a
    /// velocity column), `None` to use positions.
    pub(crate) fn peek(&self, target: f64, moved: Option<i8>) -> DirectionStep {
        let d = self.deadband;
        let Some(anchor) = self.anchor else {
            return DirectionStep {
                direction: 0,
                reversal: false,
                since_reversal: 0.0,
                extreme: target,
                turn: target,
            };
        };
        let dir = self.direction;
        let step = |direction: i8, reversal: bool, extreme: f64, turn: f64| DirectionStep {
            direction,
            reversal,
            since_reversal: (target - turn).abs(),
            extreme,
            turn,
        };
        if let Some(m) = moved {
            // Direction from a velocity sign: a reversal wherever the sign flips.
            let extreme = if dir == 0 || (target - self.extreme) * f64::from(dir) > 0.0 {
                target
            } else {
                self.extreme
            };
            return if m == 0 || m == dir {
                step(
                    dir,
                    false,
                    extreme,
                    if dir == 0 { anchor } else { self.turn },
                )
            } else if dir == 0 {
                step(m, false, target, anchor)
            } else {
                step(m, true, target, self.extreme)
            };
        }
        if dir == 0 {
            return if (target - anchor).abs() > d {
                step(sign(target - anchor), false, target, anchor)
            } else {
                step(0, false, anchor, anchor)
            };
        }
        let ahead = (target - self.extreme) * f64::from(dir);
        if ahead > 0.0 {
            step(dir, false, target, self.turn)
        } else if -ahead > d {
            step(-dir, true, target, self.extreme)
        } else {
            step(dir, false, self.extreme, self.turn)
        }
    }

    /// Records the move `s` returned by [`DirectionTracker::peek`] for `target`.
    pub(crate) fn commit(&mut self, target: f64, s: &DirectionStep) {
        if self.anchor.is_none() {
            self.anchor = Some(target);
        }
        self.direction = s.direction;
        self.extreme = s.extreme;
        self.turn = s.turn;
    }
}

/// How the direction of motion is read from a log , as a model file records it so
/// that `predict` replays direction the way `fit` did.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(tag = "mode", rename_all = "snake_case")]
#[non_exhaustive]
pub enum DirectionSource {
    /// From the raw sign of each position step (deadband 0): a log of seeks.
    #[default]
    Steps,
    /// From position steps with a deadband (`DirectionTracker`), position unit, > 0.
    Deadband {
        /// The deadband, position unit.
        deadband: f64,
    },
    /// From the sign of a velocity column (a reversal wherever its sign flips; 0 keeps the
    /// direction).
    Velocity {
        /// The column's name.
        column: String,
    },
}

/// How the user asked the direction to be read (`--deadband X`, `--velocity-col NAME`, or
/// neither); resolved against a training log into a [`DirectionSource`] by
/// [`DirectionSetting::resolve`].
#[derive(Debug, Clone, PartialEq, Default)]
#[non_exhaustive]
pub enum DirectionSetting {
    /// The deadband [`sampling`](super::sampling()) estimates: 2·√(2 ln n) × the position noise on a dense time
    /// series, 0 (raw steps) on a log of seeks.
    #[default]
    Auto,
    /// A deadband in the log's position unit (0: raw steps).
    Deadband(f64),
    /// The sign of the named velocity column.
    Velocity(String),
}

/// A direction setting that cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DirectionError {
    /// A deadband that is negative or not finite.
    #[error("--deadband {0}: the deadband must be a finite number ≥ 0 in the log's position unit")]
    BadDeadband(f64),
    /// The velocity column is not in the log.
    #[error("{file}: --velocity-col {column}: no such column (covariate columns: {available})")]
    NoVelocityColumn {
        /// The log.
        file: String,
        /// The column asked for.
        column: String,
        /// The log's covariate columns.
        available: String,
    },
}

impl DirectionSetting {
    /// Checks the setting alone (the deadband's range).
    pub fn validate(&self) -> Result<(), DirectionError> {
        match self {
            DirectionSetting::Deadband(d) if !(d.is_finite() && *d >= 0.0) => {
                Err(DirectionError::BadDeadband(*d))
            }
            _ => Ok(()),
        }
    }

    /// The source an explicit setting names without looking at a log (`None` for `Auto`);
    /// a velocity column is checked when a log is replayed.
    pub fn explicit(&self) -> Result<Option<DirectionSource>, DirectionError> {
        self.validate()?;
        Ok(match self {
            DirectionSetting::Auto => None,
            DirectionSetting::Deadband(d) if *d > 0.0 => {
                Some(DirectionSource::Deadband { deadband: *d })
            }
            DirectionSetting::Deadband(_) => Some(DirectionSource::Steps),
            DirectionSetting::Velocity(c) => Some(DirectionSource::Velocity { column: c.clone() }),
        })
    }

    /// The direction source for the training `log`: `Auto` estimates the deadband from its
    /// positions ([`sampling`](super::sampling())); a velocity column must be one of its covariates.
    pub fn resolve(&self, log: &crate::log::Log) -> Result<DirectionSource, DirectionError> {
        self.resolve_with(log, &log_sampling(log))
    }

    /// [`DirectionSetting::resolve`] with the log's [`Sampling`] already computed.
    pub fn resolve_with(
        &self,
        log: &crate::log::Log,
        sampling: &Sampling,
    ) -> Result<DirectionSource, DirectionError> {
        let source = match self.explicit()? {
            Some(s) => s,
            None => DirectionSetting::Deadband(sampling.deadband)
                .explicit()?
                .unwrap_or_default(),
        };
        source.column_index(&log.schema.file, &log.schema.covariates)?;
        Ok(source)
    }
}

impl DirectionSource {
    /// The explicit setting that resolves to this source on any log (re-fits of a model, as
    /// `diagnose` makes them, read direction the way the model was fitted).
    pub fn setting(&self) -> DirectionSetting {
        match self {
            DirectionSource::Steps => DirectionSetting::Deadband(0.0),
            DirectionSource::Deadband { deadband } => DirectionSetting::Deadband(*deadband),
            DirectionSource::Velocity { column } => DirectionSetting::Velocity(column.clone()),
        }
    }

    /// A fresh history reading direction this way (its deadband; a velocity source starts with
    /// deadband 0 and is fed signs by [`History::step_moved`]).
    pub fn history(&self) -> History {
        match self {
            DirectionSource::Deadband { deadband } => History::with_deadband(*deadband),
            _ => History::new(),
        }
    }

    /// The index of the velocity column among `covariates` (`None` for a position source);
    /// an error naming `file` when the column is missing.
    pub fn column_index(
        &self,
        file: &str,
        covariates: &[String],
    ) -> Result<Option<usize>, DirectionError> {
        match self {
            DirectionSource::Velocity { column } => covariates
                .iter()
                .position(|c| c == column)
                .map(Some)
                .ok_or_else(|| DirectionError::NoVelocityColumn {
                    file: file.to_string(),
                    column: column.clone(),
                    available: if covariates.is_empty() {
                        "none".into()
                    } else {
                        covariates.join(", ")
                    },
                }),
            _ => Ok(None),
        }
    }

    /// The direction a velocity value gives: its sign, 0 for 0 or a missing (non-finite) value.
    pub fn moved(velocity: Option<f64>) -> i8 {
        velocity.filter(|v| v.is_finite()).map_or(0, sign)
    }

    /// A warning when the number of direction `reversals` in `rows` rows is implausible for the
    /// motion ([`Sampling`]): more than the raw position steps show, or (on a dense time series)
    /// more than one reversal per 20 rows, which sensor noise makes and real motion rarely does.
    pub fn reversal_warning(&self, reversals: usize, rows: usize, s: &Sampling) -> Option<String> {
        let how = match self {
            DirectionSource::Steps => "the raw sign of each position step".to_string(),
            DirectionSource::Deadband { deadband } => format!("a deadband of {deadband:.4e}"),
            DirectionSource::Velocity { column } => format!("the sign of column `{column}`"),
        };
        let too_many = s.dense && reversals * 20 > rows;
        too_many.then(|| {
            format!(
                "direction read from {how} reverses {reversals} times in {rows} rows of a densely \
                 sampled log (one reversal per {:.1} rows; the deadband-filtered count is {}): \
                 noise is likely faking reversals; set --deadband X (position unit) or \
                 --velocity-col NAME",
                rows as f64 / reversals.max(1) as f64,
                s.reversals
            )
        })
    }
}

/// Sign of a seek length as a direction: +1 inbound, −1 outbound, 0 for no move.
pub(crate) fn sign(x: f64) -> i8 {
    if x > 0.0 {
        1
    } else if x < 0.0 {
        -1
    } else {
        0
    }
}
