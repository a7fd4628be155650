//! The `memory` term's state update (two-stack uncrossed rest positions inside `History`):
//! amortised O(1) per seek. 1M and 10M seeks of a random walk whose rest memory keeps growing;
//! the time per seek must be the same at both counts (linear total time).

use biasctl::History;
use biasctl::SimRng;
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;

fn walk(n: usize) -> Vec<f64> {
    let mut rng = SimRng::new(2);
    let mut x = 0.0;
    (0..n)
        .map(|_| {
            x += rng.below(41) as f64 - 20.0;
            x
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let all = walk(10_000_000);
    let mut g = c.benchmark_group("memory");
    for n in [1_000_000usize, 10_000_000] {
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(BenchmarkId::new("history_step", n), &n, |b, &n| {
            b.iter(|| {
                let mut h = History::new();
                let mut acc = 0.0;
                for (k, &x) in all[..n].iter().enumerate() {
                    let f = h.step(k as f64, x);
                    acc += f.rest_distance_ahead().unwrap_or(0.0);
                }
                black_box((acc, h.memory().len()))
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
