//! Discrete algebraic Riccati equation and the discrete LQR gain.
//!
//! X = AᵀXA − AᵀXB (R + BᵀXB)⁻¹ BᵀXA + Q, K = (R + BᵀXB)⁻¹ BᵀXA, u = −K x.
//!
//! Solved with the structured doubling algorithm (SDA; Chu, Fan & Lin, "A structure-preserving
//! doubling algorithm for discrete-time algebraic Riccati equations", Linear Algebra Appl. 396,
//! 2005): with A₀ = A, G₀ = B R⁻¹ Bᵀ, H₀ = Q and W = I + G_k H_k,
//! A_{k+1} = A_k W⁻¹ A_k, G_{k+1} = G_k + A_k W⁻¹ G_k A_kᵀ, H_{k+1} = H_k + A_kᵀ H_k W⁻¹ A_k;
//! H_k → X quadratically (error ~ ρ(A − BK)^{2^{k+1}}). A need not be invertible (the delay state
//! makes it singular). Before iterating, the Popov–Belevitch–Hautus test rejects an
//! unstabilisable pair; afterwards the residual and the closed-loop spectral radius are checked.

use nalgebra::{Complex, DMatrix};

/// Why the DARE could not be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DareError {
    /// Matrix shapes do not fit together.
    #[error("DARE dimensions do not fit: {0}")]
    Dimensions(String),
    /// A matrix holds NaN or an infinity.
    #[error("DARE input {0} has non-finite entries")]
    NotFinite(&'static str),
    /// R is not symmetric positive definite.
    #[error("R must be symmetric positive definite (R > 0)")]
    RNotPositiveDefinite,
    /// Q is not symmetric with a non-negative diagonal.
    #[error("Q must be symmetric positive semi-definite")]
    QNotSemiDefinite,
    /// (A, B) has an uncontrollable mode on or outside the unit circle.
    #[error(
        "(A, B) is not stabilisable: the mode at λ = {re:.6} {im:+.6}i (|λ| = {abs:.6}) is not reachable from the input"
    )]
    NotStabilisable {
        /// Real part of the offending eigenvalue of A.
        re: f64,
        /// Imaginary part.
        im: f64,
        /// Its magnitude (≥ 1).
        abs: f64,
    },
    /// The doubling iteration did not converge.
    #[error("DARE did not converge in {iterations} doubling steps (relative change {change:.3e})")]
    NotConverged {
        /// Steps taken.
        iterations: usize,
        /// Last relative change of the iterate.
        change: f64,
    },
    /// A linear solve inside the iteration was singular.
    #[error("DARE iteration hit a singular matrix at step {0}")]
    Singular(usize),
    /// The solution does not satisfy the equation to tolerance.
    #[error("DARE residual {residual:.3e} exceeds tolerance {tol:.1e}")]
    Residual {
        /// Relative residual ‖Aᵀ X A − X − AᵀXB K + Q‖_F / max(1, ‖X‖_F).
        residual: f64,
        /// The tolerance.
        tol: f64,
    },
    /// The gain does not stabilise the loop (ρ(A − BK) ≥ 1): Q does not make the unstable modes
    /// observable (for example an undamped mode with zero weight).
    #[error("LQR closed loop is not stable: spectral radius {spectral_radius:.6} ≥ 1")]
    NotStabilising {
        /// ρ(A − BK).
        spectral_radius: f64,
    },
}

/// Settings of the DARE solver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct DareOptions {
    /// Maximum number of doubling steps.
    pub max_iterations: usize,
    /// Stop when ‖H_{k+1} − H_k‖_F ≤ tol·‖H_{k+1}‖_F.
    pub tol: f64,
    /// Accepted relative residual.
    pub residual_tol: f64,
}

impl Default for DareOptions {
    fn default() -> Self {
        Self {
            max_iterations: 60,
            tol: 1e-13,
            residual_tol: 1e-8,
        }
    }
}

/// A solved DARE with the LQR gain and how the solve ended.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct DareSolution {
    /// The stabilising solution X (symmetric).
    pub x: DMatrix<f64>,
    /// The gain K = (R + BᵀXB)⁻¹ BᵀXA (u = −K x), m × n.
    pub k: DMatrix<f64>,
    /// Doubling steps taken.
    pub iterations: usize,
    /// Relative residual of the equation at X.
    pub residual: f64,
    /// Spectral radius of A − BK (< 1).
    pub spectral_radius: f64,
}

fn frob(m: &DMatrix<f64>) -> f64 {
    m.norm()
}

fn symmetric(m: &DMatrix<f64>) -> bool {
    let scale = m.amax().max(f64::MIN_POSITIVE);
    (m - m.transpose()).amax() <= 1e-12 * scale
}

/// Spectral radius of a square real matrix (largest eigenvalue magnitude).
pub(crate) fn spectral_radius(m: &DMatrix<f64>) -> f64 {
    m.complex_eigenvalues()
        .iter()
        .map(|l| l.norm())
        .fold(0.0, f64::max)
}

/// Popov–Belevitch–Hautus: for each eigenvalue λ of A with |λ| ≥ 1 − 1e-9, [A − λI, B/‖B‖] must
/// have full row rank (smallest singular value above 1e-8·max(1, ‖A‖)). The test runs on the
/// balanced pair (D⁻¹AD, D⁻¹B), which has the same rank structure but no unit-driven scaling.
fn check_stabilisable(a: &DMatrix<f64>, b: &DMatrix<f64>) -> Result<(), DareError> {
    let (a, d) = super::expm::balance(a);
    let mut b = b.clone();
    for (i, di) in d.iter().enumerate() {
        b.row_mut(i).scale_mut(1.0 / di);
    }
    let (a, b) = (&a, &b);
    let n = a.nrows();
    let m = b.ncols();
    let bn = frob(b);
    let tol = 1e-8 * frob(a).max(1.0);
    for lam in a.complex_eigenvalues().iter() {
        if lam.norm() < 1.0 - 1e-9 {
            continue;
        }
        let mut pbh = DMatrix::<Complex<f64>>::zeros(n, n + m);
        for i in 0..n {
            for j in 0..n {
                pbh[(i, j)] = Complex::new(a[(i, j)], 0.0);
            }
            pbh[(i, i)] -= lam;
            for j in 0..m {
                pbh[(i, n + j)] = Complex::new(if bn > 0.0 { b[(i, j)] / bn } else { 0.0 }, 0.0);
            }
        }
        let sv = pbh.singular_values();
        let smin = sv.iter().copied().fold(f64::INFINITY, f64::min);
        if smin <= tol {
            return Err(DareError::NotStabilisable {
                re: lam.re,
                im: lam.im,
                abs: lam.norm(),
            });
        }
    }
    Ok(())
}

/// Solves the DARE for (A, B, Q, R) with the structured doubling algorithm and returns X, the
/// LQR gain K and the solve's diagnostics. Errors are typed: bad shapes or values, an
/// unstabilisable pair, no convergence, a residual above tolerance, or an unstable closed loop.
pub(crate) fn dare(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    opts: &DareOptions,
) -> Result<DareSolution, DareError> {
    let n = a.nrows();
    let m = b.ncols();
    if a.ncols() != n || b.nrows() != n || q.shape() != (n, n) || r.shape() != (m, m) {
        return Err(DareError::Dimensions(format!(
            "A {:?}, B {:?}, Q {:?}, R {:?}",
            a.shape(),
            b.shape(),
            q.shape(),
            r.shape()
        )));
    }
    for (name, mat) in [("A", a), ("B", b), ("Q", q), ("R", r)] {
        if mat.iter().any(|v| !v.is_finite()) {
            return Err(DareError::NotFinite(name));
        }
    }
    if !symmetric(r) {
        return Err(DareError::RNotPositiveDefinite);
    }
    let r_chol = r
        .clone()
        .cholesky()
        .ok_or(DareError::RNotPositiveDefinite)?;
    if !symmetric(q) || (0..n).any(|i| q[(i, i)] < 0.0) {
        return Err(DareError::QNotSemiDefinite);
    }
    check_stabilisable(a, b)?;

    let eye = DMatrix::<f64>::identity(n, n);
    let mut ak = a.clone();
    let mut gk = b * r_chol.solve(&b.transpose());
    let mut hk = q.clone();
    let mut iterations = 0;
    let mut change = f64::INFINITY;
    while iterations < opts.max_iterations {
        iterations += 1;
        let w = &eye + &gk * &hk;
        let lu = w.lu();
        // W⁻¹ A_k and W⁻¹ G_k.
        let wa = lu.solve(&ak).ok_or(DareError::Singular(iterations))?;
        let wg = lu.solve(&gk).ok_or(DareError::Singular(iterations))?;
        let a_next = &ak * &wa;
        let mut g_next = &gk + &ak * wg * ak.transpose();
        let mut h_next = &hk + ak.transpose() * &hk * &wa;
        g_next = (&g_next + g_next.transpose()) * 0.5;
        h_next = (&h_next + h_next.transpose()) * 0.5;
        change = frob(&(&h_next - &hk)) / frob(&h_next).max(f64::MIN_POSITIVE);
        ak = a_next;
        gk = g_next;
        hk = h_next;
        if hk.iter().any(|v| !v.is_finite()) {
            return Err(DareError::NotConverged { iterations, change });
        }
        if change <= opts.tol {
            break;
        }
    }
    if change > opts.tol.max(1e3 * f64::EPSILON) {
        return Err(DareError::NotConverged { iterations, change });
    }
    let x = hk;
    let btx = b.transpose() * &x;
    let s = r + &btx * b;
    let k = s
        .clone()
        .lu()
        .solve(&(&btx * a))
        .ok_or(DareError::Singular(iterations))?;
    let res = a.transpose() * &x * a - &x - a.transpose() * &x * b * &k + q;
    let residual = frob(&res) / frob(&x).max(1.0);
    if residual.is_nan() || residual > opts.residual_tol {
        return Err(DareError::Residual {
            residual,
            tol: opts.residual_tol,
        });
    }
    let rho = spectral_radius(&(a - b * &k));
    if rho.is_nan() || rho >= 1.0 {
        return Err(DareError::NotStabilising {
            spectral_radius: rho,
        });
    }
    Ok(DareSolution {
        x,
        k,
        iterations,
        residual,
        spectral_radius: rho,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: MATLAB documentation of `dare`, example "Solve Discrete-Time Algebraic Riccati
    /// Equation": A = [−0.9 −0.3; 0.7 0.1], B = [1; 1], Q = diag(1, 3), R = 0.1 →
    /// X = [4.7687 0.9438; 0.9438 3.2369], G = K = [−0.2216 −0.1297].
    #[test]
    fn dare_matches_matlab_example() {
        let a = DMatrix::from_row_slice(2, 2, &[-0.9, -0.3, 0.7, 0.1]);
        let b = DMatrix::from_row_slice(2, 1, &[1.0, 1.0]);
        let q = DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 0.0, 3.0]);
        let r = DMatrix::from_row_slice(1, 1, &[0.1]);
        let s = dare(&a, &b, &q, &r, &DareOptions::default()).unwrap();
        let xw = [4.7687, 0.9438, 0.9438, 3.2369];
        for (i, w) in xw.iter().enumerate() {
            assert!((s.x[(i / 2, i % 2)] - w).abs() < 6e-5, "X = {}", s.x);
        }
        assert!((s.k[(0, 0)] + 0.2216).abs() < 6e-5 && (s.k[(0, 1)] + 0.1297).abs() < 6e-5);
        assert!(s.residual < 1e-12 && s.spectral_radius < 1.0 && s.iterations < 20);
    }

    /// An unstable mode the input cannot reach: A = diag(1.2, 0.5), B = [0; 1].
    #[test]
    fn dare_rejects_unstabilisable_pair() {
        let a = DMatrix::from_row_slice(2, 2, &[1.2, 0.0, 0.0, 0.5]);
        let b = DMatrix::from_row_slice(2, 1, &[0.0, 1.0]);
        let q = DMatrix::identity(2, 2);
        let r = DMatrix::from_row_slice(1, 1, &[1.0]);
        let e = dare(&a, &b, &q, &r, &DareOptions::default()).unwrap_err();
        assert!(
            matches!(e, DareError::NotStabilisable { re, .. } if (re - 1.2).abs() < 1e-12),
            "{e}"
        );
        let r0 = DMatrix::from_row_slice(1, 1, &[0.0]);
        let a2 = DMatrix::from_row_slice(2, 2, &[0.5, 0.0, 0.0, 0.5]);
        assert_eq!(
            dare(&a2, &b, &q, &r0, &DareOptions::default()).unwrap_err(),
            DareError::RNotPositiveDefinite
        );
    }
}
