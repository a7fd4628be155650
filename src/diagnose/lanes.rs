//! The permutation test's fused pass over [`LANES`] block permutations at once
//! ([`SlotTable::accumulate_lanes`]): the lanes' permuted rows gathered chunk by chunk, then
//! added into every feature's per-slot sums unit by unit ([`Plan`]) — the features that keep
//! their slot for long runs of rows with their sums held in registers, the others in panels
//! whose sums stay in the L1 cache. Every slot takes its rows in row order, so each lane's sums
//! are the bits of [`SlotTable::accumulate_permuted`]'s for that lane's permutation (tested).

use super::kernels::{PREFETCH_BLOCKS, STEADY_ROWS, SlotTable, prefetch, wrap};

/// Permutations summed side by side, one per lane of a vector, by
/// [`SlotTable::accumulate_lanes`] (eight `f64`: one 512-bit register with AVX-512, two
/// 256-bit ones with AVX2).
pub(crate) const LANES: usize = 8;

/// The [`LANES`] values of one slot's sums or of one gathered row, on one 64-byte cache line:
/// a `Vec` of bare `[f64; LANES]` is only 16-byte aligned, so every vector load and store of
/// the sums straddled two lines (a split access, which the store-to-load forwarding of a
/// slot's next addition does not take either).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[repr(C, align(64))]
pub(crate) struct Lanes(pub(crate) [f64; LANES]);

impl std::ops::Index<usize> for Lanes {
    type Output = f64;
    #[inline(always)]
    fn index(&self, l: usize) -> &f64 {
        &self.0[l]
    }
}

/// Rows per chunk of [`SlotTable::accumulate_lanes`]: the lanes' permuted rows are gathered
/// into a chunk of `CHUNK × LANES` values (16 KiB: with a panel's sums, in the L1 cache)
/// before they are summed.
pub(super) const CHUNK: usize = 256;

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
    out: &mut [Lanes],
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
            o.0[slot] = v;
        }
        for (o, &v) in out[t + first..t + take].iter_mut().zip(&y[..take - first]) {
            o.0[slot] = v;
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
    fn next(&mut self, buf: &mut [Lanes]) -> Option<(usize, usize)> {
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
        buf: &mut Vec<Lanes>,
        acc: &mut Vec<Lanes>,
        acc_signed: &mut Vec<Lanes>,
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
        buf: &mut Vec<Lanes>,
        acc: &mut Vec<Lanes>,
        acc_signed: &mut Vec<Lanes>,
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
        buf: &mut Vec<Lanes>,
        acc: &mut Vec<Lanes>,
        acc_signed: &mut Vec<Lanes>,
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
        buf: &mut Vec<Lanes>,
        acc: &mut Vec<Lanes>,
        acc_signed: &mut Vec<Lanes>,
    ) -> ([f64; LANES], [f64; LANES]) {
        let m = self.m;
        let mut sum = [-0.0; LANES];
        let mut sq = [0.0; LANES];
        acc.clear();
        acc.resize(self.len(), Lanes::default());
        if m == 0 {
            return (sum, sq);
        }
        let ms = self.signed;
        if ms > 0 {
            acc_signed.clear();
            acc_signed.resize(self.len(), Lanes::default());
        }
        let plan = Plan::of(self, y.len(), PANEL_BYTES);
        let codes = &self.codes[..];
        let (acc, acc_signed) = (&mut acc[..], &mut acc_signed[..]);
        buf.resize(CHUNK, Lanes::default());
        let mut chunks = Chunks::new(y, block, lanes);
        while let Some((k, c)) = chunks.next(buf) {
            let chunk = &buf[..c];
            let at = Rows {
                codes: &codes[k * m..(k + c) * m],
                m,
                chunk,
                d: if ms > 0 { &direction[k..k + c] } else { &[] },
            };
            for (v, &dt) in chunk.iter().zip(at.d) {
                let w = scale_lanes(&v.0, f64::from(dt));
                add_lanes(&mut sum, &w);
                add_lanes(&mut sq, &mul_lanes(&w, &w));
            }
            // One unit's sums after another's: each slot still takes its rows in row order.
            for unit in &plan.units {
                unit.add(&at, &self.offset, acc, acc_signed);
            }
        }
        (sum, sq)
    }
}

/// Most bytes of lane sums (plain and signed) of one panel of [`SlotTable::accumulate_lanes`]
/// (at least one feature a panel): less than the L1 data cache, with room for the rows read.
pub(super) const PANEL_BYTES: usize = 32 * 1024;

/// Most features of a held unit ([`Unit::Held`]): their sums, plain and signed, in registers.
pub(super) const HELD_LANES: usize = 4;

/// How [`SlotTable::accumulate_lanes`] goes through the features of a chunk of rows: one
/// unit after another, each over every row of the chunk.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) enum Unit {
    /// Features whose slot changes seldom in seek order (at most once per [`STEADY_ROWS`]
    /// rows), at most [`HELD_LANES`], all signed or none: each one's current sums held in
    /// registers, written back when its slot changes.
    Held { features: Vec<usize>, signed: bool },
    /// Other features, whose sums (plain and, for the first `signed`, signed) fit in
    /// [`PANEL_BYTES`]: added in memory, which stays in the L1 cache.
    Panel { features: Vec<usize>, signed: usize },
}

/// The units of one table ([`Plan::of`]).
#[derive(Debug, Clone)]
pub(super) struct Plan {
    pub(super) units: Vec<Unit>,
}

impl Plan {
    /// The units of `table` over `n` rows: its steady features in held units of up to
    /// [`HELD_LANES`] (signed and unsigned apart), the others in panels of at most `bytes`
    /// of sums (a larger feature alone in its panel), each in table order.
    pub(super) fn of(table: &SlotTable, n: usize, bytes: usize) -> Plan {
        let m = table.m;
        let ms = table.signed;
        let steady = |j: usize| table.changes[j] * STEADY_ROWS <= n;
        let mut units = Vec::new();
        for signed in [true, false] {
            let held: Vec<usize> = (0..m)
                .filter(|&j| steady(j) && (j < ms) == signed)
                .collect();
            units.extend(held.chunks(HELD_LANES).map(|f| Unit::Held {
                features: f.to_vec(),
                signed,
            }));
        }
        let size = |j: usize| {
            (table.offset[j + 1] - table.offset[j])
                * std::mem::size_of::<Lanes>()
                * (1 + usize::from(j < ms))
        };
        let mut panel: Vec<usize> = Vec::new();
        let mut used = 0;
        let close = |panel: &mut Vec<usize>, units: &mut Vec<Unit>| {
            if !panel.is_empty() {
                let signed = panel.iter().filter(|&&j| j < ms).count();
                units.push(Unit::Panel {
                    features: std::mem::take(panel),
                    signed,
                });
            }
        };
        for j in (0..m).filter(|&j| !steady(j)) {
            if !panel.is_empty() && used + size(j) > bytes {
                close(&mut panel, &mut units);
                used = 0;
            }
            panel.push(j);
            used += size(j);
        }
        close(&mut panel, &mut units);
        Plan { units }
    }
}

/// A chunk of rows: their codes (`m` a row), their lanes and their directions (empty when no
/// feature is signed).
struct Rows<'a> {
    codes: &'a [u8],
    m: usize,
    chunk: &'a [Lanes],
    d: &'a [i8],
}

impl Unit {
    /// Adds the chunk's lanes `chunk[t]` (and `chunk[t]·d[t]` for a signed feature) into the
    /// unit's features' slots of row `t`, row by row.
    #[inline(always)]
    fn add(&self, at: &Rows<'_>, offset: &[usize], acc: &mut [Lanes], acc_signed: &mut [Lanes]) {
        match self {
            Unit::Panel { features, signed } => {
                add_panel(at, features, *signed, offset, acc, acc_signed);
            }
            Unit::Held { features, signed } => {
                let f = features.as_slice();
                match (f.len(), *signed) {
                    (1, true) => add_held::<1, true>(at, f, offset, acc, acc_signed),
                    (2, true) => add_held::<2, true>(at, f, offset, acc, acc_signed),
                    (3, true) => add_held::<3, true>(at, f, offset, acc, acc_signed),
                    (4, true) => add_held::<4, true>(at, f, offset, acc, acc_signed),
                    (1, false) => add_held::<1, false>(at, f, offset, acc, acc_signed),
                    (2, false) => add_held::<2, false>(at, f, offset, acc, acc_signed),
                    (3, false) => add_held::<3, false>(at, f, offset, acc, acc_signed),
                    (4, false) => add_held::<4, false>(at, f, offset, acc, acc_signed),
                    // Not made by `Plan::of`: the panel's additions, the same sums.
                    _ => {
                        let s = if *signed { f.len() } else { 0 };
                        add_panel(at, f, s, offset, acc, acc_signed);
                    }
                }
            }
        }
    }
}

/// A panel's additions: every row's lanes into each feature's slot in memory, and the signed
/// lanes into the first `signed` features' signed slots. Runs of up to [`PANEL_FIXED`]
/// features go to [`add_panel_fixed`] (their slots' offsets in registers, the loop over them
/// unrolled): first the plain and signed sums of the signed features, then the plain sums of
/// the others, each a pass over the chunk. Every slot still takes its rows in row order, so
/// the sums are the bits of [`add_panel_reference`]'s (tested).
#[inline(always)]
fn add_panel(
    at: &Rows<'_>,
    features: &[usize],
    signed: usize,
    offset: &[usize],
    acc: &mut [Lanes],
    acc_signed: &mut [Lanes],
) {
    let signed = signed.min(features.len());
    for part in features[..signed].chunks(PANEL_FIXED) {
        add_panel_part::<true>(at, part, offset, acc, acc_signed);
    }
    for part in features[signed..].chunks(PANEL_FIXED) {
        add_panel_part::<false>(at, part, offset, acc, acc_signed);
    }
}

/// Most features of one pass of [`add_panel_fixed`].
pub(super) const PANEL_FIXED: usize = 6;

/// [`add_panel_fixed`] for `features.len()` (1 to [`PANEL_FIXED`]) features, all signed if `S`.
#[inline(always)]
fn add_panel_part<const S: bool>(
    at: &Rows<'_>,
    features: &[usize],
    offset: &[usize],
    acc: &mut [Lanes],
    acc_signed: &mut [Lanes],
) {
    match features.len() {
        1 => add_panel_fixed::<1, S>(at, features, offset, acc, acc_signed),
        2 => add_panel_fixed::<2, S>(at, features, offset, acc, acc_signed),
        3 => add_panel_fixed::<3, S>(at, features, offset, acc, acc_signed),
        4 => add_panel_fixed::<4, S>(at, features, offset, acc, acc_signed),
        5 => add_panel_fixed::<5, S>(at, features, offset, acc, acc_signed),
        _ => add_panel_fixed::<PANEL_FIXED, S>(at, features, offset, acc, acc_signed),
    }
}

/// The additions of `M` features (the first `M` of `features`), each row's lanes into each
/// one's slot, and (`S`) the signed lanes into its signed slot: the features' columns and
/// offsets held in registers, one vector addition per feature and row.
#[inline(always)]
fn add_panel_fixed<const M: usize, const S: bool>(
    at: &Rows<'_>,
    features: &[usize],
    offset: &[usize],
    acc: &mut [Lanes],
    acc_signed: &mut [Lanes],
) {
    let js: [usize; M] = std::array::from_fn(|i| features[i]);
    let off: [usize; M] = std::array::from_fn(|i| offset[js[i]]);
    assert!(js.iter().all(|&j| j < at.m));
    let rows = at.codes.chunks_exact(at.m).zip(at.chunk);
    for (t, (row, v)) in rows.enumerate() {
        // A local copy: one register, not reloaded after every store to `acc`.
        let v = v.0;
        let w = if S {
            scale_lanes(&v, f64::from(at.d[t]))
        } else {
            v
        };
        for i in 0..M {
            // SAFETY: `js[i] < at.m` (asserted above) and `row` has `at.m` bytes.
            let c = unsafe { *row.get_unchecked(js[i]) };
            let s = off[i] + c as usize;
            add_lanes(&mut acc[s].0, &v);
            if S {
                add_lanes(&mut acc_signed[s].0, &w);
            }
        }
    }
}

/// [`add_panel`] written plainly, every feature of every row in one loop (the reference it
/// is tested against).
#[cfg(test)]
#[allow(clippy::too_many_arguments)]
pub(super) fn add_panel_reference(
    codes: &[u8],
    m: usize,
    chunk: &[Lanes],
    d: &[i8],
    features: &[usize],
    signed: usize,
    offset: &[usize],
    acc: &mut [Lanes],
    acc_signed: &mut [Lanes],
) {
    for (t, (row, v)) in codes.chunks_exact(m).zip(chunk).enumerate() {
        for (i, &j) in features.iter().enumerate() {
            let s = offset[j] + row[j] as usize;
            add_lanes(&mut acc[s].0, &v.0);
            if i < signed {
                add_lanes(&mut acc_signed[s].0, &scale_lanes(&v.0, f64::from(d[t])));
            }
        }
    }
}

/// [`add_panel`] of one chunk (`codes`: `m` bytes a row, `chunk` its lanes, `d` its
/// directions), for the tests.
#[cfg(test)]
#[allow(clippy::too_many_arguments)]
pub(super) fn add_panel_chunk(
    codes: &[u8],
    m: usize,
    chunk: &[Lanes],
    d: &[i8],
    features: &[usize],
    signed: usize,
    offset: &[usize],
    acc: &mut [Lanes],
    acc_signed: &mut [Lanes],
) {
    let at = Rows { codes, m, chunk, d };
    add_panel(&at, features, signed, offset, acc, acc_signed);
}

/// A held unit's additions ([`Unit::Held`], `M` features, all signed if `S`): each feature's
/// current slot's sums in registers, stored and the next slot's loaded when its slot changes
/// from one row to the next. Every slot still takes its rows in row order from the value it
/// had, so the sums are the bits of [`add_panel`]'s (tested); what goes is the chain through
/// memory (each addition waiting for the store of the previous one to the same slot).
#[inline(always)]
fn add_held<const M: usize, const S: bool>(
    at: &Rows<'_>,
    features: &[usize],
    offset: &[usize],
    acc: &mut [Lanes],
    acc_signed: &mut [Lanes],
) {
    if at.chunk.is_empty() {
        return;
    }
    let js: [usize; M] = std::array::from_fn(|i| features[i]);
    let off: [usize; M] = std::array::from_fn(|i| offset[js[i]]);
    let mut slot: [usize; M] = std::array::from_fn(|i| off[i] + at.codes[js[i]] as usize);
    let mut held: [[f64; LANES]; M] = std::array::from_fn(|i| acc[slot[i]].0);
    let mut held_s: [[f64; LANES]; M] = std::array::from_fn(|i| {
        if S {
            acc_signed[slot[i]].0
        } else {
            [0.0; LANES]
        }
    });
    let rows = at.codes.chunks_exact(at.m).zip(at.chunk);
    for (t, (row, v)) in rows.enumerate() {
        let v = v.0;
        let w = if S {
            scale_lanes(&v, f64::from(at.d[t]))
        } else {
            v
        };
        for i in 0..M {
            let s = off[i] + row[js[i]] as usize;
            if s != slot[i] {
                acc[slot[i]] = Lanes(held[i]);
                held[i] = acc[s].0;
                if S {
                    acc_signed[slot[i]] = Lanes(held_s[i]);
                    held_s[i] = acc_signed[s].0;
                }
                slot[i] = s;
            }
            add_lanes(&mut held[i], &v);
            if S {
                add_lanes(&mut held_s[i], &w);
            }
        }
    }
    for i in 0..M {
        acc[slot[i]] = Lanes(held[i]);
        if S {
            acc_signed[slot[i]] = Lanes(held_s[i]);
        }
    }
}
