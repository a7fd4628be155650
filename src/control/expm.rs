//! The matrix exponential by scaling and squaring with a diagonal Padé approximant
//! (Golub & Van Loan, *Matrix Computations*, 4th ed., Algorithm 9.3.1; Moler & Van Loan,
//! "Nineteen dubious ways to compute the exponential of a matrix", 2003, method 3).

use nalgebra::DMatrix;

/// Degree of the diagonal Padé approximant. With ‖A/2^s‖₁ ≤ 1/2 the relative truncation error
/// bound 2^(3−2q)·(q!)²/((2q)!·(2q+1)!) is about 3·10⁻¹⁶ for q = 6.
const PADE_Q: usize = 6;

/// An error computing a matrix exponential.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ExpmError {
    /// The matrix is not square.
    #[error("matrix exponential needs a square matrix, got {rows}×{cols}")]
    NotSquare {
        /// Rows of the argument.
        rows: usize,
        /// Columns of the argument.
        cols: usize,
    },
    /// The matrix holds NaN or an infinity.
    #[error("matrix exponential of a matrix with non-finite entries")]
    NotFinite,
    /// The Padé denominator was singular (cannot happen for ‖A/2^s‖ ≤ 1/2 in exact arithmetic).
    #[error("Padé denominator is singular")]
    Singular,
}

/// `e^A` for a square real matrix `A` (dimensionless; scale time into `A` before calling).
///
/// Balances `A` first with an exact power-of-two diagonal similarity `A' = D⁻¹AD`
/// (Parlett & Reinsch 1969, as in LAPACK `dgebal`; `e^A = D e^{A'} D⁻¹`), which keeps badly
/// scaled physical units (µm, µm/s, ω²) from forcing many squarings. Then scales `A'` by 2^−s so
/// that its 1-norm is at most 1/2, evaluates the [6/6] Padé approximant and squares `s` times.
pub(crate) fn expm(a: &DMatrix<f64>) -> Result<DMatrix<f64>, ExpmError> {
    let (n, m) = a.shape();
    if n != m {
        return Err(ExpmError::NotSquare { rows: n, cols: m });
    }
    if a.iter().any(|v| !v.is_finite()) {
        return Err(ExpmError::NotFinite);
    }
    let (a, d) = balance(a);
    let a = &a;
    let norm = one_norm(a);
    // Smallest s ≥ 0 with norm / 2^s ≤ 1/2.
    let mut s: i32 = 0;
    if norm > 0.5 {
        s = (norm / 0.5).log2().ceil() as i32;
        if norm / 2f64.powi(s) > 0.5 {
            s += 1;
        }
    }
    let a_scaled = a / 2f64.powi(s);
    let eye = DMatrix::<f64>::identity(n, n);
    let mut x = eye.clone();
    let mut num = eye.clone();
    let mut den = eye;
    let mut c = 1.0;
    let q = PADE_Q;
    let mut sign = 1.0;
    for k in 1..=q {
        // c_k = c_{k−1} · (q − k + 1) / (k · (2q − k + 1))
        c *= (q - k + 1) as f64 / (k * (2 * q - k + 1)) as f64;
        x = &a_scaled * &x;
        sign = -sign;
        num += &x * c;
        den += &x * (sign * c);
    }
    let lu = den.lu();
    let mut e = lu.solve(&num).ok_or(ExpmError::Singular)?;
    for _ in 0..s {
        e = &e * &e;
    }
    for i in 0..n {
        for j in 0..n {
            e[(i, j)] *= d[i] / d[j];
        }
    }
    Ok(e)
}

/// Returns `(D⁻¹AD, diag D)` with D a diagonal of powers of two that roughly equalises the
/// off-diagonal row and column norms (radix-2 Parlett–Reinsch; exact in floating point).
pub(crate) fn balance(a: &DMatrix<f64>) -> (DMatrix<f64>, Vec<f64>) {
    const RADIX: f64 = 2.0;
    let n = a.nrows();
    let mut m = a.clone();
    let mut d = vec![1.0; n];
    for _sweep in 0..100 {
        let mut done = true;
        for i in 0..n {
            let (mut c, mut r) = (0.0, 0.0);
            for j in 0..n {
                if j != i {
                    c += m[(j, i)].abs();
                    r += m[(i, j)].abs();
                }
            }
            if c <= 0.0 || r <= 0.0 {
                continue;
            }
            let s = c + r;
            let mut f = 1.0;
            let g = r / RADIX;
            while c < g {
                f *= RADIX;
                c *= RADIX * RADIX;
            }
            let g = r * RADIX;
            while c > g {
                f /= RADIX;
                c /= RADIX * RADIX;
            }
            if (c + r) / f < 0.95 * s {
                done = false;
                d[i] *= f;
                for j in 0..n {
                    m[(i, j)] /= f;
                    m[(j, i)] *= f;
                }
            }
        }
        if done {
            break;
        }
    }
    (m, d)
}

fn one_norm(a: &DMatrix<f64>) -> f64 {
    a.column_iter()
        .map(|c| c.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn max_abs_diff(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
        (a - b).iter().fold(0.0, |m, v| m.max(v.abs()))
    }

    /// Reference: e^{[0 t; 0 0]} = [1 t; 0 1] (nilpotent, series ends after two terms).
    #[test]
    fn expm_rigid_body_closed_form() {
        for t in [1e-4, 0.3, 250.0] {
            let a = DMatrix::from_row_slice(2, 2, &[0.0, t, 0.0, 0.0]);
            let e = expm(&a).unwrap();
            let want = DMatrix::from_row_slice(2, 2, &[1.0, t, 0.0, 1.0]);
            assert!(max_abs_diff(&e, &want) <= 1e-13 * t.max(1.0), "t={t}: {e}");
        }
    }

    /// Reference: damped oscillator ẍ + 2ζω ẋ + ω² x = 0, closed form with ω_d = ω√(1−ζ²):
    /// e^{At} = e^{−ζωt} [[cos + (ζω/ω_d) sin, sin/ω_d], [−ω² sin/ω_d, cos − (ζω/ω_d) sin]].
    #[test]
    fn expm_damped_oscillator_closed_form() {
        for (w, z, t) in [
            (2.0, 0.1, 0.7),
            (2.0 * std::f64::consts::PI * 3000.0, 0.02, 1e-4),
        ] {
            let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, -2.0 * z * w]) * t;
            let e = expm(&a).unwrap();
            let wd = w * (1.0 - z * z).sqrt();
            let (s, c) = (wd * t).sin_cos();
            let g = (-z * w * t).exp();
            let want = DMatrix::from_row_slice(
                2,
                2,
                &[
                    g * (c + z * w / wd * s),
                    g * s / wd,
                    -g * w * w * s / wd,
                    g * (c - z * w / wd * s),
                ],
            );
            for i in 0..2 {
                for j in 0..2 {
                    let tol = 1e-12 * want[(i, j)].abs().max(1e-3 * want.amax());
                    assert!(
                        (e[(i, j)] - want[(i, j)]).abs() <= tol,
                        "w={w} ({i},{j}): {} vs {}",
                        e[(i, j)],
                        want[(i, j)]
                    );
                }
            }
        }
    }

    #[test]
    fn expm_rejects_bad_input() {
        let a = DMatrix::from_row_slice(1, 2, &[0.0, 1.0]);
        assert!(matches!(expm(&a), Err(ExpmError::NotSquare { .. })));
        let a = DMatrix::from_row_slice(1, 1, &[f64::NAN]);
        assert_eq!(expm(&a), Err(ExpmError::NotFinite));
    }
}
