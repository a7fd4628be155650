//! The handoff kernels: the blocked backward scans of [`HandoffTable::solve`] and
//! [`HandoffTable::bounds_into`], each portable version beside its AVX2 twin (the same code
//! compiled for AVX2, run when the CPU has it).

use super::table::Point;
use super::{Bounds, Handoff, HandoffSolution, HandoffTable, Interval, SettleError, Window};

/// min(a, b) as one `minsd`/`minpd`: `b` if `b < a`, else `a` (a NaN `b` is ignored).
#[inline(always)]
fn fmin(a: f64, b: f64) -> f64 {
    if b < a { b } else { a }
}

/// max(a, b) as one `maxsd`/`maxpd` (a NaN `b` is ignored).
#[inline(always)]
fn fmax(a: f64, b: f64) -> f64 {
    if b > a { b } else { a }
}

/// Samples per block of the blocked backward scans.
pub(super) const BLOCK: usize = 8;

/// The running bounds of one block: `su[j] = min(umin, min_{i ≥ j} u[i])` and `sl[j] =
/// max(lmax, max_{i ≥ j} l[i])`, where `(umin, lmax)` are the bounds over the samples above the
/// block. The block's own suffix scan starts from ±∞, so it does not wait for the blocks above
/// and consecutive blocks overlap in the CPU; only the final combine depends on them.
#[inline(always)]
pub(super) fn suffix_into(
    u: &[f64],
    l: &[f64],
    su: &mut [f64],
    sl: &mut [f64],
    umin: f64,
    lmax: f64,
) {
    let m = u.len();
    let (l, su, sl) = (&l[..m], &mut su[..m], &mut sl[..m]);
    let (mut a, mut b) = (f64::INFINITY, f64::NEG_INFINITY);
    for j in (0..m).rev() {
        a = fmin(a, u[j]);
        b = fmax(b, l[j]);
        su[j] = a;
        sl[j] = b;
    }
    for j in 0..m {
        su[j] = fmin(umin, su[j]);
        sl[j] = fmax(lmax, sl[j]);
    }
}

/// Four samples with lane-wise arithmetic: in a function compiled for AVX2 each operation is one
/// 256-bit instruction (the compiler keeps the lanes of the fixed-size array together, where a
/// loop over a block of 8 became 128-bit pairs of U and L).
#[derive(Debug, Clone, Copy)]
struct F4([f64; 4]);

impl F4 {
    #[inline(always)]
    fn splat(x: f64) -> Self {
        Self([x; 4])
    }
    #[inline(always)]
    fn load(s: &[f64]) -> Self {
        Self([s[0], s[1], s[2], s[3]])
    }
    #[inline(always)]
    fn zip(self, o: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        let (a, b) = (self.0, o.0);
        Self([f(a[0], b[0]), f(a[1], b[1]), f(a[2], b[2]), f(a[3], b[3])])
    }
    /// min over the lanes, as a tree (exact for NaN-free lanes).
    #[inline(always)]
    fn hmin(self) -> f64 {
        let a = self.0;
        fmin(fmin(a[0], a[2]), fmin(a[1], a[3]))
    }
    /// max over the lanes, as a tree (exact for NaN-free lanes).
    #[inline(always)]
    fn hmax(self) -> f64 {
        let a = self.0;
        fmax(fmax(a[0], a[2]), fmax(a[1], a[3]))
    }
}

/// The conditions of [`HandoffTable::solve`] on the running bounds (U*, L*), nested: 0, zero
/// feedforward's worst case inside (L* ≤ −s, U* ≥ s); 1, width ≥ 2s; 2, width ≥ 0.
#[inline(always)]
fn keep<const P: usize>(u: f64, l: f64, shift: f64) -> bool {
    match P {
        0 => l <= -shift && u >= shift,
        1 => u - l >= 2.0 * shift,
        _ => u - l >= 0.0,
    }
}

/// The backward scan of [`HandoffTable::solve`]: the next candidate k (samples k.. are in the
/// running bounds `umin` = U*(k), `lmax` = L*(k)), moving down towards `floor`.
struct Scan<'a> {
    table: &'a HandoffTable,
    p: Point,
    /// The handoff's point as lanes: e0, v0, du, δ.
    lanes: [F4; 4],
    floor: usize,
    /// No bound can be NaN: whole blocks may be reduced as trees.
    nan_free: bool,
    shift: f64,
    k: usize,
    umin: f64,
    lmax: f64,
    /// The samples k − `left` .. k of the block where the previous condition stopped holding,
    /// not yet walked, with their bounds in `u[..left]`, `l[..left]`: the next condition
    /// walks them first instead of computing a new (unaligned) block.
    left: usize,
    u: [f64; BLOCK],
    l: [f64; BLOCK],
}

impl Scan<'_> {
    /// U_k, L_k of the block of samples `lo .. lo + BLOCK`, four at a time.
    #[inline(always)]
    fn block(&self, lo: usize) -> ([F4; 2], [F4; 2]) {
        let t = self.table;
        let [e0, v0, du, delta] = self.lanes;
        let (pe, pv) = (&t.pe[lo..lo + BLOCK], &t.pv[lo..lo + BLOCK]);
        let (pu, w) = (&t.pu[lo..lo + BLOCK], &t.w[lo..lo + BLOCK]);
        let mut u = [F4::splat(0.0); 2];
        let mut l = [F4::splat(0.0); 2];
        for h in 0..2 {
            let o = 4 * h;
            let mul = |a: f64, b: f64| a * b;
            let add = |a: f64, b: f64| a + b;
            // Point::bounds, lane by lane, the same operations in the same order.
            let mid = F4::load(&pe[o..])
                .zip(e0, mul)
                .zip(F4::load(&pv[o..]).zip(v0, mul), add)
                .zip(F4::load(&pu[o..]).zip(du, mul), add);
            let half = F4::load(&w[o..]).zip(delta, mul);
            u[h] = mid.zip(half, add);
            l[h] = mid.zip(half, |a, b| a - b);
        }
        (u, l)
    }

    /// Moves down while condition `P` holds and returns (k, L*(k), U*(k)) for the lowest k at
    /// which it holds (k = the floor if it holds all the way; k above the last candidate if it
    /// never does). The samples the previous condition left in its last block come first,
    /// sample by sample; then whole blocks that keep it are taken from their tree min/max,
    /// and the block where it stops holding is walked sample by sample (its unwalked samples
    /// are left to the next condition).
    #[inline(always)]
    fn run<const P: usize>(&mut self) -> (usize, f64, f64) {
        let (mut k, mut umin, mut lmax) = (self.k, self.umin, self.lmax);
        let (mut u, mut l) = (self.u, self.l);
        // The running bounds ignore a NaN bound (fmin/fmax keep their first operand).
        let mut left = 0;
        for j in (0..self.left).rev() {
            let (a, b) = (fmin(umin, u[j]), fmax(lmax, l[j]));
            if !keep::<P>(a, b, self.shift) {
                left = j + 1;
                break;
            }
            (umin, lmax, k) = (a, b, k - 1);
        }
        if left == 0 {
            'blocks: while k > self.floor {
                let m = (k - self.floor).min(BLOCK);
                let lo = k - m;
                if m == BLOCK {
                    let (bu, bl) = self.block(lo);
                    if self.nan_free {
                        let bmin = bu[0].zip(bu[1], fmin).hmin();
                        let bmax = bl[0].zip(bl[1], fmax).hmax();
                        let (nu, nl) = (fmin(umin, bmin), fmax(lmax, bmax));
                        if keep::<P>(nu, nl, self.shift) {
                            (umin, lmax, k) = (nu, nl, lo);
                            continue;
                        }
                    }
                    for h in 0..2 {
                        u[4 * h..4 * h + 4].copy_from_slice(&bu[h].0);
                        l[4 * h..4 * h + 4].copy_from_slice(&bl[h].0);
                    }
                } else {
                    self.table.fill(lo, self.p, &mut u[..m], &mut l[..m]);
                }
                for j in (0..m).rev() {
                    let (a, b) = (fmin(umin, u[j]), fmax(lmax, l[j]));
                    if !keep::<P>(a, b, self.shift) {
                        left = j + 1;
                        break 'blocks;
                    }
                    (umin, lmax, k) = (a, b, lo + j);
                }
            }
        }
        (self.k, self.umin, self.lmax) = (k, umin, lmax);
        (self.left, self.u, self.l) = (left, u, l);
        (k, lmax, umin)
    }
}

impl HandoffTable {
    /// [`HandoffTable::solve`] compiled for AVX2.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn solve_avx2(
        &self,
        h: &Handoff,
        window: &Window,
        delta_b: f64,
    ) -> HandoffSolution {
        self.solve_portable(h, window, delta_b)
    }

    /// [`HandoffTable::solve`] for any CPU.
    #[inline(always)]
    pub(super) fn solve_portable(
        &self,
        h: &Handoff,
        window: &Window,
        delta_b: f64,
    ) -> HandoffSolution {
        let n = self.w.len();
        let shift = (self.dz_dbias * delta_b).abs();
        let mut out = HandoffSolution {
            optimal: None,
            robust: None,
            zero_ff_worst: None,
            shift,
        };
        let p = Point::of(h, window);
        let Point { e0, v0, du, delta } = p;
        if window.hold > n || !(e0.is_finite() && v0.is_finite() && du.is_finite()) {
            return out;
        }
        let top = n - window.hold;
        let floor = self.floor(p);
        if floor > top {
            return out;
        }
        // Running bounds over samples [k, n): start with the samples after the last candidate.
        let mut umin = f64::INFINITY;
        let mut lmax = f64::NEG_INFINITY;
        for k in top + 1..n {
            let (u, l) = p.bounds(self.pe[k], self.pv[k], self.pu[k], self.w[k]);
            umin = fmin(umin, u);
            lmax = fmax(lmax, l);
        }
        let mut scan = Scan {
            table: self,
            p,
            lanes: [e0, v0, du, delta].map(F4::splat),
            floor,
            // No bound NaN: whole blocks can be reduced as trees; otherwise every block takes
            // the per-sample path (NaN ignored).
            nan_free: self.nan_free(p),
            shift,
            k: top + 1,
            umin,
            lmax,
            left: 0,
            u: [0.0; BLOCK],
            l: [0.0; BLOCK],
        };
        // The conditions are nested: each scan starts where the previous one stopped.
        let found = [scan.run::<0>(), scan.run::<1>(), scan.run::<2>()];
        let interval =
            |(k, lo, hi): (usize, f64, f64)| (k <= top).then_some(Interval { k, lo, hi });
        out.zero_ff_worst = interval(found[0]).map(|i| i.k);
        out.robust = interval(found[1]);
        out.optimal = interval(found[2]);
        out
    }

    /// Fills `buf` with the per-sample bounds (eq. 14) and the backward running min/max
    /// (eq. 15) of `h`, without allocating. `buf` must have been made for this horizon.
    pub fn bounds_into(
        &self,
        h: &Handoff,
        window: &Window,
        buf: &mut Bounds,
    ) -> Result<(), SettleError> {
        let n = self.w.len();
        if buf.upper.len() != n {
            return Err(SettleError::BufferLength {
                got: buf.upper.len(),
                want: n,
            });
        }
        let p = Point::of(h, window);
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is true only when `new` found AVX2 on this CPU.
            unsafe { self.curves_avx2(p, buf) };
            buf.hold = window.hold;
            return Ok(());
        }
        self.curves_portable(p, buf);
        buf.hold = window.hold;
        Ok(())
    }

    /// |U_k|, |L_k| far from overflow and δ > 0 (a zero-gain sample's ∞·δ is then ∞): no bound
    /// of `p` can be NaN.
    #[inline(always)]
    fn nan_free(&self, p: Point) -> bool {
        let bound = self.coef_max * (p.e0.abs() + p.v0.abs() + p.du.abs()) + self.w_max * p.delta;
        bound < f64::MAX / 16.0 && p.delta > 0.0
    }

    /// The zero-gain samples that rule settling out: no start value settles there.
    #[inline(always)]
    fn rule_out_zero_gain(&self, p: Point, buf: &mut Bounds) {
        for z in &self.zero {
            if Self::rules_out(z, p) {
                buf.upper[z.k] = f64::NEG_INFINITY;
                buf.lower[z.k] = f64::INFINITY;
            }
        }
    }

    /// The four curves of [`HandoffTable::bounds_into`] compiled for AVX2 (`buf` of this
    /// horizon).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn curves_avx2(&self, p: Point, buf: &mut Bounds) {
        // SAFETY: the CPU has AVX2 (this function's contract).
        unsafe { self.fill_down(p, &mut buf.upper, &mut buf.lower) };
        self.rule_out_zero_gain(p, buf);
        // Without a NaN bound the running bounds may be taken over windows.
        // SAFETY: the CPU has AVX2 (this function's contract); the four buffers have n samples.
        unsafe { suffix_avx2(buf, self.nan_free(p)) };
    }

    /// U_k, L_k (eq. 14) of every sample, as [`HandoffTable::fill`] computes them (the same
    /// operations in the same order, four lanes at a time), the top samples first: the
    /// running bounds, read top-down right after, then find the top groups' stores already in
    /// the cache (a load spanning two stores still in the store buffer waits for them, and
    /// the windows of [`suffix_avx2`] span two).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn fill_down(&self, p: Point, u: &mut [f64], l: &mut [f64]) {
        use std::arch::x86_64::{
            _mm256_add_pd, _mm256_loadu_pd, _mm256_mul_pd, _mm256_set1_pd, _mm256_storeu_pd,
            _mm256_sub_pd,
        };
        let n = self.w.len();
        let (u, l) = (&mut u[..n], &mut l[..n]);
        let (pe, pv, pu, w) = (&self.pe[..n], &self.pv[..n], &self.pu[..n], &self.w[..n]);
        let n4 = n - n % 4;
        for k in n4..n {
            (u[k], l[k]) = p.bounds(pe[k], pv[k], pu[k], w[k]);
        }
        let [e0, v0, du, delta] = [p.e0, p.v0, p.du, p.delta].map(|x| _mm256_set1_pd(x));
        let mut k = n4;
        while k >= 4 {
            k -= 4;
            // SAFETY: k + 4 ≤ n4 ≤ n, the length of all six slices.
            unsafe {
                let at = |s: &[f64]| _mm256_loadu_pd(s.as_ptr().add(k));
                let mid = _mm256_add_pd(
                    _mm256_add_pd(_mm256_mul_pd(at(pe), e0), _mm256_mul_pd(at(pv), v0)),
                    _mm256_mul_pd(at(pu), du),
                );
                let half = _mm256_mul_pd(at(w), delta);
                _mm256_storeu_pd(u.as_mut_ptr().add(k), _mm256_add_pd(mid, half));
                _mm256_storeu_pd(l.as_mut_ptr().add(k), _mm256_sub_pd(mid, half));
            }
        }
    }

    /// The four curves of [`HandoffTable::bounds_into`] for any CPU (`buf` of this horizon).
    #[inline(always)]
    pub(super) fn curves_portable(&self, p: Point, buf: &mut Bounds) {
        let n = self.w.len();
        self.fill(0, p, &mut buf.upper, &mut buf.lower);
        self.rule_out_zero_gain(p, buf);
        // Blocks from the end: each block's suffix scan is independent of the blocks above.
        let mut run = (f64::INFINITY, f64::NEG_INFINITY);
        let mut hi = n;
        while hi >= BLOCK {
            run = buf.running_block(hi - BLOCK, hi, run);
            hi -= BLOCK;
        }
        if hi > 0 {
            buf.running_block(0, hi, run);
        }
    }
}

/// The backward running bounds of `buf` (U*, L* of eq. 15 from U, L), four samples per
/// instruction: the top group of four gets its own suffix min/max from two shifted copies of
/// itself, then the running bounds of the samples above it. Every min keeps the operand of the
/// higher sample on a tie and ignores a NaN bound, as the sample-by-sample scan does (a NaN
/// bound is first turned into ±∞, which the scan's min/max also leave out), so the curves are
/// bit for bit those of [`suffix_into`]'s blocks (tested: the AVX2 and portable copies agree).
///
/// When no bound can be NaN (`nan_free`), the groups below the top one take no shuffle: the
/// running bound at k + i is the min of the window of four samples k + i .. k + i + 3 (read
/// from memory at four offsets) and the running bound at k + i + 4, so a group is four loads,
/// three lane-wise mins of the windows and one of the group above (the shuffles ran on one
/// port and bound the scan). The windows overlap the group above; a min over a set that holds
/// a sample twice is the same, and with each min's lower-sample operand first, a tie still
/// keeps the highest sample's value.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn suffix_avx2(buf: &mut Bounds, nan_free: bool) {
    use std::arch::x86_64::{
        _mm256_loadu_pd, _mm256_max_pd, _mm256_min_pd, _mm256_permute4x64_pd, _mm256_set1_pd,
        _mm256_storeu_pd,
    };
    let n = buf.upper.len();
    let (u, l) = (&buf.upper[..n], &buf.lower[..n]);
    let (su, sl) = (&mut buf.upper_min[..n], &mut buf.lower_max[..n]);
    // The top n % 4 samples one by one, then groups of four down to sample 0.
    let n4 = n - n % 4;
    let (mut a, mut b) = (f64::INFINITY, f64::NEG_INFINITY);
    for j in (n4..n).rev() {
        a = fmin(a, u[j]);
        b = fmax(b, l[j]);
        su[j] = a;
        sl[j] = b;
    }
    // `_mm256_min_pd(x, y)` is `if x < y { x } else { y }`: with x the lower sample and y the
    // higher one it is `fmin(y, x)`, the scan's own step.
    let (inf, ninf) = (
        _mm256_set1_pd(f64::INFINITY),
        _mm256_set1_pd(f64::NEG_INFINITY),
    );
    let (mut ru, mut rl) = (_mm256_set1_pd(a), _mm256_set1_pd(b));
    let mut k = n4;
    while k >= 4 {
        k -= 4;
        // SAFETY: k + 4 ≤ n4 ≤ n, the length of all four slices.
        unsafe {
            let vu = _mm256_min_pd(_mm256_loadu_pd(u.as_ptr().add(k)), inf);
            let vl = _mm256_max_pd(_mm256_loadu_pd(l.as_ptr().add(k)), ninf);
            // Lane i ← lanes i, i + 1 (lane 3 with itself), then lanes i .. i + 3.
            let tu = _mm256_min_pd(vu, _mm256_permute4x64_pd::<0b11_11_10_01>(vu));
            let tl = _mm256_max_pd(vl, _mm256_permute4x64_pd::<0b11_11_10_01>(vl));
            let tu = _mm256_min_pd(tu, _mm256_permute4x64_pd::<0b11_10_11_10>(tu));
            let tl = _mm256_max_pd(tl, _mm256_permute4x64_pd::<0b11_10_11_10>(tl));
            let (gu, gl) = (_mm256_min_pd(tu, ru), _mm256_max_pd(tl, rl));
            _mm256_storeu_pd(su.as_mut_ptr().add(k), gu);
            _mm256_storeu_pd(sl.as_mut_ptr().add(k), gl);
            if nan_free {
                // Every group below reads samples k' .. k' + 7 ≤ k + 3 < n.
                windows_avx2(u, l, su, sl, k, gu, gl);
                return;
            }
            // The running bounds from this group's lane 0 (off the stores' path).
            ru = _mm256_min_pd(_mm256_permute4x64_pd::<0>(tu), ru);
            rl = _mm256_max_pd(_mm256_permute4x64_pd::<0>(tl), rl);
        }
    }
}

/// The groups of four below sample `top` (a multiple of four whose group's running bounds are
/// `gu`, `gl`): the running bound at k + i is the min of the window k + i .. k + i + 3 and the
/// running bound at k + i + 4 (see [`suffix_avx2`]). No bound may be NaN.
///
/// # Safety
/// The CPU must support AVX2; `top + 4 ≤` the length of all four slices.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn windows_avx2(
    u: &[f64],
    l: &[f64],
    su: &mut [f64],
    sl: &mut [f64],
    top: usize,
    mut gu: std::arch::x86_64::__m256d,
    mut gl: std::arch::x86_64::__m256d,
) {
    use std::arch::x86_64::{_mm256_loadu_pd, _mm256_max_pd, _mm256_min_pd, _mm256_storeu_pd};
    assert!(top + 4 <= u.len().min(l.len()).min(su.len()).min(sl.len()));
    let mut k = top;
    while k >= 4 {
        k -= 4;
        // SAFETY: k + 3 + 4 ≤ top + 3 < the slices' length (asserted above).
        unsafe {
            let (pu, pl) = (u.as_ptr().add(k), l.as_ptr().add(k));
            let wu = _mm256_min_pd(
                _mm256_min_pd(_mm256_loadu_pd(pu), _mm256_loadu_pd(pu.add(1))),
                _mm256_min_pd(_mm256_loadu_pd(pu.add(2)), _mm256_loadu_pd(pu.add(3))),
            );
            let wl = _mm256_max_pd(
                _mm256_max_pd(_mm256_loadu_pd(pl), _mm256_loadu_pd(pl.add(1))),
                _mm256_max_pd(_mm256_loadu_pd(pl.add(2)), _mm256_loadu_pd(pl.add(3))),
            );
            gu = _mm256_min_pd(wu, gu);
            gl = _mm256_max_pd(wl, gl);
            _mm256_storeu_pd(su.as_mut_ptr().add(k), gu);
            _mm256_storeu_pd(sl.as_mut_ptr().add(k), gl);
        }
    }
}
