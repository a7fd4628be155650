//! One-dimensional minimisation on an interval: a grid, then golden-section steps in the
//! bracket around the best point ([`golden_min`]); the same search for an objective that
//! evaluates a batch of points at once ([`golden_min_batched`]: the same points, the same
//! result); and a search near a known minimum in batches that follows the parabola through
//! the best points ([`zoom_min_batched`]).

/// `g` (≥ 2) evenly spaced points from `lo` to `hi`, both included: the searches' grid.
fn grid_points(lo: f64, hi: f64, g: usize) -> Vec<f64> {
    (0..g)
        .map(|i| lo + (hi - lo) * i as f64 / (g - 1) as f64)
        .collect()
}

/// The index `i < n` of the lowest `value(i)` (the first of equals; 0 where `n` is 0).
fn lowest(n: usize, value: impl Fn(usize) -> f64) -> usize {
    (0..n)
        .min_by(|&a, &b| value(a).total_cmp(&value(b)))
        .unwrap_or(0)
}

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
    let xs = grid_points(lo, hi, g);
    let fs: Vec<f64> = xs.iter().map(|&x| f(x)).collect();
    let mut evals = g;
    let best = lowest(g, |i| fs[i]);
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
    let xs = grid_points(lo, hi, g);
    let fs = f(&xs);
    let mut evals = g;
    let best = lowest(g, |i| fs[i]);
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

/// Most batches [`zoom_min_batched`] evaluates after its grid (each shrinks the bracket to at
/// most half its width: more than any bracket needs to reach 10⁻¹⁴ of itself).
const ZOOM_MAX_BATCHES: usize = 48;

/// The ratio of successive offsets of [`zoom_min_batched`]'s points around the parabola's
/// vertex.
const ZOOM_SPREAD: f64 = 8.0;

/// Minimises `f` on [lo, hi], evaluating `batch` points at a time (at least 4): `grid` evenly
/// spaced points, then batches inside the bracket around the best point known (the evaluated
/// points either side of it) until that bracket is at most `width` wide. Each batch spreads
/// `batch/2 − 1` points evenly over the bracket, so the bracket shrinks to at most half its width
/// whatever the objective, and places the others at the vertex of the parabola through the best
/// point and its neighbours and either side of it, at offsets d, 8d, 64d, … where d is a quarter
/// of the step from the best point to the vertex (at least about `width`/2): where the objective
/// is smooth at its minimum the vertex errs by far less than that step, so the bracket shrinks
/// to 2d, and the next vertex's step is smaller still (golden section shrinks it 1.6 times a
/// point, about 4 times a batch that looks three steps ahead). On a unimodal objective it
/// ends, as [`golden_min`] does, in a bracket about the minimum of the grid's best cell.
/// Returns (x, f(x), evaluations).
pub(crate) fn zoom_min_batched(
    f: &dyn Fn(&[f64]) -> Vec<f64>,
    lo: f64,
    hi: f64,
    grid: usize,
    batch: usize,
    width: f64,
) -> (f64, f64, usize) {
    let g = grid.max(3);
    let batch = batch.max(4);
    let xs = grid_points(lo, hi, g);
    let fs = f(&xs);
    let mut evals = g;
    // Evaluated points, in increasing order of x.
    let mut pts: Vec<(f64, f64)> = xs.into_iter().zip(fs).collect();
    for _ in 0..ZOOM_MAX_BATCHES {
        let i = lowest(pts.len(), |i| pts[i].1);
        let (a, b) = (
            pts[i.saturating_sub(1)].0,
            pts[(i + 1).min(pts.len() - 1)].0,
        );
        let w = b - a;
        // (A NaN width ends it too.)
        if w.partial_cmp(&width) != Some(std::cmp::Ordering::Greater) {
            break;
        }
        let v = if i > 0 && i + 1 < pts.len() {
            parabola_vertex(pts[i - 1], pts[i], pts[i + 1])
                .filter(|v| *v > a && *v < b)
                .unwrap_or(pts[i].0)
        } else {
            pts[i].0
        };
        // A quarter of the step the parabola takes from the best point: the vertex of a smooth
        // minimum's parabola errs by far less than its step (nothing left to step: the width).
        let spread = batch / 2 - 1;
        let mut new: Vec<f64> = (1..=spread)
            .map(|k| a + w * k as f64 / (spread + 1) as f64)
            .collect();
        let mut off = (0.25 * (v - pts[i].0).abs()).max(0.45 * width).min(w / 8.0);
        new.push(v);
        while new.len() < batch {
            new.push(v - off);
            if new.len() < batch {
                new.push(v + off);
            }
            off *= ZOOM_SPREAD;
        }
        // Only points strictly inside the bracket and not evaluated yet.
        new.retain(|&x| x > a && x < b);
        new.sort_by(f64::total_cmp);
        new.dedup_by(|x, y| x.to_bits() == y.to_bits());
        new.retain(|&x| pts.binary_search_by(|p| p.0.total_cmp(&x)).is_err());
        if new.is_empty() {
            break;
        }
        let vals = f(&new);
        evals += new.len();
        for (x, y) in new.into_iter().zip(vals) {
            let at = pts.partition_point(|p| p.0 < x);
            pts.insert(at, (x, y));
        }
    }
    let i = lowest(pts.len(), |i| pts[i].1);
    (pts[i].0, pts[i].1, evals)
}

/// The vertex of the parabola through three points with `l.0 < m.0 < r.0`, where it is a
/// minimum (`None` where the points are collinear, the parabola opens downwards or a value is
/// not finite).
fn parabola_vertex(l: (f64, f64), m: (f64, f64), r: (f64, f64)) -> Option<f64> {
    let (p, q) = (m.0 - l.0, m.0 - r.0);
    let (fp, fq) = (m.1 - r.1, m.1 - l.1);
    let num = p * p * fp - q * q * fq;
    let den = p * fp - q * fq;
    // A minimum: the middle point lies below the chord of the outer two (den < 0 then).
    let v = m.0 - 0.5 * num / den;
    (den < 0.0 && v.is_finite()).then_some(v)
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

    /// Reference: [`golden_min`] with 40 steps (its bracket then about 10⁻⁹ of the grid's
    /// cell). On unimodal objectives (parabolas, an asymmetric smooth minimum, a quartic, a
    /// kink, an edge minimum) [`zoom_min_batched`] ends within twice its width of golden
    /// section's point (and of 10⁻⁷ of the interval: rounding flattens a smooth minimum over
    /// about √ε), at a value no larger than the objective's within twice its width of that
    /// point. On the smooth ones it takes at most 5 batches, the grid's included, to a width of
    /// 10⁻⁷ of the interval or more, and 9 to 2.5·10⁻¹⁰ (golden section, three steps a batch:
    /// 11 and 15). On rough and partly infinite objectives it ends at a point no worse than the
    /// objective within its width of it (a local minimum).
    #[test]
    fn zoom_min_batched_ends_where_golden_section_ends() {
        type Objective = (&'static str, fn(f64) -> f64, bool);
        let objectives: [Objective; 8] = [
            ("parabola", |x| (x - 0.3) * (x - 0.3), true),
            ("shifted", |x| 2.0 + 5.0 * (x - 0.123_456_7).powi(2), true),
            ("asymmetric", |x| (x - 0.41).exp() - (x - 0.41), true),
            ("quartic", |x| (x - 0.62).powi(4), false),
            ("kink", |x| (x - 0.271_828).abs(), false),
            ("edge", |x| x, false),
            (
                "rough",
                |x| (x * 91.0).sin() + 0.1 * (x - 0.6).powi(2),
                false,
            ),
            (
                "infinite",
                |x| if x > 0.5 { f64::INFINITY } else { -x },
                false,
            ),
        ];
        for (name, f, smooth) in objectives {
            for (lo, hi, width) in [(0.0, 1.0, 1e-7), (-2.0, 2.0, 1e-9), (0.2, 0.5, 1e-6)] {
                let batches = std::cell::Cell::new(0);
                let many = |xs: &[f64]| -> Vec<f64> {
                    assert!(xs.len() <= 8, "{name}: a batch of {}", xs.len());
                    batches.set(batches.get() + 1);
                    xs.iter().map(|&x| f(x)).collect()
                };
                let (x, fx, ev) = zoom_min_batched(&many, lo, hi, 8, 8, width);
                assert_eq!(fx.to_bits(), f(x).to_bits(), "{name}");
                assert!(ev >= 8 && (lo..=hi).contains(&x), "{name}: {x} {ev}");
                if name == "rough" || name == "infinite" {
                    // A local minimum of what it saw: no better value within `width` of it.
                    for d in [-width, width] {
                        let y = (x + d).clamp(lo, hi);
                        assert!(fx <= f(y) + 1e-9, "{name}: {x} {fx} vs {y} {}", f(y));
                    }
                    continue;
                }
                let (g, fg, _) = golden_min(&f, lo, hi, 8, 40);
                // (Rounding flattens a smooth minimum over about √ε of the interval.)
                assert!(
                    (x - g).abs() <= 2.0 * width + 1e-7 * (hi - lo),
                    "{name} [{lo}, {hi}]: {x} vs {g}"
                );
                // No larger than the objective anywhere within twice its width of golden
                // section's point.
                let near = [g - 2.0 * width, g + 2.0 * width].map(|y| f(y.clamp(lo, hi)));
                assert!(fx <= fg.max(near[0]).max(near[1]), "{name}: {fx} vs {fg}");
                if smooth {
                    assert!(
                        batches.get() <= 9,
                        "{name} [{lo}, {hi}]: {} batches",
                        batches.get()
                    );
                }
            }
        }
    }

    #[test]
    fn the_parabola_vertex_is_the_minimum_of_a_parabola() {
        // Reference: 3(x − 0.7)² + 1 has its minimum at 0.7.
        let f = |x: f64| 3.0 * (x - 0.7) * (x - 0.7) + 1.0;
        let v = parabola_vertex((0.1, f(0.1)), (0.5, f(0.5)), (1.3, f(1.3))).unwrap();
        assert!((v - 0.7).abs() < 1e-12, "{v}");
        // Collinear, or a maximum: no vertex.
        assert_eq!(parabola_vertex((0.0, 0.0), (1.0, 1.0), (2.0, 2.0)), None);
        assert_eq!(parabola_vertex((0.0, 0.0), (1.0, 1.0), (2.0, 0.0)), None);
    }
}
