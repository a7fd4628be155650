//! Dahl prediction throughput (eqs. 8–9): seeks per second of the allocation-free
//! `DahlPredictor` over 1M random seeks within 250 tracks (the paper's random-seek test range),
//! and of the generic term-sum `Predictor` on the same model for comparison.

use biasctl::model::terms::dahl::DahlPredictor;
use biasctl::numeric::rng::SimRng;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;

const N: usize = 1_000_000;

fn targets() -> Vec<f64> {
    let mut rng = SimRng::new(1);
    (0..N).map(|_| 1000.0 + rng.below(250) as f64).collect()
}

fn bench(c: &mut Criterion) {
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

criterion_group!(benches, bench);
criterion_main!(benches);
