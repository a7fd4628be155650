//! `play:32` (Prandtl–Ishlinskii / Maxwell-slip, 32 elements): fitting on 1,000,000 rows of a
//! dense hysteretic log (goal < 2 s), and prediction throughput of the allocation-free
//! `PlayPredictor` with the fitted thresholds and weights (goal ≥ 20 M steps/s): one `step` per
//! row, `step_many` over the whole log, and the arithmetic before the vectorisation
//! (`reference_clamp_1M_steps`: `f64::clamp` per element, a left-to-right sum) for the ratio.
//! `BIASCTL_BENCH_CPU=1` measures the thread's CPU time instead of wall time.
//!
//! The log: a smooth random trajectory (sum of slowly varying sinusoids with random reversal
//! amplitudes, 1 kHz) through a 3-element stop-operator hysteresis plus a line and noise.

use biasctl::ModelSpec;
use biasctl::SimRng;
use biasctl::{CheckedFitOptions, fit};
use biasctl::{ColumnMap, Log};
use biasctl::{model::terms::play::PlayPredictor, model::terms::play::PlayTerm};
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
    let spec = ModelSpec::parse("poly2,play:32").expect("valid spec");
    let mut g = c.benchmark_group("play");
    g.sample_size(10);
    g.bench_function("fit_play32_1M_rows", |b| {
        b.iter(|| fit(&spec, black_box(&data), &CheckedFitOptions::default()).expect("fits"))
    });
    let model = fit(&spec, &data, &CheckedFitOptions::default()).expect("fits");
    let t = model
        .terms
        .iter()
        .find(|t| t.term.name() == "play:32")
        .expect("play term");
    let settings: PlayTerm = serde_json::from_value(t.term.settings()).expect("play settings");
    let (r, w) = (&settings.thresholds, &t.coefficients);
    let mut p = PlayPredictor::new(r, w, 0.0).expect("valid");
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function("predictor_play32_1M_steps", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for &x in black_box(&xs) {
                acc += p.step(x);
            }
            black_box(acc)
        })
    });
    let mut out = Vec::with_capacity(N);
    g.bench_function("step_many_play32_1M_steps", |b| {
        b.iter(|| {
            let mut p = PlayPredictor::new(r, w, 0.0).expect("valid");
            out.clear();
            p.step_many(black_box(&xs), &mut out);
            black_box(&out);
        })
    });
    g.bench_function("reference_clamp_1M_steps", |b| {
        // `PlayOperator::step_weighted` before the vectorisation.
        let ir: Vec<f64> = r.iter().map(|v| 1.0 / v).collect();
        let mut z = vec![xs[0]; r.len()];
        b.iter(|| {
            let mut acc = 0.0;
            for &x in black_box(&xs) {
                let mut s = 0.0;
                for (((z, &r), &ir), &wi) in z.iter_mut().zip(r).zip(&ir).zip(w) {
                    *z = z.clamp(x - r, x + r);
                    s += wi * (x - *z) * ir;
                }
                acc += s;
            }
            black_box(acc)
        })
    });
    g.finish();
}

bench_main!(bench);
