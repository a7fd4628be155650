//! Hartigans' dip test on 1,000,000 residuals (a two-hump normal mixture): the dip and p-value of
//! already sorted values (linear time), and the whole `dip_test` including its sort.

use biasctl::SimRng;
use biasctl::{numeric::dip_test, numeric::dip_test_sorted, numeric::sorted};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let mut rng = SimRng::new(5);
    let x: Vec<f64> = (0..1_000_000)
        .map(|_| if rng.uniform() < 0.5 { -1.5 } else { 1.5 } + rng.normal())
        .collect();
    let s = sorted(&x);
    let mut g = c.benchmark_group("dip");
    g.sample_size(20);
    g.bench_function("sorted_1M", |b| {
        b.iter(|| black_box(dip_test_sorted(black_box(&s)).expect("dip")))
    });
    g.bench_function("unsorted_1M", |b| {
        b.iter(|| black_box(dip_test(black_box(&x)).expect("dip")))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
