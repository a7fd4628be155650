//! Variable projection for the search over one term's nonlinear parameter ([`Projection`]):
//! the other terms' columns factorised once, each candidate's RSS in closed form from the sums
//! of its own columns, a full solve ([`slow_rss`]) where a column nears the rank tolerance.

use super::design::{FixedRows, column_flags, design_pass, offsets};
use super::kernels::{BLOCK, Blocked, SEARCH_BATCH, accumulate_one};
use super::options::CheckedFitOptions;
use super::solve::slow_rss;
use crate::model::data::FitData;
use crate::model::term::{SearchBasis, Seek, Term};
use crate::numeric::qr::StreamingQr;
use nalgebra::DMatrix;
use std::sync::Arc;

/// [`Projection`]'s fixed block.
enum FixedBlock {
    /// Row-major, one row of fixed columns per measured row.
    Stored(Vec<f64>),
    /// The fixed terms, replayed per pass ([`FixedRows`]).
    Streamed(Vec<Arc<dyn Term>>),
}

/// The fixed block's rows as a pass reads them, in order.
enum FixedReader<'s, 'a> {
    /// The stored block, `pf` columns wide.
    Stored { xf: &'s [f64], pf: usize },
    /// Replayed a block of rows at a time: `buf` holds rows `start..` (row-major, `pf` wide).
    Streamed {
        rows: Box<FixedRows<'a>>,
        buf: Vec<f64>,
        start: usize,
        pf: usize,
    },
}

impl FixedReader<'_, '_> {
    /// Measured rows `i..i + run` (row-major); `i` never goes back before the previous call's
    /// first row. `None` where the replay ends early (it cannot: the same rows as the stored
    /// block's).
    fn rows(&mut self, i: usize, run: usize) -> Option<&[f64]> {
        match self {
            FixedReader::Stored { xf, pf } => xf.get(i * *pf..(i + run) * *pf),
            FixedReader::Streamed {
                rows,
                buf,
                start,
                pf,
            } => {
                let pf = *pf;
                let have = *start + buf.len() / pf;
                if i + run > have {
                    // Drop the rows before `i`, then replay at least a block more.
                    let drop = (i.min(have) - *start) * pf;
                    buf.drain(..drop);
                    *start = i.min(have);
                    let need = i + run - have;
                    if rows.fill(buf, need.max(BLOCK)) < need {
                        return None;
                    }
                }
                buf.get((i - *start) * pf..(i - *start + run) * pf)
            }
        }
    }
}

/// The ridge rows of the fixed columns (those of `fixed`, or the columns `keep` of them, one
/// sum of squares `colsq` over the data rows each) whose term is penalised ([`Term::ridge`]):
/// `(column, sqrt(λ·colsq))` for each such column with a non-zero `colsq`, in column order
/// (the rows `solve` appends).
fn ridge_rows(fixed: &[Arc<dyn Term>], keep: Option<&[usize]>, colsq: &[f64]) -> Vec<(usize, f64)> {
    let flags = column_flags(fixed);
    (0..colsq.len())
        .filter_map(|c| {
            let lambda = flags[keep.map_or(c, |k| k[c])].1;
            (lambda > 0.0 && colsq[c] > 0.0).then(|| (c, (lambda * colsq[c]).sqrt()))
        })
        .collect()
}

/// A column whose residual on all the other columns is below this multiple of the rank
/// tolerance (× its norm) sends a candidate to [`slow_rss`], which decides what to drop.
const PROJECTION_MARGIN: f64 = 10.0;

/// Variable projection for the search over term `k`'s nonlinear parameter: the columns of the
/// other terms (the fixed block `Xf`, which do not depend on the searched value) are replayed
/// and factorised once (`[Xf y] = Q·[Rf z; 0 ρ]`); per candidate only term `k` is replayed,
/// accumulating `G = Xfᵀ D`, `H = Dᵀ D` and `e = Dᵀ y` for its columns `D`. With
/// `C = Rf⁻ᵀ G` (`= Qᵀ D`), the Schur complement `S = H − CᵀC = L Lᵀ` and `u = e − Cᵀ z`, the
/// RSS of `[Xf D]` is `ρ² − ‖L⁻¹ u‖²` (the same least-squares problem as
/// [`solve`](super::solve::solve)'s, in closed form). A candidate where a column would come
/// near the rank tolerance (so [`solve`](super::solve::solve) might drop it) is handed to
/// [`slow_rss`].
pub(super) struct Projection<'d, 'a> {
    k: usize,
    data: &'d FitData<'a>,
    /// Term `k`'s columns at a batch of candidate values ([`Term::search_basis`]).
    search: Box<dyn SearchBasis + 'd>,
    pf: usize,
    /// The fixed columns: stored row by row, or replayed per pass where too large.
    xf: FixedBlock,
    /// Per measured row, the response's residual `r = y − Xf·βf` on the fixed block (it takes
    /// the place of `y`).
    pub(super) y: Vec<f64>,
    rf: DMatrix<f64>,
    /// `Qᵀ r = Rf⁻ᵀ Xfᵀ r` (zero but for rounding) and `ρ² = ‖r‖² − ‖Qᵀ r‖²`.
    z: DMatrix<f64>,
    rho2: f64,
    colsq_f: Vec<f64>,
    /// Per fixed column, the squared norm of its row of `Rf⁻¹` (the closed form's rank test).
    rf_inv_sq: Vec<f64>,
    /// The RSS of every effective value evaluated so far ([`Projection::rss_many`]).
    memo: std::cell::RefCell<Vec<(u64, f64)>>,
    tol: f64,
}

impl<'d, 'a> Projection<'d, 'a> {
    /// `None` where the fast path does not apply (a ridge penalty, a term that fails to start,
    /// or a fixed block near rank deficiency): the search then uses [`slow_rss`] throughout.
    pub(super) fn new(
        terms: &'d [Arc<dyn Term>],
        k: usize,
        data: &'d FitData<'a>,
        opts: &CheckedFitOptions,
    ) -> Option<Self> {
        Self::with_budget(terms, k, data, opts, data.fixed_budget())
    }

    /// [`Projection::new`], storing the fixed block only if it takes at most `budget` bytes
    /// (else it is replayed per pass: the same rows, the same bits).
    ///
    /// Where a fixed column comes near the rank tolerance, the fixed block alone is solved as
    /// [`solve`](super::solve::solve) solves it; where that drops columns (droppable ones:
    /// `bins:position` beside a `table`), the projection is built on the columns it keeps
    /// (where they can be stored within `budget`), if every one of them clears the margin. A column dropped from
    /// the fixed block alone is dropped from the joint one at every candidate too: its residual
    /// on the columns before it can only shrink when the searched columns join them. What the
    /// searched columns do to the kept ones is the closed form's rank test, per candidate.
    fn with_budget(
        terms: &'d [Arc<dyn Term>],
        k: usize,
        data: &'d FitData<'a>,
        opts: &CheckedFitOptions,
        budget: usize,
    ) -> Option<Self> {
        Self::keeping(terms, k, data, opts, budget, None)
    }

    /// [`Projection::with_budget`] on the fixed columns `keep` (all where `None`).
    fn keeping(
        terms: &'d [Arc<dyn Term>],
        k: usize,
        data: &'d FitData<'a>,
        opts: &CheckedFitOptions,
        budget: usize,
        keep: Option<&[usize]>,
    ) -> Option<Self> {
        // A penalised fixed column brings its ridge row (below); a penalised searched term
        // would need its own, candidate by candidate, and penalty rows over several columns
        // (`Term::penalty`) only the full solve places: it decides those.
        if terms[k].ridge() > 0.0 || terms.iter().any(|t| !t.penalty().is_empty()) {
            return None;
        }
        let fixed: Vec<Arc<dyn Term>> = terms
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != k)
            .map(|(_, t)| t.clone())
            .collect();
        let (_, p_all) = offsets(&fixed);
        let pf = keep.map_or(p_all, <[usize]>::len);
        if pf == 0 {
            return None;
        }
        let m = data.log().measured_count();
        let store = m
            .saturating_mul(pf)
            .saturating_mul(std::mem::size_of::<f64>())
            <= budget;
        if keep.is_some() && !store {
            // The streamed block replays every fixed column: the full solve decides.
            return None;
        }
        let mut xf = Vec::with_capacity(if store { m * pf } else { 0 });
        let mut y = Vec::with_capacity(m);
        let mut qr = StreamingQr::new(pf);
        let mut kept = vec![0.0; pf];
        design_pass(&fixed, data, |x, v| {
            let x = match keep {
                Some(keep) => {
                    for (o, &c) in kept.iter_mut().zip(keep) {
                        *o = x[c];
                    }
                    &kept[..]
                }
                None => x,
            };
            if store {
                xf.extend_from_slice(x);
            }
            y.push(v);
            qr.push(x, v);
        })
        .ok()?;
        // The ridge rows of the penalised fixed columns (`sqrt(λ·‖x_j‖²)·e_j`, response 0, after
        // the data rows, as `solve` places them): the searched term is 0 on them.
        let ridge = ridge_rows(&fixed, keep, &qr.column_squares()[..pf]);
        for (c, v) in &ridge {
            let mut x = vec![0.0; pf];
            x[*c] = *v;
            qr.push(&x, 0.0);
        }
        let (r, colsq_f) = qr.finish();
        let tol = opts.rank_tolerance;
        for q in 0..pf {
            let norm = colsq_f[q].sqrt();
            if !(norm > 0.0 && r[(q, q)].abs() > PROJECTION_MARGIN * tol * norm) {
                if keep.is_some() {
                    return None;
                }
                // What the full solve of the fixed block alone keeps (an error: a column it
                // may not drop; nothing dropped: a column near the tolerance it keeps).
                let sol = super::solve::solve(&fixed, data, opts).ok()?;
                if sol.dropped.is_empty() {
                    return None;
                }
                let keep: Vec<usize> = (0..p_all).filter(|c| !sol.dropped.contains(c)).collect();
                return Self::keeping(terms, k, data, opts, budget, Some(&keep));
            }
        }
        let rf = r.view((0, 0), (pf, pf)).clone_owned();
        let beta = rf.solve_upper_triangular(&r.view((0, pf), (pf, 1)).clone_owned())?;
        // The response is replaced by its residual on the fixed block (the same least-squares
        // problem: `y − Xf·βf` differs from `y` by a combination of the fixed columns), so the
        // per-candidate sums `Dᵀ r` are small where `Dᵀ y` would cancel against `Cᵀ z`. What
        // the fixed block still explains of it (`w = Rf⁻ᵀ Xfᵀ r`, rounding) is kept exactly.
        let mut xr = Blocked::new(pf + 1);
        let mut sums = vec![0.0; pf + 1];
        let mut residual = |x: &[f64], yv: &mut f64| {
            *yv -= x.iter().zip(beta.iter()).map(|(a, b)| a * b).sum::<f64>();
            for (s, &a) in sums.iter_mut().zip(x) {
                *s = a * *yv;
            }
            sums[pf] = *yv * *yv;
            xr.add(&sums);
        };
        let xf = if store {
            for (x, yv) in xf.chunks_exact(pf).zip(y.iter_mut()) {
                residual(x, yv);
            }
            FixedBlock::Stored(xf)
        } else {
            // The same rows again, in the same order (a replay is deterministic).
            let mut rows = y.iter_mut();
            let mut short = false;
            design_pass(&fixed, data, |x, _| match rows.next() {
                Some(yv) => residual(x, yv),
                None => short = true,
            })
            .ok()?;
            if short || rows.next().is_some() {
                return None;
            }
            FixedBlock::Streamed(fixed)
        };
        // The ridge rows' residuals `0 − v·βf_c` (no measured row: `y` has none).
        for &(c, v) in &ridge {
            let rv = -(v * beta[c]);
            sums.fill(0.0);
            sums[c] = v * rv;
            sums[pf] = rv * rv;
            xr.add(&sums);
        }
        let xr = xr.total();
        let w = rf
            .transpose()
            .solve_lower_triangular(&DMatrix::from_column_slice(pf, 1, &xr[..pf]))?;
        let rf_inv_sq = {
            let inv = rf.solve_upper_triangular(&DMatrix::identity(pf, pf))?;
            (0..pf).map(|j| inv.row(j).norm_squared()).collect()
        };
        Some(Self {
            k,
            data,
            search: terms[k].search_basis(data),
            pf,
            xf,
            y,
            rf,
            rho2: xr[pf] - w.norm_squared(),
            z: w,
            colsq_f: colsq_f[..pf].to_vec(),
            rf_inv_sq,
            memo: std::cell::RefCell::new(Vec::new()),
            tol,
        })
    }

    /// A reader of the fixed block's rows for one pass; `None` where its terms fail to start.
    fn reader(&self) -> Option<FixedReader<'_, 'a>> {
        Some(match &self.xf {
            FixedBlock::Stored(xf) => FixedReader::Stored { xf, pf: self.pf },
            FixedBlock::Streamed(fixed) => FixedReader::Streamed {
                rows: Box::new(FixedRows::new(fixed, self.data).ok()?),
                buf: Vec::with_capacity(BLOCK * self.pf),
                start: 0,
                pf: self.pf,
            },
        })
    }

    /// The RSS at `t`; equal to [`slow_rss`] up to rounding (tested).
    #[cfg(test)]
    fn rss(&self, terms: &[Arc<dyn Term>], t: f64, opts: &CheckedFitOptions) -> f64 {
        self.rss_many(terms, &[t], opts)[0]
    }

    /// The RSS at each of `ts`: [`Projection::fast_rss_many`], [`slow_rss`] where it cannot
    /// decide.
    /// Values whose [`SearchBasis::effective_value`] was evaluated before take the RSS found
    /// then (the same columns, so the same bits); the others are evaluated once each.
    pub(super) fn rss_many(
        &self,
        terms: &[Arc<dyn Term>],
        ts: &[f64],
        opts: &CheckedFitOptions,
    ) -> Vec<f64> {
        let key = |t: f64| self.search.effective_value(t).to_bits();
        let known = |memo: &[(u64, f64)], t: f64| {
            let k = key(t);
            memo.iter().find(|(m, _)| *m == k).map(|&(_, v)| v)
        };
        let mut memo = self.memo.borrow_mut();
        let mut new: Vec<f64> = Vec::new();
        for &t in ts {
            if known(&memo, t).is_none() && !new.iter().any(|&n| key(n) == key(t)) {
                new.push(t);
            }
        }
        for batch in new.chunks(SEARCH_BATCH) {
            let fast = self.fast_rss_many(terms, batch);
            for (&t, f) in batch.iter().zip(fast) {
                let v = f.unwrap_or_else(|| slow_rss(terms, self.k, t, self.data, opts));
                memo.push((key(t), v));
            }
        }
        ts.iter()
            .map(|&t| known(&memo, t).unwrap_or(f64::INFINITY))
            .collect()
    }

    /// [`Projection::fast_rss`] at each of `ts`, the searched term's columns for all of them
    /// from one replay ([`SearchBasis::replay`], in batches of [`SEARCH_BATCH`] values, a short
    /// batch padded with its last value) and the sums of each accumulated exactly as
    /// [`Projection::fast_rss`] accumulates them (the same bits, tested).
    fn fast_rss_many(&self, terms: &[Arc<dyn Term>], ts: &[f64]) -> Vec<Option<f64>> {
        let mut result = vec![None; ts.len()];
        // Values the term refuses get `None` (the slow path gives `∞`).
        let ok: Vec<usize> = (0..ts.len())
            .filter(|&i| terms[self.k].with_nonlinear(ts[i]).is_some())
            .collect();
        let w = terms[self.k].param_count();
        for batch in ok.chunks(SEARCH_BATCH) {
            let mut vals: Vec<f64> = batch.iter().map(|&i| ts[i]).collect();
            let last = vals[vals.len() - 1];
            vals.resize(SEARCH_BATCH, last);
            let Some(sums) = self.sums_many(&vals, w) else {
                continue;
            };
            for (&i, all) in batch.iter().zip(sums) {
                result[i] = self.closed_form(&all, w);
            }
        }
        result
    }

    /// For each of the [`SEARCH_BATCH`] values `vals`, the sums `G = Xfᵀ D`, `H = Dᵀ D`,
    /// `e = Dᵀ r` (concatenated, row-major), in blocks of [`BLOCK`] measured rows as
    /// [`Projection::fast_rss`] takes them; the lanes of one value are the value-major
    /// accumulators `acc[j · SEARCH_BATCH + c]`.
    fn sums_many(&self, vals: &[f64], w: usize) -> Option<Vec<Vec<f64>>> {
        const L: usize = SEARCH_BATCH;
        let pf = self.pf;
        let n_acc = pf * w + w * w + w;
        let mut acc = vec![0.0; n_acc * L];
        let mut totals: Vec<Blocked> = (0..L).map(|_| Blocked::new(n_acc)).collect();
        let mut i = 0;
        let mut xf = self.reader()?;
        let mut short = false;
        self.search
            .replay(vals, &mut |block: &[f64], rows: usize| {
                if short {
                    return;
                }
                if w == 1 {
                    // Runs of rows up to the next flush, each added by one call of the kernel.
                    let mut j = 0;
                    while j < rows {
                        let run = (BLOCK - i % BLOCK).min(rows - j);
                        let Some(x) = xf.rows(i, run) else {
                            short = true;
                            return;
                        };
                        accumulate_one(
                            &mut acc,
                            x,
                            &self.y[i..i + run],
                            &block[j * L..(j + run) * L],
                        );
                        i += run;
                        j += run;
                        if i % BLOCK == 0 {
                            for (c, t) in totals.iter_mut().enumerate() {
                                t.flush_lane(&mut acc, L, c);
                            }
                        }
                    }
                    return;
                }
                for d in block.chunks_exact(L * w).take(rows) {
                    let Some(x) = xf.rows(i, 1) else {
                        short = true;
                        return;
                    };
                    let yv = self.y[i];
                    for b in 0..w {
                        for c in 0..L {
                            let db = d[c * w + b];
                            for (a, &xa) in x.iter().enumerate() {
                                acc[(a * w + b) * L + c] += xa * db;
                            }
                            for e in 0..w {
                                acc[(pf * w + b * w + e) * L + c] += db * d[c * w + e];
                            }
                            acc[(pf * w + w * w + b) * L + c] += db * yv;
                        }
                    }
                    i += 1;
                    if i % BLOCK == 0 {
                        for (c, t) in totals.iter_mut().enumerate() {
                            t.flush_lane(&mut acc, L, c);
                        }
                    }
                }
            })?;
        if short {
            return None;
        }
        Some(
            totals
                .iter_mut()
                .enumerate()
                .map(|(c, t)| {
                    t.flush_lane(&mut acc, L, c);
                    t.total()
                })
                .collect(),
        )
    }

    /// The closed-form RSS, or `None` where [`slow_rss`] must decide (including where the term
    /// refuses `t`: the slow path gives `∞` then). Row by row through [`TermState`]: the
    /// reference [`Projection::fast_rss_many`] is tested against.
    #[cfg(test)]
    fn fast_rss(&self, terms: &[Arc<dyn Term>], t: f64) -> Option<f64> {
        self.fast_rss_of(&terms[self.k].with_nonlinear(t)?)
    }

    /// [`Projection::fast_rss`] with the searched term replaced by `term`.
    pub(super) fn fast_rss_of(&self, term: &Arc<dyn Term>) -> Option<f64> {
        let w = term.param_count();
        let pf = self.pf;
        let log = self.data.log();
        let mut st = term.start(&log.schema.covariates).ok()?;
        let mut d = vec![0.0; w];
        // The sums of one block of rows, added to `total` every BLOCK rows (summation error
        // about that of a block plus that of the block sums, not that of 10⁶ terms in a row).
        let mut g = vec![0.0; pf * w];
        let mut h = vec![0.0; w * w];
        let mut e = vec![0.0; w];
        let mut total = Blocked::new(pf * w + w * w + w);
        let mut i = 0;
        let mut cov = Vec::new();
        let mut xf = self.reader()?;
        for (_, row, f) in self.data.replay_for(std::slice::from_ref(term)) {
            let seek = Seek {
                features: &f,
                covariates: row.covariates.gather(&mut cov),
            };
            if row.bias.is_some() {
                st.basis(&seek, &mut d);
                let (x, yv) = (xf.rows(i, 1)?, self.y[i]);
                if w == 1 {
                    // One column (the searched Dahl element): the same sums, without the
                    // index arithmetic.
                    let db = d[0];
                    for (ga, &xa) in g.iter_mut().zip(x) {
                        *ga += xa * db;
                    }
                    h[0] += db * db;
                    e[0] += db * yv;
                    i += 1;
                    if i % BLOCK == 0 {
                        total.flush(&mut [&mut g, &mut h, &mut e]);
                    }
                    st.update(&seek, None);
                    continue;
                }
                for (b, &db) in d.iter().enumerate() {
                    for (a, &xa) in x.iter().enumerate() {
                        g[a * w + b] += xa * db;
                    }
                    for (c, &dc) in d.iter().enumerate() {
                        h[b * w + c] += db * dc;
                    }
                    e[b] += db * yv;
                }
                i += 1;
                if i % BLOCK == 0 {
                    total.flush(&mut [&mut g, &mut h, &mut e]);
                }
            }
            st.update(&seek, None);
        }
        total.flush(&mut [&mut g, &mut h, &mut e]);
        self.closed_form(&total.total(), w)
    }

    /// The RSS from the sums `G`, `H`, `e` of the searched term's `w` columns (concatenated),
    /// or `None` where a column nears the rank tolerance (see [`Projection`]).
    fn closed_form(&self, all: &[f64], w: usize) -> Option<f64> {
        let pf = self.pf;
        let (g, rest) = all.split_at(pf * w);
        let (h, e) = rest.split_at(w * w);
        let g = DMatrix::from_row_slice(pf, w, g);
        let h = DMatrix::from_row_slice(w, w, h);
        let e = DMatrix::from_column_slice(w, 1, e);
        let c = self.rf.transpose().solve_lower_triangular(&g)?;
        let s = &h - c.transpose() * &c;
        let u = e - c.transpose() * &self.z;
        let l = s.clone().cholesky()?.unpack();
        let v = l.solve_lower_triangular(&u)?;
        let rss = self.rho2 - v.norm_squared();
        // No column may come near the rank tolerance: its residual on all the others,
        // 1/‖row of R⁻¹‖ for the joint R = [Rf C; 0 Lᵀ], bounds its R diagonal in any order.
        // R⁻¹ = [Rf⁻¹, −Rf⁻¹ C L⁻ᵀ; 0, L⁻ᵀ]: the rows of Rf⁻¹ are the same for every candidate
        // (their squared norms kept), so a candidate costs O(pf²·w), not O((pf + w)³).
        let lt_inv = l
            .transpose()
            .solve_upper_triangular(&DMatrix::identity(w, w))?;
        let m = self.rf.solve_upper_triangular(&c)? * &lt_inv;
        for j in 0..pf + w {
            let (colsq, norm_sq) = if j < pf {
                (self.colsq_f[j], self.rf_inv_sq[j] + m.row(j).norm_squared())
            } else {
                (h[(j - pf, j - pf)], lt_inv.row(j - pf).norm_squared())
            };
            let resid = 1.0 / norm_sq.sqrt();
            if !(colsq > 0.0 && resid > PROJECTION_MARGIN * self.tol * colsq.sqrt()) {
                return None;
            }
        }
        (rss.is_finite() && rss >= 0.0).then_some(rss)
    }

    /// [`Projection::closed_form`] with the rank test on the whole `R⁻¹` of the joint
    /// `R = [Rf C; 0 Lᵀ]` (inverted per candidate): the slow, obvious reference.
    #[cfg(test)]
    fn closed_form_reference(&self, all: &[f64], w: usize) -> Option<f64> {
        let pf = self.pf;
        let (g, rest) = all.split_at(pf * w);
        let (h, e) = rest.split_at(w * w);
        let g = DMatrix::from_row_slice(pf, w, g);
        let h = DMatrix::from_row_slice(w, w, h);
        let e = DMatrix::from_column_slice(w, 1, e);
        let c = self.rf.transpose().solve_lower_triangular(&g)?;
        let s = &h - c.transpose() * &c;
        let u = e - c.transpose() * &self.z;
        let l = s.clone().cholesky()?.unpack();
        let v = l.solve_lower_triangular(&u)?;
        let rss = self.rho2 - v.norm_squared();
        let p = pf + w;
        let mut r = DMatrix::zeros(p, p);
        r.view_mut((0, 0), (pf, pf)).copy_from(&self.rf);
        r.view_mut((0, pf), (pf, w)).copy_from(&c);
        r.view_mut((pf, pf), (w, w)).copy_from(&l.transpose());
        let rinv = r.solve_upper_triangular(&DMatrix::identity(p, p))?;
        for j in 0..p {
            let colsq = if j < pf {
                self.colsq_f[j]
            } else {
                h[(j - pf, j - pf)]
            };
            let resid = 1.0 / rinv.row(j).norm();
            if !(colsq > 0.0 && resid > PROJECTION_MARGIN * self.tol * colsq.sqrt()) {
                return None;
            }
        }
        (rss.is_finite() && rss >= 0.0).then_some(rss)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::FitOptions;
    use crate::model::ModelSpec;
    use crate::model::terms::intercept::InterceptTerm;
    use crate::numeric::rng::SimRng;
    use crate::numeric::search::{golden_min, golden_min_batched};

    /// The search as it was before variable projection: every candidate a full
    /// [`solve`](super::solve::solve).
    fn slow_search(
        terms: &[Arc<dyn Term>],
        k: usize,
        data: &FitData<'_>,
        opts: &CheckedFitOptions,
    ) -> (f64, f64) {
        let f = |t: f64| slow_rss(terms, k, t, data, opts);
        let (t, ft, _) = golden_min(&f, 0.0, 1.0, opts.grid, opts.refine);
        (t, ft)
    }

    /// The variable-projection RSS of every candidate against the full solve per candidate
    /// (the reference, [`slow_rss`]), and the searched rate against the slow search's, on
    /// simulated logs (three seeds; integer tracks and tracks scaled to non-integers, where
    /// the Dahl decay is not tabulated; with and without more fixed columns; and `stribeck`,
    /// whose velocity scale is searched the same way).
    #[test]
    fn projected_search_equals_full_solve_per_candidate() {
        let opts = FitOptions::default().check().unwrap();
        let (mut projected, mut worst) = (0, 0.0_f64);
        for seed in [1, 2, 7] {
            let mut log = crate::sim::random_log(4000, seed);
            if seed == 2 {
                for x in log.tracks_mut() {
                    *x *= 0.37;
                }
            }
            if seed == 7 {
                // Unmeasured rows: the block sums' runs break where the rows do not.
                for i in (3..log.len()).step_by(5) {
                    log.set_bias(i, None);
                }
            }
            for text in ["dahl", "poly2,seek,dahl", "poly2,stribeck"] {
                let spec = ModelSpec::parse(text).unwrap();
                let data = FitData::new(&log);
                let mut terms = spec
                    .terms
                    .iter()
                    .map(|t| t.prepare(&data))
                    .collect::<Result<Vec<_>, _>>()
                    .unwrap();
                if !terms.iter().any(|t| t.caps().provides_intercept) {
                    terms.insert(0, Arc::new(InterceptTerm));
                }
                let k = terms.iter().position(|t| t.nonlinear().is_some()).unwrap();
                let proj = Projection::new(&terms, k, &data, &opts).expect("fast path applies");
                let mut rng = SimRng::new(seed);
                let ts: Vec<f64> = (0..=20)
                    .map(|i| i as f64 / 20.0)
                    .chain((0..20).map(|_| rng.uniform()))
                    .collect();
                // The batched sums (the searched term's block replay, candidates side by
                // side) against the same sums taken row by row through `TermState`: bit for bit.
                // The closed form's rank test from the kept rows of `Rf⁻¹` against the whole
                // `R⁻¹` inverted per candidate: the same RSS and decision, at the candidates
                // and where the searched column nears a fixed one (`d = x_j·(1 + δ)` in sums).
                let w = terms[k].param_count();
                let bits = |v: Option<f64>| v.map(f64::to_bits);
                for chunk in ts.chunks(SEARCH_BATCH) {
                    let mut vals = chunk.to_vec();
                    vals.resize(SEARCH_BATCH, chunk[chunk.len() - 1]);
                    for all in proj.sums_many(&vals, w).into_iter().flatten() {
                        let (a, b) = (
                            proj.closed_form(&all, w),
                            proj.closed_form_reference(&all, w),
                        );
                        assert_eq!(bits(a), bits(b), "{text} seed {seed}");
                    }
                }
                if w == 1 {
                    let gram = proj.rf.transpose() * &proj.rf;
                    let mut decided = [0, 0];
                    for j in 0..proj.pf {
                        for delta in [1e-20, 1e-14, 1e-10, 1e-6, 1e-2] {
                            let mut all: Vec<f64> = gram.column(j).iter().copied().collect();
                            all.push(gram[(j, j)] * (1.0 + delta));
                            all.push(0.5);
                            let (a, b) = (
                                proj.closed_form(&all, 1),
                                proj.closed_form_reference(&all, 1),
                            );
                            assert_eq!(bits(a), bits(b), "{text} seed {seed} column {j} δ {delta}");
                            decided[usize::from(a.is_some())] += 1;
                        }
                    }
                    assert!(decided[0] > 0 && decided[1] > 0, "{text}: {decided:?}");
                }
                let many = proj.fast_rss_many(&terms, &ts);
                for (&t, m) in ts.iter().zip(&many) {
                    let one = proj.fast_rss(&terms, t);
                    assert_eq!(
                        m.map(f64::to_bits),
                        one.map(f64::to_bits),
                        "{text} seed {seed} t {t}"
                    );
                }
                for &t in &ts {
                    let slow = slow_rss(&terms, k, t, &data, &opts);
                    let fast = proj.rss(&terms, t, &opts);
                    assert!(slow.is_finite() && slow > 0.0, "{text} seed {seed} t {t}");
                    assert!(
                        (fast - slow).abs() <= 1e-9 * slow,
                        "{text} seed {seed} t {t}: {fast} vs {slow}"
                    );
                    projected += usize::from(proj.fast_rss(&terms, t).is_some());
                    worst = worst.max((fast - slow).abs() / slow);
                }
                // The per-row projected RSS, one candidate at a time, no memo.
                let f = |t: f64| {
                    proj.fast_rss(&terms, t)
                        .unwrap_or_else(|| slow_rss(&terms, k, t, &data, &opts))
                };
                let (t_fast, f_fast, ev) = golden_min(&f, 0.0, 1.0, opts.grid, opts.refine);
                // What the fit runs: the batched search (candidates side by side, values the
                // term rounds alike evaluated once), the same point, value and count.
                let batched = golden_min_batched(
                    &|ts: &[f64]| proj.rss_many(&terms, ts, &opts),
                    0.0,
                    1.0,
                    opts.grid,
                    opts.refine,
                );
                assert_eq!(
                    (t_fast.to_bits(), f_fast.to_bits(), ev),
                    (batched.0.to_bits(), batched.1.to_bits(), batched.2),
                    "{text} seed {seed}"
                );
                let (t_slow, f_slow) = slow_search(&terms, k, &data, &opts);
                let at_fast = slow_rss(&terms, k, t_fast, &data, &opts);
                assert!(
                    t_fast.to_bits() == t_slow.to_bits()
                        || (at_fast - f_slow).abs() <= 1e-12 * f_slow,
                    "{text} seed {seed}: rate {t_fast} vs {t_slow}, RSS {at_fast} vs {f_slow}"
                );
            }
        }
        // The closed form (not the fallback) answered nearly every candidate.
        assert!(projected >= 300, "{projected} of 369");
        // Observed: 1.2e-14 (the full solve's own rounding); 1e-12 leaves room for other CPUs.
        assert!(
            worst <= 1e-12,
            "largest relative RSS difference {worst:.1e}"
        );
    }

    /// `memsum`'s length and a `lag:` term's τ are searched by variable projection. Reference:
    /// the full solve per candidate ([`slow_rss`]) and the search run on it ([`golden_min`]).
    /// On family logs with the summed-memory and the lagged-temperature effect (two seeds,
    /// beside a narrow and a wide fixed block), every candidate's projected RSS equals the full
    /// solve's to 1e-9, and the fit's batched search ends where the full solves' does (or at
    /// an RSS equal to 1e-12: the searched value is then within the search's own tolerance,
    /// 40 golden-section steps, of a flat minimum).
    #[test]
    fn memsum_and_lag_searches_by_projection_equal_full_solves() {
        use crate::sim::family::{FamilyConfig, FamilyDrive, HiddenEffect, generate};
        let opts = FitOptions::default().check().unwrap();
        let drive = FamilyDrive::member("bw-sine-t").unwrap();
        let (mut checked, mut worst) = (0, 0.0_f64);
        for seed in [3, 8] {
            for (effect, texts) in [
                (
                    HiddenEffect::SummedMemory,
                    [
                        "poly2,direction,memsum",
                        "table,direction,seek,dahl:4,play:8,memsum",
                    ],
                ),
                (
                    HiddenEffect::Lag,
                    [
                        "poly2,direction,lag:temp_lag",
                        "table,direction,seek,dahl:4,play:8,lag:temp_lag",
                    ],
                ),
            ] {
                let run =
                    generate(&FamilyConfig::new(drive.clone(), &[effect], seed, 2000)).unwrap();
                for text in texts {
                    let spec = ModelSpec::parse(text).unwrap();
                    let data = FitData::new(&run.log);
                    let mut terms = spec
                        .terms
                        .iter()
                        .map(|t| t.prepare(&data))
                        .collect::<Result<Vec<_>, _>>()
                        .unwrap();
                    if !terms.iter().any(|t| t.caps().provides_intercept) {
                        terms.insert(0, Arc::new(InterceptTerm));
                    }
                    let k = terms.iter().position(|t| t.nonlinear().is_some()).unwrap();
                    assert!(terms[k].caps().search_by_projection, "{text}");
                    let proj = Projection::new(&terms, k, &data, &opts).expect("fast path applies");
                    let nl = terms[k].nonlinear().unwrap();
                    let ts: Vec<f64> = (0..=16)
                        .map(|i| nl.lo + (nl.hi - nl.lo) * f64::from(i) / 16.0)
                        .collect();
                    for &t in &ts {
                        let slow = slow_rss(&terms, k, t, &data, &opts);
                        let fast = proj.fast_rss(&terms, t).expect("closed form");
                        assert!(
                            (fast - slow).abs() <= 1e-9 * slow,
                            "{text} seed {seed} at {t}: {fast} vs {slow}"
                        );
                        worst = worst.max((fast - slow).abs() / slow);
                        checked += 1;
                    }
                    let (t_fast, _, _) = golden_min_batched(
                        &|ts: &[f64]| proj.rss_many(&terms, ts, &opts),
                        nl.lo,
                        nl.hi,
                        opts.grid,
                        opts.refine,
                    );
                    let f = |t: f64| slow_rss(&terms, k, t, &data, &opts);
                    let (t_slow, f_slow, _) = golden_min(&f, nl.lo, nl.hi, opts.grid, opts.refine);
                    let at_fast = f(t_fast);
                    assert!(
                        t_fast.to_bits() == t_slow.to_bits()
                            || (at_fast - f_slow).abs() <= 1e-12 * f_slow,
                        "{text} seed {seed}: {t_fast} vs {t_slow}, RSS {at_fast} vs {f_slow}"
                    );
                }
            }
        }
        assert_eq!(checked, 2 * 4 * 17);
        eprintln!("memsum and lag: largest relative RSS difference {worst:.1e}");
    }

    /// A fixed block that the full solve of it alone leaves short of columns (`bins:position`
    /// beside a `table`: the solve drops hinges): the projection is built on the columns that
    /// solve keeps. Reference: the full solve per candidate ([`slow_rss`]) and the search run on
    /// it ([`golden_min`]). On family logs with the summed-memory and the lagged-temperature
    /// effect, the fixed block alone must drop columns (else the case is not tested), every
    /// candidate's projected RSS (where the closed form decides: at least 3 in 4) equals the
    /// full solve's to 1e-9, and the batched search ends where the full solves' does (or at an
    /// RSS equal to 1e-12).
    #[test]
    fn projection_on_the_columns_a_rank_deficient_fixed_block_keeps() {
        use crate::sim::family::{FamilyConfig, FamilyDrive, HiddenEffect, generate};
        let opts = FitOptions::default().check().unwrap();
        let drive = FamilyDrive::member("bw-sine-t").unwrap();
        let (mut checked, mut decided) = (0, 0);
        for (effect, text, searched) in [
            (
                HiddenEffect::SummedMemory,
                "table,direction,seek,memory,dahl:4,memsum,play:8,bins:position:16",
                "memsum",
            ),
            (
                HiddenEffect::Lag,
                "table,direction,seek,memory,dahl:4,play:8,lag:temp_lag,bins:position:4",
                "lag:temp_lag",
            ),
        ] {
            let run = generate(&FamilyConfig::new(drive.clone(), &[effect], 5, 2000)).unwrap();
            let spec = ModelSpec::parse(text).unwrap();
            let data = FitData::new(&run.log);
            let mut terms = spec
                .terms
                .iter()
                .map(|t| t.prepare(&data))
                .collect::<Result<Vec<_>, _>>()
                .unwrap();
            if !terms.iter().any(|t| t.caps().provides_intercept) {
                terms.insert(0, Arc::new(InterceptTerm));
            }
            let k = terms.iter().position(|t| t.name() == searched).unwrap();
            let fixed: Vec<Arc<dyn Term>> = (0..terms.len())
                .filter(|&j| j != k)
                .map(|j| terms[j].clone())
                .collect();
            let alone = crate::fit::solve::solve(&fixed, &data, &opts).unwrap();
            assert!(!alone.dropped.is_empty(), "{text}: nothing dropped");
            let proj = Projection::new(&terms, k, &data, &opts).expect("fast path applies");
            assert_eq!(proj.pf, offsets(&fixed).1 - alone.dropped.len());
            let nl = terms[k].nonlinear().unwrap();
            let ts: Vec<f64> = (0..=16)
                .map(|i| nl.lo + (nl.hi - nl.lo) * f64::from(i) / 16.0)
                .collect();
            for &t in &ts {
                let slow = slow_rss(&terms, k, t, &data, &opts);
                checked += 1;
                let Some(fast) = proj.fast_rss(&terms, t) else {
                    continue;
                };
                decided += 1;
                assert!(
                    (fast - slow).abs() <= 1e-9 * slow,
                    "{text} at {t}: {fast} vs {slow}"
                );
            }
            let (t_fast, _, _) = golden_min_batched(
                &|ts: &[f64]| proj.rss_many(&terms, ts, &opts),
                nl.lo,
                nl.hi,
                opts.grid,
                opts.refine,
            );
            let f = |t: f64| slow_rss(&terms, k, t, &data, &opts);
            let (t_slow, f_slow, _) = golden_min(&f, nl.lo, nl.hi, opts.grid, opts.refine);
            let at_fast = f(t_fast);
            assert!(
                t_fast.to_bits() == t_slow.to_bits() || (at_fast - f_slow).abs() <= 1e-12 * f_slow,
                "{text}: {t_fast} vs {t_slow}, RSS {at_fast} vs {f_slow}"
            );
        }
        assert!(4 * decided >= 3 * checked, "{decided} of {checked} decided");
    }

    /// A fixed block over the budget is replayed per pass instead of stored: every RSS the
    /// projection gives (batched, row by row, and of `bump`'s own versions) and its residual
    /// equal the stored block's bit for bit (the reference: the stored block, itself tested
    /// against full solves above), on simulated logs with and without unmeasured rows (the
    /// replayed rows skip them as the stored ones do) and longer than several row blocks.
    #[test]
    fn streamed_fixed_block_equals_the_stored_one() {
        let opts = FitOptions::default().check().unwrap();
        for seed in [1, 7] {
            let mut log = crate::sim::random_log(3000, seed);
            if seed == 7 {
                for i in (3..log.len()).step_by(5) {
                    log.set_bias(i, None);
                }
            }
            let [lo, hi] = crate::numeric::stats::range(log.tracks()).unwrap();
            for text in ["dahl", "poly2,seek,dahl", "poly2,direction,bump"] {
                let spec = ModelSpec::parse(text).unwrap();
                let data = FitData::new(&log);
                let mut terms = spec
                    .terms
                    .iter()
                    .map(|t| t.prepare(&data))
                    .collect::<Result<Vec<_>, _>>()
                    .unwrap();
                if !terms.iter().any(|t| t.caps().provides_intercept) {
                    terms.insert(0, Arc::new(InterceptTerm));
                }
                let k = terms
                    .iter()
                    .position(|t| t.caps().search_by_projection)
                    .unwrap();
                let stored = Projection::with_budget(&terms, k, &data, &opts, usize::MAX)
                    .expect("fast path applies");
                let streamed =
                    Projection::with_budget(&terms, k, &data, &opts, 0).expect("fast path applies");
                assert!(matches!(stored.xf, FixedBlock::Stored(_)), "{text}");
                assert!(matches!(streamed.xf, FixedBlock::Streamed(_)), "{text}");
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&stored.y), bits(&streamed.y), "{text}");
                assert_eq!(stored.rho2.to_bits(), streamed.rho2.to_bits(), "{text}");
                // Candidate rates for `dahl`, centres across the tracks for `bump`.
                let ts: Vec<f64> = (0..=12)
                    .map(|i| f64::from(i) / 12.0)
                    .map(|u| {
                        if text.ends_with("bump") {
                            lo + (hi - lo) * u
                        } else {
                            u
                        }
                    })
                    .collect();
                let as_bits = |v: Vec<Option<f64>>| {
                    v.into_iter()
                        .map(|x| x.map(f64::to_bits))
                        .collect::<Vec<_>>()
                };
                let many = as_bits(stored.fast_rss_many(&terms, &ts));
                assert!(
                    many.iter().any(Option::is_some),
                    "{text}: nothing to compare"
                );
                assert_eq!(many, as_bits(streamed.fast_rss_many(&terms, &ts)), "{text}");
                for &t in &ts {
                    if let Some(version) = terms[k].with_nonlinear(t) {
                        assert_eq!(
                            stored.fast_rss_of(&version).map(f64::to_bits),
                            streamed.fast_rss_of(&version).map(f64::to_bits),
                            "{text} at {t}"
                        );
                    }
                }
            }
        }
    }
}
