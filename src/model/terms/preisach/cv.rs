//! What a Preisach fit learns of its relays from the training log: which relays the log
//! switches at all ([`identified`]: the others' weights cannot be told from the intercept), the
//! smoothness penalty on the weight surface ([`smoothness_rows`]) and its strength by
//! cross-validation on folds of consecutive rows ([`cross_validate`]).

use super::memory::{PreisachGrid, PreisachMemory};
use crate::model::data::FitData;
use nalgebra::{DMatrix, DVector};

/// Folds of consecutive measured rows of the cross-validation.
pub const FOLDS: usize = 5;

/// The candidates of log₁₀ λ: a coarse grid, then half a decade either side of its best.
const LOG_LAMBDA: (f64, f64) = (-6.0, 2.0);

/// Replays the log's positions through the memory; calls `each(B, bias)` on every measured
/// row with the relay boundary after its input ([`PreisachMemory::boundary`]).
fn replay(data: &FitData<'_>, grid: &PreisachGrid, mut each: impl FnMut(&[u8], f64)) {
    let mut mem = PreisachMemory::new(grid.levels);
    let mut b = vec![0u8; grid.levels];
    for (_, row, f) in data.replay_reading(false) {
        mem.step(grid, f.target);
        if let Some(y) = row.bias {
            mem.boundary(&mut b);
            each(&b, y);
        }
    }
}

/// Per relay (triangle order), whether the log's measured rows see it both up and down.
pub fn identified(data: &FitData<'_>, grid: &PreisachGrid) -> Vec<bool> {
    let n = grid.levels;
    let (mut lo, mut hi) = (vec![u8::MAX; n], vec![0u8; n]);
    replay(data, grid, |b, _| {
        for i in 0..n {
            lo[i] = lo[i].min(b[i]);
            hi[i] = hi[i].max(b[i]);
        }
    });
    let mut out = vec![false; grid.cells()];
    for i in 0..n {
        for j in 0..=i {
            // Up on some row (j < B) and down on another (j ≥ B).
            out[PreisachGrid::cell(i, j)] = (lo[i] as usize) <= j && j < hi[i] as usize;
        }
    }
    out
}

/// The smoothness penalty over the model's relays `cols` (`(i, j)` of each column): one row per
/// pair of neighbouring cells both in the model, the difference of their weight densities
/// (weight / cell area; the diagonal cells are half squares), as `(column, coefficient)`.
pub fn smoothness_rows(cols: &[(u8, u8)]) -> Vec<Vec<(usize, f64)>> {
    let find = |i: u8, j: u8| cols.iter().position(|&c| c == (i, j));
    let density = |i: u8, j: u8| if i == j { 2.0 } else { 1.0 };
    let mut rows = Vec::new();
    for (a, &(i, j)) in cols.iter().enumerate() {
        for (ni, nj) in [(i + 1, j), (i, j + 1)] {
            if nj > ni {
                continue;
            }
            if let Some(b) = find(ni, nj) {
                rows.push(vec![(a, density(i, j)), (b, -density(ni, nj))]);
            }
        }
    }
    rows
}

/// Per fold, the normal equations of `[1, s_c …]` (the intercept and the relay states ±1 of
/// `cols`) against the residual: `G`, `b`, `Σ r²` and the rows.
struct FoldSums {
    g: DMatrix<f64>,
    b: DVector<f64>,
    rr: f64,
    n: f64,
}

/// Consecutive rows of one fold with one relay boundary: their count and Σ residual.
struct Run {
    b: Vec<u8>,
    fold: usize,
    rows: u32,
    r: f64,
}

/// The fold sums from pair histograms of the boundaries: per row O(N²) counts, never the
/// `cells²` products.
fn fold_sums(
    data: &FitData<'_>,
    grid: &PreisachGrid,
    cols: &[(u8, u8)],
    residual: &[f64],
) -> Vec<FoldSums> {
    let n = grid.levels;
    let w = n + 1;
    let m = residual.len();
    // hist2[f][(i·n + i')·w² + b·w + b'] for i ≤ i'; hist1 of Σ r by (i, b); counts by (i, b).
    let mut hist2 = vec![vec![0u32; n * n * w * w]; FOLDS];
    let mut rsum = vec![vec![0.0f64; n * w]; FOLDS];
    let mut cnt = vec![vec![0u32; n * w]; FOLDS];
    let mut tot = [(0.0f64, 0.0f64, 0.0f64); FOLDS];
    let mut row = 0usize;
    // Consecutive rows of one fold with the same boundary (a run: the relay states change only
    // where the position crosses a threshold) are counted once, with their count and Σ r.
    let mut run = Run {
        b: vec![0; n],
        fold: 0,
        rows: 0,
        r: 0.0,
    };
    let mut add = |run: &Run| {
        let (f, b) = (run.fold, &run.b);
        let h = &mut hist2[f];
        for i in 0..n {
            let bi = b[i] as usize;
            rsum[f][i * w + bi] += run.r;
            cnt[f][i * w + bi] += run.rows;
            for (i2, &b2) in b.iter().enumerate().skip(i) {
                h[((i * n + i2) * w + bi) * w + b2 as usize] += run.rows;
            }
        }
    };
    replay(data, grid, |b, _| {
        let Some(&r) = residual.get(row) else {
            return;
        };
        let f = (row * FOLDS / m.max(1)).min(FOLDS - 1);
        row += 1;
        if run.rows > 0 && run.fold == f && run.b == b {
            run.rows += 1;
            run.r += r;
        } else {
            if run.rows > 0 {
                add(&run);
            }
            run.b.copy_from_slice(b);
            (run.fold, run.rows, run.r) = (f, 1, r);
        }
        let t = &mut tot[f];
        t.0 += 1.0;
        t.1 += r;
        t.2 += r * r;
    });
    if run.rows > 0 {
        add(&run);
    }
    let p = cols.len() + 1;
    (0..FOLDS)
        .map(|f| {
            let (nf, sr, rr) = tot[f];
            // Suffix counts: above(i, j) = #rows with B(i) > j; rabove(i, j) = Σ r there.
            let mut above = vec![0.0; n * w];
            let mut rabove = vec![0.0; n * w];
            for i in 0..n {
                let (mut c, mut s) = (0.0, 0.0);
                for bb in (0..w).rev() {
                    above[i * w + bb] = c;
                    rabove[i * w + bb] = s;
                    c += f64::from(cnt[f][i * w + bb]);
                    s += rsum[f][i * w + bb];
                }
            }
            // 2-D suffix counts of each pair's histogram: both(j, j') = #rows with B(i) > j
            // and B(i') > j'.
            let mut both = vec![0.0; n * n * w * w];
            for i in 0..n {
                for i2 in i..n {
                    let base = (i * n + i2) * w * w;
                    let h = &hist2[f][base..base + w * w];
                    let out = &mut both[base..base + w * w];
                    // S[j][j'] = Σ_{b > j, b' > j'} h[b][b'].
                    for j in (0..w).rev() {
                        for j2 in (0..w).rev() {
                            let next = |a: usize, c: usize, o: &[f64]| {
                                if a < w && c < w { o[a * w + c] } else { 0.0 }
                            };
                            let cell = if j + 1 < w && j2 + 1 < w {
                                f64::from(h[(j + 1) * w + j2 + 1])
                            } else {
                                0.0
                            };
                            let v = cell + next(j + 1, j2, out) + next(j, j2 + 1, out)
                                - next(j + 1, j2 + 1, out);
                            out[j * w + j2] = v;
                        }
                    }
                }
            }
            let mut g = DMatrix::zeros(p, p);
            let mut bv = DVector::zeros(p);
            g[(0, 0)] = nf;
            bv[0] = sr;
            for (a, &(i, j)) in cols.iter().enumerate() {
                let (i, j) = (i as usize, j as usize);
                let ca = above[i * w + j];
                g[(0, a + 1)] = 2.0 * ca - nf;
                g[(a + 1, 0)] = 2.0 * ca - nf;
                bv[a + 1] = 2.0 * rabove[i * w + j] - sr;
                for (c, &(i2, j2)) in cols.iter().enumerate().skip(a) {
                    let (i2, j2) = (i2 as usize, j2 as usize);
                    let cb = above[i2 * w + j2];
                    let (x, y, jx, jy) = if i <= i2 {
                        (i, i2, j, j2)
                    } else {
                        (i2, i, j2, j)
                    };
                    let both_up = both[(x * n + y) * w * w + jx * w + jy];
                    let v = nf - 2.0 * ca - 2.0 * cb + 4.0 * both_up;
                    g[(a + 1, c + 1)] = v;
                    g[(c + 1, a + 1)] = v;
                }
            }
            FoldSums {
                g,
                b: bv,
                rr,
                n: nf,
            }
        })
        .collect()
}

/// The penalty matrix `DᵀD` of [`smoothness_rows`] over `[1, s_c …]` (the intercept free).
fn penalty_matrix(p: usize, rows: &[Vec<(usize, f64)>]) -> DMatrix<f64> {
    let mut pm = DMatrix::zeros(p, p);
    for r in rows {
        for &(a, va) in r {
            for &(b, vb) in r {
                pm[(a + 1, b + 1)] += va * vb;
            }
        }
    }
    pm
}

/// The held-out squared error summed over the folds at penalty `λ = 10^t` (∞ where a system
/// cannot be solved).
fn cv_error(folds: &[FoldSums], all: &FoldSums, pm: &DMatrix<f64>, t: f64) -> f64 {
    let lambda = 10f64.powf(t);
    let p = all.b.len();
    let mut total = 0.0;
    for k in folds {
        let ntr = all.n - k.n;
        let mut m = &all.g - &k.g + pm * (lambda * ntr);
        // A whisper of ridge on the relays keeps a relay constant within the training folds
        // solvable; far below any penalty tried.
        for c in 1..p {
            m[(c, c)] += 1e-9 * ntr;
        }
        let rhs = &all.b - &k.b;
        let Some(ch) = m.cholesky() else {
            return f64::INFINITY;
        };
        let wv = ch.solve(&rhs);
        total += k.rr - 2.0 * wv.dot(&k.b) + (&k.g * &wv).dot(&wv);
    }
    total
}

/// log₁₀ of the smoothness penalty's strength λ (relative: `λ·n·‖D w‖²` against the RSS of
/// `n` rows) that predicts held-out folds of consecutive measured rows best, fitting the
/// relays `cols` and an intercept to `residual` (the measured bias less the rest of the
/// model, one value per measured row in log order): a grid of whole decades over
/// [−6, 2], then half a decade either side of the best.
pub fn cross_validate(
    data: &FitData<'_>,
    grid: &PreisachGrid,
    cols: &[(u8, u8)],
    residual: &[f64],
) -> f64 {
    let folds = fold_sums(data, grid, cols, residual);
    let p = cols.len() + 1;
    let mut all = FoldSums {
        g: DMatrix::zeros(p, p),
        b: DVector::zeros(p),
        rr: 0.0,
        n: 0.0,
    };
    for f in &folds {
        all.g += &f.g;
        all.b += &f.b;
        all.rr += f.rr;
        all.n += f.n;
    }
    let pm = penalty_matrix(p, &smoothness_rows(cols));
    let mut best = (f64::INFINITY, LOG_LAMBDA.1);
    let mut t = LOG_LAMBDA.0;
    while t <= LOG_LAMBDA.1 {
        let e = cv_error(&folds, &all, &pm, t);
        if e < best.0 {
            best = (e, t);
        }
        t += 1.0;
    }
    let centre = best.1;
    for t in [centre - 0.5, centre + 0.5] {
        if (LOG_LAMBDA.0..=LOG_LAMBDA.1).contains(&t) {
            let e = cv_error(&folds, &all, &pm, t);
            if e < best.0 {
                best = (e, t);
            }
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::Log;
    use crate::numeric::rng::SimRng;

    /// A densely sampled log (runs of equal relay states tens of rows long) when `dense`, else
    /// a random-seek one (the state changes nearly every row).
    fn log(dense: bool) -> Log {
        if !dense {
            return crate::sim::random_log(3000, 11);
        }
        let mut rng = SimRng::new(9);
        let (mut x, mut target) = (0.0f64, 1.0f64);
        let mut text = String::from("time_s,track,bias\n");
        for k in 0..6000 {
            if (target - x).abs() < 0.01 {
                target = rng.normal();
            }
            x += 0.01 * (target - x).signum();
            text.push_str(&format!("{},{x},{}\n", k as f64 * 1e-3, rng.normal()));
        }
        Log::from_reader("dense.csv", text.as_bytes(), &Default::default()).unwrap()
    }

    /// Reference: the fold sums from the pair histograms (runs of rows with one boundary
    /// counted once) equal the sums of the explicit design rows `[1, s_c …]` (each relay's
    /// state ±1 from the boundary, as the term's basis) fold by fold, on a dense log and on a
    /// seek log. Counts are whole numbers; `b` to 1e-9 relative.
    #[test]
    fn fold_sums_equal_the_explicit_design_rows() {
        for dense in [true, false] {
            let log = log(dense);
            let data = FitData::new(&log);
            let [lo, hi] = crate::numeric::stats::range(log.tracks()).unwrap();
            let grid = PreisachGrid { lo, hi, levels: 6 };
            let cols: Vec<(u8, u8)> = grid.relays().collect();
            let m = log.measured_count();
            let mut rng = SimRng::new(2);
            let residual: Vec<f64> = (0..m).map(|_| rng.normal()).collect();
            let got = fold_sums(&data, &grid, &cols, &residual);
            let p = cols.len() + 1;
            let mut want = vec![(DMatrix::<f64>::zeros(p, p), DVector::<f64>::zeros(p)); FOLDS];
            let mut row = 0;
            let mut s = vec![0.0; p];
            replay(&data, &grid, |b, _| {
                let f = (row * FOLDS / m).min(FOLDS - 1);
                s[0] = 1.0;
                for (o, &(i, j)) in s[1..].iter_mut().zip(&cols) {
                    *o = if j < b[i as usize] { 1.0 } else { -1.0 };
                }
                let (g, bv) = &mut want[f];
                for a in 0..p {
                    bv[a] += s[a] * residual[row];
                    for c in 0..p {
                        g[(a, c)] += s[a] * s[c];
                    }
                }
                row += 1;
            });
            assert_eq!(row, m);
            for (f, (k, (g, bv))) in got.iter().zip(&want).enumerate() {
                assert_eq!(&k.g, g, "dense {dense}, fold {f}");
                for a in 0..p {
                    let e = (k.b[a] - bv[a]).abs() / bv.abs().max().max(1.0);
                    assert!(e < 1e-9, "dense {dense}, fold {f}, column {a}: {e:e}");
                }
            }
        }
    }
}
