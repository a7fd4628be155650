//! Simulating 1,000,000 random seeks with measurement (fast superposition path), streamed to a
//! sink that folds every row (memory independent of the number of seeks). Goal: < 2 s.

use biasctl::{Drive, SequenceOptions, SimConfig, sim::simulate};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let opts = SequenceOptions {
        n: Some(1_000_000),
        ..SequenceOptions::default()
    };
    let cfg = SimConfig::new(Drive::paper1997(), "random", &opts, 1, &[]).expect("valid config");
    let mut g = c.benchmark_group("simulate");
    g.sample_size(10);
    g.bench_function("random_1M_seeks_measured", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            let s = simulate(black_box(&cfg), |row| {
                acc += row.bias.unwrap_or(0.0);
                Ok::<(), ()>(())
            })
            .expect("infallible sink");
            black_box((s, acc))
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
