//! `biasctl check`: the log format contract and its error messages.

use crate::common::{fails_with, ok, write};

#[test]
fn check_summarises_a_valid_log_with_renamed_columns() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(
        dir.path(),
        "rig.csv",
        "# rig 4\nt,pos_m,force_N,temp_c\n0,0.1,2,20\n0.1,0.2,,21\n",
    );
    let out = ok(&[
        "check",
        "--data",
        &f,
        "--time-col",
        "t",
        "--track-col",
        "pos_m",
        "--bias-col",
        "force_N",
    ]);
    assert!(out.contains("2 rows, 1 measured"), "{out}");
    assert!(out.contains("covariates: temp_c"), "{out}");
}

#[test]
fn check_reports_line_and_column_of_bad_values_with_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let f = write(dir.path(), "bad.csv", "time_s,track,bias\n0,1,2\n1,2,NaN\n");
    fails_with(
        &["check", "--data", &f],
        &[
            "bad.csv",
            "line 3",
            "column 3",
            "`bias`",
            "not a finite number",
        ],
    );
    let g = write(dir.path(), "nocol.csv", "time_s,track\n0,1\n");
    fails_with(
        &["check", "--data", &g],
        &["missing required column `bias`", "--bias-col"],
    );
    fails_with(
        &["check", "--data", "/nonexistent/x.csv"],
        &["/nonexistent/x.csv", "cannot read"],
    );
}

/// `biasctl … | head`: when the reader closes the pipe early the command must end quietly
/// (killed by SIGPIPE like other Unix tools), not panic with "Broken pipe".
#[cfg(unix)]
#[test]
fn closed_stdout_pipe_ends_quietly() {
    use std::io::Read;
    use std::process::{Command, Stdio};
    let mut child = Command::new(env!("CARGO_BIN_EXE_biasctl"))
        .args(["settle", "--preset", "paper1997", "--json"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // the reader goes away before anything is read
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    child.wait().unwrap();
    assert!(!err.contains("panicked"), "{err}");
}
