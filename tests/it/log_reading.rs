//! Reading a log: `biasctl check`, the log format contract and its error messages, column
//! roles, spreadsheet dialects, and the units of bias and position that travel with the log.

use crate::common::{
    biasctl_stdin, editor_line, fails_with, log_text, mixed_line_ends, ok, real_data,
    skip_without_real_data, with_line_ends, write,
};
use std::path::Path;

// ---- check: the log format contract and its error messages

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
/// (`biasctl::history::sampling` over every row, as `check` computed it before) gives the same lines,
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
    let want = biasctl::history::sampling(&t, &x).describe("tracks");
    let got = ok(&["check", "--data", &dense]);
    for line in want {
        assert!(got.contains(&format!("  {line}\n")), "{line}\n{got}");
    }
}

// ---- units of bias and position: metadata, column names, flags, every output

const EMPS: &str = "emps/emps_estimation.csv";

fn need(rel: &str) -> String {
    real_data(rel).unwrap_or_else(|| panic!("real data `{rel}` missing in the real-data folder"))
}

/// `args` followed by the EMPS column flags and `units`.
fn with_cols<'a>(args: &[&'a str], units: &[&'a str]) -> Vec<&'a str> {
    let mut v = args.to_vec();
    v.extend(["--track-col", "position_m", "--bias-col", "force_N"]);
    v.extend(units);
    v
}

/// The position-direction model fitted on EMPS, written to `dir/pd.json`; returns its path and
/// the fit's stdout.
fn fit_emps(dir: &Path, units: &[&str]) -> (String, String) {
    let data = need(EMPS);
    let model = dir.join("pd.json").display().to_string();
    let out = ok(&with_cols(
        &[
            "fit",
            "--data",
            &data,
            "--model",
            "position-direction",
            "--out",
            &model,
        ],
        units,
    ));
    (model, out)
}

/// The text of the `<text class="{class}">` elements of an SVG.
fn svg_texts(svg: &str, class: &str) -> Vec<String> {
    let doc = roxmltree::Document::parse(svg).expect("SVG parses");
    doc.descendants()
        .filter(|n| n.has_tag_name("text") && n.attribute("class") == Some(class))
        .filter_map(|n| n.text().map(str::to_string))
        .collect()
}

fn no_simulator_units(what: &str, text: &str) {
    assert!(
        !text.contains("counts") && !text.contains("tracks"),
        "{what} says counts or tracks:\n{text}"
    );
}

/// Without a unit flag or metadata, a renamed column's name is its unit: EMPS's force in
/// `force_N` and position in `position_m`, never counts and tracks.
#[test]
fn emps_without_flags_is_labelled_by_its_columns() {
    if skip_without_real_data() {
        return;
    }
    let data = need(EMPS);
    let dir = tempfile::tempdir().unwrap();
    let (model, fit_out) = fit_emps(dir.path(), &[]);
    assert!(fit_out.contains(" force_N, R² "), "{fit_out}");
    let check = ok(&with_cols(&["check", "--data", &data], &[]));
    assert!(
        check.contains(" position_m (column position_m)")
            && check.contains("bias in force_N (column force_N)"),
        "{check}"
    );
    let score = ok(&with_cols(
        &["score", "--model", &model, "--data", &data],
        &[],
    ));
    assert!(
        score.contains(" force_N\nrms ") && score.contains(" force_N/position_m, t "),
        "{score}"
    );
    no_simulator_units("score", &score);
    let json: serde_json::Value = serde_json::from_str(&ok(&with_cols(
        &["score", "--model", &model, "--data", &data, "--json"],
        &[],
    )))
    .unwrap();
    assert_eq!(
        json["units"],
        serde_json::json!({"bias": "force_N", "position": "position_m"})
    );
}

/// `--bias-unit N --track-unit m`: score and diagnose speak newtons and metres, as text and JSON.
#[test]
fn emps_with_unit_flags_says_newtons_and_metres() {
    if skip_without_real_data() {
        return;
    }
    let data = need(EMPS);
    let dir = tempfile::tempdir().unwrap();
    let flags = ["--bias-unit", "N", "--track-unit", "m"];
    let (model, fit_out) = fit_emps(dir.path(), &flags);
    assert!(fit_out.contains(" N, R² "), "{fit_out}");
    let score = ok(&with_cols(
        &["score", "--model", &model, "--data", &data],
        &flags,
    ));
    assert!(
        score.contains(" N\nstd ") && score.contains(" N/m, t "),
        "{score}"
    );
    no_simulator_units("score", &score);
    let diag = ok(&with_cols(
        &[
            "diagnose",
            "--model",
            &model,
            "--data",
            &data,
            "--permutations",
            "99",
            "--path",
            "1",
        ],
        &flags,
    ));
    assert!(diag.contains("Residual std: 39.1 N\n"), "{diag}");
    // The advice sentence and the path step carry the unit too.
    assert!(diag.contains(" N (from 39.1)."), "{diag}");
    let step = diag
        .lines()
        .find(|l| l.contains("→ add `col:accel_m_s2`: residual std"))
        .unwrap_or_else(|| panic!("no path step:\n{diag}"));
    assert!(step.ends_with(" N"), "{step}");
    no_simulator_units("diagnose", &diag);
    let json: serde_json::Value = serde_json::from_str(&ok(&with_cols(
        &[
            "diagnose",
            "--model",
            &model,
            "--data",
            &data,
            "--permutations",
            "99",
            "--json",
        ],
        &flags,
    )))
    .unwrap();
    assert_eq!(
        json["units"],
        serde_json::json!({"bias": "N", "position": "m"})
    );
    no_simulator_units("diagnose summary", json["summary"].as_str().unwrap());
}

/// Plot axes built from a log carry its units.
#[test]
fn emps_plot_axes_carry_the_units() {
    if skip_without_real_data() {
        return;
    }
    let data = need(EMPS);
    let dir = tempfile::tempdir().unwrap();
    let flags = ["--bias-unit", "N", "--track-unit", "m"];
    let svg = |kind: &str, extra: &[&str]| -> String {
        let out = dir.path().join(format!("{kind}.svg")).display().to_string();
        let mut args = vec!["plot", kind, "--data", &data, "--out", &out];
        args.extend(extra);
        ok(&with_cols(&args, &flags));
        std::fs::read_to_string(&out).unwrap()
    };
    let position = svg("position", &["--model", "position-direction"]);
    assert_eq!(svg_texts(&position, "xlabel"), ["position (m)"]);
    assert_eq!(svg_texts(&position, "ylabel"), ["bias (N)"]);
    let seek = svg("seek", &[]);
    assert_eq!(
        svg_texts(&seek, "xlabel"),
        ["signed seek length, + inbound (m)"]
    );
    assert_eq!(svg_texts(&seek, "ylabel"), ["bias (N)"]);
    let errors = svg("errors", &["--model", "position-direction"]);
    let x = svg_texts(&errors, "xlabel");
    assert!(
        x.contains(&"position (m)".to_string())
            && x.contains(&"prediction error, measured − predicted (N)".to_string()),
        "{x:?}"
    );
    assert!(svg_texts(&errors, "ylabel").contains(&"error (N)".to_string()));
    assert!(
        svg_texts(&errors, "title")
            .iter()
            .any(|t| t.contains(" N (n = ")),
        "{:?}",
        svg_texts(&errors, "title")
    );
    let time = svg("time", &[]);
    assert_eq!(svg_texts(&time, "ylabel"), ["bias (N)"]);
    for (name, s) in [
        ("position", &position),
        ("seek", &seek),
        ("errors", &errors),
        ("time", &time),
    ] {
        assert!(
            !s.contains("(counts)") && !s.contains("(tracks)") && !s.contains("counts/"),
            "{name}.svg keeps a simulator unit"
        );
    }
}

/// The simulator writes its units into the log, and everything read from it says counts and
/// tracks.
#[test]
fn simulator_logs_say_counts_and_tracks() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("r.csv").display().to_string();
    ok(&[
        "simulate",
        "--sequence",
        "random",
        "--n",
        "300",
        "--seed",
        "4",
        "--out",
        &log,
    ]);
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(
        text.contains("\n# bias_unit = counts\n# position_unit = tracks\n"),
        "{}",
        &text[..400.min(text.len())]
    );
    let check = ok(&["check", "--data", &log]);
    assert!(
        check.contains(" tracks (column track)") && check.contains("bias in counts"),
        "{check}"
    );
    let model = dir.path().join("m.json").display().to_string();
    ok(&[
        "fit",
        "--data",
        &log,
        "--model",
        "position-direction",
        "--out",
        &model,
    ]);
    let score = ok(&["score", "--model", &model, "--data", &log]);
    assert!(
        score.contains(" counts\nrms ") && score.contains(" counts/track, t "),
        "{score}"
    );
    let diag = ok(&[
        "diagnose",
        "--model",
        &model,
        "--data",
        &log,
        "--permutations",
        "99",
    ]);
    assert!(
        diag.contains("Residual std: ") && diag.contains(" counts\n"),
        "{diag}"
    );
}

/// A log whose metadata names its units is labelled with them without a flag; a flag still
/// wins; the HTML report of `report --data` uses them.
#[test]
fn metadata_units_label_a_log_without_flags() {
    let dir = tempfile::tempdir().unwrap();
    let sim = dir.path().join("sim.csv").display().to_string();
    ok(&[
        "simulate",
        "--sequence",
        "random",
        "--n",
        "400",
        "--seed",
        "6",
        "--out",
        &sim,
    ]);
    let text = std::fs::read_to_string(&sim)
        .unwrap()
        .replace("# bias_unit = counts", "# bias_unit = mA")
        .replace("# position_unit = tracks", "# position_unit = um");
    let log = crate::common::write(dir.path(), "ma.csv", &text);
    let model = dir.path().join("m.json").display().to_string();
    let fit_out = ok(&[
        "fit",
        "--data",
        &log,
        "--model",
        "position-direction",
        "--out",
        &model,
    ]);
    assert!(fit_out.contains(" mA, R² "), "{fit_out}");
    let score = ok(&["score", "--model", &model, "--data", &log]);
    assert!(
        score.contains(" mA\nrms ") && score.contains(" mA/um, t "),
        "{score}"
    );
    no_simulator_units("score", &score);
    let ladder = ok(&[
        "ladder",
        "--data",
        &log,
        "--test",
        &log,
        "--terms",
        "poly2,direction",
    ]);
    assert!(
        ladder.contains("(mA):\n") && ladder.contains(" std (mA) "),
        "{ladder}"
    );
    no_simulator_units("ladder", &ladder);
    // The flag wins over the metadata: a fit reads the bias in `A` …
    let flagged = ok(&[
        "fit",
        "--data",
        &log,
        "--model",
        "position-direction",
        "--bias-unit",
        "A",
        "--out",
        &dir.path().join("a.json").display().to_string(),
    ]);
    assert!(
        flagged.contains(" A, R² ") && !flagged.contains("mA"),
        "{flagged}"
    );
    // … and the mA model refuses a log the flag says is in A, naming the flag.
    crate::common::fails_with(
        &[
            "score",
            "--model",
            &model,
            "--data",
            &log,
            "--bias-unit",
            "A",
        ],
        &["fitted with bias in `mA`", "(--bias-unit)"],
    );
    // The report of the log.
    let out = dir.path().join("rep").display().to_string();
    ok(&["report", "--data", &log, "--out", &out]);
    let html = std::fs::read_to_string(Path::new(&out).join("report.html")).unwrap();
    for want in [
        "bias (mA)",
        "position (um)",
        "units (bias, position)",
        "test error std (mA)",
    ] {
        assert!(html.contains(want), "report.html lacks `{want}`");
    }
    for unwanted in ["(counts)", "(tracks)", "counts/track", " counts "] {
        assert!(!html.contains(unwanted), "report.html says `{unwanted}`");
    }
}

/// A bad unit label exits 2 naming its flag, on every command that reads a log; a bad label in
/// the metadata names the file and the key.
#[test]
fn bad_unit_labels_exit_2_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let log = crate::common::write(dir.path(), "l.csv", "time_s,track,bias\n0,1,2\n1,3,4\n");
    fails_with(
        &["check", "--data", &log, "--bias-unit", ""],
        &["--bias-unit", "must not be empty"],
    );
    fails_with(
        &["check", "--data", &log, "--track-unit", "m,s"],
        &["--track-unit", "comma"],
    );
    fails_with(
        &["check", "--data", &log, "--bias-unit", "N\nm"],
        &["--bias-unit", "control character"],
    );
    let out = dir.path().join("m.json").display().to_string();
    for args in [
        vec!["fit", "--data", &log, "--model", "poly2", "--out", &out],
        vec!["score", "--model", &out, "--data", &log],
        vec!["diagnose", "--model", &out, "--data", &log],
        vec!["plot", "position", "--data", &log, "--out", &out],
        vec!["report", "--data", &log, "--out", &out],
        vec!["ladder", "--data", &log, "--test", &log, "--terms", "poly2"],
    ] {
        let mut a = args.clone();
        a.extend(["--bias-unit", ""]);
        fails_with(&a, &["--bias-unit"]);
    }
    assert!(!Path::new(&out).exists(), "a failed run wrote {out}");
    let bad = crate::common::write(
        dir.path(),
        "bad.csv",
        "# position_unit =\ntime_s,track,bias\n0,1,2\n",
    );
    fails_with(
        &["check", "--data", &bad],
        &["bad.csv", "metadata `position_unit`", "must not be empty"],
    );
}

/// `settle --model` on a log in N and m refuses (the settle plant is a disk drive driven in
/// counts) with a message naming the unit, and never prints counts or tracks for it; on a
/// simulator log the absolute start values are the relative ones plus the converged value.
/// Reference for the absolute values: z̄ = ∂z/∂d·d (the report's own `dz_dbias` and `bias`).
#[test]
fn settle_from_a_model_speaks_its_units_or_refuses() {
    if skip_without_real_data() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (model, _) = fit_emps(dir.path(), &["--bias-unit", "N", "--track-unit", "m"]);
    let data = need(EMPS);
    let err = fails_with(
        &with_cols(
            &["settle", "--model", &model, "--data", &data],
            &["--bias-unit", "N", "--track-unit", "m"],
        ),
        &["measures bias in `N`", "disk drive", "--bias-unit counts"],
    );
    assert!(!err.contains("track"), "{err}");

    let log = dir.path().join("sim.csv").display().to_string();
    ok(&[
        "simulate",
        "--sequence",
        "random",
        "--n",
        "150",
        "--seed",
        "5",
        "--out",
        &log,
    ]);
    let m = dir.path().join("m.json").display().to_string();
    ok(&[
        "fit",
        "--data",
        &log,
        "--model",
        "position-direction",
        "--out",
        &m,
    ]);
    let v: serde_json::Value =
        serde_json::from_str(&ok(&["settle", "--model", &m, "--data", &log, "--json"])).unwrap();
    let z = v["dz_dbias"].as_f64().unwrap() * v["bias"].as_f64().unwrap();
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs().max(1.0);
    assert!(close(v["z_converged"].as_f64().unwrap(), z));
    assert!(close(v["absolute"]["zero_ff"].as_f64().unwrap(), z));
    let rel = v["robust"]["ff"].as_f64().unwrap();
    assert!(close(v["absolute"]["robust"].as_f64().unwrap(), z + rel));
    assert_eq!(v["prediction"]["units"]["bias"], "counts");
    let text = ok(&["settle", "--model", &m, "--data", &log]);
    assert!(
        text.contains("counts at ") && text.contains(" tracks (after"),
        "{text}"
    );
    assert!(text.contains(&format!("[{:.4}]", z + rel)), "{text}");
    // Δb is printed with three decimals, not every digit of the float.
    let line = text
        .lines()
        .find(|l| l.starts_with("robust for ±"))
        .unwrap();
    let db = line
        .trim_start_matches("robust for ±")
        .split(' ')
        .next()
        .unwrap();
    assert!(db.split('.').nth(1).is_some_and(|d| d.len() == 3), "{line}");
}

// ---- logs as rigs and spreadsheets write them

/// A rig's log (`time_s,position_m,force_N`) failed on `track`, then on a second run on `bias`,
/// with no hint which column was meant. Now one message names both and the flags to pass;
/// with those flags the log reads. A header's `[unit]` becomes the unit label.
#[test]
fn a_rig_log_is_told_every_flag_it_needs_in_one_message() {
    let dir = tempfile::tempdir().unwrap();
    let rig = write(
        dir.path(),
        "rig.csv",
        "time_s,position_m,force_N\n0,0.001,1.5\n0.001,0.002,1.7\n0.002,0.0015,1.6\n",
    );
    fails_with(
        &["check", "--data", &rig],
        &[
            "line 1: missing required columns `track`, `bias`",
            "name them: --track-col position_m --bias-col force_N",
        ],
    );
    ok(&[
        "check",
        "--data",
        &rig,
        "--track-col",
        "position_m",
        "--bias-col",
        "force_N",
    ]);
    let bracket = write(
        dir.path(),
        "um.csv",
        "time [s],position [um],bias [counts]\n0,1,1.5\n0.1,2,1.7\n0.2,1.5,1.6\n",
    );
    fails_with(
        &["check", "--data", &bracket],
        &["--time-col 'time [s]' --track-col 'position [um]' --bias-col 'bias [counts]'"],
    );
    let out = ok(&[
        "check",
        "--data",
        &bracket,
        "--time-col",
        "time [s]",
        "--track-col",
        "position [um]",
        "--bias-col",
        "bias [counts]",
    ]);
    assert!(
        out.contains("positions 1 .. 2 um (column position [um])")
            && out.contains("bias in counts (column bias [counts])"),
        "{out}"
    );
}

/// Excel's "Unicode Text" (UTF-16) and a Windows code page's `µ` in a header failed with
/// "stream did not contain valid UTF-8" and no line; a time column in ms was read as seconds
/// without a word.
#[test]
fn encodings_and_a_millisecond_clock_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let utf16: Vec<u8> = "\u{feff}time_s\ttrack\tbias\r\n0\t1\t2\r\n"
        .encode_utf16()
        .flat_map(u16::to_le_bytes)
        .collect();
    let p = dir.path().join("u.txt");
    std::fs::write(&p, utf16).unwrap();
    fails_with(
        &["check", "--data", &p.display().to_string()],
        &["line 1: the file is UTF-16 text", "CSV UTF-8"],
    );
    let p = dir.path().join("w.csv");
    std::fs::write(&p, b"time_s;position [\xb5m];bias\r\n0;1;2\r\n").unwrap();
    fails_with(
        &["check", "--data", &p.display().to_string()],
        &["line 1: character 18 (byte 0xB5) is not UTF-8 text"],
    );
    let ms = write(
        dir.path(),
        "ms.csv",
        "time_ms,track,bias\n0,1,2\n100,2,3\n200,3,2\n",
    );
    let out = ok(&["check", "--data", &ms, "--time-col", "time_ms"]);
    assert!(
        out.contains("column `time_ms` is read in seconds") && out.contains("milliseconds"),
        "{out}"
    );
}

/// A one-row log refused by `table,dahl` said the model "has 2 linear parameters and needs at
/// least 4 measured rows", but `table`'s knots follow the position range (one knot on one
/// position): four rows over several positions were refused again, needing 14. The message now
/// says the count is of these rows and a lower bound. Reference: the four-row log's own
/// refusal needs more than the one-row refusal said, as "at least" allows.
#[test]
fn a_too_short_log_gives_the_row_count_as_a_lower_bound() {
    let dir = tempfile::tempdir().unwrap();
    let one = write(dir.path(), "one.csv", "time_s,track,bias\n0,5,1\n");
    let four = write(
        dir.path(),
        "four.csv",
        "time_s,track,bias\n0,5,1\n1,7,2\n2,9,3\n3,4,1\n",
    );
    let out = dir.path().join("m.json").display().to_string();
    let needed = |log: &str, rows: &str| -> usize {
        let err = fails_with(
            &["fit", "--data", log, "--terms", "table,dahl", "--out", &out],
            &[
                rows,
                "needs at least",
                "linear parameters on",
                "has more on a log that spans more",
            ],
        );
        let tail = err.split("needs at least ").nth(1).unwrap();
        tail.split(' ').next().unwrap().parse().unwrap()
    };
    let (n1, n4) = (
        needed(&one, "1 measured row,"),
        needed(&four, "4 measured rows,"),
    );
    assert_eq!(n1, 4);
    assert!(n4 > 4, "{n4}");
    assert!(!std::path::Path::new(&out).exists());
}

// ---- column roles

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

/// Reference: the cells as written. An empty cell in a covariate no term reads does not stop
/// `check`, `fit` or `predict` (it is a missing value, told in a note); a term that reads the
/// column is refused naming the column and the line of its first empty cell, and a streamed
/// `predict` names the line, column and cell.
#[test]
fn an_empty_cell_in_an_unused_covariate_is_a_missing_value() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("time_s,track,bias,temp_c,humidity\n");
    for line in log_text(1.0).lines().skip(1) {
        let i = text.lines().count();
        let hum = if i == 7 {
            String::new()
        } else {
            format!("{}", 50 + i % 3)
        };
        text += &format!("{line},{},{hum}\n", 20 + i % 5);
    }
    let log = write(dir.path(), "h.csv", &text);
    let out = ok(&["check", "--data", &log]);
    assert!(
        out.contains("note: column 5 (`humidity`): 1 empty cell (line 8), read as missing"),
        "{out}"
    );
    let p = |n: &str| dir.path().join(n).display().to_string();
    ok(&[
        "fit",
        "--data",
        &log,
        "--terms",
        "poly2,direction,col:temp_c",
        "--out",
        &p("m.json"),
    ]);
    let pred = ok(&[
        "predict",
        "--model",
        &p("m.json"),
        "--data",
        &log,
        "--out",
        "-",
    ]);
    assert!(pred.lines().nth(7).unwrap().contains(",,"), "{pred}");
    fails_with(
        &[
            "fit",
            "--data",
            &log,
            "--terms",
            "poly2,col:humidity",
            "--out",
            &p("h.json"),
        ],
        &["term `col:humidity` reads column 5 (`humidity`): 1 empty cell (line 8)"],
    );
    // A model fitted where the column was complete meets the empty cell in a stream.
    let full = write(dir.path(), "f.csv", &text.replace(",\n", ",52\n"));
    ok(&[
        "fit",
        "--data",
        &full,
        "--terms",
        "poly2,col:humidity",
        "--out",
        &p("h.json"),
    ]);
    fails_with(
        &[
            "predict",
            "--model",
            &p("h.json"),
            "--data",
            &log,
            "--out",
            "-",
        ],
        &["line 8, column 5 (`humidity`): empty cell in a covariate the model reads"],
    );
}
