//! Diagnosis on 100,000 measured rows with every built-in feature (target: under 3 s on one
//! core): the feature table from a log, the full diagnosis (cross-validation of every
//! feature and 199 block permutations, pair screening, global check) of a residual with a
//! planted direction-change step, and the same with verified refits (a model fitted to a log
//! with a missing covariate: diagnose, absorption, three folds × the leading suggestions
//! refitted). `discover` on 6,000 rows (target: under 10 s) climbs from `poly2` on a log with
//! a position bump, a covariate and a direction offset.

use std::hint::black_box;

use biasctl::ModelSpec;
use biasctl::SimRng;
use biasctl::{
    CheckedDiscoverConfig, CheckedVerifyConfig, DiagnoseConfig, diagnose, diagnose::FeatureTable,
    diagnose_verified, discover,
};
use biasctl::{CheckedFitOptions, fit};
use biasctl::{ColumnMap, Log, log::LogWriter};
#[path = "common/cputime.rs"]
mod cputime;

use criterion::Criterion;
use criterion::measurement::Measurement;

const ROWS: usize = 100_000;

/// `rows` random targets in a 250-track span with random dwell times, every row measured.
fn seek_log(rows: usize) -> Log {
    let mut rng = SimRng::new(42);
    let mut w = LogWriter::new(Vec::new(), &[], &[]).expect("write to memory");
    let mut t = 0.0;
    for _ in 0..rows {
        t += rng.range(0.05, 10.0);
        w.write_row(t, rng.below(250) as f64, Some(0.0), &[])
            .expect("write to memory");
    }
    let text = w.into_inner().expect("write to memory");
    Log::from_reader("bench.csv", text.as_slice(), &ColumnMap::default()).expect("valid log")
}

/// `rows` random seeks in 0..300 whose bias is a position bump, 0.8 counts per unit of a
/// logged covariate, ±4 counts by direction and unit noise; a no-effect column rides along.
fn effects_log(rows: usize, seed: u64) -> Log {
    let mut rng = SimRng::new(seed);
    let names = ["temp_c".to_string(), "walk".to_string()];
    let mut w = LogWriter::new(Vec::new(), &[], &names).expect("write to memory");
    let (mut prev, mut walk) = (150.0, 0.0);
    for i in 0..rows {
        let pos = rng.below(300) as f64;
        let dir = if pos >= prev { 1.0 } else { -1.0 };
        prev = pos;
        let temp = 40.0 + 5.0 * rng.normal();
        walk += rng.normal();
        let bump = 10.0 * (-((pos - 150.0) / 25.0).powi(2)).exp();
        let bias = 20.0 + bump + 0.8 * (temp - 40.0) + 4.0 * dir + rng.normal();
        w.write_row(0.3 * i as f64, pos, Some(bias), &[temp, walk])
            .expect("write to memory");
    }
    let text = w.into_inner().expect("write to memory");
    Log::from_reader("effects.csv", text.as_slice(), &ColumnMap::default()).expect("valid log")
}

/// The feature table of [`seek_log`] and a residual with a planted direction-change step of 3
/// counts in unit noise.
fn planted(log: &Log) -> (FeatureTable, Vec<f64>) {
    let table = FeatureTable::from_log(log);
    let change = &table.column("direction_change").expect("built-in feature");
    let mut rng = SimRng::new(7);
    let residuals: Vec<f64> = change
        .iter()
        .map(|v| 3.0 * v.unwrap_or(0.0) + rng.normal())
        .collect();
    (table, residuals)
}

fn bench<M: Measurement>(c: &mut Criterion<M>) {
    let log = seek_log(ROWS);
    let (table, residuals) = planted(&log);
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

    // Verified diagnosis on 100k rows: the model lacks the covariate and the bump.
    let big = effects_log(ROWS, 3);
    let model = fit(
        &ModelSpec::parse("poly2,direction").expect("spec"),
        &big,
        &CheckedFitOptions::default(),
    )
    .expect("fit");
    let verify = CheckedVerifyConfig::default();
    let d = diagnose_verified(&model, &big, &config, &verify).expect("diagnosis");
    let best = d
        .verification
        .as_ref()
        .and_then(|v| v.best())
        .expect("a verified edit");
    assert!(best.gain > 0.1, "{}", d.to_text());
    let mut group = c.benchmark_group("diagnose_verified_100k");
    group.sample_size(10);
    group.bench_function("diagnose_verified", |b| {
        b.iter(|| diagnose_verified(black_box(&model), black_box(&big), &config, &verify))
    });
    group.finish();

    // discover on 6,000 rows from poly2.
    let small = effects_log(6000, 4);
    let start = ModelSpec::parse("poly2").expect("spec");
    let dc = CheckedDiscoverConfig::default();
    let (found, _) = discover(&start, &small, None, &dc).expect("discover");
    assert!(found.steps.len() >= 2, "{found}");
    let mut group = c.benchmark_group("discover_6k");
    group.sample_size(10);
    group.bench_function("discover", |b| {
        b.iter(|| discover(black_box(&start), black_box(&small), None, &dc))
    });
    group.finish();

    // The plain diagnosis on 1M rows (built only when the group is selected: it takes
    // seconds to write and read the log).
    if std::env::args().any(|a| a.contains("1M")) {
        let big = seek_log(10 * ROWS);
        let (table, residuals) = planted(&big);
        let d = diagnose(&table, &residuals, &config).expect("diagnosis");
        assert_eq!(d.features[0].name, "direction_change");
        let mut group = c.benchmark_group("diagnose_1M");
        group.sample_size(10);
        group.bench_function("diagnose", |b| {
            b.iter(|| diagnose(black_box(&table), black_box(&residuals), &config))
        });
        group.finish();
    }
}

bench_main!(bench);
