//! `biasctl fleet fit` and `fleet outliers`: one row per drive equal to `biasctl fit` on that
//! drive's log alone, a bad file kept in its row, the changed drives named as outliers.

use crate::common::{biasctl, data, fails_with, ok, simulate_random_args};
use std::path::Path;

/// The paper1997 drive with its direction friction (P2's fc) raised from 57 to 80 counts.
fn changed_drive(dir: &Path) -> String {
    let text = std::fs::read_to_string(data("paper1997.toml")).unwrap();
    assert!(text.contains("fc = 57.0"), "the drive file's fc line moved");
    let p = dir.join("changed.toml");
    std::fs::write(&p, text.replace("fc = 57.0", "fc = 80.0")).unwrap();
    p.display().to_string()
}

/// A fleet in `dir`: `normal` drives of seeds 1.., `changed` drives with the raised friction
/// (seeds 101..), 600 seeks each, and `bad.csv` (a cell that is no number on line 3).
fn fleet(dir: &Path, normal: u64, changed: u64) -> Vec<String> {
    let drive = changed_drive(dir);
    let mut names = Vec::new();
    for seed in 1..=normal {
        let out = dir
            .join(format!("drive{seed:02}.csv"))
            .display()
            .to_string();
        ok(&simulate_random_args("600", &seed.to_string(), &out));
        names.push(out);
    }
    for k in 1..=changed {
        let out = dir.join(format!("moved{k:02}.csv")).display().to_string();
        let seed = (100 + k).to_string();
        let mut args = simulate_random_args("600", &seed, &out).to_vec();
        args.extend(["--drive", &drive]);
        ok(&args);
        names.push(out);
    }
    std::fs::write(dir.join("bad.csv"), "time_s,track,bias\n0,1,2\n1,abc,3\n").unwrap();
    names
}

/// The table's rows as maps column → cell.
fn rows(text: &str) -> Vec<std::collections::BTreeMap<String, String>> {
    let mut r = csv::Reader::from_reader(text.as_bytes());
    let header: Vec<String> = r.headers().unwrap().iter().map(str::to_string).collect();
    r.records()
        .map(|rec| {
            header
                .iter()
                .cloned()
                .zip(rec.unwrap().iter().map(str::to_string))
                .collect()
        })
        .collect()
}

#[test]
fn fleet_fit_rows_equal_fit_on_each_drive_and_a_bad_file_keeps_its_error() {
    let dir = tempfile::tempdir().unwrap();
    let logs = fleet(dir.path(), 3, 1);
    let fits = dir.path().join("fits.csv").display().to_string();
    let pattern = format!("{}/*.csv", dir.path().display());
    let r = biasctl(&[
        "fleet",
        "fit",
        "--data",
        &pattern,
        "--model",
        "poly2,direction",
        "--out",
        &fits,
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(
        r.stdout.contains("5 drives, 4 fitted, 1 failed"),
        "{}",
        r.stdout
    );
    assert!(r.stderr.contains("bad.csv"), "{}", r.stderr);
    let table = rows(&std::fs::read_to_string(&fits).unwrap());
    assert_eq!(table.len(), 5);
    // The bad file: its own row, the reader's message naming file and line, no parameters.
    let bad = table
        .iter()
        .find(|r| r["source"].ends_with("bad.csv"))
        .unwrap();
    assert!(
        bad["error"].contains("bad.csv") && bad["error"].contains("line 3"),
        "{bad:?}"
    );
    assert!(bad["rows"].is_empty() && bad["poly2.c1"].is_empty());
    // Every other row: the parameters `biasctl fit` writes for that log alone.
    for log in &logs {
        let row = table.iter().find(|r| &r["source"] == log).unwrap();
        assert!(row["error"].is_empty(), "{row:?}");
        let model = dir.path().join("one.json").display().to_string();
        ok(&[
            "fit",
            "--data",
            log,
            "--terms",
            "poly2,direction",
            "--out",
            &model,
        ]);
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
        let mut seen = 0;
        for t in m["terms"].as_array().unwrap() {
            for p in t["params"].as_array().unwrap() {
                let name = p["name"].as_str().unwrap();
                let got: f64 = row[name].parse().unwrap();
                assert_eq!(
                    got.to_bits(),
                    p["value"].as_f64().unwrap().to_bits(),
                    "{name}"
                );
                if let Some(se) = p["se"].as_f64() {
                    let got: f64 = row[&format!("{name}.se")].parse().unwrap();
                    assert_eq!(got.to_bits(), se.to_bits(), "{name}.se");
                }
                seen += 1;
            }
        }
        assert!(seen >= 4, "{seen} parameters");
        let std: f64 = row["std"].parse().unwrap();
        assert_eq!(
            std.to_bits(),
            m["fit"]["residual_std"].as_f64().unwrap().to_bits()
        );
        assert_eq!(row["rows"], m["fit"]["rows_used"].to_string());
        assert_eq!(row["terms"], "poly2,direction");
    }
}

#[test]
fn fleet_outliers_names_the_changed_drives_only() {
    let dir = tempfile::tempdir().unwrap();
    fleet(dir.path(), 8, 2);
    let fits = dir.path().join("fits.csv").display().to_string();
    let pattern = format!("{}/*.csv", dir.path().display());
    ok(&[
        "fleet",
        "fit",
        "--data",
        &pattern,
        "--model",
        "poly2,direction",
        "--out",
        &fits,
    ]);
    let out = dir.path().join("outliers.csv").display().to_string();
    let text = ok(&["fleet", "outliers", "--fits", &fits, "--out", &out]);
    let found = rows(&std::fs::read_to_string(&out).unwrap());
    assert!(!found.is_empty(), "{text}");
    let drives: std::collections::BTreeSet<&str> =
        found.iter().map(|r| r["source"].as_str()).collect();
    let names: Vec<String> = drives
        .iter()
        .map(|s| {
            Path::new(s)
                .file_name()
                .unwrap()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    assert_eq!(names, ["moved01.csv", "moved02.csv"], "{text}");
    // Each verdict names its rule, and its z is past the threshold.
    for r in &found {
        assert!(r["rule"].starts_with("robust_z_"), "{r:?}");
        assert!(r["z"].parse::<f64>().unwrap().abs() > 4.0);
    }
    // A higher threshold than every z names none.
    let top = found
        .iter()
        .map(|r| r["z"].parse::<f64>().unwrap().abs())
        .fold(0.0, f64::max);
    let text = ok(&[
        "fleet",
        "outliers",
        "--fits",
        &fits,
        "--threshold",
        &format!("{}", top + 1.0),
    ]);
    assert!(text.contains(": 0 outlying parameters"), "{text}");
}

#[test]
fn fleet_bad_input_is_refused_naming_the_flag_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().display().to_string();
    let fits = format!("{d}/fits.csv");
    fails_with(
        &[
            "fleet",
            "fit",
            "--data",
            &format!("{d}/*.csv"),
            "--model",
            "poly2",
            "--out",
            &fits,
        ],
        &["--data", "no file matches"],
    );
    fails_with(
        &[
            "fleet",
            "fit",
            "--data",
            "x.csv",
            "--model",
            "nonsense_term",
            "--out",
            &fits,
        ],
        &["--model", "nonsense_term"],
    );
    std::fs::write(
        &fits,
        "source,rows,terms,poly2.c1,poly2.c1.se,std,warnings,error\na,600,poly2,oops,,1.0,,\n",
    )
    .unwrap();
    fails_with(
        &["fleet", "outliers", "--fits", &fits],
        &["fits.csv", "line 2", "poly2.c1", "oops"],
    );
    std::fs::write(&fits, ",source,rows\n").unwrap();
    fails_with(
        &["fleet", "outliers", "--fits", &fits],
        &["fits.csv", "line 1", "index=False"],
    );
    std::fs::write(&fits, "source,rows,terms,std,warnings,error\n").unwrap();
    fails_with(
        &["fleet", "outliers", "--fits", &fits, "--threshold", "0"],
        &["--threshold", "0"],
    );
    // Every drive failing is an error (the table still names each one's).
    std::fs::write(
        dir.path().join("bad.csv"),
        "time_s,track,bias\n0,1,2\n1,abc,3\n",
    )
    .unwrap();
    fails_with(
        &[
            "fleet",
            "fit",
            "--data",
            &format!("{d}/bad.csv"),
            "--model",
            "poly2",
            "--out",
            &fits,
        ],
        &["no drive could be fitted"],
    );
    assert!(std::fs::read_to_string(&fits).unwrap().contains("line 3"));
}

#[test]
fn fleet_diagnose_of_one_drive_is_diagnose_of_its_fit_and_a_bad_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = d.join("drive.csv").display().to_string();
    ok(&simulate_random_args("600", "4", &log));
    std::fs::write(d.join("bad.csv"), "time_s,track,bias\n0,1,2\n1,abc,3\n").unwrap();
    let model = d.join("m.json").display().to_string();
    ok(&[
        "fit",
        "--data",
        &log,
        "--terms",
        "poly2,direction",
        "--out",
        &model,
    ]);
    let one: serde_json::Value = serde_json::from_str(&ok(&[
        "diagnose",
        "--model",
        &model,
        "--data",
        &log,
        "--json",
        "--no-verify",
        "--seed",
        "2",
        "--permutations",
        "99",
    ]))
    .unwrap();
    let r = biasctl(&[
        "fleet",
        "diagnose",
        "--data",
        &format!("{}/*.csv", d.display()),
        "--model",
        "poly2,direction",
        "--json",
        "--seed",
        "2",
        "--permutations",
        "99",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(
        r.stderr.contains("bad.csv") && r.stderr.contains("line 3"),
        "{}",
        r.stderr
    );
    let pooled: serde_json::Value = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(pooled["drives"], 1);
    assert!(
        pooled["failed"][0][0]
            .as_str()
            .unwrap()
            .ends_with("bad.csv")
    );
    // One drive pooled: its own screen, feature by feature, as `diagnose` reports it.
    let mut compared = 0;
    for f in one["features"].as_array().unwrap() {
        let name = f["name"].as_str().unwrap();
        let p = pooled["features"]
            .as_array()
            .unwrap()
            .iter()
            .find(|g| g["name"] == name)
            .unwrap();
        assert_eq!(p["p_value"], f["p_value"], "{name}");
        compared += 1;
    }
    assert!(compared >= 8, "{compared}");
    fails_with(
        &[
            "fleet", "diagnose", "--data", &log, "--model", "poly2", "--alpha", "0.9",
        ],
        &["--alpha"],
    );
}

/// `drives` logs in `dir` whose bias is `poly2,direction` plus unit noise plus `load` counts
/// per unit of a logged standard-normal `load` column, 400 seeks each.
fn load_fleet(dir: &Path, drives: u64, load: f64) {
    for seed in 1..=drives {
        let mut rng = biasctl::SimRng::new(700 + seed);
        let mut text = String::from("time_s,track,bias,load\n");
        let mut last: Option<f64> = None;
        for i in 0..400 {
            let track = rng.below(3000) as f64;
            let d = last.map_or(0.0, |l| (track - l).signum());
            last = Some(track);
            let x = rng.normal();
            let bias =
                50.0 + 0.01 * track - 2e-6 * track * track + 6.0 * d + rng.normal() + load * x;
            text.push_str(&format!("{},{track},{bias:.6},{x:.6}\n", 0.5 * i as f64));
        }
        std::fs::write(dir.join(format!("load{seed:02}.csv")), text).unwrap();
    }
}

#[test]
fn fleet_diagnose_verifies_the_pooled_suggestion_on_every_drive() {
    let dir = tempfile::tempdir().unwrap();
    load_fleet(dir.path(), 6, 0.4);
    let data = format!("{}/*.csv", dir.path().display());
    let args = [
        "fleet",
        "diagnose",
        "--data",
        &data,
        "--model",
        "poly2,direction",
        "--permutations",
        "99",
    ];
    let json = |extra: &[&str]| -> serde_json::Value {
        let mut a = args.to_vec();
        a.push("--json");
        a.extend(extra);
        serde_json::from_str(&ok(&a)).unwrap()
    };
    let d = json(&[]);
    let v = &d["verification"];
    assert_eq!(v["feature"], "load", "{v}");
    assert_eq!(v["verified"], true, "{v}");
    assert_eq!(v["reason"], "verified_pooled_z");
    assert_eq!(d["best_edit"], v["term"]);
    assert_eq!(
        (v["drives"].as_u64(), v["folds"].as_u64()),
        (Some(6), Some(3))
    );
    // The fleet's figures from the drives' own: Σ reductions / Σ before, Σ T / √Σ s².
    let per = v["per_drive"].as_array().unwrap();
    let f = |e: &serde_json::Value, k: &str| e[k].as_f64().unwrap();
    let before: f64 = per.iter().map(|e| f(e, "sse_before")).sum();
    let after: f64 = per.iter().map(|e| f(e, "sse_after")).sum();
    let t: f64 = per.iter().map(|e| f(e, "loss_gain")).sum();
    let s2: f64 = per.iter().map(|e| f(e, "loss_se").powi(2)).sum();
    assert!(
        (f(v, "gain") - (before - after) / before).abs() < 1e-12,
        "{v}"
    );
    assert!((f(v, "z") - t / s2.sqrt()).abs() < 1e-9, "{v}");
    // The human output: the verdict with its rule.
    let edit = v["edit"].as_str().unwrap();
    assert!(
        edit.starts_with("add ") && edit.ends_with(":load"),
        "{edit}"
    );
    let text = ok(&args);
    assert!(
        text.contains(&format!("verified: {edit} across 6 drives")) && text.contains("z = "),
        "{text}"
    );
    // Without the refits: named, not run; more folds: other figures, the same rule.
    let off = json(&["--no-verify"]);
    assert_eq!(off["verification"]["reason"], "not_run");
    assert_eq!(off["best_edit"], serde_json::Value::Null);
    let text = ok(&[&args[..], &["--no-verify"]].concat());
    let cands: Vec<&str> = off["verification"]["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap())
        .collect();
    assert!(cands.contains(&v["term"].as_str().unwrap()), "{cands:?}");
    assert!(
        text.contains(&format!(
            "not verified: the refits with `{}` were not run (not_run)",
            cands.join("`, `")
        )),
        "{text}"
    );
    let five = json(&["--verify-folds", "5"]);
    assert_eq!(five["verification"]["folds"], 5);
    assert_ne!(five["verification"]["z"], v["z"]);
    fails_with(
        &[&args[..], &["--verify-folds", "1"]].concat(),
        &["--verify-folds", "2..=20"],
    );
}

/// A drive whose columns are not found is warned about with the command line's flags
/// (`--track-col NAME`), as `fit` itself says it, not with the library's setting names.
#[test]
fn fleet_warnings_name_the_column_flags() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = d.join("drive.csv").display().to_string();
    ok(&simulate_random_args("300", "4", &log));
    std::fs::write(d.join("other.csv"), "t,x,y\n0,1,2\n1,2,3\n").unwrap();
    let out = d.join("fits.csv").display().to_string();
    for args in [
        &["fleet", "fit", "--out", &out][..],
        &["fleet", "diagnose", "--permutations", "99"][..],
    ] {
        let glob = format!("{}/*.csv", d.display());
        let mut all = args.to_vec();
        all.extend(["--data", &glob, "--model", "poly2,direction"]);
        let r = biasctl(&all);
        assert_eq!(r.code, 0, "{args:?}: {}", r.stderr);
        assert!(
            r.stderr.contains("other.csv")
                && r.stderr.contains("--track-col")
                && !r.stderr.contains("ColumnMap::"),
            "{args:?}: {}",
            r.stderr
        );
    }
}
