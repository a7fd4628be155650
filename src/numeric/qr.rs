//! Least squares by streaming Householder QR: the running `R` factor of a tall problem
//! `[X y]` fed row by row ([`StreamingQr`]), the same for rows sparse in recurring patterns,
//! factorised per pattern ([`PatternQr`]), and the `R` of some of a factor's columns
//! ([`refactor_kept`]). The inner loops are in [`super::kernels`].

use super::kernels::{householder_r, nonzero_mask};
use super::runs::RunFolder;
use nalgebra::DMatrix;

/// The running `R` factor of a tall least-squares problem `[X y]`, fed row by row (TSQR: the
/// current `R` stacked on up to [`CHUNK`] new rows is re-factorised by Householder reflections in
/// a cache-resident column-major block).
#[derive(Debug, Clone)]
pub(crate) struct StreamingQr {
    cols: usize,
    /// Column-major, `cols + cap` rows: the first `cols` rows hold `R`, then the new rows.
    block: Vec<f64>,
    /// Rows of new data the block holds: `chunk`, or for a compact factorisation as many as
    /// have come so far (from [`COMPACT_START`], doubled as needed up to `chunk`).
    cap: usize,
    fill: usize,
    colsq: Vec<f64>,
    /// Whether a partial chunk is factorised on its filled rows alone ([`StreamingQr::fold`]).
    compact: bool,
    /// Rows added between two re-factorisations ([`CHUNK`], or [`COMPACT_CHUNK`]).
    chunk: usize,
    /// Whether any rows have been factorised (else `R` is zero and the block holds them all).
    folded: bool,
}

/// Rows between two re-factorisations of a [`StreamingQr::compact`].
const COMPACT_CHUNK: usize = 1024;

/// Rows of new data a [`StreamingQr::compact`]'s block holds at first (it grows as rows come:
/// a pattern group of a few rows neither zeroes nor factorises a block of [`COMPACT_CHUNK`]).
const COMPACT_START: usize = 16;

/// Rows added between two re-factorisations.
pub(crate) const CHUNK: usize = 1024;

impl StreamingQr {
    /// A problem with `p` regressors (plus the response column).
    pub(crate) fn new(p: usize) -> Self {
        let cols = p + 1;
        Self {
            cols,
            block: vec![0.0; (cols + CHUNK) * cols],
            cap: CHUNK,
            fill: 0,
            colsq: vec![0.0; cols],
            compact: false,
            chunk: CHUNK,
            folded: false,
        }
    }

    /// [`StreamingQr::new`] whose last, partial chunk is factorised on its filled rows alone
    /// (a block of `p + 1 + filled` rows instead of `p + 1 + CHUNK`) and whose chunks are
    /// [`COMPACT_CHUNK`] rows: the same `R` up to rounding (the dot products split into other
    /// partial sums), much less work and memory where a factorisation ends with a few rows —
    /// the chunks of a chunked solve and the pattern groups of a short log, whose every group
    /// ends with a partial chunk. Its block grows with the rows ([`COMPACT_START`]); the rows
    /// factorised together are the same whatever its size, so the same `R` bit for bit.
    pub(crate) fn compact(p: usize) -> Self {
        let cols = p + 1;
        Self {
            cols,
            block: vec![0.0; (cols + COMPACT_START) * cols],
            cap: COMPACT_START,
            fill: 0,
            colsq: vec![0.0; cols],
            compact: true,
            chunk: COMPACT_CHUNK,
            folded: false,
        }
    }

    /// [`StreamingQr::compact`] in the storage `block` of a finished one
    /// ([`StreamingQr::finish_keeping`]; of any size and contents): only the rows of `R` are
    /// cleared (the other rows are written before they are read), so the same `R` bit for bit as
    /// a fresh one, without zeroing (and faulting in) a new block.
    fn compact_in(p: usize, mut block: Vec<f64>) -> Self {
        let cols = p + 1;
        let cap = (block.len() / cols)
            .saturating_sub(cols)
            .clamp(COMPACT_START, COMPACT_CHUNK);
        let m = cols + cap;
        block.resize(m * cols, 0.0);
        for j in 0..cols {
            block[j * m..j * m + cols].fill(0.0);
        }
        Self {
            cols,
            block,
            cap,
            fill: 0,
            colsq: vec![0.0; cols],
            compact: true,
            chunk: COMPACT_CHUNK,
            folded: false,
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

    /// The sums of squares of the columns (the response's last) of the rows [`StreamingQr::push`]
    /// added so far.
    pub(crate) fn column_squares(&self) -> &[f64] {
        &self.colsq
    }

    /// Adds one row (its `p` regressors, then the response `y`) without summing its squares.
    #[inline(always)]
    fn place(&mut self, x: impl Iterator<Item = f64>, y: f64) {
        if self.fill == self.cap {
            self.grow();
        }
        let m = self.cols + self.cap;
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

    /// Doubles the rows of new data the block holds (up to `chunk`), moving `R` and the rows
    /// so far to the new stride.
    fn grow(&mut self) {
        let (n, m) = (self.cols, self.cols + self.cap);
        let cap = (2 * self.cap).min(self.chunk);
        let m2 = n + cap;
        let mut block = vec![0.0; m2 * n];
        let used = n + self.fill;
        for j in 0..n {
            block[j * m2..j * m2 + used].copy_from_slice(&self.block[j * m..j * m + used]);
        }
        self.block = block;
        self.cap = cap;
    }

    fn fold(&mut self) {
        if self.fill == 0 {
            return;
        }
        self.folded = true;
        let (n, m) = (self.cols, self.cols + self.cap);
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

    /// Where fewer rows than columns came and none was factorised yet, those rows themselves
    /// (`fill × (p+1)`: the same least squares as their `R`, without factorising a block for
    /// them), else [`StreamingQr::finish_keeping`]; with the block's storage.
    fn finish_rows_keeping(self) -> (DMatrix<f64>, Vec<f64>) {
        if self.folded || self.fill >= self.cols {
            return self.finish_keeping();
        }
        let (n, m) = (self.cols, self.cols + self.cap);
        let rows = DMatrix::from_fn(self.fill, n, |i, j| self.block[j * m + n + i]);
        (rows, self.block)
    }

    fn final_r(&mut self) -> DMatrix<f64> {
        self.fold();
        let (n, m) = (self.cols, self.cols + self.cap);
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
    /// a chunked solve sums its own and adds rows with [`PatternQr::place_row`]).
    #[cfg_attr(not(test), allow(dead_code))]
    colsq: Vec<f64>,
    #[cfg_attr(not(test), allow(dead_code))]
    rows: usize,
    /// Storage of finished factorisations for new groups and the probe
    /// ([`PatternQr::compact_reusing`]).
    spare: Vec<Vec<f64>>,
    /// Runs of rows equal in some columns, folded before they are grouped
    /// ([`PatternQr::with_runs`]), and the factorisation of their contrast rows (on the
    /// folder's other columns; made at the first contrast row).
    runs: Option<Box<RunFolder>>,
    contrast: Option<StreamingQr>,
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
            runs: None,
            contrast: None,
        }
    }

    /// This factorisation with the runs of consecutive rows that share their values in the
    /// columns `run` folded first ([`RunFolder`]: an orthogonal transformation, so the same
    /// `R` up to signs and rounding; rows in runs of one pass unchanged). Nothing changes for
    /// an empty `run`.
    pub(crate) fn with_runs(mut self, run: &[usize]) -> Self {
        if !run.is_empty() {
            self.runs = Some(Box::new(RunFolder::new(self.p, run)));
        }
        self
    }

    /// [`PatternQr::new`] that never groups: [`StreamingQr`]'s `R` bit for bit (the tests'
    /// reference for the grouped solve).
    pub(crate) fn dense(p: usize) -> Self {
        Self {
            probe: None,
            ..Self::new(p)
        }
    }

    /// [`PatternQr::new`] (or [`PatternQr::dense`] with `dense`) whose groups are
    /// [`StreamingQr::compact`]: for the chunks of a chunked solve and the one chunk of a short
    /// log.
    pub(crate) fn compact(p: usize, dense: bool) -> Self {
        let base = if dense { Self::dense(p) } else { Self::new(p) };
        Self {
            compact: true,
            ..base
        }
    }

    /// [`PatternQr::compact`] whose groups and probe take their storage from `spare` (the
    /// storage [`PatternQr::finish_groups_keeping`] gave back: a chunked solve's chunks reuse the
    /// previous chunks' blocks; the same `R` bit for bit, [`StreamingQr::compact_in`]).
    pub(crate) fn compact_reusing(p: usize, dense: bool, spare: Vec<Vec<f64>>) -> Self {
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
            match self.take_spare((k + 1 + COMPACT_START) * (k + 1)) {
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
        self.place_row_known(x, y, false)
    }

    /// [`PatternQr::place_row`]; with `known`, the caller vouches that the row's values in the
    /// columns of [`PatternQr::with_runs`] are those of the previous row, bit for bit (the
    /// run then continues without comparing them; the same `R`).
    pub(crate) fn place_row_known(&mut self, x: &[f64], y: f64, known: bool) {
        let Some(mut runs) = self.runs.take() else {
            return self.place_data(x, y);
        };
        let mut contrast = self.contrast.take();
        runs.push(
            x,
            y,
            known,
            &mut |x, y| self.place_data(x, y),
            &mut |z, y| {
                contrast
                    .get_or_insert_with(|| StreamingQr::compact(z.len()))
                    .place(z.iter().copied(), y)
            },
        );
        self.runs = Some(runs);
        self.contrast = contrast;
    }

    /// Adds a row that continues the open run of rows ([`PatternQr::with_runs`]; one row at
    /// least was placed since the factorisation began), given by its values `z` on the other
    /// columns (those not in the `run` of [`PatternQr::with_runs`], in increasing order) and
    /// its response: what [`PatternQr::place_row_known`] does with the whole row, bit for bit.
    pub(crate) fn place_continuing(&mut self, z: &[f64], y: f64) {
        let runs = self.runs.as_mut().expect("runs are folded");
        let contrast = &mut self.contrast;
        runs.push_continuing(z, y, &mut |z, y| {
            contrast
                .get_or_insert_with(|| StreamingQr::compact(z.len()))
                .place(z.iter().copied(), y)
        });
    }

    /// Closes the open run of rows ([`PatternQr::with_runs`]) and returns the factorisation
    /// of the contrast rows, if any, with its columns.
    fn end_runs(&mut self) -> Option<(Vec<usize>, StreamingQr)> {
        let mut runs = self.runs.take()?;
        runs.flush(&mut |x, y| self.place_data(x, y));
        let qr = self.contrast.take()?;
        Some((runs.rest().to_vec(), qr))
    }

    /// [`PatternQr::place_row`] after the runs are folded.
    fn place_data(&mut self, x: &[f64], y: f64) {
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

    /// A [`PatternQr`] that groups from the first row (no probe): a chunked solve's merge of its
    /// chunks' groups ([`PatternQr::place_group_r`]); dense for designs of 64 columns or more.
    pub(crate) fn merging(p: usize) -> Self {
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
    /// groups were made (the order their patterns first occur in the rows), then the contrast
    /// rows' group of folded runs ([`PatternQr::with_runs`]): the factorisation before
    /// [`PatternQr::finish`] stacks the groups; and the storage of its groups, probe and
    /// spare blocks (for [`PatternQr::compact_reusing`]). Where runs are folded, a group that
    /// received fewer than k + 1 rows gives those rows instead of their `R` (the same least
    /// squares, no block factorised for a chunk's few mean rows).
    pub(crate) fn finish_groups_keeping(mut self) -> (Groups, Vec<Vec<f64>>) {
        let folds_runs = self.runs.is_some();
        let contrast = self.end_runs();
        self.decide();
        let mut spare = std::mem::take(&mut self.spare);
        let groups = self
            .groups
            .into_iter()
            .chain(contrast)
            .map(|(cols, qr)| {
                // With folded runs, a chunk's few mean rows go to the merge as they are.
                let (r, block) = if folds_runs {
                    qr.finish_rows_keeping()
                } else {
                    qr.finish_keeping()
                };
                spare.push(block);
                (cols, r)
            })
            .collect();
        (groups, spare)
    }

    /// Adds the rows of `r`, a group's `R` (or rows) over the design columns `cols`
    /// ([`PatternQr::finish_groups_keeping`]), to the group of those columns (every row of a group's
    /// `R` lies in its columns; the dense group where there is no room or no grouping).
    pub(crate) fn place_group_r(&mut self, cols: &[usize], r: &DMatrix<f64>) {
        let g = if self.patterned {
            self.group(cols.iter().fold(0u64, |m, &j| m | 1 << j))
        } else {
            self.dense_group()
        };
        let k = cols.len();
        let mut x = vec![0.0; self.p];
        let (gcols, qr) = &mut self.groups[g];
        for i in 0..r.nrows() {
            for (a, &j) in cols.iter().enumerate() {
                x[j] = r[(i, a)];
            }
            qr.place(gcols.iter().map(|&j| x[j]), r[(i, k)]);
        }
    }

    /// The final `R` of `[X y]` ((p+1) × (p+1), diagonal of either sign) and the column norms²
    /// (as [`StreamingQr::finish`]).
    pub(crate) fn finish(mut self) -> (DMatrix<f64>, Vec<f64>) {
        let contrast = self.end_runs();
        self.decide();
        self.groups.extend(contrast);
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

/// Per group of a [`PatternQr`]: its columns and its `R` ([`PatternQr::finish_groups_keeping`]).
pub(crate) type Groups = Vec<(Vec<usize>, DMatrix<f64>)>;

/// The `R` of the columns `keep` of the `(p+1) × (p+1)` factor `r` and its last column (the
/// response), `(k+1) × (k+1)`: the re-factorisation of a solve that dropped columns. By
/// [`householder_r`], whose reflector scales a column of tiny values (nalgebra's `qr()`, used
/// before, squares them unscaled: a kept column whose entries in `r` were all ~1e-170 gave a
/// zero diagonal, the triangular solve failed and every coefficient came out 0; at ~1e-158
/// subnormal squares cost 6e-9 relative; tested).
pub(crate) fn refactor_kept(r: &DMatrix<f64>, keep: &[usize]) -> DMatrix<f64> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::rng::SimRng;

    /// Least-squares solution of the `R` of `[X y]` as the fit's solve takes it: columns whose
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

    /// A column whose entries are all below ~1e-154 (`memsum`'s
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

    /// The re-factorisation after dropping a column ([`refactor_kept`]) on the `R` of
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

    /// A chunked solve's merge on the designs of
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

    /// A compact factorisation's block grows with its rows ([`COMPACT_START`], doubled up to
    /// [`COMPACT_CHUNK`]). Reference: the same factorisation in a block of the full chunk from
    /// the start (`compact_in` a block that large: no growth). The same `R` and column sums bit
    /// for bit, for row counts below, at and across the growth steps and the chunk.
    #[test]
    fn grown_compact_block_equals_the_full_block() {
        let mut rng = SimRng::new(3);
        for p in [1, 6, 30] {
            for n in [1, 15, 16, 17, 100, 1023, 1024, 1025, 2500] {
                let full = vec![f64::NAN; (p + 1 + COMPACT_CHUNK) * (p + 1)];
                let mut grown = StreamingQr::compact(p);
                let mut reference = StreamingQr::compact_in(p, full);
                assert_eq!(reference.cap, COMPACT_CHUNK);
                for _ in 0..n {
                    let x: Vec<f64> = (0..p).map(|_| rng.normal()).collect();
                    let y = rng.normal();
                    grown.push(&x, y);
                    reference.push(&x, y);
                }
                let bits = |m: &DMatrix<f64>| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                let (a, sa) = grown.finish();
                let (b, sb) = reference.finish();
                assert_eq!(bits(&a), bits(&b), "p {p}, {n} rows");
                assert_eq!(sa, sb, "p {p}, {n} rows");
                assert!(a.iter().all(|v| v.is_finite()), "p {p}, {n} rows");
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
}
