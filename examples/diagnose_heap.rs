//! Peak heap of `diagnose` per log row, counted by the allocator (goal: `diagnose`
//! ≤ 160 B/row): a deterministic figure, unlike peak-RSS slopes, which move by ±10 B/row
//! between runs on a shared machine (RSS keeps pages the allocator freed but has not
//! returned, and depends on what other threads did in between).
//!
//! ```sh
//! cargo run --release --example diagnose_heap -- [THREADS] [screen|verified|both]
//! ```
//!
//! A counting `#[global_allocator]` (wrapping the system allocator) tracks the bytes
//! allocated now and their peak. For each model (`fit --model calibration` and `--model dahl`,
//! fitted once on the 1M-row log) and each log (`simulate --sequence random --seed 1` of
//! 300,000 and 1,000,000 seeks, the CLI's logs of README's memory rounds) it runs the
//! library's screen (`diagnose_model`, the CLI's `diagnose --no-verify`) and the verified run
//! (`diagnose_verified`, the CLI's default) on `THREADS` threads (default 2), and prints the
//! peak heap of each run — everything allocated at that moment, the log and the model
//! included, as in the CLI — and the slope between the two logs in bytes per row. The
//! counts are exact and the same on every run for a given thread count (the order in which
//! two threads' allocations overlap can move the peak slightly between thread schedules;
//! with 1 thread it is fully deterministic).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use biasctl::{
    CheckedDiagnoseConfig, DiagnoseConfig, Drive, FitOptions, FittedModel, Log, ModelSpec,
    SequenceOptions, SimConfig, VerifyConfig, diagnose_model, diagnose_verified, fit, simulate_log,
};

/// The system allocator, counting the bytes in use and their peak.
struct Counting;

static NOW: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

impl Counting {
    fn add(n: usize) {
        let now = NOW.fetch_add(n, Ordering::Relaxed) + n;
        PEAK.fetch_max(now, Ordering::Relaxed);
    }
    fn sub(n: usize) {
        NOW.fetch_sub(n, Ordering::Relaxed);
    }
}

// SAFETY: every call is forwarded to `System` unchanged; the counters only observe sizes.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract is `System::alloc`'s.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            Counting::add(layout.size());
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as `alloc`.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            Counting::add(layout.size());
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` with `layout` (every allocation goes
        // through this allocator).
        unsafe { System.dealloc(ptr, layout) };
        Counting::sub(layout.size());
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as `dealloc` and `alloc`. A moving realloc holds both blocks for a
        // moment: counted as the new block added before the old one is released.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            Counting::add(new_size);
            Counting::sub(layout.size());
        }
        p
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

/// Bytes allocated now.
fn now() -> usize {
    NOW.load(Ordering::Relaxed)
}

/// Runs `f` and returns its value and the peak of bytes allocated while it ran (everything
/// allocated before it and still held included).
fn peak_of<T>(f: impl FnOnce() -> T) -> (T, usize) {
    PEAK.store(now(), Ordering::Relaxed);
    let v = f();
    (v, PEAK.load(Ordering::Relaxed))
}

/// The CLI's `simulate --sequence random --seed 1 --n rows` log.
fn log_of(rows: usize) -> Log {
    let seq = SequenceOptions {
        n: Some(rows as u64),
        ..SequenceOptions::default()
    };
    let sim =
        SimConfig::new(Drive::paper1997(), "random", &seq, 1, &[]).expect("simulation config");
    simulate_log(&sim).expect("simulate")
}

fn mb(bytes: usize) -> f64 {
    bytes as f64 / 1e6
}

fn main() {
    let mut args = std::env::args().skip(1);
    let threads: usize = args.next().map_or(2, |t| t.parse().expect("THREADS"));
    let which = args.next().unwrap_or_else(|| "both".into());
    let (screen, verified) = match which.as_str() {
        "screen" => (true, false),
        "verified" => (false, true),
        "both" => (true, true),
        other => panic!("screen, verified or both, not {other}"),
    };
    biasctl::set_threads(threads).expect("threads");
    let sizes = [300_000usize, 1_000_000];
    let config: CheckedDiagnoseConfig = DiagnoseConfig::default().check().expect("config");

    // The models, fitted on the 1M-row log as README's memory rounds do.
    let big = log_of(sizes[1]);
    let models: Vec<(&str, FittedModel)> = ["calibration", "dahl"]
        .iter()
        .map(|name| {
            let spec = ModelSpec::preset(name).expect("preset");
            let opts = FitOptions::default().check().expect("fit options");
            (*name, fit(&spec, &big, &opts).expect("fit"))
        })
        .collect();
    drop(big);

    println!("diagnose peak heap ({threads} threads; log and model included)");
    println!(
        "{:<10} {:<12} {:>12} {:>12} {:>10}",
        "run", "model", "300k, MB", "1M, MB", "B/row"
    );
    let runs = [("screen", screen), ("verified", verified)];
    for (run, on) in runs {
        if !on {
            continue;
        }
        for (name, model) in &models {
            let peaks: Vec<usize> = sizes
                .iter()
                .map(|&rows| {
                    let log = log_of(rows);
                    let fit_opts = FitOptions {
                        direction: model.direction.setting(),
                        ..FitOptions::default()
                    }
                    .check()
                    .expect("fit options");
                    let verify = VerifyConfig {
                        fit: fit_opts,
                        ..VerifyConfig::default()
                    }
                    .check()
                    .expect("verify config");
                    let (d, peak) = peak_of(|| {
                        if run == "screen" {
                            diagnose_model(model, &log, &config)
                        } else {
                            diagnose_verified(model, &log, &config, &verify)
                        }
                    });
                    let d = d.expect("diagnosis");
                    // The diagnosis is real: it names features and a top one.
                    assert_eq!(d.rows, rows);
                    assert!(!d.features.is_empty());
                    peak
                })
                .collect();
            let slope = (peaks[1] as f64 - peaks[0] as f64) / (sizes[1] - sizes[0]) as f64;
            println!(
                "{:<10} {:<12} {:>12.1} {:>12.1} {:>10.1}",
                run,
                name,
                mb(peaks[0]),
                mb(peaks[1]),
                slope
            );
        }
    }
}
