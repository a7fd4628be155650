//! The seek-history state machine: `History`, stepped row by row, and its `RestMemory` of
//! uncrossed rest positions.

use super::{DirectionTracker, SeekFeatures};

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
    pub(super) turns: DirectionTracker,
    memory: RestMemory,
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

#[cfg(test)]
mod tests {
    #![allow(clippy::float_cmp)] // positions are exact integers here; equality is meant

    use super::*;
    use crate::numeric::rng::SimRng;

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
