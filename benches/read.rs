//! Reading a 1,000,000-row measurement log from disk, the work every command starts with:
//! `Log::read` (the whole log in memory, what fit/predict/diagnose use),
//! `LogReader::summarise` (streaming, constant memory, the read `biasctl check` does) and
//! `summarise_sampling` (all of `check`: that read and the exact quantiles). The log is
//! what `biasctl simulate --sequence random --n 1000000 --seed 1` writes (same code path),
//! made once outside the timed loop. Throughput is in bytes of the file. This bench only
//! measures: the reader is being changed elsewhere.

use biasctl::{ColumnMap, Log, log::LogReader};
use biasctl::{Drive, SequenceOptions, SimConfig, sim::simulate_to_files};
#[path = "common/cputime.rs"]
mod cputime;

use criterion::measurement::Measurement;
use criterion::{Criterion, Throughput};
use std::hint::black_box;

const N: u64 = 1_000_000;

fn bench<M: Measurement>(c: &mut Criterion<M>) {
    let dir = tempfile::tempdir().expect("temporary directory");
    let path = dir.path().join("random_1M.csv");
    let opts = SequenceOptions {
        n: Some(N),
        ..SequenceOptions::default()
    };
    let cfg = SimConfig::new(Drive::paper1997(), "random", &opts, 1, &[]).expect("valid config");
    simulate_to_files(&cfg, &path, None).expect("log written");
    let bytes = std::fs::metadata(&path).expect("log exists").len();
    let map = ColumnMap::default();
    // The work is real: every row is read and validated.
    let rows = Log::read(&path, &map).expect("valid log").len();
    assert!(rows as u64 >= N, "{rows} rows");
    let mut g = c.benchmark_group("read");
    g.sample_size(10);
    g.throughput(Throughput::Bytes(bytes));
    g.bench_function("log_read_1M_rows", |b| {
        b.iter(|| {
            let log = Log::read(black_box(&path), &map).expect("valid log");
            black_box(log.len())
        })
    });
    g.bench_function("check_summarise_1M_rows", |b| {
        b.iter(|| {
            let mut r = LogReader::open(black_box(&path), &map).expect("valid log");
            black_box(r.summarise().expect("valid log"))
        })
    });
    // All of `biasctl check`: the streaming read, every row's time and position spooled to a
    // temporary file, the exact quantiles' later passes over that file.
    g.bench_function("check_sampling_1M_rows", |b| {
        b.iter(|| {
            let mut r = LogReader::open(black_box(&path), &map).expect("valid log");
            black_box(biasctl::history::summarise_sampling(&mut r, &path, &map).expect("valid log"))
        })
    });
    g.finish();
}

bench_main!(bench);
