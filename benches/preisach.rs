//! `preisach:16` (136 relays): fitting on 1,000,000 rows of a dense hysteretic log against
//! `play:16` on the same log (goal ≤ 3×), and the step rate of the allocation-free
//! `PreisachPredictor` with the fitted grid and weights (goal ≥ 20 M steps/s).
//! `BIASCTL_BENCH_CPU=1` measures the thread's CPU time instead of wall time.
//!
//! The log: `play`'s bench log (a smooth random trajectory with random reversal amplitudes,
//! 1 kHz, through a 3-element stop-operator hysteresis plus a line and noise).

use biasctl::ModelSpec;
use biasctl::SimRng;
use biasctl::model::terms::preisach::PreisachTerm;
use biasctl::model::terms::preisach::memory::PreisachPredictor;
use biasctl::{CheckedFitOptions, fit};
use biasctl::{ColumnMap, Log};
#[path = "common/cputime.rs"]
mod cputime;

use criterion::measurement::Measurement;
use criterion::{Criterion, Throughput};
use std::hint::black_box;

const N: usize = 1_000_000;

fn positions() -> Vec<f64> {
    let mut rng = SimRng::new(7);
    let (mut x, mut v, mut target) = (0.0f64, 0.0f64, 1.0f64);
    (0..N)
        .map(|_| {
            if (target - x).abs() < 1e-3 {
                target = 2.0 * rng.normal();
            }
            v = 0.99 * v + 0.01 * (target - x).signum() * 0.004;
            x += v;
            x
        })
        .collect()
}

fn log(xs: &[f64]) -> Log {
    let mut rng = SimRng::new(8);
    let r = [0.05, 0.3, 1.0];
    let mut z = [xs[0]; 3];
    let mut text = String::with_capacity(N * 40);
    text.push_str("time_s,track,bias\n");
    for (k, &x) in xs.iter().enumerate() {
        for (zi, ri) in z.iter_mut().zip(r) {
            *zi = zi.clamp(x - ri, x + ri);
        }
        let y = 2.0 + 0.5 * x + 3.0 * (x - z[0]) / r[0] + 2.0 * (x - z[1]) / r[1]
            - 1.0 * (x - z[2]) / r[2]
            + 0.05 * rng.normal();
        text.push_str(&format!("{},{x},{y}\n", k as f64 * 1e-3));
    }
    Log::from_reader("bench.csv", text.as_bytes(), &ColumnMap::default()).expect("valid log")
}

fn bench<M: Measurement>(c: &mut Criterion<M>) {
    let xs = positions();
    let data = log(&xs);
    let play = ModelSpec::parse("poly2,play:16").expect("valid spec");
    let preisach = ModelSpec::parse("poly2,preisach:16").expect("valid spec");
    let mut g = c.benchmark_group("preisach");
    g.sample_size(10);
    g.bench_function("fit_play16_1M_rows", |b| {
        b.iter(|| fit(&play, black_box(&data), &CheckedFitOptions::default()).expect("fits"))
    });
    g.bench_function("fit_preisach16_1M_rows", |b| {
        b.iter(|| fit(&preisach, black_box(&data), &CheckedFitOptions::default()).expect("fits"))
    });
    let model = fit(&preisach, &data, &CheckedFitOptions::default()).expect("fits");
    let t = model
        .terms
        .iter()
        .find(|t| t.term.name() == "preisach:16")
        .expect("preisach term");
    let settings: PreisachTerm =
        serde_json::from_value(t.term.settings()).expect("preisach settings");
    let mu = settings.weights(&t.coefficients);
    let mut p = PreisachPredictor::new(settings.grid, &mu, 0.0).expect("valid");
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function("predictor_preisach16_1M_steps", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for &x in black_box(&xs) {
                acc += p.step(x);
            }
            black_box(acc)
        })
    });
    g.finish();
}

bench_main!(bench);
