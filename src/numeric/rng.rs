//! Seeded, portable random numbers for every simulation in biasctl.
//!
//! All randomness flows through [`SimRng`], a thin wrapper over the ChaCha8 stream cipher
//! generator (`rand_chacha`), whose output for a given seed is specified bit-for-bit and does not
//! depend on the platform. Normal deviates use the Box–Muller transform, so the sequence depends
//! only on the seed. Outputs are written with a fixed number of decimals, so one seed gives a
//! byte-identical log on every machine.
//!
//! ```
//! use biasctl::SimRng;
//! let mut a = SimRng::new(7);
//! let mut b = SimRng::new(7);
//! assert_eq!(a.uniform().to_bits(), b.uniform().to_bits());
//! ```

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A seeded random generator (ChaCha8) with the few draws the simulator needs.
#[derive(Debug, Clone)]
pub struct SimRng {
    inner: ChaCha8Rng,
    spare_normal: Option<f64>,
}

impl SimRng {
    /// A generator whose whole output is fixed by `seed`.
    pub fn new(seed: u64) -> Self {
        Self {
            inner: ChaCha8Rng::seed_from_u64(seed),
            spare_normal: None,
        }
    }

    /// An independent generator for sub-stream `stream` of the same seed (for example one per
    /// physical effect), so that switching one effect off does not change the others' draws.
    pub fn substream(seed: u64, stream: u64) -> Self {
        let mut inner = ChaCha8Rng::seed_from_u64(seed);
        inner.set_stream(stream);
        Self {
            inner,
            spare_normal: None,
        }
    }

    /// A raw 64-bit draw.
    pub fn next_u64(&mut self) -> u64 {
        self.inner.next_u64()
    }

    /// Uniform on [0, 1) with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        (self.inner.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform on [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Uniform integer on 0..n (unbiased, by rejection). Returns 0 when `n` is 0.
    pub fn below(&mut self, n: u64) -> u64 {
        if n == 0 {
            return 0;
        }
        loop {
            let v = self.inner.next_u64();
            if accept(v, n) {
                return v % n;
            }
        }
    }

    /// `below(k + 1)` for k = `hi`, `hi` − 1, …, `lo` (in that order, `lo` ≤ `hi`), appended to
    /// `out`: the same values and the same generator state afterwards as those calls one by
    /// one (tested). The draws come first, in bulk (the generator's output copied as bytes:
    /// the same `u64`s, little-endian, as one `next_u64` after another), and the reductions
    /// `v mod (k + 1)` after, in a loop without divisions where k + 1 ≥ 2¹⁶ (an exact quotient
    /// from a floating-point estimate, vectorised on a CPU with AVX-512), which is what a
    /// shuffle's long run of draws costs.
    pub(crate) fn below_descending(&mut self, lo: u64, hi: u64, out: &mut Vec<u64>) {
        let start = out.len();
        let count = (hi - lo + 1) as usize;
        out.resize(start + count, 0);
        self.fill_u64(&mut out[start..]);
        // Every draw at most u64::MAX − (hi + 1) is accepted for every modulus ≤ hi + 1; a
        // larger one (probability about hi / 2⁶⁴ a draw) may be rejected: then the drawn
        // values are taken one by one as the loop of `below` calls takes them, the stream
        // continuing after them where more are needed.
        let sure = u64::MAX - (hi + 1);
        if out[start..].iter().any(|&v| v > sure) {
            let mut drawn = out.drain(start..).collect::<Vec<u64>>().into_iter();
            for k in (lo..=hi).rev() {
                let n = k + 1;
                loop {
                    let v = drawn.next().unwrap_or_else(|| self.inner.next_u64());
                    if accept(v, n) {
                        out.push(v);
                        break;
                    }
                }
            }
        }
        reduce_descending(&mut out[start..], hi + 1);
    }

    /// Fills `out` with the next `out.len()` raw draws: the same values and the same
    /// generator state afterwards as that many [`SimRng::next_u64`] calls (the generator's
    /// 32-bit words taken in pairs, low word first, which is how its byte output orders
    /// them; tested).
    fn fill_u64(&mut self, out: &mut [u64]) {
        let mut bytes = [0u8; 512];
        for chunk in out.chunks_mut(bytes.len() / 8) {
            let b = &mut bytes[..chunk.len() * 8];
            self.inner.fill_bytes(b);
            for (v, le) in chunk.iter_mut().zip(b.chunks_exact(8)) {
                let mut w = [0u8; 8];
                w.copy_from_slice(le);
                *v = u64::from_le_bytes(w);
            }
        }
    }
}

/// Whether `below(n)` accepts draw `v`: `v` below the largest multiple of `n` that fits, so
/// every residue is equally likely. That zone starts above `u64::MAX − n`, so the division
/// that finds it is needed only for the last `n` values of the range.
#[inline]
fn accept(v: u64, n: u64) -> bool {
    v <= u64::MAX - n || v < u64::MAX - (u64::MAX % n)
}

/// Smallest modulus [`mod_by_estimate`] takes: its quotient estimate is then within one of
/// the true quotient.
const FAST_MOD_MIN: u64 = 1 << 16;

/// `v mod n` for `FAST_MOD_MIN ≤ n < 2⁵³` without a division instruction: the quotient
/// estimated in floating point, `v / n` (relative error ≤ 2⁻⁵², so for v < 2⁶⁴ and n ≥ 2¹⁶
/// within 2⁻⁴ of the true v / n before truncation) is the true quotient or one off, and one
/// correction each way makes the remainder exact (tested against `%`).
#[inline]
fn mod_by_estimate(v: u64, n: u64) -> u64 {
    let q = (v as f64 / n as f64) as u64;
    // v − q·n is in [−n, 2n): exact in wrapping arithmetic read as signed.
    let mut r = v.wrapping_sub(q.wrapping_mul(n)) as i64;
    let ni = n as i64;
    r += (r >> 63) & ni;
    r -= ni & -((r >= ni) as i64);
    r as u64
}

/// Replaces `v[t]` by `v[t] mod (n0 − t)` (n0 − t ≥ 1); by [`mod_by_estimate`] where the
/// modulus is at least [`FAST_MOD_MIN`] and below 2⁵³.
fn reduce_descending(v: &mut [u64], n0: u64) {
    // The moduli of at least FAST_MOD_MIN come first (they descend).
    let fast = if n0 < 1 << 53 {
        (n0.saturating_sub(FAST_MOD_MIN - 1) as usize).min(v.len())
    } else {
        0
    };
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512dq") {
        // SAFETY: the CPU has AVX-512 F and DQ (DQ implies F; checked just above).
        unsafe { reduce_fast_avx512(&mut v[..fast], n0) };
    } else {
        reduce_fast(&mut v[..fast], n0);
    }
    #[cfg(not(target_arch = "x86_64"))]
    reduce_fast(&mut v[..fast], n0);
    for (t, x) in v.iter_mut().enumerate().skip(fast) {
        *x %= n0 - t as u64;
    }
}

/// [`mod_by_estimate`] over a run of descending moduli from `n0` (each ≥ [`FAST_MOD_MIN`]).
#[inline]
fn reduce_fast(v: &mut [u64], n0: u64) {
    for (t, x) in v.iter_mut().enumerate() {
        *x = mod_by_estimate(*x, n0 - t as u64);
    }
}

/// [`reduce_fast`] compiled for AVX-512 F/DQ (64-bit integer ↔ double conversions and
/// multiplies in vector registers): the same arithmetic, the same results.
///
/// # Safety
/// The CPU must support AVX-512 F and DQ.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq")]
unsafe fn reduce_fast_avx512(v: &mut [u64], n0: u64) {
    reduce_fast(v, n0);
}

impl SimRng {
    /// A standard normal deviate (Box–Muller, both values used).
    pub fn normal(&mut self) -> f64 {
        if let Some(z) = self.spare_normal.take() {
            return z;
        }
        // 1 - uniform() lies in (0, 1], so the logarithm is finite.
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        let radius = (-2.0 * u1.ln()).sqrt();
        let angle = std::f64::consts::TAU * u2;
        self.spare_normal = Some(radius * angle.sin());
        radius * angle.cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_stream_and_substreams_differ() {
        let mut a = SimRng::new(1);
        let mut b = SimRng::new(1);
        for _ in 0..100 {
            assert_eq!(a.next_u64(), b.next_u64());
        }
        let mut s0 = SimRng::substream(1, 0);
        let mut s1 = SimRng::substream(1, 1);
        assert_ne!(s0.next_u64(), s1.next_u64());
    }

    /// Reference: `below` as it was written first (the rejection zone from a division on
    /// every call, `v % n`), and `%` itself for the division-free reduction: the same values
    /// and the same generator state, for small and large moduli, across the 2¹⁶ switch of
    /// `below_descending`, and at the draws nearest `u64::MAX` where rejection happens.
    #[test]
    fn below_and_below_descending_equal_the_reference() {
        fn below_reference(r: &mut SimRng, n: u64) -> u64 {
            if n == 0 {
                return 0;
            }
            let zone = u64::MAX - (u64::MAX % n);
            loop {
                let v = r.next_u64();
                if v < zone {
                    return v % n;
                }
            }
        }
        for n in [
            1u64,
            2,
            3,
            7,
            1000,
            65_535,
            65_536,
            65_537,
            1 << 40,
            u64::MAX / 3 + 1,
        ] {
            let (mut a, mut b) = (SimRng::new(n), SimRng::new(n));
            for _ in 0..2000 {
                assert_eq!(a.below(n), below_reference(&mut b, n), "n {n}");
            }
        }
        // The last two: moduli near 2⁶³ and 2⁶², where a quarter to a half of the draws
        // are rejected (the bulk draw's one-by-one path).
        for (lo, hi) in [
            (0u64, 10u64),
            (1, 70_000),
            (65_530, 65_540),
            (999_000, 1_000_000),
            (u64::MAX / 2 - 40, u64::MAX / 2),
            (u64::MAX / 4 + 1, u64::MAX / 4 + 60),
        ] {
            let (mut a, mut b) = (SimRng::substream(3, lo), SimRng::substream(3, lo));
            let mut fast = vec![7];
            a.below_descending(lo, hi, &mut fast);
            let slow: Vec<u64> = std::iter::once(7)
                .chain((lo..=hi).rev().map(|k| below_reference(&mut b, k + 1)))
                .collect();
            assert_eq!(fast, slow, "{lo}..={hi}");
            assert_eq!(a.next_u64(), b.next_u64());
        }
        // The bulk draw alone, from every offset in the generator's buffer of words (an odd
        // one too: a pair of words across two of its blocks).
        for skip in 0..70u64 {
            let (mut a, mut b) = (SimRng::new(skip), SimRng::new(skip));
            for _ in 0..skip {
                let _ = a.inner.next_u32();
                let _ = b.inner.next_u32();
            }
            let mut bulk = vec![0u64; 1000 + skip as usize];
            a.fill_u64(&mut bulk);
            let one_by_one: Vec<u64> = (0..bulk.len()).map(|_| b.next_u64()).collect();
            assert_eq!(bulk, one_by_one, "skip {skip}");
            assert_eq!(a.next_u64(), b.next_u64(), "skip {skip}");
        }
        // The reduction alone, at the ends of the range of v and of n.
        let mut r = SimRng::new(11);
        for k in 0..200_000u64 {
            let n = match k % 4 {
                0 => FAST_MOD_MIN + k,
                1 => (1 << 52) - k,
                _ => FAST_MOD_MIN + r.next_u64() % (1 << 40),
            };
            let v = match k % 3 {
                0 => u64::MAX - k,
                1 => k,
                _ => r.next_u64(),
            };
            assert_eq!(mod_by_estimate(v, n), v % n, "{v} mod {n}");
        }
        let mut v: Vec<u64> = (0..70_000).map(|_| r.next_u64()).collect();
        let want: Vec<u64> = v
            .iter()
            .enumerate()
            .map(|(t, x)| x % (70_000 - t as u64))
            .collect();
        reduce_descending(&mut v, 70_000);
        assert_eq!(v, want);
    }

    #[test]
    fn normal_moments_match_standard_normal() {
        // Reference: mean 0, variance 1; with 200k draws the standard errors are ~0.0022 and ~0.0032.
        let mut r = SimRng::new(42);
        let n = 200_000;
        let xs: Vec<f64> = (0..n).map(|_| r.normal()).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((var - 1.0).abs() < 0.015, "var {var}");
    }

    #[test]
    fn below_is_in_range_and_roughly_uniform() {
        let mut r = SimRng::new(3);
        let mut counts = [0u32; 5];
        for _ in 0..50_000 {
            counts[r.below(5) as usize] += 1;
        }
        for c in counts {
            assert!((9_500..10_500).contains(&c), "{counts:?}");
        }
        assert_eq!(r.below(0), 0);
    }
}
