//! `biasctl check`: the log format contract and its error messages.

use crate::common::{
    biasctl_stdin, editor_line, fails_with, mixed_line_ends, ok, with_line_ends, write,
};

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
fn check_names_the_physical_line_after_blank_lines_and_in_crlf_files() {
    // Reference: the line an editor shows, counted by hand (1 + the `\n` before the bad row),
    // for a file and for standard input.
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            "time_s,track,bias\n0,1,2\n\n\n1,x,2\n",
            "line 5, column 2 (`track`)",
        ),
        (
            "time_s,track,bias\r\n0,1,2\r\n1,2,2\r\n2,3,NaN\r\n",
            "line 4, column 3 (`bias`)",
        ),
        (
            "time_s,track,bias,note\n0,1,2,\"a\nb\"\n1,x,2,c\n",
            "line 4, column 2 (`track`)",
        ),
    ];
    for (i, (text, want)) in cases.iter().enumerate() {
        let f = write(dir.path(), &format!("bad{i}.csv"), text);
        let name = format!("bad{i}.csv: {want}");
        fails_with(&["check", "--data", &f], &[&name]);
        if text.contains('"') {
            // Standard input has no look-ahead: the text column `note` fails at its first
            // cell (line 2) before the bad row; the file's case is the one for this count.
            continue;
        }
        let r = biasctl_stdin(&["check", "--data", "-"], text.as_bytes());
        assert_eq!(r.code, 2, "{}", r.stderr);
        assert!(
            r.stderr.contains(&format!("<stdin>: {want}")),
            "{}",
            r.stderr
        );
    }
}

#[test]
fn check_names_the_same_line_an_editor_shows_whatever_the_line_ends() {
    // Reference: the line of the bad cell `x` counted in the raw text (`editor_line`: `\r\n`,
    // `\n` and a lone `\r` each end a line). Each text is written with LF, CRLF, lone-CR (old
    // Mac, as Excel's "CSV (Macintosh)") and mixed line ends, read from a file and from
    // standard input: the same line each time, exit 2.
    let dir = tempfile::tempdir().unwrap();
    let cases: &[(&str, &str)] = &[
        (
            "time_s,track,bias\n0,1,2\n1,2,2\n2,x,2\n",
            "column 2 (`track`)",
        ),
        (
            "time_s,track,bias\n0,1,2\n\n\n1,x,2\n",
            "column 2 (`track`)",
        ),
        (
            "# rig 4\n\n# a\ntime_s,track,bias\n\n0,1,2\n1,2,x\n",
            "column 3 (`bias`)",
        ),
        (
            "time_s,track,bias,note\n0,1,2,\"a\nb\"\n1,x,2,c\n",
            "column 2 (`track`)",
        ),
    ];
    let mut k = 0;
    for (text, want) in cases {
        let mut lines = Vec::new();
        for text in [
            text.to_string(),
            with_line_ends(text, "\r\n"),
            with_line_ends(text, "\r"),
            mixed_line_ends(text),
        ] {
            let line = editor_line(&text, text.find('x').unwrap());
            lines.push(line);
            k += 1;
            let name = format!("bad{k}.csv");
            let f = write(dir.path(), &name, &text);
            fails_with(
                &["check", "--data", &f],
                &[&format!("{name}: line {line}, {want}")],
            );
            if text.contains('"') {
                // Standard input has no look-ahead: the text column fails first (see above).
                continue;
            }
            let r = biasctl_stdin(&["check", "--data", "-"], text.as_bytes());
            assert_eq!(r.code, 2, "{text:?}: {}", r.stderr);
            assert!(
                r.stderr.contains(&format!("<stdin>: line {line}, {want}")),
                "{text:?}: {}",
                r.stderr
            );
        }
        // LF, CRLF and lone CR keep every line: the same line number each way.
        assert!(
            lines[..3].iter().all(|&l| l == lines[0]),
            "{text:?}: {lines:?}"
        );
    }
}

#[test]
fn a_lone_cr_log_larger_than_the_line_limit_reads() {
    // A 1M-row log is tens of MB: with lone-CR line ends (no `\n` anywhere) it is still made of
    // short lines, not one line over the 1 MiB limit. Reference: the rows written.
    let dir = tempfile::tempdir().unwrap();
    let mut rows = String::new();
    for i in 0..100_000 {
        rows.push_str(&format!("{i},{},1.5\r", i % 1000));
    }
    assert!(rows.len() > 1 << 20);
    // All lone CR, and a plain (`\n`) start handing over to lone-CR rows.
    for (name, head) in [
        ("mac.csv", "# rig 4\rtime_s,track,bias\r"),
        ("mixed.csv", "# rig 4\ntime_s,track,bias\n"),
    ] {
        let f = write(dir.path(), name, &format!("{head}{rows}"));
        let out = ok(&["check", "--data", &f]);
        assert!(
            out.contains("100000 rows, 100000 measured"),
            "{name}: {out}"
        );
    }
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

/// Every CSV biasctl writes reads back with its own `check`: the simulated log and its truth,
/// `predict`'s output (with a covariate named `temp,C`, which must be quoted), and the settle
/// responses. Reference: the covariate names `check` lists equal the ones written.
#[test]
fn every_written_csv_reads_back_with_check() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    ok(&[
        "simulate",
        "--sequence",
        "random",
        "--n",
        "120",
        "--seed",
        "3",
        "--out",
        &p("sim.csv"),
        "--truth",
        &p("truth.csv"),
    ]);
    ok(&["check", "--data", &p("sim.csv")]);
    ok(&[
        "check",
        "--data",
        &p("truth.csv"),
        "--bias-col",
        "bias_true",
    ]);
    // A log with a covariate whose name holds a comma (quoted in the input).
    let mut text = String::from("time_s,track,bias,\"temp,C\"\n");
    for i in 0..60 {
        let x = (i * 37 % 200) as f64;
        text.push_str(&format!(
            "{},{x},{},{}\n",
            i as f64 * 0.2,
            10.0 + 0.1 * x,
            20 + i % 7
        ));
    }
    let log = write(dir.path(), "c.csv", &text);
    ok(&[
        "fit",
        "--data",
        &log,
        "--terms",
        "poly2",
        "--out",
        &p("m.json"),
    ]);
    ok(&[
        "predict",
        "--model",
        &p("m.json"),
        "--data",
        &log,
        "--out",
        &p("pred.csv"),
    ]);
    let pred = std::fs::read_to_string(p("pred.csv")).unwrap();
    assert!(
        pred.starts_with("time_s,track,bias,\"temp,C\",predicted,residual"),
        "{pred}"
    );
    let out = ok(&["check", "--data", &p("pred.csv")]);
    assert!(
        out.contains("covariates: temp,C, predicted, residual"),
        "{out}"
    );
    ok(&[
        "settle",
        "--bounds-out",
        &p("b.csv"),
        "--response-out",
        &p("r.csv"),
    ]);
    // The bounds file has empty cells where no bound exists (k = 0), which `check` refuses in
    // a covariate column; its quoting is the same writer's, tested here through its header.
    let b = std::fs::read_to_string(p("b.csv")).unwrap();
    assert!(
        b.starts_with("k,time_s,upper,lower,upper_min,lower_max\n0,0.0000000,,,,\n"),
        "{b}"
    );
    ok(&[
        "check",
        "--data",
        &p("r.csv"),
        "--track-col",
        "k",
        "--bias-col",
        "e_zero_ff_um",
    ]);
}

/// The dialects a spreadsheet or a European rig writes: `;` with decimal commas, tabs, header
/// case and spaces, a notes column, Excel's trailing comma; `--delimiter` forces one.
#[test]
fn check_reads_spreadsheet_dialects_with_notes() {
    let dir = tempfile::tempdir().unwrap();
    let semi = write(
        dir.path(),
        "s.csv",
        "time_s;track;bias\n0;1;2,5\n0,5;3;4,25\n",
    );
    let out = ok(&["check", "--data", &semi]);
    assert!(
        out.contains("2 rows, 2 measured") && out.contains("semicolon"),
        "{out}"
    );
    let messy = write(
        dir.path(),
        "m.csv",
        " Time_S ,TRACK,Bias,notes,\n0,1,2,start,\n1,2,3,,\n",
    );
    let out = ok(&["check", "--data", &messy]);
    assert!(
        out.contains("`notes`) is not numeric (line 2: `start`); skipped"),
        "{out}"
    );
    assert!(!out.contains("covariates"), "{out}");
    fails_with(
        &["check", "--data", &semi, "--delimiter", ","],
        &["missing required column `time_s`"],
    );
    fails_with(
        &["check", "--data", &semi, "--delimiter", "|"],
        &["--delimiter"],
    );
    fails_with(
        &["check", "--data", &semi, "--bias-col", "bais"],
        &["did you mean `bias`?"],
    );
}

/// `check` reads a log in several passes (constant memory): the later passes read a temporary
/// file of every row's time and position (a file is read again when no temporary file can be
/// made). Reference: the in-memory summary of the same rows
/// (`biasctl::sampling` over every row, as `check` computed it before) gives the same lines,
/// and the file and standard input give the same output but for the name, on a dense time
/// series (regular clock: the deadband pass) and a random seek log.
#[test]
fn check_reads_a_file_and_stdin_alike_and_matches_the_in_memory_sampling() {
    use std::process::{Command, Stdio};
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("time_s,track,bias\n");
    let (mut t, mut x) = (Vec::new(), Vec::new());
    let mut state = 7u64;
    for i in 0..20_000 {
        // A slow sine with uniform noise from a fixed LCG (deterministic).
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let noise = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        let ti = i as f64 * 1e-3;
        let xi = 100.0 * (0.001 * i as f64).sin() + 0.1 * noise;
        text.push_str(&format!("{ti},{xi},1\n"));
        t.push(ti);
        x.push(xi);
    }
    let dense = write(dir.path(), "dense.csv", &text);
    let seek = dir.path().join("seek.csv").display().to_string();
    ok(&crate::common::simulate_random_args("3000", "4", &seek));
    for (f, dense_log) in [(&dense, true), (&seek, false)] {
        let from_file = ok(&["check", "--data", f]);
        let out = Command::new(env!("CARGO_BIN_EXE_biasctl"))
            .args(["check", "--data", "-"])
            .stdin(std::fs::File::open(f).unwrap())
            .stderr(Stdio::piped())
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let from_stdin = String::from_utf8(out.stdout).unwrap();
        let rest = |s: &str| s.lines().skip(1).map(String::from).collect::<Vec<_>>();
        assert_eq!(rest(&from_file), rest(&from_stdin), "{f}");
        assert!(from_stdin.starts_with("<stdin>: "), "{from_stdin}");
        assert_eq!(
            from_file.contains("mode: dense time series"),
            dense_log,
            "{from_file}"
        );
    }
    // Without a usable temporary folder a file is read again for the later passes (the same
    // output); standard input cannot be, and says what it needs (exit 2, nothing on stdout).
    let no_tmp = |args: &[&str], stdin: Stdio| {
        Command::new(env!("CARGO_BIN_EXE_biasctl"))
            .args(args)
            .env("TMPDIR", dir.path().join("missing"))
            .stdin(stdin)
            .output()
            .unwrap()
    };
    for f in [&dense, &seek] {
        let out = no_tmp(&["check", "--data", f], Stdio::null());
        assert!(out.status.success(), "{out:?}");
        assert_eq!(
            String::from_utf8(out.stdout).unwrap(),
            ok(&["check", "--data", f])
        );
    }
    let out = no_tmp(
        &["check", "--data", "-"],
        Stdio::from(std::fs::File::open(&seek).unwrap()),
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        out.stdout.is_empty() && err.contains("<stdin>") && err.contains("TMPDIR"),
        "{err}"
    );
    // The rows as written (Rust's float formatting reads back to the same bits).
    let want = biasctl::sampling(&t, &x).describe("tracks");
    let got = ok(&["check", "--data", &dense]);
    for line in want {
        assert!(got.contains(&format!("  {line}\n")), "{line}\n{got}");
    }
}
