//! The features of one seek's history (`SeekFeatures`) and their names (`Feature`).

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

    /// Where the motion last reversed direction (`reversal_position`): the turning point
    /// `since_reversal` is measured from, `target − direction·since_reversal`, tracks (the
    /// target itself before the head has moved).
    pub fn reversal_position(&self) -> f64 {
        self.target - f64::from(self.direction) * self.since_reversal
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
    /// `reversal_position`: where the motion last reversed direction (the turning point
    /// `since_reversal` is measured from), tracks; the target itself before any reversal.
    ReversalPosition,
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
    pub const ALL: [Feature; 12] = [
        Feature::Position,
        Feature::SeekLength,
        Feature::SeekAbs,
        Feature::Direction,
        Feature::DirectionChange,
        Feature::SinceReversal,
        Feature::ReversalPosition,
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
            Feature::ReversalPosition => "reversal_position",
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
            Feature::ReversalPosition => Some(self.reversal_position()),
            Feature::RestDistanceOd => self.rest_distance_od,
            Feature::RestDistanceId => self.rest_distance_id,
            Feature::DwellS => Some(self.dwell_s),
            Feature::ElapsedS => Some(self.elapsed_s),
            Feature::SeekIndex => Some(self.seek_index as f64),
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::float_cmp)] // positions are exact integers here; equality is meant

    use super::*;

    /// Reference: the turning points read off the targets alone — the target before each
    /// non-zero move whose sign differs from the last non-zero move's, the first target
    /// before any reversal — on a seeded random walk with zero-length moves and long runs.
    #[test]
    fn reversal_position_is_the_last_turning_point() {
        let mut rng = crate::numeric::rng::SimRng::new(33);
        let mut h = super::super::History::new();
        let mut x = 500.0;
        let (mut last_sign, mut turn, mut prev) = (0.0f64, x, x);
        for k in 0..2000 {
            if k > 0 {
                x += rng.below(41) as f64 - 20.0;
            }
            let f = h.step(k as f64 * 0.1, x);
            let sign = (x - prev).signum() * f64::from(u8::from(x != prev));
            if sign != 0.0 {
                if last_sign != 0.0 && sign != last_sign {
                    turn = prev;
                }
                last_sign = sign;
            }
            prev = x;
            assert_eq!(f.value(Feature::ReversalPosition), Some(turn), "row {k}");
        }
    }

    #[test]
    fn feature_names_round_trip() {
        for f in Feature::ALL {
            assert_eq!(Feature::from_name(f.name()), Some(f));
        }
        assert_eq!(Feature::from_name("nope"), None);
    }
}
