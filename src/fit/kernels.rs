//! The accumulation kernels of variable projection ([`super::projection`]): sums of many
//! rows taken in blocks with compensation ([`Blocked`]) and the per-lane sums of a batch of
//! candidate values ([`accumulate_one`]), each SIMD copy beside its portable twin (no fused
//! multiply-add: the same bits).

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
pub(super) const BLOCK: usize = 256;

/// Sums of many terms taken in blocks: the caller sums up to [`BLOCK`] terms into its own
/// accumulators and hands them over ([`Blocked::flush`] zeroes them); the block sums are added
/// here with Neumaier's compensation. The rounding error stays near that of one block.
pub(super) struct Blocked {
    sum: Vec<f64>,
    comp: Vec<f64>,
}

impl Blocked {
    pub(super) fn new(n: usize) -> Self {
        Self {
            sum: vec![0.0; n],
            comp: vec![0.0; n],
        }
    }

    /// Adds one block's sums `v` (in order, `len` = n).
    pub(super) fn add(&mut self, v: &[f64]) {
        for ((s, c), &x) in self.sum.iter_mut().zip(&mut self.comp).zip(v) {
            neumaier(s, c, x);
        }
    }

    /// Adds the concatenation of `parts` and zeroes them.
    pub(super) fn flush(&mut self, parts: &mut [&mut Vec<f64>]) {
        let xs = parts.iter_mut().flat_map(|p| p.iter_mut());
        for ((s, c), x) in self.sum.iter_mut().zip(&mut self.comp).zip(xs) {
            neumaier(s, c, std::mem::take(x));
        }
    }

    /// [`Blocked::flush`] of lane `c` of the lane-interleaved `acc` (`acc[j · lanes + c]` is
    /// sum `j`), zeroing it: the same arithmetic per sum.
    pub(super) fn flush_lane(&mut self, acc: &mut [f64], lanes: usize, c: usize) {
        let xs = acc.iter_mut().skip(c).step_by(lanes);
        for ((s, comp), x) in self.sum.iter_mut().zip(&mut self.comp).zip(xs) {
            neumaier(s, comp, std::mem::take(x));
        }
    }

    /// The compensated totals.
    pub(super) fn total(&self) -> Vec<f64> {
        self.sum
            .iter()
            .zip(&self.comp)
            .map(|(s, c)| s + c)
            .collect()
    }
}

/// Candidate values whose columns [`Projection`](super::projection::Projection) takes from one
/// replay.
pub(super) const SEARCH_BATCH: usize = 8;

/// Adds measured rows to the lane-interleaved sums of
/// [`Projection::sums_many`](super::projection::Projection::sums_many) for a one-column term, row
/// after row: `G[a] += x[a]·d`, `H += d·d`, `e += d·y` per lane (the per-lane arithmetic of
/// [`Projection::fast_rss`](super::projection::Projection::fast_rss)); `xf` holds the rows' fixed
/// columns (row-major), `y` their responses and `d` their columns (`SEARCH_BATCH` per row).
/// Compiled for AVX2 when the CPU has it (no fused multiply-add).
pub(super) fn accumulate_one(acc: &mut [f64], xf: &[f64], y: &[f64], d: &[f64]) {
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
