//! The command line as a whole: exit codes, the one JSON writer, output safety of multi-file
//! outputs, checked settings named by their flags, and the mistakes a first run makes.

use crate::common::{
    biasctl, fails_with, log_text, ok, random_log_and_model, simulate_random_args, write,
};
use biasctl::plot::views::PanelOptions;
use biasctl::{StoryOptions, ladder_terms};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// The number under `key` of a JSON object.
fn num(v: &serde_json::Value, key: &str) -> f64 {
    v.pointer(key)
        .and_then(serde_json::Value::as_f64)
        .unwrap_or_else(|| panic!("{key} missing or not a number in {v}"))
}

fn settle_json(bias: &str) -> serde_json::Value {
    serde_json::from_str(&ok(&["settle", "--json", "--bias", bias])).unwrap()
}

/// `settle --json`'s `absolute` {zero_ff, ff_midpoint, paper_robust, robust} (µm·samples).
/// Reference: linear superposition, not the code's `z_converged + relative`. The handoff loop is
/// linear and the bias enters as a constant input, so (a) at bias 0 the converged integrator
/// value is 0 and each absolute value equals its relative one; (b) the relative start values do
/// not depend on the bias; (c) every absolute value moves by dz/dbias·Δbias when the bias
/// moves, the same for all four keys; (d) the text output prints the same values in brackets.
#[test]
fn settle_json_absolute_keys_follow_the_bias_by_superposition() {
    let keys = [
        ("zero_ff", None),
        ("ff_midpoint", Some("/ff_midpoint")),
        ("paper_robust", Some("/paper_robust/ff")),
        ("robust", Some("/robust/ff")),
    ];
    let zero = settle_json("0");
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0);
    for (key, rel) in keys {
        let rel0 = rel.map_or(0.0, |r| num(&zero, r));
        assert!(
            close(num(&zero, &format!("/absolute/{key}")), rel0),
            "{key} at bias 0"
        );
    }
    for bias in [25.0, -40.0, 1e6] {
        let v = settle_json(&bias.to_string());
        let dz = num(&v, "/dz_dbias");
        assert!(
            close(num(&zero, "/dz_dbias"), dz),
            "dz/dbias depends on the bias"
        );
        for (key, rel) in keys {
            if let Some(r) = rel {
                assert!(close(num(&v, r), num(&zero, r)), "{key} relative moved");
            }
            let moved =
                num(&v, &format!("/absolute/{key}")) - num(&zero, &format!("/absolute/{key}"));
            assert!(
                close(moved, dz * bias),
                "{key}: moved {moved}, dz·Δb {}",
                dz * bias
            );
        }
    }
    let text = ok(&["settle", "--bias", "25"]);
    let v = settle_json("25");
    for key in ["robust", "paper_robust"] {
        let a = format!("[{:.4}]", num(&v, &format!("/absolute/{key}")));
        assert!(text.contains(&a), "text lacks {a}:\n{text}");
    }
}

/// A simulated training and test log and a model fitted on the first, in `dir`.
fn fixture(dir: &Path) -> (String, String, String) {
    let p = |n: &str| dir.join(n).display().to_string();
    let (train, test, model) = (p("train.csv"), p("test.csv"), p("m.json"));
    ok(&simulate_random_args("400", "3", &train));
    ok(&simulate_random_args("300", "4", &test));
    ok(&[
        "fit",
        "--data",
        &train,
        "--model",
        "position-direction",
        "--out",
        &model,
    ]);
    (train, test, model)
}

fn nulls(v: &serde_json::Value, path: &str, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Null => out.push(path.to_string()),
        serde_json::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                nulls(x, &format!("{path}[{i}]"), out);
            }
        }
        serde_json::Value::Object(o) => {
            for (k, x) in o {
                nulls(x, &format!("{path}.{k}"), out);
            }
        }
        _ => {}
    }
}

/// Every `--json` command prints one JSON document through the one writer: it parses (so every
/// number is a finite JSON number: the writer refuses NaN and inf, unit-tested in
/// `render::json`), it has the command's documented keys, and `score --json` holds no `null`
/// at all. The source audit below keeps every JSON text on that writer.
#[test]
fn every_json_command_prints_parseable_json_and_score_never_null() {
    let dir = tempfile::tempdir().unwrap();
    let (train, test, model) = fixture(dir.path());
    let runs: [(&[&str], &[&str]); 7] = [
        (
            &["score", "--model", &model, "--data", &test, "--json"],
            &["/mean", "/std", "/trend"],
        ),
        (
            &[
                "diagnose",
                "--model",
                &model,
                "--data",
                &test,
                "--json",
                "--no-verify",
                "--permutations",
                "99",
            ],
            &["/residual_std", "/features"],
        ),
        (
            &[
                "diagnose",
                "--model",
                &model,
                "--data",
                &test,
                "--json",
                "--no-verify",
                "--permutations",
                "99",
                "--path",
                "1",
            ],
            &["/residual_std", "/path"],
        ),
        (
            &[
                "ladder",
                "--data",
                &train,
                "--test",
                &test,
                "--terms",
                "poly2,direction",
                "--json",
            ],
            &["/steps"],
        ),
        (
            &[
                "discover",
                "--data",
                &train,
                "--test",
                &test,
                "--max-steps",
                "1",
                "--json",
            ],
            &["/steps", "/final_terms"],
        ),
        (
            &["settle", "--json"],
            &["/absolute/zero_ff", "/z_converged"],
        ),
        (
            &["settle", "--model", &model, "--data", &test, "--json"],
            &["/prediction/bias", "/absolute/robust"],
        ),
    ];
    for (args, keys) in runs {
        let out = ok(args);
        let v: serde_json::Value =
            serde_json::from_str(&out).unwrap_or_else(|e| panic!("{args:?}: {e}\n{out}"));
        for k in keys {
            assert!(v.pointer(k).is_some(), "{args:?}: no {k}");
        }
        if args[0] == "score" {
            let mut found = Vec::new();
            nulls(&v, "$", &mut found);
            assert!(found.is_empty(), "score --json prints null at {found:?}");
        }
    }
}

/// The source audit of "one JSON writer": outside `io/json.rs`, no code that is not a test
/// turns a value into JSON text with serde_json directly (`to_string`, `to_vec`, `to_writer`,
/// pretty or not); it calls `render::json::to_string_pretty`. Reference: the source tree.
#[test]
fn every_json_text_is_made_by_the_one_writer() {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|x| x == "rs") {
                out.push(p);
            }
        }
    }
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    walk(&root, &mut files);
    let mut offenders = Vec::new();
    for f in files {
        let name = f.file_name().unwrap().to_string_lossy().into_owned();
        if name.starts_with("tests") || f.ends_with("io/json.rs") {
            continue;
        }
        let text = std::fs::read_to_string(&f).unwrap();
        let code = text.split("#[cfg(test)]").next().unwrap_or("");
        for (i, line) in code.lines().enumerate() {
            if [
                "serde_json::to_string",
                "serde_json::to_vec",
                "serde_json::to_writer",
            ]
            .iter()
            .any(|n| line.contains(n))
            {
                offenders.push(format!("{}:{}: {}", f.display(), i + 1, line.trim()));
            }
        }
    }
    assert!(
        offenders.is_empty(),
        "JSON written around the one writer:\n{}",
        offenders.join("\n")
    );
}

/// Copies `from` to `to` and returns `to` as a String.
fn copy(from: &str, to: &Path) -> String {
    std::fs::copy(from, to).unwrap();
    to.display().to_string()
}

/// What a folder holds, sorted (staging folders and temporaries would show here).
fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// An input inside a multi-file output folder under the name of one of its files is refused,
/// exit 2, the input byte for byte intact and no staging folder left: before anything runs
/// where the name is fixed (`diagnose`'s diagnosis.json, `discover`'s model.json, `report`'s
/// report.html, `export c`'s bias_model.h), when the staged folder is moved into place where
/// the name is made by the run (a `diagnose --out` feature CSV).
#[test]
fn multi_file_outputs_never_replace_an_input() {
    let dir = tempfile::tempdir().unwrap();
    let (train, test, model) = fixture(dir.path());
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let check = |args: &[&str], input: &Path, needle: &str| {
        let before = std::fs::read(input).unwrap();
        fails_with(args, &["name the same file", needle]);
        assert_eq!(
            std::fs::read(input).unwrap(),
            before,
            "{args:?}: input changed"
        );
        assert!(
            listing(&out).iter().all(|n| !n.contains("biasctl")),
            "{args:?}: stray {:?}",
            listing(&out)
        );
    };
    let d = copy(&test, &out.join("diagnosis.json"));
    check(
        &[
            "diagnose",
            "--model",
            &model,
            "--data",
            &d,
            "--out",
            out.to_str().unwrap(),
        ],
        &out.join("diagnosis.json"),
        "--data",
    );
    let m = copy(&model, &out.join("model.json"));
    check(
        &[
            "discover",
            "--data",
            &train,
            "--start",
            &m,
            "--out",
            out.to_str().unwrap(),
        ],
        &out.join("model.json"),
        "--start",
    );
    let r = copy(&model, &out.join("report.html"));
    check(
        &[
            "report",
            "--data",
            &test,
            "--model",
            &r,
            "--out",
            out.to_str().unwrap(),
        ],
        &out.join("report.html"),
        "--model",
    );
    let h = copy(&model, &out.join("bias_model.h"));
    check(
        &["export", "c", "--model", &h, "--out", out.to_str().unwrap()],
        &out.join("bias_model.h"),
        "--model",
    );
    // A name the run makes: find one diagnose writes, then give the log that name.
    let probe = dir.path().join("probe");
    let diag = [
        "diagnose",
        "--model",
        &model,
        "--data",
        &test,
        "--no-verify",
        "--permutations",
        "99",
    ];
    ok(&[&diag[..], &["--out", probe.to_str().unwrap()]].concat());
    let csv = listing(&probe)
        .into_iter()
        .find(|n| n.starts_with("residual_vs_"))
        .expect("diagnose --out writes a feature CSV");
    let input = copy(&test, &out.join(&csv));
    let mut args = diag.to_vec();
    args[4] = &input;
    check(
        &[&args[..], &["--out", out.to_str().unwrap()]].concat(),
        &out.join(&csv),
        "--data",
    );
}

/// `discover --out` is all or nothing: when one of its three files cannot be moved into place
/// (a folder named model.json is in the way), the folder keeps its old discover.json byte for
/// byte and no staging folder remains; with the way clear all three files appear.
#[test]
fn discover_out_is_all_or_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (train, test, _) = fixture(dir.path());
    let out = dir.path().join("d");
    std::fs::create_dir_all(out.join("model.json")).unwrap();
    std::fs::write(out.join("discover.json"), "old").unwrap();
    let args = [
        "discover",
        "--data",
        &train,
        "--test",
        &test,
        "--max-steps",
        "1",
        "--out",
        out.to_str().unwrap(),
    ];
    let r = biasctl(&args);
    assert_eq!(r.code, 2, "{}", r.stderr);
    assert!(r.stderr.contains("model.json"), "{}", r.stderr);
    assert_eq!(
        std::fs::read_to_string(out.join("discover.json")).unwrap(),
        "old"
    );
    assert_eq!(listing(&out), ["discover.json", "model.json"]);
    assert_eq!(
        listing(dir.path())
            .iter()
            .filter(|n| n.contains("biasctl"))
            .count(),
        0
    );
    std::fs::remove_dir(out.join("model.json")).unwrap();
    ok(&args);
    assert_eq!(
        listing(&out),
        ["discover.json", "discover.txt", "model.json"]
    );
    assert!(
        std::fs::read_to_string(out.join("discover.json"))
            .unwrap()
            .contains("final_terms")
    );
}

// ---- checked settings: a bad value is refused naming its flag

#[test]
fn report_refuses_seeks_out_of_range_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r");
    let out_s = out.display().to_string();
    for seeks in ["5", "1000001"] {
        let e = fails_with(
            &["report", "--out", &out_s, "--seeks", seeks],
            &[&format!("--seeks {seeks}: give "), "random seeks"],
        );
        assert!(!e.contains("StoryOptions"), "library name leaked: {e}");
        assert!(!out.exists(), "report wrote {out_s} for --seeks {seeks}");
    }
    let e = fails_with(
        &["demo", "--out", &out_s, "--seeks", "0"],
        &["--seeks 0: give "],
    );
    assert!(!e.contains("StoryOptions"), "{e}");
    assert!(!out.exists());
}

#[test]
fn ladder_refuses_an_empty_term_naming_the_flag() {
    // The term list is checked before either log is read: the logs need not exist.
    let e = fails_with(
        &[
            "ladder",
            "--data",
            "none.csv",
            "--test",
            "none.csv",
            "--terms",
            "poly2,,seek",
        ],
        &["--terms: term list `poly2,,seek`: term 2 is empty"],
    );
    assert!(!e.contains("LadderTerms"), "{e}");
    assert!(
        !e.contains("none.csv"),
        "logs read before the terms were checked: {e}"
    );
}

#[test]
fn plot_refuses_top_zero_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let svg = dir.path().join("d.svg");
    let svg_s = svg.display().to_string();
    let e = fails_with(
        &[
            "plot", "diagnose", "--out", &svg_s, "--data", "none.csv", "--model", "poly2", "--top",
            "0",
        ],
        &["--top 0: give at least 1"],
    );
    assert!(!e.contains("PanelOptions"), "{e}");
    assert!(!svg.exists());
    // The same flag on a plot that has a valid value draws as before (checked default).
    let r = biasctl(&["plot", "bounds", "--out", &svg_s, "--top", "1"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
}

#[test]
fn library_checks_name_the_setting() {
    // Library-only settings (no flag): the error names the field as the library knows it.
    let cases = [
        (
            StoryOptions {
                permutations: 0,
                ..StoryOptions::default()
            },
            "StoryOptions::permutations 0: ",
        ),
        (
            StoryOptions {
                settle_preset: "nope".into(),
                ..StoryOptions::default()
            },
            "StoryOptions::settle_preset ",
        ),
        (
            StoryOptions {
                random_seeks: 1,
                ..StoryOptions::default()
            },
            "StoryOptions::random_seeks 1: ",
        ),
    ];
    for (opts, want) in cases {
        let e = opts.check().unwrap_err();
        assert!(e.to_string().starts_with(want), "{e}");
    }
    assert!(StoryOptions::default().check().is_ok());
    assert!(StoryOptions::quick(3).check().is_ok());

    let e = PanelOptions { top: 0 }.check().unwrap_err();
    assert_eq!(e.to_string(), "PanelOptions::top 0: give at least 1");
    assert_eq!(PanelOptions { top: 1 }.check().unwrap().top, 1);

    let e = ladder_terms(" ,poly2").unwrap_err();
    assert!(
        e.to_string()
            .starts_with("LadderTerms::terms: term list ` ,poly2`: term 1 is empty"),
        "{e}"
    );
    assert_eq!(&*ladder_terms("poly2, seek").unwrap(), ["poly2", "seek"]);
}

/// Reference: the term registry (`biasctl::model::builtin_names`, what a spec error lists). `fit
/// --help` lists every built-in term's syntax, so a new term cannot be missing from the help
/// (its text was written by hand and had fallen eight terms behind).
#[test]
fn fit_help_lists_every_built_in_term() {
    let help = ok(&["fit", "--help"]);
    let flat = help.split_whitespace().collect::<Vec<_>>().join(" ");
    for syntax in biasctl::model::builtin_names().split(", ") {
        assert!(
            flat.contains(syntax),
            "`{syntax}` missing from fit --help:\n{help}"
        );
    }
}

// ---- stdout and error messages

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

// ---- flag mistakes of a first run

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

/// Reference: the names each flag accepts. A mistyped value gets the closest name ("did you
/// mean"), and the list stays whole.
#[test]
fn mistyped_names_get_a_did_you_mean() {
    fails_with(
        &["simulate", "--sequence", "randm", "--out", "-"],
        &["did you mean `random`?", "table1, table2"],
    );
    fails_with(
        &[
            "simulate",
            "--sequence",
            "random",
            "--disable",
            "memry",
            "--out",
            "-",
        ],
        &["did you mean `memory`?"],
    );
    fails_with(
        &["settle", "--preset", "paper197"],
        &["did you mean `paper1997`?"],
    );
    let d = tempfile::tempdir().unwrap();
    let log = write(
        d.path(),
        "l.csv",
        "time_s,track,bias\n0,1,2\n1,3,4\n2,5,6\n",
    );
    let out = d.path().join("m.json").display().to_string();
    fails_with(
        &["fit", "--data", &log, "--model", "dahll", "--out", &out],
        &["unknown model preset `dahll`; did you mean `dahl`?"],
    );
    let e = fails_with(
        &[
            "fit",
            "--data",
            &log,
            "--terms",
            "poly2,dahll:4",
            "--out",
            &out,
        ],
        &[
            "unknown term `dahll:4`; did you mean `dahl:4`?",
            "stribeck, bins, dbins",
        ],
    );
    assert!(!e.contains('…'), "{e}");
}
