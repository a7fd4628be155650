//! The inner loops of the QR factorisations of [`super::qr`]: dot products, Householder
//! reflections and the pattern of a row's non-zero values, each SIMD copy beside its portable
//! twin (the same operations in the same order, so the same bits; tested).

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
pub(super) fn householder_r(a: &mut [f64], m: usize, n: usize) {
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
/// `I − (2/‖v‖²)·v·vᵀ`), or `None` for a zero column. Where `‖v‖²` is below [`TINY_NORM_SQ`]
/// (and not zero) the column is divided by its largest magnitude first (a vector of the same
/// direction, so the same reflector; `α` is scaled back): unscaled, `‖v‖²` underflows (entries
/// below ~1e-154) and `2/‖v‖²` overflows to ∞, which turned the trailing columns into NaN (a
/// column whose only entries in a factorisation are tiny — `memsum`'s decayed basis values in a
/// small [`PatternQr`](super::qr::PatternQr) group). Above it the arithmetic is the plain one,
/// bit for bit.
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

/// The pattern of the non-zero values of `x` (at most 63 of them): bit `j` set where
/// `x[j] != 0.0` (NaN included). Runs the AVX copy when the CPU has it (four comparisons to
/// an instruction: the same bits, tested against [`nonzero_mask_portable`]).
#[inline(always)]
pub(super) fn nonzero_mask(x: &[f64]) -> u64 {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::rng::SimRng;

    /// The Householder loop one trailing column at a time (before the four-column kernel): the
    /// reference the fast loop is tested against bit for bit.
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
}
