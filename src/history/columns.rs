//! The history-column cache: the history-dependent features of every row of a long log,
//! kept compactly after one replay.

use super::{DirectionSource, SeekFeatures};

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
    pub(super) flags: Vec<u8>,
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
    pub(super) fn fill(&self, i: usize, x: &[f64], f: &mut SeekFeatures) {
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

#[cfg(test)]
mod tests {
    #![allow(clippy::float_cmp)] // positions are exact integers here; equality is meant

    use super::*;
    use crate::history::replay_checked;
    use crate::numeric::rng::SimRng;

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
}
