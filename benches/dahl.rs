//! Dahl prediction throughput (eqs. 8–9): seeks per second of the allocation-free
//! `DahlPredictor` over 1M random seeks within 250 tracks (the paper's random-seek test range):
//! one `step` per seek, and `step_many` over the whole sequence (the per-seek factors computed a
//! block ahead of the loop-carried chain); and 1M candidate peeks.

use biasctl::SimRng;
use biasctl::{model::terms::dahl::DahlPredictor, model::terms::dahl::DahlState};
#[path = "common/cputime.rs"]
mod cputime;

use criterion::measurement::Measurement;
use criterion::{Criterion, Throughput};
use std::hint::black_box;

const N: usize = 1_000_000;

fn targets() -> Vec<f64> {
    let mut rng = SimRng::new(1);
    (0..N).map(|_| 1000.0 + rng.below(250) as f64).collect()
}

fn bench<M: Measurement>(c: &mut Criterion<M>) {
    let xs = targets();
    let mut g = c.benchmark_group("dahl");
    g.throughput(Throughput::Elements(N as u64));
    g.bench_function("predictor_1M_seeks", |b| {
        b.iter(|| {
            let mut p =
                DahlPredictor::new([5.0, 0.01, -1e-6], 15.0, 1.2).expect("valid parameters");
            let mut acc = 0.0;
            for &x in black_box(&xs) {
                acc += p.step(x);
            }
            black_box(acc)
        })
    });
    g.bench_function("reference_eq8_1M_seeks", |b| {
        // The per-seek arithmetic before `affine`: DahlState::step, s + (G − s)·r^|dx| with a
        // branch on the sign (what `DahlPredictor::step` ran until then).
        let (c, fc, r) = ([5.0, 0.01, -1e-6], 15.0, 1.0 - 1.2 / 15.0);
        b.iter(|| {
            let mut g = DahlState::new(r);
            let mut prev = None::<f64>;
            let mut acc = 0.0;
            for &x in black_box(&xs) {
                let dx = prev.map_or(0.0, |p| x - p);
                prev = Some(x);
                acc += c[0] + x * (c[1] + x * c[2]) + fc * g.step(dx);
            }
            black_box(acc)
        })
    });
    g.bench_function("step_many_1M_seeks", |b| {
        let mut out = Vec::with_capacity(N);
        b.iter(|| {
            let mut p =
                DahlPredictor::new([5.0, 0.01, -1e-6], 15.0, 1.2).expect("valid parameters");
            out.clear();
            p.step_many(black_box(&xs), &mut out);
            black_box(&out);
        })
    });
    g.bench_function("peek_1M_candidates", |b| {
        let mut p = DahlPredictor::new([5.0, 0.01, -1e-6], 15.0, 1.2).expect("valid parameters");
        p.step(1100.0);
        b.iter(|| {
            let mut acc = 0.0;
            for &x in black_box(&xs) {
                acc += p.peek(x);
            }
            black_box(acc)
        })
    });
    g.finish();
}

bench_main!(bench);
