//! The permutation test: the residual permuted in blocks of consecutive seeks (each feature's
//! block as long as the pair needs), every permutation on its own seeded streams, and the
//! Westfall–Young single-step min-p family-wise p-values.

use rayon::prelude::*;

use crate::numeric::rng::SimRng;
use crate::numeric::stats;

use super::ftest::{FTest, sst_of_sums, sst_one_pass};
use super::kernels::{self, Permuted, SlotTable};
use super::lanes::{BlockLane, LANES, Lanes};
use super::smoother::{Binned, Unusable};
use super::{DiagnoseConfig, FeatureOrigin, values};

/// One feature's intermediate results.
pub(super) struct Analysed {
    pub(super) binned: Binned,
    pub(super) shift: u32,
    pub(super) explained: f64,
    /// ln of the smallest F-test p-value over the plain and (if signable) the signed analysis.
    pub(super) observed: f64,
    /// Whether the direction-signed analysis explains more than the plain one.
    pub(super) by_direction: bool,
    /// Whether the signed analysis was run for this feature.
    pub(super) signable: bool,
    /// Built-in feature or logged covariate.
    pub(super) origin: FeatureOrigin,
}

/// Fisher–Yates shuffle with the seeded generator.
pub(super) fn shuffle<T>(v: &mut [T], rng: &mut SimRng) {
    for i in (1..v.len()).rev() {
        let j = rng.below(i as u64 + 1) as usize;
        v.swap(i, j);
    }
}

/// [`shuffle`] of a residual, the same swaps in the same order (so the same permutation,
/// tested): the random indices of a chunk are drawn first ([`SimRng::below_descending`],
/// without a division per draw), then each swap prefetches the row it will swap
/// [`SHUFFLE_AHEAD`] swaps later, so the cache misses of a residual larger than the cache
/// overlap instead of following one another (a prefetch, unlike a load, does not hold the
/// swaps behind it while it waits).
pub(super) fn shuffle_rows<T: Copy>(v: &mut [T], rng: &mut SimRng) {
    const CHUNK: usize = 4096;
    if v.len() < 2 {
        return;
    }
    let mut js: Vec<u64> = Vec::with_capacity(CHUNK);
    let mut i = v.len() - 1;
    while i >= 1 {
        let lo = i.saturating_sub(CHUNK - 1).max(1);
        js.clear();
        rng.below_descending(lo as u64, i as u64, &mut js);
        for (step, &j) in js.iter().enumerate() {
            if let Some(&ahead) = js.get(step + SHUFFLE_AHEAD) {
                kernels::prefetch(&v[ahead as usize..]);
            }
            v.swap(i - step, j as usize);
        }
        i = lo - 1;
    }
}

/// How many swaps ahead [`shuffle_rows`] reads its rows.
pub(super) const SHUFFLE_AHEAD: usize = 32;

/// Longest block of the automatic permutation null, in seeks.
pub(crate) const MAX_NULL_BLOCK: usize = 200;

/// The automatic null block is this many times the residual's decorrelation lag.
pub(crate) const NULL_BLOCK_FACTOR: usize = 6;

/// The autocorrelation below which the residual counts as decorrelated (automatic null block).
pub(crate) const NULL_ACF: f64 = 0.1;

/// The block length of the permutation null for residual `y`: [`NULL_BLOCK_FACTOR`] times the
/// first lag at which its autocorrelation falls below [`NULL_ACF`], at most [`MAX_NULL_BLOCK`]
/// and n/8 (so there are at least 8 blocks to permute), at least 1. Serial correlation shorter
/// than a block is kept by the null (a block boundary cuts it, so the block must be several
/// correlation lengths long for the null not to be too narrow), so a slowly varying feature is
/// not flagged for riding on it. Structure slower than the block is what the time features
/// (`elapsed_s`, `seek_index` → `drift`) stand for, and a slow column must add to them to be
/// flagged.
pub(crate) fn null_block_len(y: &[f64]) -> usize {
    let n = y.len();
    let cap = MAX_NULL_BLOCK.min(n / 8).max(1);
    let longest = cap.div_ceil(NULL_BLOCK_FACTOR);
    // The first lag below NULL_ACF, as `autocorrelation` lag by lag finds it (the same bits;
    // several lags a pass).
    let k0 = stats::first_lag_below(y, longest, NULL_ACF).unwrap_or(longest);
    (NULL_BLOCK_FACTOR * k0).clamp(1, cap)
}

/// The null block of one feature beside a residual whose own null block is `residual_block`:
/// [`null_block_len`] of the feature's values in seek order (undefined rows at the mean),
/// rounded up to a power of two, at most `residual_block`. A feature that is exchangeable in
/// seek order (random targets) gets short blocks, a slow column the residual's. NaN marks an
/// undefined value.
pub(crate) fn feature_null_block(
    values: std::borrow::Cow<'_, [f64]>,
    residual_block: usize,
) -> usize {
    // The mean of the defined values, summed in row order as `stats::mean` sums them.
    let defined = || values.iter().copied().filter(|x| !x.is_nan());
    let count = defined().count();
    let mean = if count > 0 {
        defined().sum::<f64>() / count as f64
    } else {
        0.0
    };
    // One buffer: the decoded column itself where it was decoded for this call.
    let mut filled = values.into_owned();
    for v in &mut filled {
        *v = values::defined(*v).unwrap_or(mean) - mean;
    }
    null_block_len(&filled)
        .next_power_of_two()
        .min(residual_block)
        .max(1)
}

/// Writes into `out` a block permutation of `y`: `y` rotated by a random offset (so block
/// boundaries are not fixed), cut into consecutive blocks of `block` rows, the blocks
/// concatenated in random order. `block == 1` is a plain row permutation.
pub(super) fn block_permute(y: &[f64], block: usize, out: &mut [f64], rng: &mut SimRng) {
    let n = y.len();
    if block <= 1 {
        out.copy_from_slice(y);
        shuffle_rows(out, rng);
        return;
    }
    let mut order = Vec::new();
    let offset = draw_blocks(n, block, &mut order, rng);
    Permuted::Blocks {
        y,
        block,
        offset,
        order: &order,
    }
    .for_each_run(|k, run| out[k..k + run.len()].copy_from_slice(run));
}

/// The random part of a block permutation of `n` rows in blocks of `block` (> 1): the
/// rotation offset (returned) and the order of the blocks (written to `order`), drawn as
/// [`block_permute_reference`] draws them.
pub(super) fn draw_blocks(
    n: usize,
    block: usize,
    order: &mut Vec<usize>,
    rng: &mut SimRng,
) -> usize {
    let offset = rng.below(n as u64) as usize;
    order.clear();
    order.extend(0..n.div_ceil(block));
    shuffle_rows(order, rng);
    offset
}

/// [`block_permute`] written row by row with the modulo (the slow, obvious reference it is
/// tested against).
#[cfg(test)]
pub(super) fn block_permute_reference(y: &[f64], block: usize, out: &mut [f64], rng: &mut SimRng) {
    let n = y.len();
    if block <= 1 {
        out.copy_from_slice(y);
        shuffle(out, rng);
        return;
    }
    let offset = rng.below(n as u64) as usize;
    let n_blocks = n.div_ceil(block);
    let mut order: Vec<usize> = (0..n_blocks).collect();
    shuffle(&mut order, rng);
    let mut k = 0;
    for b in order {
        for i in b * block..((b + 1) * block).min(n) {
            out[k] = y[(i + offset) % n];
            k += 1;
        }
    }
}

/// First random stream of the permutations: permutation `i` draws its permutation for the
/// `b`-th distinct block length from stream `PERM_STREAM + PERM_STRIDE·i + b` of the diagnosis
/// seed (streams 1–3 are the folds' and older uses).
pub(super) const PERM_STREAM: u64 = 1 << 32;

/// Streams reserved per permutation (more than the distinct block lengths: powers of two up to
/// [`MAX_NULL_BLOCK`], 1 and the residual's own).
pub(super) const PERM_STRIDE: u64 = 16;

/// The features tested against one block length's permutation, swept in one fused pass
/// ([`SlotTable`]): their indices into the usable features, the signable ones first.
pub(super) struct PermGroup {
    /// Block length index (into the distinct lengths).
    length: usize,
    /// Usable-feature indices, signable first.
    features: Vec<usize>,
    /// Their fine slots; `None` (a feature with more than 256 slots) tests the group one
    /// feature at a time with [`FTest::min_p`].
    table: Option<SlotTable>,
}

/// The groups of the fused permutation pass: one per distinct block length (`which[k]`: the
/// length of usable feature `k`), signable features first when the residual is signed. Each
/// group's [`SlotTable`] takes its features' one-byte slots from `analysed` (`usable[k]`:
/// the index of usable feature `k` there); [`give_back`] returns them.
pub(super) fn perm_groups(
    analysed: &mut [Result<Analysed, Unusable>],
    usable: &[usize],
    lengths: usize,
    which: &[usize],
    signed: bool,
    fused: bool,
) -> Vec<PermGroup> {
    let is_signed = |a: &Analysed| signed && a.signable;
    let mut groups: Vec<(PermGroup, Vec<&mut Binned>)> = (0..lengths)
        .map(|length| {
            let group = PermGroup {
                length,
                features: Vec::new(),
                table: None,
            };
            (group, Vec::new())
        })
        .collect();
    // Signable first, each part in usable order (the mutable borrows are handed out in
    // usable order, then each group's are reordered alike).
    let mut usable_at = vec![usize::MAX; analysed.len()];
    for (k, &j) in usable.iter().enumerate() {
        usable_at[j] = k;
    }
    let mut members: Vec<Vec<(bool, usize, &mut Binned)>> =
        (0..lengths).map(|_| Vec::new()).collect();
    for (j, a) in analysed.iter_mut().enumerate() {
        if let (Ok(a), Some(&k)) = (a.as_mut(), usable_at.get(j).filter(|&&k| k != usize::MAX)) {
            let s = is_signed(a);
            members[which[k]].push((!s, k, &mut a.binned));
        }
    }
    for ((g, bins), mut ms) in groups.iter_mut().zip(members) {
        // Stable: signable first, each part in usable order.
        ms.sort_by_key(|&(unsigned, k, _)| (unsigned, k));
        let n_signed = ms.iter().filter(|(unsigned, _, _)| !unsigned).count();
        g.features = ms.iter().map(|&(_, k, _)| k).collect();
        bins.extend(ms.into_iter().map(|(_, _, b)| b));
        g.table = if fused {
            SlotTable::take(bins, n_signed)
        } else {
            None
        };
    }
    groups
        .into_iter()
        .map(|(g, _)| g)
        .filter(|g| !g.features.is_empty())
        .collect()
}

/// Returns the slots the groups' tables took ([`perm_groups`]) to the features of
/// `analysed` (`usable[k]`: the index of usable feature `k` there), freeing the tables.
pub(super) fn give_back(
    groups: Vec<PermGroup>,
    analysed: &mut [Result<Analysed, Unusable>],
    usable: &[usize],
) {
    let mut bins: Vec<Option<&mut Binned>> = analysed
        .iter_mut()
        .map(|a| a.as_mut().ok().map(|a| &mut a.binned))
        .collect();
    for g in groups {
        if let Some(table) = g.table {
            let mut mine: Vec<&mut Binned> = g
                .features
                .iter()
                .filter_map(|&k| bins[usable[k]].take())
                .collect();
            table.give_back(&mut mine);
        }
    }
}

/// One thread's buffers and hit counts of the permutation test (one slot per usable feature).
pub(super) struct PermWorker {
    tests: Vec<FTest>,
    /// The row permutation of the residual (block length 1), shuffled in place.
    rows: Vec<f64>,
    /// The block orders of the [`LANES`] block permutations of a batch.
    orders: [Vec<usize>; LANES],
    /// A materialised permutation and its direction-signed copy, for a group without a
    /// [`SlotTable`] only.
    perm: Vec<f64>,
    signed: Vec<f64>,
    /// Per-slot sums of the fused pass (plain and signed residual) of one permutation.
    acc: Vec<f64>,
    acc_signed: Vec<f64>,
    /// The same for the lanes of a batch, and the batch's gathered rows.
    acc_lanes: Vec<Lanes>,
    acc_signed_lanes: Vec<Lanes>,
    chunk: Vec<Lanes>,
    /// `stat[l·m + k]`: feature `k`'s statistic in permutation `l` of the batch.
    stat: Vec<f64>,
}

/// What every permutation of one test shares.
pub(super) struct PermInput<'a, 'b> {
    usable: &'a [(usize, &'b Analysed)],
    y: &'a [f64],
    sst: f64,
    direction: Option<&'a [i8]>,
    lengths: &'a [usize],
    groups: &'a [PermGroup],
    seed: u64,
    permutations: usize,
}

impl PermWorker {
    /// A worker with its own copy of the usable features' F-tests (`tests`: their counts
    /// are counted once, not once per worker).
    fn new(tests: &[FTest]) -> PermWorker {
        let m = tests.len();
        PermWorker {
            tests: tests.to_vec(),
            rows: Vec::new(),
            orders: Default::default(),
            perm: Vec::new(),
            signed: Vec::new(),
            acc: Vec::new(),
            acc_signed: Vec::new(),
            acc_lanes: Vec::new(),
            acc_signed_lanes: Vec::new(),
            chunk: Vec::new(),
            stat: vec![0.0; m * LANES],
        }
    }

    /// The random generator of permutation `i` for block length index `b`.
    fn rng(seed: u64, i: usize, b: usize) -> SimRng {
        SimRng::substream(seed, PERM_STREAM + PERM_STRIDE * i as u64 + b as u64)
    }

    /// Permutations `LANES·batch ..` (at most [`LANES`], fewer at the end): the residual
    /// permuted once per distinct block length, each feature tested against the permutation
    /// of its own block (`groups`, one per length, one fused pass each over the permutation
    /// read in place — the block permutations of the batch side by side in the lanes of one
    /// vector); the family-wise statistic is the smallest over features. Each permutation
    /// draws from its own streams, and each lane's sums are those of its own pass, so the
    /// statistics are those of one permutation at a time. Returns how many permutations the
    /// batch holds; their statistics are `self.stat[..count·m]`.
    fn run_batch(&mut self, batch: usize, p: &PermInput) -> usize {
        let first = LANES * batch;
        let count = LANES.min(p.permutations - first);
        let m = p.usable.len();
        let n = p.y.len();
        let mut stat = std::mem::take(&mut self.stat);
        for g in p.groups {
            let len = p.lengths[g.length];
            match &g.table {
                Some(table) if len > 1 => {
                    let mut offsets = [0usize; LANES];
                    for (l, offset) in offsets.iter_mut().enumerate().take(count) {
                        let mut rng = Self::rng(p.seed, first + l, g.length);
                        *offset = draw_blocks(n, len, &mut self.orders[l], &mut rng);
                    }
                    // Unused lanes (the last batch) repeat lane 0; their sums are ignored.
                    let lanes: [BlockLane; LANES] = std::array::from_fn(|l| {
                        let l = if l < count { l } else { 0 };
                        BlockLane {
                            offset: offsets[l],
                            order: &self.orders[l],
                        }
                    });
                    let d = p.direction.filter(|_| table.signed() > 0).unwrap_or(&[]);
                    let (sum, sq) = table.accumulate_lanes(
                        p.y,
                        len,
                        &lanes,
                        d,
                        &mut self.chunk,
                        &mut self.acc_lanes,
                        &mut self.acc_signed_lanes,
                    );
                    // The signed sum of squares from the pass's own sums (no second gather).
                    let sst_signed: [f64; LANES] =
                        std::array::from_fn(|l| sst_of_sums(sum[l], sq[l], n));
                    for l in 0..count {
                        self.acc.clear();
                        self.acc.extend(self.acc_lanes.iter().map(|a| a[l]));
                        self.acc_signed.clear();
                        if table.signed() > 0 {
                            self.acc_signed
                                .extend(self.acc_signed_lanes.iter().map(|a| a[l]));
                        }
                        let stat = &mut stat[l * m..(l + 1) * m];
                        for (j, &k) in g.features.iter().enumerate() {
                            let (t, a) = (&mut self.tests[k], p.usable[k].1);
                            stat[k] =
                                t.min_p_of_sums(&a.binned, table.sums(&self.acc, j), n, p.sst);
                            if j < table.signed() {
                                let sums = table.sums(&self.acc_signed, j);
                                stat[k] =
                                    stat[k].min(t.min_p_of_sums(&a.binned, sums, n, sst_signed[l]));
                            }
                        }
                    }
                }
                _ => {
                    for l in 0..count {
                        let mut rng = Self::rng(p.seed, first + l, g.length);
                        self.run_group(g, len, &mut rng, p, &mut stat[l * m..(l + 1) * m]);
                    }
                }
            }
        }
        self.stat = stat;
        count
    }

    /// One permutation of group `g` (block length `len`) drawn from `rng`, one at a time: the
    /// row permutation shuffled into a buffer and read by the fused pass, or (no
    /// [`SlotTable`]) materialised and tested feature by feature. Writes the group's
    /// features' statistics into `stat`.
    fn run_group(
        &mut self,
        g: &PermGroup,
        len: usize,
        rng: &mut SimRng,
        p: &PermInput,
        stat: &mut [f64],
    ) {
        let (y, n, sst) = (p.y, p.y.len(), p.sst);
        match &g.table {
            Some(table) => {
                let permuted = if len <= 1 {
                    self.rows.clear();
                    self.rows.extend_from_slice(y);
                    shuffle_rows(&mut self.rows, rng);
                    Permuted::Rows(&self.rows)
                } else {
                    let offset = draw_blocks(n, len, &mut self.orders[0], rng);
                    Permuted::Blocks {
                        y,
                        block: len,
                        offset,
                        order: &self.orders[0],
                    }
                };
                self.acc.resize(table.len(), 0.0);
                self.acc_signed.resize(table.len(), 0.0);
                let d = p.direction.filter(|_| table.signed() > 0).unwrap_or(&[]);
                let (sum, sq) =
                    table.accumulate_permuted(&permuted, d, &mut self.acc, &mut self.acc_signed);
                let sst_signed = sst_of_sums(sum, sq, n);
                for (j, &k) in g.features.iter().enumerate() {
                    let (t, a) = (&mut self.tests[k], p.usable[k].1);
                    stat[k] = t.min_p_of_sums(&a.binned, table.sums(&self.acc, j), n, sst);
                    if j < table.signed() {
                        let sums = table.sums(&self.acc_signed, j);
                        stat[k] = stat[k].min(t.min_p_of_sums(&a.binned, sums, n, sst_signed));
                    }
                }
            }
            None => {
                self.perm.resize(n, 0.0);
                block_permute(y, len, &mut self.perm, rng);
                let mut sst_signed = 0.0;
                if let Some(d) = p.direction {
                    self.signed.clear();
                    self.signed
                        .extend(self.perm.iter().zip(d).map(|(p, &d)| p * f64::from(d)));
                    sst_signed = sst_one_pass(&self.signed);
                }
                for &k in &g.features {
                    let (t, a) = (&mut self.tests[k], p.usable[k].1);
                    stat[k] = t.min_p(&a.binned, &self.perm, sst);
                    if a.signable && p.direction.is_some() {
                        stat[k] = stat[k].min(t.min_p(&a.binned, &self.signed, sst_signed));
                    }
                }
            }
        }
    }
}

/// Every permutation's statistic of every feature: `stats[i·m + j]` is feature `j`'s (of
/// `m`, in `analysed` order) ln of its smallest F-test p-value on permutation `i`, 0 (p = 1)
/// for an unusable feature; and the F-test's observed value per feature (the same, 0 for an
/// unusable one). What the family-wise p-values of one log ([`permutation_test`]) and of a
/// fleet of logs (the pooled screen) are counted from.
pub(crate) struct NullStatistics {
    /// Permutations (rows of `stats`).
    pub(crate) permutations: usize,
    /// Row-major, one row per permutation.
    pub(crate) stats: Vec<f64>,
    /// The observed statistic per feature.
    pub(crate) observed: Vec<f64>,
    /// Whether the feature was tested (usable, and a residual with variance).
    pub(crate) tested: Vec<bool>,
}

/// The statistics of `config.permutations` block permutations of `y` for every feature
/// (feature `j` against permutations of `blocks[j]` consecutive residuals; 1: rows permuted one
/// by one). `fused`: the statistics of many features from one pass over each permuted residual
/// ([`SlotTable`]); else each feature's own pass ([`FTest::min_p`], the slow reference — the
/// results are bit-identical, tested). Every permutation draws from its own seeded streams, so
/// the statistics are the same for any number of threads.
pub(crate) fn permutation_statistics(
    analysed: &mut [Result<Analysed, Unusable>],
    y: &[f64],
    sst: f64,
    direction: Option<&[i8]>,
    blocks: &[usize],
    config: &DiagnoseConfig,
    fused: bool,
) -> NullStatistics {
    let m = analysed.len();
    let b = config.permutations;
    let mut out = NullStatistics {
        permutations: b,
        stats: vec![0.0; b * m],
        observed: analysed
            .iter()
            .map(|a| a.as_ref().map_or(0.0, |a| a.observed))
            .collect(),
        tested: vec![false; m],
    };
    let usable_idx: Vec<usize> = (0..m).filter(|&j| analysed[j].is_ok()).collect();
    if sst.is_nan() || sst <= 0.0 || usable_idx.is_empty() {
        out.observed.iter_mut().for_each(|o| *o = 0.0);
        return out;
    }
    let mut lengths: Vec<usize> = usable_idx.iter().map(|&j| blocks[j]).collect();
    lengths.sort_unstable();
    lengths.dedup();
    let which: Vec<usize> = usable_idx
        .iter()
        .map(|&j| lengths.binary_search(&blocks[j]).unwrap_or(0))
        .collect();
    // The counts before the slot tables take the features' slots.
    let tests: Vec<FTest> = usable_idx
        .par_iter()
        .filter_map(|&j| analysed[j].as_ref().ok())
        .map(|a| FTest::new(&a.binned))
        .collect();
    let groups = perm_groups(
        analysed,
        &usable_idx,
        lengths.len(),
        &which,
        direction.is_some(),
        fused,
    );
    let usable: Vec<(usize, &Analysed)> = analysed
        .iter()
        .enumerate()
        .filter_map(|(j, a)| a.as_ref().ok().map(|a| (j, a)))
        .collect();
    let k = usable.len();
    let input = PermInput {
        usable: &usable,
        y,
        sst,
        direction,
        lengths: &lengths,
        groups: &groups,
        seed: config.seed,
        permutations: b,
    };
    // One batch of up to LANES permutations per task, collected in batch order.
    let batches: Vec<Vec<f64>> = (0..b.div_ceil(LANES))
        .into_par_iter()
        .map_init(
            || PermWorker::new(&tests),
            |w, batch| {
                let count = w.run_batch(batch, &input);
                w.stat[..count * k].to_vec()
            },
        )
        .collect();
    drop(usable);
    give_back(groups, analysed, &usable_idx);
    for (i, row) in batches.iter().flat_map(|s| s.chunks_exact(k)).enumerate() {
        for (&j, &v) in usable_idx.iter().zip(row) {
            out.stats[i * m + j] = v;
        }
    }
    for &j in &usable_idx {
        out.tested[j] = true;
    }
    out
}

/// [`family_wise_p_values`] of one log's statistics.
pub(crate) fn p_values(null: &NullStatistics) -> (Vec<f64>, Vec<f64>) {
    family_wise_p_values(null.permutations, &null.observed, &null.stats, &null.tested)
}

/// Raw and Westfall–Young single-step min-p family-wise p-values of `m` features from their
/// observed statistics (`observed`, smaller is stronger) and their statistics under each of
/// `permutations` permutations (`null`, row-major permutations × features): raw, the fraction
/// of permutations (the observed one counted) in which the feature's own statistic is at least
/// as strong (≤); family-wise, in which the strongest of the tested features is. 1 for a
/// feature not `tested`. The counts of one log's diagnosis and of a fleet's pooled screen.
pub fn family_wise_p_values(
    permutations: usize,
    observed: &[f64],
    null: &[f64],
    tested: &[bool],
) -> (Vec<f64>, Vec<f64>) {
    let m = observed.len();
    let mut raw = vec![0usize; m];
    let mut adj = vec![0usize; m];
    for row in null.chunks_exact(m.max(1)).take(permutations) {
        let min_stat = row
            .iter()
            .zip(tested)
            .filter(|&(_, &t)| t)
            .map(|(&s, _)| s)
            .fold(f64::INFINITY, f64::min);
        for j in (0..m).filter(|&j| tested[j]) {
            if row[j] <= observed[j] {
                raw[j] += 1;
            }
            if min_stat <= observed[j] {
                adj[j] += 1;
            }
        }
    }
    let b = permutations as f64 + 1.0;
    let p = |counts: Vec<usize>| -> Vec<f64> {
        counts
            .iter()
            .zip(tested)
            .map(|(&c, &t)| if t { (c as f64 + 1.0) / b } else { 1.0 })
            .collect()
    };
    (p(raw), p(adj))
}

/// Raw and Westfall–Young family-wise permutation p-values for every feature (1 for unusable
/// ones): [`p_values`] of [`permutation_statistics`].
pub(super) fn permutation_test(
    analysed: &mut [Result<Analysed, Unusable>],
    y: &[f64],
    sst: f64,
    direction: Option<&[i8]>,
    blocks: &[usize],
    config: &DiagnoseConfig,
    fused: bool,
) -> (Vec<f64>, Vec<f64>) {
    p_values(&permutation_statistics(
        analysed, y, sst, direction, blocks, config, fused,
    ))
}
