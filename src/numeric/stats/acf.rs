//! Autocorrelations at many lags from one pass over the values: the same bits as
//! [`autocorrelation`](super::autocorrelation) lag by lag (each lag's products added in row
//! order from the same start), with the mean and the spread computed once instead of once per
//! lag, and [`LAGS`] lags summed side by side in the lanes of one vector.

use super::{mean, sum_start};

/// Lags summed side by side in one pass over the values.
pub(crate) const LAGS: usize = 8;

/// The values centred on their mean and their spread `c0`, as
/// [`autocorrelation`](super::autocorrelation) computes them; `None` where it returns 0 for
/// every lag (no values, or no spread).
struct Centred {
    d: Vec<f64>,
    c0: f64,
}

impl Centred {
    fn new(x: &[f64]) -> Option<Centred> {
        let m = mean(x)?;
        let c0: f64 = x.iter().map(|v| (v - m).powi(2)).sum();
        if c0 <= 0.0 {
            return None;
        }
        Some(Centred {
            d: x.iter().map(|v| v - m).collect(),
            c0,
        })
    }

    /// The autocorrelations at lags `first..first + LAGS` (0 for a lag ≥ n), each
    /// `Σ_{i ≥ lag} d[i]·d[i − lag]` added in row order from [`sum_start`], over `c0`.
    fn batch(&self, first: usize) -> [f64; LAGS] {
        let d = &self.d[..];
        let n = d.len();
        // Lane `l` holds lag `top − l`, so a row's partners d[i − top .. i − top + LAGS] are
        // consecutive values.
        let top = first + LAGS - 1;
        let mut acc = [sum_start(); LAGS];
        // Each lag's rows before `top` (where not every lane has its partner yet), in order.
        for (l, a) in acc.iter_mut().enumerate() {
            let lag = top - l;
            for i in lag..top.min(n) {
                *a += d[i] * d[i - lag];
            }
        }
        if top < n {
            lanes(d, top, &mut acc);
        }
        let mut out = [0.0; LAGS];
        for (l, a) in acc.iter().enumerate() {
            let lag = top - l;
            out[lag - first] = if lag < n { a / self.c0 } else { 0.0 };
        }
        out
    }
}

/// Adds `d[i]·d[i − top + l]` into `acc[l]` for every row `i ≥ top`, in row order (one vector
/// multiplication and addition a row; each lane its own sum).
#[inline]
fn lanes(d: &[f64], top: usize, acc: &mut [f64; LAGS]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU supports AVX-512F (checked just above).
        return unsafe { lanes_avx512(d, top, acc) };
    }
    lanes_portable(d, top, acc);
}

/// [`lanes`] compiled for AVX-512F (the same products and sums, lane by lane).
///
/// # Safety
/// The CPU must support AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn lanes_avx512(d: &[f64], top: usize, acc: &mut [f64; LAGS]) {
    lanes_portable(d, top, acc);
}

/// [`lanes`] for any CPU.
#[inline(always)]
fn lanes_portable(d: &[f64], top: usize, acc: &mut [f64; LAGS]) {
    let mut a = *acc;
    for (&v, w) in d[top..].iter().zip(d.windows(LAGS)) {
        for l in 0..LAGS {
            a[l] += v * w[l];
        }
    }
    *acc = a;
}

/// The autocorrelations of `x` at lags `1..=max_lag`: element `k − 1` has the bits of
/// [`autocorrelation`](super::autocorrelation)`(x, k)` (tested).
pub(crate) fn autocorrelations(x: &[f64], max_lag: usize) -> Vec<f64> {
    let Some(c) = Centred::new(x) else {
        return vec![0.0; max_lag];
    };
    let mut out = Vec::with_capacity(max_lag + LAGS);
    let mut first = 1;
    while first <= max_lag {
        out.extend(c.batch(first));
        first += LAGS;
    }
    out.truncate(max_lag);
    out
}

/// The first lag in `1..=max_lag` at which the autocorrelation of `x` is below `below`, as
/// `(1..=max_lag).find(|&k| autocorrelation(x, k) < below)` finds it (tested), [`LAGS`] lags
/// a pass.
pub(crate) fn first_lag_below(x: &[f64], max_lag: usize, below: f64) -> Option<usize> {
    let Some(c) = Centred::new(x) else {
        return (max_lag >= 1 && 0.0 < below).then_some(1);
    };
    let mut first = 1;
    while first <= max_lag {
        let acf = c.batch(first);
        let found = (first..(first + LAGS).min(max_lag + 1)).find(|&k| acf[k - first] < below);
        if found.is_some() {
            return found;
        }
        first += LAGS;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::super::autocorrelation;
    use super::*;
    use crate::numeric::rng::SimRng;

    fn series(n: usize, phi: f64, seed: u64) -> Vec<f64> {
        let mut rng = SimRng::new(seed);
        let mut v = 0.0;
        (0..n)
            .map(|_| {
                v = phi * v + rng.normal();
                v + 3.0
            })
            .collect()
    }

    #[test]
    fn batched_autocorrelations_are_the_bits_of_one_lag_at_a_time() {
        for (n, phi) in [
            (0, 0.0),
            (1, 0.0),
            (5, 0.5),
            (9, 0.9),
            (40, 0.99),
            (1000, 0.0),
            (1000, 0.95),
            (3001, 0.999),
        ] {
            let x = series(n, phi, n as u64 + 1);
            for max_lag in [1, 7, 8, 9, 17, 40] {
                let got = autocorrelations(&x, max_lag);
                let want: Vec<f64> = (1..=max_lag).map(|k| autocorrelation(&x, k)).collect();
                let bits = |v: &[f64]| v.iter().map(|a| a.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&got), bits(&want), "n {n} phi {phi} lags {max_lag}");
                for below in [0.1, 0.5, 0.0, -1.0] {
                    assert_eq!(
                        first_lag_below(&x, max_lag, below),
                        (1..=max_lag).find(|&k| autocorrelation(&x, k) < below),
                        "n {n} phi {phi} lags {max_lag} below {below}"
                    );
                }
            }
        }
        // No spread: every lag 0, as one lag at a time.
        let flat = vec![2.5; 50];
        assert_eq!(autocorrelations(&flat, 3), vec![0.0; 3]);
        assert_eq!(first_lag_below(&flat, 3, 0.1), Some(1));
        assert_eq!(first_lag_below(&flat, 0, 0.1), None);
    }
}
