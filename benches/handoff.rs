//! One handoff on the paper's test bed: bounds (eq. 14), backward min/max and search (eq. 15–16),
//! and the start-value choices (optimal, robust for Δb = 8 counts, zero feedforward's worst case),
//! for horizons 64, 128 and 256. The table is precomputed outside the timed loop, as in a drive.
//! `BIASCTL_BENCH_CPU=1` measures the thread's CPU time instead of wall time (a shared machine).

use biasctl::control::Controller;
use biasctl::{HandoffTable, SettleSpec, control::Bounds, control::Handoff};
use criterion::measurement::Measurement;
use criterion::{BenchmarkId, Criterion};
use std::hint::black_box;
#[path = "common/cputime.rs"]
mod cputime;

fn handoff<M: Measurement>(c: &mut Criterion<M>) {
    let cfg = SettleSpec::preset("paper1997")
        .and_then(|s| s.check())
        .expect("preset is valid");
    let ctl = Controller::design(&cfg.plant, &cfg.weights).expect("preset designs");
    let window = cfg.scenario.window;
    let h = Handoff {
        e0_um: -15.0,
        v0_um_s: 0.0,
        u_prev_counts: 12.0,
        bias_counts: 12.0,
    };
    let mut group = c.benchmark_group("handoff");
    for n in [64usize, 128, 256] {
        let table = HandoffTable::new(&ctl, n).expect("horizon is valid");
        group.bench_with_input(BenchmarkId::new("solve", n), &n, |b, _| {
            b.iter(|| {
                let sol = table.solve(black_box(&h), black_box(&window), black_box(8.0));
                let opt = sol.optimal.map(|i| i.choice(0.0));
                let rob = sol.robust.map(|i| i.choice(sol.shift));
                black_box((sol, opt, rob))
            })
        });
        let mut buf = Bounds::new(n);
        group.bench_with_input(BenchmarkId::new("bounds_into", n), &n, |b, _| {
            b.iter(|| {
                table
                    .bounds_into(black_box(&h), black_box(&window), &mut buf)
                    .expect("buffer fits");
                black_box(buf.optimal())
            })
        });
    }
    group.finish();
}

bench_main!(handoff);
