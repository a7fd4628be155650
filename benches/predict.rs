//! `biasctl predict` on 1,000,000 rows: streaming a 1M-seek random log (held in memory as CSV
//! text) through the `calibration` model (eq. 1, fitted on the calibration run of the built-in
//! drive) with `write_predictions_csv` (what `biasctl predict` calls; input columns,
//! `predicted`, `residual`, one column per term; the rows formatted on a second thread, so
//! `benches/peers/run.sh` times it by the process's CPU time) into a `Vec<u8>`; and the same
//! replay into a
//! sink that drops the rows (`replay_stream`), to separate the writer's share. The set-up checks
//! the output byte for byte against the real `biasctl predict` on a small log.

use biasctl::{ColumnMap, log::BiasColumn, log::LogReader};
use biasctl::{Drive, SequenceOptions, SimConfig, sim::simulate_to_files, simulate_log};
use biasctl::{FitOptions, fit};
use biasctl::{
    FittedModel, ModelSpec, model::RowPrediction, model::replay_stream,
    model::write_predictions_csv,
};
#[path = "common/cputime.rs"]
mod cputime;

use criterion::measurement::Measurement;
use criterion::{Criterion, Throughput};
use std::hint::black_box;

const N: u64 = 1_000_000;

/// `biasctl predict`'s CSV of the log in `text` (the library writer the CLI calls), into `out`
/// (or only the replay when `out` is `None`). Returns the rows replayed.
fn predict_csv(model: &FittedModel, text: &[u8], out: Option<&mut Vec<u8>>) -> u64 {
    let map = ColumnMap::default();
    let mut reader =
        LogReader::from_reader_with("bench.csv", text, &map, BiasColumn::Optional).expect("log");
    let s = match out {
        Some(out) => write_predictions_csv(model, &mut reader, None, out, false),
        None => replay_stream(model, &mut reader, None, |_, p: &RowPrediction, c| {
            black_box((p, c));
            Ok(())
        }),
    };
    s.expect("replay").rows
}

fn log_text(n: u64, seed: u64) -> Vec<u8> {
    let opts = SequenceOptions {
        n: Some(n),
        ..SequenceOptions::default()
    };
    let cfg = SimConfig::new(Drive::paper1997(), "random", &opts, seed, &[]).expect("config");
    let dir = tempfile::tempdir().expect("temporary directory");
    let path = dir.path().join("log.csv");
    simulate_to_files(&cfg, &path, None).expect("log written");
    std::fs::read(&path).expect("log read")
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
    std::fs::write(&log_path, log_text(300, 2)).expect("log written");
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
    // The CLI replays the model as read back from its file.
    let loaded = FittedModel::load(&model_path).expect("model loads");
    let mut mine = Vec::new();
    predict_csv(
        &loaded,
        &std::fs::read(&log_path).expect("log"),
        Some(&mut mine),
    );
    let cli = std::fs::read(&out).expect("CLI output");
    assert!(
        mine == cli,
        "the bench's predict writer no longer matches `biasctl predict`: update benches/predict.rs"
    );
}

fn bench<M: Measurement>(c: &mut Criterion<M>) {
    let opts = SequenceOptions::default();
    let cal = SimConfig::new(Drive::paper1997(), "calibration", &opts, 1, &[]).expect("config");
    let train = simulate_log(&cal).expect("calibration run");
    let spec = ModelSpec::preset("calibration").expect("preset");
    let checked = FitOptions::default().check().expect("default options");
    let model = fit(&spec, &train, &checked).expect("fit");
    check_against_cli(&model);
    let text = log_text(N, 2);
    let mut out = Vec::new();
    let rows = predict_csv(&model, &text, Some(&mut out));
    assert!(rows >= N, "{rows} rows");
    let mut g = c.benchmark_group("predict");
    g.sample_size(10);
    g.throughput(Throughput::Elements(rows));
    g.bench_function("replay_1M_rows", |b| {
        b.iter(|| black_box(predict_csv(&model, black_box(&text), None)))
    });
    g.throughput(Throughput::Bytes(out.len() as u64));
    g.bench_function("replay_and_write_1M_rows", |b| {
        b.iter(|| {
            out.clear();
            black_box(predict_csv(&model, black_box(&text), Some(&mut out)))
        })
    });
    g.finish();
}

bench_main!(bench);
