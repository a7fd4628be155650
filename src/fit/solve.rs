//! The one linear least-squares solve of a fit: every term's linear parameters from a
//! chunked, pattern-grouped Householder QR of the design rows ([`solve`]), with the rank test,
//! the covariance and each column's conditioning ([`Solution`]); and the RSS of a full solve
//! with one term replaced ([`slow_rss`]), the reference of the nonlinear searches.

use super::design::{ChunkStart, FixedRows, column_flags, offsets, param_label};
use super::options::CheckedFitOptions;
use crate::model::data::{FitData, FitError};
use crate::model::term::Term;
use crate::numeric::qr::{CHUNK, Groups, PatternQr, refactor_kept};
use nalgebra::DMatrix;
use std::sync::Arc;

/// The least-squares solution of one design.
#[derive(Debug, Clone)]
pub(super) struct Solution {
    pub(super) coef: Vec<f64>,
    /// Row-major p × p covariance (zero rows/cols for dropped columns).
    pub(super) cov: Vec<f64>,
    pub(super) rss: f64,
    pub(super) dropped: Vec<usize>,
    pub(super) rank: usize,
    pub(super) n: usize,
    /// Per design column (original order): its spread about its mean over the rows
    /// (√(Σ(x − x̄)²/n), the column's unit) and, for kept columns, `|R_qq| / ‖x − x̄‖`, the sine
    /// of its angle to the columns before it (1 − R² of regressing it on them is its square).
    pub(super) spread: Vec<f64>,
    pub(super) independence: Vec<Option<f64>>,
}

/// Bytes of design rows [`solve`] factorises as one chunk (its `[X y]` rows, row-major).
const SOLVE_CHUNK_BYTES: usize = 4 << 20;

/// Measured rows per chunk of [`solve`] for `p` design columns: [`SOLVE_CHUNK_BYTES`] of rows,
/// a multiple of [`CHUNK`]. Depends on `p` alone, never on the thread count.
pub(super) fn solve_chunk_rows(p: usize) -> usize {
    (SOLVE_CHUNK_BYTES / 8 / (p + 1)).max(1).div_ceil(CHUNK) * CHUNK
}

/// Design columns from which [`solve`]'s replay, not its pool, sums the rows (and merges the
/// chunks' groups): the factorisation's work grows as the square of the columns.
const REPLAY_SIDE_COLUMNS: usize = 16;

/// The row-major `[X y]` rows `rows` (`p + 1` values each, the design columns in [`solve`]'s
/// order) factorised by `qr`: its groups' columns and `R` factors, and its storage
/// ([`PatternQr::finish_groups_keeping`]). With `sums`, adds each column value to the first
/// and its square (and the response's) to the second, by position, row by row: the sums of
/// [`FixedRows::each_ordered`], bit for bit, where the rows of each call follow those of the
/// previous one in the log. `kinds[i]`: how row `i` is held ([`RowKind`]); a [`RowKind::Continues`]
/// row holds its `q` other columns' values (not in the folded runs) and its response.
fn factorise_rows(
    mut qr: PatternQr,
    rows: &[f64],
    kinds: &[RowKind],
    (p, q): (usize, usize),
    mut sums: Option<(&mut [f64], &mut [f64])>,
) -> (Groups, Vec<Vec<f64>>) {
    let mut at = 0;
    for &kind in kinds {
        if kind == RowKind::Continues {
            debug_assert!(sums.is_none(), "the sums need the whole rows");
            qr.place_continuing(&rows[at..at + q], rows[at + q]);
            at += q + 1;
            continue;
        }
        let (x, y) = (&rows[at..at + p], rows[at + p]);
        at += p + 1;
        if let Some((s, sq)) = sums.as_mut() {
            for ((&v, s), sq) in x.iter().zip(s.iter_mut()).zip(sq.iter_mut()) {
                *s += v;
                *sq += v * v;
            }
            sq[p] += y * y;
        }
        qr.place_row_known(x, y, kind == RowKind::Known);
    }
    debug_assert_eq!(at, rows.len());
    qr.finish_groups_keeping()
}

/// How [`Plan::chunks_beside_replay`] holds a design row for the factorisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RowKind {
    /// The whole row; its run columns are compared with the open run's.
    Whole,
    /// The whole row, whose run columns are those of the row before
    /// ([`FixedRows::measured_rows`]'s flag; [`PatternQr::place_row_known`]).
    Known,
    /// A row of the open run (its run columns are those of the row before, held in the same
    /// chunk): only its other columns and its response ([`PatternQr::place_continuing`]).
    Continues,
}

pub(super) fn solve(
    terms: &[Arc<dyn Term>],
    data: &FitData<'_>,
    opts: &CheckedFitOptions,
) -> Result<Solution, FitError> {
    solve_marking(terms, data, opts, None)
}

/// [`solve`], which also records in `starts` where each of its chunks of
/// [`solve_chunk_rows`] measured rows begins ([`ChunkStart`]; one per chunk, in log order).
pub(super) fn solve_marking<'a>(
    terms: &[Arc<dyn Term>],
    data: &FitData<'a>,
    opts: &CheckedFitOptions,
    starts: Option<&mut Vec<ChunkStart<'a>>>,
) -> Result<Solution, FitError> {
    let (_, p) = offsets(terms);
    let order = column_order(terms, p);
    #[cfg(test)]
    let dense = tests::DENSE_SOLVE.get();
    #[cfg(not(test))]
    let dense = false;
    let mut rows = FixedRows::new(terms, data)?;
    // Ridge rows: `sqrt(λ·‖x_j‖²)·e_j` with response 0 for every penalised column (after the
    // data rows; `colsq` is the data rows' sums of squares).
    let ridge: Vec<f64> = column_flags(terms).into_iter().map(|f| f.1).collect();
    // Penalty rows of the terms that have them (`Term::penalty`), after the ridge rows.
    let (off, _) = offsets(terms);
    let penalties: Vec<TermPenalty> = terms
        .iter()
        .zip(&off)
        .map(|(t, &o)| (o..o + t.param_count(), t.penalty()))
        .filter(|(_, rows)| !rows.is_empty())
        .collect();
    // The positions (in `order`) of the columns of piecewise-constant terms, whose runs of
    // equal rows are folded before the factorisation (not in the tests' dense reference).
    let runs: Vec<usize> = if dense {
        Vec::new()
    } else {
        terms
            .iter()
            .zip(&off)
            .filter(|(t, _)| t.caps().piecewise_constant)
            .flat_map(|(t, &o)| o..o + t.param_count())
            .filter_map(|c| order.iter().position(|&q| q == c))
            .collect()
    };
    let plan = Plan {
        runs: &runs,
        order: &order,
        ridge: &ridge,
        penalties: &penalties,
        dense,
        per_chunk: solve_chunk_rows(p),
    };
    let factorised = if data.log().measured_count() <= plan.per_chunk {
        plan.one_chunk(&mut rows, starts)
    } else {
        plan.chunks(&mut rows, starts)
    };
    solution(terms, data, opts, &order, factorised)
}

/// The design columns in the order [`solve`] factorises them: the essential ones first, so
/// that a dependency is blamed on a droppable hinge if possible.
fn column_order(terms: &[Arc<dyn Term>], p: usize) -> Vec<usize> {
    let droppable: Vec<bool> = column_flags(terms).into_iter().map(|f| f.0).collect();
    debug_assert_eq!(droppable.len(), p);
    let mut order: Vec<usize> = (0..p).filter(|&c| !droppable[c]).collect();
    order.extend((0..p).filter(|&c| droppable[c]));
    order
}

/// A term's design columns and its penalty rows ([`Term::penalty`]).
type TermPenalty = (std::ops::Range<usize>, Vec<Vec<(usize, f64)>>);

/// How [`solve_marking`] factorises the design rows: the columns' order ([`column_order`]),
/// the ridge penalty of each column, whether every row goes on all columns (the tests' dense
/// reference, [`PatternQr::dense`]) and the measured rows per chunk ([`solve_chunk_rows`]).
struct Plan<'o> {
    /// Positions in `order` of the columns whose runs of equal rows are folded
    /// ([`PatternQr::with_runs`]).
    runs: &'o [usize],
    order: &'o [usize],
    ridge: &'o [f64],
    /// Per term with a [`Term::penalty`]: its design columns and its penalty rows.
    penalties: &'o [TermPenalty],
    dense: bool,
    per_chunk: usize,
}

/// The design rows factorised by a [`Plan`], by position in its order: the `R` of `[X y]`
/// (the ridge rows included), each column's sum, its sum of squares with the ridge rows (the
/// response's last) and without them (`data_sq`), and the count of measured rows.
struct Factorised {
    r: DMatrix<f64>,
    sums: Vec<f64>,
    colsq: Vec<f64>,
    data_sq: Vec<f64>,
    n: usize,
}

impl Plan<'_> {
    /// Design columns.
    fn p(&self) -> usize {
        self.order.len()
    }

    /// Hands the ridge rows to `push` (after the data rows) and adds their squares to `colsq`
    /// (as the rank test has always seen them); returns the data rows' sums of squares.
    fn ridge_rows(&self, colsq: &mut [f64], push: &mut dyn FnMut(&[f64])) -> Vec<f64> {
        let mut xp = vec![0.0; self.p()];
        let data_sq = colsq.to_vec();
        for (q, &c) in self.order.iter().enumerate() {
            if self.ridge[c] > 0.0 && data_sq[q] > 0.0 {
                xp.fill(0.0);
                xp[q] = (self.ridge[c] * data_sq[q]).sqrt();
                push(&xp);
                colsq[q] += xp[q] * xp[q];
            }
        }
        // Penalty rows: `sqrt(s)·row`, `s` the mean data sum of squares of the term's columns.
        for (cols, rows) in self.penalties {
            let qs: Vec<usize> = cols
                .clone()
                .filter_map(|c| self.order.iter().position(|&o| o == c))
                .collect();
            let s = qs.iter().map(|&q| data_sq[q]).sum::<f64>() / qs.len().max(1) as f64;
            if !(s > 0.0 && s.is_finite()) {
                continue;
            }
            let scale = s.sqrt();
            for row in rows {
                xp.fill(0.0);
                for &(c, v) in row {
                    if let Some(&q) = qs.get(c) {
                        xp[q] += scale * v;
                    }
                }
                push(&xp);
                for (sq, v) in colsq.iter_mut().zip(&xp) {
                    *sq += v * v;
                }
            }
        }
        data_sq
    }

    /// One chunk: its factorisation, the ridge rows included (as before the chunks).
    fn one_chunk<'a>(
        &self,
        rows: &mut FixedRows<'a>,
        starts: Option<&mut Vec<ChunkStart<'a>>>,
    ) -> Factorised {
        let p = self.p();
        // Compact groups: a short log's pattern groups hold a few rows each.
        let mut qr = PatternQr::compact(p, self.dense).with_runs(self.runs);
        let (mut sums, mut colsq) = (vec![0.0; p], vec![0.0; p + 1]);
        let mut scratch = vec![0.0; p];
        if let Some(s) = starts {
            s.push(rows.start());
        }
        let n = rows.each_ordered(
            self.per_chunk,
            self.order,
            &mut sums,
            &mut colsq,
            &mut scratch,
            |x, y, known| qr.place_row_known(x, y, known),
        );
        let data_sq = self.ridge_rows(&mut colsq, &mut |x| qr.place_row(x, 0.0));
        Factorised {
            r: qr.finish().0,
            sums,
            colsq,
            data_sq,
            n,
        }
    }

    /// Chunks of `per_chunk` measured rows (boundaries fixed by the row count alone), each
    /// factorised on its own, their `R` factors stacked in chunk order into one more
    /// factorisation: the same `R` for any thread count, bit for bit (tested).
    fn chunks<'a>(
        &self,
        rows: &mut FixedRows<'a>,
        starts: Option<&mut Vec<ChunkStart<'a>>>,
    ) -> Factorised {
        let p = self.p();
        let mut merged = if self.dense {
            PatternQr::dense(p)
        } else {
            PatternQr::merging(p)
        };
        let (n, sums, mut colsq) = if rayon::current_num_threads() > 1 {
            self.chunks_beside_replay(rows, &mut merged, starts)
        } else {
            self.chunks_in_turn(rows, &mut merged, starts)
        };
        let data_sq = self.ridge_rows(&mut colsq, &mut |x| merged.place_row(x, 0.0));
        Factorised {
            r: merged.finish().0,
            sums,
            colsq,
            data_sq,
            n,
        }
    }

    /// [`Plan::chunks`] on a pool of several threads: each chunk factorised while the replay
    /// fills the next chunk's rows (`rayon::join`: on another core where the pool has one), its
    /// groups merged into `merged`. Returns the measured rows, the column sums and the sums of
    /// squares.
    fn chunks_beside_replay<'a>(
        &self,
        rows: &mut FixedRows<'a>,
        merged: &mut PatternQr,
        mut starts: Option<&mut Vec<ChunkStart<'a>>>,
    ) -> (usize, Vec<f64>, Vec<f64>) {
        let (p, per_chunk, order, dense) = (self.p(), self.per_chunk, self.order, self.dense);
        let runs = self.runs;
        let w = p + 1;
        // The column sums (the one thread's `each_ordered` sums, bit for bit, either way) go
        // to the lighter side: the replay's for a wide design (its factorisation is the
        // heavier side: `calibration`, reading the history columns, thread CPU 57 ms
        // against 35 per 10⁶ rows before), the pool's for a narrow one (`dahl`: a light
        // factorisation beside its rate's state replay), and likewise the merge of the
        // previous chunk's groups.
        let on_replay = p >= REPLAY_SIDE_COLUMNS;
        // A chunk's rows (row-major `[x y]`, or the other columns and `y`) and their kinds.
        let mut cur = (
            Vec::with_capacity(per_chunk * w),
            Vec::with_capacity(per_chunk),
        );
        let mut next = (
            Vec::with_capacity(per_chunk * w),
            Vec::with_capacity(per_chunk),
        );
        // The positions not in the folded runs (a continuing row's values).
        let rest: Vec<usize> = (0..p).filter(|q| !runs.contains(q)).collect();
        let q = rest.len();
        let mut scratch = vec![0.0; p];
        let (mut fill_sums, mut fill_colsq) = (vec![0.0; p], vec![0.0; w]);
        let (mut pool_sums, mut pool_colsq) = (vec![0.0; p], vec![0.0; w]);
        let mut fill = |rows: &mut FixedRows<'a>, (out, kinds): &mut (Vec<f64>, Vec<RowKind>)| {
            let start = starts.is_some().then(|| rows.start());
            let got = if on_replay {
                rows.each_ordered(
                    per_chunk,
                    order,
                    &mut fill_sums,
                    &mut fill_colsq,
                    &mut scratch,
                    |x, y, same| {
                        // The chunk's first row opens its factorisation's first run.
                        if same && !runs.is_empty() && !kinds.is_empty() {
                            out.extend(rest.iter().map(|&c| x[c]));
                            kinds.push(RowKind::Continues);
                        } else {
                            out.extend_from_slice(x);
                            kinds.push(if same { RowKind::Known } else { RowKind::Whole });
                        }
                        out.push(y);
                    },
                )
            } else {
                rows.measured_rows(per_chunk, |buf, y, same| {
                    out.extend(order.iter().map(|&c| buf[c]));
                    out.push(y);
                    kinds.push(if same { RowKind::Known } else { RowKind::Whole });
                })
            };
            if let (Some(s), Some(start)) = (starts.as_deref_mut(), start)
                && got > 0
            {
                s.push(start);
            }
            got
        };
        let mut n = fill(rows, &mut cur);
        // Each chunk's factorisation in the blocks of the one before (no fresh zeroed
        // blocks to fault in).
        let mut spare = Vec::new();
        let mut pending: Groups = Vec::new();
        while !cur.0.is_empty() {
            let ((groups, kept), got) = rayon::join(
                || {
                    let qr = PatternQr::compact_reusing(p, dense, std::mem::take(&mut spare))
                        .with_runs(runs);
                    let sums = (!on_replay).then_some((&mut pool_sums[..], &mut pool_colsq[..]));
                    factorise_rows(qr, &cur.0, &cur.1, (p, q), sums)
                },
                || {
                    for (cols, r) in &pending {
                        merged.place_group_r(cols, r);
                    }
                    fill(rows, &mut next)
                },
            );
            spare = kept;
            if on_replay {
                pending = groups;
            } else {
                pending.clear();
                for (cols, r) in &groups {
                    merged.place_group_r(cols, r);
                }
            }
            n += got;
            std::mem::swap(&mut cur, &mut next);
            next.0.clear();
            next.1.clear();
        }
        for (cols, r) in &pending {
            merged.place_group_r(cols, r);
        }
        // Only one side summed: the other's sums are all zero.
        if on_replay {
            (n, fill_sums, fill_colsq)
        } else {
            (n, pool_sums, pool_colsq)
        }
    }

    /// [`Plan::chunks`] on one thread: each chunk's rows straight into its factorisation (no
    /// buffer), the same chunks, so the same `R` bit for bit; its groups merged into `merged`.
    /// Returns the measured rows, the column sums and the sums of squares.
    fn chunks_in_turn<'a>(
        &self,
        rows: &mut FixedRows<'a>,
        merged: &mut PatternQr,
        mut starts: Option<&mut Vec<ChunkStart<'a>>>,
    ) -> (usize, Vec<f64>, Vec<f64>) {
        let p = self.p();
        let (mut sums, mut colsq) = (vec![0.0; p], vec![0.0; p + 1]);
        let mut n = 0;
        let mut scratch = vec![0.0; p];
        let mut spare = Vec::new();
        loop {
            let mut qr = PatternQr::compact_reusing(p, self.dense, std::mem::take(&mut spare))
                .with_runs(self.runs);
            let start = starts.is_some().then(|| rows.start());
            let got = rows.each_ordered(
                self.per_chunk,
                self.order,
                &mut sums,
                &mut colsq,
                &mut scratch,
                |x, y, known| qr.place_row_known(x, y, known),
            );
            if got == 0 {
                break;
            }
            if let (Some(s), Some(start)) = (starts.as_deref_mut(), start) {
                s.push(start);
            }
            let (groups, kept) = qr.finish_groups_keeping();
            spare = kept;
            for (cols, r) in &groups {
                merged.place_group_r(cols, r);
            }
            n += got;
        }
        (n, sums, colsq)
    }
}

/// The least-squares solution of the design factorised with its columns in the order `order`:
/// columns whose `R` diagonal falls below `rank_tolerance` × their norm are dropped (fixed at 0)
/// where their term allows it, else the fit fails naming the parameter; the kept columns are
/// re-factorised where any was dropped and solved, with the covariance `s²·R⁻¹R⁻ᵀ`, each
/// column's spread and its independence of the columns before it.
fn solution(
    terms: &[Arc<dyn Term>],
    data: &FitData<'_>,
    opts: &CheckedFitOptions,
    order: &[usize],
    factorised: Factorised,
) -> Result<Solution, FitError> {
    let Factorised {
        r,
        sums,
        colsq,
        data_sq,
        n,
    } = factorised;
    let p = order.len();
    // Σ(x − x̄)² = Σx² − (Σx)²/n, from the data rows' sums of squares (before any ridge row).
    let centred_sq: Vec<f64> = {
        let mut v = vec![0.0; p];
        for (q, &c) in order.iter().enumerate() {
            let nf = n.max(1) as f64;
            v[c] = (data_sq[q] - sums[q] * sums[q] / nf).max(0.0);
        }
        v
    };
    let mut keep = Vec::new();
    let mut dropped = Vec::new();
    for q in 0..p {
        let norm = colsq[q].sqrt();
        if norm <= 0.0 || r[(q, q)].abs() <= opts.rank_tolerance * norm {
            let (name, ok) = param_label(terms, order[q]);
            if !ok {
                return Err(FitError::RankDeficient {
                    file: data.log().schema.file.clone(),
                    param: name,
                    hint: "too few distinct positions, seeks or covariate values for this term, or two terms describing the same thing".into(),
                });
            }
            dropped.push(order[q]);
        } else {
            keep.push(q);
        }
    }
    let independence: Vec<Option<f64>> = {
        let mut v = vec![None; p];
        for &q in &keep {
            let c = order[q];
            if centred_sq[c] > 0.0 {
                v[c] = Some(r[(q, q)].abs() / centred_sq[c].sqrt());
            }
        }
        v
    };
    let spread: Vec<f64> = centred_sq
        .iter()
        .map(|s| (s / n.max(1) as f64).sqrt())
        .collect();
    let k = keep.len();
    // Re-factorise the kept columns of R (and y) when columns were dropped.
    let r = if dropped.is_empty() {
        r
    } else {
        refactor_kept(&r, &keep)
    };
    let rk = r.view((0, 0), (k, k)).clone_owned();
    let z = r.view((0, k), (k, 1)).clone_owned();
    let rss = r[(k, k)].powi(2);
    let beta = rk
        .solve_upper_triangular(&z)
        .unwrap_or_else(|| DMatrix::zeros(k, 1));
    let rinv = rk
        .solve_upper_triangular(&DMatrix::identity(k, k))
        .unwrap_or_else(|| DMatrix::zeros(k, k));
    let dof = n.saturating_sub(k).max(1) as f64;
    let s2 = rss / dof;
    let ck = &rinv * rinv.transpose() * s2;
    let mut coef = vec![0.0; p];
    let mut cov = vec![0.0; p * p];
    for (a, &qa) in keep.iter().enumerate() {
        coef[order[qa]] = beta[(a, 0)];
        for (b, &qb) in keep.iter().enumerate() {
            cov[order[qa] * p + order[qb]] = ck[(a, b)];
        }
    }
    dropped.sort_unstable();
    Ok(Solution {
        spread,
        independence,
        coef,
        cov,
        rss,
        dropped,
        rank: k,
        n,
    })
}

/// The least-squares RSS of `terms` with term `k`'s nonlinear parameter at `t` (search
/// coordinate): a full [`solve`] (every term replayed, one streaming QR); `∞` where the term
/// refuses `t` or the solve fails. The reference for
/// [`Projection::rss`](super::projection::Projection::rss).
pub(super) fn slow_rss(
    terms: &[Arc<dyn Term>],
    k: usize,
    t: f64,
    data: &FitData<'_>,
    opts: &CheckedFitOptions,
) -> f64 {
    match terms[k].with_nonlinear(t) {
        Some(term) => slow_rss_of(terms, k, &term, data, opts),
        None => f64::INFINITY,
    }
}

/// [`slow_rss`] with term `k` replaced by `term` (a version of it from [`Term::search`]).
pub(super) fn slow_rss_of(
    terms: &[Arc<dyn Term>],
    k: usize,
    term: &Arc<dyn Term>,
    data: &FitData<'_>,
    opts: &CheckedFitOptions,
) -> f64 {
    let mut trial = terms.to_vec();
    trial[k] = term.clone();
    solve(&trial, data, opts).map_or(f64::INFINITY, |s| s.rss)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{FitOptions, fit};
    use crate::model::{FittedModel, ModelSpec};

    thread_local! {
        /// Makes [`solve`] factorise every row on all columns ([`PatternQr::dense`], i.e.
        /// [`StreamingQr`] bit for bit): the reference the grouped solve is tested against.
        pub(super) static DENSE_SOLVE: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
    }

    /// `spec` fitted on `log` on a pool of `threads`, by the dense reference when `dense`.
    fn fit_on(
        spec: &ModelSpec,
        log: &crate::log::Log,
        opts: &crate::fit::CheckedFitOptions,
        threads: usize,
        dense: bool,
    ) -> FittedModel {
        crate::with_threads(threads, || {
            DENSE_SOLVE.set(dense);
            let m = fit(spec, log, opts);
            DENSE_SOLVE.set(false);
            m
        })
        .unwrap()
        .unwrap()
    }

    /// [`solve`] on a log of several chunks ([`solve_chunk_rows`]: 100,000 seeks, the
    /// `calibration` preset, three chunks): the fitted model is the same bit for bit on 1, 2
    /// and 4 threads (1: every chunk straight into its factorisation; 2 and 4: buffered and
    /// factorised beside the replay of the next — the chunk boundaries and the merge order are
    /// the same), and equals the dense reference (every chunk on all columns, [`DENSE_SOLVE`],
    /// [`StreamingQr`] merged densely) to 1e-10 relative in every parameter (of its value, or
    /// absolute below 1): both are backward-stable QR solutions of one well-conditioned
    /// problem, the rows combined in another order (measured: below 1e-12).
    #[test]
    fn chunked_solve_is_the_same_on_any_thread_count_and_equals_the_dense_one() {
        let log = crate::sim::random_log(100_000, 29);
        let spec = ModelSpec::preset("calibration").unwrap();
        let opts = FitOptions::default().check().unwrap();
        let (_, p) = {
            let data = FitData::new(&log);
            let terms: Vec<Arc<dyn Term>> = spec
                .terms
                .iter()
                .map(|t| t.prepare(&data).unwrap())
                .collect();
            offsets(&terms)
        };
        assert!(
            log.measured_count() > 2 * solve_chunk_rows(p),
            "several chunks"
        );
        let params = |m: &FittedModel| -> Vec<(String, f64)> {
            m.params().map(|p| (p.name.clone(), p.value)).collect()
        };
        let run = |threads: usize, dense: bool| fit_on(&spec, &log, &opts, threads, dense);
        let one = run(1, false);
        for threads in [2, 4] {
            let other = run(threads, false);
            let (a, b) = (params(&one), params(&other));
            assert_eq!(a.len(), b.len());
            for ((na, va), (nb, vb)) in a.iter().zip(&b) {
                assert_eq!(na, nb);
                assert_eq!(va.to_bits(), vb.to_bits(), "{threads} threads: {na}");
            }
            assert_eq!(
                one.fit.ls_rss.to_bits(),
                other.fit.ls_rss.to_bits(),
                "{threads}"
            );
            // The statistics from the static predictions, replayed chunk by chunk in parallel.
            for (a, b) in [
                (one.fit.residual_std, other.fit.residual_std),
                (one.fit.residual_rms, other.fit.residual_rms),
                (one.fit.r2, other.fit.r2),
            ] {
                assert_eq!(a.to_bits(), b.to_bits(), "{threads} threads");
            }
            assert_eq!(
                one.fit.position_range.map(|r| r.map(f64::to_bits)),
                other.fit.position_range.map(|r| r.map(f64::to_bits))
            );
        }
        let dense = run(2, true);
        let mut worst = 0.0f64;
        for ((na, va), (_, vb)) in params(&one).iter().zip(&params(&dense)) {
            assert!(va.is_finite(), "{na}");
            let rel = (va - vb).abs() / vb.abs().max(1.0);
            worst = worst.max(rel);
            assert!(rel <= 1e-10, "{na}: {va} {vb}");
        }
        eprintln!("chunked vs dense: worst relative difference {worst:e}");
    }

    /// A Preisach fit on a densely sampled log (a smooth trajectory, so the relay states hold
    /// over runs of tens to hundreds of rows): the solve folds the runs ([`PatternQr::with_runs`]),
    /// the dense reference ([`DENSE_SOLVE`]) factorises every row on all columns. Same
    /// parameters to 1e-8 relative (of the value, or absolute below 1), same RSS to 1e-10, on one
    /// chunk and on several (1 and 2 threads; the same bits on both). Measured: about 1e-11.
    #[test]
    fn a_preisach_solve_with_folded_runs_equals_the_dense_one() {
        let log = crate::fit::statistics::tests::dense_log(30_000);
        let spec = ModelSpec::parse("poly2,preisach:8").unwrap();
        let opts = FitOptions::default().check().unwrap();
        let run = |threads: usize, dense: bool| fit_on(&spec, &log, &opts, threads, dense);
        let reference = run(2, true);
        let one = run(1, false);
        for threads in [1, 2] {
            let folded = run(threads, false);
            // The same bits on one thread (whole rows) and on two (a run's rows held as their
            // other columns, `RowKind::Continues`).
            for (a, b) in folded.params().zip(one.params()) {
                assert_eq!(
                    a.value.to_bits(),
                    b.value.to_bits(),
                    "{threads}: {}",
                    a.name
                );
            }
            let rss = (folded.fit.ls_rss - reference.fit.ls_rss).abs() / reference.fit.ls_rss;
            assert!(rss <= 1e-10, "{threads} threads: RSS {rss:e}");
            let mut worst = 0.0f64;
            for (a, b) in folded.params().zip(reference.params()) {
                assert_eq!(a.name, b.name);
                let rel = (a.value - b.value).abs() / b.value.abs().max(1.0);
                worst = worst.max(rel);
                assert!(rel <= 1e-8, "{}: {} {}", a.name, a.value, b.value);
            }
            eprintln!("folded vs dense, {threads} threads: worst relative difference {worst:e}");
        }
    }

    /// The whole fit on the log where the grouped solve gave a NaN coefficient (`table:10,
    /// dahl:8` plus `memsum` or `lag:temp_lag` on the family drive `bw-sine-t`, seed 31, 3000
    /// seeks) and on the `calibration` preset: reference, the same fit with every solve dense
    /// ([`DENSE_SOLVE`], [`StreamingQr`] on all columns). Every parameter within 1e-6 relative
    /// (of its value, or absolute below 1), none NaN: the searched nonlinear parameters
    /// (`memsum.L`, `lag.tau`) sit at a minimum of the RSS, which a rounding-level change of
    /// the RSS (the rows are combined in another order) moves by ~√ε ≈ 1e-8 relative (measured
    /// 5.2e-8 for `memsum.L`, 2.1e-8 for `lag.tau`; the linear coefficients follow, ≤ 2.3e-8).
    #[test]
    fn grouped_solve_fits_as_the_dense_solve_on_the_family_log_that_gave_nan() {
        use crate::sim::family::{FamilyConfig, FamilyDrive, HiddenEffect, generate};
        let drive = FamilyDrive::member("bw-sine-t").unwrap();
        let opts = FitOptions::default().check().unwrap();
        for (effect, terms) in [
            (HiddenEffect::SummedMemory, "table:10,dahl:8,memsum"),
            (HiddenEffect::Lag, "table:10,dahl:8,lag:temp_lag"),
        ] {
            let run = generate(&FamilyConfig::new(drive.clone(), &[effect], 31, 3000)).unwrap();
            let spec = ModelSpec::parse(terms).unwrap();
            DENSE_SOLVE.set(true);
            let dense = fit(&spec, &run.log, &opts);
            DENSE_SOLVE.set(false);
            let dense = dense.unwrap();
            let grouped = fit(&spec, &run.log, &opts).unwrap();
            let mut worst = 0.0f64;
            for (a, b) in dense.params().zip(grouped.params()) {
                assert_eq!(a.name, b.name);
                assert!(b.value.is_finite(), "{terms}: {}", b.name);
                let d = (a.value - b.value).abs() / a.value.abs().max(1.0);
                worst = worst.max(d);
                assert!(d <= 1e-6, "{terms}: {} {} vs {}", a.name, a.value, b.value);
            }
            eprintln!("{terms}: worst relative difference {worst:e}");
        }
    }
}
