//! Diagnosis on 100,000 measured rows with every built-in feature (target: under 3 s on one
//! core): the feature table from a log, and the full diagnosis (cross-validation of every
//! feature and 199 permutations) of a residual with a planted direction-change step.

use std::hint::black_box;

use biasctl::diagnose::{DiagnoseConfig, FeatureTable, diagnose};
use biasctl::log::{ColumnMap, Log, LogWriter};
use biasctl::rng::SimRng;
use criterion::{Criterion, criterion_group, criterion_main};

const ROWS: usize = 100_000;

/// Random targets in a 250-track span with random dwell times, every row measured.
fn log() -> Log {
    let mut rng = SimRng::new(42);
    let mut w = LogWriter::new(Vec::new(), &[], &[]).expect("write to memory");
    let mut t = 0.0;
    for _ in 0..ROWS {
        t += rng.range(0.05, 10.0);
        w.write_row(t, rng.below(250) as f64, Some(0.0), &[])
            .expect("write to memory");
    }
    let text = w.into_inner();
    Log::from_reader("bench.csv", text.as_slice(), &ColumnMap::default()).expect("valid log")
}

fn bench(c: &mut Criterion) {
    let log = log();
    let table = FeatureTable::from_log(&log);
    let change = &table
        .column("direction_change")
        .expect("built-in feature")
        .values;
    let mut rng = SimRng::new(7);
    let residuals: Vec<f64> = change
        .iter()
        .map(|v| 3.0 * v.unwrap_or(0.0) + rng.normal())
        .collect();
    let config = DiagnoseConfig::default().check().expect("config");
    // The benchmark measures a real diagnosis: check that it finds the planted effect.
    let d = diagnose(&table, &residuals, &config).expect("diagnosis");
    assert_eq!(d.features[0].name, "direction_change");

    let mut group = c.benchmark_group("diagnose_100k");
    group.bench_function("feature_table", |b| {
        b.iter(|| FeatureTable::from_log(black_box(&log)))
    });
    group.bench_function("diagnose", |b| {
        b.iter(|| diagnose(black_box(&table), black_box(&residuals), &config))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
