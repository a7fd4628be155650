//! Runs of consecutive least-squares rows that share their values in some columns, folded by
//! an orthogonal transformation before they are factorised ([`RunFolder`]).
//!
//! A run of `K` rows `[c, z_k, y_k]` whose columns `c` are equal (the relay states of a
//! Preisach term, constant until the position crosses a threshold) is replaced by the Helmert
//! transformation of its rows: one row `√K·[c, z̄, ȳ]` and `K − 1` contrast rows
//! `√((k−1)/k)·[0, z_k − z̄_{k−1}, y_k − ȳ_{k−1}]` (k = 2…K, `z̄_{k−1}` the mean of the run's
//! first k − 1 rows, Welford's update). The Helmert matrix is orthogonal, so the `R` factor of
//! the transformed rows is that of the original ones up to signs and rounding: the same least
//! squares. The contrast rows are zero in the run columns, so they are factorised on the other
//! columns alone (`2·k²` instead of `2·p²` flops a row); a run of one row passes unchanged,
//! bit for bit.

/// Folds runs of rows equal in the columns `run` (see the module).
#[derive(Debug, Clone)]
pub(crate) struct RunFolder {
    /// Positions in a row of the columns that define a run.
    run: Vec<usize>,
    /// `run` as a range where its positions are consecutive (compared as one slice).
    span: Option<std::ops::Range<usize>>,
    /// Positions of the other columns (the contrast rows' columns).
    rest: Vec<usize>,
    /// The run columns' values of the current run.
    key: Vec<f64>,
    /// The mean of the current run's rows on `rest`, then the response.
    mean: Vec<f64>,
    /// Rows in the current run (0: none open).
    k: usize,
    /// A whole row (the run's mean row), and a contrast row on `rest`.
    full: Vec<f64>,
    contrast: Vec<f64>,
}

impl RunFolder {
    /// Rows of `p` columns (the response apart) whose runs are defined by the columns `run`
    /// (positions, each below `p`).
    pub(crate) fn new(p: usize, run: &[usize]) -> Self {
        let mut is_run = vec![false; p];
        for &j in run {
            is_run[j] = true;
        }
        let run: Vec<usize> = (0..p).filter(|&j| is_run[j]).collect();
        let rest: Vec<usize> = (0..p).filter(|&j| !is_run[j]).collect();
        let span = match (run.first(), run.last()) {
            (Some(&a), Some(&b)) if b + 1 - a == run.len() => Some(a..b + 1),
            _ => None,
        };
        Self {
            span,
            key: vec![0.0; run.len()],
            mean: vec![0.0; rest.len() + 1],
            k: 0,
            full: vec![0.0; p],
            contrast: vec![0.0; rest.len()],
            run,
            rest,
        }
    }

    /// The positions of the contrast rows' columns.
    pub(crate) fn rest(&self) -> &[usize] {
        &self.rest
    }

    /// Adds the row `x` with response `y`: a row that ends the current run first hands the
    /// run's mean row to `whole`; a row that continues it hands a contrast row (on
    /// [`RunFolder::rest`]) to `contrast`. With `known`, the caller vouches that the run
    /// columns of `x` are those of the previous row pushed, bit for bit (they are not compared).
    #[inline]
    pub(crate) fn push(
        &mut self,
        x: &[f64],
        y: f64,
        known: bool,
        whole: &mut impl FnMut(&[f64], f64),
        contrast: &mut impl FnMut(&[f64], f64),
    ) {
        // Equal bit for bit (a run's rows have the very same values in its columns).
        let same = self.k > 0
            && (known
                || match &self.span {
                    Some(r) => x[r.clone()]
                        .iter()
                        .zip(&self.key)
                        .all(|(a, b)| a.to_bits() == b.to_bits()),
                    None => self
                        .run
                        .iter()
                        .zip(&self.key)
                        .all(|(&j, &c)| x[j].to_bits() == c.to_bits()),
                });
        debug_assert!(
            !(known && self.k > 0)
                || self
                    .run
                    .iter()
                    .zip(&self.key)
                    .all(|(&j, &c)| x[j].to_bits() == c.to_bits()),
            "a row vouched for differs from its run in the run columns"
        );
        if !same {
            self.flush(whole);
            for (c, &j) in self.key.iter_mut().zip(&self.run) {
                *c = x[j];
            }
            for (m, &j) in self.mean.iter_mut().zip(&self.rest) {
                *m = x[j];
            }
            self.mean[self.rest.len()] = y;
            self.k = 1;
            return;
        }
        self.extend(|_, j| x[j], y, contrast);
    }

    /// [`RunFolder::push`] of a row that continues the open run (the caller vouches for its run
    /// columns, which it leaves out): `z`, its values on [`RunFolder::rest`], in that order.
    #[inline]
    pub(crate) fn push_continuing(
        &mut self,
        z: &[f64],
        y: f64,
        contrast: &mut impl FnMut(&[f64], f64),
    ) {
        assert!(self.k > 0, "no run is open");
        debug_assert_eq!(z.len(), self.rest.len());
        self.extend(|i, _| z[i], y, contrast);
    }

    /// Adds a row to the open run: `value(i, j)`, its value in the `i`-th other column (at
    /// position `j` of a whole row); hands its contrast row to `contrast`.
    #[inline(always)]
    fn extend(
        &mut self,
        value: impl Fn(usize, usize) -> f64,
        y: f64,
        contrast: &mut impl FnMut(&[f64], f64),
    ) {
        self.k += 1;
        let k = self.k as f64;
        let scale = ((k - 1.0) / k).sqrt();
        let q = self.rest.len();
        for (i, ((o, m), &j)) in self
            .contrast
            .iter_mut()
            .zip(&mut self.mean)
            .zip(&self.rest)
            .enumerate()
        {
            let d = value(i, j) - *m;
            *o = scale * d;
            *m += d / k;
        }
        let d = y - self.mean[q];
        self.mean[q] += d / k;
        contrast(&self.contrast, scale * d);
    }

    /// Hands the open run's mean row (× √K) to `whole` and closes the run.
    pub(crate) fn flush(&mut self, whole: &mut impl FnMut(&[f64], f64)) {
        match self.k {
            0 => return,
            1 => {
                for (&j, &c) in self.run.iter().zip(&self.key) {
                    self.full[j] = c;
                }
                for (&j, &m) in self.rest.iter().zip(&self.mean) {
                    self.full[j] = m;
                }
                whole(&self.full, self.mean[self.rest.len()]);
            }
            k => {
                let s = (k as f64).sqrt();
                for (&j, &c) in self.run.iter().zip(&self.key) {
                    self.full[j] = s * c;
                }
                for (&j, &m) in self.rest.iter().zip(&self.mean) {
                    self.full[j] = s * m;
                }
                whole(&self.full, s * self.mean[self.rest.len()]);
            }
        }
        self.k = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::rng::SimRng;

    /// The Gram matrix `[X y]ᵀ[X y]` of rows, row-major (p + 1)².
    fn gram(rows: &[(Vec<f64>, f64)]) -> Vec<f64> {
        let w = rows[0].0.len() + 1;
        let mut g = vec![0.0; w * w];
        for (x, y) in rows {
            let v: Vec<f64> = x.iter().copied().chain([*y]).collect();
            for a in 0..w {
                for b in 0..w {
                    g[a * w + b] += v[a] * v[b];
                }
            }
        }
        g
    }

    /// Reference: the Helmert transformation is orthogonal, so the transformed rows (mean rows
    /// and contrast rows, zero in the run columns) have the Gram matrix of the original rows —
    /// checked on random rows in runs of 1 to 40 (relay states ±1 in three run columns, two
    /// free columns of large mean and small spread, the cancellation Welford's update avoids).
    /// A run of one row passes bit for bit.
    #[test]
    fn folded_rows_keep_the_gram_matrix() {
        let mut rng = SimRng::new(3);
        let p = 5;
        let run = [0, 2, 3];
        let mut rows = Vec::new();
        while rows.len() < 2000 {
            let len = 1 + (rng.uniform() * 40.0) as usize;
            let key: Vec<f64> = (0..3)
                .map(|_| if rng.uniform() < 0.5 { 1.0 } else { -1.0 })
                .collect();
            for _ in 0..len {
                let mut x = vec![0.0; p];
                x[0] = key[0];
                x[2] = key[1];
                x[3] = key[2];
                x[1] = 1e4 + rng.normal();
                x[4] = rng.normal();
                rows.push((x, 3.0 * rng.normal() + 100.0));
            }
        }
        let mut f = RunFolder::new(p, &run);
        let mut out: Vec<(Vec<f64>, f64)> = Vec::new();
        let mut contrast: Vec<(Vec<f64>, f64)> = Vec::new();
        for (x, y) in &rows {
            f.push(
                x,
                *y,
                false,
                &mut |x, y| out.push((x.to_vec(), y)),
                &mut |z, y| {
                    let mut x = vec![0.0; p];
                    for (&j, &v) in [1usize, 4].iter().zip(z) {
                        x[j] = v;
                    }
                    contrast.push((x, y));
                },
            );
        }
        f.flush(&mut |x, y| out.push((x.to_vec(), y)));
        assert_eq!(f.rest(), &[1, 4]);
        assert!(out.len() < rows.len() / 5, "{} mean rows", out.len());
        assert_eq!(out.len() + contrast.len(), rows.len());
        let all: Vec<(Vec<f64>, f64)> = out.iter().chain(&contrast).cloned().collect();
        let (g0, g1) = (gram(&rows), gram(&all));
        let w = p + 1;
        for a in 0..w {
            for b in 0..w {
                let scale = (g0[a * w + a] * g0[b * w + b]).sqrt();
                let e = (g0[a * w + b] - g1[a * w + b]).abs() / scale;
                assert!(
                    e < 1e-12,
                    "({a}, {b}): {} vs {}",
                    g0[a * w + b],
                    g1[a * w + b]
                );
            }
        }
        // Runs of one row: the rows themselves.
        let mut f = RunFolder::new(p, &run);
        let mut back = Vec::new();
        let distinct: Vec<(Vec<f64>, f64)> = (0..50)
            .map(|i| {
                (
                    vec![i as f64, 0.1, -(i as f64), 0.3, 1.0 / 3.0],
                    0.7 * i as f64,
                )
            })
            .collect();
        for (x, y) in &distinct {
            f.push(
                x,
                *y,
                false,
                &mut |x, y| back.push((x.to_vec(), y)),
                &mut |_, _| panic!("no run has two rows"),
            );
        }
        f.flush(&mut |x, y| back.push((x.to_vec(), y)));
        assert_eq!(back, distinct);
    }
}
