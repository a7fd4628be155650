//! The random processes and the pivot physics a family run is made of: Bouc–Wen and
//! Prandtl–Ishlinskii pivots, Ornstein–Uhlenbeck and Student-t draws, and the plain list of
//! uncrossed rest positions behind the summed-memory effect.

use super::Pivot;
use crate::numeric::rng::SimRng;

/// The pivot's state.
pub(super) enum PivotState<'a> {
    BoucWen {
        z: f64,
        amplitude: f64,
        length: f64,
        beta: f64,
        n: f64,
    },
    Prandtl {
        s: Vec<f64>,
        thresholds: &'a [f64],
        weights: &'a [f64],
    },
}

impl PivotState<'_> {
    pub(super) fn new(p: &Pivot) -> PivotState<'_> {
        match p {
            Pivot::BoucWen {
                amplitude,
                length,
                beta,
                n,
            } => PivotState::BoucWen {
                z: 0.0,
                amplitude: *amplitude,
                length: *length,
                beta: *beta,
                n: *n,
            },
            Pivot::Prandtl {
                thresholds,
                weights,
            } => PivotState::Prandtl {
                s: vec![0.0; thresholds.len()],
                thresholds,
                weights,
            },
        }
    }

    /// Moves by `dx` tracks and returns the force, counts.
    pub(super) fn step(&mut self, dx: f64) -> f64 {
        match self {
            PivotState::BoucWen {
                z,
                amplitude,
                length,
                beta,
                n,
            } => {
                if dx != 0.0 {
                    let d = dx.signum();
                    let rate = |z: f64| {
                        let b = if d * z > 0.0 { *beta } else { -*beta };
                        d * (1.0 - (b + 1.0 - *beta) * z.abs().powf(*n)) / *length
                    };
                    let steps = (dx.abs() / (*length / 20.0)).ceil().max(1.0);
                    let h = dx.abs() / steps;
                    for _ in 0..steps as usize {
                        let k1 = rate(*z);
                        let k2 = rate(*z + 0.5 * h * k1);
                        let k3 = rate(*z + 0.5 * h * k2);
                        let k4 = rate(*z + h * k3);
                        *z = (*z + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)).clamp(-1.0, 1.0);
                    }
                }
                *amplitude * *z
            }
            PivotState::Prandtl {
                s,
                thresholds,
                weights,
            } => {
                let mut f = 0.0;
                for ((si, &r), &w) in s.iter_mut().zip(thresholds.iter()).zip(weights.iter()) {
                    *si = (*si + dx).clamp(-r, r);
                    f += w * *si / r;
                }
                f
            }
        }
    }
}

/// An Ornstein–Uhlenbeck value with time constant `tau` (s) and stationary std `sd` around
/// `mean`, advanced exactly over `dt`.
pub(super) fn ou_step(x: f64, mean: f64, sd: f64, tau: f64, dt: f64, rng: &mut SimRng) -> f64 {
    let a = (-dt / tau).exp();
    mean + (x - mean) * a + sd * (1.0 - a * a).sqrt() * rng.normal()
}

/// Student-t (ν) scaled to unit variance, or a standard normal.
pub(super) fn innovation(nu: Option<u32>, rng: &mut SimRng) -> f64 {
    let z = rng.normal();
    match nu {
        None => z,
        Some(nu) => {
            let chi2: f64 = (0..nu).map(|_| rng.normal().powi(2)).sum();
            let nu = f64::from(nu);
            z / (chi2 / nu).sqrt() * ((nu - 2.0) / nu).sqrt()
        }
    }
}

/// The uncrossed rest positions, kept the plain way (a list scanned in full at every seek), as
/// an independent reference for the summed-memory law. A move forgets every rest position it
/// crosses or lands on; the source is remembered after the move.
#[derive(Debug, Default)]
pub(super) struct Rests {
    positions: Vec<f64>,
}

impl Rests {
    /// Σ sgn(x − p)·exp(−|x − p|/l) over the rests left after the move `source → x` (every
    /// remembered p outside the closed interval the move covers; the source is not yet in).
    pub(super) fn sum_after_move(&self, source: f64, x: f64, l: f64) -> f64 {
        let (lo, hi) = (source.min(x), source.max(x));
        self.positions
            .iter()
            .filter(|&&p| p < lo || p > hi)
            .map(|&p| (x - p).signum() * (-(x - p).abs() / l).exp())
            .sum()
    }

    /// Forgets the rests the move crosses or lands on and remembers the source; a zero-length
    /// move changes nothing.
    pub(super) fn apply_move(&mut self, source: f64, x: f64) {
        let (lo, hi) = (source.min(x), source.max(x));
        if hi > lo {
            self.positions.retain(|&p| p < lo || p > hi);
            self.positions.push(source);
        }
    }
}

/// Relay levels of the generator's Preisach effect.
const PREISACH_LEVELS: usize = 40;

/// The generator's Preisach hysteresis over `[centre − half, centre + half]` (see
/// [`HiddenEffect::Preisach`](super::HiddenEffect::Preisach)), in [−1, 1]: the slow, obvious
/// model — every relay a bool, all updated every step, all down at the start.
pub(super) fn preisach(tracks: &[f64], centre: f64, half: f64) -> Vec<f64> {
    let m = PREISACH_LEVELS;
    let (lo, h) = (centre - half, 2.0 * half / m as f64);
    let mut relays = Vec::new();
    for i in 0..m {
        for j in 0..=i {
            let (alpha, beta) = (lo + (i + 1) as f64 * h, lo + j as f64 * h);
            let (a, b) = ((alpha - centre) / half, (beta - centre) / half);
            let w = (-0.5 * ((a - 0.35).powi(2) + (b + 0.25).powi(2)) / 0.25f64.powi(2)).exp();
            relays.push((alpha, beta, w, false));
        }
    }
    let total: f64 = relays.iter().map(|r| r.2).sum();
    tracks
        .iter()
        .map(|&x| {
            let mut y = 0.0;
            for r in &mut relays {
                if x >= r.0 {
                    r.3 = true;
                } else if x <= r.1 {
                    r.3 = false;
                }
                y += if r.3 { r.2 } else { -r.2 };
            }
            y / total
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: the Bouc–Wen loop saturates at ±amplitude on long seeks, and a Prandtl
    /// operator's output after a seek longer than every threshold is ±Σw.
    #[test]
    fn pivots_saturate_at_their_closed_form_limits() {
        let bw = Pivot::BoucWen {
            amplitude: 9.0,
            length: 12.0,
            beta: 0.75,
            n: 2.0,
        };
        let mut s = PivotState::new(&bw);
        assert!((s.step(400.0) - 9.0).abs() < 1e-6);
        assert!((s.step(-800.0) + 9.0).abs() < 1e-6);
        let pi = Pivot::Prandtl {
            thresholds: vec![2.0, 6.0],
            weights: vec![3.0, 4.0],
        };
        let mut s = PivotState::new(&pi);
        assert!((s.step(50.0) - 7.0).abs() < 1e-12);
        // Back 4 tracks: the 2-track stop goes to −2 (−3), the 6-track one to 2 (4·2/6).
        assert!((s.step(-4.0) - (-3.0 + 4.0 * 2.0 / 6.0)).abs() < 1e-12);
    }
}
