//! A servo engineer's first hour: logs and scripts as rigs and spreadsheets write them, and the
//! mistakes a first run makes. Each case failed (or misled) before the fix it names; each bad
//! input must exit 2 with one clear message and write nothing.

use crate::common::{biasctl, fails_with, ok, write};

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

/// Mistakes of a first run, each refused before any work with the flag named: a term list
/// given to `fit --model`, a file output into a folder that does not exist (the fit ran, then
/// the write failed), a folder given as the output file.
#[test]
fn first_run_flag_mistakes_are_refused_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("r.csv");
    let log_s = log.display().to_string();
    ok(&[
        "simulate",
        "--sequence",
        "random",
        "--n",
        "60",
        "--out",
        &log_s,
    ]);
    let model = dir.path().join("m.json").display().to_string();
    fails_with(
        &[
            "fit",
            "--data",
            &log_s,
            "--model",
            "poly2,dahl",
            "--out",
            &model,
        ],
        &["--model poly2,dahl", "--terms poly2,dahl"],
    );
    let missing = dir.path().join("no_such_folder").join("m.json");
    let missing_s = missing.display().to_string();
    let err = fails_with(
        &[
            "fit", "--data", &log_s, "--model", "dahl", "--out", &missing_s,
        ],
        &["--out", "does not exist"],
    );
    assert!(!err.contains("poly2.c0"), "{err}");
    let dir_s = dir.path().display().to_string();
    fails_with(
        &["fit", "--data", &log_s, "--model", "dahl", "--out", &dir_s],
        &["--out", "is a folder"],
    );
    ok(&["fit", "--data", &log_s, "--model", "dahl", "--out", &model]);
    for args in [
        vec![
            "predict", "--model", &model, "--data", &log_s, "--out", &missing_s,
        ],
        vec!["plot", "position", "--data", &log_s, "--out", &missing_s],
        vec![
            "simulate",
            "--sequence",
            "random",
            "--out",
            &log_s,
            "--truth",
            &missing_s,
        ],
        vec![
            "settle",
            "--preset",
            "paper1997",
            "--bounds-out",
            &missing_s,
        ],
    ] {
        let r = biasctl(&args);
        assert_eq!(r.code, 2, "{args:?}: {}", r.stderr);
        assert!(
            r.stderr.contains("does not exist"),
            "{args:?}: {}",
            r.stderr
        );
        assert!(r.stdout.is_empty(), "{args:?}: {}", r.stdout);
    }
    assert!(!missing.parent().unwrap().exists());
}

/// Flags that a library error named wrongly or not at all: `settle --target nan` said
/// "bias (--bias) must be within ±1e9 counts, got NaN" (the NaN target's prediction), an
/// unknown `--preset` / `--handoff` preset was named without its flag.
#[test]
fn settle_and_handoff_flags_are_named_as_given() {
    let dir = tempfile::tempdir().unwrap();
    let (log, model) = random_log_and_model(dir.path(), "60");
    for bad in ["nan", "inf", "2e15"] {
        let err = fails_with(
            &["settle", "--model", &model, "--data", &log, "--target", bad],
            &["--target", "finite position within ±1e15"],
        );
        assert!(!err.contains("--bias"), "{err}");
    }
    fails_with(
        &["settle", "--preset", "paper1998"],
        &["--preset paper1998", "unknown preset"],
    );
    let out = dir.path().join("p.csv");
    fails_with(
        &[
            "predict",
            "--model",
            &model,
            "--data",
            &log,
            "--out",
            &out.display().to_string(),
            "--handoff",
            "paper1998",
        ],
        &["--handoff paper1998", "not a plant file"],
    );
    assert!(!out.exists());
}

/// A folder output that cannot be made (here: inside a file) failed only after the whole
/// diagnosis or discovery, naming the hidden staging folder and not the flag. Now it is staged
/// before the work and named as `--out`; nothing is printed or left behind.
#[test]
fn a_folder_output_that_cannot_be_made_is_named_as_out_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let (log, model) = random_log_and_model(dir.path(), "80");
    let inside_a_file = format!("{log}/diag");
    for args in [
        vec![
            "diagnose",
            "--model",
            &model,
            "--data",
            &log,
            "--out",
            &inside_a_file,
        ],
        vec![
            "discover",
            "--data",
            &log,
            "--max-steps",
            "1",
            "--out",
            &inside_a_file,
        ],
    ] {
        let r = biasctl(&args);
        assert_eq!(r.code, 2, "{args:?}: {}", r.stderr);
        assert!(
            r.stderr
                .starts_with(&format!("error: --out {inside_a_file}")),
            "{args:?}: {}",
            r.stderr
        );
        assert!(r.stdout.is_empty(), "{args:?}: {}", r.stdout);
    }
    fails_with(
        &["diagnose", "--model", &model, "--data", &log, "--out", &log],
        &["--out", "is a file; --out takes a directory"],
    );
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("partial"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// A negative number given to a whole-number flag was taken for an unknown flag ("unexpected
/// argument '-5' found", no flag named). Now the flag and the value are named.
#[test]
fn a_negative_count_names_its_flag() {
    for (args, flag) in [
        (
            vec![
                "simulate",
                "--sequence",
                "random",
                "--n",
                "-5",
                "--out",
                "x.csv",
            ],
            "'--n <N>'",
        ),
        (
            vec![
                "simulate",
                "--sequence",
                "random",
                "--seed",
                "-1",
                "--out",
                "x.csv",
            ],
            "'--seed <SEED>'",
        ),
        (vec!["settle", "--horizon", "-3"], "'--horizon <N>'"),
        (vec!["--threads", "-1", "settle"], "'--threads <N>'"),
    ] {
        fails_with(&args, &["invalid value '-", flag]);
    }
}

/// A negative non-finite value for a real-number flag (`settle --target -inf`) was taken for an
/// unknown flag ("unexpected argument '-inf' found"): only values clap reads as numbers passed.
/// Now every real-number flag takes any value after it (`allow_hyphen_values`) and its check
/// refuses the non-finite one naming the flag, exit 2, nothing written. Reference: the flag's
/// documented range; a flag given no value (`--target --json`) is named too.
#[test]
fn a_negative_infinite_real_flag_is_refused_naming_its_flag() {
    let dir = tempfile::tempdir().unwrap();
    let (log, model) = random_log_and_model(dir.path(), "60");
    let out = dir.path().join("out").display().to_string();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["settle", "--model", &model, "--data", &log, "--target"],
            "--target -inf",
        ),
        (vec!["settle", "--bias"], "(--bias)"),
        (vec!["settle", "--bias-uncertainty"], "(--bias-uncertainty)"),
        (vec!["settle", "--step-um"], "(--step-um)"),
        (vec!["settle", "--window-um"], "(--window-um)"),
        (
            vec!["diagnose", "--model", &model, "--data", &log, "--alpha"],
            "--alpha",
        ),
        (vec!["discover", "--data", &log, "--alpha"], "--alpha"),
        (
            vec!["simulate", "--sequence", "random", "--out", &out, "--span"],
            "--span -inf",
        ),
        (
            vec![
                "simulate",
                "--sequence",
                "random",
                "--out",
                &out,
                "--center",
            ],
            "--center -inf",
        ),
        (
            vec![
                "simulate",
                "--sequence",
                "random",
                "--out",
                &out,
                "--dwell-min",
            ],
            "--dwell-min -inf",
        ),
        (
            vec!["plot", "time", "--data", &log, "--out", &out, "--track"],
            "no measured row at track -inf",
        ),
        (
            vec![
                "fit",
                "--data",
                &log,
                "--model",
                "position-direction",
                "--out",
                &out,
                "--deadband",
            ],
            "--deadband -inf",
        ),
        (
            vec![
                "predict",
                "--model",
                &model,
                "--data",
                &log,
                "--out",
                &out,
                "--handoff",
                "paper1997",
                "--bias-uncertainty",
            ],
            "(--bias-uncertainty)",
        ),
        (
            vec![
                "export",
                "c",
                "--model",
                &model,
                "--out",
                &out,
                "--handoff",
                "paper1997",
                "--bias-uncertainty",
            ],
            "(--bias-uncertainty)",
        ),
    ];
    for (mut args, flag) in cases {
        args.push("-inf");
        let err = fails_with(&args, &[flag]);
        assert!(!err.contains("unexpected argument"), "{args:?}: {err}");
        assert!(!std::path::Path::new(&out).exists(), "{args:?} wrote {out}");
    }
    // A negative finite value still reads as a number; a flag followed by another flag is
    // named with what it got.
    ok(&["settle", "--bias", "-3.5"]);
    fails_with(
        &["settle", "--target", "--json"],
        &["invalid value '--json' for '--target <TRACK>'"],
    );
}

/// `--terms step:col:abc` read `col:abc` as the column and said the log lacks column
/// `col:abc`. A column name holds no `:` in the term grammar (as in `by:A:B`): now the
/// threshold is named as what is wrong, before the log is read.
#[test]
fn a_step_threshold_that_is_no_number_is_named_as_the_threshold() {
    let dir = tempfile::tempdir().unwrap();
    let log = write(
        dir.path(),
        "r.csv",
        "time_s,track,bias,col\n0,1,1,0.1\n1,2,2,0.2\n2,3,1,0.3\n",
    );
    let out = dir.path().join("m.json").display().to_string();
    let err = fails_with(
        &[
            "fit",
            "--data",
            &log,
            "--terms",
            "poly2,step:col:abc",
            "--out",
            &out,
        ],
        &[
            "--terms",
            "threshold T after `col:`",
            "got `abc`",
            "step:COL:T",
        ],
    );
    assert!(!err.contains("col:abc`,"), "{err}");
    assert!(!err.contains("lacks"), "{err}");
    assert!(!std::path::Path::new(&out).exists());
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

/// A random-seek log of `n` rows on the default drive (`r.csv` in `dir`) and the
/// `position-direction` model fitted to it (`m.json`): the start of the tests that need both.
fn random_log_and_model(dir: &std::path::Path, n: &str) -> (String, String) {
    let log = dir.join("r.csv").display().to_string();
    ok(&["simulate", "--sequence", "random", "--n", n, "--out", &log]);
    let model = dir.join("m.json").display().to_string();
    ok(&[
        "fit",
        "--data",
        &log,
        "--model",
        "position-direction",
        "--out",
        &model,
    ]);
    (log, model)
}
