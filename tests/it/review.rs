//! Regressions from a first-use review: inputs a user tries that broke the README's contract
//! (exit 2 with a message, no panic, no NaN/inf in outputs, nothing half-written).

use crate::common::{biasctl, fails_with, ok, write};
use std::fmt::Write as _;
use std::process::{Command, Stdio};

/// A small log with 60 measured rows spread over the stroke; `bias_scale` multiplies the bias.
fn log_text(bias_scale: f64) -> String {
    let mut s = String::from("time_s,track,bias\n");
    for i in 0..60u32 {
        let track = (i * 397) % 2999;
        let bias =
            (30.0 + 0.01 * f64::from(track) + if i % 2 == 0 { 5.0 } else { -5.0 }) * bias_scale;
        s.push_str(&format!("{:.1},{track},{bias}\n", f64::from(i) * 0.1));
    }
    s
}

fn no_nonfinite(text: &str, what: &str) {
    for cell in text.split([',', '\n', ' ', '"', ':']) {
        let c = cell.trim().to_ascii_lowercase();
        assert!(
            !matches!(c.as_str(), "nan" | "inf" | "-inf" | "+inf" | "infinity"),
            "{what} holds a non-finite value `{cell}`"
        );
    }
}

#[test]
fn settle_bounds_csv_has_no_infinities() {
    let dir = tempfile::tempdir().unwrap();
    let bounds = dir.path().join("b.csv").display().to_string();
    let resp = dir.path().join("r.csv").display().to_string();
    ok(&["settle", "--bounds-out", &bounds, "--response-out", &resp]);
    let b = std::fs::read_to_string(&bounds).unwrap();
    no_nonfinite(&b, "bounds CSV");
    // k = 0 has no bound: empty cells, and the row keeps its six fields.
    let row0 = b.lines().nth(1).unwrap();
    assert_eq!(row0, "0,0.0000000,,,,", "{row0}");
    no_nonfinite(&std::fs::read_to_string(&resp).unwrap(), "responses CSV");
}

#[test]
fn printing_into_a_closed_pipe_does_not_panic() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_biasctl"))
        .args(["settle", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // the reader goes away before biasctl prints
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert_ne!(out.status.code(), Some(101), "{stderr}");
}

#[test]
fn one_column_cannot_be_two_roles() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(dir.path(), "log.csv", &log_text(1.0));
    let out = dir.path().join("m.json");
    fails_with(
        &[
            "fit",
            "--data",
            &f,
            "--bias-col",
            "time_s",
            "--model",
            "position-direction",
            "--out",
            &out.display().to_string(),
        ],
        &["--time-col", "--bias-col", "`time_s`"],
    );
    assert!(!out.exists());
    fails_with(
        &["check", "--data", &f, "--track-col", "bias"],
        &["--track-col", "--bias-col", "`bias`"],
    );
}

#[test]
fn fit_that_overflows_fails_instead_of_writing_nan() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(dir.path(), "huge.csv", &log_text(1e300));
    let out = dir.path().join("m.json");
    let err = fails_with(
        &[
            "fit",
            "--data",
            &f,
            "--model",
            "position-direction",
            "--out",
            &out.display().to_string(),
        ],
        // The reader now refuses such values (issue #17: finite in, finite out) before the
        // fit could overflow.
        &["huge.csv", "line 2", "outside ±1e15"],
    );
    assert!(!err.contains("NaN"), "{err}");
    assert!(!out.exists(), "a model file was written");
}

#[test]
fn report_rejects_too_few_or_too_many_seeks_before_writing_anything() {
    let dir = tempfile::tempdir().unwrap();
    for n in ["1", "49", "1000001"] {
        let out = dir.path().join(format!("r{n}"));
        fails_with(
            &["report", "--seeks", n, "--out", &out.display().to_string()],
            &["--seeks", "50"],
        );
        assert!(!out.exists(), "--seeks {n} left {}", out.display());
    }
    let out = dir.path().join("demo");
    fails_with(
        &["demo", "--seeks", "10", "--out", &out.display().to_string()],
        &["--seeks"],
    );
    assert!(!out.exists());
}

#[test]
fn settle_text_says_when_zero_feedforward_does_not_settle() {
    let out = ok(&["settle", "--horizon", "5"]);
    assert!(
        out.contains("zero feedforward: does not settle within the horizon"),
        "{out}"
    );
    assert!(!out.contains("settles in not settled"), "{out}");
}

#[test]
fn an_error_cause_is_not_printed_twice() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(dir.path(), "log.csv", &log_text(1.0));
    // A folder that does not exist is now refused before the fit (`first_use`); a write the
    // operating system refuses in an existing folder (/proc takes no new file) still reaches the
    // writer's error and its cause.
    let out = std::path::Path::new("/proc/m.json");
    let err = fails_with(
        &[
            "fit",
            "--data",
            &f,
            "--model",
            "position-direction",
            "--out",
            &out.display().to_string(),
        ],
        &["cannot write", "m.json"],
    );
    assert_eq!(err.matches("No such file").count(), 1, "{err}");
}

#[test]
fn report_summary_says_when_the_users_model_could_not_be_scored() {
    let dir = tempfile::tempdir().unwrap();
    let mut with_cov = String::from("time_s,track,bias,temp_c\n");
    for (i, line) in log_text(1.0).lines().skip(1).enumerate() {
        writeln!(with_cov, "{line},{}", 20.0 + 0.1 * i as f64).unwrap();
    }
    let train = write(dir.path(), "train.csv", &with_cov);
    let plain = write(dir.path(), "plain.csv", &log_text(1.0));
    let model = dir.path().join("m.json").display().to_string();
    ok(&[
        "fit",
        "--data",
        &train,
        "--terms",
        "poly2,col:temp_c",
        "--out",
        &model,
    ]);
    let out = dir.path().join("rep").display().to_string();
    let r = biasctl(&["report", "--data", &plain, "--model", &model, "--out", &out]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(
        r.stdout
            .contains("your model (--model) could not be scored"),
        "{}",
        r.stdout
    );
    assert!(
        !r.stdout.contains("no model of yours given"),
        "{}",
        r.stdout
    );
}

#[test]
fn plot_time_rejects_a_track_without_measurements() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(dir.path(), "log.csv", &log_text(1.0));
    for track in ["7", "nan"] {
        let out = dir.path().join(format!("t{track}.svg"));
        fails_with(
            &[
                "plot",
                "time",
                "--data",
                &f,
                "--track",
                track,
                "--out",
                &out.display().to_string(),
            ],
            &["--track", "no measured row"],
        );
        assert!(
            !out.exists(),
            "an empty figure was written for --track {track}"
        );
    }
    let out = dir.path().join("t.svg").display().to_string();
    ok(&[
        "plot", "time", "--data", &f, "--track", "397", "--out", &out,
    ]);
    fails_with(
        &["plot", "seek", "--data", &f, "--test", &f, "--out", &out],
        &["--test is for `plot ladder`"],
    );
}

/// `diagnose --out` must name a directory: an existing file is refused with that explanation.
#[test]
fn diagnose_out_that_is_a_file_is_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    ok(&[
        "simulate",
        "--sequence",
        "random",
        "--n",
        "200",
        "--seed",
        "5",
        "--out",
        &p("log.csv"),
    ]);
    ok(&[
        "fit",
        "--data",
        &p("log.csv"),
        "--model",
        "position-direction",
        "--out",
        &p("m.json"),
    ]);
    fails_with(
        &[
            "diagnose",
            "--model",
            &p("m.json"),
            "--data",
            &p("log.csv"),
            "--out",
            &p("log.csv"),
        ],
        &["--out", "is a file", "takes a directory"],
    );
}
