//! `biasctl simulate` and `biasctl demo`: byte-identical output per seed, metadata, truth file,
//! seek scripts, flag validation with exit 2, nothing half-written on error.

use crate::common::{data, editor_line, fails_with, mixed_line_ends, ok, with_line_ends, write};

fn sim(dir: &std::path::Path, name: &str, extra: &[&str]) -> (String, String) {
    let out = dir.join(name).display().to_string();
    let mut args = vec!["simulate", "--out", &out];
    args.extend_from_slice(extra);
    let stdout = ok(&args);
    (std::fs::read_to_string(&out).unwrap(), stdout)
}

#[test]
fn same_seed_byte_identical_other_seed_different() {
    let dir = tempfile::tempdir().unwrap();
    let a = sim(
        dir.path(),
        "a.csv",
        &["--sequence", "calibration", "--n", "200", "--seed", "5"],
    )
    .0;
    let b = sim(
        dir.path(),
        "b.csv",
        &["--sequence", "calibration", "--n", "200", "--seed", "5"],
    )
    .0;
    let c = sim(
        dir.path(),
        "c.csv",
        &["--sequence", "calibration", "--n", "200", "--seed", "6"],
    )
    .0;
    assert_eq!(a, b);
    assert_ne!(a, c);
    for key in [
        "# seed = 5",
        "# generator = biasctl",
        "# drive = paper1997",
        "# sequence = calibration",
        "# disabled = none",
        "# bias_unit = counts",
        "# position_unit = tracks",
    ] {
        assert!(a.contains(key), "missing {key}");
    }
}

#[test]
fn truth_file_is_separate_and_adds_up() {
    let dir = tempfile::tempdir().unwrap();
    let truth = dir.path().join("t.csv").display().to_string();
    let (log, stdout) = sim(
        dir.path(),
        "l.csv",
        &[
            "--sequence",
            "random",
            "--n",
            "50",
            "--disable",
            "drift,memory",
            "--truth",
            &truth,
        ],
    );
    assert!(
        stdout.contains("seed 1") && stdout.contains("50 measured"),
        "{stdout}"
    );
    assert!(log.contains("# disabled = memory,drift"));
    assert!(
        log.contains("time_s,track,bias\n"),
        "the log holds no truth columns"
    );
    let t = std::fs::read_to_string(&truth).unwrap();
    let mut lines = t.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header.join(","), biasctl::sim::TRUTH_COLUMNS);
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    for line in lines {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        // Reference: bias_true is the sum of the noiseless contributions (4-decimal rounding).
        let sum: f64 = [
            "position",
            "direction",
            "overshoot",
            "time",
            "memory",
            "drift",
            "temperature",
        ]
        .iter()
        .map(|n| v[col(n)])
        .sum();
        assert!((sum - v[col("bias_true")]).abs() < 1e-3, "{line}");
        assert!(v[col("memory")].abs() < 1e-12 && v[col("drift")].abs() < 1e-12);
    }
}

#[test]
fn temperature_variant_logs_temp_c() {
    let dir = tempfile::tempdir().unwrap();
    let drive = data("drive_temperature.toml");
    let (log, _) = sim(
        dir.path(),
        "t.csv",
        &["--sequence", "random", "--n", "5", "--drive", &drive],
    );
    assert!(log.contains("time_s,track,bias,temp_c\n"), "{log}");
    let (plain, _) = sim(dir.path(), "p.csv", &["--sequence", "random", "--n", "5"]);
    assert!(!plain.contains("temp_c"));
}

#[test]
fn script_sequence_runs_and_bad_rows_name_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let s = write(
        dir.path(),
        "s.csv",
        "track,dwell_s,measure\n1000,0.1,0\n1100,0.5,1\n",
    );
    let (log, _) = sim(
        dir.path(),
        "o.csv",
        &["--sequence", "script", "--script", &s],
    );
    let rows: Vec<&str> = log.lines().filter(|l| !l.starts_with('#')).collect();
    assert_eq!(rows.len(), 3);
    assert!(rows[1].ends_with(','), "unmeasured row: {}", rows[1]);
    let bad = write(
        dir.path(),
        "bad.csv",
        "track,dwell_s\n1000,0.1\n1100,soon\n",
    );
    let out = dir.path().join("x.csv").display().to_string();
    fails_with(
        &[
            "simulate",
            "--sequence",
            "script",
            "--script",
            &bad,
            "--out",
            &out,
        ],
        &["--script", "bad.csv", "line 3", "column 2", "`dwell_s`"],
    );
}

#[test]
fn script_errors_name_the_line_an_editor_shows() {
    // Reference: the line of the bad cell (marked `x`, or the row marked `@`) counted in the raw
    // text (`editor_line`: `\r\n`, `\n` and a lone `\r` each end a line), for blank lines,
    // a quoted line break, a header after blank lines, and the same texts with CRLF, lone-CR
    // (old Mac) and mixed line ends. Every case exits 2 and writes no log.
    let dir = tempfile::tempdir().unwrap();
    let cases: &[(&str, &str)] = &[
        (
            "track,dwell_s\n10,0.1\n\n\n20,x\n",
            "column 2 (`dwell_s`): not a number",
        ),
        (
            "track,dwell_s\n10,0.1\n20,0.1\n30,x\n",
            "column 2 (`dwell_s`): not a number",
        ),
        (
            "\n\ntrack,dwell_s\n\n10,0.1\nx,0.1\n",
            "column 1 (`track`): not a number",
        ),
        (
            "track,dwell_s,note\n10,0.1,\"a\nb\"\n\n20,x,c\n",
            "column 2 (`dwell_s`): not a number",
        ),
        (
            "track,dwell_s\n10,0.1\n\n@20,0.1,3\n",
            "3 fields, but the header has 2",
        ),
        ("\n\ntrack,dwell\n10,0.1\n", "missing column `dwell_s`"),
    ];
    let out = dir.path().join("o.csv");
    let mut k = 0;
    for (text, want) in cases {
        for text in [
            text.to_string(),
            with_line_ends(text, "\r\n"),
            with_line_ends(text, "\r"),
            mixed_line_ends(text),
        ] {
            let at = text
                .find(['x', '@'])
                .unwrap_or_else(|| text.find("track").unwrap());
            let line = editor_line(&text, at);
            let text = text.replace('@', "");
            k += 1;
            let name = format!("bad{k}.csv");
            let f = write(dir.path(), &name, &text);
            let err = fails_with(
                &[
                    "simulate",
                    "--sequence",
                    "script",
                    "--script",
                    &f,
                    "--out",
                    &out.display().to_string(),
                ],
                &[&format!("{name}: line {line}")],
            );
            assert!(err.contains(want), "{text:?}: {err}");
            assert!(!out.exists(), "{text:?}: a log was written");
        }
    }
}

#[test]
fn bad_flags_exit_2_naming_the_flag_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.csv");
    let o = out.display().to_string();
    let cases: &[(&[&str], &str)] = &[
        (&["--sequence", "table9"], "--sequence"),
        (
            &["--sequence", "random", "--disable", "friction"],
            "--disable",
        ),
        (&["--sequence", "random", "--n", "0"], "--n"),
        (&["--sequence", "random", "--span", "0"], "--span"),
        (&["--sequence", "random", "--span", "-5"], "--span"),
        (&["--sequence", "random", "--center", "5000"], "--center"),
        (&["--sequence", "random", "--center", "10"], "--span"),
        (&["--sequence", "table4", "--center", "200"], "--center"),
        (&["--sequence", "script"], "--script"),
        (
            &[
                "--sequence",
                "random",
                "--dwell-min",
                "1",
                "--dwell-max",
                "0.5",
            ],
            "--dwell-max",
        ),
    ];
    for (extra, flag) in cases {
        let mut args = vec!["simulate", "--out", &o];
        args.extend_from_slice(extra);
        fails_with(&args, &[flag]);
        assert!(!out.exists(), "{extra:?} left {o}");
    }
    let bad_drive = write(dir.path(), "d.toml", "name = \"x\"\n");
    fails_with(
        &[
            "simulate",
            "--sequence",
            "random",
            "--drive",
            &bad_drive,
            "--out",
            &o,
        ],
        &["d.toml", "missing field"],
    );
    // An unwritable output: nothing half-written, exit 2.
    fails_with(
        &[
            "simulate",
            "--sequence",
            "random",
            "--out",
            "/nonexistent/dir/x.csv",
        ],
        &["/nonexistent/dir/x.csv"],
    );
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "only the drive file"
    );
}

#[test]
fn demo_writes_tables_dwell_and_random() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let stdout = ok(&["demo", "--out", &out.display().to_string()]);
    for name in ["table1", "table7", "dwell", "random"] {
        assert!(out.join(format!("{name}.csv")).exists(), "{name}");
        assert!(out.join(format!("{name}_truth.csv")).exists(), "{name}");
        assert!(stdout.contains(name), "{stdout}");
    }
}

// ---- seek scripts as spreadsheets write them

/// The known bug: an empty or blank-only `--script` named its missing `track` column at the
/// line after the file's end (line 3 of a two-line file). Reference: the file has no header at
/// all, so no line is named and the message says what a script holds.
#[test]
fn an_empty_or_blank_script_is_called_empty_without_a_line() {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in [
        ("empty.csv", ""),
        ("blank.csv", "\n\n"),
        ("blank_crlf.csv", "\r\n  \r\n"),
        ("bom.csv", "\u{feff}"),
    ] {
        let script = write(dir.path(), name, text);
        let out = dir.path().join("o.csv");
        let err = fails_with(
            &[
                "simulate",
                "--sequence",
                "script",
                "--script",
                &script,
                "--out",
                &out.display().to_string(),
            ],
            &[
                &format!("{script}: the script is empty"),
                "track,dwell_s[,measure]",
            ],
        );
        assert!(!err.contains("line "), "{name}: {err}");
        assert!(!out.exists(), "{name}: nothing is written");
    }
}

/// A script saved by a European spreadsheet (byte-order mark, `;`, decimal commas, CRLF,
/// capitalised quoted header) failed with "missing column `track`". Reference: the plain comma
/// script of the same seeks gives a byte-identical log (same seed; all but the metadata line
/// that names the script file).
#[test]
fn a_spreadsheet_script_simulates_the_same_log_as_the_plain_one() {
    let dir = tempfile::tempdir().unwrap();
    let plain = write(
        dir.path(),
        "plain.csv",
        "track,dwell_s,measure\n100,0.25,1\n220,1.5,0\n180,0.5,1\n",
    );
    let excel = write(
        dir.path(),
        "excel.csv",
        "\u{feff}\"Track\";\"Dwell_s\";\"Measure\"\r\n100;0,25;1\r\n220;1,5;0\r\n180;0,5;1\r\n",
    );
    let logs: Vec<String> = [&plain, &excel]
        .iter()
        .enumerate()
        .map(|(i, script)| {
            let out = dir.path().join(format!("log{i}.csv"));
            // `--script` alone implies `--sequence script`.
            ok(&[
                "simulate",
                "--script",
                script,
                "--out",
                &out.display().to_string(),
            ]);
            // All but the metadata line naming the script file.
            std::fs::read_to_string(out)
                .unwrap()
                .lines()
                .filter(|l| !l.starts_with("# script ="))
                .collect::<Vec<_>>()
                .join("\n")
        })
        .collect();
    assert_eq!(logs[0], logs[1]);
    assert_eq!(logs[0].lines().filter(|l| !l.starts_with('#')).count(), 4);
    // A script beside another sequence was silently unused: refused naming both flags.
    let out = dir.path().join("r.csv");
    fails_with(
        &[
            "simulate",
            "--sequence",
            "random",
            "--script",
            &plain,
            "--out",
            &out.display().to_string(),
        ],
        &["--script", "--sequence random"],
    );
    assert!(!out.exists());
}
