//! Fitting a [`ModelSpec`] to a measurement log.
//!
//! 1. **Prepare**: every [`TermSpec`](crate::model::term::TermSpec) looks at the training data
//!    once ([`FitData`]) and fixes its knots/centring; an `intercept` is added unless a term
//!    spans a constant.
//! 2. **One linear least-squares solve** for all linear parameters of all terms: the basis rows
//!    of the measured rows are streamed through a chunked Householder QR (TSQR: the running
//!    `R` factor stacked on 1024 new rows, re-factorised), so memory is O(p²) and nothing like
//!    normal equations is ever formed; rows sparse in recurring patterns are factorised per
//!    pattern on their non-zero columns ([`PatternQr`]). Terms supply centred/scaled columns (`poly2` uses
//!    `(x − centre)/scale`, hinges are divided by their largest knot). Columns whose `R`
//!    diagonal falls below `rank_tolerance` × their norm cannot be determined from the log:
//!    for hinge terms they are fixed at 0 with a warning, otherwise the fit fails naming the
//!    parameter. Covariance `s²·R⁻¹R⁻ᵀ`, `s² = RSS/(n − rank)`.
//! 3. **Variable projection** for a term's nonlinear parameter (the Dahl rate): a 1-D search
//!    (grid, then golden section) on the least-squares RSS with the linear parameters refitted
//!    at each candidate. The other terms' columns are factorised once and each candidate's RSS
//!    comes in closed form from its own columns' sums (`Projection`; a full solve where a column
//!    nears the rank tolerance); the chosen value is then solved in full. Its standard error
//!    comes from the curvature of the RSS (three full solves). A term that searches its own
//!    parameters ([`Term::search`], `bump`'s centre and width) is handed the residual of the
//!    other terms and this RSS for any version of itself instead.
//! 4. **Causal offsets** (`drift`) are tuned on the residual series of the other terms.
//! 5. The fitted model is replayed causally over the training log for the fit statistics
//!    (only its adaptive terms, over the others' stored prediction, where those read nothing
//!    but residuals: [`adaptive_tail`]).

use crate::field::Field;
use crate::log::Log;
use crate::model::term::{Param, SearchBasis, Seek, Term};
use crate::model::terms::intercept::InterceptTerm;
use crate::model::{ColumnsUsed, FittedModel, FittedTerm, ModelSpec};
use nalgebra::DMatrix;
use std::sync::Arc;

pub use crate::model::data::{FitData, FitError, FitReport};

/// Fit settings as given (unchecked). [`FitOptions::check`] validates them once into the
/// [`CheckedFitOptions`] that [`fit`] accepts (linfa's `ParamGuard` pattern).
///
/// ```
/// use biasctl::FitOptions;
/// let opts = FitOptions { grid: 48, ..FitOptions::default() }.check().unwrap();
/// assert_eq!(opts.grid, 48);
/// assert!(FitOptions { rank_tolerance: f64::NAN, ..FitOptions::default() }.check().is_err());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct FitOptions {
    /// Relative size of an `R` diagonal below which a column is called undetermined; in (0, 1)
    /// (default 1e-9).
    pub rank_tolerance: f64,
    /// Grid points of the nonlinear search before golden-section refinement, 3..=10000
    /// (default 24).
    pub grid: usize,
    /// Golden-section iterations, 0..=1000 (default 40).
    pub refine: usize,
    /// How the direction of motion is read (`--deadband X`, `--velocity-col NAME`; default:
    /// a deadband estimated from the position noise on a dense time series, raw steps on a
    /// log of seeks). The fitted model records what it resolved to.
    pub direction: crate::history::DirectionSetting,
}

impl FitOptions {
    /// Checks every setting's range; the error names the setting and what is allowed.
    pub fn check(self) -> Result<CheckedFitOptions, FitError> {
        let bad = |field, message: String| Err(FitError::InvalidOptions { field, message });
        if !(self.rank_tolerance > 0.0 && self.rank_tolerance < 1.0) {
            return bad(
                Field::RankTolerance,
                format!("{} is not in (0, 1)", self.rank_tolerance),
            );
        }
        if !(3..=10_000).contains(&self.grid) {
            return bad(Field::Grid, format!("{} is not in 3..=10000", self.grid));
        }
        if self.refine > 1000 {
            return bad(Field::Refine, format!("{} is not in 0..=1000", self.refine));
        }
        self.direction.validate()?;
        Ok(CheckedFitOptions(self))
    }
}

checked_settings! {
    /// Fit settings that passed [`FitOptions::check`]; the only settings [`fit`] accepts. Read
    /// them through `Deref` ([`FitOptions`]'s fields). `Default` is the checked default.
    #[derive(Debug, Clone, PartialEq, Default)]
    pub struct CheckedFitOptions(FitOptions);
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            rank_tolerance: 1e-9,
            grid: 24,
            refine: 40,
            direction: crate::history::DirectionSetting::Auto,
        }
    }
}

/// Minimises `f` on [lo, hi]: `grid` evenly spaced points, then `iters` golden-section steps
/// in the bracket around the best. Returns (x, f(x), evaluations).
pub(crate) fn golden_min(
    f: &dyn Fn(f64) -> f64,
    lo: f64,
    hi: f64,
    grid: usize,
    iters: usize,
) -> (f64, f64, usize) {
    let g = grid.max(3);
    let xs: Vec<f64> = (0..g)
        .map(|i| lo + (hi - lo) * i as f64 / (g - 1) as f64)
        .collect();
    let fs: Vec<f64> = xs.iter().map(|&x| f(x)).collect();
    let mut evals = g;
    let best = (0..g).min_by(|&a, &b| fs[a].total_cmp(&fs[b])).unwrap_or(0);
    let (mut a, mut b) = (xs[best.saturating_sub(1)], xs[(best + 1).min(g - 1)]);
    let (mut bx, mut bf) = (xs[best], fs[best]);
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - phi * (b - a);
    let mut d = a + phi * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    evals += 2;
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - phi * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + phi * (b - a);
            fd = f(d);
        }
        evals += 1;
    }
    for (x, v) in [(c, fc), (d, fd)] {
        if v < bf {
            bx = x;
            bf = v;
        }
    }
    (bx, bf, evals)
}

/// Golden-section iterations [`golden_min_batched`] looks ahead: it evaluates every point the
/// next `SPECULATE` iterations may need (at most 2^SPECULATE − 1) in one batch.
const SPECULATE: u32 = 3;

/// [`golden_min`] for an objective that evaluates a batch of points at once (cheaper per point
/// than one at a time): the same points compared in the same order, so the same result and the
/// same count of evaluations (tested), but each golden-section step whose point is not yet known
/// evaluates, in one batch, that point and every point the next iterations may ask for whichever
/// way their comparisons go ([`SPECULATE`] iterations deep; the grid is one batch too). The
/// evaluations counted are those [`golden_min`] makes; the speculative ones are not.
pub(crate) fn golden_min_batched(
    f: &dyn Fn(&[f64]) -> Vec<f64>,
    lo: f64,
    hi: f64,
    grid: usize,
    iters: usize,
) -> (f64, f64, usize) {
    let g = grid.max(3);
    let xs: Vec<f64> = (0..g)
        .map(|i| lo + (hi - lo) * i as f64 / (g - 1) as f64)
        .collect();
    let fs = f(&xs);
    let mut evals = g;
    let best = (0..g).min_by(|&a, &b| fs[a].total_cmp(&fs[b])).unwrap_or(0);
    let (mut a, mut b) = (xs[best.saturating_sub(1)], xs[(best + 1).min(g - 1)]);
    let (mut bx, mut bf) = (xs[best], fs[best]);
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - phi * (b - a);
    let mut d = a + phi * (b - a);
    let mut known = Golden {
        phi,
        memo: Vec::new(),
    };
    let mut pts = vec![c, d];
    known.explore([a, b, c, d], [None, None], iters, SPECULATE - 1, &mut pts);
    known.evaluate(f, pts);
    let (mut fc, mut fd) = (known.get(c), known.get(d));
    evals += 2;
    for left in (0..iters).rev() {
        // `left`: iterations after this one.
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - phi * (b - a);
            if known.lookup(c).is_none() {
                let mut pts = vec![c];
                known.explore(
                    [a, b, c, d],
                    [None, Some(fd)],
                    left,
                    SPECULATE - 1,
                    &mut pts,
                );
                known.evaluate(f, pts);
            }
            fc = known.get(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + phi * (b - a);
            if known.lookup(d).is_none() {
                let mut pts = vec![d];
                known.explore(
                    [a, b, c, d],
                    [Some(fc), None],
                    left,
                    SPECULATE - 1,
                    &mut pts,
                );
                known.evaluate(f, pts);
            }
            fd = known.get(d);
        }
        evals += 1;
    }
    for (x, v) in [(c, fc), (d, fd)] {
        if v < bf {
            bx = x;
            bf = v;
        }
    }
    (bx, bf, evals)
}

/// The objective values [`golden_min_batched`] knows, by the bits of the point.
struct Golden {
    phi: f64,
    memo: Vec<(u64, f64)>,
}

impl Golden {
    fn lookup(&self, x: f64) -> Option<f64> {
        self.memo
            .iter()
            .find(|(bits, _)| *bits == x.to_bits())
            .map(|&(_, v)| v)
    }

    /// A value evaluated before (always, by construction; NaN otherwise, which compares false
    /// as an unevaluated point would never be compared).
    fn get(&self, x: f64) -> f64 {
        self.lookup(x).unwrap_or(f64::NAN)
    }

    /// Evaluates the points of `pts` not known yet, in one batch.
    fn evaluate(&mut self, f: &dyn Fn(&[f64]) -> Vec<f64>, mut pts: Vec<f64>) {
        let mut seen = Vec::with_capacity(pts.len());
        pts.retain(|x| {
            let new = self.lookup(*x).is_none() && !seen.contains(&x.to_bits());
            seen.push(x.to_bits());
            new
        });
        if pts.is_empty() {
            return;
        }
        let vals = f(&pts);
        self.memo.extend(pts.iter().map(|x| x.to_bits()).zip(vals));
    }

    /// Appends to `pts` the points the next `left` iterations (at most `depth` of them) of the
    /// golden-section loop may need from the bracket `[a, b]` with inner points `c`, `d` and
    /// their values `fc`, `fd` (`None`: not known yet, so both outcomes of the comparison are
    /// followed). The arithmetic is [`golden_min`]'s, so the points are the same bits.
    fn explore(
        &self,
        [a, b, c, d]: [f64; 4],
        [fc, fd]: [Option<f64>; 2],
        left: usize,
        depth: u32,
        pts: &mut Vec<f64>,
    ) {
        if left == 0 || depth == 0 {
            return;
        }
        let phi = self.phi;
        let outcomes: &[bool] = match (fc, fd) {
            (Some(x), Some(y)) => {
                if x < y {
                    &[true]
                } else {
                    &[false]
                }
            }
            _ => &[true, false],
        };
        for &less in outcomes {
            if less {
                let (b, d, fd) = (d, c, fc);
                let c = b - phi * (b - a);
                let fc = self.lookup(c);
                if fc.is_none() {
                    pts.push(c);
                }
                self.explore([a, b, c, d], [fc, fd], left - 1, depth - 1, pts);
            } else {
                let (a, c, fc) = (c, d, fd);
                let d = a + phi * (b - a);
                let fd = self.lookup(d);
                if fd.is_none() {
                    pts.push(d);
                }
                self.explore([a, b, c, d], [fc, fd], left - 1, depth - 1, pts);
            }
        }
    }
}

/// The running `R` factor of a tall least-squares problem `[X y]`, fed row by row (TSQR: the
/// current `R` stacked on up to [`CHUNK`] new rows is re-factorised by Householder reflections in
/// a cache-resident column-major block).
#[derive(Debug, Clone)]
pub(crate) struct StreamingQr {
    cols: usize,
    /// Column-major, `cols + CHUNK` rows: the first `cols` rows hold `R`, then the new rows.
    block: Vec<f64>,
    fill: usize,
    colsq: Vec<f64>,
    /// Whether a partial chunk is factorised on its filled rows alone ([`StreamingQr::fold`]).
    compact: bool,
    /// Rows added between two re-factorisations ([`CHUNK`], or [`COMPACT_CHUNK`]).
    chunk: usize,
}

/// Rows between two re-factorisations of a [`StreamingQr::compact`].
const COMPACT_CHUNK: usize = 1024;

/// Rows added between two re-factorisations.
pub(crate) const CHUNK: usize = 1024;

/// Dot product with four accumulators (vectorises).
#[inline(always)]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for i in 0..4 {
            acc[i] += x[i] * y[i];
        }
    }
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    acc[0] + acc[1] + acc[2] + acc[3] + tail
}

/// `N` [`dot`]s of `v` with `c[0..N]` at once (each summed exactly as [`dot`] sums it).
#[inline(always)]
fn dotn<const N: usize>(v: &[f64], c: [&[f64]; N]) -> [f64; N] {
    let len = v.len();
    let c = c.map(|c| &c[..len]);
    let mut acc = [[0.0f64; 4]; N];
    let body = len - len % 4;
    let mut i = 0;
    while i < body {
        let x = &v[i..i + 4];
        for q in 0..N {
            let y = &c[q][i..i + 4];
            for l in 0..4 {
                acc[q][l] += x[l] * y[l];
            }
        }
        i += 4;
    }
    let mut out = [0.0; N];
    for q in 0..N {
        let tail: f64 = v[body..]
            .iter()
            .zip(&c[q][body..])
            .map(|(x, y)| x * y)
            .sum();
        out[q] = acc[q][0] + acc[q][1] + acc[q][2] + acc[q][3] + tail;
    }
    out
}

/// Householder QR of the column-major `m × n` matrix `a` (m ≥ n), in place: on return the
/// upper triangle of the first `n` rows is `R` (below it, zeros). Runs the AVX2 copy when the
/// CPU has it: the same operations in the same order four lanes wide (no fused multiply-add),
/// so the result is the same bit for bit (tested).
fn householder_r(a: &mut [f64], m: usize, n: usize) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        unsafe { householder_r_avx2(a, m, n) };
        return;
    }
    householder_r_portable(a, m, n);
}

/// [`householder_r`] compiled for AVX2.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn householder_r_avx2(a: &mut [f64], m: usize, n: usize) {
    householder_r_portable(a, m, n);
}

/// [`householder_r`] for any CPU.
#[inline(always)]
fn householder_r_portable(a: &mut [f64], m: usize, n: usize) {
    for j in 0..n {
        let (left, right) = a.split_at_mut((j + 1) * m);
        let v = &mut left[j * m + j..j * m + m];
        let Some((alpha, vv)) = reflector(v) else {
            continue;
        };
        if vv > 0.0 {
            let tau = 2.0 / vv;
            let v = &*v;
            // The trailing columns eight, then four at a time: independent dot products share
            // each load of `v` (one accumulator chain alone waits on the adder's latency; eight
            // keep both adders busy), then the updates in one pass. Each column's arithmetic is
            // exactly [`dot`]'s and the update's, in the same order.
            let ncols = n - j - 1;
            let octs = ncols / 8;
            for o in 0..octs {
                let block = &mut right[o * 8 * m..(o * 8 + 8) * m];
                update_columns::<8>(block, m, j, v, tau);
            }
            let quads = (ncols - octs * 8) / 4;
            for qd in 0..quads {
                let at = octs * 8 + qd * 4;
                let block = &mut right[at * m..(at + 4) * m];
                update_columns::<4>(block, m, j, v, tau);
            }
            for k in octs * 8 + quads * 4..ncols {
                let c = &mut right[k * m + j..k * m + m];
                let s = tau * dot(v, c);
                for (ci, vi) in c.iter_mut().zip(v.iter()) {
                    *ci -= s * vi;
                }
            }
        }
        v[0] = alpha;
        v[1..].fill(0.0);
    }
}

/// Below this `‖v‖²` [`reflector`] scales the column first (well above where the
/// squares of its largest entries underflow or `2/‖v‖²` overflows).
const TINY_NORM_SQ: f64 = 1e-270;

/// Turns the column `v` (rows `j..` of column `j`) into the Householder vector that zeroes
/// `v[1..]`: returns the new diagonal `α` (`∓‖v‖`) and `‖v‖²` of the vector (the reflector is
/// `I − (2/‖v‖²)·v·vᵀ`), or `None` for a zero column. Where `‖v‖²` is below
/// [`TINY_NORM_SQ`] (and not zero) the column is divided by its largest magnitude first (a vector of the same
/// direction, so the same reflector; `α` is scaled back): unscaled, `‖v‖²` underflows (entries
/// below ~1e-154) and `2/‖v‖²` overflows to ∞, which turned the trailing columns into NaN (a
/// column whose only entries in a factorisation are tiny — `memsum`'s decayed basis values in a
/// small [`PatternQr`] group). Above it the arithmetic is the plain one, bit for bit.
#[inline(always)]
fn reflector(v: &mut [f64]) -> Option<(f64, f64)> {
    let nn = dot(v, v);
    // (NaN takes the plain path, as before: it is never hidden.)
    if nn >= TINY_NORM_SQ || nn.is_nan() {
        let norm = nn.sqrt();
        let alpha = if v[0] > 0.0 { -norm } else { norm };
        v[0] -= alpha;
        return Some((alpha, dot(v, v)));
    }
    let scale = v.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    if scale <= 0.0 {
        return None;
    }
    for x in v.iter_mut() {
        *x /= scale;
    }
    let norm = dot(v, v).sqrt();
    let alpha = if v[0] > 0.0 { -norm } else { norm };
    v[0] -= alpha;
    Some((alpha * scale, dot(v, v)))
}

/// Applies the reflector `I − τ·v·vᵀ` (on rows `j..`) to the `N` columns of `block` (column-major,
/// `m` rows each): `N` dot products sharing each load of `v`, then the `N` updates.
#[inline(always)]
fn update_columns<const N: usize>(block: &mut [f64], m: usize, j: usize, v: &[f64], tau: f64) {
    let len = v.len();
    let cols: [&mut [f64]; N] = {
        let mut rest = block;
        std::array::from_fn(|_| {
            let (c, r) = std::mem::take(&mut rest).split_at_mut(m);
            rest = r;
            &mut c[j..j + len]
        })
    };
    let d = dotn::<N>(v, std::array::from_fn(|q| &*cols[q]));
    let s: [f64; N] = std::array::from_fn(|q| tau * d[q]);
    for i in 0..len {
        let vi = v[i];
        for q in 0..N {
            cols[q][i] -= s[q] * vi;
        }
    }
}

/// The Householder loop one trailing column at a time (before the four-column kernel): the
/// reference the fast loop is tested against bit for bit.
#[cfg(test)]
fn householder_r_reference(a: &mut [f64], m: usize, n: usize) {
    for j in 0..n {
        let (left, right) = a.split_at_mut((j + 1) * m);
        let v = &mut left[j * m + j..j * m + m];
        let norm = dot(v, v).sqrt();
        if norm <= 0.0 {
            continue;
        }
        let alpha = if v[0] > 0.0 { -norm } else { norm };
        v[0] -= alpha;
        let vv = dot(v, v);
        if vv > 0.0 {
            let tau = 2.0 / vv;
            for k in 0..n - j - 1 {
                let c = &mut right[k * m + j..k * m + m];
                let s = tau * dot(v, c);
                for (ci, vi) in c.iter_mut().zip(v.iter()) {
                    *ci -= s * vi;
                }
            }
        }
        v[0] = alpha;
        v[1..].fill(0.0);
    }
}

impl StreamingQr {
    /// A problem with `p` regressors (plus the response column).
    pub(crate) fn new(p: usize) -> Self {
        let cols = p + 1;
        Self {
            cols,
            block: vec![0.0; (cols + CHUNK) * cols],
            fill: 0,
            colsq: vec![0.0; cols],
            compact: false,
            chunk: CHUNK,
        }
    }

    /// [`StreamingQr::new`] whose last, partial chunk is factorised on its filled rows alone
    /// (a block of `p + 1 + filled` rows instead of `p + 1 + CHUNK`) and whose chunks are
    /// [`COMPACT_CHUNK`] rows: the same `R` up to rounding (the dot products split into other
    /// partial sums), much less work and memory where a factorisation ends with a few rows —
    /// [`solve`]'s chunks, whose every pattern group ends with a partial chunk.
    fn compact(p: usize) -> Self {
        let cols = p + 1;
        Self {
            cols,
            block: vec![0.0; (cols + COMPACT_CHUNK) * cols],
            fill: 0,
            colsq: vec![0.0; cols],
            compact: true,
            chunk: COMPACT_CHUNK,
        }
    }

    /// [`StreamingQr::compact`] in the storage `block` of a finished one
    /// ([`StreamingQr::finish_keeping`]; of any size and contents): only the rows of `R` are
    /// cleared (the other rows are written before they are read), so the same `R` bit for bit as
    /// a fresh one, without zeroing (and faulting in) a new block.
    fn compact_in(p: usize, mut block: Vec<f64>) -> Self {
        let cols = p + 1;
        let m = cols + COMPACT_CHUNK;
        block.resize(m * cols, 0.0);
        for j in 0..cols {
            block[j * m..j * m + cols].fill(0.0);
        }
        Self {
            cols,
            block,
            fill: 0,
            colsq: vec![0.0; cols],
            compact: true,
            chunk: COMPACT_CHUNK,
        }
    }

    /// Adds one row `x` (length p) with response `y`.
    pub(crate) fn push(&mut self, x: &[f64], y: f64) {
        let p = x.len();
        for (s, &v) in self.colsq.iter_mut().zip(x) {
            *s += v * v;
        }
        self.colsq[p] += y * y;
        self.place(x.iter().copied(), y);
    }

    /// Adds one row (its `p` regressors, then the response `y`) without summing its squares.
    #[inline(always)]
    fn place(&mut self, x: impl Iterator<Item = f64>, y: f64) {
        let m = self.cols + self.chunk;
        let row = self.cols + self.fill;
        let mut at = row;
        for v in x {
            self.block[at] = v;
            at += m;
        }
        self.block[at] = y;
        self.fill += 1;
        if self.fill == self.chunk {
            self.fold();
        }
    }

    fn fold(&mut self) {
        if self.fill == 0 {
            return;
        }
        let (n, m) = (self.cols, self.cols + self.chunk);
        if self.fill < self.chunk && self.compact {
            // Partial chunk on its filled rows alone: the columns moved together (each column's
            // first `n + fill` rows; forward, so no column overwrites one not yet moved), the
            // factorisation, and `R` (the first `n` rows) moved back (backward, likewise).
            let mc = n + self.fill;
            for j in 1..n {
                self.block.copy_within(j * m..j * m + mc, j * mc);
            }
            householder_r(&mut self.block[..n * mc], mc, n);
            for j in (1..n).rev() {
                self.block.copy_within(j * mc..j * mc + n, j * m);
            }
            self.fill = 0;
            return;
        }
        if self.fill < self.chunk {
            // Partial chunk: factorise only the filled rows (zero the stale ones).
            for j in 0..n {
                self.block[j * m + n + self.fill..(j + 1) * m].fill(0.0);
            }
        }
        householder_r(&mut self.block, m, n);
        self.fill = 0;
    }

    /// The final `R` of `[X y]` ((p+1) × (p+1), diagonal of either sign) and the column norms².
    pub(crate) fn finish(mut self) -> (DMatrix<f64>, Vec<f64>) {
        let r = self.final_r();
        (r, self.colsq)
    }

    /// The final `R` (as [`StreamingQr::finish`]) and the block's storage, for
    /// [`StreamingQr::compact_in`].
    fn finish_keeping(mut self) -> (DMatrix<f64>, Vec<f64>) {
        let r = self.final_r();
        (r, self.block)
    }

    fn final_r(&mut self) -> DMatrix<f64> {
        self.fold();
        let (n, m) = (self.cols, self.cols + self.chunk);
        DMatrix::from_fn(
            n,
            n,
            |i, j| if i <= j { self.block[j * m + i] } else { 0.0 },
        )
    }
}

/// Byte budget of the blocks of [`PatternQr`]'s per-pattern factorisations; rows of a new
/// pattern beyond it go to the dense block (all columns).
const PATTERN_BYTES: usize = 16 << 20;

/// Rows [`PatternQr`] looks at before it decides whether grouping by pattern pays.
const PATTERN_PROBE: usize = 1024;

/// Slots of [`PatternQr`]'s pattern table (a power of two, more than the patterns it keeps).
const PATTERN_SLOTS: usize = 1 << 10;

/// [`StreamingQr`] for designs whose rows are sparse in a few recurring patterns (the hinge
/// curves of `seek` and `memory`: one curve of four, its hinges beyond the seek zero): rows are
/// grouped by the set of their non-zero columns and each group is factorised on those columns
/// alone (a Householder TSQR of `k + 1` instead of `p + 1` columns: `2k²` instead of `2p²`
/// flops per row); [`PatternQr::finish`] stacks the groups' `R` factors, each in its columns
/// of the whole design, and factorises them once more. Every step is an orthogonal
/// transformation of the rows of `[X y]`, so the `R` is [`StreamingQr`]'s up to the signs of
/// its rows and rounding (the rows are combined in another order; tested against it). Rows of
/// patterns beyond the byte budget [`PATTERN_BYTES`] go to one dense group of all columns.
/// Grouping is used only where it at least halves the flops (judged on the first
/// [`PATTERN_PROBE`] rows; designs of at most 63 columns): otherwise every row goes to the
/// dense group and the result is [`StreamingQr`]'s bit for bit (tested).
#[derive(Debug, Clone)]
pub(crate) struct PatternQr {
    p: usize,
    /// Per group: its columns (increasing, the response not included) and its factorisation.
    groups: Vec<(Vec<usize>, StreamingQr)>,
    /// Open-addressing table from a pattern (bit `j`: column `j` is non-zero) to its group
    /// (`u32::MAX`: empty slot).
    table: Vec<(u64, u32)>,
    /// The group of every row of a pattern that found no room ([`PATTERN_BYTES`]).
    dense: Option<usize>,
    /// Slots of `table` in use.
    filled: usize,
    /// The first rows (row-major, regressors then response) until [`PatternQr::decide`].
    probe: Option<Vec<f64>>,
    /// Whether rows are grouped by pattern (else all go to the dense group).
    patterned: bool,
    bytes: usize,
    /// Whether its groups are [`StreamingQr::compact`].
    compact: bool,
    /// Column norms² and count of the rows [`PatternQr::push`] added (the tests' entry point;
    /// [`solve`] sums its own and adds rows with [`PatternQr::place_row`]).
    #[cfg_attr(not(test), allow(dead_code))]
    colsq: Vec<f64>,
    #[cfg_attr(not(test), allow(dead_code))]
    rows: usize,
    /// Storage of finished factorisations for new groups and the probe
    /// ([`PatternQr::compact_reusing`]).
    spare: Vec<Vec<f64>>,
}

impl PatternQr {
    /// A problem with `p` regressors (plus the response column).
    pub(crate) fn new(p: usize) -> Self {
        Self {
            p,
            groups: Vec::new(),
            table: vec![(0, u32::MAX); PATTERN_SLOTS],
            dense: None,
            filled: 0,
            probe: Some(Vec::with_capacity(PATTERN_PROBE * (p + 1))),
            patterned: false,
            bytes: 0,
            compact: false,
            colsq: vec![0.0; p + 1],
            rows: 0,
            spare: Vec::new(),
        }
    }

    /// [`PatternQr::new`] that never groups: [`StreamingQr`]'s `R` bit for bit (the tests'
    /// reference for the grouped solve).
    fn dense(p: usize) -> Self {
        Self {
            probe: None,
            ..Self::new(p)
        }
    }

    /// [`PatternQr::new`] (or [`PatternQr::dense`] with `dense`) whose groups are
    /// [`StreamingQr::compact`]: for [`solve`]'s chunks.
    fn compact(p: usize, dense: bool) -> Self {
        let base = if dense { Self::dense(p) } else { Self::new(p) };
        Self {
            compact: true,
            ..base
        }
    }

    /// [`PatternQr::compact`] whose groups and probe take their storage from `spare` (the
    /// storage [`PatternQr::finish_groups_keeping`] gave back: [`solve`]'s chunks reuse the
    /// previous chunks' blocks; the same `R` bit for bit, [`StreamingQr::compact_in`]).
    fn compact_reusing(p: usize, dense: bool, spare: Vec<Vec<f64>>) -> Self {
        let mut qr = Self {
            spare,
            ..Self::compact(p, dense)
        };
        if qr.probe.is_some()
            && let Some(mut buf) = qr.take_spare(PATTERN_PROBE * (p + 1))
        {
            buf.clear();
            qr.probe = Some(buf);
        }
        qr
    }

    /// The spare storage of the least capacity that holds `len` values, if any.
    fn take_spare(&mut self, len: usize) -> Option<Vec<f64>> {
        let i = (0..self.spare.len())
            .filter(|&i| self.spare[i].capacity() >= len)
            .min_by_key(|&i| self.spare[i].capacity())?;
        Some(self.spare.swap_remove(i))
    }

    /// A group's factorisation of `k` columns.
    fn group_qr(&mut self, k: usize) -> StreamingQr {
        if self.compact {
            match self.take_spare((k + 1 + COMPACT_CHUNK) * (k + 1)) {
                Some(block) => StreamingQr::compact_in(k, block),
                None => StreamingQr::compact(k),
            }
        } else {
            StreamingQr::new(k)
        }
    }

    /// The group of all columns.
    fn dense_group(&mut self) -> usize {
        if let Some(g) = self.dense {
            return g;
        }
        let qr = self.group_qr(self.p);
        self.groups.push(((0..self.p).collect(), qr));
        let g = self.groups.len() - 1;
        self.dense = Some(g);
        g
    }

    /// The group of the rows whose non-zero columns are `mask`, made on first use (the dense
    /// group where there is no room).
    fn group(&mut self, mask: u64) -> usize {
        let mut slot = (mask.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 54) as usize % PATTERN_SLOTS;
        loop {
            let (m, g) = self.table[slot];
            if g == u32::MAX {
                break;
            }
            if m == mask {
                return g as usize;
            }
            slot = (slot + 1) % PATTERN_SLOTS;
        }
        // The table holds at most half its slots (so a probe always ends at an empty one).
        if self.filled >= PATTERN_SLOTS / 2 {
            return self.dense_group();
        }
        let cols: Vec<usize> = (0..self.p).filter(|&j| mask >> j & 1 == 1).collect();
        let chunk = if self.compact { COMPACT_CHUNK } else { CHUNK };
        let size = (cols.len() + 1 + chunk) * (cols.len() + 1) * 8;
        let g = if self.bytes + size <= PATTERN_BYTES {
            self.bytes += size;
            let k = cols.len();
            let qr = self.group_qr(k);
            self.groups.push((cols, qr));
            self.groups.len() - 1
        } else {
            self.dense_group()
        };
        self.table[slot] = (mask, g as u32);
        self.filled += 1;
        g
    }

    /// Adds one row `x` (length p) with response `y`.
    #[cfg_attr(not(test), allow(dead_code))]
    pub(crate) fn push(&mut self, x: &[f64], y: f64) {
        self.rows += 1;
        for (s, &v) in self.colsq.iter_mut().zip(x) {
            *s += v * v;
        }
        self.colsq[self.p] += y * y;
        self.place_row(x, y);
    }

    /// Adds one row `x` (length p) with response `y`, without counting it or summing its
    /// squares ([`PatternQr::rows`] and [`PatternQr::colsq`] do not see it).
    pub(crate) fn place_row(&mut self, x: &[f64], y: f64) {
        if let Some(buf) = &mut self.probe {
            buf.extend_from_slice(x);
            buf.push(y);
            if buf.len() == PATTERN_PROBE * (self.p + 1) {
                self.decide();
            }
            return;
        }
        self.route(x, y);
    }

    /// Decides from the rows held so far whether grouping by pattern pays (the mean count `k`
    /// of non-zero columns: `(k + 1)² ≤ (p + 1)² / 2`, at most half the flops), then adds them.
    fn decide(&mut self) {
        let Some(buf) = self.probe.take() else {
            return;
        };
        let w = self.p + 1;
        let rows = buf.len() / w;
        let nonzero = buf
            .chunks_exact(w)
            .map(|r| r[..self.p].iter().filter(|&&v| v != 0.0).count())
            .sum::<usize>() as f64
            / rows.max(1) as f64;
        self.patterned = self.p < 64 && 2.0 * (nonzero + 1.0).powi(2) <= (w * w) as f64;
        for r in buf.chunks_exact(w) {
            self.route(&r[..self.p], r[self.p]);
        }
        self.spare.push(buf);
    }

    /// Adds one row to its group (the dense one unless [`PatternQr::decide`] chose patterns).
    fn route(&mut self, x: &[f64], y: f64) {
        if !self.patterned {
            // Every row on all columns: straight into the dense group's block.
            let g = self.dense_group();
            self.groups[g].1.place(x.iter().copied(), y);
            return;
        }
        let g = self.group(nonzero_mask(x));
        let (cols, qr) = &mut self.groups[g];
        qr.place(cols.iter().map(|&j| x[j]), y);
    }

    /// Rows pushed so far.
    #[cfg(test)]
    pub(crate) fn rows(&self) -> usize {
        self.rows
    }

    /// A [`PatternQr`] that groups from the first row (no probe): [`solve`]'s merge of its
    /// chunks' groups ([`PatternQr::place_group_r`]); dense for designs of 64 columns or more.
    fn merging(p: usize) -> Self {
        Self {
            probe: None,
            patterned: p < 64,
            ..Self::new(p)
        }
    }

    /// Each group's columns and its `R` ([`PatternQr::finish_groups_keeping`] without the
    /// storage).
    #[cfg(test)]
    fn finish_groups(self) -> Vec<(Vec<usize>, DMatrix<f64>)> {
        self.finish_groups_keeping().0
    }

    /// Each group's columns and its `R` ((k+1) × (k+1), the response last), in the order the
    /// groups were made (the order their patterns first occur in the rows): the factorisation
    /// before [`PatternQr::finish`] stacks the groups; and the storage of its groups, probe and
    /// spare blocks (for [`PatternQr::compact_reusing`]).
    fn finish_groups_keeping(mut self) -> (Groups, Vec<Vec<f64>>) {
        self.decide();
        let mut spare = std::mem::take(&mut self.spare);
        let groups = self
            .groups
            .into_iter()
            .map(|(cols, qr)| {
                let (r, block) = qr.finish_keeping();
                spare.push(block);
                (cols, r)
            })
            .collect();
        (groups, spare)
    }

    /// Adds the `k + 1` rows of `r`, a group's `R` over the design columns `cols`
    /// ([`PatternQr::finish_groups`]), to the group of those columns (every row of a group's
    /// `R` lies in its columns; the dense group where there is no room or no grouping).
    fn place_group_r(&mut self, cols: &[usize], r: &DMatrix<f64>) {
        let g = if self.patterned {
            self.group(cols.iter().fold(0u64, |m, &j| m | 1 << j))
        } else {
            self.dense_group()
        };
        let k = cols.len();
        let mut x = vec![0.0; self.p];
        let (gcols, qr) = &mut self.groups[g];
        for i in 0..=k {
            for (a, &j) in cols.iter().enumerate() {
                x[j] = r[(i, a)];
            }
            qr.place(gcols.iter().map(|&j| x[j]), r[(i, k)]);
        }
    }

    /// The final `R` of `[X y]` ((p+1) × (p+1), diagonal of either sign) and the column norms²
    /// (as [`StreamingQr::finish`]).
    pub(crate) fn finish(mut self) -> (DMatrix<f64>, Vec<f64>) {
        self.decide();
        let p = self.p;
        if self.groups.len() == 1 && self.groups[0].0.len() == p {
            // One dense factorisation: [`StreamingQr`]'s `R` itself.
            if let Some((_, qr)) = self.groups.pop() {
                return (qr.finish().0, self.colsq);
            }
        }
        let mut all = self.group_qr(p);
        let mut row = vec![0.0; p];
        for (cols, qr) in self.groups {
            let k = cols.len();
            let (r, _) = qr.finish();
            for i in 0..=k {
                row.fill(0.0);
                for (a, &j) in cols.iter().enumerate() {
                    row[j] = r[(i, a)];
                }
                all.push(&row, r[(i, k)]);
            }
        }
        let (r, _) = all.finish();
        (r, self.colsq)
    }
}

/// The pattern of the non-zero values of `x` (at most 63 of them): bit `j` set where
/// `x[j] != 0.0` (NaN included). Runs the AVX copy when the CPU has it (four comparisons to
/// an instruction: the same bits, tested against [`nonzero_mask_portable`]).
#[inline(always)]
fn nonzero_mask(x: &[f64]) -> u64 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx") {
        // SAFETY: the CPU supports AVX (checked just above).
        return unsafe { nonzero_mask_avx(x) };
    }
    nonzero_mask_portable(x)
}

/// [`nonzero_mask`] for any CPU, one value at a time.
#[inline(always)]
fn nonzero_mask_portable(x: &[f64]) -> u64 {
    debug_assert!(x.len() < 64);
    let mut mask = 0u64;
    for (j, &v) in x.iter().enumerate() {
        mask |= u64::from(v != 0.0) << j;
    }
    mask
}

/// [`nonzero_mask`] compiled for AVX: four values to a comparison (`!=` is the unordered
/// not-equal, true for NaN as Rust's), the rest one at a time.
///
/// # Safety
/// The CPU must support AVX.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn nonzero_mask_avx(x: &[f64]) -> u64 {
    use std::arch::x86_64::{
        _CMP_NEQ_UQ, _mm256_cmp_pd, _mm256_loadu_pd, _mm256_movemask_pd, _mm256_setzero_pd,
    };
    debug_assert!(x.len() < 64);
    let zero = _mm256_setzero_pd();
    let mut mask = 0u64;
    let quads = x.chunks_exact(4);
    let rest = quads.remainder();
    for (i, q) in quads.enumerate() {
        // SAFETY: `q` holds four f64 (an unaligned load).
        let v = unsafe { _mm256_loadu_pd(q.as_ptr()) };
        let bits = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_NEQ_UQ>(v, zero)) as u64;
        mask |= bits << (4 * i);
    }
    let base = x.len() - rest.len();
    for (j, &v) in rest.iter().enumerate() {
        mask |= u64::from(v != 0.0) << (base + j);
    }
    mask
}

/// Per group of a [`PatternQr`]: its columns and its `R` ([`PatternQr::finish_groups_keeping`]).
type Groups = Vec<(Vec<usize>, DMatrix<f64>)>;

/// The least-squares solution of one design.
#[derive(Debug, Clone)]
struct Solution {
    coef: Vec<f64>,
    /// Row-major p × p covariance (zero rows/cols for dropped columns).
    cov: Vec<f64>,
    rss: f64,
    dropped: Vec<usize>,
    rank: usize,
    n: usize,
    /// Per design column (original order): its spread about its mean over the rows
    /// (√(Σ(x − x̄)²/n), the column's unit) and, for kept columns, `|R_qq| / ‖x − x̄‖`, the sine
    /// of its angle to the columns before it (1 − R² of regressing it on them is its square).
    spread: Vec<f64>,
    independence: Vec<Option<f64>>,
}

fn offsets(terms: &[Arc<dyn Term>]) -> (Vec<usize>, usize) {
    let mut off = Vec::with_capacity(terms.len());
    let mut p = 0;
    for t in terms {
        off.push(p);
        p += t.param_count();
    }
    (off, p)
}

/// Replays the log and calls `visit(basis_row, y)` for each measured row.
fn design_pass(
    terms: &[Arc<dyn Term>],
    data: &FitData<'_>,
    mut visit: impl FnMut(&[f64], f64),
) -> Result<(), FitError> {
    let covs = &data.log().schema.covariates;
    let mut states = terms
        .iter()
        .map(|t| t.start(covs))
        .collect::<Result<Vec<_>, _>>()?;
    let (off, p) = offsets(terms);
    let widths: Vec<usize> = terms.iter().map(|t| t.param_count()).collect();
    let mut buf = vec![0.0; p];
    let mut cov = Vec::new();
    for (_, row, f) in data.replay_for(terms) {
        let seek = Seek {
            features: &f,
            covariates: row.covariates.gather(&mut cov),
        };
        if let Some(y) = row.bias {
            for (k, s) in states.iter().enumerate() {
                s.basis(&seek, &mut buf[off[k]..off[k] + widths[k]]);
            }
            visit(&buf, y);
        }
        for s in &mut states {
            s.update(&seek, None);
        }
    }
    Ok(())
}

fn param_label(terms: &[Arc<dyn Term>], col: usize) -> (String, bool) {
    let mut start = 0;
    for t in terms {
        let names = t.param_names();
        if col < start + names.len() {
            return (
                format!("{}.{}", t.name(), names[col - start]),
                t.droppable(),
            );
        }
        start += names.len();
    }
    (format!("column {col}"), false)
}

/// The ridge penalty of design column `col` (its term's [`Term::ridge`]).
fn ridge_of(terms: &[Arc<dyn Term>], col: usize) -> f64 {
    let mut start = 0;
    for t in terms {
        let w = t.param_names().len();
        if col < start + w {
            return t.ridge();
        }
        start += w;
    }
    0.0
}

/// Bytes of design rows [`solve`] factorises as one chunk (its `[X y]` rows, row-major).
const SOLVE_CHUNK_BYTES: usize = 4 << 20;

/// Measured rows per chunk of [`solve`] for `p` design columns: [`SOLVE_CHUNK_BYTES`] of rows,
/// a multiple of [`CHUNK`]. Depends on `p` alone, never on the thread count.
fn solve_chunk_rows(p: usize) -> usize {
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
/// previous one in the log.
fn factorise_rows(
    mut qr: PatternQr,
    rows: &[f64],
    p: usize,
    mut sums: Option<(&mut [f64], &mut [f64])>,
) -> (Groups, Vec<Vec<f64>>) {
    for row in rows.chunks_exact(p + 1) {
        let (x, y) = (&row[..p], row[p]);
        if let Some((s, sq)) = sums.as_mut() {
            for ((&v, s), sq) in x.iter().zip(s.iter_mut()).zip(sq.iter_mut()) {
                *s += v;
                *sq += v * v;
            }
            sq[p] += y * y;
        }
        qr.place_row(x, y);
    }
    qr.finish_groups_keeping()
}

fn solve(
    terms: &[Arc<dyn Term>],
    data: &FitData<'_>,
    opts: &CheckedFitOptions,
) -> Result<Solution, FitError> {
    solve_marking(terms, data, opts, None)
}

/// Where one of [`solve`]'s chunks of measured rows begins in its replay: the history and
/// every term's state just before the chunk's first measured row (after the previous chunk's
/// last row was learnt from), so that the chunk's rows can be replayed on their own, in
/// parallel with the others ([`static_predictions_chunked`]).
struct ChunkStart<'a> {
    replay: crate::history::Replay<'a>,
    states: Vec<Box<dyn crate::model::term::TermState>>,
}

/// [`solve`], which also records in `starts` where each of its chunks of
/// [`solve_chunk_rows`] measured rows begins ([`ChunkStart`]; one per chunk, in log order).
fn solve_marking<'a>(
    terms: &[Arc<dyn Term>],
    data: &FitData<'a>,
    opts: &CheckedFitOptions,
    mut starts: Option<&mut Vec<ChunkStart<'a>>>,
) -> Result<Solution, FitError> {
    let (_, p) = offsets(terms);
    // Essential columns first, so that a dependency is blamed on a droppable hinge if possible.
    let droppable: Vec<bool> = (0..p).map(|c| param_label(terms, c).1).collect();
    let mut order: Vec<usize> = (0..p).filter(|&c| !droppable[c]).collect();
    order.extend((0..p).filter(|&c| droppable[c]));
    #[cfg(test)]
    let dense = tests::DENSE_SOLVE.get();
    #[cfg(not(test))]
    let dense = false;
    let new_qr = |p| {
        if dense {
            PatternQr::dense(p)
        } else {
            PatternQr::new(p)
        }
    };
    let w = p + 1;
    let mut rows = FixedRows::new(terms, data)?;
    // The column sums, by position in `order` (as `colsq`).
    let mut sums = vec![0.0; p];
    let mut colsq = vec![0.0; w];
    let per_chunk = solve_chunk_rows(p);
    let measured = data.log().measured_count();
    let mut xp = vec![0.0; p];
    // Ridge rows: `sqrt(λ·‖x_j‖²)·e_j` with response 0 for every penalised column (after the
    // data rows; `colsq` is the data rows' sums of squares).
    let ridge: Vec<f64> = (0..p).map(|c| ridge_of(terms, c)).collect();
    // Pushes them and adds their squares to `colsq` (as the rank test has always seen them).
    let mut ridge_rows = |colsq: &mut [f64], push: &mut dyn FnMut(&[f64])| -> Vec<f64> {
        let data_sq = colsq.to_vec();
        for (q, &c) in order.iter().enumerate() {
            if ridge[c] > 0.0 && data_sq[q] > 0.0 {
                xp.fill(0.0);
                xp[q] = (ridge[c] * data_sq[q]).sqrt();
                push(&xp);
                colsq[q] += xp[q] * xp[q];
            }
        }
        data_sq
    };
    let mut n = 0;
    let (r, data_sq) = if measured <= per_chunk {
        // One chunk: its factorisation, the ridge rows included (as before the chunks).
        let mut qr = new_qr(p);
        let mut scratch = vec![0.0; p];
        if let Some(s) = starts.as_deref_mut() {
            s.push(rows.start());
        }
        n = rows.each_ordered(
            per_chunk,
            &order,
            &mut sums,
            &mut colsq,
            &mut scratch,
            |x, y| qr.place_row(x, y),
        );
        let data_sq = ridge_rows(&mut colsq, &mut |x| qr.place_row(x, 0.0));
        (qr.finish().0, data_sq)
    } else {
        // Chunks of `per_chunk` measured rows (boundaries fixed by the row count alone), each
        // factorised on its own while the replay fills the next (`rayon::join`: on another
        // core where the pool has one), their `R` factors stacked in chunk order into one
        // more factorisation: the same `R` for any thread count, bit for bit (tested).
        let mut merged = if dense {
            PatternQr::dense(p)
        } else {
            PatternQr::merging(p)
        };
        if rayon::current_num_threads() > 1 {
            // The replay fills the next chunk's rows while the pool factorises the current one.
            // The column sums (the one thread's `each_ordered` sums, bit for bit, either way) go
            // to the lighter side: the replay's for a wide design (its factorisation is the
            // heavier side: `calibration`, reading the history columns, thread CPU 57 ms
            // against 35 per 10⁶ rows before), the pool's for a narrow one (`dahl`: a light
            // factorisation beside its rate's state replay), and likewise the merge of the
            // previous chunk's groups.
            let on_replay = p >= REPLAY_SIDE_COLUMNS;
            let mut cur = Vec::with_capacity(per_chunk * w);
            let mut next = Vec::with_capacity(per_chunk * w);
            let mut scratch = vec![0.0; p];
            let (mut fill_sums, mut fill_colsq) = (vec![0.0; p], vec![0.0; w]);
            let (mut pool_sums, mut pool_colsq) = (vec![0.0; p], vec![0.0; w]);
            let mut fill = |rows: &mut FixedRows<'a>, out: &mut Vec<f64>| {
                let start = starts.is_some().then(|| rows.start());
                let got = if on_replay {
                    rows.each_ordered(
                        per_chunk,
                        &order,
                        &mut fill_sums,
                        &mut fill_colsq,
                        &mut scratch,
                        |x, y| {
                            out.extend_from_slice(x);
                            out.push(y);
                        },
                    )
                } else {
                    rows.measured_rows(per_chunk, |buf, y| {
                        out.extend(order.iter().map(|&c| buf[c]));
                        out.push(y);
                    })
                };
                if let (Some(s), Some(start)) = (starts.as_deref_mut(), start)
                    && got > 0
                {
                    s.push(start);
                }
                got
            };
            n = fill(&mut rows, &mut cur);
            // Each chunk's factorisation in the blocks of the one before (no fresh zeroed
            // blocks to fault in).
            let mut spare = Vec::new();
            let mut pending: Groups = Vec::new();
            while !cur.is_empty() {
                let ((groups, kept), got) = rayon::join(
                    || {
                        let qr = PatternQr::compact_reusing(p, dense, std::mem::take(&mut spare));
                        let sums =
                            (!on_replay).then_some((&mut pool_sums[..], &mut pool_colsq[..]));
                        factorise_rows(qr, &cur, p, sums)
                    },
                    || {
                        for (cols, r) in &pending {
                            merged.place_group_r(cols, r);
                        }
                        fill(&mut rows, &mut next)
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
                next.clear();
            }
            for (cols, r) in &pending {
                merged.place_group_r(cols, r);
            }
            // Only one side summed: the other's sums are all zero.
            (sums, colsq) = if on_replay {
                (fill_sums, fill_colsq)
            } else {
                (pool_sums, pool_colsq)
            };
        } else {
            // One thread: each chunk's rows straight into its factorisation (no buffer), the
            // same chunks, so the same `R` bit for bit.
            let mut scratch = vec![0.0; p];
            let mut spare = Vec::new();
            loop {
                let mut qr = PatternQr::compact_reusing(p, dense, std::mem::take(&mut spare));
                let start = starts.is_some().then(|| rows.start());
                let got = rows.each_ordered(
                    per_chunk,
                    &order,
                    &mut sums,
                    &mut colsq,
                    &mut scratch,
                    |x, y| qr.place_row(x, y),
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
        }
        let data_sq = ridge_rows(&mut colsq, &mut |x| merged.place_row(x, 0.0));
        (merged.finish().0, data_sq)
    };
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

/// The `R` of the columns `keep` of the `(p+1) × (p+1)` factor `r` and its last column (the
/// response), `(k+1) × (k+1)`: [`solve`]'s re-factorisation when columns were dropped. By
/// [`householder_r`], whose reflector scales a column of tiny values (nalgebra's `qr()`, used
/// before, squares them unscaled: a kept column whose entries in `r` were all ~1e-170 gave a
/// zero diagonal, the triangular solve failed and every coefficient came out 0; at ~1e-158
/// subnormal squares cost 6e-9 relative; tested).
fn refactor_kept(r: &DMatrix<f64>, keep: &[usize]) -> DMatrix<f64> {
    let (m, p) = (r.nrows(), r.ncols() - 1);
    let n = keep.len() + 1;
    let mut a = vec![0.0; m * n];
    for (col, &c) in keep.iter().chain(std::iter::once(&p)).enumerate() {
        for i in 0..m {
            a[col * m + i] = r[(i, c)];
        }
    }
    householder_r(&mut a, m, n);
    DMatrix::from_fn(n, n, |i, j| if i <= j { a[j * m + i] } else { 0.0 })
}

/// The least-squares RSS of `terms` with term `k`'s nonlinear parameter at `t` (search
/// coordinate): a full [`solve`] (every term replayed, one streaming QR); `∞` where the term
/// refuses `t` or the solve fails. The reference for [`Projection::rss`].
fn slow_rss(
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
fn slow_rss_of(
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

/// Term `k`'s own search ([`Term::search`]), if it has one: the residual of the other terms
/// and the projection are built only when the term asks for them.
fn own_search(
    terms: &[Arc<dyn Term>],
    k: usize,
    data: &FitData<'_>,
    opts: &CheckedFitOptions,
    dof: usize,
) -> Option<crate::model::term::Searched> {
    use std::cell::OnceCell;
    let proj: OnceCell<Option<Projection<'_, '_>>> = OnceCell::new();
    let projection = || {
        proj.get_or_init(|| {
            terms[k]
                .search_by_projection()
                .then(|| Projection::new(terms, k, data, opts))
                .flatten()
        })
    };
    let rest: OnceCell<Vec<f64>> = OnceCell::new();
    let residual = || -> &[f64] {
        rest.get_or_init(|| match projection() {
            // The projection's response is already the residual on the other terms.
            Some(p) => p.y.clone(),
            None => rest_residual(terms, k, data, opts),
        })
    };
    let rss = |term: &Arc<dyn Term>| match projection() {
        Some(p) => p
            .fast_rss_of(term)
            .unwrap_or_else(|| slow_rss_of(terms, k, term, data, opts)),
        None => slow_rss_of(terms, k, term, data, opts),
    };
    let ctx = crate::model::term::SearchContext::new(data, &residual, &rss, dof);
    terms[k].search(&ctx)
}

/// Per measured row, the bias minus the least-squares fit of every term but `k` (the bias
/// itself where that fit fails).
fn rest_residual(
    terms: &[Arc<dyn Term>],
    k: usize,
    data: &FitData<'_>,
    opts: &CheckedFitOptions,
) -> Vec<f64> {
    let fixed: Vec<Arc<dyn Term>> = terms
        .iter()
        .enumerate()
        .filter(|&(j, _)| j != k)
        .map(|(_, t)| t.clone())
        .collect();
    let coef = solve(&fixed, data, opts).map(|s| s.coef).ok();
    let mut out = Vec::new();
    let pass = design_pass(&fixed, data, |x, y| {
        let fit = coef
            .as_ref()
            .map_or(0.0, |c| x.iter().zip(c).map(|(a, b)| a * b).sum::<f64>());
        out.push(y - fit);
    });
    if pass.is_err() {
        out.clear();
        // No terms: nothing can fail to start.
        let _ = design_pass(&[], data, |_, y| out.push(y));
    }
    out
}

/// One step of Neumaier's compensated sum: adds `x` to the running sum `s`, and the rounding
/// error of that addition to the compensation `c`.
#[inline(always)]
fn neumaier(s: &mut f64, c: &mut f64, x: f64) {
    let t = *s + x;
    *c += if s.abs() >= x.abs() {
        (*s - t) + x
    } else {
        (x - t) + *s
    };
    *s = t;
}

/// Rows per block of [`Blocked`] sums.
const BLOCK: usize = 256;

/// Sums of many terms taken in blocks: the caller sums up to [`BLOCK`] terms into its own
/// accumulators and hands them over ([`Blocked::flush`] zeroes them); the block sums are added
/// here with Neumaier's compensation. The rounding error stays near that of one block.
struct Blocked {
    sum: Vec<f64>,
    comp: Vec<f64>,
}

impl Blocked {
    fn new(n: usize) -> Self {
        Self {
            sum: vec![0.0; n],
            comp: vec![0.0; n],
        }
    }

    /// Adds one block's sums `v` (in order, `len` = n).
    fn add(&mut self, v: &[f64]) {
        for ((s, c), &x) in self.sum.iter_mut().zip(&mut self.comp).zip(v) {
            neumaier(s, c, x);
        }
    }

    /// Adds the concatenation of `parts` and zeroes them.
    fn flush(&mut self, parts: &mut [&mut Vec<f64>]) {
        let xs = parts.iter_mut().flat_map(|p| p.iter_mut());
        for ((s, c), x) in self.sum.iter_mut().zip(&mut self.comp).zip(xs) {
            neumaier(s, c, std::mem::take(x));
        }
    }

    /// [`Blocked::flush`] of lane `c` of the lane-interleaved `acc` (`acc[j · lanes + c]` is
    /// sum `j`), zeroing it: the same arithmetic per sum.
    fn flush_lane(&mut self, acc: &mut [f64], lanes: usize, c: usize) {
        let xs = acc.iter_mut().skip(c).step_by(lanes);
        for ((s, comp), x) in self.sum.iter_mut().zip(&mut self.comp).zip(xs) {
            neumaier(s, comp, std::mem::take(x));
        }
    }

    /// The compensated totals.
    fn total(&self) -> Vec<f64> {
        self.sum
            .iter()
            .zip(&self.comp)
            .map(|(s, c)| s + c)
            .collect()
    }
}

/// Candidate values whose columns [`Projection`] takes from one replay.
const SEARCH_BATCH: usize = 8;

/// Adds measured rows to the lane-interleaved sums of [`Projection::sums_many`] for a
/// one-column term, row after row: `G[a] += x[a]·d`, `H += d·d`, `e += d·y` per lane (the
/// per-lane arithmetic of [`Projection::fast_rss`]); `xf` holds the rows' fixed columns
/// (row-major), `y` their responses and `d` their columns (`SEARCH_BATCH` per row). Compiled
/// for AVX2 when the CPU has it (no fused multiply-add).
fn accumulate_one(acc: &mut [f64], xf: &[f64], y: &[f64], d: &[f64]) {
    // The sums live in registers for a fixed block of up to 6 columns (a width known to the
    // compiler); a wider one keeps them in memory.
    match xf.len() / y.len().max(1) {
        1 => accumulate_dispatch::<1>(acc, xf, y, d),
        2 => accumulate_dispatch::<2>(acc, xf, y, d),
        3 => accumulate_dispatch::<3>(acc, xf, y, d),
        4 => accumulate_dispatch::<4>(acc, xf, y, d),
        5 => accumulate_dispatch::<5>(acc, xf, y, d),
        6 => accumulate_dispatch::<6>(acc, xf, y, d),
        _ => accumulate_dispatch::<0>(acc, xf, y, d),
    }
}

/// [`accumulate_one`] for `PF` fixed columns (0: any number), compiled for AVX2 when the CPU
/// has it.
#[inline(always)]
fn accumulate_dispatch<const PF: usize>(acc: &mut [f64], xf: &[f64], y: &[f64], d: &[f64]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above).
        return unsafe { accumulate_one_avx2::<PF>(acc, xf, y, d) };
    }
    if PF == 0 {
        accumulate_one_portable(acc, xf, y, d);
    } else {
        accumulate_fixed::<PF>(acc, xf, y, d);
    }
}

/// [`accumulate_one`] compiled for AVX2.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn accumulate_one_avx2<const PF: usize>(acc: &mut [f64], xf: &[f64], y: &[f64], d: &[f64]) {
    if PF == 0 {
        accumulate_one_portable(acc, xf, y, d);
    } else {
        accumulate_fixed::<PF>(acc, xf, y, d);
    }
}

/// [`accumulate_one_portable`] for exactly `PF` fixed columns: the sums held in local arrays
/// over the rows (the same additions in the same order).
#[inline(always)]
fn accumulate_fixed<const PF: usize>(acc: &mut [f64], xf: &[f64], y: &[f64], d: &[f64]) {
    const L: usize = SEARCH_BATCH;
    if acc.len() != (PF + 2) * L {
        return accumulate_one_portable(acc, xf, y, d);
    }
    let mut g = [[0.0f64; L]; PF];
    for (ga, a) in g.iter_mut().zip(acc.chunks_exact(L)) {
        ga.copy_from_slice(a);
    }
    let mut h: [f64; L] = std::array::from_fn(|c| acc[PF * L + c]);
    let mut e: [f64; L] = std::array::from_fn(|c| acc[(PF + 1) * L + c]);
    for ((x, &yv), d) in xf.chunks_exact(PF).zip(y).zip(d.chunks_exact(L)) {
        let (Ok(x), Ok(d)) = (<&[f64; PF]>::try_from(x), <&[f64; L]>::try_from(d)) else {
            break;
        };
        for a in 0..PF {
            for c in 0..L {
                g[a][c] += x[a] * d[c];
            }
        }
        for c in 0..L {
            h[c] += d[c] * d[c];
        }
        for c in 0..L {
            e[c] += d[c] * yv;
        }
    }
    for (ga, a) in g.iter().zip(acc.chunks_exact_mut(L)) {
        a.copy_from_slice(ga);
    }
    acc[PF * L..(PF + 1) * L].copy_from_slice(&h);
    acc[(PF + 1) * L..(PF + 2) * L].copy_from_slice(&e);
}

/// [`accumulate_one`] for any CPU.
#[inline(always)]
fn accumulate_one_portable(acc: &mut [f64], xf: &[f64], y: &[f64], d: &[f64]) {
    const L: usize = SEARCH_BATCH;
    let pf = xf.len() / y.len().max(1);
    let (g, rest) = acc.split_at_mut(pf * L);
    let (h, e) = rest.split_at_mut(L);
    let (h, e): (&mut [f64; L], &mut [f64; L]) = match (h.try_into(), e.try_into()) {
        (Ok(h), Ok(e)) => (h, e),
        _ => return,
    };
    for ((x, &yv), d) in xf.chunks_exact(pf.max(1)).zip(y).zip(d.chunks_exact(L)) {
        let d: &[f64; L] = match d.try_into() {
            Ok(d) => d,
            Err(_) => return,
        };
        for (ga, &xa) in g.chunks_exact_mut(L).zip(x) {
            for c in 0..L {
                ga[c] += xa * d[c];
            }
        }
        for c in 0..L {
            h[c] += d[c] * d[c];
        }
        for c in 0..L {
            e[c] += d[c] * yv;
        }
    }
}

/// [`Projection`] keeps its fixed block row by row up to this many bytes (64 MiB); a larger
/// one is replayed from its terms on every pass ([`FixedRows`]) instead: the same rows and the
/// same bits, for the CPU time of a replay of the fixed terms per pass.
pub(crate) const STORED_FIXED_BYTES: usize = 64 << 20;

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

/// The measured rows of a design of `terms`, replayed a block at a time: the rows
/// [`design_pass`] visits, in the same order and with the same bits.
struct FixedRows<'a> {
    replay: crate::history::Replay<'a>,
    states: Vec<Box<dyn crate::model::term::TermState>>,
    /// The states that are not [`TermState::constant`](crate::model::term::TermState::constant)
    /// (the only ones a row updates).
    moving: Vec<usize>,
    off: Vec<usize>,
    widths: Vec<usize>,
    buf: Vec<f64>,
    cov: Vec<f64>,
}

impl<'a> FixedRows<'a> {
    /// Starts the replay; fails where a term fails to start.
    fn new(terms: &[Arc<dyn Term>], data: &FitData<'a>) -> Result<Self, FitError> {
        let covs = &data.log().schema.covariates;
        let states = terms
            .iter()
            .map(|t| t.start(covs))
            .collect::<Result<Vec<_>, _>>()?;
        let (off, p) = offsets(terms);
        Ok(Self {
            replay: data.replay_for(terms),
            moving: (0..states.len())
                .filter(|&k| !states[k].constant())
                .collect(),
            states,
            off,
            widths: terms.iter().map(|t| t.param_count()).collect(),
            buf: vec![0.0; p],
            cov: Vec::new(),
        })
    }

    /// Where the replay stands: the history and every term's state before the next row.
    fn start(&self) -> ChunkStart<'a> {
        ChunkStart {
            replay: self.replay.clone(),
            states: self.states.iter().map(|s| s.clone_box()).collect(),
        }
    }

    /// Replays the next `rows` measured rows (fewer where the log ends), handing each one's
    /// design row (every column, in design order) and its response to `each`; every row,
    /// measured or not, updates the term states. Returns how many measured rows it handed on.
    /// The one replay loop behind [`FixedRows::each_ordered`] and [`FixedRows::fill`].
    fn measured_rows(&mut self, rows: usize, mut each: impl FnMut(&[f64], f64)) -> usize {
        let mut n = 0;
        while n < rows {
            let Some((_, row, f)) = self.replay.next() else {
                break;
            };
            let seek = Seek {
                features: &f,
                covariates: row.covariates.gather(&mut self.cov),
            };
            if let Some(y) = row.bias {
                for (k, s) in self.states.iter().enumerate() {
                    s.basis(
                        &seek,
                        &mut self.buf[self.off[k]..self.off[k] + self.widths[k]],
                    );
                }
                each(&self.buf, y);
                n += 1;
            }
            for &k in &self.moving {
                self.states[k].update(&seek, None);
            }
        }
        n
    }

    /// Replays the next `rows` measured rows (fewer where the log ends), handing each one's
    /// design columns in the order `order` (in the scratch `xp`) and its response to `each`;
    /// adds each column value to `sums` and its square (and the response's) to `colsq`, by
    /// position in `order`, row by row. Returns how many rows it
    /// handed on.
    fn each_ordered(
        &mut self,
        rows: usize,
        order: &[usize],
        sums: &mut [f64],
        colsq: &mut [f64],
        xp: &mut [f64],
        mut each: impl FnMut(&[f64], f64),
    ) -> usize {
        let p = order.len();
        self.measured_rows(rows, |buf, y| {
            for (x, &c) in xp.iter_mut().zip(order) {
                *x = buf[c];
            }
            // By position: one pass the compiler vectorises.
            for ((&v, s), sq) in xp.iter().zip(sums.iter_mut()).zip(colsq.iter_mut()) {
                *s += v;
                *sq += v * v;
            }
            colsq[p] += y * y;
            each(xp, y);
        })
    }

    /// Appends the next `rows` measured rows (fewer where the log ends) to `out`, row-major;
    /// returns how many it appended.
    fn fill(&mut self, out: &mut Vec<f64>, rows: usize) -> usize {
        self.measured_rows(rows, |buf, _| out.extend_from_slice(buf))
    }
}

/// A column whose residual on all the other columns is below this multiple of the rank
/// tolerance (× its norm) sends a candidate to [`slow_rss`], which decides what to drop.
const PROJECTION_MARGIN: f64 = 10.0;

/// Variable projection for the search over term `k`'s nonlinear parameter: the columns of the
/// other terms (the fixed block `Xf`, which do not depend on the searched value) are replayed
/// and factorised once (`[Xf y] = Q·[Rf z; 0 ρ]`); per candidate only term `k` is replayed,
/// accumulating `G = Xfᵀ D`, `H = Dᵀ D` and `e = Dᵀ y` for its columns `D`. With
/// `C = Rf⁻ᵀ G` (`= Qᵀ D`), the Schur complement `S = H − CᵀC = L Lᵀ` and `u = e − Cᵀ z`, the
/// RSS of `[Xf D]` is `ρ² − ‖L⁻¹ u‖²` (the same least-squares problem as [`solve`]'s, in
/// closed form). A candidate where a column would come near the rank tolerance (so [`solve`]
/// might drop it) is handed to [`slow_rss`].
struct Projection<'d, 'a> {
    k: usize,
    data: &'d FitData<'a>,
    /// Term `k`'s columns at a batch of candidate values ([`Term::search_basis`]).
    search: Box<dyn SearchBasis + 'd>,
    pf: usize,
    /// The fixed columns: stored row by row, or replayed per pass where too large.
    xf: FixedBlock,
    /// Per measured row, the response's residual `r = y − Xf·βf` on the fixed block (it takes
    /// the place of `y`).
    y: Vec<f64>,
    rf: DMatrix<f64>,
    /// `Qᵀ r = Rf⁻ᵀ Xfᵀ r` (zero but for rounding) and `ρ² = ‖r‖² − ‖Qᵀ r‖²`.
    z: DMatrix<f64>,
    rho2: f64,
    colsq_f: Vec<f64>,
    /// The RSS of every effective value evaluated so far ([`Projection::rss_many`]).
    memo: std::cell::RefCell<Vec<(u64, f64)>>,
    tol: f64,
}

impl<'d, 'a> Projection<'d, 'a> {
    /// `None` where the fast path does not apply (a ridge penalty, a term that fails to start,
    /// or a fixed block near rank deficiency): the search then uses [`slow_rss`] throughout.
    fn new(
        terms: &'d [Arc<dyn Term>],
        k: usize,
        data: &'d FitData<'a>,
        opts: &CheckedFitOptions,
    ) -> Option<Self> {
        Self::with_budget(terms, k, data, opts, data.fixed_budget())
    }

    /// [`Projection::new`], storing the fixed block only if it takes at most `budget` bytes
    /// (else it is replayed per pass: the same rows, the same bits).
    fn with_budget(
        terms: &'d [Arc<dyn Term>],
        k: usize,
        data: &'d FitData<'a>,
        opts: &CheckedFitOptions,
        budget: usize,
    ) -> Option<Self> {
        if terms.iter().any(|t| t.ridge() > 0.0) {
            return None;
        }
        let fixed: Vec<Arc<dyn Term>> = terms
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != k)
            .map(|(_, t)| t.clone())
            .collect();
        let (_, pf) = offsets(&fixed);
        if pf == 0 {
            return None;
        }
        let m = data.log().measured_count();
        let store = m
            .saturating_mul(pf)
            .saturating_mul(std::mem::size_of::<f64>())
            <= budget;
        let mut xf = Vec::with_capacity(if store { m * pf } else { 0 });
        let mut y = Vec::with_capacity(m);
        let mut qr = StreamingQr::new(pf);
        design_pass(&fixed, data, |x, v| {
            if store {
                xf.extend_from_slice(x);
            }
            y.push(v);
            qr.push(x, v);
        })
        .ok()?;
        let (r, colsq_f) = qr.finish();
        let tol = opts.rank_tolerance;
        for q in 0..pf {
            let norm = colsq_f[q].sqrt();
            if !(norm > 0.0 && r[(q, q)].abs() > PROJECTION_MARGIN * tol * norm) {
                return None;
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
        let xr = xr.total();
        let w = rf
            .transpose()
            .solve_lower_triangular(&DMatrix::from_column_slice(pf, 1, &xr[..pf]))?;
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
    fn rss_many(&self, terms: &[Arc<dyn Term>], ts: &[f64], opts: &CheckedFitOptions) -> Vec<f64> {
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
    fn fast_rss_of(&self, term: &Arc<dyn Term>) -> Option<f64> {
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

/// A coefficient whose share of the prediction swings more than this many times the spread of
/// the measured bias is "blowing up": neighbouring columns cancel each other.
pub(crate) const BLOW_UP_RATIO: f64 = 100.0;

/// A design column whose sine of angle to the columns before it is below this (1 − R² below its
/// square, a variance inflation above 10¹⁰) makes the fit ill-conditioned.
pub(crate) const ILL_CONDITIONED: f64 = 1e-5;

/// The fit's self-check (issue #11): coefficients whose contribution swings far beyond the
/// measured bias (`|coef| × column spread > BLOW_UP_RATIO × bias std`, unit-free: both sides
/// are in the bias unit), and columns nearly a combination of the others. Dropped columns are
/// reported elsewhere.
fn self_check(terms: &[Arc<dyn Term>], sol: &Solution, bias_std: f64) -> Vec<String> {
    let mut out = Vec::new();
    for c in 0..sol.coef.len() {
        if sol.dropped.contains(&c) {
            continue;
        }
        let name = param_label(terms, c).0;
        let swing = sol.coef[c].abs() * sol.spread[c];
        if bias_std > 0.0 && swing > BLOW_UP_RATIO * bias_std {
            out.push(format!(
                "{name}: its contribution swings ±{:.3e} (coefficient × the column's spread), \
                 {:.0}× the spread of the measured bias ({:.3e}): neighbouring columns cancel \
                 each other (weights blowing up); drop or merge a term",
                swing,
                swing / bias_std,
                bias_std
            ));
        }
        if let Some(sin) = sol.independence[c].filter(|&s| s < ILL_CONDITIONED) {
            out.push(format!(
                "{name}: ill-conditioned: the column is all but a combination of the columns \
                 before it (1 − R² = {:.1e}); its coefficient and standard error are unreliable",
                sin * sin
            ));
        }
    }
    out
}

/// What [`replay_residuals`] returns: measured bias, residuals, position range.
type Residuals = (Vec<f64>, Vec<f64>, Option<[f64; 2]>);

/// The causal replay of `model` over `log` that the fit statistics need: the measured bias and
/// the residual of every measured row, and the range of their finite positions — what
/// [`FittedModel::predict_log`] gives in `measured`, `residual` and `range(positions)` (tested),
/// without holding its other columns (rows, positions, predictions, every term's contribution:
/// about 80 bytes per row).
fn replay_residuals(model: &FittedModel, log: &Log) -> Result<Residuals, FitError> {
    let m = log.measured_count();
    let (mut measured, mut residual) = (Vec::with_capacity(m), Vec::with_capacity(m));
    let mut range: Option<[f64; 2]> = None;
    model.replay_measured(log, crate::model::Feedback::EveryRow, |row, pred, _| {
        measured.push(row.measured);
        residual.push(row.measured - pred);
        let x = row.position;
        if x.is_finite() {
            range = Some(match range {
                None => [x, x],
                Some([lo, hi]) => [lo.min(x), hi.max(x)],
            });
        }
    })?;
    Ok((measured, residual, range))
}

/// Where the adaptive terms begin, if they all come after the others and read nothing but the
/// residuals ([`Term::reads_only_residuals`]; `terms.len()` when there are none): then the
/// fit's statistics replay only them ([`replay_tail`]) over the static prediction of the others
/// ([`static_predictions_chunked`]) instead of the whole model over the log.
fn adaptive_tail(terms: &[Arc<dyn Term>]) -> Option<usize> {
    let first = terms
        .iter()
        .position(|t| t.adaptive())
        .unwrap_or(terms.len());
    terms[first..]
        .iter()
        .all(|t| t.adaptive() && t.param_count() == 0 && t.reads_only_residuals())
        .then_some(first)
}

/// The measured bias of every measured row, in log order.
#[cfg(test)]
fn measured_bias(log: &Log) -> impl Iterator<Item = f64> + '_ {
    log.bias_raw().iter().copied().filter(|b| !b.is_nan())
}

/// Per measured row, the prediction of `terms[..tail]` with coefficients `coef` (the whole
/// design's), each term's basis times its coefficients plus its offset, summed term by term
/// in the order and the arithmetic of `Predictor::evaluate` (so the same bits as the
/// predictor's running total before term `tail`; tested); and the range of the measured rows'
/// finite positions. One replay of the history: the reference for
/// [`static_predictions_chunked`], which [`fit`] uses.
#[cfg(test)]
fn static_predictions(
    terms: &[Arc<dyn Term>],
    tail: usize,
    data: &FitData<'_>,
    coef: &[f64],
) -> Result<(Vec<f64>, Option<[f64; 2]>), FitError> {
    let head = &terms[..tail];
    let covs = &data.log().schema.covariates;
    let mut states = head
        .iter()
        .map(|t| t.start(covs))
        .collect::<Result<Vec<_>, _>>()?;
    let (off, _) = offsets(terms);
    let widths: Vec<usize> = head.iter().map(|t| t.param_count()).collect();
    let mut buf = vec![0.0; widths.iter().copied().max().unwrap_or(0)];
    let mut out = Vec::with_capacity(data.log().measured_count());
    let mut range: Option<[f64; 2]> = None;
    let mut cov = Vec::new();
    for (_, row, f) in data.replay_for(head) {
        let seek = Seek {
            features: &f,
            covariates: row.covariates.gather(&mut cov),
        };
        if row.bias.is_some() {
            let mut total = 0.0;
            for (k, s) in states.iter().enumerate() {
                let b = &mut buf[..widths[k]];
                s.basis(&seek, b);
                let c = &coef[off[k]..off[k] + widths[k]];
                total += b.iter().zip(c).map(|(b, c)| b * c).sum::<f64>() + s.offset(&seek);
            }
            out.push(total);
            let x = row.track;
            if x.is_finite() {
                range = Some(match range {
                    None => [x, x],
                    Some([lo, hi]) => [lo.min(x), hi.max(x)],
                });
            }
        }
        for s in &mut states {
            s.update(&seek, None);
        }
    }
    Ok((out, range))
}

/// What [`static_predictions_chunked`] gives per measured row, in log order.
struct Statics<'l> {
    /// The prediction of the terms before the adaptive tail: per term, its basis times its
    /// coefficients plus its offset, summed in the order and arithmetic of
    /// `Predictor::evaluate`.
    pred: Vec<f64>,
    /// The measured bias: the log's bias column itself where every row is measured (no copy).
    measured: std::borrow::Cow<'l, [f64]>,
    /// `measured − pred` (for the adaptive terms' tuning; [`fit`] frees it after that).
    residual: Vec<f64>,
    /// The range of the measured rows' finite positions.
    range: Option<[f64; 2]>,
}

/// The static predictions (`static_predictions`, the sequential replay the tests hold it to)
/// from [`solve_marking`]'s chunk starts: each chunk of `per_chunk`
/// measured rows replayed from its [`ChunkStart`] on its own, the chunks in parallel on
/// rayon's pool (the same arithmetic per row as the one sequential replay, so the same bits;
/// the ranges of the chunks merged in log order by the same `min`/`max`; tested). `starts`
/// holds every term's state (of `terms`, the whole design); only those before `tail` are read.
fn static_predictions_chunked<'l>(
    terms: &[Arc<dyn Term>],
    tail: usize,
    starts: Vec<ChunkStart<'_>>,
    per_chunk: usize,
    log: &'l Log,
    coef: &[f64],
) -> Statics<'l> {
    use rayon::prelude::*;
    let measured = log.measured_count();
    let (off, _) = offsets(terms);
    let widths: Vec<usize> = terms[..tail].iter().map(|t| t.param_count()).collect();
    let mut pred = vec![0.0; measured];
    // Every row measured: the bias column is the measured bias (no NaN in it), not copied.
    let all = (measured == log.len()).then(|| log.bias_raw());
    let mut meas = vec![0.0; if all.is_some() { 0 } else { measured }];
    let meas_parts: Vec<Option<&mut [f64]>> = match all {
        Some(_) => (0..measured.div_ceil(per_chunk)).map(|_| None).collect(),
        None => meas.chunks_mut(per_chunk).map(Some).collect(),
    };
    let mut residual = vec![0.0; measured];
    let ranges: Vec<(usize, Option<[f64; 2]>)> = pred
        .par_chunks_mut(per_chunk)
        .zip(meas_parts.into_par_iter())
        .zip(residual.par_chunks_mut(per_chunk))
        .zip(starts.into_par_iter())
        .map(|(((pred, mut meas), residual), start)| {
            let ChunkStart { replay, mut states } = start;
            states.truncate(tail);
            // Constant states add 0 and never change (`TermState::constant`): the same
            // `+ 0.0` without the call, and no update.
            let constant: Vec<bool> = states.iter().map(|s| s.constant()).collect();
            let moving: Vec<usize> = (0..states.len()).filter(|&k| !constant[k]).collect();
            let mut buf = vec![0.0; widths.iter().copied().max().unwrap_or(0)];
            let mut cov = Vec::new();
            let mut range: Option<[f64; 2]> = None;
            let mut n = 0;
            for (_, row, f) in replay {
                if n == pred.len() {
                    break;
                }
                let seek = Seek {
                    features: &f,
                    covariates: row.covariates.gather(&mut cov),
                };
                if let Some(y) = row.bias {
                    let mut total = 0.0;
                    for (k, s) in states.iter().enumerate() {
                        let b = &mut buf[..widths[k]];
                        s.basis(&seek, b);
                        let c = &coef[off[k]..off[k] + widths[k]];
                        let offset = if constant[k] { 0.0 } else { s.offset(&seek) };
                        total += b.iter().zip(c).map(|(b, c)| b * c).sum::<f64>() + offset;
                    }
                    pred[n] = total;
                    if let Some(m) = meas.as_deref_mut() {
                        m[n] = y;
                    }
                    residual[n] = y - total;
                    n += 1;
                    let x = row.track;
                    if x.is_finite() {
                        range = Some(match range {
                            None => [x, x],
                            Some([lo, hi]) => [lo.min(x), hi.max(x)],
                        });
                    }
                }
                for &k in &moving {
                    states[k].update(&seek, None);
                }
            }
            (n, range)
        })
        .collect();
    debug_assert!(ranges.iter().all(|&(n, _)| n > 0));
    let range = ranges
        .into_iter()
        .filter_map(|(_, r)| r)
        .reduce(|[lo, hi], [a, b]| [lo.min(a), hi.max(b)]);
    Statics {
        pred,
        measured: match all {
            Some(b) => std::borrow::Cow::Borrowed(b),
            None => std::borrow::Cow::Owned(meas),
        },
        residual,
        range,
    }
}

/// The residual of every measured row (measured bias `measured`) when the adaptive terms
/// `tail` (which read nothing but the residuals) follow the static prediction `statics` of the
/// others: each adds its offset to the running total and learns from the residual, as in
/// `Predictor::step_detailed` (what [`replay_residuals`] gives, bit for bit; tested).
fn replay_tail(
    tail: &[Arc<dyn Term>],
    log: &Log,
    statics: &[f64],
    measured: &[f64],
) -> Result<Vec<f64>, FitError> {
    let mut states = tail
        .iter()
        .map(|t| t.start(&log.schema.covariates))
        .collect::<Result<Vec<_>, _>>()?;
    // These states read no features and no covariates.
    let none = crate::history::SeekFeatures {
        seek_index: 0,
        time_s: 0.0,
        elapsed_s: 0.0,
        dwell_s: 0.0,
        source: 0.0,
        target: 0.0,
        seek_length: 0.0,
        direction: 0,
        direction_change: false,
        since_reversal: 0.0,
        rest_distance_od: None,
        rest_distance_id: None,
    };
    let seek = Seek {
        features: &none,
        covariates: &[],
    };
    let mut residual = Vec::with_capacity(measured.len());
    for (&s, &y) in statics.iter().zip(measured) {
        let mut total = s;
        for st in &states {
            total += crate::numeric::stats::sum_start() + st.offset(&seek);
        }
        let r = y - total;
        for st in &mut states {
            st.update(&seek, Some(r));
        }
        residual.push(r);
    }
    Ok(residual)
}

/// The fit's statistics of its residuals.
#[derive(Debug, Clone, Copy)]
struct ResidualStats {
    /// `stats::std_dev` (0 with fewer than two).
    std: f64,
    /// The sum of squares, summed in order.
    sse: f64,
    /// `stats::rms` (0 for none).
    rms: f64,
}

impl ResidualStats {
    /// The statistics of `residual`: one pass for its sum and sum of squares, one for the
    /// squares about the mean ([`ResidualStats::from_sums`]).
    fn of(residual: &[f64]) -> Self {
        let zero = crate::numeric::stats::sum_start();
        let (sum, sse) = residual
            .iter()
            .fold((zero, zero), |(s, q), &r| (s + r, q + r * r));
        Self::from_sums(residual, sum, sse)
    }

    /// The statistics of `residual` from its sum and its sum of squares, each added in row
    /// order from `stats::sum_start`: `std` as `stats::std_dev` (the mean `sum / n`, then the
    /// squares about it), `rms` as `stats::rms` (`sqrt(sse / n)`), the same bits (tested).
    fn from_sums(residual: &[f64], sum: f64, sse: f64) -> Self {
        let n = residual.len();
        let std = if n < 2 {
            0.0
        } else {
            let ss = crate::numeric::stats::sum_sq_about(residual, sum / n as f64);
            (ss / (n - 1) as f64).sqrt()
        };
        let rms = if n == 0 { 0.0 } else { (sse / n as f64).sqrt() };
        Self { std, sse, rms }
    }
}

/// [`ResidualStats::of`] the residuals [`replay_tail`] gives. Where the tail is one term of
/// exponential forgetting ([`Term::forgetting_factor`]: `drift`), its replay is one plain loop
/// that also sums the residuals and their squares as it goes, in the order and arithmetic of
/// the statistics' own passes ([`forgetting_tail_stats`]), which leaves one more pass (the
/// squares about the mean) instead of a replay of the term's state and four (the same bits;
/// tested against the replay and the three statistics).
fn tail_stats(
    tail: &[Arc<dyn Term>],
    log: &Log,
    statics: &[f64],
    measured: &[f64],
) -> Result<ResidualStats, FitError> {
    if let [t] = tail
        && let Some(alpha) = t.forgetting_factor()
    {
        return Ok(forgetting_tail_stats(alpha, statics, measured));
    }
    Ok(ResidualStats::of(&replay_tail(
        tail, log, statics, measured,
    )?))
}

/// [`tail_stats`] of a tail of one term of exponential forgetting with factor `alpha`: per
/// row the residual `r = y − (s + m)` and the update `m += alpha · r` (`drift`'s state, as
/// [`replay_tail`] runs it: its offset after the empty sum of no basis values), with the
/// running sums of `r` and `r²` that `stats::mean` and the sum of squares add in the same
/// order from the same start.
fn forgetting_tail_stats(alpha: f64, statics: &[f64], measured: &[f64]) -> ResidualStats {
    // Also the start of `replay_tail`'s empty basis sum.
    let zero = crate::numeric::stats::sum_start();
    let mut residual = Vec::with_capacity(statics.len());
    let (mut m, mut sum, mut sse) = (0.0, zero, zero);
    for (&s, &y) in statics.iter().zip(measured) {
        let r = y - (s + (zero + m));
        m += alpha * r;
        sum += r;
        sse += r * r;
        residual.push(r);
    }
    ResidualStats::from_sums(&residual, sum, sse)
}

/// Direction changes in the fit's replay of the history. `sampling` has counted them already
/// (the same tracker over the same positions) when the direction comes from position steps
/// with its deadband: then no replay is needed (tested equal to [`FitData::reversals`]).
fn reversal_count(
    direction: &crate::history::DirectionSource,
    sampling: &crate::history::Sampling,
    data: &FitData<'_>,
) -> usize {
    use crate::history::DirectionSource;
    match direction {
        DirectionSource::Steps => sampling.raw_reversals,
        DirectionSource::Deadband { deadband }
            if deadband.to_bits() == sampling.deadband.to_bits() =>
        {
            sampling.reversals
        }
        _ => data.reversals(),
    }
}

/// Fits `spec` to the measured rows of `log`.
pub fn fit(spec: &ModelSpec, log: &Log, opts: &CheckedFitOptions) -> Result<FittedModel, FitError> {
    fit_sharing(spec, log, opts, &Refits::default())
}

/// What many refits of one log's rows share (`diagnose`'s verification: every candidate on
/// every fold, the folds differing in which biases are blanked): the log's sampling and its
/// replayed features (a history reads times, positions and covariates, never the bias), and
/// the fixed-block budget of their variable-projection searches (several refits run at once).
#[derive(Debug, Clone)]
pub(crate) struct Refits {
    /// [`crate::history::log_sampling`] of the log.
    pub sampling: Option<crate::history::Sampling>,
    /// The log's history replayed with this direction source.
    pub history: Option<(
        crate::history::DirectionSource,
        crate::model::data::SharedHistory,
    )>,
    /// [`FitData::with_fixed_budget`].
    pub fixed_budget: usize,
}

impl Default for Refits {
    /// Nothing shared, the default budget: [`fit`].
    fn default() -> Self {
        Self {
            sampling: None,
            history: None,
            fixed_budget: STORED_FIXED_BYTES,
        }
    }
}

/// [`fit`], taking what `shared` holds instead of computing it again: the same model bit for
/// bit (tested in `diagnose::tests_verify`).
pub(crate) fn fit_sharing(
    spec: &ModelSpec,
    log: &Log,
    opts: &CheckedFitOptions,
    shared: &Refits,
) -> Result<FittedModel, FitError> {
    let sampling = shared
        .sampling
        .unwrap_or_else(|| crate::history::log_sampling(log));
    let direction = opts.direction.resolve_with(log, &sampling)?;
    let mut data = FitData::with_direction(log, &direction)?.with_fixed_budget(shared.fixed_budget);
    if let Some((d, h)) = &shared.history
        && *d == direction
    {
        data = data.sharing(h);
    }
    let reversals = reversal_count(&direction, &sampling, &data);
    let reversal_warning = direction.reversal_warning(reversals, log.len(), &sampling);
    // Each term prepares on its own replays (knots, centring, …), so they run in parallel;
    // the first error in spec order is the one reported, whatever the thread count.
    let mut terms = {
        use rayon::prelude::*;
        spec.terms
            .par_iter()
            .map(|t| t.prepare(&data))
            .collect::<Vec<_>>()
            .into_iter()
            .collect::<Result<Vec<_>, _>>()?
    };
    if !terms.iter().any(|t| t.provides_intercept()) {
        terms.insert(0, Arc::new(InterceptTerm));
    }
    if !terms.iter().any(|t| t.reads_history()) {
        // No later replay steps the history (`dahl`): the columns its preparation kept go.
        data.forget_history_columns();
    }
    let file = log.schema.file.clone();
    for t in &terms {
        t.start(&log.schema.covariates)?;
    }
    let (_, p) = offsets(&terms);
    let measured = log.measured_count();
    let needed = p + 2;
    if measured < needed {
        return Err(FitError::TooShort {
            file,
            measured,
            params: p,
            needed,
            spec: spec.to_string(),
        });
    }

    // Variable projection over nonlinear parameters (coordinate-wise if several).
    let nl_terms: Vec<usize> = (0..terms.len())
        .filter(|&k| terms[k].nonlinear().is_some())
        .collect();
    let mut evaluations = 0;
    let mut converged = true;
    let mut nl_se: Vec<Option<f64>> = vec![None; terms.len()];
    let cycles = if nl_terms.len() > 1 { 2 } else { 1 };
    for _ in 0..cycles {
        for &k in &nl_terms {
            let Some(nl) = terms[k].nonlinear() else {
                continue;
            };
            // A term that searches its own parameters (`Term::search`: `bump`'s centre and
            // width) does so here; its standard errors are its own.
            let dof = measured.saturating_sub(p + 1).max(1);
            if let Some(found) = own_search(&terms, k, &data, opts, dof) {
                evaluations += found.evaluations;
                converged &= found.converged;
                terms[k] = found.term;
                continue;
            }
            // The search compares RSS values from the variable projection; the standard
            // error below differentiates the RSS twice, so it takes three full solves.
            // Used where the term allows it (`Term::search_by_projection`: the `dahl` rate, its
            // search tested to end where the full solves' does, and its model files compared);
            // `stribeck`'s search keeps the full solve per candidate: its velocity-scale search
            // compares RSS values that differ by rounding only, and ends elsewhere within that
            // noise with the projection (its unit-invariance test, 1e-9 of the prediction, then
            // fails by 1.5×).
            let proj = terms[k]
                .search_by_projection()
                .then(|| Projection::new(&terms, k, &data, opts))
                .flatten();
            let (t, _, ev) = match &proj {
                // The projected RSS is cheaper per candidate in batches (one replay for
                // several): the same points, compared in the same order.
                Some(p) => golden_min_batched(
                    &|ts: &[f64]| p.rss_many(&terms, ts, opts),
                    nl.lo,
                    nl.hi,
                    opts.grid,
                    opts.refine,
                ),
                None => golden_min(
                    &|t: f64| slow_rss(&terms, k, t, &data, opts),
                    nl.lo,
                    nl.hi,
                    opts.grid,
                    opts.refine,
                ),
            };
            drop(proj);
            evaluations += ev;
            let rss_at = |t: f64| slow_rss(&terms, k, t, &data, opts);
            let ft = rss_at(t);
            let span = nl.hi - nl.lo;
            converged &= t > nl.lo + 1e-3 * span && t < nl.hi - 1e-3 * span;
            // Standard error from the curvature of the RSS: var(t) ≈ 2 s² / RSS''(t).
            let h = 1e-3 * span;
            let (fm, fp) = (rss_at(t - h), rss_at(t + h));
            evaluations += 2;
            let curv = (fp - 2.0 * ft + fm) / (h * h);
            let s2 = ft / (measured.saturating_sub(p + 1).max(1)) as f64;
            nl_se[k] = (curv > 0.0 && ft.is_finite()).then(|| (2.0 * s2 / curv).sqrt());
            if let Some(term) = terms[k].with_nonlinear(t) {
                terms[k] = term;
            }
        }
    }

    // The prediction of every term before the adaptive ones, per measured row, where those
    // read nothing but the residuals (`drift`): then they are replayed over it below. The
    // solve marks where its chunks begin in its replay; the static predictions replay the
    // chunks from there in parallel.
    let tail = adaptive_tail(&terms);
    let mut starts = Vec::new();
    let sol = solve_marking(&terms, &data, opts, tail.map(|_| &mut starts))?;
    let mut statics = tail.map(|t| {
        static_predictions_chunked(
            &terms,
            t,
            std::mem::take(&mut starts),
            solve_chunk_rows(p),
            log,
            &sol.coef,
        )
    });

    // Causal offsets tuned on the static residuals. Beside the tuning (a sequential pass per
    // zoom), the measured bias's statistics, which need no tuned term (from the static
    // predictions' copy of it: `FitData::measured_bias_std` and `sum_sq_about_mean` of the
    // same values in the same order, so the same bits; `None` where there is none).
    let tune = |terms: &mut Vec<Arc<dyn Term>>| -> Result<(), FitError> {
        if terms.iter().any(|t| t.param_count() == 0) {
            let design_residuals;
            let residuals: &[f64] = match &statics {
                Some(st) => &st.residual,
                None => {
                    let mut residuals = Vec::with_capacity(sol.n);
                    design_pass(terms, &data, |x, y| {
                        residuals
                            .push(y - x.iter().zip(&sol.coef).map(|(a, b)| a * b).sum::<f64>());
                    })?;
                    design_residuals = residuals;
                    &design_residuals
                }
            };
            for t in terms.iter_mut() {
                if let Some(tuned) = t.tune_on_residuals(residuals) {
                    *t = tuned;
                }
            }
        }
        Ok(())
    };
    let (tuned, measured_stats) = match &statics {
        Some(st) => {
            let (tuned, stats) = rayon::join(
                || tune(&mut terms),
                || {
                    let b = &st.measured;
                    (
                        crate::numeric::stats::std_dev(b).unwrap_or(0.0),
                        crate::numeric::stats::sum_sq_about_mean(b),
                    )
                },
            );
            (tuned, Some(stats))
        }
        None => (tune(&mut terms), None),
    };
    tuned?;

    // The static residuals served the tuning alone: freed before the tail's replay, as are
    // the history columns (no replay of the history follows).
    if let Some(st) = statics.as_mut() {
        st.residual = Vec::new();
    }
    data.forget_history_columns();
    let (off, _) = offsets(&terms);
    let mut warnings = Vec::new();
    let mut fitted = Vec::with_capacity(terms.len());
    for (k, t) in terms.iter().enumerate() {
        let w = t.param_count();
        let coef = sol.coef[off[k]..off[k] + w].to_vec();
        let mut cov = vec![0.0; w * w];
        for a in 0..w {
            for b in 0..w {
                cov[a * w + b] = sol.cov[(off[k] + a) * p + off[k] + b];
            }
        }
        let params: Vec<Param> = t.report(&coef, &cov, nl_se[k]);
        for prm in &params {
            if let Some(se) = prm.se
                && se > prm.value.abs()
                && !sol
                    .dropped
                    .iter()
                    .any(|&c| param_label(&terms, c).0 == prm.name)
            {
                warnings.push(format!(
                    "{}: standard error {:.4e} exceeds |value| {:.4e}: not identifiable from this log",
                    prm.name, se, prm.value
                ));
            }
        }
        for w in t.fit_warnings(&terms) {
            if !warnings.contains(&w) {
                warnings.push(w);
            }
        }
        fitted.push(FittedTerm {
            term: t.clone(),
            coefficients: coef,
            params,
        });
    }
    let dropped: Vec<String> = sol
        .dropped
        .iter()
        .map(|&c| param_label(&terms, c).0)
        .collect();
    for d in &dropped {
        warnings.push(format!(
            "{d}: the log cannot determine this coefficient (no data, or a combination of others); fixed at 0"
        ));
    }
    if !converged {
        warnings.push("a nonlinear parameter ended at the edge of its search interval".into());
    }
    let bias_std = match measured_stats {
        Some((std, _)) => std,
        None => data.measured_bias_std(),
    };
    warnings.extend(self_check(&terms, &sol, bias_std));
    warnings.extend(reversal_warning);
    let mut covariates: Vec<String> = terms.iter().flat_map(|t| t.covariates()).collect();
    covariates.dedup();
    let map = &log.schema.map;
    let mut model = FittedModel {
        spec: spec.clone(),
        columns: ColumnsUsed {
            time: map.time.clone(),
            track: map.track.clone(),
            bias: map.bias.clone(),
            covariates,
        },
        terms: fitted,
        fit: FitReport {
            rows_used: sol.n,
            parameters: sol.rank,
            residual_std: 0.0,
            residual_rms: 0.0,
            r2: 0.0,
            ls_rss: sol.rss,
            dropped,
            evaluations,
            converged,
            position_range: None,
        },
        warnings,
        direction,
    };
    if let Some(p) = model.params().find(|p| !p.value.is_finite()) {
        let (lo, hi) = log.rows().fold((f64::MAX, f64::MIN), |(lo, hi), r| {
            (lo.min(r.track), hi.max(r.track))
        });
        return Err(FitError::ParamOverflow {
            file: log.schema.file.clone(),
            param: p.name.clone(),
            value: p.value,
            spread: (hi - lo).max(0.0),
        });
    }
    let (measured_bias, stats, position_range) = match (tail, statics) {
        (Some(t), Some(st)) => {
            let stats = tail_stats(&terms[t..], log, &st.pred, &st.measured)?;
            (st.measured, stats, st.range)
        }
        _ => {
            let (m, r, range) = replay_residuals(&model, log)?;
            (std::borrow::Cow::Owned(m), ResidualStats::of(&r), range)
        }
    };
    model.fit.position_range = position_range;
    let sst = match measured_stats {
        Some((_, sst)) => sst,
        None => crate::numeric::stats::sum_sq_about_mean(&measured_bias),
    };
    let ResidualStats {
        std: residual_std,
        sse,
        rms: residual_rms,
    } = stats;
    model.fit.residual_std = residual_std;
    model.fit.residual_rms = residual_rms;
    model.fit.r2 = if sst > 0.0 { 1.0 - sse / sst } else { 0.0 };
    let f = &model.fit;
    if ![f.residual_std, f.residual_rms, f.r2, sse, sst]
        .iter()
        .all(|v| v.is_finite())
    {
        let max_of = |v: &mut dyn Iterator<Item = f64>| v.fold(0.0_f64, |m, x| m.max(x.abs()));
        return Err(FitError::Overflow {
            file: log.schema.file.clone(),
            max_abs: max_of(&mut log.rows().filter_map(|r| r.bias)),
            max_pos: max_of(&mut log.rows().map(|r| r.track)),
        });
    }
    Ok(model)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::rng::SimRng;

    thread_local! {
        /// Makes [`solve`] factorise every row on all columns ([`PatternQr::dense`], i.e.
        /// [`StreamingQr`] bit for bit): the reference the grouped solve is tested against.
        pub(super) static DENSE_SOLVE: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
    }

    /// Least-squares solution of the `R` of `[X y]` as [`solve`] takes it: columns whose
    /// `|R_qq|` is at most `1e-9 × ‖x_q‖` dropped (their coefficient 0), the rest re-factorised
    /// and solved. Returns (the dropped columns, β, RSS).
    fn ls_of_r(r: &DMatrix<f64>, colsq: &[f64]) -> (Vec<usize>, Vec<f64>, f64) {
        let p = r.ncols() - 1;
        let (keep, dropped): (Vec<usize>, Vec<usize>) =
            (0..p).partition(|&q| r[(q, q)].abs() > 1e-9 * colsq[q].sqrt());
        // The kept columns re-factorised by the (scaling) Householder of [`StreamingQr`].
        let k = keep.len();
        let mut qr = StreamingQr::new(k);
        let mut row = vec![0.0; k];
        for i in 0..=p {
            for (a, &q) in keep.iter().enumerate() {
                row[a] = r[(i, q)];
            }
            qr.push(&row, r[(i, p)]);
        }
        let sub = qr.finish().0;
        let b = sub
            .view((0, 0), (k, k))
            .clone_owned()
            .solve_upper_triangular(&sub.view((0, k), (k, 1)).clone_owned())
            .unwrap();
        let mut beta = vec![0.0; p];
        for (a, &q) in keep.iter().enumerate() {
            beta[q] = b[(a, 0)];
        }
        (dropped, beta, sub[(k, k)].powi(2))
    }

    /// The NaN of the sixth round: a column whose entries are all below ~1e-154 (`memsum`'s
    /// decayed basis in a small pattern group) made `‖v‖²` underflow and `2/‖v‖²` overflow
    /// in the Householder step, and the response column became NaN. Reference: the same
    /// problem with that column multiplied by 2^600 (exact), an ordinary one: its coefficient
    /// must be the reference's times 2^600, the others and the RSS the reference's (1e-12).
    #[test]
    fn householder_scales_a_column_of_tiny_values_instead_of_giving_nan() {
        let mut rng = SimRng::new(5);
        let big = 2f64.powi(600);
        for (n, tiny) in [(3usize, 1e-160), (40, 1e-158), (2000, 1e-170), (5, 1e-300)] {
            let mut a = StreamingQr::new(3);
            let mut b = StreamingQr::new(3);
            for _ in 0..n {
                let x = rng.normal();
                let t = tiny * (0.5 + rng.uniform());
                let y = 1.0 + 2.0 * x + 3.0 * t / tiny + 0.1 * rng.normal();
                a.push(&[1.0, x, t], y);
                b.push(&[1.0, x, t * big], y);
            }
            let (ra, ca) = a.finish();
            let (rb, cb) = b.finish();
            assert!(ra.iter().all(|v| v.is_finite()), "{n} {tiny}");
            let (da, ba, sa) = ls_of_r(&ra, &[ca[0], ca[1], cb[2] / big / big]);
            let (db, bb, sb) = ls_of_r(&rb, &cb);
            assert_eq!(da, db, "{n} {tiny}");
            for (q, (u, w)) in ba.iter().zip(&bb).enumerate() {
                let u = if q == 2 { u / big } else { *u };
                assert!(
                    (u - w).abs() <= 1e-12 * w.abs().max(1.0),
                    "{n} {tiny} {q}: {u} {w}"
                );
            }
            // (n = 3: an interpolation, the RSS is rounding; relative to ‖y‖².)
            assert!((sa - sb).abs() <= 1e-12 * (sb + cb[3]), "{n} {tiny}");
        }
    }

    /// [`solve`]'s re-factorisation after dropping a column ([`refactor_kept`]) on the `R` of
    /// `[1, x, x (a duplicate, dropped), t, y]` where `t`'s values are tiny (1e-158 … 1e-300).
    /// Reference: the same design with `t` multiplied by 2^600 (exact), an ordinary problem:
    /// the coefficient of `t` must be the reference's times 2^600, the others and the RSS the
    /// reference's (1e-12 relative: both are backward-stable QR solutions of problems that
    /// differ only by an exact power-of-two scaling of one column, so they agree to rounding);
    /// and nothing zero or NaN. nalgebra's `qr()`, used before, failed this: at 1e-170 and
    /// below its `‖v‖²` underflowed to 0, it gave a zero diagonal and the triangular solve gave
    /// up (`solve` then reported all coefficients 0); at 1e-158 its coefficients were off by 6e-9
    /// relative (subnormal arithmetic). Both measured when this test was written.
    #[test]
    fn refactor_of_kept_columns_scales_a_column_of_tiny_values() {
        let mut rng = SimRng::new(17);
        let big = 2f64.powi(600);
        let solve_r = |r: &DMatrix<f64>| {
            let k = r.ncols() - 1;
            let b = r
                .view((0, 0), (k, k))
                .clone_owned()
                .solve_upper_triangular(&r.view((0, k), (k, 1)).clone_owned())
                .expect("a non-singular triangle");
            (b.iter().copied().collect::<Vec<f64>>(), r[(k, k)].powi(2))
        };
        for (n, tiny) in [
            (40usize, 1e-158),
            (300, 1e-170),
            (2000, 1e-200),
            (6, 1e-300),
        ] {
            let mut a = StreamingQr::new(4);
            let mut b = StreamingQr::new(4);
            for _ in 0..n {
                let x = rng.normal();
                let t = tiny * (0.5 + rng.uniform());
                let y = 1.0 + 2.0 * x + 3.0 * t / tiny + 0.1 * rng.normal();
                a.push(&[1.0, x, x, t], y);
                b.push(&[1.0, x, x, t * big], y);
            }
            let keep = [0, 1, 3];
            let ra = refactor_kept(&a.finish().0, &keep);
            let rb = refactor_kept(&b.finish().0, &keep);
            assert!(ra.iter().all(|v| v.is_finite()), "{n} {tiny}");
            assert!((0..3).all(|i| ra[(i, i)].abs() > 0.0), "{n} {tiny}");
            let (ba, sa) = solve_r(&ra);
            let (bb, sb) = solve_r(&rb);
            for (q, (u, w)) in ba.iter().zip(&bb).enumerate() {
                let u = if q == 2 { u / big } else { *u };
                assert!(
                    (u - w).abs() <= 1e-12 * w.abs().max(1.0),
                    "{n} {tiny} {q}: {u} {w}"
                );
            }
            assert!(
                (sa - sb).abs() <= 1e-12 * sb.max(1e-300),
                "{n} {tiny}: {sa} {sb}"
            );
        }
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
        let run = |threads: usize, dense: bool| {
            crate::with_threads(threads, || {
                DENSE_SOLVE.set(dense);
                let m = fit(&spec, &log, &opts);
                DENSE_SOLVE.set(false);
                m
            })
            .unwrap()
            .unwrap()
        };
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

    /// [`solve`]'s chunk merge on the designs of
    /// `pattern_qr_solves_rank_deficient_and_nearly_collinear_designs_as_dense` (exactly
    /// rank-deficient hat columns; a nearly collinear column; a column of 1e-160 values on a
    /// few rows of their own pattern; patterns with fewer rows than columns): the rows cut into
    /// chunks of 700 (short chunks: some patterns have a row or two per chunk), each chunk
    /// factorised by its own [`PatternQr::compact`], the groups' `R` merged in chunk order
    /// ([`PatternQr::merging`]). Reference: [`StreamingQr`] over all rows at once. Same
    /// dropped columns, RSS within 1e-10, coefficients within 1e-10 of the largest (1e-5 in the
    /// nearly collinear case, condition number ~1e7), nothing NaN.
    #[test]
    fn chunk_merge_solves_rank_deficient_tiny_and_short_chunk_designs_as_dense() {
        let mut rng = SimRng::new(23);
        for case in 0..4 {
            let (p, rows) = hinge_design(case, &mut rng);
            let mut dense = StreamingQr::new(p);
            let mut merged = PatternQr::merging(p);
            let mut colsq = vec![0.0; p + 1];
            for chunk in rows.chunks(700) {
                let mut qr = PatternQr::compact(p, false);
                for (x, y) in chunk {
                    dense.push(x, *y);
                    qr.place_row(x, *y);
                    for (s, v) in colsq.iter_mut().zip(x.iter().chain([y])) {
                        *s += v * v;
                    }
                }
                for (cols, r) in &qr.finish_groups() {
                    merged.place_group_r(cols, r);
                }
            }
            let (rd, cd) = dense.finish();
            let (rm, _) = merged.finish();
            assert!(rm.iter().all(|v| v.is_finite()), "{case}");
            let (dd, bd, sd) = ls_of_r(&rd, &cd);
            let (dm, bm, sm) = ls_of_r(&rm, &colsq);
            assert_eq!(dd, dm, "{case}");
            assert!(!dd.is_empty(), "{case}: the design is rank-deficient");
            assert!((sd - sm).abs() <= 1e-10 * sd, "{case}: {sd} {sm}");
            let scale = bd.iter().fold(0.0f64, |a, b| a.max(b.abs()));
            let tol = if case == 1 { 1e-5 } else { 1e-10 };
            for (q, (a, b)) in bd.iter().zip(&bm).enumerate() {
                assert!((a - b).abs() <= tol * scale, "{case} {q}: {a} {b}");
            }
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

    /// Reference: the one-column-at-a-time Householder loop (what every CPU ran before). The
    /// four-column kernel, portable and compiled for AVX2, must give the same `R` bit for bit
    /// on blocks of the sizes the fits use.
    #[test]
    fn householder_kernels_equal_the_one_column_loop_bit_for_bit() {
        let mut rng = SimRng::new(9);
        let sizes = [
            (1024 + 5, 5),
            (1024 + 30, 30),
            (1024 + 31, 31),
            (37, 7),
            (200, 64),
            (9, 2),
        ];
        for &(m, n) in &sizes {
            let a: Vec<f64> = (0..m * n)
                .map(|_| rng.normal() * 10f64.powi(rng.below(6) as i32 - 3))
                .collect();
            let (mut fast, mut portable, mut slow) = (a.clone(), a.clone(), a);
            householder_r(&mut fast, m, n);
            householder_r_portable(&mut portable, m, n);
            householder_r_reference(&mut slow, m, n);
            let same = |x: &[f64]| x.iter().zip(&slow).all(|(x, y)| x.to_bits() == y.to_bits());
            assert!(same(&fast) && same(&portable), "{m} x {n}");
        }
    }

    /// Reference: `FittedModel::predict_log` (what `fit` replayed before) — the measured bias,
    /// the residuals and the position range must be the same bit for bit.
    /// The search as it was before variable projection: every candidate a full [`solve`].
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
                if !terms.iter().any(|t| t.provides_intercept()) {
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

    /// Reference: the full replay (the features every term saw before). A term that says it
    /// does not read the history ([`Term::reads_history`]) must give the same basis, bit for
    /// bit, over the light replay; and the flag matters: `direction` and `memory` do read it.
    #[test]
    fn terms_without_history_give_the_same_basis_from_a_light_replay() {
        let mut log = crate::sim::random_log(3000, 5);
        for x in log.tracks_mut() {
            *x *= 0.37;
        }
        let data = FitData::new(&log);
        let spec =
            ModelSpec::parse("poly2,table,dahl,dahl:4,play:8,bump,direction,memory").unwrap();
        let mut terms: Vec<Arc<dyn Term>> = spec
            .terms
            .iter()
            .map(|t| t.prepare(&data).unwrap())
            .collect();
        terms.push(Arc::new(InterceptTerm));
        let reads: Vec<bool> = terms.iter().map(|t| t.reads_history()).collect();
        assert_eq!(
            reads,
            [false, false, false, false, false, false, true, true, false]
        );
        for t in terms.iter().filter(|t| !t.reads_history()) {
            let one = std::slice::from_ref(t);
            let basis = |light: bool| {
                let mut out = Vec::new();
                let replay = if light {
                    data.replay_for(one)
                } else {
                    data.replay()
                };
                let mut st = t.start(&[]).unwrap();
                let mut b = vec![0.0; t.param_count()];
                for (_, _, f) in replay {
                    let seek = Seek {
                        features: &f,
                        covariates: &[],
                    };
                    st.basis(&seek, &mut b);
                    out.extend(b.iter().map(|v| v.to_bits()));
                    st.update(&seek, None);
                }
                out
            };
            assert_eq!(basis(true), basis(false), "{}", t.name());
        }
    }

    /// Reference: [`FitData::reversals`], the count of the fit's own replay. The count taken
    /// from `sampling` must equal it on a seek log (raw steps) and on a dense noisy series (the
    /// estimated deadband), and an explicit deadband still replays.
    #[test]
    fn reversal_count_from_sampling_equals_the_replays() {
        use crate::history::DirectionSetting;
        let seeks = crate::sim::random_log(3000, 8);
        let mut rng = SimRng::new(4);
        let mut text = String::from("time_s,track,bias\n");
        for i in 0..4000 {
            let t = i as f64 * 1e-3;
            let x = 100.0 * (t * 7.0).sin() + 0.3 * rng.normal();
            text += &format!("{t},{x},{}\n", rng.normal());
        }
        let dense = Log::from_reader("d.csv", text.as_bytes(), &Default::default()).unwrap();
        let mut checked = 0;
        for log in [&seeks, &dense] {
            let sampling = crate::history::log_sampling(log);
            for setting in [
                DirectionSetting::Auto,
                DirectionSetting::Deadband(0.0),
                DirectionSetting::Deadband(0.5),
            ] {
                let direction = setting.resolve_with(log, &sampling).unwrap();
                let data = FitData::with_direction(log, &direction).unwrap();
                let want = data.reversals();
                assert_eq!(
                    reversal_count(&direction, &sampling, &data),
                    want,
                    "{setting:?}"
                );
                checked += usize::from(want >= 5);
            }
        }
        assert!(crate::history::log_sampling(&dense).deadband > 0.0);
        assert_eq!(checked, 6);
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
                if !terms.iter().any(|t| t.provides_intercept()) {
                    terms.insert(0, Arc::new(InterceptTerm));
                }
                let k = terms.iter().position(|t| t.search_by_projection()).unwrap();
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

    /// `bump` searches its own centre and width (`Term::search`) on the RSS by variable
    /// projection. Reference: [`slow_rss_of`], a full solve per version. On a simulated log
    /// with a planted defect, the projected RSS of versions across the range equals the full
    /// solve's to 1e-9, and the whole search run on full solves ends at the same centre and
    /// width (or at an RSS equal to 1e-12).
    #[test]
    fn bump_search_by_projection_equals_full_solves() {
        use crate::model::term::SearchContext;
        let mut log = crate::sim::random_log(3000, 5);
        let [lo, hi] = crate::numeric::stats::range(log.tracks()).unwrap();
        let (c0, w0) = (lo + 0.37 * (hi - lo), (hi - lo) / 300.0);
        for i in 0..log.len() {
            if let Some(b) = log.bias(i) {
                let x = log.tracks()[i];
                log.set_bias(i, Some(b + 40.0 * (-0.5 * ((x - c0) / w0).powi(2)).exp()));
            }
        }
        let opts = FitOptions::default().check().unwrap();
        let spec = ModelSpec::parse("poly2,direction,bump").unwrap();
        let data = FitData::new(&log);
        let mut terms = spec
            .terms
            .iter()
            .map(|t| t.prepare(&data))
            .collect::<Result<Vec<_>, _>>()
            .unwrap();
        let k = terms.iter().position(|t| t.name() == "bump").unwrap();
        let proj = Projection::new(&terms, k, &data, &opts).expect("fast path applies");
        let mut rng = SimRng::new(5);
        for i in 0..30 {
            let c = if i < 10 {
                c0 + w0 * (rng.uniform() - 0.5)
            } else {
                lo + (hi - lo) * rng.uniform()
            };
            let version = terms[k].with_nonlinear(c).unwrap();
            let slow = slow_rss_of(&terms, k, &version, &data, &opts);
            let fast = proj.fast_rss_of(&version).expect("closed form");
            assert!(
                (fast - slow).abs() <= 1e-9 * slow,
                "centre {c}: {fast} vs {slow}"
            );
        }
        drop(proj);
        let measured = log.measured_count();
        let (_, p) = offsets(&terms);
        let dof = measured - p - 1;
        let found = own_search(&terms, k, &data, &opts, dof).expect("bump searches itself");
        let residual = rest_residual(&terms, k, &data, &opts);
        let residual_fn = || -> &[f64] { &residual };
        let rss = |t: &Arc<dyn Term>| slow_rss_of(&terms, k, t, &data, &opts);
        let ctx = SearchContext::new(&data, &residual_fn, &rss, dof);
        let reference = terms[k].search(&ctx).unwrap();
        let params = |t: &Arc<dyn Term>| {
            t.report(&[0.0], &[0.0], None)
                .into_iter()
                .skip(1)
                .map(|p| p.value)
                .collect::<Vec<_>>()
        };
        let (a, b) = (params(&found.term), params(&reference.term));
        let (fa, fb) = (
            slow_rss_of(&terms, k, &found.term, &data, &opts),
            slow_rss_of(&terms, k, &reference.term, &data, &opts),
        );
        assert!(
            a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits())
                || (fa - fb).abs() <= 1e-12 * fb,
            "projected {a:?} (RSS {fa}) vs full solves {b:?} (RSS {fb})"
        );
        assert!((a[0] - c0).abs() < 0.2 * w0, "centre {} vs {c0}", a[0]);
        terms[k] = found.term;
        assert!(solve(&terms, &data, &opts).is_ok());
    }

    /// `step` searches its own threshold (`Term::search`) on the RSS by variable projection.
    /// Reference: [`slow_rss_of`], a full solve per version. On a simulated log with a logged
    /// covariate and a planted step in it, the projected RSS at thresholds across the column
    /// equals the full solve's to 1e-9, and the whole search run on full solves ends at the
    /// same threshold (or at an RSS equal to 1e-12), the planted one.
    #[test]
    fn step_search_by_projection_equals_full_solves() {
        use crate::model::term::SearchContext;
        let mut rng = SimRng::new(11);
        let mut text = String::from("time_s,track,bias,load\n");
        let (mut x, mut load) = (200.0f64, 0.0f64);
        for k in 0..3000 {
            x = (x + (rng.uniform() - 0.5) * 160.0)
                .round()
                .clamp(0.0, 400.0);
            load = 0.95 * load + 0.3 * rng.normal();
            let load = (load * 1000.0).round() / 1000.0;
            let d = if rng.uniform() < 0.5 { 1.0 } else { -1.0 };
            let bias = 5.0 + 0.02 * x + 1.5 * d + if load > 0.4 { 2.0 } else { 0.0 } + rng.normal();
            text += &format!("{:?},{x:?},{bias:?},{load:?}\n", 0.2 * k as f64);
        }
        let log = Log::from_reader("step.csv", text.as_bytes(), &Default::default()).unwrap();
        let opts = FitOptions::default().check().unwrap();
        let spec = ModelSpec::parse("poly2,direction,step:load").unwrap();
        let data = FitData::new(&log);
        let mut terms = spec
            .terms
            .iter()
            .map(|t| t.prepare(&data))
            .collect::<Result<Vec<_>, _>>()
            .unwrap();
        let k = terms.iter().position(|t| t.name() == "step:load").unwrap();
        let proj = Projection::new(&terms, k, &data, &opts).expect("fast path applies");
        let nl = terms[k].nonlinear().unwrap();
        for i in 0..30 {
            let t = nl.lo + (nl.hi - nl.lo) * (f64::from(i) + rng.uniform()) / 30.0;
            let version = terms[k].with_nonlinear(t).unwrap();
            let slow = slow_rss_of(&terms, k, &version, &data, &opts);
            let fast = proj.fast_rss_of(&version).expect("closed form");
            assert!(
                (fast - slow).abs() <= 1e-9 * slow,
                "threshold {t}: {fast} vs {slow}"
            );
        }
        drop(proj);
        let measured = log.measured_count();
        let (_, p) = offsets(&terms);
        let dof = measured - p - 1;
        let found = own_search(&terms, k, &data, &opts, dof).expect("step searches itself");
        let residual = rest_residual(&terms, k, &data, &opts);
        let residual_fn = || -> &[f64] { &residual };
        let rss = |t: &Arc<dyn Term>| slow_rss_of(&terms, k, t, &data, &opts);
        let ctx = SearchContext::new(&data, &residual_fn, &rss, dof);
        let reference = terms[k].search(&ctx).unwrap();
        let threshold = |t: &Arc<dyn Term>| t.nonlinear().unwrap().value;
        let (a, b) = (threshold(&found.term), threshold(&reference.term));
        let (fa, fb) = (
            slow_rss_of(&terms, k, &found.term, &data, &opts),
            slow_rss_of(&terms, k, &reference.term, &data, &opts),
        );
        assert!(
            a.to_bits() == b.to_bits() || (fa - fb).abs() <= 1e-12 * fb,
            "projected {a} (RSS {fa}) vs full solves {b} (RSS {fb})"
        );
        assert!((a - 0.4).abs() < 0.02, "threshold {a} vs 0.4");
        terms[k] = found.term;
        assert!(solve(&terms, &data, &opts).is_ok());
    }

    #[test]
    fn fit_statistics_replay_equals_predict_log() {
        let log = crate::sim::random_log(3000, 4);
        for preset in ["calibration", "dahl"] {
            let spec = ModelSpec::preset(preset).unwrap();
            let model = fit(&spec, &log, &FitOptions::default().check().unwrap()).unwrap();
            let pred = model.predict_log(&log).unwrap();
            let (measured, residual, range) = replay_residuals(&model, &log).unwrap();
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&measured), bits(&pred.measured), "{preset}");
            assert_eq!(bits(&residual), bits(&pred.residual), "{preset}");
            let want = crate::numeric::stats::range(&pred.positions);
            assert_eq!(
                range.map(|r| r.map(f64::to_bits)),
                want.map(|r| r.map(f64::to_bits))
            );
            assert!(residual.len() > 2000, "{preset}");
        }
    }

    /// Reference: `FittedModel::predict_log` (the predictor replayed over the log). Where the
    /// adaptive terms come last and read only residuals, the fit's statistics come from the
    /// static prediction of the other terms and a replay of the adaptive ones alone: the
    /// measured bias, the residuals and the position range must be the predictor's bit for bit
    /// (drift last, no drift, a fixed drift; every fifth row unmeasured in the second log).
    /// Where drift is not last, or a term other than drift adapts, there is no such path.
    #[test]
    fn static_prediction_and_tail_replay_equal_predict_log() {
        let full = crate::sim::random_log(3000, 5);
        let mut gaps = full.clone();
        for i in (2..gaps.len()).step_by(5) {
            gaps.set_bias(i, None);
        }
        let opts = FitOptions::default().check().unwrap();
        let mut fast = 0;
        for log in [&full, &gaps] {
            for text in [
                "calibration",
                "dahl",
                "poly2,seek,drift:0.05",
                "poly2,direction,memory",
                "poly2,drift,seek",
            ] {
                let spec = ModelSpec::preset(text)
                    .or_else(|_| ModelSpec::parse(text))
                    .unwrap();
                let model = fit(&spec, log, &opts).unwrap();
                let terms: Vec<Arc<dyn Term>> =
                    model.terms.iter().map(|t| t.term.clone()).collect();
                let coef: Vec<f64> = model
                    .terms
                    .iter()
                    .flat_map(|t| t.coefficients.iter().copied())
                    .collect();
                let Some(tail) = adaptive_tail(&terms) else {
                    assert_eq!(text, "poly2,drift,seek");
                    continue;
                };
                fast += 1;
                let data = FitData::with_direction(log, &model.direction).unwrap();
                let (st, range) = static_predictions(&terms, tail, &data, &coef).unwrap();
                let measured: Vec<f64> = measured_bias(log).collect();
                let residual = replay_tail(&terms[tail..], log, &st, &measured).unwrap();
                let pred = model.predict_log(log).unwrap();
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&measured), bits(&pred.measured), "{text}");
                assert_eq!(bits(&residual), bits(&pred.residual), "{text}");
                let want = crate::numeric::stats::range(&pred.positions);
                assert_eq!(
                    range.map(|r| r.map(f64::to_bits)),
                    want.map(|r| r.map(f64::to_bits))
                );
            }
        }
        assert_eq!(fast, 8);
    }

    /// Reference: [`replay_tail`] of a `drift` term (its state replayed through the `Term`
    /// interface) and [`ResidualStats::of`] its residuals (`stats::std_dev`, the sum of
    /// squares, `stats::rms`). The one-loop replay of exponential forgetting gives the same
    /// three statistics bit for bit, for factors from 1e-4 to 1, on residuals with outliers
    /// and runs of zeros, and on 0, 1, 2 and many rows.
    #[test]
    fn forgetting_tail_stats_equal_the_replay_and_the_statistics() {
        let mut rng = SimRng::new(23);
        let log = crate::sim::random_log(10, 1);
        for (case, n) in [0usize, 1, 2, 3, 1000, 50_000].into_iter().enumerate() {
            let statics: Vec<f64> = (0..n).map(|i| 3.0 * (i as f64 * 1e-3).sin()).collect();
            let measured: Vec<f64> = (0..n)
                .map(|i| match i % 89 {
                    0 => 1e4 * rng.normal(),
                    1..=4 => 0.0,
                    _ => statics[i] + 0.5 + rng.normal(),
                })
                .collect();
            for alpha in [1e-4, 3.7e-3, 0.05, 0.5, 1.0] {
                let term: Arc<dyn Term> = Arc::new(crate::model::terms::drift::DriftTerm {
                    name: "drift".into(),
                    alpha,
                    fixed: false,
                });
                assert_eq!(term.forgetting_factor(), Some(alpha));
                let r =
                    replay_tail(std::slice::from_ref(&term), &log, &statics, &measured).unwrap();
                let want = [
                    crate::numeric::stats::std_dev(&r).unwrap_or(0.0),
                    r.iter().map(|e| e * e).sum(),
                    crate::numeric::stats::rms(&r).unwrap_or(0.0),
                ]
                .map(f64::to_bits);
                let got =
                    tail_stats(std::slice::from_ref(&term), &log, &statics, &measured).unwrap();
                let bits = |s: ResidualStats| [s.std, s.sse, s.rms].map(f64::to_bits);
                assert_eq!(bits(got), want, "case {case}, alpha {alpha}");
                assert_eq!(
                    bits(ResidualStats::of(&r)),
                    want,
                    "case {case}, alpha {alpha}"
                );
            }
        }
    }

    /// Reference: [`nonzero_mask_portable`], one comparison per value. The dispatched mask
    /// (AVX where the CPU has it) is the same on rows of 0 to 63 values mixing zeros, negative
    /// zeros, NaN, infinities, subnormals and ordinary values.
    #[test]
    fn nonzero_mask_equals_the_one_value_loop() {
        let mut rng = SimRng::new(31);
        let pick = [
            0.0,
            -0.0,
            f64::NAN,
            f64::INFINITY,
            -f64::INFINITY,
            5e-324,
            -1.5,
            2.0,
        ];
        for len in 0..64 {
            for _ in 0..50 {
                let x: Vec<f64> = (0..len)
                    .map(|_| pick[rng.below(pick.len() as u64) as usize])
                    .collect();
                assert_eq!(nonzero_mask(&x), nonzero_mask_portable(&x), "{x:?}");
            }
        }
        assert_eq!(nonzero_mask(&[0.0, 1.0, -0.0, f64::NAN, 0.0]), 0b01010);
    }

    /// Reference: the same fit with the history stepped on every replay
    /// (`FitData`'s `STEP_HISTORY`, the path of a log of any length before the history
    /// columns). On a log longer than `FEATURE_CACHE_ROWS` (so the memory knots' replay builds
    /// the columns and the solve and the chunked static predictions read them), with a
    /// deadband direction source, the `calibration` fit gives the same model file byte for
    /// byte on 1, 2 and 3 threads; `dahl`, whose preparation's one full replay builds no
    /// columns, too.
    #[test]
    fn fit_reading_history_columns_equals_the_stepped_fit() {
        use crate::model::data::tests::{STEP_HISTORY, STEP_LOCK};
        use std::sync::atomic::Ordering;
        let _only = STEP_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        let log =
            crate::sim::random_log(crate::model::data::FEATURE_CACHE_ROWS as u64 + 40_000, 21);
        let opts = FitOptions {
            direction: crate::history::DirectionSetting::Deadband(3.0),
            ..FitOptions::default()
        }
        .check()
        .unwrap();
        for preset in ["calibration", "dahl"] {
            let spec = ModelSpec::preset(preset).unwrap();
            let json = |m: &FittedModel| m.to_json().unwrap();
            STEP_HISTORY.store(true, Ordering::Relaxed);
            let want = crate::with_threads(2, || fit(&spec, &log, &opts))
                .unwrap()
                .unwrap();
            STEP_HISTORY.store(false, Ordering::Relaxed);
            let threads: &[usize] = if preset == "dahl" { &[2] } else { &[1, 2, 3] };
            for &t in threads {
                let got = crate::with_threads(t, || fit(&spec, &log, &opts))
                    .unwrap()
                    .unwrap();
                assert_eq!(json(&got), json(&want), "{preset}, {t} threads");
            }
        }
    }

    /// [`static_predictions_chunked`] against the one sequential replay of
    /// [`static_predictions`] (the slow reference) and the measured bias against
    /// [`measured_bias`]: bit for bit, on 1, 2 and 3 threads, on logs of several of
    /// [`solve`]'s chunks (every seventh row unmeasured, so chunks end before unmeasured rows
    /// and begin after them), for the head terms of three designs (with and without the
    /// history's direction and memory terms); the residual is the measured bias minus the
    /// prediction, the range the reference's, bit for bit.
    #[test]
    fn chunked_static_predictions_equal_the_sequential_replay() {
        let full = crate::sim::random_log(60_000, 11);
        let mut gaps = full.clone();
        for i in (3..gaps.len()).step_by(7) {
            gaps.set_bias(i, None);
        }
        // Every row measured (the bias column itself is the measured bias) for one design.
        for (log, designs) in [(&gaps, 3), (&full, 1)] {
            statics_case(log, designs);
        }
    }

    fn statics_case(log: &Log, designs: usize) {
        let opts = FitOptions::default().check().unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let measured: Vec<f64> = measured_bias(log).collect();
        for text in [
            "calibration",
            "poly2,seek,drift:0.05",
            "poly2,direction,memory",
        ]
        .into_iter()
        .take(designs)
        {
            let spec = ModelSpec::preset(text)
                .or_else(|_| ModelSpec::parse(text))
                .unwrap();
            let model = fit(&spec, log, &opts).unwrap();
            let terms: Vec<Arc<dyn Term>> = model.terms.iter().map(|t| t.term.clone()).collect();
            let coef: Vec<f64> = model
                .terms
                .iter()
                .flat_map(|t| t.coefficients.iter().copied())
                .collect();
            let tail = adaptive_tail(&terms).unwrap();
            let data = FitData::with_direction(log, &model.direction).unwrap();
            let (want, want_range) = static_predictions(&terms, tail, &data, &coef).unwrap();
            let per_chunk = solve_chunk_rows(offsets(&terms).1);
            assert!(measured.len() > per_chunk, "{text}: two chunks at least");
            for threads in [1, 2, 3] {
                let got = crate::with_threads(threads, || {
                    let mut starts = Vec::new();
                    solve_marking(&terms, &data, &opts, Some(&mut starts)).unwrap();
                    assert_eq!(starts.len(), measured.len().div_ceil(per_chunk));
                    static_predictions_chunked(&terms, tail, starts, per_chunk, log, &coef)
                })
                .unwrap();
                assert_eq!(bits(&got.pred), bits(&want), "{text}, {threads} threads");
                assert_eq!(bits(&got.measured), bits(&measured), "{text}");
                let residual: Vec<f64> = measured.iter().zip(&want).map(|(y, s)| y - s).collect();
                assert_eq!(bits(&got.residual), bits(&residual), "{text}");
                assert_eq!(
                    got.range.map(|r| r.map(f64::to_bits)),
                    want_range.map(|r| r.map(f64::to_bits)),
                    "{text}"
                );
            }
        }
    }

    /// The rows `(x, y)` of the rank-deficient designs of
    /// `pattern_qr_solves_rank_deficient_and_nearly_collinear_designs_as_dense` (`case` 0–3)
    /// and their column count.
    fn hinge_design(case: usize, rng: &mut SimRng) -> (usize, Vec<(Vec<f64>, f64)>) {
        let knots = 6;
        // intercept, the hats, a duplicate of hat 2, x, (x + 1e-7 noise | tiny | nothing)
        let p = 1 + knots + 1 + 1 + 1;
        let n = if case == 3 { 40 } else { 3000 };
        let mut rows = Vec::with_capacity(n);
        for i in 0..n {
            let mut x = vec![0.0; p];
            x[0] = 1.0;
            let u = if case == 3 {
                // Few rows per interval, some exactly on a knot (one hat non-zero).
                (i % 11) as f64 * 0.5
            } else {
                rng.uniform() * (knots - 1) as f64
            };
            let k = (u.floor() as usize).min(knots - 2);
            let f = u - k as f64;
            x[1 + k] = 1.0 - f;
            x[2 + k] = f;
            x[1 + knots] = x[3];
            let z = if rng.uniform() < 0.3 {
                rng.normal()
            } else {
                0.0
            };
            x[2 + knots] = z;
            x[3 + knots] = match case {
                1 => z + 1e-7 * rng.normal(),
                2 if i % 97 == 0 => 1e-160 * (1.0 + rng.uniform()),
                _ => 0.0,
            };
            let y = 2.0 + x[1] - x[4] + 0.5 * z + 0.1 * rng.normal();
            rows.push((x, y));
        }
        (p, rows)
    }

    /// Reference: the dense [`StreamingQr`] of the same rows (one factorisation of all
    /// columns). On designs whose rows are sparse in recurring patterns (hinge-like blocks, one
    /// of four active per row, as `seek` and `memory` give; and random patterns over 40
    /// columns, more than the byte budget holds, so rows also go to the dense group),
    /// [`PatternQr`] must give the same column norms bit for bit (and on dense rows the same
    /// `R` bit for bit), `RᵀR` (= `[X y]ᵀ[X y]`, which
    /// fixes `R` up to the signs of its rows) within rounding, and the same least-squares
    /// solution and RSS within 1e-10 relative (the rows are combined in another order).
    /// Reference: the dense [`StreamingQr`] of the same rows, solved the same way
    /// ([`ls_of_r`]). Sparse hat-basis rows (a `table`-like term whose hats sum to the
    /// intercept column, so the design is exactly rank-deficient; one knot column also
    /// duplicated), with (case 1) a column nearly collinear with another (`x + 1e-7·noise`) and
    /// (case 2) a `memsum`-like column whose values are 1e-160 on a few rows of their own
    /// pattern and zero elsewhere, and (case 3) patterns with fewer rows than columns: the
    /// grouped factorisation must drop the same columns and give the same RSS (1e-10) and
    /// coefficients (1e-10 of the largest; 1e-5 in the nearly collinear case, whose condition
    /// number is ~1e7), and nothing NaN.
    #[test]
    fn pattern_qr_solves_rank_deficient_and_nearly_collinear_designs_as_dense() {
        let mut rng = SimRng::new(23);
        for case in 0..4 {
            let (p, rows) = hinge_design(case, &mut rng);
            let mut dense = StreamingQr::new(p);
            let mut pattern = PatternQr::new(p);
            for (x, y) in &rows {
                dense.push(x, *y);
                pattern.push(x, *y);
            }
            let (rd, cd) = dense.finish();
            let (rp, cp) = pattern.finish();
            assert!(rp.iter().all(|v| v.is_finite()), "{case}");
            assert!(cd.iter().zip(&cp).all(|(a, b)| a.to_bits() == b.to_bits()));
            let (dd, bd, sd) = ls_of_r(&rd, &cd);
            let (dp, bp, sp) = ls_of_r(&rp, &cp);
            assert_eq!(dd, dp, "{case}");
            assert!(!dd.is_empty(), "{case}: the design is rank-deficient");
            assert!((sd - sp).abs() <= 1e-10 * sd, "{case}: {sd} {sp}");
            let scale = bd.iter().fold(0.0f64, |a, b| a.max(b.abs()));
            let tol = if case == 1 { 1e-5 } else { 1e-10 };
            for (q, (a, b)) in bd.iter().zip(&bp).enumerate() {
                assert!((a - b).abs() <= tol * scale, "{case} {q}: {a} {b}");
            }
        }
    }

    #[test]
    fn pattern_qr_equals_dense_streaming_qr() {
        let mut rng = SimRng::new(11);
        for case in 0..4 {
            let (n, p) = match case {
                0 => (5000, 1 + 16 + 2),
                1 => (1500, 7),
                2 => (3000, 40),
                _ => (2500, 5),
            };
            let mut dense = StreamingQr::new(p);
            let mut pattern = PatternQr::new(p);
            let mut rows = Vec::new();
            for _ in 0..n {
                let mut x = vec![0.0; p];
                if case == 3 {
                    x.iter_mut().for_each(|v| *v = rng.normal());
                } else if case == 2 {
                    for v in x.iter_mut() {
                        if rng.uniform() < 0.5 {
                            *v = rng.normal();
                        }
                    }
                    x[0] = 1.0;
                } else {
                    x[0] = 1.0;
                    let curve = rng.below(4) as usize;
                    let a = 100.0 * rng.uniform();
                    for (j, k) in [20.0, 40.0, 60.0, 80.0].iter().enumerate() {
                        if 1 + curve * 4 + j < p {
                            x[1 + curve * 4 + j] = (k - a).max(0.0) / 80.0;
                        }
                    }
                    let u = rng.uniform() * 2.0 - 1.0;
                    x[p - 2] = u;
                    x[p - 1] = u * u;
                }
                let y = x.iter().sum::<f64>() + 0.3 * rng.normal();
                dense.push(&x, y);
                pattern.push(&x, y);
                rows.push((x, y));
            }
            assert_eq!(pattern.rows(), n);
            let (rd, cd) = dense.finish();
            let (rp, cp) = pattern.finish();
            assert!(cd.iter().zip(&cp).all(|(a, b)| a.to_bits() == b.to_bits()));
            if case == 3 {
                // Dense rows: grouping would not pay, so the dense factorisation itself.
                assert!(
                    rd.iter()
                        .zip(rp.iter())
                        .all(|(a, b)| a.to_bits() == b.to_bits())
                );
            }
            let (gd, gp) = (rd.transpose() * &rd, rp.transpose() * &rp);
            for i in 0..=p {
                for j in 0..=p {
                    let scale = (cd[i] * cd[j]).sqrt();
                    assert!(
                        (gd[(i, j)] - gp[(i, j)]).abs() <= 1e-12 * scale,
                        "{case} {i} {j}"
                    );
                }
            }
            let solve = |r: &DMatrix<f64>| {
                let beta = r
                    .view((0, 0), (p, p))
                    .clone_owned()
                    .solve_upper_triangular(&r.view((0, p), (p, 1)).clone_owned())
                    .unwrap();
                (beta, r[(p, p)].powi(2))
            };
            let ((bd, sd), (bp, sp)) = (solve(&rd), solve(&rp));
            let norm = bd.norm();
            assert!((&bd - &bp).norm() <= 1e-10 * norm, "{case}");
            assert!((sd - sp).abs() <= 1e-10 * sd, "{case}");
            // And both solve the problem: the residual is orthogonal to every column.
            for j in 0..p {
                let g: f64 = rows
                    .iter()
                    .map(|(x, y)| {
                        x[j] * (y - x.iter().zip(bp.iter()).map(|(a, b)| a * b).sum::<f64>())
                    })
                    .sum();
                assert!(
                    g.abs() <= 1e-8 * (cd[j] * sp).sqrt().max(1e-300),
                    "{case} {j}"
                );
            }
        }
    }

    #[test]
    fn streaming_qr_matches_svd_least_squares() {
        // Reference: nalgebra's SVD least-squares solution of the same (well-scaled) problem,
        // over several chunk boundaries (2500 rows = 2 full chunks + a partial one).
        let mut rng = SimRng::new(1);
        let (n, p) = (2500, 6);
        let x = DMatrix::from_fn(n, p, |_, _| rng.normal());
        let y = DMatrix::from_fn(n, 1, |i, _| x.row(i).sum() + 0.1 * rng.normal());
        let mut qr = StreamingQr::new(p);
        for i in 0..n {
            let row: Vec<f64> = x.row(i).iter().copied().collect();
            qr.push(&row, y[(i, 0)]);
        }
        let (r, colsq) = qr.finish();
        let beta = r
            .view((0, 0), (p, p))
            .clone_owned()
            .solve_upper_triangular(&r.view((0, p), (p, 1)).clone_owned())
            .unwrap();
        let svd = x.clone().svd(true, true).solve(&y, 1e-12).unwrap();
        for j in 0..p {
            assert!((beta[(j, 0)] - svd[(j, 0)]).abs() < 1e-10, "{j}");
            assert!((colsq[j] - x.column(j).norm_squared()).abs() < 1e-8 * colsq[j]);
        }
        let rss = (&y - &x * &svd).norm_squared();
        assert!((r[(p, p)].powi(2) - rss).abs() < 1e-9 * rss);
    }

    #[test]
    fn a_one_row_log_is_refused_in_the_singular() {
        let text = "time_s,track,bias\n0,5,1\n";
        let log = Log::from_reader("one.csv", text.as_bytes(), &Default::default()).unwrap();
        let spec = ModelSpec::preset("calibration").unwrap();
        let e = fit(&spec, &log, &CheckedFitOptions::default()).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("one.csv: 1 measured row, but"), "{msg}");
    }

    #[test]
    fn fit_options_check_names_the_bad_setting() {
        // Reference: the documented ranges; the default passes and equals the checked default.
        assert_eq!(
            FitOptions::default().check().unwrap(),
            CheckedFitOptions::default()
        );
        for (opts, field) in [
            (
                FitOptions {
                    rank_tolerance: 0.0,
                    ..FitOptions::default()
                },
                "rank_tolerance",
            ),
            (
                FitOptions {
                    rank_tolerance: f64::INFINITY,
                    ..FitOptions::default()
                },
                "rank_tolerance",
            ),
            (
                FitOptions {
                    grid: 2,
                    ..FitOptions::default()
                },
                "grid",
            ),
            (
                FitOptions {
                    refine: 1001,
                    ..FitOptions::default()
                },
                "refine",
            ),
        ] {
            match opts.check() {
                Err(FitError::InvalidOptions { field: f, .. }) => {
                    assert_eq!(f.name().rsplit("::").next(), Some(field))
                }
                other => panic!("{field}: {other:?}"),
            }
        }
    }

    /// Reference: [`golden_min`], one point at a time. The batched search must return the
    /// same point, value and count of evaluations (bits) on smooth, flat, rough, partly
    /// infinite and edge-minimum objectives, and evaluate in far fewer batches than points.
    #[test]
    fn golden_min_batched_equals_golden_min() {
        type Objective = (&'static str, fn(f64) -> f64);
        let objectives: [Objective; 6] = [
            ("parabola", |x| (x - 0.3) * (x - 0.3)),
            ("flat", |_| 1.0),
            ("steps", |x| ((x * 37.0).floor() - 11.0).abs()),
            ("rough", |x| (x * 91.0).sin() + 0.1 * (x - 0.6).powi(2)),
            ("infinite", |x| if x > 0.5 { f64::INFINITY } else { -x }),
            ("edge", |x| x),
        ];
        for (name, f) in objectives {
            for (lo, hi, grid, iters) in [(0.0, 1.0, 24, 40), (-2.0, 2.0, 3, 7), (0.0, 1.0, 10, 0)]
            {
                let batches = std::cell::Cell::new(0);
                let many = |xs: &[f64]| -> Vec<f64> {
                    batches.set(batches.get() + 1);
                    xs.iter().map(|&x| f(x)).collect()
                };
                let one = golden_min(&f, lo, hi, grid, iters);
                let b = golden_min_batched(&many, lo, hi, grid, iters);
                assert_eq!(
                    (one.0.to_bits(), one.1.to_bits(), one.2),
                    (b.0.to_bits(), b.1.to_bits(), b.2),
                    "{name} {grid} {iters}"
                );
                assert!(
                    batches.get() <= 2 + iters.div_ceil(3),
                    "{name}: {}",
                    batches.get()
                );
            }
        }
    }

    #[test]
    fn golden_min_finds_a_parabola_minimum() {
        // Reference: the minimum of (x − 0.3)² is at 0.3.
        let (x, fx, ev) = golden_min(&|x: f64| (x - 0.3) * (x - 0.3), -2.0, 2.0, 10, 40);
        assert!(
            (x - 0.3).abs() < 1e-6 && fx < 1e-12 && ev == 52,
            "{x} {fx} {ev}"
        );
    }
}
