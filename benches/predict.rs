//! `biasctl predict` on 1,000,000 rows: replaying the `calibration` model (eq. 1, fitted on the
//! calibration run of the built-in drive) causally over a 1M-seek random log, and writing the
//! predict CSV (input columns, `predicted`, `residual`, one column per term) into a `Vec<u8>`.
//! The log is in memory (reading is the `read` bench). The writer below is the row format of
//! `src/cli/predict.rs`; the set-up checks it byte for byte against the real `biasctl predict`
//! on a small log, so it cannot drift from the CLI unnoticed. This bench only measures: the
//! writers are being changed elsewhere.

use biasctl::fit::{FitOptions, fit};
use biasctl::log::{ColumnMap, Log, fmt_fixed, fmt_trimmed};
use biasctl::model::{FittedModel, ModelSpec, Prediction};
use biasctl::sim::{Drive, SequenceOptions, SimConfig, simulate_log, simulate_to_files};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use std::io::Write;

const N: u64 = 1_000_000;

/// The predict CSV of `src/cli/predict.rs`, into `w`.
fn write_predict_csv(w: &mut impl Write, log: &Log, pred: &Prediction) -> std::io::Result<()> {
    let s = &log.schema;
    write!(w, "{},{},{}", s.map.time, s.map.track, s.map.bias)?;
    for c in &s.covariates {
        write!(w, ",{c}")?;
    }
    write!(w, ",predicted,residual")?;
    for t in &pred.term_names {
        write!(w, ",{t}")?;
    }
    writeln!(w)?;
    for (i, &r) in pred.rows.iter().enumerate() {
        let row = &log.rows[r];
        write!(
            w,
            "{},{},{}",
            fmt_fixed(row.time_s, 6),
            fmt_trimmed(row.track, 6),
            fmt_fixed(pred.measured[i], 4)
        )?;
        for c in &row.covariates {
            write!(w, ",{}", fmt_trimmed(*c, 6))?;
        }
        write!(
            w,
            ",{},{}",
            fmt_fixed(pred.predicted[i], 4),
            fmt_fixed(pred.residual[i], 4)
        )?;
        for c in &pred.contributions {
            write!(w, ",{}", fmt_fixed(c[i], 4))?;
        }
        writeln!(w)?;
    }
    Ok(())
}

fn random_log(n: u64, seed: u64) -> Log {
    let opts = SequenceOptions {
        n: Some(n),
        ..SequenceOptions::default()
    };
    let cfg = SimConfig::new(Drive::paper1997(), "random", &opts, seed, &[]).expect("config");
    simulate_log(&cfg).expect("simulated log")
}

/// The bench's writer against the real CLI on a small log (byte for byte).
fn check_against_cli(model: &FittedModel) {
    let dir = tempfile::tempdir().expect("temporary directory");
    let (model_path, log_path, out) = (
        dir.path().join("cal.json"),
        dir.path().join("test.csv"),
        dir.path().join("pred.csv"),
    );
    model.save(&model_path).expect("model saved");
    let opts = SequenceOptions {
        n: Some(300),
        ..SequenceOptions::default()
    };
    let cfg = SimConfig::new(Drive::paper1997(), "random", &opts, 2, &[]).expect("config");
    simulate_to_files(&cfg, &log_path, None).expect("log written");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_biasctl"))
        .args(["predict", "--model"])
        .arg(&model_path)
        .arg("--data")
        .arg(&log_path)
        .arg("--out")
        .arg(&out)
        .output()
        .expect("biasctl runs");
    assert!(
        status.status.success(),
        "biasctl predict failed: {status:?}"
    );
    let log = Log::read(&log_path, &ColumnMap::default()).expect("valid log");
    let pred = model.predict_log(&log).expect("replay");
    let mut mine = Vec::new();
    write_predict_csv(&mut mine, &log, &pred).expect("in memory");
    let cli = std::fs::read(&out).expect("CLI output");
    assert!(
        mine == cli,
        "the bench's predict writer no longer matches `biasctl predict`: update benches/predict.rs"
    );
}

fn bench(c: &mut Criterion) {
    let opts = SequenceOptions::default();
    let cal = SimConfig::new(Drive::paper1997(), "calibration", &opts, 1, &[]).expect("config");
    let train = simulate_log(&cal).expect("calibration run");
    let spec = ModelSpec::preset("calibration").expect("preset");
    let model = fit(&spec, &train, &FitOptions::default()).expect("fit");
    check_against_cli(&model);
    let log = random_log(N, 2);
    let mut out = Vec::new();
    let pred = model.predict_log(&log).expect("replay");
    write_predict_csv(&mut out, &log, &pred).expect("in memory");
    let bytes = out.len();
    let mut g = c.benchmark_group("predict");
    g.sample_size(10);
    g.throughput(Throughput::Elements(pred.rows.len() as u64));
    g.bench_function("replay_1M_rows", |b| {
        b.iter(|| black_box(model.predict_log(black_box(&log)).expect("replay")))
    });
    g.throughput(Throughput::Bytes(bytes as u64));
    g.bench_function("write_csv_1M_rows", |b| {
        b.iter(|| {
            out.clear();
            write_predict_csv(&mut out, black_box(&log), &pred).expect("in memory");
            black_box(out.len())
        })
    });
    g.bench_function("replay_and_write_1M_rows", |b| {
        b.iter(|| {
            let pred = model.predict_log(black_box(&log)).expect("replay");
            out.clear();
            write_predict_csv(&mut out, &log, &pred).expect("in memory");
            black_box(out.len())
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
