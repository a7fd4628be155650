//! The allocation-free handoff table: per controller and horizon, the coefficients of every
//! sample's start-value bounds, and the entry points of the handoff computation.

use super::spec::check_horizon;
use super::{Handoff, HandoffSolution, SettleError, Window};
use crate::control::Controller;

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ZeroGain {
    pub(super) k: usize,
    pub(super) ce: f64,
    pub(super) cv: f64,
    pub(super) cu: f64,
}

/// What every sample's bounds are linear in: the handoff state and the window half-width.
#[derive(Debug, Clone, Copy)]
pub(super) struct Point {
    pub(super) e0: f64,
    pub(super) v0: f64,
    pub(super) du: f64,
    pub(super) delta: f64,
}

impl Point {
    /// The point of handoff `h` in `window`.
    #[inline(always)]
    pub(super) fn of(h: &super::Handoff, window: &super::Window) -> Self {
        Self {
            e0: h.e0_um,
            v0: h.v0_um_s,
            du: h.u_prev_counts - h.bias_counts,
            delta: window.half_width_um,
        }
    }

    /// U_k and L_k (eq. 14) from one sample's coefficients.
    #[inline(always)]
    pub(super) fn bounds(&self, pe: f64, pv: f64, pu: f64, w: f64) -> (f64, f64) {
        let mid = pe * self.e0 + pv * self.v0 + pu * self.du;
        let half = w * self.delta;
        (mid + half, mid - half)
    }
}

/// A sample k with a_k = 0 and its coefficients `[ce, cv, cu]` ([`HandoffTable::export_rows`]).
pub(crate) type ZeroGainRow = (usize, [f64; 3]);

/// Per-controller, per-horizon coefficients of the handoff bounds (see the module docs), laid
/// out as four plain arrays (one per coefficient) so the bound loops vectorise.
#[derive(Debug, Clone, PartialEq)]
pub struct HandoffTable {
    /// −ce_k/a_k (0 where a_k = 0).
    pub(super) pe: Box<[f64]>,
    /// −cv_k/a_k (0 where a_k = 0).
    pub(super) pv: Box<[f64]>,
    /// −cu_k/a_k (0 where a_k = 0).
    pub(super) pu: Box<[f64]>,
    /// 1/|a_k| (+∞ where a_k = 0: unconstrained unless `zero` rules the sample out).
    pub(super) w: Box<[f64]>,
    /// The samples with a_k = 0, latest first.
    pub(super) zero: Vec<ZeroGain>,
    pub(super) ts_s: f64,
    pub(super) dz_dbias: f64,
    /// Largest |pe|, |pv|, |pu| and largest finite w: with them a handoff's bounds are known
    /// to be NaN-free before they are computed.
    pub(super) coef_max: f64,
    pub(super) w_max: f64,
    /// The CPU has AVX2: the same arithmetic runs four samples per instruction.
    pub(super) avx2: bool,
}

/// |a_k| below this fraction of max |a_k| counts as a_k = 0.
const ZERO_GAIN_REL: f64 = 1e-13;

impl HandoffTable {
    /// Precomputes a_k, c_k's coefficients for k = 0 .. horizon − 1 from C·Acl^k (the
    /// measured-error row). `horizon` must be ≥ 1.
    pub fn new(controller: &Controller, horizon: usize) -> Result<Self, SettleError> {
        check_horizon(horizon)?;
        let n = controller.order();
        let acl = controller.closed_loop();
        let mut row = controller.c().transpose();
        let mut raw = Vec::with_capacity(horizon);
        for _ in 0..horizon {
            raw.push((row[0], row[1], row[2], row[n - 1]));
            row = &row * acl;
        }
        let amax = raw.iter().fold(0.0f64, |m, r| m.max(r.0.abs()));
        let (mut pe, mut pv, mut pu, mut w) = (
            Vec::with_capacity(horizon),
            Vec::with_capacity(horizon),
            Vec::with_capacity(horizon),
            Vec::with_capacity(horizon),
        );
        let mut zero = Vec::new();
        for (k, &(a, ce, cv, cu)) in raw.iter().enumerate() {
            if a.abs() <= ZERO_GAIN_REL * amax || a.abs() == 0.0 {
                zero.push(ZeroGain { k, ce, cv, cu });
                pe.push(0.0);
                pv.push(0.0);
                pu.push(0.0);
                w.push(f64::INFINITY);
            } else {
                pe.push(-ce / a);
                pv.push(-cv / a);
                pu.push(-cu / a);
                w.push(1.0 / a.abs());
            }
        }
        zero.reverse();
        let abs_max = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let coef_max = abs_max(&pe).max(abs_max(&pv)).max(abs_max(&pu));
        let w_max = w
            .iter()
            .filter(|x| x.is_finite())
            .fold(0.0f64, |m, &x| m.max(x));
        Ok(Self {
            pe: pe.into(),
            pv: pv.into(),
            pu: pu.into(),
            w: w.into(),
            zero,
            ts_s: controller.ts_s(),
            dz_dbias: controller.dz_dbias(),
            coef_max,
            w_max,
            avx2: has_avx2(),
        })
    }

    /// Horizon N in samples.
    pub fn horizon(&self) -> usize {
        self.w.len()
    }
    /// Sample period Ts in s.
    pub fn ts_s(&self) -> f64 {
        self.ts_s
    }
    /// ∂z/∂d of the controller (µm·samples per count).
    pub fn dz_dbias(&self) -> f64 {
        self.dz_dbias
    }

    /// The table as the C export writes it: per sample k the bounds' coefficients
    /// `[−ce/a, −cv/a, −cu/a, 1/|a|]` (`[0, 0, 0, ∞]` where a_k = 0), and the samples with
    /// a_k = 0 as `(k, [ce, cv, cu])` in ascending k.
    pub fn export_rows(&self) -> (Vec<[f64; 4]>, Vec<ZeroGainRow>) {
        let rows = (0..self.w.len())
            .map(|k| [self.pe[k], self.pv[k], self.pu[k], self.w[k]])
            .collect();
        let mut zeros: Vec<ZeroGainRow> = self
            .zero
            .iter()
            .map(|z| (z.k, [z.ce, z.cv, z.cu]))
            .collect();
        zeros.sort_by_key(|z| z.0);
        (rows, zeros)
    }

    /// c_k of a sample with a_k = 0 rules out every settle index ≤ k when |c_k| > δ.
    #[inline]
    pub(super) fn rules_out(z: &ZeroGain, p: Point) -> bool {
        let c = z.ce * p.e0 + z.cv * p.v0 + z.cu * p.du;
        c.is_nan() || c.abs() > p.delta
    }

    /// One plus the largest k with a_k = 0 and |c_k| > δ (0 if none): no settle index below it.
    #[inline]
    pub(super) fn floor(&self, p: Point) -> usize {
        self.zero
            .iter()
            .find(|z| Self::rules_out(z, p))
            .map_or(0, |z| z.k + 1)
    }

    /// U_k, L_k (eq. 14) of samples `lo .. lo + u.len()` into `u` and `l`, zero-gain samples
    /// unconstrained (`floor` and `bounds_into` handle the ones that rule settling out).
    #[inline(always)]
    pub(super) fn fill(&self, lo: usize, p: Point, u: &mut [f64], l: &mut [f64]) {
        let m = u.len();
        let l = &mut l[..m];
        let (pe, pv) = (&self.pe[lo..lo + m], &self.pv[lo..lo + m]);
        let (pu, w) = (&self.pu[lo..lo + m], &self.w[lo..lo + m]);
        for j in 0..m {
            (u[j], l[j]) = p.bounds(pe[j], pv[j], pu[j], w[j]);
        }
    }

    /// The handoff computation, allocation-free: a backward pass over the bounds of eq. 14
    /// with the running min/max of eq. 15, stopping as soon as the interval is empty. Returns
    /// k* with the optimal interval (eq. 16), the robust interval for a bias uncertainty
    /// `delta_b` (counts, ≥ 0; its absolute value is used) and zero feedforward's worst case.
    /// A non-finite handoff state settles nothing (all `None`).
    ///
    /// The three conditions (zero feedforward's worst case inside, width ≥ 2s, width ≥ 0) are
    /// nested and each holds on a suffix of settle indices (U* grows and L* falls with k), so
    /// one scan per condition continues where the previous one stopped, each with its
    /// condition fixed (no test of which condition is current in the loop). The scan runs over
    /// blocks of 8 samples: a block's bounds are computed four lanes at a time and reduced as a
    /// tree; only the block where the condition stops holding is walked sample by sample. On a
    /// CPU with AVX2 the same code runs compiled for it (the same operations in the same
    /// order: identical results).
    pub fn solve(&self, h: &Handoff, window: &Window, delta_b: f64) -> HandoffSolution {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is true only when `new` found AVX2 on this CPU.
            return unsafe { self.solve_avx2(h, window, delta_b) };
        }
        self.solve_portable(h, window, delta_b)
    }
}

/// Whether this CPU runs the AVX2 copies of the handoff loops.
fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

#[cfg(test)]
mod tests {
    //! The handoff fast paths ([`HandoffTable::solve`], [`HandoffTable::bounds_into`]) against
    //! the slow obvious implementation of the same definitions, over many random handoffs.
    use super::*;
    use crate::control::settle::spec::PRESETS;
    use crate::control::settle::{Bounds, Interval, SettleSpec};
    use crate::numeric::rng::SimRng;

    /// The reference: every sample's bounds U_k, L_k (eq. 14) into vectors, a zero-gain sample
    /// with |c_k| > δ ruling every k ≤ it out (U = −∞, L = +∞), the running bounds U*, L*
    /// (eq. 15) sample by sample from the end with `f64::min`/`max`, and each answer as the
    /// first k ≤ N − M where its condition holds. No floor, no blocks, no early exit.
    fn reference(
        t: &HandoffTable,
        h: &Handoff,
        window: &Window,
        delta_b: f64,
    ) -> ([Vec<f64>; 4], HandoffSolution) {
        let n = t.horizon();
        let p = Point {
            e0: h.e0_um,
            v0: h.v0_um_s,
            du: h.u_prev_counts - h.bias_counts,
            delta: window.half_width_um(),
        };
        let (mut upper, mut lower) = (vec![0.0; n], vec![0.0; n]);
        for k in 0..n {
            (upper[k], lower[k]) = p.bounds(t.pe[k], t.pv[k], t.pu[k], t.w[k]);
        }
        for z in &t.zero {
            let c = z.ce * p.e0 + z.cv * p.v0 + z.cu * p.du;
            if c.is_nan() || c.abs() > p.delta {
                upper[z.k] = f64::NEG_INFINITY;
                lower[z.k] = f64::INFINITY;
            }
        }
        let (mut upper_min, mut lower_max) = (vec![0.0; n], vec![0.0; n]);
        let (mut umin, mut lmax) = (f64::INFINITY, f64::NEG_INFINITY);
        for k in (0..n).rev() {
            umin = umin.min(upper[k]);
            lmax = lmax.max(lower[k]);
            upper_min[k] = umin;
            lower_max[k] = lmax;
        }
        let shift = (t.dz_dbias * delta_b).abs();
        let finite = p.e0.is_finite() && p.v0.is_finite() && p.du.is_finite();
        let first = |cond: &dyn Fn(f64, f64) -> bool| {
            if !finite || window.hold() > n {
                return None;
            }
            (0..=n - window.hold())
                .find(|&k| cond(upper_min[k], lower_max[k]))
                .map(|k| Interval {
                    k,
                    lo: lower_max[k],
                    hi: upper_min[k],
                })
        };
        let sol = HandoffSolution {
            optimal: first(&|u, l| u - l >= 0.0),
            robust: first(&|u, l| u - l >= 2.0 * shift),
            zero_ff_worst: first(&|u, l| l <= -shift && u >= shift).map(|i| i.k),
            shift,
        };
        ([upper, lower, upper_min, lower_max], sol)
    }

    /// Equal within 1e-12 relative; infinities and NaN must match exactly.
    fn same(a: f64, b: f64) -> bool {
        if a.is_finite() && b.is_finite() {
            (a - b).abs() <= 1e-12 * a.abs().max(b.abs())
        } else {
            a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
        }
    }

    fn same_interval(a: Option<Interval>, b: Option<Interval>) -> bool {
        match (a, b) {
            (None, None) => true,
            (Some(a), Some(b)) => a.k == b.k && same(a.lo, b.lo) && same(a.hi, b.hi),
            _ => false,
        }
    }

    /// A table with random coefficients and random zero-gain samples (a_k = 0), which a
    /// designed controller has only at k = 0, so the floor logic is exercised anywhere.
    fn synthetic(rng: &mut SimRng, n: usize) -> HandoffTable {
        let mut t = HandoffTable {
            pe: vec![0.0; n].into(),
            pv: vec![0.0; n].into(),
            pu: vec![0.0; n].into(),
            w: vec![f64::INFINITY; n].into(),
            zero: Vec::new(),
            ts_s: 1e-4,
            dz_dbias: rng.range(-2.0, 2.0),
            coef_max: 0.0,
            w_max: 0.0,
            avx2: has_avx2(),
        };
        for k in 0..n {
            if rng.uniform() < 0.05 {
                t.zero.push(ZeroGain {
                    k,
                    ce: rng.range(-1.0, 1.0),
                    cv: rng.range(-1e-3, 1e-3),
                    cu: rng.range(-1.0, 1.0),
                });
            } else {
                // Bounds that tighten with k, as a settling loop's do, plus noise.
                let a = rng.range(0.2, 2.0) * (1.0 + k as f64 / 8.0);
                t.pe[k] = rng.range(-3.0, 3.0) + 50.0 / (1.0 + k as f64);
                t.pv[k] = rng.range(-1e-3, 1e-3);
                t.pu[k] = rng.range(-2.0, 2.0);
                t.w[k] = 1.0 / a;
            }
        }
        t.zero.reverse();
        t.coef_max = [&t.pe, &t.pv, &t.pu]
            .iter()
            .flat_map(|v| v.iter())
            .fold(0.0f64, |m, x| m.max(x.abs()));
        t.w_max =
            t.w.iter()
                .filter(|x| x.is_finite())
                .fold(0.0f64, |m, &x| m.max(x));
        t
    }

    fn random_handoff(rng: &mut SimRng, scale: f64) -> Handoff {
        let mut h = Handoff {
            e0_um: scale * rng.range(-2.0, 2.0),
            v0_um_s: scale * rng.range(-2000.0, 2000.0),
            u_prev_counts: rng.range(-20.0, 20.0),
            bias_counts: rng.range(-20.0, 20.0),
        };
        match rng.below(10) {
            0 => h.u_prev_counts = h.bias_counts, // a step from rest
            1 => h.e0_um = 0.0,
            // Bounds that overflow (±∞, NaN): the exact per-sample path.
            2 if rng.uniform() < 0.2 => h.e0_um = 1e306 * h.e0_um.signum(),
            _ => {}
        }
        h
    }

    /// Checks one handoff: every curve of `bounds_into` and every answer of `solve` equal the
    /// reference's; returns the reference solution.
    fn check(
        t: &HandoffTable,
        h: &Handoff,
        window: &Window,
        db: f64,
        what: &str,
    ) -> HandoffSolution {
        let ([u, l, um, lm], want) = reference(t, h, window, db);
        let mut buf = Bounds::new(t.horizon());
        t.bounds_into(h, window, &mut buf).unwrap();
        for (name, got, want) in [
            ("upper", buf.upper(), &u),
            ("lower", buf.lower(), &l),
            ("upper_min", buf.upper_min(), &um),
            ("lower_max", buf.lower_max(), &lm),
        ] {
            for k in 0..want.len() {
                assert!(
                    same(got[k], want[k]),
                    "{what}: {name}[{k}] {} vs {}",
                    got[k],
                    want[k]
                );
            }
        }
        // Both compiled copies (AVX2 where the CPU has it, and the portable one) agree.
        let portable = HandoffTable {
            avx2: false,
            ..t.clone()
        };
        let mut buf2 = Bounds::new(t.horizon());
        portable.bounds_into(h, window, &mut buf2).unwrap();
        assert_eq!(
            format!("{buf:?}"),
            format!("{buf2:?}"),
            "{what}: portable bounds"
        );
        let got = t.solve(h, window, db);
        assert_eq!(
            format!("{got:?}"),
            format!("{:?}", portable.solve(h, window, db)),
            "{what}: portable solve"
        );
        assert!(
            same_interval(got.optimal, want.optimal),
            "{what}: optimal {got:?} vs {want:?}"
        );
        assert!(
            same_interval(got.robust, want.robust),
            "{what}: robust {got:?} vs {want:?}"
        );
        assert_eq!(got.zero_ff_worst, want.zero_ff_worst, "{what}: zero ff");
        assert!(same(got.shift, want.shift));
        let finite = h.e0_um.is_finite() && h.v0_um_s.is_finite() && h.u_prev_counts.is_finite();
        if finite && window.hold() <= t.horizon() {
            assert_eq!(
                buf.optimal().map(|i| i.k),
                want.optimal.map(|i| i.k),
                "{what}"
            );
        }
        want
    }

    /// Reference: [`reference`] (the definitions written out naively). 1500 random handoffs on
    /// the two presets' controllers at random horizons 1–300 (multiples of the block and not),
    /// random windows, holds and Δb; identical results within 1e-12 relative, the same k.
    #[test]
    fn fast_handoff_equals_reference_on_designed_controllers() {
        let mut rng = SimRng::new(16);
        for preset in PRESETS {
            let cfg = SettleSpec::preset(preset).unwrap().check().unwrap();
            let ctl = Controller::design(&cfg.plant, &cfg.weights).unwrap();
            let scale = cfg.scenario.step_um;
            let (mut settled, mut unsettled) = (0, 0);
            for case in 0..750 {
                let n = match case % 3 {
                    0 => 8 * (1 + rng.below(32) as usize),
                    _ => 1 + rng.below(300) as usize,
                };
                let t = HandoffTable::new(&ctl, n).unwrap();
                let hold = 1 + rng.below(4.min(n as u64) + 1) as usize;
                let window = Window::new(scale * rng.range(0.005, 0.3), hold).unwrap();
                let h = random_handoff(&mut rng, scale);
                let db = if case % 5 == 0 {
                    0.0
                } else {
                    rng.range(0.0, 30.0)
                };
                let sol = check(&t, &h, &window, db, &format!("{preset} case {case}"));
                if sol.optimal.is_some() {
                    settled += 1;
                } else {
                    unsettled += 1;
                }
            }
            assert!(
                settled > 100 && unsettled > 10,
                "{preset}: {settled} / {unsettled}"
            );
        }
    }

    /// Reference: [`reference`]. 1500 random handoffs on random tables with zero-gain samples
    /// anywhere (the floor), plus non-finite handoff states; identical results.
    #[test]
    fn fast_handoff_equals_reference_on_random_tables() {
        let mut rng = SimRng::new(61);
        let (mut floored, mut found) = (0, 0);
        for case in 0..1500 {
            let n = 1 + rng.below(200) as usize;
            let t = synthetic(&mut rng, n);
            let hold = 1 + rng.below(3) as usize;
            let window = Window::new(rng.range(0.05, 3.0), hold).unwrap();
            let mut h = random_handoff(&mut rng, 1.0);
            if case % 100 == 0 {
                h.v0_um_s = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][case / 100 % 3];
            }
            let db = rng.range(0.0, 5.0);
            let sol = check(&t, &h, &window, db, &format!("random case {case}"));
            let p = Point {
                e0: h.e0_um,
                v0: h.v0_um_s,
                du: h.u_prev_counts - h.bias_counts,
                delta: window.half_width_um(),
            };
            if let Some(o) = sol.optimal {
                found += 1;
                floored += usize::from(o.k > 0 && o.k == t.floor(p));
            }
        }
        assert!(
            found > 300 && floored > 10,
            "{found} settled, {floored} at the floor"
        );
    }
}
