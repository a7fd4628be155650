//! Fitting on 1,000,000 measured rows of a synthetic random-seek log (made once, outside the
//! timed loop): the `calibration` preset (poly2+direction+seek+memory+drift, eq. 1;
//! goal ≤ 150 ms) and the `dahl` preset (a 1-D search over the Dahl rate by variable
//! projection, its candidates replayed eight side by side through `Term::search_basis`, then
//! four full solves; goal ≤ 0.5 s). `BIASCTL_BENCH_CPU=process` measures the
//! process's CPU time (the solve factorises row chunks on rayon's pool as well, which the
//! thread CPU time of `BIASCTL_BENCH_CPU=1` would not count).

use biasctl::History;
use biasctl::ModelSpec;
use biasctl::SimRng;
use biasctl::{ColumnMap, Log};
use biasctl::{FitOptions, fit};
#[path = "common/cputime.rs"]
mod cputime;

use criterion::Criterion;
use criterion::measurement::Measurement;
use std::hint::black_box;

fn log(n: usize) -> Log {
    let mut rng = SimRng::new(3);
    let mut h = History::new();
    let mut text = String::with_capacity(n * 32);
    text.push_str("time_s,track,bias\n");
    let mut x = 500.0;
    for k in 0..n {
        x = if rng.uniform() < 0.5 {
            (x + rng.below(41) as f64 - 20.0).clamp(0.0, 1000.0)
        } else {
            rng.below(1001) as f64
        };
        let f = h.step(k as f64 * 0.01, x);
        let u = (x - 500.0) / 500.0;
        let seek = if f.direction_change {
            8.0 * (-f.seek_abs() / 40.0).exp()
        } else {
            0.0
        };
        let y = 20.0 + 10.0 * u - 5.0 * u * u + 15.0 * f64::from(f.direction)
            - seek * f64::from(f.direction)
            + 2.0 * rng.normal();
        text.push_str(&format!("{:.2},{x},{y:.4}\n", k as f64 * 0.01));
    }
    Log::from_reader("bench.csv", text.as_bytes(), &ColumnMap::default()).expect("synthetic log")
}

fn bench<M: Measurement>(c: &mut Criterion<M>) {
    let log = log(1_000_000);
    let mut g = c.benchmark_group("fit");
    g.sample_size(10);
    for (name, preset) in [
        ("calibration_1M_rows", "calibration"),
        ("dahl_1M_rows", "dahl"),
    ] {
        let spec = ModelSpec::preset(preset).expect("preset");
        g.bench_function(name, |b| {
            b.iter(|| {
                black_box(
                    fit(
                        &spec,
                        black_box(&log),
                        &FitOptions::default().check().unwrap(),
                    )
                    .expect("fit"),
                )
            })
        });
    }
    g.finish();
}

bench_main!(bench);
