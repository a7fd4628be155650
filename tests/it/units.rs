//! Units of bias and position: they travel with the log (`# bias_unit`, `# position_unit`
//! metadata, or the renamed column's own name), `--bias-unit` / `--track-unit` override them, and
//! every text, JSON and axis that shows log data carries them. The real-data tests need
//! `data/real/` (a missing file fails the test, as in `real`).

use crate::common::{fails_with, ok, real_data};
use std::path::Path;

const EMPS: &str = "emps/emps_estimation.csv";

fn need(rel: &str) -> String {
    real_data(rel).unwrap_or_else(|| panic!("real data `{rel}` missing under data/real"))
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
    // The flag wins over the metadata.
    let flagged = ok(&[
        "score",
        "--model",
        &model,
        "--data",
        &log,
        "--bias-unit",
        "A",
    ]);
    assert!(
        flagged.contains(" A/um, t ") && !flagged.contains("mA"),
        "{flagged}"
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
