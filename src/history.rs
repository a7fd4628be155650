//! The seek history: a state machine fed one seek at a time that yields, for every seek, the
//! features of its history that bias depends on (the paper's P1–P7).
//!
//! Conventions: positions in tracks (0 at the outer diameter, OD); a positive seek length moves
//! inbound, towards the inner diameter (ID); direction `+1` is inbound, `-1` outbound, `0` before
//! the first move. Times in seconds.
//!
//! The *uncrossed rest positions* (the paper's memory effect, P6) are kept in [`RestMemory`]: two
//! stacks, one on each side of the head, each sorted with the nearest position on top. A seek pops
//! the positions it crosses from the stack ahead of it and pushes its source onto the stack behind,
//! so an update costs amortised O(1) whatever the length of the history.
//!
//! ```
//! use biasctl::History;
//! let mut h = History::new();
//! h.step(0.0, 100.0);          // first row: the head starts at track 100
//! h.step(1.0, 150.0);          // rest at 100, move inbound to 150
//! let f = h.step(2.0, 120.0);  // reverse: outbound to 120
//! assert_eq!(f.seek_length, -30.0);
//! assert!(f.direction_change);
//! // 100 (OD side of 120) was never crossed since the head rested there:
//! assert_eq!(f.rest_distance_od, Some(20.0));
//! ```

/// Features of one seek's history, as seen when the head arrives at the target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeekFeatures {
    /// 0-based index of the seek in the log (`seek_index`).
    pub seek_index: u64,
    /// Time of the seek, s.
    pub time_s: f64,
    /// Time since the first row, s (`elapsed_s`).
    pub elapsed_s: f64,
    /// Time since the previous row, s (`dwell_s`); 0 for the first row.
    pub dwell_s: f64,
    /// Source of the seek (the previous row's target), tracks.
    pub source: f64,
    /// Target of the seek (`position`), tracks.
    pub target: f64,
    /// Signed seek length target − source (`seek_length`), tracks; positive is inbound.
    pub seek_length: f64,
    /// Direction of the last non-zero move including this one (`direction`): +1 inbound, −1
    /// outbound, 0 if the head has not moved yet.
    pub direction: i8,
    /// Whether this seek reverses the direction of the move into its source (`direction_change`).
    /// False for zero-length seeks and for the first move.
    pub direction_change: bool,
    /// Distance from the last turning point (where the last direction change began) to the
    /// target (`since_reversal`); with deadband 0, the tracks travelled since the last direction
    /// change, this seek included.
    pub since_reversal: f64,
    /// Distance from the target to the nearest uncrossed earlier rest position on the OD side
    /// (smaller track numbers), not counting the source (`rest_distance_od`); `None` if there is none.
    pub rest_distance_od: Option<f64>,
    /// Distance to the nearest uncrossed earlier rest position on the ID side (`rest_distance_id`);
    /// `None` if there is none.
    pub rest_distance_id: Option<f64>,
}

impl SeekFeatures {
    /// Absolute seek length in tracks (`seek_abs`).
    pub fn seek_abs(&self) -> f64 {
        self.seek_length.abs()
    }

    /// Distance to the nearest uncrossed rest position ahead of the approach, i.e. on the side
    /// the head was moving towards (ID side for an inbound seek), if any.
    pub fn rest_distance_ahead(&self) -> Option<f64> {
        if self.direction > 0 {
            self.rest_distance_id
        } else if self.direction < 0 {
            self.rest_distance_od
        } else {
            None
        }
    }
}

/// The built-in candidate features of a seek's history, by the names the CLI and JSON use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Feature {
    /// `position`: the target track.
    Position,
    /// `seek_length`: signed seek length (positive inbound), tracks.
    SeekLength,
    /// `seek_abs`: absolute seek length, tracks.
    SeekAbs,
    /// `direction`: +1 inbound, −1 outbound, 0 before any move.
    Direction,
    /// `direction_change`: 1 if the seek reverses the move into its source, else 0.
    DirectionChange,
    /// `since_reversal`: tracks travelled since the last direction change.
    SinceReversal,
    /// `rest_distance_od`: distance to the nearest uncrossed rest position on the OD side.
    RestDistanceOd,
    /// `rest_distance_id`: distance to the nearest uncrossed rest position on the ID side.
    RestDistanceId,
    /// `dwell_s`: time since the previous row, s.
    DwellS,
    /// `elapsed_s`: time since the first row, s.
    ElapsedS,
    /// `seek_index`: 0-based index of the seek.
    SeekIndex,
}

impl Feature {
    /// Every built-in feature, in a fixed order.
    pub const ALL: [Feature; 11] = [
        Feature::Position,
        Feature::SeekLength,
        Feature::SeekAbs,
        Feature::Direction,
        Feature::DirectionChange,
        Feature::SinceReversal,
        Feature::RestDistanceOd,
        Feature::RestDistanceId,
        Feature::DwellS,
        Feature::ElapsedS,
        Feature::SeekIndex,
    ];

    /// The feature's name (`seek_length`, …).
    pub fn name(self) -> &'static str {
        match self {
            Feature::Position => "position",
            Feature::SeekLength => "seek_length",
            Feature::SeekAbs => "seek_abs",
            Feature::Direction => "direction",
            Feature::DirectionChange => "direction_change",
            Feature::SinceReversal => "since_reversal",
            Feature::RestDistanceOd => "rest_distance_od",
            Feature::RestDistanceId => "rest_distance_id",
            Feature::DwellS => "dwell_s",
            Feature::ElapsedS => "elapsed_s",
            Feature::SeekIndex => "seek_index",
        }
    }

    /// The feature called `name`, if it is a built-in one.
    pub fn from_name(name: &str) -> Option<Feature> {
        Feature::ALL.into_iter().find(|f| f.name() == name)
    }
}

impl SeekFeatures {
    /// The value of feature `f` for this seek; `None` where it is undefined (a rest distance with
    /// no uncrossed rest position on that side).
    pub fn value(&self, f: Feature) -> Option<f64> {
        match f {
            Feature::Position => Some(self.target),
            Feature::SeekLength => Some(self.seek_length),
            Feature::SeekAbs => Some(self.seek_length.abs()),
            Feature::Direction => Some(f64::from(self.direction)),
            Feature::DirectionChange => Some(f64::from(u8::from(self.direction_change))),
            Feature::SinceReversal => Some(self.since_reversal),
            Feature::RestDistanceOd => self.rest_distance_od,
            Feature::RestDistanceId => self.rest_distance_id,
            Feature::DwellS => Some(self.dwell_s),
            Feature::ElapsedS => Some(self.elapsed_s),
            Feature::SeekIndex => Some(self.seek_index as f64),
        }
    }
}

/// The uncrossed rest positions, kept in two stacks around the head (amortised O(1) per seek).
#[derive(Debug, Clone, Default)]
pub struct RestMemory {
    /// Rest positions on the OD side of the head (smaller tracks), nearest last.
    below: Vec<f64>,
    /// Rest positions on the ID side of the head (larger tracks), nearest last.
    above: Vec<f64>,
}

impl RestMemory {
    /// An empty memory.
    pub fn new() -> Self {
        Self::default()
    }

    /// Nearest uncrossed rest positions on the OD and ID sides of `target`, as they would be
    /// after a move from `source` to `target` but before `source` itself is remembered. Does not
    /// change the memory. Costs O(number of positions the move crosses).
    pub fn nearest_after_move(&self, source: f64, target: f64) -> (Option<f64>, Option<f64>) {
        if target > source {
            let od = self.below.last().copied();
            let id = self.above.iter().rev().copied().find(|&p| p > target);
            (od, id)
        } else if target < source {
            let od = self.below.iter().rev().copied().find(|&p| p < target);
            let id = self.above.last().copied();
            (od, id)
        } else {
            (self.below.last().copied(), self.above.last().copied())
        }
    }

    /// Applies a move from `source` (where the head rested) to `target`: forgets every rest
    /// position the move crosses or lands on, and remembers `source` behind the head.
    pub fn apply_move(&mut self, source: f64, target: f64) {
        if target > source {
            while self.above.last().is_some_and(|&p| p <= target) {
                self.above.pop();
            }
            self.below.push(source);
        } else if target < source {
            while self.below.last().is_some_and(|&p| p >= target) {
                self.below.pop();
            }
            self.above.push(source);
        }
    }

    /// [`RestMemory::nearest_after_move`] and then [`RestMemory::apply_move`] in one: the
    /// nearest uncrossed rest positions on the OD and ID sides of `target` after a move from
    /// `source`, before `source` is remembered, and the memory updated. The same values as the
    /// two calls (tested): the positions the move crosses are popped off the stack ahead
    /// first, and the one left on top is the nearest beyond `target` (what the scan found);
    /// the crossed positions are visited once instead of twice.
    #[inline(always)]
    pub(crate) fn move_and_nearest(
        &mut self,
        source: f64,
        target: f64,
    ) -> (Option<f64>, Option<f64>) {
        if target > source {
            while self.above.last().is_some_and(|&p| p <= target) {
                self.above.pop();
            }
            let near = (self.below.last().copied(), self.above.last().copied());
            self.below.push(source);
            near
        } else if target < source {
            while self.below.last().is_some_and(|&p| p >= target) {
                self.below.pop();
            }
            let near = (self.below.last().copied(), self.above.last().copied());
            self.above.push(source);
            near
        } else {
            (self.below.last().copied(), self.above.last().copied())
        }
    }

    /// Reserves room for `per_side` positions on each side, so that remembering up to that many
    /// allocates nothing.
    pub fn reserve(&mut self, per_side: usize) {
        self.below.reserve(per_side);
        self.above.reserve(per_side);
    }

    /// Number of remembered positions (both sides).
    pub fn len(&self) -> usize {
        self.below.len() + self.above.len()
    }

    /// Whether no position is remembered.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// All remembered positions, OD side then ID side, in no particular order within a side.
    pub fn positions(&self) -> impl Iterator<Item = f64> + '_ {
        self.below.iter().chain(self.above.iter()).copied()
    }
}

/// The seek-history state machine. Feed it each row's `(time_s, track)` with [`History::step`];
/// ask about a candidate seek without changing it with [`History::peek`].
#[derive(Debug, Clone, Default)]
pub struct History {
    position: Option<f64>,
    start_time: f64,
    last_time: f64,
    seeks: u64,
    turns: DirectionTracker,
    memory: RestMemory,
}

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
    extreme: f64,
    turn: f64,
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

impl History {
    /// A history before the first row, direction from raw position steps (deadband 0).
    pub fn new() -> Self {
        Self::default()
    }

    /// A history whose direction has a deadband (position unit; see `DirectionTracker`).
    pub fn with_deadband(deadband: f64) -> Self {
        Self {
            turns: DirectionTracker::new(deadband),
            ..Self::default()
        }
    }

    /// Reserves room for `per_side` uncrossed rest positions on each side ([`RestMemory::reserve`]).
    pub fn reserve(&mut self, per_side: usize) {
        self.memory.reserve(per_side);
    }

    /// Current head position (the last target), if any row was seen.
    pub fn position(&self) -> Option<f64> {
        self.position
    }

    /// Direction of the last non-zero move (+1, −1, or 0 before any move).
    pub fn direction(&self) -> i8 {
        self.turns.direction()
    }

    /// Number of seeks seen so far.
    pub fn seeks(&self) -> u64 {
        self.seeks
    }

    /// The uncrossed rest positions.
    pub fn memory(&self) -> &RestMemory {
        &self.memory
    }

    /// The features a seek to `target` at `time_s` would have, without changing the history.
    pub fn peek(&self, time_s: f64, target: f64) -> SeekFeatures {
        self.peek_moved(time_s, target, None)
    }

    /// As [`History::peek`], with the direction of the move from `moved` (the sign of a velocity
    /// column: +1, −1, 0 for "no new information") instead of the position steps when `Some`.
    pub fn peek_moved(&self, time_s: f64, target: f64, moved: Option<i8>) -> SeekFeatures {
        let source = self.position.unwrap_or(target);
        let seek_length = target - source;
        let turn = self.turns.peek(target, moved);
        let (od, id) = self.memory.nearest_after_move(source, target);
        let first = self.position.is_none();
        SeekFeatures {
            seek_index: self.seeks,
            time_s,
            elapsed_s: if first { 0.0 } else { time_s - self.start_time },
            dwell_s: if first { 0.0 } else { time_s - self.last_time },
            source,
            target,
            seek_length,
            direction: turn.direction,
            direction_change: turn.reversal,
            since_reversal: turn.since_reversal,
            rest_distance_od: od.map(|p| target - p),
            rest_distance_id: id.map(|p| p - target),
        }
    }

    /// Records a seek to `target` at `time_s` and returns only the features its time and the
    /// positions give without the seek history: `seek_index`, `time_s`, `elapsed_s`,
    /// `dwell_s`, `source`, `target` and `seek_length`, each the same bits as
    /// [`History::step`]'s (tested); `direction` 0, no `direction_change`, `since_reversal` 0
    /// and no rest distances. The direction and rest memory are not advanced: a history is
    /// stepped one way or the other throughout.
    #[inline(always)]
    pub(crate) fn step_light(&mut self, time_s: f64, target: f64) -> SeekFeatures {
        let source = self.position.unwrap_or(target);
        let first = self.position.is_none();
        let f = SeekFeatures {
            seek_index: self.seeks,
            time_s,
            elapsed_s: if first { 0.0 } else { time_s - self.start_time },
            dwell_s: if first { 0.0 } else { time_s - self.last_time },
            source,
            target,
            seek_length: target - source,
            direction: 0,
            direction_change: false,
            since_reversal: 0.0,
            rest_distance_od: None,
            rest_distance_id: None,
        };
        if first {
            self.start_time = time_s;
        }
        self.position = Some(target);
        self.last_time = time_s;
        self.seeks += 1;
        f
    }

    /// Records a seek to `target` at `time_s` and returns its features.
    pub fn step(&mut self, time_s: f64, target: f64) -> SeekFeatures {
        self.step_moved(time_s, target, None)
    }

    /// As [`History::step`], with the direction of the move from `moved` when `Some` (see
    /// [`History::peek_moved`]).
    ///
    /// The same features as [`History::peek_moved`] followed by the update (kept as
    /// `History::step_moved_reference` and tested equal bit for bit), with the direction
    /// tracker asked once and the rest memory walked once (`RestMemory::move_and_nearest`).
    pub fn step_moved(&mut self, time_s: f64, target: f64, moved: Option<i8>) -> SeekFeatures {
        let first = self.position.is_none();
        let source = self.position.unwrap_or(target);
        let turn = self.turns.peek(target, moved);
        let (od, id) = self.memory.move_and_nearest(source, target);
        let f = SeekFeatures {
            seek_index: self.seeks,
            time_s,
            elapsed_s: if first { 0.0 } else { time_s - self.start_time },
            dwell_s: if first { 0.0 } else { time_s - self.last_time },
            source,
            target,
            seek_length: target - source,
            direction: turn.direction,
            direction_change: turn.reversal,
            since_reversal: turn.since_reversal,
            rest_distance_od: od.map(|p| target - p),
            rest_distance_id: id.map(|p| p - target),
        };
        if first {
            self.start_time = time_s;
        }
        self.position = Some(target);
        self.last_time = time_s;
        self.seeks += 1;
        self.turns.commit(target, &turn);
        f
    }

    /// The slow, obvious [`History::step_moved`]: [`History::peek_moved`], then the update
    /// (the rest memory scanned by `peek` and again by [`RestMemory::apply_move`], the
    /// direction tracker asked twice). The reference the fused step is tested against.
    #[cfg(test)]
    pub(crate) fn step_moved_reference(
        &mut self,
        time_s: f64,
        target: f64,
        moved: Option<i8>,
    ) -> SeekFeatures {
        let f = self.peek_moved(time_s, target, moved);
        if self.position.is_none() {
            self.start_time = time_s;
        }
        self.memory.apply_move(f.source, target);
        self.position = Some(target);
        self.last_time = time_s;
        self.seeks += 1;
        let turn = self.turns.peek(target, moved);
        self.turns.commit(target, &turn);
        f
    }
}

/// How the direction of motion is read from a log (issue #11), as a model file records it so
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
    /// The deadband [`sampling`] estimates: 2·√(2 ln n) × the position noise on a dense time
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
    /// positions ([`sampling`]); a velocity column must be one of its covariates.
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

/// [`sampling`] of every row of `log` (its time and position columns, read in place).
pub fn log_sampling(log: &crate::log::Log) -> Sampling {
    sampling(log.times(), log.tracks())
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

/// Replays a log's seek history with direction read as `source` says; `Err` when a velocity
/// column is missing.
pub(crate) fn replay_with<'a>(
    log: &'a crate::log::Log,
    source: &DirectionSource,
) -> Result<Replay<'a>, DirectionError> {
    let velocity = source.column_index(&log.schema.file, &log.schema.covariates)?;
    Ok(replay_checked(log, source, velocity, false))
}

/// [`replay_with`] for a source already checked against `log`: `velocity` is
/// [`DirectionSource::column_index`]'s answer. With `light`, only the features a log's times
/// and positions give without the seek history are computed ([`History::step_light`]).
pub(crate) fn replay_checked<'a>(
    log: &'a crate::log::Log,
    source: &DirectionSource,
    velocity: Option<usize>,
    light: bool,
) -> Replay<'a> {
    Replay {
        rows: log.rows().enumerate(),
        history: source.history(),
        velocity,
        light,
        cached: None,
        columns: None,
    }
}

/// The features of every row of a log that depend on its seek history (`direction`,
/// `direction_change`, `since_reversal`, the rest distances), kept compactly after one full
/// replay: 13 B/row, every position named by the row whose target it is (a rest position is
/// the source of a seek, i.e. the previous row's target; a turning point is a row's target).
/// A [`Replay`] reading them ([`Replay::reading_columns`]) gives every feature bit for bit as
/// [`History::step_moved`] does (the distances are the same subtraction of the same two
/// tracks; tested), without the branches of the direction tracker and the rest memory.
#[derive(Debug)]
pub(crate) struct HistoryColumns {
    /// `direction + 1` (0, 1, 2) in bits 0–1, `direction_change` in bit 2.
    flags: Vec<u8>,
    /// The row whose target is the turning point `since_reversal` is measured from.
    turn: Vec<u32>,
    /// The row whose target is the nearest uncrossed rest position on the OD side
    /// ([`NO_ROW`] for none); likewise on the ID side.
    od: Vec<u32>,
    id: Vec<u32>,
}

/// "No row" in [`HistoryColumns`].
const NO_ROW: u32 = u32::MAX;

impl HistoryColumns {
    /// Rows held (the log's rows).
    pub(crate) fn len(&self) -> usize {
        self.flags.len()
    }

    /// One full replay of `log` (direction as `source` says; `velocity` its checked column,
    /// [`DirectionSource::column_index`]). `None` for a log of 2³² − 1 rows or more, or whose
    /// first position is not finite (its `since_reversal` 0 is not `|x − x|`).
    pub(crate) fn build(
        log: &crate::log::Log,
        source: &DirectionSource,
        velocity: Option<usize>,
    ) -> Option<Self> {
        let x = log.tracks();
        let n = x.len();
        if n >= NO_ROW as usize || !x.first().is_none_or(|v| v.is_finite()) {
            return None;
        }
        let vel = velocity.map(|k| log.covariate(k));
        // The direction tracker and the rest memory read the positions alone, never each
        // other: each side walks the rows on its own (`rayon::join`), the same steps in the
        // same order as one walk doing both.
        let (turns, rests) = rayon::join(
            || Self::direction_rows(x, vel, source),
            || Self::rest_rows(x),
        );
        let ((flags, turn), (od, id)) = (turns?, rests);
        let cols = Self {
            flags,
            turn,
            od,
            id,
        };
        Some(cols)
    }

    /// [`HistoryColumns::build`]'s direction side: per row, the flags (direction and
    /// direction change) and the row whose target is the turning point; `None` where a
    /// tracker position names no row.
    fn direction_rows(
        x: &[f64],
        vel: Option<&[f64]>,
        source: &DirectionSource,
    ) -> Option<(Vec<u8>, Vec<u32>)> {
        let n = x.len();
        let mut tracker = source.history().turns;
        let (mut flags, mut turns) = (Vec::with_capacity(n), Vec::with_capacity(n));
        // The rows whose targets are the tracker's extreme and turning point (the anchor is
        // row 0's target): each new one is one of these or the current target, found by its
        // bits (any row with the same bits names the same value).
        let (mut ext, mut turn) = (0u32, 0u32);
        for (i, &target) in x.iter().enumerate() {
            let moved = vel.map(|v| DirectionSource::moved(Some(v[i])));
            let s = tracker.peek(target, moved);
            let find = |v: f64| {
                [i as u32, ext, turn, 0]
                    .into_iter()
                    .find(|&j| x[j as usize].to_bits() == v.to_bits())
            };
            let (e, t) = (find(s.extreme)?, find(s.turn)?);
            tracker.commit(target, &s);
            (ext, turn) = (e, t);
            flags.push((s.direction + 1) as u8 | u8::from(s.reversal) << 2);
            turns.push(t);
        }
        Some((flags, turns))
    }

    /// [`HistoryColumns::build`]'s rest side: per row, the rows whose targets are the nearest
    /// uncrossed rest positions on the OD and the ID side ([`NO_ROW`] for none).
    fn rest_rows(x: &[f64]) -> (Vec<u32>, Vec<u32>) {
        let n = x.len();
        let (mut below, mut above): (Vec<u32>, Vec<u32>) = (Vec::new(), Vec::new());
        let (mut ods, mut ids) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for (i, &target) in x.iter().enumerate() {
            let (od, id) = match i.checked_sub(1) {
                None => (None, None),
                Some(prev) => {
                    let source = x[prev];
                    // `RestMemory::move_and_nearest` on row numbers.
                    if target > source {
                        while above.last().is_some_and(|&p| x[p as usize] <= target) {
                            above.pop();
                        }
                        let near = (below.last().copied(), above.last().copied());
                        below.push(prev as u32);
                        near
                    } else if target < source {
                        while below.last().is_some_and(|&p| x[p as usize] >= target) {
                            below.pop();
                        }
                        let near = (below.last().copied(), above.last().copied());
                        above.push(prev as u32);
                        near
                    } else {
                        (below.last().copied(), above.last().copied())
                    }
                }
            };
            ods.push(od.unwrap_or(NO_ROW));
            ids.push(id.unwrap_or(NO_ROW));
        }
        (ods, ids)
    }

    /// [`SeekFeatures::rest_distance_ahead`] of every row whose `bias` is not NaN (a measured
    /// row), in log order, where `x` is the log's tracks: the features [`HistoryColumns::fill`]
    /// gives those rows (the same subtraction of the same two tracks, so the same bits),
    /// without stepping the positional history a [`Replay`] steps for every row.
    pub(crate) fn measured_rest_distances_ahead(&self, x: &[f64], bias: &[f64]) -> Vec<f64> {
        let mut out = Vec::with_capacity(bias.iter().filter(|b| !b.is_nan()).count());
        for (i, (&target, b)) in x.iter().zip(bias).enumerate() {
            if b.is_nan() {
                continue;
            }
            let ahead = match (self.flags[i] & 3) as i8 - 1 {
                1 => (self.id[i] != NO_ROW).then(|| x[self.id[i] as usize] - target),
                -1 => (self.od[i] != NO_ROW).then(|| target - x[self.od[i] as usize]),
                _ => None,
            };
            out.extend(ahead);
        }
        out
    }

    /// Fills the history features of row `i` into `f`, which holds its positional ones
    /// ([`History::step_light`]); `x` is the log's tracks.
    #[inline(always)]
    fn fill(&self, i: usize, x: &[f64], f: &mut SeekFeatures) {
        let flags = self.flags[i];
        let target = f.target;
        f.direction = (flags & 3) as i8 - 1;
        f.direction_change = flags & 4 != 0;
        f.since_reversal = if i == 0 {
            0.0
        } else {
            (target - x[self.turn[i] as usize]).abs()
        };
        let (od, id) = (self.od[i], self.id[i]);
        f.rest_distance_od = (od != NO_ROW).then(|| target - x[od as usize]);
        f.rest_distance_id = (id != NO_ROW).then(|| x[id as usize] - target);
    }
}

/// The turning points of a replayed log, in order: where each direction change began
/// (`target − direction·since_reversal` of every seek with `direction_change`), position unit.
pub(crate) fn turning_points(features: impl IntoIterator<Item = SeekFeatures>) -> Vec<f64> {
    features
        .into_iter()
        .filter(|f| f.direction_change)
        .map(|f| f.target - f64::from(f.direction) * f.since_reversal)
        .collect()
}

/// The reversal amplitudes of a replayed log: distances between consecutive turning points
/// ([`turning_points`]), position unit; the travel a hysteresis loop of the log spans. Empty
/// with fewer than two reversals.
pub(crate) fn reversal_amplitudes(features: impl IntoIterator<Item = SeekFeatures>) -> Vec<f64> {
    turning_points(features)
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|a| *a > 0.0)
        .collect()
}

/// How a log samples the motion, and how its direction of motion is read (`biasctl check`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sampling {
    /// Rows per second (rows − 1 over the time span); `None` for a log without a time span.
    pub rows_per_s: Option<f64>,
    /// Median |position step| between consecutive rows, position unit.
    pub median_step: f64,
    /// The travel: 5–95 % quantile range of the positions, position unit.
    pub travel: f64,
    /// Position noise estimate, position unit: 1.4826·MAD(Δ²x)/√6 (the spread of the second
    /// difference, which removes a smooth motion; white noise of std σ gives σ).
    pub noise: f64,
    /// Whether the rows come on a regular clock: the median |Δt − median Δt| is at most 1 % of
    /// the median Δt (a sampled signal; a seek log's dwells vary).
    pub regular_clock: bool,
    /// Whether the log is a dense time series (on a regular clock, with the median step below
    /// 1 % of the travel) rather than a log of seeks.
    pub dense: bool,
    /// The deadband [`sampling`] estimates: 2·√(2 ln n) × the noise for a dense log of n rows, else 0.
    pub deadband: f64,
    /// Direction reversals from the raw sign of each step.
    pub raw_reversals: usize,
    /// Direction reversals with the deadband.
    pub reversals: usize,
}

/// Describes how `positions` (in row order, position unit) sample the motion; `times_s` are the
/// rows' times. A seek log (each row a seek: irregular times, or a median step ≥ 1 % of the
/// travel) keeps deadband 0.
///
/// The times' quantiles, the median step and the raw reversal count run beside the positions'
/// quantiles (`rayon::join`, each side with its own scratch buffer), and the 5 % and 95 % quantiles of
/// the positions come from one nested selection (`numeric::stats::percentiles_select`): the same bits as
/// the one-buffer, one-quantile-at-a-time `sampling_reference` (tested), on any thread count.
pub fn sampling(times_s: &[f64], positions: &[f64]) -> Sampling {
    use crate::numeric::stats::{percentile_select, percentiles_select};
    // Every quantile is found by selection in a scratch buffer (O(n), no sort); it equals
    // `percentile_sorted(&sorted(v), p)` bit for bit (tested against it).
    let median = |scratch: &mut Vec<f64>, values: &mut dyn Iterator<Item = f64>| {
        scratch.clear();
        scratch.extend(values);
        percentile_select(scratch, 50.0).unwrap_or(0.0)
    };
    // The times' side also finds the median step (three selections and a pass each side,
    // about: the positions' quantiles are two selections nested in one).
    let times_side = || {
        let mut scratch = Vec::with_capacity(times_s.len().max(positions.len()));
        let dt = median(&mut scratch, &mut times_s.windows(2).map(|w| w[1] - w[0]));
        let dt_dev = median(
            &mut scratch,
            &mut times_s.windows(2).map(|w| ((w[1] - w[0]) - dt).abs()),
        );
        let median_step = median(
            &mut scratch,
            &mut positions.windows(2).map(|w| (w[1] - w[0]).abs()),
        );
        (dt, dt_dev, median_step, count_reversals(positions, 0.0))
    };
    let positions_side = || {
        let mut scratch = Vec::with_capacity(positions.len());
        scratch.extend_from_slice(positions);
        let (p95, p5) = match percentiles_select(&mut scratch, &[95.0, 5.0]) {
            Some(q) => (q[0], q[1]),
            None => (0.0, 0.0),
        };
        let mad = median(
            &mut scratch,
            &mut positions
                .windows(3)
                .map(|w| second_difference(w[0], w[1], w[2])),
        );
        (p95, p5, mad)
    };
    let ((dt, dt_dev, median_step, raw), (p95, p5, mad)) = rayon::join(times_side, positions_side);
    let q = Quantiles {
        regular_clock: regular_clock(dt, dt_dev),
        median_step,
        p95,
        p5,
        mad,
    };
    let span = match (times_s.first(), times_s.last()) {
        (Some(a), Some(b)) if b > a => Some(b - a),
        _ => None,
    };
    q.sampling(positions.len(), span, raw, |d| {
        count_reversals(positions, d)
    })
}

/// Direction reversals of `positions` with deadband `d` ([`DirectionTracker`]).
fn count_reversals(positions: &[f64], d: f64) -> usize {
    let mut t = DirectionTracker::new(d);
    positions
        .iter()
        .filter(|&&x| {
            let s = t.peek(x, None);
            t.commit(x, &s);
            s.reversal
        })
        .count()
}

/// The slow, obvious [`sampling`]: one scratch buffer, every quantile selected on its own in
/// turn, on one thread. The reference the parallel, nested one is tested against.
#[cfg(test)]
pub(crate) fn sampling_reference(times_s: &[f64], positions: &[f64]) -> Sampling {
    // Every quantile is found by selection in one reused scratch buffer (O(n), no sort); it
    // equals `percentile_sorted(&sorted(v), p)` bit for bit (tested against it).
    let mut scratch: Vec<f64> = Vec::with_capacity(positions.len().max(times_s.len()));
    let mut quantile = |values: &mut dyn Iterator<Item = f64>, p: f64| {
        scratch.clear();
        scratch.extend(values);
        crate::numeric::stats::percentile_select(&mut scratch, p).unwrap_or(0.0)
    };
    let dt = quantile(&mut times_s.windows(2).map(|w| w[1] - w[0]), 50.0);
    let dt_dev = quantile(
        &mut times_s.windows(2).map(|w| ((w[1] - w[0]) - dt).abs()),
        50.0,
    );
    let q = Quantiles {
        regular_clock: regular_clock(dt, dt_dev),
        median_step: quantile(&mut positions.windows(2).map(|w| (w[1] - w[0]).abs()), 50.0),
        p95: quantile(&mut positions.iter().copied(), 95.0),
        p5: quantile(&mut positions.iter().copied(), 5.0),
        mad: quantile(
            &mut positions
                .windows(3)
                .map(|w| second_difference(w[0], w[1], w[2])),
            50.0,
        ),
    };
    let span = match (times_s.first(), times_s.last()) {
        (Some(a), Some(b)) if b > a => Some(b - a),
        _ => None,
    };
    q.sampling(
        positions.len(),
        span,
        count_reversals(positions, 0.0),
        |d| count_reversals(positions, d),
    )
}

/// |x₂ − 2x₁ + x₀|, the second difference [`Sampling::noise`] is estimated from.
fn second_difference(x0: f64, x1: f64, x2: f64) -> f64 {
    (x2 - 2.0 * x1 + x0).abs()
}

/// Whether rows whose median Δt is `dt` and median |Δt − median Δt| is `dt_dev` come on a
/// regular clock ([`Sampling::regular_clock`]).
fn regular_clock(dt: f64, dt_dev: f64) -> bool {
    dt > 0.0 && dt_dev <= CLOCK_TOLERANCE * dt
}

/// How far (relative) the median |Δt − median Δt| may stray for a regular clock.
const CLOCK_TOLERANCE: f64 = 0.01;

/// The quantiles [`sampling`] is made of: whether the clock is regular (from the median Δt and
/// the median |Δt − median Δt|); the median |position step|; the 95 % and 5 % quantiles of the
/// positions; the median |Δ²x|.
struct Quantiles {
    regular_clock: bool,
    median_step: f64,
    p95: f64,
    p5: f64,
    mad: f64,
}

impl Quantiles {
    /// The position noise estimate (see [`Sampling::noise`]).
    fn noise(&self) -> f64 {
        1.4826 * self.mad / 6f64.sqrt()
    }

    /// The deadband of a dense log of `rows` rows: the range i.i.d. noise spans over n samples
    /// (twice its expected maximum, √(2 ln n)·σ); a smaller band lets two opposite noise
    /// extremes fake a reversal somewhere in a long log.
    fn dense_deadband(&self, rows: usize) -> f64 {
        let n = rows.max(2) as f64;
        2.0 * (2.0 * n.ln()).sqrt() * self.noise()
    }

    /// The [`Sampling`] of a log of `rows` rows over time `span` (s) with `raw_reversals`;
    /// `count` counts the reversals with a deadband.
    fn sampling(
        &self,
        rows: usize,
        span: Option<f64>,
        raw_reversals: usize,
        count: impl FnOnce(f64) -> usize,
    ) -> Sampling {
        let regular_clock = self.regular_clock;
        let travel = self.p95 - self.p5;
        let dense = regular_clock && travel > 0.0 && self.median_step < 0.01 * travel;
        let deadband = if dense {
            self.dense_deadband(rows)
        } else {
            0.0
        };
        Sampling {
            rows_per_s: span.map(|s| (rows.saturating_sub(1)) as f64 / s),
            median_step: self.median_step,
            travel,
            noise: self.noise(),
            regular_clock,
            dense,
            deadband,
            raw_reversals,
            // With no deadband (every seek log) the count is the raw one: one pass, not two.
            reversals: if deadband == 0.0 {
                raw_reversals
            } else {
                count(deadband)
            },
        }
    }
}

/// [`sampling`] of a log read in passes, in memory independent of its length (`biasctl
/// check`): feed every row's time and position with [`SamplingStream::push`], end the pass
/// with [`SamplingStream::end_pass`], and read the log again while it returns `true`; then
/// [`SamplingStream::finish`]. Each quantile is exact ([`StreamPercentile`]), so the result
/// equals [`sampling`] of the whole log bit for bit. Passes: the first counts and
/// histograms; the quantiles of the positions and of Δt usually end with the second; a dense
/// log's reversals with the deadband need one more. Whether the clock is regular (the spread of
/// Δt about its median) costs no pass of its own when the first pass settles it: a Δt of at
/// most 4096 distinct values (a clock) is known value by value, so the spread is
/// computed from that table; else the first pass's histogram bounds how many Δt can lie within
/// 2 % of their median, and when that is fewer than half of them the clock is irregular (the
/// median spread is then above 1 % of the median: a seek log's dwells). Only a clock that is
/// neither (jittered beyond the table, yet within 2 %) reads the log for the spread: one or two
/// passes after the median.
///
/// [`StreamPercentile`]: crate::numeric::stats::StreamPercentile
pub(crate) struct SamplingStream {
    dt: StreamPercentile,
    step: StreamPercentile,
    p95: StreamPercentile,
    p5: StreamPercentile,
    d2: StreamPercentile,
    /// Started in the pass after the median Δt is known (at once, from the first pass's
    /// values, when Δt has few distinct values).
    dt_dev: Option<(f64, StreamPercentile)>,
    /// The first pass settled that the clock is irregular: `dt_dev` is not needed.
    irregular: bool,
    /// Rows in the pass so far, and the last two rows' time and position.
    row: usize,
    prev: (f64, f64),
    prev2_x: f64,
    /// The first pass: rows, first and last time, the raw reversals.
    rows: usize,
    first_last: (f64, f64),
    raw: (DirectionTracker, usize),
    /// The reversals with the deadband the quantiles give a dense log: counted in the pass
    /// after the noise is known; `(deadband, tracker, count, done)`.
    banded: Option<(f64, DirectionTracker, usize, bool)>,
    passes: usize,
}

use crate::numeric::stats::StreamPercentile;

impl SamplingStream {
    /// Before the first pass.
    pub(crate) fn new() -> Self {
        Self {
            dt: StreamPercentile::new(50.0),
            step: StreamPercentile::new(50.0),
            p95: StreamPercentile::new(95.0),
            p5: StreamPercentile::new(5.0),
            d2: StreamPercentile::new(50.0),
            dt_dev: None,
            irregular: false,
            row: 0,
            prev: (0.0, 0.0),
            prev2_x: 0.0,
            rows: 0,
            first_last: (0.0, 0.0),
            raw: (DirectionTracker::new(0.0), 0),
            banded: None,
            passes: 0,
        }
    }

    /// The next row of the pass: its time (s) and position.
    pub(crate) fn push(&mut self, t: f64, x: f64) {
        let count = |tr: &mut DirectionTracker, n: &mut usize| {
            let s = tr.peek(x, None);
            tr.commit(x, &s);
            *n += usize::from(s.reversal);
        };
        if self.passes == 0 {
            if self.row == 0 {
                self.first_last.0 = t;
            }
            self.first_last.1 = t;
            self.rows += 1;
            let (tr, n) = &mut self.raw;
            count(tr, n);
        }
        if let Some((_, tr, n, false)) = &mut self.banded {
            count(tr, n);
        }
        let (pt, px) = self.prev;
        if self.row >= 1 {
            let dt = t - pt;
            self.dt.push(dt);
            if let Some((median, q)) = &mut self.dt_dev {
                q.push((dt - *median).abs());
            }
            self.step.push((x - px).abs());
        }
        if self.row >= 2 {
            self.d2.push(second_difference(self.prev2_x, px, x));
        }
        if self.passes > 0 {
            self.p95.push(x);
        }
        self.p5.push(x);
        self.prev2_x = px;
        self.prev = (t, x);
        self.row += 1;
    }

    /// Ends a pass; `true` when the log must be read once more.
    pub(crate) fn end_pass(&mut self) -> bool {
        // Read before the first pass's histograms and value tables are dropped.
        let first = self.passes == 0;
        let dt_values = first.then(|| self.dt.first_pass_values()).flatten();
        let dt_near = first
            .then(|| self.dt.first_pass_count_near(2.0 * CLOCK_TOLERANCE))
            .flatten();
        if first {
            // The first pass pushed the positions into `p5` alone.
            self.p95 = self.p5.first_pass_twin(95.0);
        }
        for q in [
            &mut self.dt,
            &mut self.step,
            &mut self.p95,
            &mut self.p5,
            &mut self.d2,
        ] {
            q.end_pass();
        }
        if let Some((_, q)) = &mut self.dt_dev {
            q.end_pass();
        }
        if let Some(b) = &mut self.banded {
            b.3 = true;
        }
        self.passes += 1;
        self.row = 0;
        if let Some(near) = dt_near
            && self.dt.result().is_none()
        {
            // Fewer Δt within 2 % of the median than the lower middle rank of the spreads
            // (`percentile_select`'s position for 50 % of rows − 1 values): the median spread is
            // at least that order statistic, above 1 % of the median.
            let lower_middle = (0.5 * self.rows.saturating_sub(2) as f64).floor() as u64;
            self.irregular = near <= lower_middle;
        }
        if self.dt_dev.is_none()
            && !self.irregular
            && let Some(median) = self.dt.result()
        {
            let median = median.unwrap_or(0.0);
            let mut spread = StreamPercentile::new(50.0);
            if let Some(values) = dt_values {
                // Every Δt of the log, value by value: the spreads' stream is that table.
                for (dt, count) in values {
                    spread.push_counted((dt - median).abs(), count);
                }
                spread.end_pass();
            }
            self.dt_dev = Some((median, spread));
        }
        if self.banded.is_none()
            && let Some(mad) = self.d2.result()
        {
            let q = Quantiles {
                regular_clock: false,
                median_step: 0.0,
                p95: 0.0,
                p5: 0.0,
                mad: mad.unwrap_or(0.0),
            };
            let d = q.dense_deadband(self.rows);
            self.banded = Some((d, DirectionTracker::new(d), 0, false));
        }
        match self.quantiles() {
            None => true,
            Some(q) => {
                let s = q.sampling(self.rows, None, 0, |_| 0);
                s.dense && !self.banded.as_ref().is_some_and(|b| b.3)
            }
        }
    }

    /// Every quantile, once all are known.
    fn quantiles(&self) -> Option<Quantiles> {
        let get = |q: &StreamPercentile| q.result().map(|r| r.unwrap_or(0.0));
        let regular =
            !self.irregular && regular_clock(get(&self.dt)?, get(&self.dt_dev.as_ref()?.1)?);
        Some(Quantiles {
            regular_clock: regular,
            median_step: get(&self.step)?,
            p95: get(&self.p95)?,
            p5: get(&self.p5)?,
            mad: get(&self.d2)?,
        })
    }

    /// The sampling, once [`SamplingStream::end_pass`] has returned `false` (`None` before).
    pub(crate) fn finish(&self) -> Option<Sampling> {
        let q = self.quantiles()?;
        let (a, b) = self.first_last;
        let span = (self.rows > 0 && b > a).then_some(b - a);
        let banded = self.banded.as_ref().map(|b| b.2);
        let s = q.sampling(self.rows, span, self.raw.1, |_| banded.unwrap_or(0));
        (!s.dense || self.banded.as_ref().is_some_and(|b| b.3)).then_some(s)
    }
}

/// Streams the log `reader` was opened on (from `path` with `map`) and returns its summary
/// ([`LogReader::summarise`](crate::LogReader::summarise)) and its [`sampling`], in memory
/// independent of the number of rows (`biasctl check`): the exact quantiles (the same bits as
/// [`sampling`] of every row in memory) need a few passes of radix selection (one on logs
/// whose quantiles take few distinct values and whose clock the first pass settles, three on a
/// dense 1 kHz log with noisy positions, more when a jittered clock's spread must be read).
/// The log itself is read once: while it is, the time and position of every row (16 bytes per
/// row) are written to a temporary file in [`std::env::temp_dir`], which the later passes read
/// and which is removed at the end. Should that file not be made or written, a regular file is
/// read again from `path` instead (every pass validates the rows as the first; a file whose row
/// count changes between passes is an error); for standard input (`path` `-`) it is an error.
pub fn summarise_sampling(
    reader: &mut crate::log::LogReader<Box<dyn std::io::Read>>,
    path: &std::path::Path,
    map: &crate::log::ColumnMap,
) -> Result<(crate::log::LogSummary, Sampling), crate::log::LogError> {
    use crate::log::{LogError, LogReader, Row, STDIN_PATH};
    use std::io::{BufWriter, Read, Seek, Write};
    let file = reader.schema().file.clone();
    let io = |source: std::io::Error| LogError::Io {
        file: file.clone(),
        source,
    };
    let stdin = path.as_os_str() == STDIN_PATH;
    // Standard input cannot be read again: its passes need the temporary file.
    let spool_failed = |e: std::io::Error| {
        let dir = std::env::temp_dir();
        io(std::io::Error::new(
            e.kind(),
            format!(
                "the later passes need a temporary file in {} (set TMPDIR to a writable folder with room for 16 bytes per row): {e}",
                dir.display()
            ),
        ))
    };
    let mut stream = SamplingStream::new();
    let mut spool = match Spool::create() {
        Ok(s) => Some(s),
        Err(e) if stdin => return Err(spool_failed(e)),
        Err(_) => None,
    };
    let mut spool_err = None;
    let summary = {
        let mut out = spool.as_mut().map(|s| BufWriter::new(&mut s.file));
        let summary = reader.summarise_each(|r| {
            stream.push(r.time_s, r.track);
            if let Some(w) = out.as_mut()
                && spool_err.is_none()
            {
                let mut rec = [0u8; 16];
                rec[..8].copy_from_slice(&r.time_s.to_le_bytes());
                rec[8..].copy_from_slice(&r.track.to_le_bytes());
                if let Err(e) = w.write_all(&rec) {
                    spool_err = Some(e);
                }
            }
        })?;
        let flushed = out.map(|w| w.into_inner().map(|_| ()).map_err(|e| e.into_error()));
        spool_err = spool_err.or(flushed.and_then(Result::err));
        summary
    };
    if let Some(e) = spool_err {
        if stdin {
            return Err(spool_failed(e));
        }
        // A full or failing temporary directory: read the file again instead.
        spool = None;
    }
    let changed = || {
        io(std::io::Error::other(
            "the file changed while it was read (its row count differs between passes)",
        ))
    };
    while stream.end_pass() {
        let mut rows = 0u64;
        match spool.as_mut() {
            Some(s) => {
                s.file.rewind().map_err(io)?;
                // Whole records from a block buffer (a short read may split one).
                let mut buf = vec![0u8; 1 << 16];
                let mut filled = 0;
                loop {
                    let got = s.file.read(&mut buf[filled..]).map_err(io)?;
                    filled += got;
                    let whole = filled - filled % 16;
                    for rec in buf[..whole].chunks_exact(16) {
                        let (t, x) = rec.split_at(8);
                        let f = |b: &[u8]| f64::from_le_bytes(b.try_into().unwrap_or([0; 8]));
                        stream.push(f(t), f(x));
                    }
                    rows += (whole / 16) as u64;
                    buf.copy_within(whole..filled, 0);
                    filled -= whole;
                    if got == 0 {
                        break;
                    }
                }
                if filled != 0 {
                    return Err(changed());
                }
            }
            None => {
                let mut again = LogReader::open(path, map)?;
                let mut row = Row::empty(again.schema().covariates.len());
                while again.read_into(&mut row)? {
                    stream.push(row.time_s, row.track);
                    rows += 1;
                }
            }
        }
        if rows != summary.rows {
            return Err(changed());
        }
    }
    let sampling = stream.finish().ok_or_else(changed)?;
    Ok((summary, sampling))
}

/// A temporary file of `summarise_sampling`, removed when dropped.
struct Spool {
    file: std::fs::File,
    path: std::path::PathBuf,
}

impl Spool {
    /// A new file in the temporary directory, named after the process and the time.
    fn create() -> std::io::Result<Self> {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        let path =
            std::env::temp_dir().join(format!("biasctl-check-{}-{nanos}.bin", std::process::id()));
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&path)?;
        Ok(Self { file, path })
    }
}

impl Drop for Spool {
    fn drop(&mut self) {
        // Best effort: a file that cannot be removed stays in the temporary directory.
        let _ = std::fs::remove_file(&self.path);
    }
}

impl Sampling {
    /// Plain-language lines for `check`, positions in `unit`.
    pub fn describe(&self, unit: &str) -> Vec<String> {
        let g = |v: f64| format!("{v:.4e}");
        let mut out = vec![match self.rows_per_s {
            Some(r) => format!("sampling: {} rows/s", crate::log::fmt_trimmed(r, 3)),
            None => "sampling: no time span".into(),
        }];
        if self.dense {
            out.push(format!(
                "mode: dense time series (rows on a regular clock; the median step, {} {unit}, is below 1 % of the travel, {} {unit}); \
                 each row is one sample of a continuous motion, and the direction reverses only once the \
                 position has come back more than a deadband of {} {unit} (2·√(2 ln n) × the estimated position noise, {} {unit}) \
                 from its furthest point",
                g(self.median_step), g(self.travel), g(self.deadband), g(self.noise)
            ));
            out.push(format!(
                "reversals: {} with the deadband ({} from the raw sign of each step)",
                self.reversals, self.raw_reversals
            ));
            if self.raw_reversals > 3 * self.reversals.max(1) {
                out.push(format!(
                    "warning: the raw steps reverse {} times, {}× the {} reversals with the deadband: \
                     sensor noise fakes reversals when direction is read from raw steps",
                    self.raw_reversals,
                    self.raw_reversals / self.reversals.max(1),
                    self.reversals
                ));
            }
        } else {
            let why = if self.travel <= 0.0 {
                "every row is at the same position: no motion to read a direction from".to_string()
            } else if self.regular_clock {
                format!(
                    "the median step, {} {unit}, is at least 1 % of the travel, {} {unit}",
                    g(self.median_step),
                    g(self.travel)
                )
            } else {
                "the rows come at irregular times".to_string()
            };
            out.push(format!(
                "mode: seek log ({why}); each row is one seek and its direction is the sign of \
                 the move (no deadband)"
            ));
            out.push(format!("reversals: {}", self.raw_reversals));
        }
        out
    }
}

/// The one replay of a log's seek history: every row of `log` in order, with its index in
/// the log and its [`SeekFeatures`]. Unmeasured rows move the head too, so they are yielded
/// as well; callers that want only measured rows filter on `row.bias`. Used by the fit
/// ([`crate::model::data::FitData`]), diagnose, the plots and the report.
///
/// ```
/// use biasctl::replay;
/// use biasctl::{ColumnMap, Log};
/// let text = "time_s,track,bias\n0,100,5\n1,150,\n2,120,3\n";
/// let log = Log::from_reader("t.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
/// let seeks: Vec<f64> = replay(&log).map(|(_, _, f)| f.seek_length).collect();
/// assert_eq!(seeks, [0.0, 50.0, -30.0]);
/// let (i, row, f) = replay(&log).filter(|(_, r, _)| r.bias.is_some()).last().unwrap();
/// assert_eq!((i, row.track, f.direction), (2, 120.0, -1));
/// ```
pub fn replay(log: &crate::log::Log) -> Replay<'_> {
    Replay {
        rows: log.rows().enumerate(),
        history: History::new(),
        velocity: None,
        light: false,
        cached: None,
        columns: None,
    }
}

/// The iterator of [`replay`]: yields `(index, row, features)` for every row of a log.
#[derive(Debug, Clone)]
pub struct Replay<'a> {
    rows: std::iter::Enumerate<crate::log::Rows<'a>>,
    history: History,
    velocity: Option<usize>,
    /// Only the features of [`History::step_light`].
    light: bool,
    /// Every row's features, replayed before (`crate::model::FitData`'s bounded cache): read
    /// instead of stepping the history (the same values, bit for bit).
    cached: Option<std::sync::Arc<[SeekFeatures]>>,
    /// The history features of every row, replayed before ([`HistoryColumns`]), and the log's
    /// tracks they name: read instead of stepping the history (the same values, bit for bit).
    columns: Option<(std::sync::Arc<HistoryColumns>, &'a [f64])>,
}

impl<'a> Replay<'a> {
    /// This replay reading `features` (one per row of the log, from a full replay of it with
    /// the same direction source) instead of stepping the history.
    pub(crate) fn reading_cache(mut self, features: std::sync::Arc<[SeekFeatures]>) -> Self {
        self.cached = Some(features);
        self
    }

    /// This full replay (not light) reading `columns` (built by [`HistoryColumns::build`]
    /// from `log`, the log this replays, with the same direction source) for the history
    /// features; the positional ones are stepped ([`History::step_light`]).
    pub(crate) fn reading_columns(
        mut self,
        columns: std::sync::Arc<HistoryColumns>,
        log: &'a crate::log::Log,
    ) -> Self {
        debug_assert_eq!(columns.flags.len(), log.len());
        self.columns = (!self.light).then_some((columns, log.tracks()));
        self
    }
}

impl<'a> Iterator for Replay<'a> {
    type Item = (usize, crate::log::RowRef<'a>, SeekFeatures);

    #[inline(always)]
    fn next(&mut self) -> Option<Self::Item> {
        let (i, row) = self.rows.next()?;
        if let Some(c) = &self.cached {
            return Some((i, row, c[i]));
        }
        if self.light {
            return Some((i, row, self.history.step_light(row.time_s, row.track)));
        }
        if let Some((c, x)) = &self.columns {
            let mut f = self.history.step_light(row.time_s, row.track);
            c.fill(i, x, &mut f);
            return Some((i, row, f));
        }
        let moved = self
            .velocity
            .map(|k| DirectionSource::moved(row.covariates.get(k)));
        Some((
            i,
            row,
            self.history.step_moved(row.time_s, row.track, moved),
        ))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.rows.size_hint()
    }
}

impl ExactSizeIterator for Replay<'_> {}

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

#[cfg(test)]
#[allow(clippy::float_cmp)] // positions are exact integers here; equality is meant
mod tests {
    use super::*;
    use crate::numeric::rng::SimRng;

    /// A log whose every row is at one position says so in `check`'s mode line, instead of
    /// comparing a zero median step with a zero travel.
    #[test]
    fn a_constant_position_log_is_described_as_such() {
        let text = "time_s,track,bias\n0,5,1\n1,5,2\n2,5,3\n3,5,2\n";
        let log =
            crate::log::Log::from_reader("c.csv", text.as_bytes(), &Default::default()).unwrap();
        let lines = log_sampling(&log).describe("tracks");
        let mode = lines.iter().find(|l| l.starts_with("mode:")).unwrap();
        assert!(mode.contains("every row is at the same position"), "{mode}");
        assert!(!mode.contains("1 % of the travel"), "{mode}");
    }

    /// Reference: sort a copy, then `percentile_sorted` (what `sampling` did before it selected).
    #[test]
    fn selected_percentiles_equal_sorted_ones_bit_for_bit() {
        use crate::numeric::stats::{percentile_select, percentile_sorted, sorted};
        let mut rng = SimRng::new(7);
        for case in 0..300 {
            let n = 1 + rng.below(200) as usize;
            // Few distinct values (ties), signed zeros, and wide spreads.
            let v: Vec<f64> = (0..n)
                .map(|_| match case % 3 {
                    0 => rng.below(5) as f64 - 2.0,
                    1 => [0.0, -0.0, 1.5, -1.5][rng.below(4) as usize],
                    _ => rng.normal() * 10f64.powi(rng.below(20) as i32 - 10),
                })
                .collect();
            for p in [0.0, 5.0, 37.5, 50.0, 95.0, 100.0] {
                let want = percentile_sorted(&sorted(&v), p).unwrap();
                let got = percentile_select(&mut v.clone(), p).unwrap();
                assert_eq!(got.to_bits(), want.to_bits(), "case {case}, p {p}, n {n}");
            }
        }
        assert_eq!(percentile_select(&mut [], 50.0), None);
    }

    /// Reference: [`sampling_reference`] (one buffer, each quantile selected alone, one
    /// thread). The parallel sampling with the nested 5/95 % selection gives the same
    /// `Sampling`, every float bit for bit, on dense sine logs (the deadband count runs), seek
    /// logs, ties and signed zeros, jittered clocks and logs of 0–3 rows, on 1 and 2 threads.
    #[test]
    fn parallel_sampling_equals_the_reference_bit_for_bit() {
        let mut rng = SimRng::new(29);
        let bits = |s: &Sampling| {
            (
                s.rows_per_s.map(f64::to_bits),
                [s.median_step, s.travel, s.noise, s.deadband].map(f64::to_bits),
                (s.regular_clock, s.dense, s.raw_reversals, s.reversals),
            )
        };
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let mut dense = 0;
        for case in 0..120 {
            let n = match case % 8 {
                0 => rng.below(4) as usize,
                1 => 30_000,
                _ => 1 + rng.below(4000) as usize,
            };
            let dt = [1e-3, 0.01, 0.5][rng.below(3) as usize];
            let (t, x): (Vec<f64>, Vec<f64>) = (0..n)
                .map(|i| {
                    let ti = i as f64 * dt;
                    match case % 5 {
                        0 | 1 => (ti, 100.0 * (0.002 * i as f64).sin() + 0.05 * rng.normal()),
                        2 => (
                            ti + rng.range(0.0, 0.9) * dt,
                            [0.0, -0.0, -3.0, 7.5][rng.below(4) as usize],
                        ),
                        3 => (
                            ti + rng.range(-0.01, 0.01) * dt,
                            rng.range(-500.0, 500.0).round(),
                        ),
                        _ => (ti, rng.below(1001) as f64 * 0.37),
                    }
                })
                .unzip();
            let want = sampling_reference(&t, &x);
            dense += usize::from(want.dense && want.deadband > 0.0);
            assert_eq!(bits(&sampling(&t, &x)), bits(&want), "case {case}, n {n}");
            assert_eq!(bits(&one.install(|| sampling(&t, &x))), bits(&want));
        }
        assert!(dense > 10, "the deadband count ran on {dense} logs");
    }

    /// Reference: sort a copy and index it (`sorted`, `percentile_sorted`). Nested selection
    /// of several ranks (repeats, neighbours, both ends) and several percentiles from one
    /// selection give the same bits as the sorted copy, on values with ties and signed zeros.
    #[test]
    fn nested_order_statistics_equal_sorted_ones_bit_for_bit() {
        use crate::numeric::stats::{
            order_statistics, percentile_sorted, percentiles_select, sorted,
        };
        let mut rng = SimRng::new(11);
        for case in 0..600 {
            let n = 1 + rng.below(300) as usize;
            let v = awkward_values(&mut rng, case, n);
            let s = sorted(&v);
            let mut ranks: Vec<usize> = (0..rng.below(9) as usize)
                .map(|_| match rng.below(4) {
                    0 => 0,
                    1 => n - 1,
                    _ => rng.below(n as u64) as usize,
                })
                .collect();
            ranks.sort_unstable();
            let mut out = vec![f64::NAN; ranks.len()];
            order_statistics(&mut v.clone(), &ranks, &mut out);
            for (r, o) in ranks.iter().zip(&out) {
                assert_eq!(o.to_bits(), s[*r].to_bits(), "case {case}, rank {r}, n {n}");
            }
            let ps = [95.0, 5.0, 50.0, 37.5, 0.0, 100.0, 99.9];
            let got = percentiles_select(&mut v.clone(), &ps).unwrap();
            for (p, g) in ps.iter().zip(&got) {
                let want = percentile_sorted(&s, *p).unwrap();
                assert_eq!(g.to_bits(), want.to_bits(), "case {case}, p {p}, n {n}");
            }
        }
        assert_eq!(percentiles_select(&mut [], &[50.0]), None);
    }

    /// Values with ties, signed zeros, negatives, near-equal clusters (a clock's Δt differing
    /// in the last bits) and wide spreads, by `case`.
    fn awkward_values(rng: &mut SimRng, case: usize, n: usize) -> Vec<f64> {
        (0..n)
            .map(|_| match case % 6 {
                0 => rng.below(5) as f64 - 2.0,
                1 => [0.0, -0.0, 1.5, -1.5][rng.below(4) as usize],
                2 => rng.normal() * 10f64.powi(rng.below(20) as i32 - 10),
                3 => f64::from_bits(1e-3f64.to_bits() + rng.below(40)) - 1e-3 * rng.below(2) as f64,
                4 => -1e-3 * (1.0 + rng.below(3) as f64 * f64::EPSILON),
                _ => rng.range(-1e6, 1e6).round() + [0.0, 0.25, -0.0][rng.below(3) as usize],
            })
            .collect()
    }

    /// Runs a [`StreamPercentile`] over `v` pass after pass; its result and the passes taken.
    fn streamed(v: &[f64], p: f64, caps: (u64, usize)) -> (Option<f64>, u32) {
        use crate::numeric::stats::StreamPercentile;
        let mut q = StreamPercentile::with_caps(p, caps.0, caps.1);
        loop {
            v.iter().for_each(|&x| q.push(x));
            q.end_pass();
            if let Some(r) = q.result() {
                return (r, q.passes());
            }
            assert!(q.passes() < 5, "more than five passes");
        }
    }

    /// Reference: sort a copy, then `percentile_sorted` (the in-memory definition). The
    /// constant-memory radix selection `check` uses gives the same bits on random streams with
    /// ties, ±0, negatives and near-equal clusters, with the production caps and with caps of
    /// 0 / a few values (every value then goes through all four 16-bit digits, or through the
    /// distinct-value count), at most five passes.
    #[test]
    fn streamed_percentiles_equal_sorted_ones_bit_for_bit() {
        use crate::numeric::stats::{percentile_sorted, sorted};
        let mut rng = SimRng::new(17);
        let caps = [(1 << 17, 4096), (0, 0), (3, 2), (0, 16), (64, 0)];
        for case in 0..240 {
            let n = 1 + rng.below(if case % 10 == 0 { 3000 } else { 150 }) as usize;
            let v = awkward_values(&mut rng, case, n);
            let sorted = sorted(&v);
            for p in [0.0, 5.0, 37.5, 50.0, 95.0, 100.0] {
                let want = percentile_sorted(&sorted, p).unwrap();
                for cap in caps {
                    let (got, _) = streamed(&v, p, cap);
                    assert_eq!(
                        got.map(f64::to_bits),
                        Some(want.to_bits()),
                        "case {case}, p {p}, n {n}, caps {cap:?}: {got:?} vs {want}"
                    );
                }
            }
        }
        assert_eq!(streamed(&[], 50.0, (0, 0)), (None, 1));
        // A long near-constant stream (a regular clock's Δt, differing in the last bits) beyond
        // the collect cap: exact from the distinct count, with the production caps, at once.
        let v: Vec<f64> = (0..300_000)
            .map(|i| ((i + 1) as f64 * 1e-3) - (i as f64 * 1e-3))
            .collect();
        let want = percentile_sorted(&sorted(&v), 50.0).unwrap();
        let (got, passes) = streamed(&v, 50.0, (1 << 17, 4096));
        assert_eq!(got.map(f64::to_bits), Some(want.to_bits()));
        assert_eq!(passes, 1);
        // Without the distinct count: the histogram passes.
        let (got, passes) = streamed(&v, 50.0, (1 << 17, 0));
        assert_eq!(got.map(f64::to_bits), Some(want.to_bits()));
        assert!(passes >= 3, "{passes}");
    }

    /// Runs [`SamplingStream`] over rows `(t, x)` pass after pass; the sampling, the passes and
    /// whether the first pass settled the clock as irregular.
    fn stream_sampling(t: &[f64], x: &[f64]) -> (Sampling, usize, bool) {
        let mut s = SamplingStream::new();
        let mut passes = 0;
        loop {
            t.iter().zip(x).for_each(|(&t, &x)| s.push(t, x));
            passes += 1;
            if !s.end_pass() {
                break;
            }
            assert!(passes < 12, "too many passes");
        }
        (s.finish().expect("finished"), passes, s.irregular)
    }

    /// Reference: [`sampling`] of the rows in memory (its quantiles by selection, themselves
    /// tested against sorting above). The streamed sampling `check` uses is the same bit for
    /// bit (every field) on dense time series (regular clock, noisy sine: the deadband pass),
    /// seek logs (irregular times), logs of a few distinct positions with ±0, negative and
    /// tiny logs, and clocks whose jitter straddles the 1 % a regular clock allows (beyond the
    /// first pass's value table, so only the exact passes can tell) or whose Δt are half
    /// regular, half spread. It also checks the passes: a seek log with irregular times ends
    /// in at most two (the first settles the clock), a clock of few distinct Δt needs no pass for the
    /// spread, and the settling happens on the seek logs (it is not a path never taken).
    #[test]
    fn streamed_sampling_equals_in_memory_sampling() {
        let mut rng = SimRng::new(23);
        let (mut dense, mut seek, mut settled) = (0, 0, 0);
        let mut jittered = [0, 0];
        for case in 0..150 {
            let n = match case % 10 {
                0 => rng.below(4) as usize,
                1 | 4 | 7 => 20_000,
                _ => 1 + rng.below(3000) as usize,
            };
            let dt = [1e-3, 0.01, 0.5][rng.below(3) as usize];
            let jitter = [0.03, 0.034, 0.04][rng.below(3) as usize];
            let mut clock = 0.0;
            let (t, x): (Vec<f64>, Vec<f64>) = (0..n)
                .map(|i| {
                    let ti = i as f64 * dt;
                    match case % 6 {
                        0 | 1 => (ti, 100.0 * (0.002 * i as f64).sin() + 0.05 * rng.normal()),
                        2 => (
                            ti + rng.range(0.0, 0.9) * dt,
                            [0.0, -0.0, -3.0, 7.5][rng.below(4) as usize],
                        ),
                        3 => (ti, rng.range(-500.0, 500.0).round()),
                        // Jitter of ±1.5–2 % of Δt at each row: median spreads of
                        // 0.3·that, 0.88–1.17 % (triangular differences), about the 1 % bar.
                        4 => (
                            ti + rng.range(-jitter, jitter) * dt * 0.5,
                            100.0 * (0.002 * i as f64).sin() + 0.05 * rng.normal(),
                        ),
                        // Every other step on the clock, the rest 1.5–3 Δt: the median Δt at
                        // the edge of the regular half.
                        _ => {
                            clock += if i % 2 == 0 {
                                dt
                            } else {
                                dt * rng.range(1.5, 3.0)
                            };
                            (clock, rng.range(-500.0, 500.0).round())
                        }
                    }
                })
                .unzip();
            let want = sampling(&t, &x);
            let (got, passes, irregular) = stream_sampling(&t, &x);
            assert_eq!(
                format!("{got:?}"),
                format!("{want:?}"),
                "case {case}, n {n}"
            );
            assert!(passes <= 6, "case {case}: {passes} passes");
            if case % 6 == 2 && n > 5000 {
                assert!(passes <= 2 && irregular, "case {case}: {passes} passes");
            }
            if case % 6 == 3 {
                // Integer positions, a clock of one Δt: every quantile from the first pass.
                assert_eq!(passes, 1, "case {case}");
            }
            settled += usize::from(irregular);
            if case % 6 == 4 && n > 1000 {
                jittered[usize::from(want.regular_clock)] += 1;
            }
            if want.dense {
                dense += 1;
            } else {
                seek += 1;
            }
        }
        assert!(dense > 20 && seek > 20, "{dense} dense, {seek} seek logs");
        assert!(settled >= 5, "{settled} logs settled as irregular");
        assert!(
            jittered[0] > 0 && jittered[1] > 0,
            "jittered clocks {jittered:?}"
        );
    }

    /// Reference: the count, in a sorted copy, of the values within `1 ± rel` of the exact
    /// percentile (`percentile_sorted`). The first pass's bound on it
    /// (`first_pass_count_near`) is never below it, on streams of ties, clusters, wide spreads
    /// and signed values, and stays well below the stream's length on wide spreads (it is a
    /// bound that can settle something).
    #[test]
    fn first_pass_count_near_bounds_the_true_count() {
        use crate::numeric::stats::{StreamPercentile, percentile_sorted, sorted};
        let mut rng = SimRng::new(29);
        for case in 0..200 {
            let n = 1 + rng.below(5000) as usize;
            let wide = case % 4 == 3;
            let v: Vec<f64> = if wide {
                (0..n).map(|_| rng.range(0.05, 0.5)).collect()
            } else {
                awkward_values(&mut rng, case, n)
            };
            let p = [5.0, 50.0, 95.0][case % 3];
            let mut q = StreamPercentile::new(p);
            v.iter().for_each(|&x| q.push(x));
            let m = percentile_sorted(&sorted(&v), p).unwrap();
            for rel in [0.0, 0.02, 0.1] {
                let Some(bound) = q.first_pass_count_near(rel) else {
                    assert!(
                        m <= 0.0 || m < 1e-300 || !wide,
                        "case {case}: no bound for {m}"
                    );
                    continue;
                };
                let (lo, hi) = (m * (1.0 - rel), m * (1.0 + rel));
                let truth = v.iter().filter(|&&x| x >= lo && x <= hi).count() as u64;
                assert!(bound >= truth, "case {case}, rel {rel}: {bound} < {truth}");
                if wide && n > 1000 && rel == 0.02 {
                    assert!(bound < n as u64 / 4, "case {case}: {bound} of {n}");
                }
            }
        }
    }

    /// Slow, obvious reference for the rest memory: keep every rest position with the time it was
    /// made, and call it crossed if any later move's closed interval [min, max] covered it.
    fn reference_nearest(moves: &[(f64, f64)], target: f64) -> (Option<f64>, Option<f64>) {
        // moves: (source, target) pairs already made, plus the candidate as the last element.
        let n = moves.len();
        let mut od: Option<f64> = None;
        let mut id: Option<f64> = None;
        // rest position i is the source of move i (made before move i+1...n-1); the candidate
        // move's source is excluded.
        for i in 0..n - 1 {
            let (p, t) = moves[i];
            if p == t {
                continue; // no move away: not a separate rest
            }
            let crossed = moves[i + 1..].iter().any(|&(a, b)| {
                let (lo, hi) = if a < b { (a, b) } else { (b, a) };
                // a move crosses p if p lies in (lo, hi], measured from its source side
                a != b && p != a && p >= lo && p <= hi
            });
            if crossed || p == target {
                continue;
            }
            if p < target {
                od = Some(od.map_or(p, |q: f64| q.max(p)));
            } else {
                id = Some(id.map_or(p, |q: f64| q.min(p)));
            }
        }
        (od.map(|p| target - p), id.map(|p| p - target))
    }

    /// Reference: [`History::step`], the full replay. The light step must give its positional
    /// features bit for bit (repeated positions, equal times, non-integer positions) and leave
    /// the history-dependent ones empty.
    #[test]
    fn light_steps_give_the_positional_features_bit_for_bit() {
        let mut rng = SimRng::new(3);
        let (mut full, mut light) = (History::new(), History::new());
        let mut t = 0.25;
        for k in 0..2000 {
            let x = if k % 7 == 0 {
                500.0
            } else {
                rng.below(1000) as f64 * 0.37
            };
            t += [0.0, 0.125, 1.0 / 3.0][rng.below(3) as usize];
            let (f, l) = (full.step(t, x), light.step_light(t, x));
            let bits = |g: &SeekFeatures| {
                [
                    g.time_s,
                    g.elapsed_s,
                    g.dwell_s,
                    g.source,
                    g.target,
                    g.seek_length,
                ]
                .map(f64::to_bits)
            };
            assert_eq!((bits(&f), f.seek_index), (bits(&l), l.seek_index), "{k}");
            assert_eq!((l.direction, l.direction_change), (0, false));
            assert_eq!(
                (l.since_reversal, l.rest_distance_od, l.rest_distance_id),
                (0.0, None, None)
            );
        }
    }

    /// Reference: the stepped replay ([`History::step_moved`] row by row, `replay_checked`).
    /// A replay reading the history columns gives every feature of every row bit for bit,
    /// with direction from position steps, a deadband and a velocity column (signs, zeros),
    /// on repeated, tied, signed-zero and non-integer positions.
    #[test]
    fn replay_from_history_columns_equals_the_stepped_one_bit_for_bit() {
        use crate::log::{ColumnMap, Log};
        use std::sync::Arc;
        for seed in 0..6 {
            let mut rng = SimRng::new(40 + seed);
            let mut text = String::from("time_s,track,bias,vel\n");
            let mut x = 500.0;
            for k in 0..5000 {
                x = match rng.below(5) {
                    0 => x,
                    1 => (x + rng.below(41) as f64 - 20.0).clamp(0.0, 1000.0),
                    2 => rng.below(1001) as f64,
                    3 => [0.0, -0.0, 0.5][rng.below(3) as usize],
                    _ => rng.below(100_000) as f64 * 0.0137,
                };
                let vel = [-1.5, 0.0, 2.0, 0.0][rng.below(4) as usize];
                let bias = if k % 3 == 0 {
                    String::new()
                } else {
                    "1".into()
                };
                text += &format!("{},{x:?},{bias},{vel}\n", k / 2);
            }
            let log = Log::from_reader("h.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
            for source in [
                DirectionSource::Steps,
                DirectionSource::Deadband { deadband: 3.0 },
                DirectionSource::Velocity {
                    column: "vel".into(),
                },
            ] {
                let velocity = source
                    .column_index(&log.schema.file, &log.schema.covariates)
                    .unwrap();
                let cols = Arc::new(HistoryColumns::build(&log, &source, velocity).unwrap());
                let stepped = replay_checked(&log, &source, velocity, false);
                let read = replay_checked(&log, &source, velocity, false)
                    .reading_columns(cols.clone(), &log);
                let mut rows = 0;
                for ((i, _, f), (j, _, g)) in stepped.zip(read) {
                    assert_eq!(i, j);
                    assert_eq!(format!("{f:?}"), format!("{g:?}"), "{source:?} row {i}");
                    let b = |h: &SeekFeatures| {
                        [
                            h.since_reversal,
                            h.rest_distance_od.unwrap_or(f64::NAN),
                            h.rest_distance_id.unwrap_or(f64::NAN),
                            h.seek_length,
                            h.elapsed_s,
                        ]
                        .map(f64::to_bits)
                    };
                    assert_eq!(b(&f), b(&g), "{source:?} row {i}");
                    rows += 1;
                }
                assert_eq!(rows, log.len());
                // A light replay ignores the columns (its features stay the light ones).
                let light = replay_checked(&log, &source, velocity, true)
                    .reading_columns(cols, &log)
                    .all(|(_, _, f)| f.rest_distance_od.is_none() && f.direction == 0);
                assert!(light);
            }
        }
    }

    /// Reference: [`History::step_moved_reference`] (peek, then the update: the rest memory
    /// scanned twice, the direction tracker asked twice). The fused step gives every feature
    /// bit for bit and leaves the same state, with position steps, a deadband and a velocity
    /// sign (including 0 and disagreeing signs), on repeated, tied and non-integer positions.
    #[test]
    fn fused_step_equals_peek_then_update_bit_for_bit() {
        for (seed, deadband) in [(1, 0.0), (2, 0.0), (3, 2.5), (4, 40.0)] {
            let mut rng = SimRng::new(seed);
            let (mut fast, mut slow) = (
                History::with_deadband(deadband),
                History::with_deadband(deadband),
            );
            let mut t = 0.0;
            let mut x = 500.0;
            for k in 0..20_000 {
                x = match rng.below(4) {
                    0 => x,
                    1 => (x + rng.below(41) as f64 - 20.0).clamp(0.0, 1000.0),
                    2 => rng.below(1001) as f64,
                    _ => rng.below(100_000) as f64 * 0.0137,
                };
                t += [0.0, 0.5, 1.0 / 3.0][rng.below(3) as usize];
                let moved = match (seed, rng.below(4)) {
                    (1 | 3, _) => None,
                    (_, 0) => Some(0),
                    (_, 1) => Some(1),
                    (_, 2) => Some(-1),
                    _ => Some(crate::history::sign(rng.normal())),
                };
                let (f, g) = (
                    fast.step_moved(t, x, moved),
                    slow.step_moved_reference(t, x, moved),
                );
                assert_eq!(format!("{f:?}"), format!("{g:?}"), "seed {seed} row {k}");
                assert_eq!(
                    (f.since_reversal.to_bits(), f.seek_length.to_bits()),
                    (g.since_reversal.to_bits(), g.seek_length.to_bits())
                );
                assert_eq!(fast.turns, slow.turns);
                assert_eq!(
                    (fast.memory.below.clone(), fast.memory.above.clone()),
                    (slow.memory.below.clone(), slow.memory.above.clone())
                );
            }
        }
    }

    #[test]
    fn rest_memory_matches_full_history_scan_on_random_histories() {
        for seed in 0..20 {
            let mut rng = SimRng::new(seed);
            let mut h = History::new();
            let mut moves: Vec<(f64, f64)> = Vec::new();
            let mut pos = 500.0;
            h.step(0.0, pos);
            for k in 1..400 {
                let target = (rng.below(60) as f64) + 470.0;
                moves.push((pos, target));
                let f = h.step(k as f64, target);
                let (od, id) = reference_nearest(&moves, target);
                assert_eq!(
                    (f.rest_distance_od, f.rest_distance_id),
                    (od, id),
                    "seed {seed} seek {k}"
                );
                pos = target;
            }
        }
    }

    #[test]
    fn table_vi_geometry_only_far_side_rests_survive() {
        // Start at 1000, rest at p, go far OD (track 0), then approach target 300 inbound: a rest
        // at 290 is crossed on the way in (the nearest ID-side rest is the start, 700 away); a
        // rest at 310 is not.
        for (p, expect_id) in [(290.0, Some(700.0)), (310.0, Some(10.0))] {
            let mut h = History::new();
            h.step(0.0, 1000.0);
            h.step(1.0, p);
            h.step(2.0, 0.0);
            let f = h.step(3.0, 300.0);
            assert_eq!(f.rest_distance_id, expect_id, "p = {p}");
        }
    }

    #[test]
    fn direction_change_and_since_reversal() {
        let mut h = History::new();
        let f0 = h.step(0.0, 10.0);
        assert_eq!(
            (f0.direction, f0.direction_change, f0.dwell_s),
            (0, false, 0.0)
        );
        let f1 = h.step(0.5, 20.0);
        assert_eq!(
            (f1.direction, f1.direction_change, f1.since_reversal),
            (1, false, 10.0)
        );
        let f2 = h.step(1.0, 25.0);
        assert_eq!((f2.direction_change, f2.since_reversal), (false, 15.0));
        let f3 = h.step(1.0, 25.0);
        assert_eq!(
            (f3.direction, f3.direction_change, f3.since_reversal),
            (1, false, 15.0)
        );
        let f4 = h.step(2.0, 5.0);
        assert_eq!(
            (f4.direction, f4.direction_change, f4.since_reversal),
            (-1, true, 20.0)
        );
        assert_eq!((f4.elapsed_s, f4.dwell_s, f4.seek_index), (2.0, 1.0, 4));
    }

    #[test]
    fn feature_names_round_trip() {
        for f in Feature::ALL {
            assert_eq!(Feature::from_name(f.name()), Some(f));
        }
        assert_eq!(Feature::from_name("nope"), None);
    }

    #[test]
    fn peek_does_not_change_state() {
        let mut h = History::new();
        h.step(0.0, 100.0);
        h.step(1.0, 200.0);
        let before = format!("{h:?}");
        let p = h.peek(2.0, 150.0);
        assert_eq!(format!("{h:?}"), before);
        assert_eq!(h.step(2.0, 150.0), p);
    }
}
