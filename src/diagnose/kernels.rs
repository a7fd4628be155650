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
    codes: Vec<u8>,
    /// Features.
    m: usize,
    /// The first `signed` features also sum a second (direction-signed) residual.
    signed: usize,
    /// Start of feature `j`'s slots in the accumulators (`offset[m]`: their length).
    offset: Vec<usize>,
    /// Whether every feature stays in one slot for long runs of rows in seek order (at most
    /// one change of slot per [`STEADY_ROWS`] rows, as the time features' monotone bins do):
    /// then a row-permuted residual is summed with each feature's current slot held in a
    /// register ([`add_rows_held`]).
    steady: bool,
}

/// Rows per change of slot, at least, of a [`SlotTable`] summed with [`add_rows_held`].
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
        let changes = (0..m)
            .map(|j| {
                let col = codes.iter().skip(j).step_by(m);
                col.clone().zip(col.skip(1)).filter(|(a, b)| a != b).count()
            })
            .max()
            .unwrap_or(0);
        SlotTable {
            steady: m <= HELD_MAX && changes * STEADY_ROWS <= n,
            codes,
            m,
            signed: signed.min(m),
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

/// Permutations summed side by side, one per lane of a vector, by
/// [`SlotTable::accumulate_lanes`] (eight `f64`: one 512-bit register with AVX-512, two
/// 256-bit ones with AVX2).
pub(crate) const LANES: usize = 8;

/// Rows per chunk of [`SlotTable::accumulate_lanes`]: the lanes' permuted rows are gathered
/// into a chunk of `CHUNK × LANES` values (32 KiB, in L1/L2) before they are summed.
pub(super) const CHUNK: usize = 512;

/// One lane's block permutation, read in place: the residual rotated by `offset`, cut into
/// blocks of `block` rows taken in `order` (as [`Permuted::Blocks`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct BlockLane<'a> {
    /// Rotation.
    pub(crate) offset: usize,
    /// Block order.
    pub(crate) order: &'a [usize],
}

/// Where one lane's gathering stands: the block (index into its order) and the row in it.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Cursor {
    idx: usize,
    pos: usize,
}

/// Copies the next `out.len()` rows of lane `lane`'s block permutation of `y` (blocks of
/// `block` rows) into `out[t][slot]`, advancing `cur`; prefetches the rows of the block
/// [`PREFETCH_BLOCKS`] blocks ahead, as [`Permuted::for_each_run`] does.
#[inline(always)]
pub(super) fn gather_lane(
    y: &[f64],
    block: usize,
    lane: &BlockLane<'_>,
    slot: usize,
    cur: &mut Cursor,
    out: &mut [[f64; LANES]],
) {
    let n = y.len();
    let mut t = 0;
    while t < out.len() {
        let b = lane.order[cur.idx];
        let len = ((b + 1) * block).min(n) - b * block;
        let take = (len - cur.pos).min(out.len() - t);
        // The block's rows from `cur.pos` on: at most two runs of `y` (it may wrap).
        let start = wrap(b * block + lane.offset + cur.pos, n);
        let first = take.min(n - start);
        for (o, &v) in out[t..t + first].iter_mut().zip(&y[start..start + first]) {
            o[slot] = v;
        }
        for (o, &v) in out[t + first..t + take].iter_mut().zip(&y[..take - first]) {
            o[slot] = v;
        }
        t += take;
        cur.pos += take;
        if cur.pos == len {
            cur.pos = 0;
            cur.idx += 1;
            if let Some(&ahead) = lane.order.get(cur.idx + PREFETCH_BLOCKS) {
                let s = wrap(ahead * block + lane.offset, n);
                prefetch(&y[s..]);
                prefetch(&y[(s + block - 1).min(n - 1)..]);
            }
        }
    }
}

/// The [`LANES`] block permutations of `y`, gathered chunk by chunk in row order from row 0
/// (`next` fills `buf[t][l]` with row `k + t` of lane `l`'s permutation).
pub(super) struct Chunks<'a, 'b> {
    y: &'a [f64],
    block: usize,
    lanes: &'a [BlockLane<'b>; LANES],
    cur: [Cursor; LANES],
    k: usize,
}

impl<'a, 'b> Chunks<'a, 'b> {
    /// Starts at row 0 (asking for the first blocks' rows).
    #[inline(always)]
    fn new(y: &'a [f64], block: usize, lanes: &'a [BlockLane<'b>; LANES]) -> Self {
        let n = y.len();
        for lane in lanes {
            for &b in lane.order.iter().take(PREFETCH_BLOCKS) {
                prefetch(&y[wrap(b * block + lane.offset, n)..]);
            }
        }
        Chunks {
            y,
            block,
            lanes,
            cur: [Cursor::default(); LANES],
            k: 0,
        }
    }

    /// Gathers the next chunk into `buf` (at most `buf.len()` rows): its first row and its
    /// length, `None` after the last row.
    #[inline(always)]
    fn next(&mut self, buf: &mut [[f64; LANES]]) -> Option<(usize, usize)> {
        let k = self.k;
        let c = buf.len().min(self.y.len() - k);
        if c == 0 {
            return None;
        }
        for (l, lane) in self.lanes.iter().enumerate() {
            gather_lane(self.y, self.block, lane, l, &mut self.cur[l], &mut buf[..c]);
        }
        self.k += c;
        Some((k, c))
    }
}

/// `v[l]·d` for every lane (one vector multiplication).
#[inline(always)]
pub(super) fn scale_lanes(v: &[f64; LANES], d: f64) -> [f64; LANES] {
    let mut w = [0.0; LANES];
    for l in 0..LANES {
        w[l] = v[l] * d;
    }
    w
}

/// `a[l]·b[l]` for every lane (one vector multiplication).
#[inline(always)]
pub(super) fn mul_lanes(a: &[f64; LANES], b: &[f64; LANES]) -> [f64; LANES] {
    let mut w = [0.0; LANES];
    for l in 0..LANES {
        w[l] = a[l] * b[l];
    }
    w
}

/// `a[l] += v[l]` for every lane (one vector addition; each lane its own IEEE sum).
#[inline(always)]
pub(super) fn add_lanes(a: &mut [f64; LANES], v: &[f64; LANES]) {
    for l in 0..LANES {
        a[l] += v[l];
    }
}

impl SlotTable {
    /// [`SlotTable::accumulate_permuted`] of [`LANES`] block permutations (blocks of `block`
    /// rows > 1) at once: `acc[s][l]` is lane `l`'s sum of slot `s`, `acc_signed` the same
    /// for the signed residual (permuted × `direction`; unused, and may be empty, when no
    /// feature is signed). Returns each lane's Σ of the signed residual in row order (−0 when
    /// none is signed) and Σ of its squares (0 when none is signed). Each lane's sums take the same additions in the same order as
    /// [`SlotTable::accumulate_permuted`] of that lane's permutation, so they are the same
    /// bits (tested); the lanes of one row are added by one vector instruction. Runs the
    /// AVX2 copy when the CPU has it (lane-wise additions and products, no fused
    /// multiply-add: the same results).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn accumulate_lanes(
        &self,
        y: &[f64],
        block: usize,
        lanes: &[BlockLane<'_>; LANES],
        direction: &[i8],
        buf: &mut Vec<[f64; LANES]>,
        acc: &mut Vec<[f64; LANES]>,
        acc_signed: &mut Vec<[f64; LANES]>,
    ) -> ([f64; LANES], [f64; LANES]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU supports AVX-512F (checked just above).
            return unsafe {
                self.accumulate_lanes_avx512(y, block, lanes, direction, buf, acc, acc_signed)
            };
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe {
                self.accumulate_lanes_avx2(y, block, lanes, direction, buf, acc, acc_signed)
            };
        }
        self.accumulate_lanes_portable(y, block, lanes, direction, buf, acc, acc_signed)
    }

    /// [`SlotTable::accumulate_lanes`] compiled for AVX-512F (the lanes' sums in one
    /// register; each lane's additions the same, in the same order, as any other build's).
    ///
    /// # Safety
    /// The CPU must support AVX-512F.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn accumulate_lanes_avx512(
        &self,
        y: &[f64],
        block: usize,
        lanes: &[BlockLane<'_>; LANES],
        direction: &[i8],
        buf: &mut Vec<[f64; LANES]>,
        acc: &mut Vec<[f64; LANES]>,
        acc_signed: &mut Vec<[f64; LANES]>,
    ) -> ([f64; LANES], [f64; LANES]) {
        self.accumulate_lanes_portable(y, block, lanes, direction, buf, acc, acc_signed)
    }

    /// [`SlotTable::accumulate_lanes`] compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn accumulate_lanes_avx2(
        &self,
        y: &[f64],
        block: usize,
        lanes: &[BlockLane<'_>; LANES],
        direction: &[i8],
        buf: &mut Vec<[f64; LANES]>,
        acc: &mut Vec<[f64; LANES]>,
        acc_signed: &mut Vec<[f64; LANES]>,
    ) -> ([f64; LANES], [f64; LANES]) {
        self.accumulate_lanes_portable(y, block, lanes, direction, buf, acc, acc_signed)
    }

    /// [`SlotTable::accumulate_lanes`] for any CPU.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn accumulate_lanes_portable(
        &self,
        y: &[f64],
        block: usize,
        lanes: &[BlockLane<'_>; LANES],
        direction: &[i8],
        buf: &mut Vec<[f64; LANES]>,
        acc: &mut Vec<[f64; LANES]>,
        acc_signed: &mut Vec<[f64; LANES]>,
    ) -> ([f64; LANES], [f64; LANES]) {
        let m = self.m;
        let mut sum = [-0.0; LANES];
        let mut sq = [0.0; LANES];
        acc.clear();
        acc.resize(self.len(), [0.0; LANES]);
        if m == 0 {
            return (sum, sq);
        }
        let ms = self.signed;
        if ms > 0 {
            acc_signed.clear();
            acc_signed.resize(self.len(), [0.0; LANES]);
        }
        let offset = &self.offset[..m];
        let codes = &self.codes[..];
        let (acc, acc_signed) = (&mut acc[..], &mut acc_signed[..]);
        buf.resize(CHUNK, [0.0; LANES]);
        let mut chunks = Chunks::new(y, block, lanes);
        while let Some((k, c)) = chunks.next(buf) {
            let chunk = &buf[..c];
            let rows = &codes[k * m..(k + c) * m];
            if ms == 0 {
                for (row, v) in rows.chunks_exact(m).zip(chunk) {
                    // A local copy: one register, not reloaded after every store to `acc`.
                    let v = *v;
                    for (&c, &o) in row.iter().zip(offset) {
                        add_lanes(&mut acc[o + c as usize], &v);
                    }
                }
            } else {
                let d = &direction[k..k + chunk.len()];
                for ((row, v), &dt) in rows.chunks_exact(m).zip(chunk).zip(d) {
                    let v = *v;
                    let w = scale_lanes(&v, f64::from(dt));
                    add_lanes(&mut sum, &w);
                    add_lanes(&mut sq, &mul_lanes(&w, &w));
                    for (&c, &o) in row.iter().zip(offset) {
                        add_lanes(&mut acc[o + c as usize], &v);
                    }
                    for (&c, &o) in row[..ms].iter().zip(offset) {
                        add_lanes(&mut acc_signed[o + c as usize], &w);
                    }
                }
            }
        }
        (sum, sq)
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
