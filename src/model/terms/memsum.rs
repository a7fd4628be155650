//! `memsum`: summed-kernel rest memory. Where `memory` looks only at the nearest
//! uncrossed rest position ahead, `memsum` lets **every** uncrossed earlier rest position p
//! contribute, signed by the side it lies on and fading with its distance:
//!
//! `b = A · Σ_p sgn(x − p) · exp(−|x − p| / L)`
//!
//! (x the target; a rest on the OD side, p < x, counts +1, one on the ID side −1; the source of
//! the seek is not yet a rest position, exactly as for
//! [`SeekFeatures::rest_distance_od`](crate::history::SeekFeatures::rest_distance_od)). `A` is
//! linear (counts, fitted by least squares; its sign says which way the ridges push), the length
//! scale `L` (in the log's position unit) is the term's nonlinear parameter, searched by variable
//! projection on `ln L` over `[travel/500, travel]`, where travel is the range of positions the
//! training log visits (so the range follows the log, never an absolute unit).
//!
//! **State, O(1) amortised per seek.** The uncrossed rest positions are the two stacks of
//! [`RestMemory`](crate::history::RestMemory) (positions below the head, nearest on top; above
//! it, nearest on top; a move pops what it crosses and pushes its source). Each stack entry
//! also keeps the kernel sum of itself and everything beneath it **as seen from that entry**,
//! `c_i = 1 + exp(−|p_i − p_{i−1}|/L)·c_{i−1}`; a stack's whole sum at x is then one
//! multiplication, `exp(−|x − p_top|/L)·c_top` (the stacks are sorted, so every term shares the
//! factor). A push or pop is O(1) and each position is pushed and popped at most once, so a
//! seek costs amortised O(1); [`TermState::basis`] looks past the entries the move will pop,
//! which [`TermState::update`] then pops. Relative sums never overflow, whatever the positions.

use crate::model::ModelError;
use crate::model::cue::{Answer, Cue};
use crate::model::data::{FitData, FitError};
use crate::model::term::{
    Nonlinear, Param, SearchBasis, Seek, Term, TermCaps, TermSpec, TermState, se_from_cov,
};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The head of the term's spec text (`memsum`).
pub(crate) const HEAD: &str = "memsum";

/// Spec of the `memsum` term.
#[derive(Debug, Clone, Copy)]
pub struct MemsumSpec;

impl TermSpec for MemsumSpec {
    fn name(&self) -> String {
        HEAD.into()
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let positions: Vec<f64> = data.log().rows().map(|r| r.track).collect();
        let travel = crate::numeric::stats::range(&positions)
            .map(|[lo, hi]| hi - lo)
            .filter(|t| *t > 0.0)
            .ok_or_else(|| FitError::BadSetting {
                term: HEAD.into(),
                why: "the log never moves, so no rest position is ever left behind".into(),
            })?;
        let (lo, hi) = ((travel / 500.0).ln(), travel.ln());
        Ok(Arc::new(MemsumTerm {
            length: (0.5 * (lo + hi)).exp(),
            ln_lo: lo,
            ln_hi: hi,
        }))
    }
}

/// The fitted `memsum` term.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MemsumTerm {
    /// Kernel length scale L, in the log's position unit.
    pub length: f64,
    /// Lower end of the `ln L` search interval.
    pub ln_lo: f64,
    /// Upper end of the `ln L` search interval.
    pub ln_hi: f64,
}

impl Term for MemsumTerm {
    fn caps(&self) -> TermCaps {
        TermCaps {
            // The projected RSS and the search on it are tested against a full solve per
            // candidate (`fit::projection`'s memsum and lag test).
            search_by_projection: true,
            ..TermCaps::DEFAULT
        }
    }
    fn name(&self) -> String {
        HEAD.into()
    }
    fn param_names(&self) -> Vec<String> {
        vec!["A".into()]
    }
    fn start(&self, _covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        Ok(Box::new(MemsumState::new(self.length)))
    }
    fn nonlinear(&self) -> Option<Nonlinear> {
        Some(Nonlinear {
            name: "ln_L".into(),
            value: self.length.ln(),
            lo: self.ln_lo,
            hi: self.ln_hi,
        })
    }
    fn search_basis<'d>(&'d self, data: &'d FitData<'_>) -> Box<dyn SearchBasis + 'd> {
        Box::new(MemsumSearch { term: self, data })
    }
    fn with_nonlinear(&self, t: f64) -> Option<Arc<dyn Term>> {
        Some(Arc::new(MemsumTerm {
            length: t.clamp(self.ln_lo, self.ln_hi).exp(),
            ..self.clone()
        }))
    }
    /// `memsum.A` (counts, the bias of one rest position at distance 0 on the OD side) and
    /// `memsum.L` (position unit; standard error by the delta method from that of `ln L`).
    fn report(&self, coef: &[f64], cov: &[f64], nl_se: Option<f64>) -> Vec<Param> {
        vec![
            Param {
                name: "memsum.A".into(),
                value: coef[0],
                se: se_from_cov(cov, 1, 0),
            },
            Param {
                name: "memsum.L".into(),
                value: self.length,
                se: nl_se.map(|s| s * self.length),
            },
        ]
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
}

/// One stack entry: a rest position and the kernel sum of it and every entry beneath it, seen
/// from it.
#[derive(Debug, Clone, Copy)]
struct Entry {
    p: f64,
    c: f64,
}

/// The running state of [`MemsumTerm`]: two sorted stacks with relative kernel sums (see the
/// module docs). Public so a predictor or a bench can use it directly.
#[derive(Debug, Clone)]
pub struct MemsumState {
    inv_l: f64,
    /// Below the head (smaller positions), nearest on top.
    below: Vec<Entry>,
    /// Above the head (larger positions), nearest on top.
    above: Vec<Entry>,
}

impl MemsumState {
    /// An empty memory with kernel length `length` (> 0, the log's position unit).
    pub fn new(length: f64) -> Self {
        Self {
            inv_l: 1.0 / length,
            below: Vec::new(),
            above: Vec::new(),
        }
    }

    fn kernel(&self, d: f64) -> f64 {
        (-d.abs() * self.inv_l).exp()
    }

    /// Σ sgn(x − p)·exp(−|x − p|/L) over the rests that remain after a move from `source` to
    /// `x` (before `source` is remembered), without changing the state. Costs O(1 + number of
    /// positions the move crosses).
    pub fn value_after_move(&self, source: f64, x: f64) -> f64 {
        let below = if x < source {
            self.below.iter().rev().find(|e| e.p < x)
        } else {
            self.below.last()
        };
        let above = if x > source {
            self.above.iter().rev().find(|e| e.p > x)
        } else {
            self.above.last()
        };
        let side = |e: Option<&Entry>| e.map_or(0.0, |e| self.kernel(x - e.p) * e.c);
        side(below) - side(above)
    }

    /// Applies a move from `source` to `x`: forgets the rest positions it crosses or lands on
    /// and remembers `source` behind the head. A zero-length move changes nothing.
    pub fn apply_move(&mut self, source: f64, x: f64) {
        if x > source {
            while self.above.last().is_some_and(|e| e.p <= x) {
                self.above.pop();
            }
            let c = 1.0
                + self
                    .below
                    .last()
                    .map_or(0.0, |e| self.kernel(source - e.p) * e.c);
            self.below.push(Entry { p: source, c });
        } else if x < source {
            while self.below.last().is_some_and(|e| e.p >= x) {
                self.below.pop();
            }
            let c = 1.0
                + self
                    .above
                    .last()
                    .map_or(0.0, |e| self.kernel(e.p - source) * e.c);
            self.above.push(Entry { p: source, c });
        }
    }

    /// Number of remembered rest positions.
    pub fn len(&self) -> usize {
        self.below.len() + self.above.len()
    }

    /// Whether no rest position is remembered.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl TermState for MemsumState {
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        let f = seek.features;
        out[0] = self.value_after_move(f.source, f.target);
    }
    fn update(&mut self, seek: &Seek<'_>, _residual: Option<f64>) {
        self.apply_move(seek.features.source, seek.features.target);
    }
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(self.clone())
    }
}

/// Measured rows per block [`MemsumSearch`] hands its sink.
const SEARCH_BLOCK: usize = 256;

/// Longest whole distance whose kernel [`MemsumSearch`] tabulates per searched length.
const KERNEL_TABLE: usize = 4096;

/// The search basis of `memsum`'s length ([`SearchBasis`]): one pair of stacks for every
/// searched length at once — which rest positions a move pops or pushes does not depend on the
/// length, only the relative kernel sums do, kept per length beside each entry — read from the
/// log's positions directly (a seek's source is the previous row's target, the first row's
/// its own), and the kernel of a whole distance taken from a table per length (the same
/// expression, so the same bits). The same values, bit for bit, as [`MemsumState`] gives row
/// by row (tested against the per-row replay).
struct MemsumSearch<'d, 'a> {
    term: &'d MemsumTerm,
    data: &'d FitData<'a>,
}

/// [`MemsumSearch`]'s stacks: positions, and per entry one relative sum per searched length.
struct Stacks {
    lanes: usize,
    below: Vec<f64>,
    below_c: Vec<f64>,
    above: Vec<f64>,
    above_c: Vec<f64>,
}

impl SearchBasis for MemsumSearch<'_, '_> {
    fn replay(&self, values: &[f64], sink: &mut dyn FnMut(&[f64], usize)) -> Option<()> {
        let log = self.data.log();
        let (tracks, bias) = (log.tracks(), log.bias_raw());
        let n = values.len();
        // 1/L as the state computes it from the term at each value.
        let inv_l: Vec<f64> = values
            .iter()
            .map(|&v| 1.0 / v.clamp(self.term.ln_lo, self.term.ln_hi).exp())
            .collect();
        // Whole positions: the kernel of each whole distance below the table's end, per length.
        let whole = tracks.iter().all(|x| x.fract() == 0.0);
        let span = crate::numeric::stats::range(tracks).map_or(0.0, |[lo, hi]| hi - lo);
        let len = if whole && span < KERNEL_TABLE as f64 {
            span as usize + 1
        } else {
            0
        };
        let mut table = vec![0.0; len * n];
        for (lane, &il) in inv_l.iter().enumerate() {
            for d in 0..len {
                table[lane * len + d] = (-(d as f64) * il).exp();
            }
        }
        let kernel = |d: f64, lane: usize| {
            let a = d.abs();
            if a < len as f64 && a.fract() == 0.0 {
                table[lane * len + a as usize]
            } else {
                (-a * inv_l[lane]).exp()
            }
        };
        let mut st = Stacks {
            lanes: n,
            below: Vec::new(),
            below_c: Vec::new(),
            above: Vec::new(),
            above_c: Vec::new(),
        };
        let mut block = vec![0.0; SEARCH_BLOCK * n];
        let mut rows = 0;
        let mut source = tracks.first().copied().unwrap_or(0.0);
        for (&x, &b) in tracks.iter().zip(bias) {
            if !b.is_nan() {
                st.values(source, x, &kernel, &mut block[rows * n..(rows + 1) * n]);
                rows += 1;
                if rows == SEARCH_BLOCK {
                    sink(&block, rows);
                    rows = 0;
                }
            }
            st.apply(source, x, &kernel);
            source = x;
        }
        if rows > 0 {
            sink(&block[..rows * n], rows);
        }
        Some(())
    }
}

impl Stacks {
    /// [`MemsumState::value_after_move`] at every length (`out[lane]`).
    fn values(&self, source: f64, x: f64, kernel: &dyn Fn(f64, usize) -> f64, out: &mut [f64]) {
        let below = if x < source {
            self.below.iter().rposition(|&p| p < x)
        } else {
            self.below.len().checked_sub(1)
        };
        let above = if x > source {
            self.above.iter().rposition(|&p| p > x)
        } else {
            self.above.len().checked_sub(1)
        };
        let n = self.lanes;
        for (lane, o) in out.iter_mut().enumerate() {
            let side = |e: Option<usize>, ps: &[f64], cs: &[f64]| {
                e.map_or(0.0, |i| kernel(x - ps[i], lane) * cs[i * n + lane])
            };
            *o = side(below, &self.below, &self.below_c) - side(above, &self.above, &self.above_c);
        }
    }

    /// [`MemsumState::apply_move`] at every length.
    fn apply(&mut self, source: f64, x: f64, kernel: &dyn Fn(f64, usize) -> f64) {
        let n = self.lanes;
        if x > source {
            while self.above.last().is_some_and(|&p| p <= x) {
                self.above.pop();
                self.above_c.truncate(self.above.len() * n);
            }
            let top = self.below.len().checked_sub(1);
            for lane in 0..n {
                let c = 1.0
                    + top.map_or(0.0, |i| {
                        kernel(source - self.below[i], lane) * self.below_c[i * n + lane]
                    });
                self.below_c.push(c);
            }
            self.below.push(source);
        } else if x < source {
            while self.below.last().is_some_and(|&p| p >= x) {
                self.below.pop();
                self.below_c.truncate(self.below.len() * n);
            }
            let top = self.above.len().checked_sub(1);
            for lane in 0..n {
                let c = 1.0
                    + top.map_or(0.0, |i| {
                        kernel(self.above[i] - source, lane) * self.above_c[i * n + lane]
                    });
                self.above_c.push(c);
            }
            self.above.push(source);
        }
    }
}

/// Parses `memsum` (no argument); the registry's parser.
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    t.no_arg(Arc::new(MemsumSpec))
}

/// The pattern `memsum` answers: the summed memory (first when even; it has no direction).
pub(crate) fn answers(cue: Cue) -> Option<Answer> {
    match cue {
        Cue::SummedMemory(signed) => Answer::fixed(if signed { 1 } else { 0 }),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::rng::SimRng;

    /// The slow, obvious reference: every rest position ever made, with the index of the move
    /// that made it; a rest counts if no later move's closed interval covered it (the
    /// candidate move included) and it is not the candidate's source. O(n) per seek, O(n²)
    /// per history.
    fn reference(moves: &[(f64, f64)], l: f64) -> f64 {
        let (source, x) = moves[moves.len() - 1];
        let mut sum = 0.0;
        for (i, &(p, t)) in moves[..moves.len() - 1].iter().enumerate() {
            // The rest made by move i is its source p, remembered only if the head left it.
            let left = (t - p).abs() > 0.0;
            let covered = moves[i + 1..].iter().any(|&(a, b)| {
                let (lo, hi) = (a.min(b), a.max(b));
                hi > lo && p >= lo && p <= hi
            });
            let is_source = (p - source).abs() <= 0.0;
            if left && !covered && !is_source {
                sum += (x - p).signum() * (-(x - p).abs() / l).exp();
            }
        }
        sum
    }

    /// `memsum`'s search basis keeps one pair of stacks for every searched length and reads a
    /// table for whole distances ([`MemsumSearch`]). Reference: the default per-row replay of
    /// the term's state (`PerRowSearch`: `basis` then `update` through the history replay).
    /// Every value bit for bit, at lengths across and beyond the search interval, on a log of
    /// whole tracks (the table) and one of fractional positions (no table), with unmeasured
    /// rows (their moves still change the memory) and repeated positions.
    #[test]
    fn memsum_search_basis_equals_the_per_row_replay() {
        use crate::model::term::{PerRowSearch, SearchBasis};
        for whole in [true, false] {
            let mut rng = SimRng::new(4);
            let mut text = String::from("time_s,track,bias\n");
            for k in 0..3000 {
                let x = if whole {
                    rng.below(200) as f64
                } else {
                    rng.range(0.0, 200.0)
                };
                text += &format!("{:?},{x:?},{:?}\n", 0.3 * k as f64, rng.normal());
            }
            let mut log =
                crate::log::Log::from_reader("m.csv", text.as_bytes(), &Default::default())
                    .unwrap();
            for i in (2..log.len()).step_by(5) {
                log.set_bias(i, None);
            }
            let data = FitData::new(&log);
            let term = MemsumSpec.prepare(&data).unwrap();
            let nl = term.nonlinear().unwrap();
            let values: Vec<f64> = (0..8)
                .map(|i| nl.lo - 1.0 + (nl.hi - nl.lo + 2.0) * f64::from(i) / 7.0)
                .collect();
            let collect = |basis: &dyn SearchBasis| {
                let mut out = Vec::new();
                basis
                    .replay(&values, &mut |block, n| {
                        out.extend(block[..n * values.len()].iter().map(|v| v.to_bits()));
                    })
                    .unwrap();
                out
            };
            let fast = collect(&*term.search_basis(&data));
            let slow = collect(&PerRowSearch {
                term: &*term,
                data: &data,
            });
            assert_eq!(fast.len(), log.measured_count() * values.len());
            assert!(fast == slow, "whole tracks: {whole}");
        }
    }

    /// Reference: [`reference`], a full scan of the history at every seek. The stacks with
    /// relative sums must agree to rounding on random histories: whole tracks with repeats and
    /// zero-length moves, and real-valued positions, for short and long kernels.
    #[test]
    fn fast_state_matches_full_history_scan() {
        for seed in 0..12u64 {
            let mut rng = SimRng::new(seed);
            let l = [0.7, 5.0, 40.0][seed as usize % 3];
            let whole = seed % 2 == 0;
            let mut state = MemsumState::new(l);
            let mut moves: Vec<(f64, f64)> = Vec::new();
            let mut pos = 500.0;
            for k in 0..300 {
                let x = if whole {
                    470.0 + rng.below(61) as f64
                } else {
                    pos + rng.range(-25.0, 25.0)
                };
                moves.push((pos, x));
                let fast = state.value_after_move(pos, x);
                let slow = reference(&moves, l);
                assert!(
                    (fast - slow).abs() <= 1e-9 * (1.0 + slow.abs()),
                    "seed {seed} seek {k}: fast {fast}, reference {slow}"
                );
                state.apply_move(pos, x);
                pos = x;
            }
        }
    }

    /// Reference: by hand. Rest at 100 (left for 150), then back to 120: the rest at 100 is on
    /// the OD side, 20 away; 150 is the source, not yet a rest.
    #[test]
    fn one_rest_by_hand() {
        let mut s = MemsumState::new(10.0);
        s.apply_move(100.0, 150.0);
        let v = s.value_after_move(150.0, 120.0);
        assert!((v - (-2.0f64).exp()).abs() < 1e-15);
        s.apply_move(150.0, 120.0);
        // Now 150 is a rest on the ID side (30 away) and 100 on the OD side (20 away).
        let v = s.value_after_move(120.0, 120.0);
        assert!((v - ((-2.0f64).exp() - (-3.0f64).exp())).abs() < 1e-15);
        // Crossing 150 and landing at 160 leaves only 100 (60 away) and not 120 (the source).
        let v = s.value_after_move(120.0, 160.0);
        assert!((v - (-6.0f64).exp()).abs() < 1e-15);
    }
}
