//! `predict` on plans (rows without a measured bias), the per-seek integrator start value,
//! streaming through stdin/stdout, and the allocation-free `Predictor`.

use crate::common::{biasctl, data, fails_with, ok, write};
use biasctl::{CheckedFitOptions, ColumnMap, Log, ModelSpec, Predictor, fit};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::Path;

/// Counts allocations per thread, so that tests running in parallel do not disturb each other.
struct Counting;

thread_local! {
    static ALLOCS: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: forwards every call to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> u64 {
    ALLOCS.with(Cell::get)
}

/// Simulates a training log (calibration sequence) and a test log (random seeks) on the drive
/// with a temperature covariate; returns their paths.
pub(crate) fn logs(dir: &Path) -> (String, String) {
    let drive = data("drive_temperature.toml");
    let train = dir.join("train.csv").display().to_string();
    let test = dir.join("test.csv").display().to_string();
    ok(&[
        "simulate",
        "--sequence",
        "calibration",
        "--seed",
        "1",
        "--drive",
        &drive,
        "--out",
        &train,
    ]);
    ok(&[
        "simulate",
        "--sequence",
        "random",
        "--n",
        "400",
        "--seed",
        "2",
        "--drive",
        &drive,
        "--out",
        &test,
    ]);
    (train, test)
}

fn fit_cli(dir: &Path, train: &str, terms: &str, name: &str) -> String {
    let out = dir.join(name).display().to_string();
    ok(&["fit", "--data", train, "--terms", terms, "--out", &out]);
    out
}

/// The CSV text without `#` lines, split into header and rows of cells.
fn table(text: &str) -> (Vec<String>, Vec<Vec<String>>) {
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    (header, rows)
}

pub(crate) fn column(text: &str, name: &str) -> Vec<String> {
    let (h, rows) = table(text);
    let i = h
        .iter()
        .position(|c| c == name)
        .unwrap_or_else(|| panic!("no {name} in {h:?}"));
    rows.into_iter().map(|r| r[i].clone()).collect()
}

/// The log with the bias column removed (a plan), or with the bias cells of `rows` emptied.
pub(crate) fn edit_log(
    text: &str,
    drop_column: bool,
    empty_rows: std::ops::Range<usize>,
) -> String {
    let mut out = String::new();
    let mut data_row = None::<usize>;
    for line in text.lines() {
        if line.starts_with('#') {
            out += line;
            out.push('\n');
            continue;
        }
        let mut cells: Vec<&str> = line.split(',').collect();
        match data_row {
            None => data_row = Some(0),
            Some(i) => {
                if empty_rows.contains(&i) {
                    cells[2] = "";
                }
                data_row = Some(i + 1);
            }
        }
        if drop_column {
            cells.remove(2);
        }
        out += &cells.join(",");
        out.push('\n');
    }
    out
}

fn predict(model: &str, log: &str, out: &str, extra: &[&str]) -> (String, String) {
    let mut args = vec!["predict", "--model", model, "--data", log, "--out", out];
    args.extend_from_slice(extra);
    let stdout = ok(&args);
    (std::fs::read_to_string(out).unwrap(), stdout)
}

#[test]
fn a_plan_without_bias_is_predicted_exactly_as_the_measured_log() {
    // Reference: the same log with its bias column. Without adaptive terms the prediction
    // depends on no measured bias, so the two `predicted` columns must be identical strings.
    let dir = tempfile::tempdir().unwrap();
    let (train, test) = logs(dir.path());
    let model = fit_cli(
        dir.path(),
        &train,
        "poly2,dahl:4,seek,memory,col:temp_c,bins:dwell_s",
        "m.json",
    );
    let text = std::fs::read_to_string(&test).unwrap();
    let plan = write(dir.path(), "plan.csv", &edit_log(&text, true, 0..0));
    let empty = write(
        dir.path(),
        "empty.csv",
        &edit_log(&text, false, 0..usize::MAX),
    );
    let out = dir.path().join("p.csv").display().to_string();
    let (measured, _) = predict(&model, &test, &out, &[]);
    let (planned, summary) = predict(&model, &plan, &out, &[]);
    let (emptied, _) = predict(&model, &empty, &out, &[]);
    assert_eq!(column(&measured, "predicted").len(), 400);
    assert_eq!(
        column(&planned, "predicted"),
        column(&measured, "predicted")
    );
    assert_eq!(
        column(&emptied, "predicted"),
        column(&measured, "predicted")
    );
    assert!(column(&planned, "residual").iter().all(String::is_empty));
    assert!(column(&measured, "residual").iter().all(|r| !r.is_empty()));
    assert!(
        summary.contains("400 rows predicted")
            && summary.contains("0 scored")
            && summary.contains("400 only predicted"),
        "{summary}"
    );
    // The library's replay takes the plan too (bias column optional there as well).
    let log = Log::read_with(
        Path::new(&plan),
        &ColumnMap::default(),
        biasctl::log::BiasColumn::Optional,
    )
    .unwrap();
    let m = biasctl::FittedModel::load(Path::new(&model)).unwrap();
    let mut p = Predictor::new(&m, &log.schema.covariates).unwrap();
    for (row, want) in log.rows().zip(column(&measured, "predicted")) {
        let got = p
            .step(row.time_s, row.track, &row.covariates.to_vec(), row.bias)
            .unwrap();
        assert_eq!(got.to_string(), want);
    }
}

#[test]
fn measured_history_then_plan_drift_holds_and_predictions_are_causal() {
    let dir = tempfile::tempdir().unwrap();
    let (train, test) = logs(dir.path());
    let model = fit_cli(
        dir.path(),
        &train,
        "poly2,direction,seek,memory,drift",
        "cal.json",
    );
    let text = std::fs::read_to_string(&test).unwrap();
    // Rows 0..250 measured, 250..400 a plan (bias empty).
    let mixed = write(dir.path(), "mixed.csv", &edit_log(&text, false, 250..400));
    let out = dir.path().join("p.csv").display().to_string();
    let (pred, summary) = predict(&model, &mixed, &out, &[]);
    assert!(
        summary.contains("400 rows predicted")
            && summary.contains("250 scored")
            && summary.contains("150 only predicted"),
        "{summary}"
    );
    let drift = column(&pred, "drift");
    let residual = column(&pred, "residual");
    // drift learns on measured rows (it moves), holds over the plan (row 250 is the first
    // prediction after the last measurement; every later row has the same value).
    assert!(drift[1..250].windows(2).any(|w| w[0] != w[1]));
    assert!(
        drift[250..].iter().all(|d| *d == drift[250]),
        "drift moved in the plan"
    );
    assert!(residual[..250].iter().all(|r| !r.is_empty()));
    assert!(residual[250..].iter().all(String::is_empty));
    // Causality: changing row 100's bias changes no prediction up to and including row 100.
    let (h, _) = table(&text);
    assert_eq!(h[2], "bias");
    let mut changed = String::new();
    let mut i = 0usize;
    for line in text.lines() {
        if line.starts_with('#') || line.starts_with("time_s") {
            changed += line;
        } else {
            let mut c: Vec<String> = line.split(',').map(str::to_string).collect();
            if i == 100 {
                c[2] = "999.0000".into();
            }
            i += 1;
            changed += &c.join(",");
        }
        changed.push('\n');
    }
    let changed = write(dir.path(), "changed.csv", &changed);
    let (a, _) = predict(&model, &test, &out, &[]);
    let (b, _) = predict(&model, &changed, &out, &[]);
    let (pa, pb) = (column(&a, "predicted"), column(&b, "predicted"));
    assert_eq!(pa[..=100], pb[..=100]);
    assert_ne!(
        pa[101], pb[101],
        "drift should react to the changed measurement"
    );
}

#[test]
fn a_plan_without_a_covariate_the_model_needs_fails_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let (train, _) = logs(dir.path());
    let model = fit_cli(dir.path(), &train, "poly2,col:temp_c", "m.json");
    let plan = write(dir.path(), "plan.csv", "time_s,track\n0,100\n0.1,200\n");
    let out = dir.path().join("p.csv").display().to_string();
    fails_with(
        &["predict", "--model", &model, "--data", &plan, "--out", &out],
        &["col:temp_c", "`temp_c`"],
    );
    assert!(!Path::new(&out).exists(), "half-written output");
    // A bad cell in a plan names file, line and column.
    let bad = write(
        dir.path(),
        "bad.csv",
        "time_s,track,temp_c\n0,100,25\n0.1,x,25\n",
    );
    fails_with(
        &["predict", "--model", &model, "--data", &bad, "--out", &out],
        &["bad.csv", "line 3, column 2 (`track`)"],
    );
    assert!(!Path::new(&out).exists(), "half-written output");
    // --handoff with an unknown preset names it.
    let ok_plan = write(dir.path(), "ok.csv", "time_s,track,temp_c\n0,100,25\n");
    fails_with(
        &[
            "predict",
            "--model",
            &model,
            "--data",
            &ok_plan,
            "--out",
            &out,
            "--handoff",
            "nope",
        ],
        &["nope"],
    );
}

#[test]
fn integrator_start_equals_settle_for_the_predicted_bias() {
    // Reference: `biasctl settle --bias B --bias-uncertainty DB --json` for each checked row's
    // predicted bias B and the model's residual_std DB: z_converged + robust.ff.
    let dir = tempfile::tempdir().unwrap();
    let (train, test) = logs(dir.path());
    let model = fit_cli(dir.path(), &train, "poly2,dahl:4,seek", "m.json");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let db = m["fit"]["residual_std"].as_f64().unwrap();
    let text = std::fs::read_to_string(&test).unwrap();
    let plan = write(dir.path(), "plan.csv", &edit_log(&text, true, 0..0));
    let out = dir.path().join("p.csv").display().to_string();
    for handoff in ["paper1997".to_string(), data("plant_modern.toml")] {
        let (pred, _) = predict(&model, &plan, &out, &["--handoff", &handoff]);
        let predicted = column(&pred, "predicted");
        let start = column(&pred, "integrator_start");
        let plant_flag = if handoff.ends_with(".toml") {
            "--plant"
        } else {
            "--preset"
        };
        for i in [0usize, 57, 399] {
            let b = predicted[i].clone();
            let db = db.to_string();
            let js = ok(&[
                "settle",
                plant_flag,
                &handoff,
                "--bias",
                &b,
                "--bias-uncertainty",
                &db,
                "--json",
            ]);
            let r: serde_json::Value = serde_json::from_str(&js).unwrap();
            let want = r["z_converged"].as_f64().unwrap() + r["robust"]["ff"].as_f64().unwrap();
            let got: f64 = start[i].parse().unwrap();
            assert!(
                (got - want).abs() <= 1e-9 * want.abs().max(1.0),
                "{handoff} row {i}: {got} vs settle {want}"
            );
        }
    }
}

#[test]
fn stdin_to_stdout_answers_each_seek_as_it_arrives() {
    use std::io::{BufRead, BufReader, Write};
    use std::process::{Command, Stdio};
    let dir = tempfile::tempdir().unwrap();
    let (train, test) = logs(dir.path());
    let model = fit_cli(
        dir.path(),
        &train,
        "poly2,direction,seek,memory,drift",
        "cal.json",
    );
    let text = std::fs::read_to_string(&test).unwrap();
    // Reference: the same log read from a file.
    let out = dir.path().join("p.csv").display().to_string();
    let (from_file, _) = predict(&model, &test, &out, &[]);
    let mut child = Command::new(env!("CARGO_BIN_EXE_biasctl"))
        .args(["predict", "--model", &model, "--data", "-", "--out", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel::<String>();
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            if tx.send(line.unwrap()).is_err() {
                break;
            }
        }
    });
    let wait = std::time::Duration::from_secs(20);
    let mut lines = text.lines();
    let mut got = Vec::new();
    // Metadata and header: the CSV header arrives before any row is sent.
    for l in lines.by_ref() {
        writeln!(stdin, "{l}").unwrap();
        if l.starts_with("time_s") {
            break;
        }
    }
    stdin.flush().unwrap();
    got.push(rx.recv_timeout(wait).expect("header not flushed"));
    // Each row's answer arrives before the next row is written.
    for l in lines.take(20) {
        writeln!(stdin, "{l}").unwrap();
        stdin.flush().unwrap();
        got.push(
            rx.recv_timeout(wait)
                .expect("row not answered before the next was sent"),
        );
    }
    drop(stdin);
    let status = child.wait().unwrap();
    reader.join().unwrap();
    assert!(status.success());
    let want: Vec<&str> = from_file.lines().take(21).collect();
    assert_eq!(got, want);
    // A bad row on stdin names `<stdin>` with its line and column, exit 2.
    let r = {
        let mut c = Command::new(env!("CARGO_BIN_EXE_biasctl"))
            .args(["predict", "--model", &model, "--data", "-", "--out", "-"])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        c.stdin
            .take()
            .unwrap()
            .write_all(b"time_s,track,temp_c\n0,100,25\n0.1,nan,25\n")
            .unwrap();
        c.wait_with_output().unwrap()
    };
    assert_eq!(r.status.code(), Some(2));
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("<stdin>: line 3, column 2 (`track`)"), "{err}");
    // Every command that reads a log takes `-`.
    let mut c = Command::new(env!("CARGO_BIN_EXE_biasctl"))
        .args(["check", "--data", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    c.stdin.take().unwrap().write_all(text.as_bytes()).unwrap();
    let o = c.wait_with_output().unwrap();
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("400"));
    let _ = biasctl;
}

#[test]
fn predictor_step_and_peek_allocate_nothing() {
    // Reference: a counting global allocator (per thread). Every built-in term kind is in the
    // model, including the adaptive `drift` and the covariate and bins terms.
    let dir = tempfile::tempdir().unwrap();
    let (train, test) = logs(dir.path());
    let train = Log::read(Path::new(&train), &ColumnMap::default()).unwrap();
    let test = Log::read(Path::new(&test), &ColumnMap::default()).unwrap();
    let spec = ModelSpec::parse(
        "table:250,direction,seek,memory,drift,dahl:4,col:temp_c,bins:dwell_s,dbins:rest_distance_id",
    )
    .unwrap();
    let model = fit(&spec, &train, &CheckedFitOptions::default()).unwrap();
    let mut p = Predictor::new(&model, &test.schema.covariates).unwrap();
    let mut sum = 0.0;
    let mut cov = Vec::with_capacity(test.schema.covariates.len());
    let before = allocations();
    for row in test.rows() {
        let c = row.covariates.gather(&mut cov);
        sum += p.peek(row.time_s, row.track + 7.0, c).unwrap_or(f64::NAN);
        sum += p
            .step(row.time_s, row.track, c, row.bias)
            .unwrap_or(f64::NAN);
        sum += p.step(row.time_s, row.track, c, None).unwrap_or(f64::NAN);
    }
    let after = allocations();
    assert!(sum.is_finite());
    assert_eq!(after - before, 0, "Predictor::step/peek allocated");
    // The counter works: a Vec allocates.
    let v = std::hint::black_box(vec![1u8; 3]);
    assert!(allocations() > after && v.len() == 3);
}

/// Reference: the covariate names given to `Predictor::new`. Fewer (or more) covariate values
/// than names is an error, not a value read as 0, and a refused step leaves the state as it
/// was (the next prediction equals a fresh predictor's).
#[test]
fn predictor_refuses_another_number_of_covariate_values() {
    let mut text = String::from("time_s,track,bias,temp_c\n");
    for i in 0..80u32 {
        let x = f64::from((i * 397) % 1999);
        let t = 20.0 + f64::from(i % 7);
        text += &format!("{i},{x},{},{t}\n", 0.01 * x + 2.0 * t);
    }
    let log = Log::from_reader("c.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
    let spec = ModelSpec::parse("poly2,col:temp_c").unwrap();
    let model = fit(&spec, &log, &CheckedFitOptions::default()).unwrap();
    let mut p = Predictor::new(&model, &log.schema.covariates).unwrap();
    let e = p.peek(0.0, 25.0, &[]).unwrap_err().to_string();
    assert_eq!(
        e,
        "0 covariate values given, but the predictor was made with 1 covariate names: pass one \
         value per name, in their order"
    );
    assert!(p.peek(0.0, 25.0, &[20.0, 1.0]).is_err());
    assert!(p.step(0.0, 25.0, &[], Some(1.0)).is_err());
    let fresh = Predictor::new(&model, &log.schema.covariates).unwrap();
    let (a, b) = (
        p.peek(0.0, 25.0, &[21.0]).unwrap(),
        fresh.peek(0.0, 25.0, &[21.0]).unwrap(),
    );
    assert_eq!(a.to_bits(), b.to_bits());
    // The value is the model's: 2·temp_c at the fitted coefficient, not temp_c read as 0.
    assert!(
        (a - fresh.peek(0.0, 25.0, &[0.0]).unwrap() - 42.0).abs() < 1e-6,
        "{a}"
    );
}

/// Reference: the unit labels given at fit. The model file records the units it was fitted in;
/// reading a log in others for it is refused naming the flag, and a model fitted with
/// `--bias-unit N` scores in N without the flag.
#[test]
fn a_model_file_records_its_units_and_refuses_others() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    let log = write(dir.path(), "l.csv", &crate::common::log_text(1.0));
    ok(&[
        "fit",
        "--data",
        &log,
        "--model",
        "position-direction",
        "--out",
        &p("m.json"),
    ]);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(p("m.json")).unwrap()).unwrap();
    assert_eq!(
        json["columns"]["units"],
        serde_json::json!({"bias": "counts", "position": "tracks"})
    );
    fails_with(
        &[
            "score",
            "--model",
            &p("m.json"),
            "--data",
            &log,
            "--bias-unit",
            "N",
        ],
        &[
            "the model was fitted with bias in `counts`, but this log's bias is in `N` (--bias-unit)",
        ],
    );
    fails_with(
        &[
            "predict",
            "--model",
            &p("m.json"),
            "--data",
            &log,
            "--track-unit",
            "mm",
            "--out",
            &p("p.csv"),
        ],
        &["position in `tracks`", "(--track-unit)"],
    );
    let rig = write(
        dir.path(),
        "r.csv",
        &crate::common::log_text(1.0).replacen("time_s,track,bias", "time_s,x_mm,force_N", 1),
    );
    let cols = ["--track-col", "x_mm", "--bias-col", "force_N"];
    let mut args = vec!["fit", "--data", &rig, "--model", "position-direction"];
    args.extend(cols);
    let out = p("r.json");
    args.extend(["--bias-unit", "N", "--out", &out]);
    ok(&args);
    let mut args = vec!["score", "--model", &out, "--data", &rig];
    args.extend(cols);
    let text = ok(&args);
    assert!(
        text.contains(" N") && !text.contains("force_N,") && !text.contains(" force_N"),
        "{text}"
    );
}
