//! Acceptance tests of `diagnose` on the simulated drive (issue #5) and the CLI contracts.
//!
//! Each effect test simulates random seeks (3000 train, 3000 test, span 250) on the frozen
//! drive `data/diag_base.toml` with only P1 (position), P2 (direction), P8 (scatter) and the
//! effect under test switched on, fits a model that lacks the matching term, and checks that the
//! diagnosis ranks the feature the simulator's own law depends on first (the reference: the
//! law in `src/sim/drive.rs`), and that adding the suggested term brings the test error within
//! 10 % of the model holding every matching term.

use crate::common::{biasctl, data, fails_with, ok, write};
use biasctl::Log;
use biasctl::ModelSpec;
use biasctl::{DiagnoseConfig, Diagnosis, diagnose_model, ladder_fit};
use biasctl::{Drive, SequenceOptions, SimConfig, simulate_log};
use biasctl::{FitOptions, fit};

const OFF: [&str; 6] = [
    "overshoot",
    "time",
    "memory",
    "drift",
    "runout",
    "temperature",
];

fn drive(file: &str) -> Drive {
    let text = std::fs::read_to_string(data(file)).unwrap();
    Drive::from_toml_str(file, &text).unwrap()
}

/// Train and test logs (3000 random seeks each) with every effect of `OFF` off except `on`.
fn logs(file: &str, on: &[&str], dwell_max_s: f64, seed: u64) -> (Log, Log) {
    logs_n(file, on, dwell_max_s, seed, 3000)
}

/// As [`logs`], with `n_train` seeks in the training log (the test log keeps 3000).
fn logs_n(file: &str, on: &[&str], dwell_max_s: f64, seed: u64, n_train: u64) -> (Log, Log) {
    let disabled: Vec<&str> = OFF.iter().copied().filter(|e| !on.contains(e)).collect();
    let sim = |s: u64, n: u64| {
        let opts = SequenceOptions {
            n: Some(n),
            dwell_max_s: Some(dwell_max_s),
            ..SequenceOptions::default()
        };
        simulate_log(&SimConfig::new(drive(file), "random", &opts, s, &disabled).unwrap()).unwrap()
    };
    (sim(seed, n_train), sim(seed + 1000, 3000))
}

fn test_std(train: &Log, test: &Log, terms: &str) -> f64 {
    let t = biasctl::ladder_terms(terms).unwrap();
    ladder_fit(train, test, &t, &FitOptions::default().check().unwrap())
        .unwrap()
        .steps
        .last()
        .unwrap()
        .std
}

#[test]
fn ladder_is_identical_for_any_thread_count() {
    // Reference: the ladder computed on one thread (the serial order). Its steps run in
    // parallel; on 2 and 3 threads every step's std and reduction must be the same bits.
    let (train, test) = logs_n("diag_base.toml", &["memory"], 0.05, 7, 1500);
    let terms = biasctl::ladder_terms("poly2,direction,seek,memory").unwrap();
    let opts = FitOptions::default().check().unwrap();
    let run = |threads| {
        biasctl::with_threads(threads, || {
            ladder_fit(&train, &test, &terms, &opts).unwrap()
        })
        .unwrap()
    };
    let one = run(1);
    assert_eq!(one.steps.len(), 4);
    for threads in [2, 3] {
        assert_eq!(run(threads), one, "{threads} threads");
    }
    assert!(matches!(
        biasctl::with_threads(0, || ()),
        Err(biasctl::ThreadsError::Zero)
    ));
}

/// Fits `base` on train and diagnoses it on test with `config`.
fn diagnose_fit(train: &Log, test: &Log, base: &str, config: &DiagnoseConfig) -> Diagnosis {
    let model = fit(
        &ModelSpec::parse(base).unwrap(),
        train,
        &FitOptions::default().check().unwrap(),
    )
    .unwrap();
    diagnose_model(&model, test, &config.clone().check().unwrap()).unwrap()
}

/// Diagnoses `base` fitted on train, on test; asserts the top feature is one of `expected`,
/// returns its suggested term.
fn top(train: &Log, test: &Log, base: &str, expected: &[&str]) -> Option<String> {
    let d = diagnose_fit(
        train,
        test,
        base,
        &DiagnoseConfig::default().check().unwrap(),
    );
    let f = &d.features[0];
    assert!(
        expected.contains(&f.name.as_str()) && f.flagged,
        "top feature {} not in {expected:?}:\n{}",
        f.name,
        d.to_text()
    );
    f.suggested_term.clone()
}

/// Adds the suggested term and compares with the model holding every matching term.
fn fixes(train: &Log, test: &Log, base: &str, suggested: &str, full: &str) -> (f64, f64, f64) {
    let before = test_std(train, test, base);
    let after = test_std(train, test, &format!("{base},{suggested}"));
    let all = test_std(train, test, full);
    assert!(
        after <= 1.1 * all && after < 0.9 * before,
        "{base} → +{suggested}: {before} → {after}, full `{full}` {all}"
    );
    (before, after, all)
}

/// P4/P5: the extra pivot elements are Dahl elements (`src/sim/drive.rs`), whose state depends
/// on the travel since the last reversal, signed by the direction: `since_reversal` (× direction)
/// is the honest first feature, and `dahl:4` (fast and slow elements) models the overshoot.
#[test]
fn overshoot_ranks_since_reversal_and_dahl4_fixes_it() {
    let (train, test) = logs("diag_base.toml", &["overshoot"], 0.5, 1);
    let s = top(
        &train,
        &test,
        "poly2,dahl",
        &[
            "since_reversal",
            "seek_length",
            "seek_abs",
            "direction_change",
        ],
    );
    assert_eq!(s.as_deref(), Some("dahl:4"));
    // The model with every matching term: P1 poly2, P2+P4/P5 as pivot elements (dahl:6).
    let (b, a, all) = fixes(&train, &test, "poly2", "dahl:4", "poly2,dahl:6");
    eprintln!("P4/P5: {b:.2} → {a:.2} (all {all:.2})");
}

/// P6: the lubricant ridge at uncrossed rest positions (`memory` in the simulator).
#[test]
fn rest_memory_ranks_rest_distance_and_memory_fixes_it() {
    let (train, test) = logs("diag_base.toml", &["memory"], 0.5, 2);
    let s = top(
        &train,
        &test,
        "poly2,dahl",
        // The summed-memory features see the same ridge (× direction, at a short length
        // scale they isolate the nearest rest); every one of them points at `memory`.
        &[
            "rest_distance_id",
            "rest_distance_od",
            "memsum_L3.906",
            "memsum_L15.6",
        ],
    );
    assert_eq!(s.as_deref(), Some("memory"));
    let (b, a, all) = fixes(&train, &test, "poly2,dahl", "memory", "poly2,dahl,memory");
    eprintln!("P6: {b:.2} → {a:.2} (all {all:.2})");
}

/// P7: Ornstein–Uhlenbeck offset drift.
#[test]
fn drift_ranks_time_and_drift_fixes_it() {
    let (train, test) = logs("diag_base.toml", &["drift"], 0.5, 3);
    let s = top(&train, &test, "poly2,dahl", &["elapsed_s", "seek_index"]);
    assert_eq!(s.as_deref(), Some("drift"));
    let (b, a, all) = fixes(&train, &test, "poly2,dahl", "drift", "poly2,dahl,drift");
    eprintln!("P7: {b:.2} → {a:.2} (all {all:.2})");
}

/// P3: −direction·A·(1 − exp(−t/τ)) with t the time at the track; dwell 0.05–4 s so it matters.
/// No dedicated term models it (that is `examples/new_effect.rs`); the engine must name
/// `dwell_s` × direction and suggest `dbins:dwell_s` (direction × piecewise-linear in the
/// feature), never the even `bins:dwell_s`.
#[test]
fn time_at_track_ranks_dwell_by_direction() {
    let (train, test) = logs("diag_base.toml", &["time"], 4.0, 4);
    let d = diagnose_fit(
        &train,
        &test,
        "poly2,dahl",
        &DiagnoseConfig::default().check().unwrap(),
    );
    let f = &d.features[0];
    assert_eq!(f.name, "dwell_s", "{}", d.to_text());
    assert!(f.flagged && f.by_direction, "{}", d.to_text());
    assert_eq!(f.suggested_term.as_deref(), Some("dbins:dwell_s"));
}

/// Covariate: bias = … + 1.5·(temp_c − t0) in `diag_temperature.toml` (the simulator's law).
/// The slow temperature is confounded with `elapsed_s`/`seek_index`, which explain about as
/// much; the near-tie rule (module docs of `biasctl::diagnose`) must rank the logged `temp_c`
/// first because it explains the time features away.
#[test]
fn temperature_covariate_ranks_first() {
    let (train, test) = logs("diag_temperature.toml", &["temperature"], 0.5, 5);
    let s = top(&train, &test, "poly2,dahl", &["temp_c"]);
    assert_eq!(s.as_deref(), Some("col:temp_c"));
    fixes(
        &train,
        &test,
        "poly2,dahl",
        "col:temp_c",
        "poly2,dahl,col:temp_c",
    );
}

/// A model holding every effect present (P1, P2, P8 only: poly2 + dahl, which is the
/// simulator's eq. 8 element exactly) must raise no flag at 1 % in at least 9 of 10 seeds
/// (seeds 100..=109, fixed and arbitrary; diagnosis seeds 0..=9).
///
/// The model is fitted on 30 000 seeks and tested on 3000. With a 3000-seek training log the
/// fitted poly2 is off by 0.1–0.4 counts (its sampling error, collinear with the Dahl state),
/// a TRUE position/direction-change structure in the test residual that the diagnosis
/// rightly detects (2 of 10 seeds); the residual against the simulator's truth (measured −
/// true bias) raises no flag in these seeds, nor does pure scatter. What remains in the
/// measurement beyond the model is the servo's integrator carry-over, ≈ 0.0017 × the bias
/// jump from the previous track (about 0.1 % of the residual variance), below detection here.
#[test]
fn complete_model_raises_no_false_alarm_in_nine_of_ten_seeds() {
    let mut alarms = Vec::new();
    for seed in 0..10u64 {
        let (train, test) = logs_n("diag_base.toml", &[], 0.5, 100 + seed, 30_000);
        let config = DiagnoseConfig {
            seed,
            ..DiagnoseConfig::default()
        };
        let d = diagnose_fit(&train, &test, "poly2,dahl", &config);
        if d.features.iter().any(|f| f.flagged) {
            alarms.push((seed, d.features[0].name.clone()));
        }
    }
    assert!(alarms.len() <= 1, "false alarms: {alarms:?}");
}

fn sim_file(dir: &std::path::Path, name: &str, seed: &str, n: &str) -> String {
    let p = dir.join(name).display().to_string();
    ok(&[
        "simulate",
        "--sequence",
        "random",
        "--drive",
        &data("diag_base.toml"),
        "--n",
        n,
        "--seed",
        seed,
        "--disable",
        "overshoot,time,drift,runout,temperature",
        "--out",
        &p,
    ]);
    p
}

/// `fit --terms terms` of the log `data` into `dir/m.json`; returns that path.
fn fit_file(dir: &std::path::Path, data: &str, terms: &str) -> String {
    let model = dir.join("m.json").display().to_string();
    ok(&["fit", "--data", data, "--terms", terms, "--out", &model]);
    model
}

#[test]
fn cli_diagnose_and_ladder_contracts() {
    let dir = tempfile::tempdir().unwrap();
    let train = sim_file(dir.path(), "train.csv", "1", "2000");
    let test = sim_file(dir.path(), "test.csv", "2", "2000");
    let model = fit_file(dir.path(), &train, "poly2,dahl");
    let out = dir.path().join("diag").display().to_string();
    let json = ok(&[
        "diagnose",
        "--model",
        &model,
        "--data",
        &test,
        "--json",
        "--out",
        &out,
        "--permutations",
        "99",
        "--seed",
        "3",
    ]);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let keys: Vec<&str> = v.as_object().unwrap().keys().map(String::as_str).collect();
    for k in [
        "residual_std",
        "features",
        "whiteness",
        "bimodality",
        "summary",
    ] {
        assert!(keys.contains(&k), "{keys:?}");
    }
    let first = &v["features"][0];
    for k in ["name", "explained", "p_value", "suggested_term"] {
        assert!(first.get(k).is_some(), "{first}");
    }
    assert!(
        ["rest_distance", "memsum_L"]
            .iter()
            .any(|p| first["name"].as_str().unwrap().starts_with(p)),
        "{first}"
    );
    assert!(std::path::Path::new(&out).join("diagnosis.json").exists());
    // File names keep letters, digits, `_` and `-` (`memsum_L3.906` → `memsum_L3_906`).
    let csv = std::path::Path::new(&out).join(format!(
        "residual_vs_{}.csv",
        first["name"].as_str().unwrap().replace('.', "_")
    ));
    assert!(csv.exists(), "{csv:?}");
    let text = ok(&["diagnose", "--model", &model, "--data", &test]);
    assert!(
        text.contains("Advice:") && text.contains("memory"),
        "{text}"
    );
    let lj = ok(&[
        "ladder",
        "--data",
        &train,
        "--test",
        &test,
        "--terms",
        "poly2,dahl,memory",
        "--json",
    ]);
    let l: serde_json::Value = serde_json::from_str(&lj).unwrap();
    let steps = l["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 3);
    assert!(steps[2]["std"].as_f64().unwrap() < steps[1]["std"].as_f64().unwrap());
    let lt = ok(&[
        "ladder",
        "--data",
        &train,
        "--test",
        &test,
        "--terms",
        "poly2,dahl,memory",
    ]);
    assert!(lt.contains("+ memory"), "{lt}");
}

#[test]
fn cli_bad_inputs_exit_2_with_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let train = dir.path().join("train.csv").display().to_string();
    ok(&[
        "simulate",
        "--sequence",
        "random",
        "--drive",
        &data("diag_temperature.toml"),
        "--n",
        "300",
        "--out",
        &train,
    ]);
    let model = fit_file(dir.path(), &train, "poly2,direction,col:temp_c");
    // Different column names: the model needs temp_c, this log has none.
    let other = write(dir.path(), "other.csv", &{
        let mut s = String::from("time_s,track,bias,humidity\n");
        for i in 0..100 {
            s += &format!("{i},{},{},0.5\n", 100 + (i * 37) % 50, i % 7);
        }
        s
    });
    let e = fails_with(
        &["diagnose", "--model", &model, "--data", &other],
        &["temp_c"],
    );
    assert!(!e.contains("panicked"), "{e}");
    // Too few measured rows for 5-fold cross-validation.
    let short = write(
        dir.path(),
        "short.csv",
        "time_s,track,bias,temp_c\n0,1,1,20\n1,5,2,20\n2,3,1,21\n",
    );
    fails_with(
        &["diagnose", "--model", &model, "--data", &short],
        &["too few measured rows"],
    );
    // Settings out of range.
    // The library names the setting (`DiagnoseConfig::folds`); the CLI prints its flag.
    let err = fails_with(
        &[
            "diagnose", "--model", &model, "--data", &train, "--folds", "1",
        ],
        &["--folds", "2..=50"],
    );
    assert!(!err.contains("DiagnoseConfig::"), "{err}");
    fails_with(
        &[
            "diagnose",
            "--model",
            &model,
            "--data",
            &train,
            "--verify-folds",
            "1",
        ],
        &["--verify-folds", "2..=20"],
    );
    fails_with(
        &["discover", "--data", &train, "--max-steps", "0"],
        &["--max-steps", "1..=30"],
    );
    fails_with(
        &[
            "diagnose",
            "--model",
            &model,
            "--data",
            &train,
            "--alpha",
            "0.001",
            "--permutations",
            "10",
        ],
        &["permutations"],
    );
    fails_with(
        &[
            "ladder",
            "--data",
            &train,
            "--test",
            &train,
            "--terms",
            "poly2,,seek",
        ],
        &["empty"],
    );
    // `plot ladder` reads the term list the same way as `ladder` (it used to skip empty ones).
    let svg = dir.path().join("l.svg").display().to_string();
    fails_with(
        &[
            "plot",
            "ladder",
            "--data",
            &train,
            "--test",
            &train,
            "--terms",
            "poly2,,seek",
            "--out",
            &svg,
        ],
        &["--terms", "term 2 is empty"],
    );
    assert!(!std::path::Path::new(&svg).exists());
    // A failing step is numbered as in the ladder's table (step 0 = the first term alone).
    fails_with(
        &[
            "ladder",
            "--data",
            &train,
            "--test",
            &train,
            "--terms",
            "poly2,direction,col:nothere",
        ],
        &["ladder step 2 (`poly2,direction,col:nothere`)", "nothere"],
    );
    // A constant feature: no NaN, a note, exit 0.
    let constant = write(dir.path(), "const.csv", &{
        let mut s = String::from("time_s,track,bias,temp_c\n");
        for i in 0..200 {
            s += &format!("{i},{},{},20\n", 100 + (i * 37) % 50, (i * 13) % 7);
        }
        s
    });
    let r = biasctl(&["diagnose", "--model", &model, "--data", &constant, "--json"]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(
        !r.stdout.contains("NaN") && r.stdout.contains("constant"),
        "{}",
        r.stdout
    );
}

/// Issue #11 item 4, velocity friction. Reference: the EMPS benchmark's published IDIM-LS
/// model holds a viscous force Fv·velocity (Fv = 203.5 N·s/m), which a position-only model
/// (`poly2`) lacks. With the logged velocity column, its suggestion is
/// `viscous:velocity_m_s` (its sign is the direction and the residual is a line in it). With
/// the velocity and acceleration columns removed (a position-only log), the velocity derived
/// from position and time is a feature of this dense log, and its suggestion is velocity
/// friction (`viscous` or `stribeck`), verified by refit.
#[test]
fn emps_velocity_friction_is_suggested_as_viscous() {
    use biasctl::ColumnMap;
    use biasctl::{CheckedVerifyConfig, DERIVED_VELOCITY, diagnose_verified};
    let map = ColumnMap {
        time: "time_s".into(),
        track: "position_m".into(),
        bias: "force_N".into(),
        ..ColumnMap::default()
    };
    let path = data("real/emps/emps_estimation.csv");
    let opts = FitOptions::default().check().unwrap();
    let config = DiagnoseConfig::default().check().unwrap();
    let full = Log::read(std::path::Path::new(&path), &map).unwrap();
    let model = fit(&ModelSpec::parse("poly2").unwrap(), &full, &opts).unwrap();
    let d = diagnose_model(&model, &full, &config).unwrap();
    // (Its 39 ms lag ranks first here, suggesting `lag:velocity_m_s`; the column's own
    // report names the physics.)
    let v = d
        .features
        .iter()
        .find(|f| f.name == "velocity_m_s")
        .unwrap();
    assert!(v.significant, "{}", d.to_text());
    assert_eq!(v.suggested_term.as_deref(), Some("viscous:velocity_m_s"));

    let text = std::fs::read_to_string(&path).unwrap();
    let mut short = String::new();
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        let cells: Vec<&str> = line.split(',').collect();
        short.push_str(&cells[..3].join(","));
        short.push('\n');
    }
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "emps_position_only.csv", &short);
    let log = Log::read(std::path::Path::new(&file), &map).unwrap();
    assert!(log.schema.covariates.is_empty());
    let model = fit(&ModelSpec::parse("poly2").unwrap(), &log, &opts).unwrap();
    let d = diagnose_verified(&model, &log, &config, &CheckedVerifyConfig::default()).unwrap();
    let v = d
        .features
        .iter()
        .find(|f| f.name == DERIVED_VELOCITY)
        .unwrap();
    assert!(v.flagged, "{}", d.to_text());
    let friction = |t: &str| t == "viscous" || t == "stribeck";
    assert!(v.suggested_term.as_deref().is_some_and(friction), "{v:?}");
    let verified = d.verification.as_ref().unwrap();
    assert!(
        verified
            .edits
            .iter()
            .any(|e| e.verified && e.feature == DERIVED_VELOCITY),
        "{}",
        d.to_text()
    );
}

/// Velocity friction is not suggested where it does not apply: a seek log (each row a seek,
/// irregular times) has no derived-velocity feature, and on a dense log whose bias has no
/// velocity dependence (a position line plus seeded white noise, sine motion at 1 kHz) the
/// derived velocity is not flagged and no velocity-friction edit is verified.
#[test]
fn velocity_friction_is_not_suggested_without_velocity_friction() {
    use biasctl::ColumnMap;
    use biasctl::{CheckedVerifyConfig, DERIVED_VELOCITY, FeatureTable, diagnose_verified};
    let (train, _) = logs("diag_base.toml", &[], 1.0, 5);
    assert!(
        FeatureTable::from_log(&train)
            .column(DERIVED_VELOCITY)
            .is_none()
    );

    let mut rng = biasctl::SimRng::new(17);
    let mut text = String::from("time_s,track,bias\n");
    for i in 0..6000 {
        let t = i as f64 * 1e-3;
        let x = 100.0 * (2.0 * std::f64::consts::PI * 0.7 * t).sin();
        let b = 0.05 * x + rng.normal();
        text.push_str(&format!("{t},{x},{b}\n"));
    }
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "dense.csv", &text);
    let log = Log::read(std::path::Path::new(&file), &ColumnMap::default()).unwrap();
    assert!(
        FeatureTable::from_log(&log)
            .column(DERIVED_VELOCITY)
            .is_some()
    );
    let opts = FitOptions::default().check().unwrap();
    let model = fit(&ModelSpec::parse("poly2").unwrap(), &log, &opts).unwrap();
    let config = DiagnoseConfig::default().check().unwrap();
    let d = diagnose_verified(&model, &log, &config, &CheckedVerifyConfig::default()).unwrap();
    let v = d
        .features
        .iter()
        .find(|f| f.name == DERIVED_VELOCITY)
        .unwrap();
    assert!(!v.flagged, "{}", d.to_text());
    assert!(
        !d.verification
            .as_ref()
            .unwrap()
            .edits
            .iter()
            .any(|e| e.verified && (e.edit.contains("viscous") || e.edit.contains("stribeck"))),
        "{}",
        d.to_text()
    );
}
