//! The permutation test's fused pass: the fine slots of many features in one table
//! ([`SlotTable`]), a permuted residual read in place ([`Permuted`]), and the kernels that sum
//! it per slot — portable, and the AVX2 / AVX-512 builds of the same additions beside them.

use super::smoother::{Binned, FineSlots};

/// The fine slots of several features, one row after another as bytes, for the permutation
/// test's fused pass: one sweep over a permuted residual adds every row into every feature's
/// per-slot sums (the features' additions are independent, so they overlap in the CPU instead
/// of waiting on each other, and the residual is read once instead of once per feature). Each
/// slot's sum still adds its rows in row order from 0, so the sums — and every statistic from
/// them — are bit-identical to [`FTest::min_p`]'s own pass (tested).
#[derive(Debug, Clone)]
pub(crate) struct SlotTable {
    /// `codes[i·m + j]`: the fine slot of feature `j` at row `i`.
    pub(super) codes: Vec<u8>,
    /// Features.
    pub(super) m: usize,
    /// The first `signed` features also sum a second (direction-signed) residual.
    pub(super) signed: usize,
    /// Start of feature `j`'s slots in the accumulators (`offset[m]`: their length).
    pub(super) offset: Vec<usize>,
    /// Whether every feature stays in one slot for long runs of rows in seek order (at most
    /// one change of slot per [`STEADY_ROWS`] rows, as the time features' monotone bins do):
    /// then a row-permuted residual is summed with each feature's current slot held in a
    /// register ([`add_rows_held`]).
    steady: bool,
    /// Per feature, how many times its slot changes from one row to the next in seek order
    /// (the lanes' pass holds the sums of a feature that changes seldom in registers).
    pub(super) changes: Vec<usize>,
}

/// Rows per change of slot, at least, of a feature whose sums are held in registers
/// ([`add_rows_held`], and the lanes' held units).
pub(super) const STEADY_ROWS: usize = 64;

impl SlotTable {
    /// The table of `bins` (the first `signed` of them also summed for the signed residual);
    /// `None` when a feature has more than 256 fine slots (then use [`FTest::min_p`]). The
    /// features keep their own slots (a copy): the reference of [`SlotTable::take`].
    #[cfg(test)]
    pub(crate) fn new(bins: &[&Binned], signed: usize) -> Option<SlotTable> {
        if bins.iter().any(|b| b.fine.narrow().is_none()) {
            return None;
        }
        let m = bins.len();
        let n = bins.first().map_or(0, |b| b.fine.len());
        let mut codes = vec![0u8; n * m];
        for (j, b) in bins.iter().enumerate() {
            for (i, row) in codes.chunks_exact_mut(m).enumerate() {
                row[j] = b.fine_slot(i) as u8;
            }
        }
        Some(Self::of_codes(codes, bins, signed))
    }

    /// [`SlotTable::new`] of `bins` that takes their one-byte slots instead of copying them:
    /// each feature's slots are moved into the table column by column (freed as they are
    /// copied in, so the table and the features' slots are not held twice), and the
    /// features hold no slots (0 rows) until [`SlotTable::give_back`] returns them. `None`
    /// (nothing taken) when a feature has more than 256 fine slots.
    pub(crate) fn take(bins: &mut [&mut Binned], signed: usize) -> Option<SlotTable> {
        if bins.iter().any(|b| b.fine.narrow().is_none()) {
            return None;
        }
        let m = bins.len();
        let n = bins.first().map_or(0, |b| b.fine.len());
        let mut codes = vec![0u8; n * m];
        for (j, b) in bins.iter_mut().enumerate() {
            let col = b.fine.take_narrow().unwrap_or_default();
            for (row, &c) in codes.chunks_exact_mut(m).zip(&col) {
                row[j] = c;
            }
        }
        let shared: Vec<&Binned> = bins.iter().map(|b| &**b).collect();
        Some(Self::of_codes(codes, &shared, signed))
    }

    /// Puts the slots [`SlotTable::take`] took back into `bins` (the same features in the
    /// same order), freeing the table.
    pub(crate) fn give_back(self, bins: &mut [&mut Binned]) {
        let m = self.m;
        let mut codes = self.codes;
        for (j, b) in bins.iter_mut().enumerate().take(m) {
            b.fine = FineSlots::Narrow(codes.iter().skip(j).step_by(m).copied().collect());
        }
        codes.clear();
        codes.shrink_to_fit();
    }

    /// The table of the interleaved `codes` of `bins`.
    fn of_codes(codes: Vec<u8>, bins: &[&Binned], signed: usize) -> SlotTable {
        let m = bins.len();
        let n = codes.len() / m.max(1);
        let mut offset = vec![0usize];
        for b in bins {
            offset.push(offset.last().copied().unwrap_or(0) + b.n_fine + 1);
        }
        let changes: Vec<usize> = (0..m)
            .map(|j| {
                let col = codes.iter().skip(j).step_by(m);
                col.clone().zip(col.skip(1)).filter(|(a, b)| a != b).count()
            })
            .collect();
        let most = changes.iter().copied().max().unwrap_or(0);
        let signed = signed.min(m);
        SlotTable {
            steady: m <= HELD_MAX && most * STEADY_ROWS <= n,
            changes,
            codes,
            m,
            signed,
            offset,
        }
    }

    /// Whether a row-permuted residual is summed by [`add_rows_held`].
    #[cfg(test)]
    pub(crate) fn steady(&self) -> bool {
        self.steady
    }

    /// Length of the accumulators [`SlotTable::accumulate`] fills.
    pub(crate) fn len(&self) -> usize {
        self.offset[self.m]
    }

    /// Feature `j`'s sums in an accumulator filled by [`SlotTable::accumulate`].
    pub(crate) fn sums<'a>(&self, acc: &'a [f64], j: usize) -> &'a [f64] {
        &acc[self.offset[j]..self.offset[j + 1]]
    }

    /// Sets `acc` to every feature's per-slot sums of `y`, and `acc_signed` to the first
    /// `signed` features' sums of `y_signed` (ignored, and may be empty, when there are none):
    /// the fused pass over a materialised residual, the reference of
    /// [`SlotTable::accumulate_permuted`].
    #[cfg(test)]
    pub(crate) fn accumulate(
        &self,
        y: &[f64],
        y_signed: &[f64],
        acc: &mut [f64],
        acc_signed: &mut [f64],
    ) {
        acc.iter_mut().for_each(|a| *a = 0.0);
        let m = self.m;
        if m == 0 {
            return;
        }
        let offset = &self.offset[..m];
        if self.signed == 0 {
            for (row, &v) in self.codes.chunks_exact(m).zip(y) {
                for (&c, &o) in row.iter().zip(offset) {
                    acc[o + c as usize] += v;
                }
            }
        } else {
            acc_signed.iter_mut().for_each(|a| *a = 0.0);
            let ms = self.signed;
            for ((row, &v), &w) in self.codes.chunks_exact(m).zip(y).zip(y_signed) {
                for (&c, &o) in row.iter().zip(offset) {
                    acc[o + c as usize] += v;
                }
                for (&c, &o) in row[..ms].iter().zip(offset) {
                    acc_signed[o + c as usize] += w;
                }
            }
        }
    }
}

/// A permutation of a residual read in place: consecutive runs of rows of a source, so the
/// permutation test's fused pass needs no permuted copy of the residual (and no signed copy:
/// [`SlotTable::accumulate_permuted`] multiplies by the direction as it reads).
pub(crate) enum Permuted<'a> {
    /// The permuted residual itself (a row permutation, shuffled into a buffer).
    Rows(&'a [f64]),
    /// `y` rotated by `offset`, cut into consecutive blocks of `block` rows, the blocks in
    /// `order`: block `b` is rows `(i + offset) mod n` for `i` in `b·block..(b+1)·block`, at
    /// most two runs of `y`.
    Blocks {
        /// The residual.
        y: &'a [f64],
        /// Rows per block (the last block may be shorter).
        block: usize,
        /// Rotation.
        offset: usize,
        /// Block order.
        order: &'a [usize],
    },
}

/// How many blocks ahead [`Permuted::for_each_run`] prefetches a block's rows.
pub(super) const PREFETCH_BLOCKS: usize = 16;

/// A hint to bring the cache line of `x[0]` into the cache (nothing elsewhere).
#[inline(always)]
pub(crate) fn prefetch<T>(x: &[T]) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch has no effect beyond the cache; SSE is part of x86_64.
    #[allow(unused_unsafe)]
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
            x.as_ptr().cast::<i8>(),
        );
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

/// `i mod n` for `i < 2n` (a block start `b·block < n` plus an offset `< n`): one compare
/// instead of a 64-bit division per block.
#[inline(always)]
pub(super) fn wrap(i: usize, n: usize) -> usize {
    if i >= n { i - n } else { i }
}

impl Permuted<'_> {
    /// Calls `f(k, run)` for consecutive runs of the permuted residual: `run` is its rows
    /// `k..k + run.len()`, in order from row 0.
    #[inline]
    pub(crate) fn for_each_run(&self, mut f: impl FnMut(usize, &[f64])) {
        match *self {
            Permuted::Rows(v) => f(0, v),
            Permuted::Blocks {
                y,
                block,
                offset,
                order,
            } => {
                let n = y.len();
                let mut k = 0;
                for (idx, &b) in order.iter().enumerate() {
                    // The blocks are scattered over a residual larger than the cache: ask
                    // for a block's rows PREFETCH_BLOCKS blocks before they are read.
                    if let Some(&ahead) = order.get(idx + PREFETCH_BLOCKS) {
                        let start = wrap(ahead * block + offset, n);
                        prefetch(&y[start..]);
                        prefetch(&y[(start + block - 1).min(n - 1)..]);
                    }
                    let len = ((b + 1) * block).min(n) - b * block;
                    let start = wrap(b * block + offset, n);
                    let first = len.min(n - start);
                    f(k, &y[start..start + first]);
                    if len > first {
                        f(k + first, &y[..len - first]);
                    }
                    k += len;
                }
            }
        }
    }
}

impl SlotTable {
    /// [`SlotTable::accumulate`] of a permuted residual read in place, the signed residual
    /// being the permuted one times `direction` (unused, and may be empty, when no feature is
    /// signed). Returns Σ of the signed residual in row order (−0 when none is signed) and
    /// Σ of its squares (0 when none is signed; for [`sst_of_sums`]). The same additions in
    /// the same order as [`SlotTable::accumulate`] of the materialised permutation and its
    /// product (tested).
    pub(crate) fn accumulate_permuted(
        &self,
        y: &Permuted<'_>,
        direction: &[i8],
        acc: &mut [f64],
        acc_signed: &mut [f64],
    ) -> (f64, f64) {
        acc.iter_mut().for_each(|a| *a = 0.0);
        let m = self.m;
        let mut signed = (-0.0, 0.0);
        if m == 0 {
            return signed;
        }
        let offset = &self.offset[..m];
        let ms = self.signed;
        if ms > 0 {
            acc_signed.iter_mut().for_each(|a| *a = 0.0);
        }
        let codes = &self.codes[..];
        y.for_each_run(|k, run| {
            let rows = &codes[k * m..(k + run.len()) * m];
            if ms == 0 && self.steady {
                add_rows_held(rows, m, offset, run, acc);
            } else if ms == 0 {
                add_rows(rows, m, offset, run, acc);
            } else if self.steady {
                signed = add_rows_signed_held(
                    rows,
                    m,
                    ms,
                    offset,
                    run,
                    &direction[k..k + run.len()],
                    acc,
                    acc_signed,
                    signed,
                );
            } else {
                signed = add_rows_signed(
                    rows,
                    m,
                    ms,
                    offset,
                    run,
                    &direction[k..k + run.len()],
                    acc,
                    acc_signed,
                    signed,
                );
            }
        });
        signed
    }

    /// Features whose sums of the signed residual are taken.
    pub(crate) fn signed(&self) -> usize {
        self.signed
    }
}

/// Most features [`add_rows_held`] takes.
pub(super) const HELD_MAX: usize = 4;

/// [`add_rows`] (m ≤ [`HELD_MAX`]) with each feature's current slot held in a register: it is
/// written back, and the next slot read, only when the feature's slot changes. Every slot
/// still receives its rows in row order from the value it had, so the sums are the same bits
/// (tested); what goes is the chain through memory (each add waiting for the previous add's
/// store to the same slot) when a feature keeps its slot for many rows.
pub(super) fn add_rows_held(
    codes: &[u8],
    m: usize,
    offset: &[usize],
    run: &[f64],
    acc: &mut [f64],
) {
    match m {
        1 => add_rows_held_m::<1>(codes, offset, run, acc),
        2 => add_rows_held_m::<2>(codes, offset, run, acc),
        3 => add_rows_held_m::<3>(codes, offset, run, acc),
        4 => add_rows_held_m::<4>(codes, offset, run, acc),
        _ => add_rows(codes, m, offset, run, acc),
    }
}

/// [`add_rows_held`] for `M` features.
#[inline]
pub(super) fn add_rows_held_m<const M: usize>(
    codes: &[u8],
    offset: &[usize],
    run: &[f64],
    acc: &mut [f64],
) {
    if run.is_empty() {
        return;
    }
    let off: [usize; M] = std::array::from_fn(|j| offset[j]);
    let mut slot: [usize; M] = std::array::from_fn(|j| off[j] + codes[j] as usize);
    let mut held: [f64; M] = std::array::from_fn(|j| acc[slot[j]]);
    for (row, &v) in codes.chunks_exact(M).zip(run) {
        for j in 0..M {
            let s = off[j] + row[j] as usize;
            if s != slot[j] {
                acc[slot[j]] = held[j];
                slot[j] = s;
                held[j] = acc[s];
            }
            held[j] += v;
        }
    }
    for j in 0..M {
        acc[slot[j]] = held[j];
    }
}

/// Adds `run[t]` into `acc[offset[j] + codes[t·m + j]]` for every row t and feature j < m.
#[inline]
pub(super) fn add_rows(codes: &[u8], m: usize, offset: &[usize], run: &[f64], acc: &mut [f64]) {
    for (t, &v) in run.iter().enumerate() {
        let row = &codes[t * m..(t + 1) * m];
        for (&c, &o) in row.iter().zip(offset) {
            acc[o + c as usize] += v;
        }
    }
}

/// [`add_rows`], and `run[t]·d[t]` into `acc_signed` for the first `ms` features; returns
/// `(sum, sq)` plus every `run[t]·d[t]` and its square in row order (local chains, kept in
/// registers).
#[allow(clippy::too_many_arguments)]
#[inline]
pub(super) fn add_rows_signed(
    codes: &[u8],
    m: usize,
    ms: usize,
    offset: &[usize],
    run: &[f64],
    d: &[i8],
    acc: &mut [f64],
    acc_signed: &mut [f64],
    (mut sum, mut sq): (f64, f64),
) -> (f64, f64) {
    for (t, (&v, &dt)) in run.iter().zip(d).enumerate() {
        let w = v * f64::from(dt);
        sum += w;
        sq += w * w;
        let row = &codes[t * m..(t + 1) * m];
        for (&c, &o) in row.iter().zip(offset) {
            acc[o + c as usize] += v;
        }
        for (&c, &o) in row[..ms].iter().zip(offset) {
            acc_signed[o + c as usize] += w;
        }
    }
    (sum, sq)
}

/// [`add_rows_signed`] (m ≤ [`HELD_MAX`]) with each feature's current slots (plain and
/// signed) held in registers, as [`add_rows_held`]: the same adds per slot in row order.
#[allow(clippy::too_many_arguments)]
pub(super) fn add_rows_signed_held(
    codes: &[u8],
    m: usize,
    ms: usize,
    offset: &[usize],
    run: &[f64],
    d: &[i8],
    acc: &mut [f64],
    acc_signed: &mut [f64],
    sum: (f64, f64),
) -> (f64, f64) {
    let f = match m {
        1 => add_rows_signed_held_m::<1>,
        2 => add_rows_signed_held_m::<2>,
        3 => add_rows_signed_held_m::<3>,
        4 => add_rows_signed_held_m::<4>,
        _ => return add_rows_signed(codes, m, ms, offset, run, d, acc, acc_signed, sum),
    };
    f(codes, ms, offset, run, d, acc, acc_signed, sum)
}

/// [`add_rows_signed_held`] for `M` features.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(super) fn add_rows_signed_held_m<const M: usize>(
    codes: &[u8],
    ms: usize,
    offset: &[usize],
    run: &[f64],
    d: &[i8],
    acc: &mut [f64],
    acc_signed: &mut [f64],
    (mut sum, mut sq): (f64, f64),
) -> (f64, f64) {
    if run.is_empty() {
        return (sum, sq);
    }
    let off: [usize; M] = std::array::from_fn(|j| offset[j]);
    let mut slot: [usize; M] = std::array::from_fn(|j| off[j] + codes[j] as usize);
    let mut held: [f64; M] = std::array::from_fn(|j| acc[slot[j]]);
    let mut held_s: [f64; M] =
        std::array::from_fn(|j| if j < ms { acc_signed[slot[j]] } else { 0.0 });
    for ((row, &v), &dt) in codes.chunks_exact(M).zip(run).zip(d) {
        let w = v * f64::from(dt);
        sum += w;
        sq += w * w;
        for j in 0..M {
            let s = off[j] + row[j] as usize;
            if s != slot[j] {
                acc[slot[j]] = held[j];
                held[j] = acc[s];
                if j < ms {
                    acc_signed[slot[j]] = held_s[j];
                    held_s[j] = acc_signed[s];
                }
                slot[j] = s;
            }
            held[j] += v;
            if j < ms {
                held_s[j] += w;
            }
        }
    }
    for j in 0..M {
        acc[slot[j]] = held[j];
        if j < ms {
            acc_signed[slot[j]] = held_s[j];
        }
    }
    (sum, sq)
}
