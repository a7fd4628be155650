//! How the simulated drive *measures* its bias, as the paper does: the average of the control
//! effort of a closed-loop track-following servo over one spindle revolution.
//!
//! ## The loop (the reference, [`Servo::measure_slow`])
//! Rigid-body plant at the servo rate `T = 1/sample_rate_hz`, position error `e` in tracks,
//! velocity `v` in tracks/s, acceleration `G·(u − b)` with `u` the control in counts and `b` the
//! bias force in counts (so at rest `u = b`: the bias is the current that holds the head). The
//! position-error signal is `e_m = e + w`, `w` = repeatable runout + sensor noise. A PID with
//! integrator state `z` (counts):
//!
//! ```text
//! u_k     = z_k − Kp·e_m,k − Kd·(e_m,k − e_m,k−1)/T
//! z_k+1   = z_k − Ki·T·e_m,k
//! e_k+1   = e_k + T·v_k + T²/2·G·(u_k − b),   v_k+1 = v_k + T·G·(u_k − b)
//! ```
//!
//! with `G·Kd = 3ω`, `G·Kp = 3ω²`, `G·Ki = ω³` (a triple pole at `−ω`, `ω = 2π·bandwidth_hz`).
//! `G` only scales the gains; we take `G·Kp`-normalised units with `Kp = 100` counts/track.
//! A measurement starts at handoff with the previous track's integrator `z0`, a position error
//! `e0` and zero velocity, runs `settle_samples`, then averages `u` over one revolution
//! (`floor(60·fs/rpm)` samples, 111 at 10 kHz and 5400 rpm). What the average leaves behind —
//! the integrator still converging from the previous track's bias, runout not cancelled by a
//! non-integer number of samples per revolution, sensor noise — stays in the measured value.
//!
//! ## The fast path ([`Servo::measure_fast`])
//! The loop is linear and time-invariant, so the average and the final integrator are
//! `c·[e0, v0, z0, b] + Σ_k g_k·w_k`. The coefficients come from running the reference loop on
//! unit inputs once; runout is a sum of sinusoids, so `Σ g_k·w_k` is a few complex
//! multiplications; the noise part is Gaussian with the covariance `σ²·[Σg², Σgf; Σgf, Σf²]`
//! and is drawn exactly from that law (two normals instead of one per sample). With noise off
//! the fast path equals the loop to rounding; with noise on it has the same distribution.

use super::drive::{Harmonic, ServoParams};
use crate::numeric::rng::SimRng;
use std::f64::consts::TAU;

/// Normalised proportional gain, counts per track (fixes the plant gain `G = 3ω²/Kp`).
const KP: f64 = 100.0;

/// The servo's state at handoff.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Handoff {
    /// Position error at handoff, tracks.
    pub e0: f64,
    /// Velocity at handoff, tracks/s.
    pub v0: f64,
    /// Integrator value carried over from the previous track, counts.
    pub z0: f64,
}

impl Handoff {
    /// A handoff with no position error or velocity and integrator `z0` counts.
    pub(crate) fn at_rest(z0: f64) -> Handoff {
        Handoff {
            e0: 0.0,
            v0: 0.0,
            z0,
        }
    }
}

/// The result of one measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Measured {
    /// The one-revolution average of the control effort: the measured bias, counts.
    pub average: f64,
    /// The integrator at the end of the measurement (handed to the next track), counts.
    pub z_end: f64,
}

/// Coefficients of a linear functional of the loop (average or final integrator).
#[derive(Debug, Clone, Copy, Default)]
struct Linear {
    e0: f64,
    v0: f64,
    z0: f64,
    b: f64,
}

impl Linear {
    fn apply(&self, h: &Handoff, b: f64) -> f64 {
        self.e0 * h.e0 + self.v0 * h.v0 + self.z0 * h.z0 + self.b * b
    }
}

/// The measuring servo with its precomputed superposition coefficients.
#[derive(Debug, Clone)]
pub(crate) struct Servo {
    t: f64,
    kp: f64,
    kd: f64,
    ki: f64,
    g: f64,
    settle: usize,
    window: usize,
    /// Spindle angle advance per sample, rad.
    dtheta: f64,
    avg: Linear,
    zend: Linear,
    /// Per harmonic: Σ g_k e^{i h Δ k} and Σ f_k e^{i h Δ k} as (re, im) pairs.
    runout_avg: Vec<(f64, f64)>,
    runout_zend: Vec<(f64, f64)>,
    harmonics: Vec<Harmonic>,
    /// Σ g², Σ f², Σ g·f over the samples (noise covariance per unit variance).
    sum_gg: f64,
    sum_ff: f64,
    sum_gf: f64,
}

impl Servo {
    /// Builds the loop for `params` with the runout `harmonics` (empty = no runout).
    pub(crate) fn new(params: &ServoParams, harmonics: &[Harmonic]) -> Servo {
        let t = 1.0 / params.sample_rate_hz;
        let w = TAU * params.bandwidth_hz;
        let g = 3.0 * w * w / KP;
        let mut s = Servo {
            t,
            kp: KP,
            kd: 3.0 * w / g,
            ki: w * w * w / g,
            g,
            settle: params.settle_samples as usize,
            window: params.window_samples(),
            dtheta: TAU * params.spindle_rpm / 60.0 * t,
            avg: Linear::default(),
            zend: Linear::default(),
            runout_avg: Vec::new(),
            runout_zend: Vec::new(),
            harmonics: harmonics.to_vec(),
            sum_gg: 0.0,
            sum_ff: 0.0,
            sum_gf: 0.0,
        };
        s.precompute();
        s
    }

    /// Samples from handoff to the end of the average.
    pub(crate) fn samples(&self) -> usize {
        self.settle + self.window
    }

    /// Duration of one measurement (settle + one revolution), s.
    pub(crate) fn duration_s(&self) -> f64 {
        self.samples() as f64 * self.t
    }

    /// Spindle angle (rad) at the first servo sample of a measurement that ends at `time_s`.
    pub(crate) fn start_angle(&self, time_s: f64, spindle_rpm: f64) -> f64 {
        let revs = spindle_rpm / 60.0 * (time_s - self.duration_s());
        TAU * (revs - revs.floor())
    }

    /// Runs the loop sample by sample with disturbance `w(k)` (tracks); the reference.
    fn run(&self, h: &Handoff, b: f64, mut w: impl FnMut(usize) -> f64) -> Measured {
        let (mut e, mut v, mut z) = (h.e0, h.v0, h.z0);
        let mut em_prev = h.e0;
        let mut sum = 0.0;
        for k in 0..self.samples() {
            let em = e + w(k);
            let u = z - self.kp * em - self.kd * (em - em_prev) / self.t;
            if k >= self.settle {
                sum += u;
            }
            z -= self.ki * self.t * em;
            let a = self.g * (u - b);
            e += self.t * v + 0.5 * self.t * self.t * a;
            v += self.t * a;
            em_prev = em;
        }
        Measured {
            average: sum / self.window as f64,
            z_end: z,
        }
    }

    /// The runout at sample `k` of a measurement whose first sample is at spindle angle `theta0`.
    fn runout_at(&self, theta0: f64, k: usize) -> f64 {
        let theta = theta0 + self.dtheta * k as f64;
        self.harmonics
            .iter()
            .map(|hm| {
                hm.amplitude * (f64::from(hm.order) * theta + hm.phase_deg.to_radians()).cos()
            })
            .sum()
    }

    /// The reference measurement: the loop sample by sample, with runout and `pes_noise`
    /// (tracks, std) drawn per sample from `rng`.
    pub(crate) fn measure_slow(
        &self,
        h: &Handoff,
        b: f64,
        theta0: f64,
        pes_noise: f64,
        rng: &mut SimRng,
    ) -> Measured {
        self.run(h, b, |k| {
            let n = if pes_noise > 0.0 {
                pes_noise * rng.normal()
            } else {
                0.0
            };
            self.runout_at(theta0, k) + n
        })
    }

    /// The fast measurement by superposition (same law as [`Servo::measure_slow`]).
    pub(crate) fn measure_fast(
        &self,
        h: &Handoff,
        b: f64,
        theta0: f64,
        pes_noise: f64,
        rng: &mut SimRng,
    ) -> Measured {
        let (ra, rz) = self.runout_parts(theta0);
        let mut average = self.avg.apply(h, b) + ra;
        let mut z_end = self.zend.apply(h, b) + rz;
        if pes_noise > 0.0 {
            let (n1, n2) = (rng.normal(), rng.normal());
            let sa = self.sum_gg.sqrt();
            let sz = self.sum_ff.sqrt();
            let rho = if sa > 0.0 && sz > 0.0 {
                (self.sum_gf / (sa * sz)).clamp(-1.0, 1.0)
            } else {
                0.0
            };
            average += pes_noise * sa * n1;
            z_end += pes_noise * sz * (rho * n1 + (1.0 - rho * rho).sqrt() * n2);
        }
        Measured { average, z_end }
    }

    /// What the runout leaves in the average and in the final integrator, counts.
    pub(crate) fn runout_parts(&self, theta0: f64) -> (f64, f64) {
        let (mut a, mut z) = (0.0, 0.0);
        for (i, hm) in self.harmonics.iter().enumerate() {
            let psi = f64::from(hm.order) * theta0 + hm.phase_deg.to_radians();
            let (s, c) = psi.sin_cos();
            let (gr, gi) = self.runout_avg[i];
            let (fr, fi) = self.runout_zend[i];
            a += hm.amplitude * (c * gr - s * gi);
            z += hm.amplitude * (c * fr - s * fi);
        }
        (a, z)
    }

    /// The average's sensitivity to a constant bias `b` (1 when the integrator has converged).
    #[cfg(test)]
    pub(crate) fn bias_gain(&self) -> f64 {
        self.avg.b
    }

    /// The average's sensitivity to the handoff integrator `z0` (what settling leaves behind).
    #[cfg(test)]
    pub(crate) fn z0_gain(&self) -> f64 {
        self.avg.z0
    }

    fn precompute(&mut self) {
        let zero = Handoff::at_rest(0.0);
        let unit = |f: fn(&mut Handoff)| {
            let mut h = zero;
            f(&mut h);
            h
        };
        let m_e = self.run(&unit(|h| h.e0 = 1.0), 0.0, |_| 0.0);
        let m_v = self.run(&unit(|h| h.v0 = 1.0), 0.0, |_| 0.0);
        let m_z = self.run(&unit(|h| h.z0 = 1.0), 0.0, |_| 0.0);
        let m_b = self.run(&zero, 1.0, |_| 0.0);
        self.avg = Linear {
            e0: m_e.average,
            v0: m_v.average,
            z0: m_z.average,
            b: m_b.average,
        };
        self.zend = Linear {
            e0: m_e.z_end,
            v0: m_v.z_end,
            z0: m_z.z_end,
            b: m_b.z_end,
        };
        // Impulse response of u and z to a unit disturbance at sample 0 (time-invariant, so a
        // disturbance at sample k gives the same response shifted by k).
        let n = self.samples();
        let (mut hu, mut hz) = (vec![0.0; n], vec![0.0; n + 1]);
        {
            let (mut e, mut v, mut z, mut em_prev) = (0.0, 0.0, 0.0, 0.0);
            for k in 0..n {
                let em = e + if k == 0 { 1.0 } else { 0.0 };
                let u = z - self.kp * em - self.kd * (em - em_prev) / self.t;
                hu[k] = u;
                z -= self.ki * self.t * em;
                hz[k + 1] = z;
                let a = self.g * u;
                e += self.t * v + 0.5 * self.t * self.t * a;
                v += self.t * a;
                em_prev = em;
            }
        }
        // g_k = (1/N) Σ_{j = max(k, S)}^{n−1} hu[j − k];  f_k = hz[n − k].
        let mut prefix = vec![0.0; n + 1];
        for j in 0..n {
            prefix[j + 1] = prefix[j] + hu[j];
        }
        let g: Vec<f64> = (0..n)
            .map(|k| {
                let lo = self.settle.max(k) - k;
                (prefix[n - k] - prefix[lo]) / self.window as f64
            })
            .collect();
        let f: Vec<f64> = (0..n).map(|k| hz[n - k]).collect();
        self.sum_gg = g.iter().map(|x| x * x).sum();
        self.sum_ff = f.iter().map(|x| x * x).sum();
        self.sum_gf = g.iter().zip(&f).map(|(a, b)| a * b).sum();
        let phasor_sum = |coef: &[f64], order: u32| {
            coef.iter()
                .enumerate()
                .fold((0.0, 0.0), |(re, im), (k, c)| {
                    let (s, co) = (f64::from(order) * self.dtheta * k as f64).sin_cos();
                    (re + c * co, im + c * s)
                })
        };
        self.runout_avg = self
            .harmonics
            .iter()
            .map(|h| phasor_sum(&g, h.order))
            .collect();
        self.runout_zend = self
            .harmonics
            .iter()
            .map(|h| phasor_sum(&f, h.order))
            .collect();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::Drive;

    fn servo() -> (Servo, ServoParams) {
        let d = Drive::paper1997();
        (Servo::new(&d.servo, &d.runout.harmonics), d.servo)
    }

    #[test]
    fn window_is_one_revolution() {
        // Reference: 10 kHz · 60 / 5400 rpm = 111.1 samples → 111.
        let (s, p) = servo();
        assert_eq!(p.window_samples(), 111);
        assert_eq!(s.samples(), 111 + p.settle_samples as usize);
    }

    #[test]
    fn converged_loop_measures_the_bias_exactly() {
        // Reference: at equilibrium (z0 = b, e0 = v0 = 0, no disturbance) the loop stays put and
        // u = b at every sample, so the average is b.
        let (s, _) = servo();
        let h = Handoff::at_rest(42.0);
        let m = s.run(&h, 42.0, |_| 0.0);
        assert!((m.average - 42.0).abs() < 1e-9, "{m:?}");
        assert!((m.z_end - 42.0).abs() < 1e-9);
        // Linearity: avg.b + avg.z0 = 1 (a constant shift of both is measured one-for-one).
        assert!((s.bias_gain() + s.z0_gain() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn loop_is_stable_and_settles_within_the_settle_period() {
        // Reference: a triple pole at −2π·300 rad/s has a 3 ms settling scale; the impulse
        // response of the discretised loop must decay (stability) and the handoff error must
        // have mostly left the average: a 50-count bias step leaves < 10 % in the average.
        let (s, _) = servo();
        let h = Handoff::at_rest(0.0);
        let m = s.run(&h, 50.0, |_| 0.0);
        let left = 50.0 - m.average;
        assert!(left > 0.0 && left < 5.0, "left behind {left}");
        // Long run: the integrator converges to b.
        let long = ServoParams {
            settle_samples: 3000,
            ..Drive::paper1997().servo
        };
        let sl = Servo::new(&long, &[]);
        let m = sl.run(&h, 50.0, |_| 0.0);
        assert!((m.average - 50.0).abs() < 1e-6, "{m:?}");
    }

    #[test]
    fn runout_mostly_cancels_over_one_revolution() {
        // Reference: a pure runout of 0.1 track at once per revolution would give a control
        // swing of ~Kp·0.1 = 10 counts; averaged over one revolution what is left is far smaller.
        let (s, _) = servo();
        let h = Handoff::at_rest(0.0);
        let worst = (0..36)
            .map(|i| s.runout_parts(f64::from(i) * 10f64.to_radians()).0.abs())
            .fold(0.0, f64::max);
        let swing = (0..s.samples())
            .map(|k| s.runout_at(0.0, k).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.2 * KP * swing, "left {worst}, swing {swing}");
        // And the slow loop agrees with the decomposition.
        let m = s.run(&h, 0.0, |k| s.runout_at(1.0, k));
        assert!((m.average - s.runout_parts(1.0).0).abs() < 1e-9);
    }

    #[test]
    fn fast_path_equals_slow_loop_without_noise() {
        // Reference: the slow sample-by-sample loop. Random handoffs, biases and spindle angles.
        let (s, _) = servo();
        let mut r = SimRng::new(11);
        let mut dummy = SimRng::new(0);
        for _ in 0..200 {
            let h = Handoff {
                e0: r.range(-0.3, 0.3),
                v0: r.range(-50.0, 50.0),
                z0: r.range(-200.0, 200.0),
            };
            let b = r.range(-200.0, 200.0);
            let th = r.range(0.0, TAU);
            let slow = s.measure_slow(&h, b, th, 0.0, &mut dummy);
            let fast = s.measure_fast(&h, b, th, 0.0, &mut dummy);
            assert!(
                (slow.average - fast.average).abs() < 1e-8,
                "{slow:?} {fast:?}"
            );
            assert!((slow.z_end - fast.z_end).abs() < 1e-8, "{slow:?} {fast:?}");
        }
    }

    #[test]
    fn fast_path_noise_has_the_slow_loops_law() {
        // Reference: the slow loop with per-sample noise; compare the std of the average and of
        // the final integrator and their correlation over 3000 measurements (standard error of a
        // std estimate ≈ 1.3 %, so a 6 % band is > 4 standard errors).
        let (s, _) = servo();
        let h = Handoff::at_rest(0.0);
        let n = 3000;
        let sigma = 0.05;
        let collect = |fast: bool| {
            let mut r = SimRng::new(if fast { 1 } else { 2 });
            let mut a = Vec::with_capacity(n);
            let mut z = Vec::with_capacity(n);
            for _ in 0..n {
                let m = if fast {
                    s.measure_fast(&h, 0.0, 0.0, sigma, &mut r)
                } else {
                    s.measure_slow(&h, 0.0, 0.0, sigma, &mut r)
                };
                let base = s.measure_fast(&h, 0.0, 0.0, 0.0, &mut r);
                a.push(m.average - base.average);
                z.push(m.z_end - base.z_end);
            }
            (a, z)
        };
        let (fa, fz) = collect(true);
        let (sa, sz) = collect(false);
        let sd = |x: &[f64]| crate::numeric::stats::std_dev(x).unwrap();
        for (f, sl) in [(sd(&fa), sd(&sa)), (sd(&fz), sd(&sz))] {
            assert!((f / sl - 1.0).abs() < 0.06, "fast {f} slow {sl}");
        }
        let corr = |x: &[f64], y: &[f64]| {
            let n = x.len() as f64;
            let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
            let c: f64 = x
                .iter()
                .zip(y)
                .map(|(a, b)| (a - mx) * (b - my))
                .sum::<f64>()
                / n;
            c / (sd(x) * sd(y))
        };
        assert!((corr(&fa, &fz) - corr(&sa, &sz)).abs() < 0.08);
    }
}
