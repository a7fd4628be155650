//! Issue #17, output safety: `settle --json`'s `absolute` keys, the one JSON writer on every
//! `--json` command, and clash checks on every multi-file output (`diagnose --out`,
//! `discover --out`, `report --out`, `export c --out`), `discover --out` all or nothing.

use crate::common::{biasctl, fails_with, ok, simulate_random_args};
use std::path::{Path, PathBuf};

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

/// The source audit of "one JSON writer": outside `render/json.rs`, no code that is not a test
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
        if name.starts_with("tests") || f.ends_with("render/json.rs") {
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
