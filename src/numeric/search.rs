//! One-dimensional minimisation on an interval: a grid, then golden-section steps in the
//! bracket around the best point ([`golden_min`]); the same search for an objective that
//! evaluates a batch of points at once ([`golden_min_batched`]: the same points, the same
//! result).

/// Minimises `f` on [lo, hi]: `grid` evenly spaced points, then `iters` golden-section steps
/// in the bracket around the best. Returns (x, f(x), evaluations).
pub(crate) fn golden_min(
    f: &dyn Fn(f64) -> f64,
    lo: f64,
    hi: f64,
    grid: usize,
    iters: usize,
) -> (f64, f64, usize) {
    let g = grid.max(3);
    let xs: Vec<f64> = (0..g)
        .map(|i| lo + (hi - lo) * i as f64 / (g - 1) as f64)
        .collect();
    let fs: Vec<f64> = xs.iter().map(|&x| f(x)).collect();
    let mut evals = g;
    let best = (0..g).min_by(|&a, &b| fs[a].total_cmp(&fs[b])).unwrap_or(0);
    let (mut a, mut b) = (xs[best.saturating_sub(1)], xs[(best + 1).min(g - 1)]);
    let (mut bx, mut bf) = (xs[best], fs[best]);
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - phi * (b - a);
    let mut d = a + phi * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    evals += 2;
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - phi * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + phi * (b - a);
            fd = f(d);
        }
        evals += 1;
    }
    for (x, v) in [(c, fc), (d, fd)] {
        if v < bf {
            bx = x;
            bf = v;
        }
    }
    (bx, bf, evals)
}

/// Golden-section iterations [`golden_min_batched`] looks ahead: it evaluates every point the
/// next `SPECULATE` iterations may need (at most 2^SPECULATE − 1) in one batch.
const SPECULATE: u32 = 3;

/// [`golden_min`] for an objective that evaluates a batch of points at once (cheaper per point
/// than one at a time): the same points compared in the same order, so the same result and the
/// same count of evaluations (tested), but each golden-section step whose point is not yet known
/// evaluates, in one batch, that point and every point the next iterations may ask for whichever
/// way their comparisons go ([`SPECULATE`] iterations deep; the grid is one batch too). The
/// evaluations counted are those [`golden_min`] makes; the speculative ones are not.
pub(crate) fn golden_min_batched(
    f: &dyn Fn(&[f64]) -> Vec<f64>,
    lo: f64,
    hi: f64,
    grid: usize,
    iters: usize,
) -> (f64, f64, usize) {
    let g = grid.max(3);
    let xs: Vec<f64> = (0..g)
        .map(|i| lo + (hi - lo) * i as f64 / (g - 1) as f64)
        .collect();
    let fs = f(&xs);
    let mut evals = g;
    let best = (0..g).min_by(|&a, &b| fs[a].total_cmp(&fs[b])).unwrap_or(0);
    let (mut a, mut b) = (xs[best.saturating_sub(1)], xs[(best + 1).min(g - 1)]);
    let (mut bx, mut bf) = (xs[best], fs[best]);
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - phi * (b - a);
    let mut d = a + phi * (b - a);
    let mut known = Golden {
        phi,
        memo: Vec::new(),
    };
    let mut pts = vec![c, d];
    known.explore([a, b, c, d], [None, None], iters, SPECULATE - 1, &mut pts);
    known.evaluate(f, pts);
    let (mut fc, mut fd) = (known.get(c), known.get(d));
    evals += 2;
    for left in (0..iters).rev() {
        // `left`: iterations after this one.
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - phi * (b - a);
            if known.lookup(c).is_none() {
                let mut pts = vec![c];
                known.explore(
                    [a, b, c, d],
                    [None, Some(fd)],
                    left,
                    SPECULATE - 1,
                    &mut pts,
                );
                known.evaluate(f, pts);
            }
            fc = known.get(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + phi * (b - a);
            if known.lookup(d).is_none() {
                let mut pts = vec![d];
                known.explore(
                    [a, b, c, d],
                    [Some(fc), None],
                    left,
                    SPECULATE - 1,
                    &mut pts,
                );
                known.evaluate(f, pts);
            }
            fd = known.get(d);
        }
        evals += 1;
    }
    for (x, v) in [(c, fc), (d, fd)] {
        if v < bf {
            bx = x;
            bf = v;
        }
    }
    (bx, bf, evals)
}

/// The objective values [`golden_min_batched`] knows, by the bits of the point.
struct Golden {
    phi: f64,
    memo: Vec<(u64, f64)>,
}

impl Golden {
    fn lookup(&self, x: f64) -> Option<f64> {
        self.memo
            .iter()
            .find(|(bits, _)| *bits == x.to_bits())
            .map(|&(_, v)| v)
    }

    /// A value evaluated before (always, by construction; NaN otherwise, which compares false
    /// as an unevaluated point would never be compared).
    fn get(&self, x: f64) -> f64 {
        self.lookup(x).unwrap_or(f64::NAN)
    }

    /// Evaluates the points of `pts` not known yet, in one batch.
    fn evaluate(&mut self, f: &dyn Fn(&[f64]) -> Vec<f64>, mut pts: Vec<f64>) {
        let mut seen = Vec::with_capacity(pts.len());
        pts.retain(|x| {
            let new = self.lookup(*x).is_none() && !seen.contains(&x.to_bits());
            seen.push(x.to_bits());
            new
        });
        if pts.is_empty() {
            return;
        }
        let vals = f(&pts);
        self.memo.extend(pts.iter().map(|x| x.to_bits()).zip(vals));
    }

    /// Appends to `pts` the points the next `left` iterations (at most `depth` of them) of the
    /// golden-section loop may need from the bracket `[a, b]` with inner points `c`, `d` and
    /// their values `fc`, `fd` (`None`: not known yet, so both outcomes of the comparison are
    /// followed). The arithmetic is [`golden_min`]'s, so the points are the same bits.
    fn explore(
        &self,
        [a, b, c, d]: [f64; 4],
        [fc, fd]: [Option<f64>; 2],
        left: usize,
        depth: u32,
        pts: &mut Vec<f64>,
    ) {
        if left == 0 || depth == 0 {
            return;
        }
        let phi = self.phi;
        let outcomes: &[bool] = match (fc, fd) {
            (Some(x), Some(y)) => {
                if x < y {
                    &[true]
                } else {
                    &[false]
                }
            }
            _ => &[true, false],
        };
        for &less in outcomes {
            if less {
                let (b, d, fd) = (d, c, fc);
                let c = b - phi * (b - a);
                let fc = self.lookup(c);
                if fc.is_none() {
                    pts.push(c);
                }
                self.explore([a, b, c, d], [fc, fd], left - 1, depth - 1, pts);
            } else {
                let (a, c, fc) = (c, d, fd);
                let d = a + phi * (b - a);
                let fd = self.lookup(d);
                if fd.is_none() {
                    pts.push(d);
                }
                self.explore([a, b, c, d], [fc, fd], left - 1, depth - 1, pts);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: [`golden_min`], one point at a time. The batched search must return the
    /// same point, value and count of evaluations (bits) on smooth, flat, rough, partly
    /// infinite and edge-minimum objectives, and evaluate in far fewer batches than points.
    #[test]
    fn golden_min_batched_equals_golden_min() {
        type Objective = (&'static str, fn(f64) -> f64);
        let objectives: [Objective; 6] = [
            ("parabola", |x| (x - 0.3) * (x - 0.3)),
            ("flat", |_| 1.0),
            ("steps", |x| ((x * 37.0).floor() - 11.0).abs()),
            ("rough", |x| (x * 91.0).sin() + 0.1 * (x - 0.6).powi(2)),
            ("infinite", |x| if x > 0.5 { f64::INFINITY } else { -x }),
            ("edge", |x| x),
        ];
        for (name, f) in objectives {
            for (lo, hi, grid, iters) in [(0.0, 1.0, 24, 40), (-2.0, 2.0, 3, 7), (0.0, 1.0, 10, 0)]
            {
                let batches = std::cell::Cell::new(0);
                let many = |xs: &[f64]| -> Vec<f64> {
                    batches.set(batches.get() + 1);
                    xs.iter().map(|&x| f(x)).collect()
                };
                let one = golden_min(&f, lo, hi, grid, iters);
                let b = golden_min_batched(&many, lo, hi, grid, iters);
                assert_eq!(
                    (one.0.to_bits(), one.1.to_bits(), one.2),
                    (b.0.to_bits(), b.1.to_bits(), b.2),
                    "{name} {grid} {iters}"
                );
                assert!(
                    batches.get() <= 2 + iters.div_ceil(3),
                    "{name}: {}",
                    batches.get()
                );
            }
        }
    }

    #[test]
    fn golden_min_finds_a_parabola_minimum() {
        // Reference: the minimum of (x − 0.3)² is at 0.3.
        let (x, fx, ev) = golden_min(&|x: f64| (x - 0.3) * (x - 0.3), -2.0, 2.0, 10, 40);
        assert!(
            (x - 0.3).abs() < 1e-6 && fx < 1e-12 && ev == 52,
            "{x} {fx} {ev}"
        );
    }
}
