//! `diagnose`, `discover` and `ladder`: acceptance on the simulated drive and on the independent
//! drives of `biasctl::sim::family`, independence of the position unit, and the CLI contracts.

use crate::common::{biasctl, data, fails_with, ok, real_data, skip_without_real_data, write};
use crate::diagnose::diagnose_family::{config, fit_terms};
use biasctl::sim::family::{FamilyConfig, FamilyDrive, HiddenEffect, generate};
use biasctl::{
    CheckedVerifyConfig, DiagnoseConfig, Diagnosis, Drive, FitOptions, Log, ModelSpec,
    SequenceOptions, SimConfig, diagnose::FeatureTable, diagnose_model, diagnose_verified, fit,
    ladder_fit, simulate_log,
};
use diagnose_family::{Outcome, full_model_flags, run, scenarios};
use serde_json::Value;

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

/// Velocity friction. Reference: the EMPS benchmark's published IDIM-LS
/// model holds a viscous force Fv·velocity (Fv = 203.5 N·s/m), which a position-only model
/// (`poly2`) lacks. With the logged velocity column, its suggestion is
/// `viscous:velocity_m_s` (its sign is the direction and the residual is a line in it). With
/// the velocity and acceleration columns removed (a position-only log), the velocity derived
/// from position and time is a feature of this dense log, and its suggestion is velocity
/// friction (`viscous` or `stribeck`), verified by refit.
#[test]
fn emps_velocity_friction_is_suggested_as_viscous() {
    if skip_without_real_data() {
        return;
    }
    use biasctl::ColumnMap;
    use biasctl::{CheckedVerifyConfig, diagnose::DERIVED_VELOCITY, diagnose_verified};
    let map = ColumnMap {
        time: "time_s".into(),
        track: "position_m".into(),
        bias: "force_N".into(),
        ..ColumnMap::default()
    };
    let path = real_data("emps/emps_estimation.csv").expect("EMPS in the real-data folder");
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
    use biasctl::{
        CheckedVerifyConfig, diagnose::DERIVED_VELOCITY, diagnose::FeatureTable, diagnose_verified,
    };
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

// ---- the independent drives of `biasctl::sim::family` (scoring code: `examples/diagnose_family.rs`)

#[path = "../../examples/diagnose_family.rs"]
#[allow(dead_code)]
pub(crate) mod diagnose_family;

/// Seeks per log in the tests (the scoreboard uses 2000).
const N: usize = 1500;

/// Scenario `i` on drive `i mod 3`, seed `100 + i`: every scenario once, every drive four times.
fn rotation() -> Vec<Outcome> {
    let drives = FamilyDrive::members();
    scenarios()
        .iter()
        .enumerate()
        .map(|(i, effects)| run(&drives[i % drives.len()], effects, 100 + i as u64, N))
        .collect()
}

fn describe(o: &Outcome) -> String {
    let names: Vec<&str> = o.effects.iter().map(|e| e.name()).collect();
    format!(
        "{} {} seed {}: first {:?}, edit {:?}, std {:.3} -> {:.3} (true term {:?}), recovered \
         {:?} (unverified suggestion {:?}: {:?}); scored: {}",
        o.drive,
        names.join("+"),
        o.seed,
        o.first,
        o.edit,
        o.std_base,
        o.std_edit,
        o.std_true,
        o.recovered(),
        o.suggested,
        o.recovered_by_suggestion(),
        o.verification
    )
}

/// The bar: every scenario right first, every first edit ≥ 90 % of the achievable.
const ISSUE_SCENARIOS: usize = 12;
/// Known gap (docs/validation.md, "Independent drives for testing diagnosis"): what diagnose reaches today
/// on this rotation; the test fails if it falls below, and docs/validation.md says what is missing.
/// (7 and 5 before the strongest unflagged features were verified by refit; 10 and 9 since;
/// 11 and 10 since the `bump` term resolves the narrow defect; 11 and 11 since the
/// verification's z-score is taken on the noise part of the paired loss difference: the
/// `bw1-sine-tar` threshold run's `bins:load:16`, 6.6 % at z = 1.2 before, is verified at 2.4;
/// 12 of 12 since the interaction is scored too, against its true term `by:position:supply`.)
const KNOWN_RIGHT_FIRST: usize = 12;
/// See [`KNOWN_RIGHT_FIRST`].
const KNOWN_RECOVERED: usize = 12;
/// The bar for the model holding every effect: at most 1 of 20 seeds flags anything.
const ISSUE_FLAGGED_SEEDS: usize = 1;
/// Seeds of 20 allowed to flag something: the issue's bar, met since diagnose's null keeps the
/// residual's serial structure (0 of 20 today; 8 of 20 with the row-shuffling null before it).
const KNOWN_FLAGGED_SEEDS: usize = ISSUE_FLAGGED_SEEDS;

/// Reference: the generator's truth (which effect is on). The first-ranked flagged feature must
/// name a hidden effect (its column or a lag of it, `position`, a `memsum_L` feature) and the
/// first verified edit (what `diagnose_verified` leads with; none verified recovers nothing)
/// must recover at least 90 % of the residual-std reduction that refitting with the effect's
/// true term achieves. The family test asks for all 12 scenarios (the interaction's true term is
/// `by:position:supply`); today's counts are asserted as a floor and every miss is printed. Before #10, diagnose named `elapsed_s` for a lagged temperature and
/// `rest_distance_*` for summed memory.
#[test]
#[ignore = "long study (minutes on 2 cores): cargo test --test it -- --ignored diagnose::study_; CI runs it"]
fn study_right_feature_first_and_first_edit_recovers_the_achievable_reduction() {
    let outcomes = rotation();
    let mut misses = Vec::new();
    let (mut right, mut recovered) = (0, 0);
    for o in &outcomes {
        if o.right_first {
            right += 1;
        } else {
            misses.push(format!("wrong first feature: {}", describe(o)));
        }
        if o.recovered().is_some_and(|r| r >= 0.9) {
            recovered += 1;
        } else {
            misses.push(format!("edit recovers < 90 %: {}", describe(o)));
        }
        // No bump where there is no defect (a verified edit is starred in `verification`).
        assert!(
            o.effects.contains(&HiddenEffect::Defect) || !o.verification.contains("*add bump"),
            "a bump verified without a defect: {}",
            describe(o)
        );
        // No step where there is no threshold.
        assert!(
            o.effects.contains(&HiddenEffect::Threshold) || !o.verification.contains("*add step"),
            "a step verified without a threshold: {}",
            describe(o)
        );
    }
    eprintln!(
        "right first {right}/{ISSUE_SCENARIOS}, edit ≥ 90 % {recovered}/{ISSUE_SCENARIOS}\n{}",
        misses.join("\n")
    );
    assert!(
        right >= KNOWN_RIGHT_FIRST && recovered >= KNOWN_RECOVERED,
        "right first {right}/{ISSUE_SCENARIOS} (floor {KNOWN_RIGHT_FIRST}), edit ≥ 90 % \
         {recovered}/{ISSUE_SCENARIOS} (floor {KNOWN_RECOVERED}):\n{}",
        misses.join("\n")
    );
}

/// Reference: with every effect present held by its true term (and the drive's own trend and
/// pivot by `table` and `dahl:8`), the residual is noise: the family test asks that nothing be
/// flagged in at least 19 of 20 seeds (alpha = 1 % family-wise); today's count is the floor.
/// The diagnosis is verified and a verified edit counts as a flag, so this is also the
/// false-alarm check of verifying the strongest unflagged features.
#[test]
#[ignore = "long study (minutes on 2 cores): cargo test --test it -- --ignored diagnose::study_; CI runs it"]
fn study_model_holding_every_effect_flags_nothing_in_19_of_20_seeds() {
    let drives = FamilyDrive::members();
    let held: Vec<Vec<HiddenEffect>> = scenarios();
    let mut flagged = Vec::new();
    for seed in 0..20u64 {
        let drive = &drives[seed as usize % drives.len()];
        let effects = &held[seed as usize % held.len()];
        let f = full_model_flags(drive, effects, 200 + seed, N);
        if !f.is_empty() {
            flagged.push(format!("{} seed {}: {f:?}", drive.name, 200 + seed));
        }
    }
    eprintln!(
        "{} of 20 seeds flag a feature (issue: ≤ {ISSUE_FLAGGED_SEEDS})\n{}",
        flagged.len(),
        flagged.join("\n")
    );
    assert!(
        flagged.len() <= KNOWN_FLAGGED_SEEDS,
        "{} of 20 seeds flag a feature (known gap: {KNOWN_FLAGGED_SEEDS}):\n{}",
        flagged.len(),
        flagged.join("\n")
    );
}

/// Reference: the generator's parameters. On a `bw-sine-t` log with the lag effect, `lag:temp_lag`
/// recovers the lag's time constant (10 s) and slope (1.2 × noise std per 3 °C = 0.8 counts/°C);
/// with summed memory, `memsum` recovers L = span/12 = 20 tracks and A = 1.2 × noise std = 2.4
/// counts. Both fitted models survive a save/load round trip with identical predictions.
#[test]
fn lag_and_memsum_terms_recover_the_generators_parameters() {
    use biasctl::{sim::family::FamilyConfig, sim::family::generate};
    let drive = FamilyDrive::member("bw-sine-t").unwrap();
    let base = diagnose_family::base_terms(&drive);
    let dir = tempfile::tempdir().unwrap();
    for (effect, term, checks) in [
        (
            HiddenEffect::Lag,
            "lag:temp_lag",
            [
                ("lag:temp_lag.tau", 10.0, 0.25),
                ("lag:temp_lag.slope", 0.8, 0.1),
            ],
        ),
        (
            HiddenEffect::SummedMemory,
            "memsum",
            [("memsum.L", 20.0, 0.25), ("memsum.A", 2.4, 0.15)],
        ),
    ] {
        let run = generate(&FamilyConfig::new(drive.clone(), &[effect], 31, 3000)).unwrap();
        let terms = diagnose_family::with_term(&base, term);
        let model = diagnose_family::fit_terms(&terms, &run.log);
        for (name, want, rel) in checks {
            let got = model.param(name).unwrap().value;
            assert!(
                (got - want).abs() <= rel * want,
                "{name}: {got} vs {want} (±{:.0} %)",
                rel * 100.0
            );
        }
        let path = dir.path().join(format!("{}.json", effect.name()));
        model.save(&path).unwrap();
        let back = biasctl::FittedModel::load(&path).unwrap();
        let (a, b) = (
            model.predict_log(&run.log).unwrap(),
            back.predict_log(&run.log).unwrap(),
        );
        let worst = a
            .predicted
            .iter()
            .zip(&b.predicted)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-9, "{term}: reloaded model differs by {worst}");
    }
}

/// The `play` term and interactions, each suggested as a typed edit and verified by
/// refit. Reference: the generator's physics. The `pi-cubic-ar1` pivot is a Prandtl–Ishlinskii
/// (stop-operator) loop; a model with only a direction offset (`table:S,direction`) cannot
/// express it, and the verified best edit is `play:N` (scored beside `dahl:4`). With the pivot
/// held (`table:S,dahl:8`) no `play` edit is verified. The interaction scenario's bias is
/// `supply × position`: the verified best edit is `by:position:supply`; with no interaction
/// (the fast-covariate scenario, its true term held) no `by:` edit is verified.
#[test]
fn play_and_interaction_are_suggested_where_they_apply_and_only_there() {
    use biasctl::sim::family::{FamilyConfig, generate};
    use biasctl::{CheckedVerifyConfig, diagnose_verified};
    let drive = FamilyDrive::member("pi-cubic-ar1").unwrap();
    let run = generate(&FamilyConfig::new(drive.clone(), &[], 7, N)).unwrap();
    let table = diagnose_family::base_terms(&drive)[0].clone();
    let verified = |terms: &[String], log: &biasctl::Log, seed: u64| {
        let model = diagnose_family::fit_terms(terms, log);
        let d = diagnose_verified(
            &model,
            log,
            &diagnose_family::config(seed),
            &CheckedVerifyConfig::default(),
        )
        .unwrap();
        let v = d.verification.clone().unwrap();
        (d, v)
    };
    let (d, v) = verified(&[table.clone(), "direction".into()], &run.log, 7);
    let best = v.best().unwrap_or_else(|| panic!("{}", d.to_text()));
    assert!(best.edit.starts_with("add play"), "{}", d.to_text());
    let (d, v) = verified(&diagnose_family::base_terms(&drive), &run.log, 7);
    assert!(
        !v.edits
            .iter()
            .any(|e| e.verified && e.edit.contains("play")),
        "{}",
        d.to_text()
    );

    let bw = FamilyDrive::member("bw-sine-t").unwrap();
    let run = generate(&FamilyConfig::new(
        bw.clone(),
        &[HiddenEffect::Interaction],
        8,
        N,
    ))
    .unwrap();
    let (d, v) = verified(&diagnose_family::base_terms(&bw), &run.log, 8);
    let best = v.best().unwrap_or_else(|| panic!("{}", d.to_text()));
    assert!(
        best.edit.starts_with("add by:")
            && best.edit.contains("supply")
            && best.edit.contains("position"),
        "{}",
        d.to_text()
    );
    let run = generate(&FamilyConfig::new(
        bw.clone(),
        &[HiddenEffect::FastCovariate],
        8,
        N,
    ))
    .unwrap();
    let held = diagnose_family::with_term(&diagnose_family::base_terms(&bw), "col:temp_fast");
    let (d, v) = verified(&held, &run.log, 8);
    assert!(
        !v.edits.iter().any(|e| e.verified && e.edit.contains("by:")),
        "{}",
        d.to_text()
    );
}

/// The reversal-memory pair screen. Reference: the generator's truth. On `pi-cubic-ar1` with
/// the Preisach effect (a weight blob off the diagonal of the (α, β) plane: the output steps
/// only for reversals between two regions of the travel, which no congruent loop makes) and
/// the family's user model (`table`, `dahl:8`), the pair (`position`, `reversal_position`)
/// explains jointly what neither does alone, and the best verified edit is `preisach:N`, N
/// chosen by the refit. On every family drive **without** it — Bouc–Wen (a smooth Dahl-like
/// loop) and Prandtl–Ishlinskii (Maxwell-slip/play) pivots — neither the user model nor a
/// model whose loop term is too coarse for the pivot (`dahl:4`; `play:8` on a Bouc–Wen drive)
/// gets a `preisach` suggestion, verified or not.
#[test]
fn preisach_is_suggested_for_reversal_memory_and_only_there() {
    let verified = |terms: &[String], log: &Log, seed: u64| {
        let model = fit_terms(terms, log);
        diagnose_verified(&model, log, &config(seed), &CheckedVerifyConfig::default()).unwrap()
    };
    let pi = FamilyDrive::member("pi-cubic-ar1").unwrap();
    for seed in [17u64, 18] {
        let run = generate(&FamilyConfig::new(
            pi.clone(),
            &[HiddenEffect::Preisach],
            seed,
            N,
        ))
        .unwrap();
        let d = verified(&diagnose_family::base_terms(&pi), &run.log, seed);
        assert!(
            d.interactions.iter().any(|i| i.a == "position"
                && i.b == "reversal_position"
                && i.suggested_term == "preisach"),
            "seed {seed}: {:?}\n{}",
            d.interactions,
            d.to_text()
        );
        let best = d.verification.as_ref().and_then(|v| v.best());
        assert!(
            best.is_some_and(|b| b.edit.starts_with("add preisach:")),
            "seed {seed}: {}",
            d.to_text()
        );
    }
    let mut drives = FamilyDrive::members();
    drives.push(diagnose_family::fresh_drive());
    for (k, drive) in drives.iter().enumerate() {
        let run = generate(&FamilyConfig::new(drive.clone(), &[], 60 + k as u64, N)).unwrap();
        let table = diagnose_family::base_terms(drive)[0].clone();
        for terms in [
            diagnose_family::base_terms(drive),
            vec![table.clone(), "dahl:4".into()],
            vec![table, "play:8".into()],
        ] {
            let d = verified(&terms, &run.log, 60 + k as u64);
            let v = d.verification.clone().unwrap_or_default();
            assert!(
                !d.interactions
                    .iter()
                    .any(|i| i.suggested_term.contains("preisach"))
                    && !v.edits.iter().any(|e| e.edit.contains("preisach")),
                "{} {terms:?}: {}",
                drive.name,
                d.to_text()
            );
        }
    }
}

/// The covariate × position pair screen. Reference: the generator's truth. The windage effect
/// (`sim::family::HiddenEffect::Windage`: air density falling with the slow column `temp_slow`
/// times a force that changes sign along the stroke) averages to zero over the travel and
/// over the column, so no single feature has a marginal of it; on every family drive the
/// pair (`position`, `temp_slow`) is screened and the best verified edit is its term
/// `by:position:temp_slow` (not the `scale:temp_slow:dahl:8` it is scored beside, nor a table).
#[test]
fn windage_is_named_by_the_covariate_position_pair() {
    let mut drives = FamilyDrive::members();
    drives.push(diagnose_family::fresh_drive());
    for (k, drive) in drives.iter().enumerate() {
        let seed = 70 + k as u64;
        let run = generate(&FamilyConfig::new(
            drive.clone(),
            &[HiddenEffect::Windage],
            seed,
            N,
        ))
        .unwrap();
        let model = fit_terms(&diagnose_family::base_terms(drive), &run.log);
        let d = diagnose_verified(
            &model,
            &run.log,
            &config(seed),
            &CheckedVerifyConfig::default(),
        )
        .unwrap();
        assert!(
            d.interactions
                .iter()
                .any(|i| i.suggested_term == "by:position:temp_slow"),
            "{}: {:?}",
            drive.name,
            d.interactions
        );
        let best = d.verification.as_ref().and_then(|v| v.best());
        assert!(
            best.is_some_and(|b| b.edit == "add by:position:temp_slow"),
            "{}: {}",
            drive.name,
            d.to_text()
        );
    }
}

/// Runs of the slow-threshold check ([`slow_threshold_behind_drift_is_named_and_only_there`])
/// whose edit is verified by its refit, of 8; the test fails below it. The rest gain 13–24 %
/// out of sample at z 1.4–1.8: the column rose above the set point once in the log, one
/// episode, which the verification's block z-score rightly does not take as sure.
const KNOWN_SLOW_THRESHOLD_VERIFIED: usize = 6;

/// What `drift` absorbed, on a slow column with a set point. Reference: the generator's truth
/// (`sim::family::HiddenEffect::SlowThreshold`: nothing while `temp_slow` ≤ 41 °C, a ramp of
/// 3·a per °C above; its term `bins:temp_slow:8`). With `drift` in the user's model, drift
/// follows the ramp step by step and no feature of the residual is flagged; on every family
/// drive (the three members and the held-out one, seeds 200 and 201) the absorbed check must
/// name `temp_slow` (or a lag of it), its suggestion must be a `temp_slow` term, that edit
/// must be refitted with a gain out of sample, every verified edit must be a `temp_slow` term,
/// and at least [`KNOWN_SLOW_THRESHOLD_VERIFIED`] of the 8 must be verified. On the same
/// drives and seeds without the effect (drift in the model), nothing is absorbed and nothing
/// verified names `temp_slow`: no new false alarm. Before the slow-column rule the check was
/// silent on 5 of 12 such logs (all three `pi-cubic-ar1` seeds: family-wise p 0.04–0.80).
#[test]
fn slow_threshold_behind_drift_is_named_and_only_there() {
    let mut drives = FamilyDrive::members();
    drives.push(diagnose_family::fresh_drive());
    let mut verified = 0;
    let mut misses = Vec::new();
    for drive in &drives {
        for seed in [200u64, 201] {
            for on in [true, false] {
                let effects: &[HiddenEffect] = if on {
                    &[HiddenEffect::SlowThreshold]
                } else {
                    &[]
                };
                let run = generate(&FamilyConfig::new(drive.clone(), effects, seed, N)).unwrap();
                let mut terms = diagnose_family::base_terms(drive);
                terms.push("drift".into());
                let model = fit_terms(&terms, &run.log);
                let d = diagnose_verified(
                    &model,
                    &run.log,
                    &config(seed),
                    &CheckedVerifyConfig::default(),
                )
                .unwrap();
                let what = format!("{} seed {seed} effect {on}", drive.name);
                let slow = |t: &str| t.contains("temp_slow");
                let edits = d.verification.clone().unwrap_or_default().edits;
                if edits.iter().any(|e| e.verified && !slow(&e.edit)) && on {
                    misses.push(format!("{what}: a verified edit that is not temp_slow's"));
                }
                if !on {
                    if !d.absorbed.is_empty() || edits.iter().any(|e| e.verified && slow(&e.edit)) {
                        misses.push(format!("{what}: false alarm\n{}", d.to_text()));
                    }
                    continue;
                }
                let named = d.absorbed.iter().find(|a| {
                    a.term == "drift"
                        && slow(&a.feature)
                        && a.suggested_term.as_deref().is_some_and(slow)
                });
                let edit = edits
                    .iter()
                    .find(|e| e.feature.starts_with("drift → temp_slow"));
                match (named, edit) {
                    (Some(_), Some(e)) if slow(&e.edit) && e.gain > 0.0 => {
                        verified += usize::from(e.verified);
                    }
                    _ => misses.push(format!("{what}: not named\n{}", d.to_text())),
                }
            }
        }
    }
    assert!(misses.is_empty(), "{}", misses.join("\n"));
    assert!(
        verified >= KNOWN_SLOW_THRESHOLD_VERIFIED,
        "{verified} of 8 verified"
    );
}

/// A slowly varying column with **no** effect must not be flagged under strongly
/// autocorrelated noise. Reference: the generator's truth. `pi-cubic-ar1` logs (AR(1) noise in
/// seek order, ρ = 0.6) with the threshold effect, diagnosed (with verification) on the model
/// that holds every effect present (`table`, `dahl:8`, the true `step:load`): the random
/// walk `walk`, the warm-up curve and white noise are logged but never enter the bias, so any
/// flag or verified edit is a false alarm, and none of 6 seeds may have one. Seed 50 is the
/// held-out log where, before the within-fold gain was required, `walk@lag32.4s` was flagged
/// and `col:walk` verified (3.2 % out of sample at z = 4.2, 0.3 % within folds): this test
/// failed there.
#[test]
fn slow_no_effect_column_is_not_flagged_under_ar1_noise() {
    let drive = FamilyDrive::member("pi-cubic-ar1").unwrap();
    let mut flagged = Vec::new();
    for seed in 45..=50u64 {
        let f = full_model_flags(&drive, &[HiddenEffect::Threshold], seed, N);
        if !f.is_empty() {
            flagged.push(format!("seed {seed}: {f:?}"));
        }
    }
    assert!(flagged.is_empty(), "{}", flagged.join("\n"));
}

/// Reference: the generator's truth. The defect scenario adds `5·a·exp(−½((x − c)/1.5)²)`
/// (a = the drive's effect scale × noise std; c = the track where the truth series peaks,
/// where it equals 5·a exactly since tracks are integers). Fitting the user's model plus
/// `bump` (centre and width found from the data) on three drives must recover the centre
/// within a quarter of a track, the width within 20 % and the amplitude within 2.5 standard
/// errors; the fitted model survives a save/load round trip bit for bit.
#[test]
fn bump_term_recovers_the_generators_defect() {
    use biasctl::{sim::family::FamilyConfig, sim::family::generate};
    let dir = tempfile::tempdir().unwrap();
    for (i, drive) in FamilyDrive::members().into_iter().enumerate() {
        let seed = 41 + i as u64;
        let run = generate(&FamilyConfig::new(
            drive.clone(),
            &[HiddenEffect::Defect],
            seed,
            3000,
        ))
        .unwrap();
        let truth = run.truth("defect").unwrap();
        let (k, a_true) = truth
            .iter()
            .enumerate()
            .fold((0, f64::MIN), |b, (k, &v)| if v > b.1 { (k, v) } else { b });
        let c_true = run.log.tracks()[k];
        let terms = diagnose_family::with_term(&diagnose_family::base_terms(&drive), "bump");
        let model = diagnose_family::fit_terms(&terms, &run.log);
        let p = |n: &str| model.param(&format!("bump.{n}")).unwrap().clone();
        let (a, c, w) = (p("A"), p("centre"), p("width"));
        eprintln!(
            "{} seed {seed}: A {:.3} ± {:.3} (truth {a_true:.3}), centre {:.3} ± {:.3} (truth \
             {c_true}), width {:.3} ± {:.3} (truth 1.5)",
            drive.name,
            a.value,
            a.se.unwrap(),
            c.value,
            c.se.unwrap_or(f64::NAN),
            w.value,
            w.se.unwrap_or(f64::NAN)
        );
        assert!(
            (c.value - c_true).abs() < 0.25,
            "{}: centre {c:?}",
            drive.name
        );
        assert!(
            (w.value - 1.5).abs() < 0.2 * 1.5,
            "{}: width {w:?}",
            drive.name
        );
        assert!(
            (a.value - a_true).abs() < 2.5 * a.se.unwrap(),
            "{}: amplitude {a:?} vs {a_true}",
            drive.name
        );
        assert_reload_predicts_the_same_bits(&model, &run.log, dir.path(), &drive.name);
    }
}

/// Reference: the generator's truth. The threshold scenario adds `2·a` where `load > 0.6`
/// (a = the drive's effect scale × noise std: the largest value of the truth series).
/// Fitting the user's model plus `step:load` (threshold found from the data) on three drives
/// must put the threshold within 0.005 of 0.6 (2.5 % of load's std), with a profile standard
/// error, and the height within 2.5 standard errors of `2·a`; the fitted model survives a
/// save/load round trip bit for bit.
#[test]
fn step_term_recovers_the_generators_threshold() {
    use biasctl::{sim::family::FamilyConfig, sim::family::generate};
    let dir = tempfile::tempdir().unwrap();
    for (i, drive) in FamilyDrive::members().into_iter().enumerate() {
        let seed = 51 + i as u64;
        let run = generate(&FamilyConfig::new(
            drive.clone(),
            &[HiddenEffect::Threshold],
            seed,
            3000,
        ))
        .unwrap();
        let truth = run.truth("threshold").unwrap();
        let a_true = truth.iter().copied().fold(0.0, f64::max);
        let terms = diagnose_family::with_term(&diagnose_family::base_terms(&drive), "step:load");
        let model = diagnose_family::fit_terms(&terms, &run.log);
        let p = |n: &str| model.param(&format!("step:load.{n}")).unwrap().clone();
        let (a, t) = (p("A"), p("threshold"));
        eprintln!(
            "{} seed {seed}: A {:.3} ± {:.3} (truth {a_true:.3}), threshold {:.4} ± {:.4} \
             (truth 0.6)",
            drive.name,
            a.value,
            a.se.unwrap(),
            t.value,
            t.se.unwrap_or(f64::NAN),
        );
        assert!(
            (t.value - 0.6).abs() < 0.005,
            "{}: threshold {t:?}",
            drive.name
        );
        assert!(t.se.is_some_and(|se| se > 0.0), "{}: {t:?}", drive.name);
        assert!(
            (a.value - a_true).abs() < 2.5 * a.se.unwrap(),
            "{}: height {a:?} vs {a_true}",
            drive.name
        );
        assert_reload_predicts_the_same_bits(&model, &run.log, dir.path(), &drive.name);
    }
}

/// The bar on the narrow defect, on every drive (seeds not in the rotation).
/// Reference: the generator's truth — the first-ranked flagged feature is `position`, the first
/// verified edit adds a `bump` whose centre lies within half a track of the track where the
/// truth series peaks, and refitting with it recovers ≥ 90 % of the reduction the true term
/// achieves.
#[test]
fn narrow_defect_is_named_first_and_its_bump_recovers_the_achievable_reduction() {
    use biasctl::{sim::family::FamilyConfig, sim::family::generate};
    for (i, drive) in FamilyDrive::members().into_iter().enumerate() {
        let seed = 300 + i as u64;
        let o = run(&drive, &[HiddenEffect::Defect], seed, N);
        let text = describe(&o);
        assert!(o.right_first, "{text}");
        assert!(o.recovered().is_some_and(|r| r >= 0.9), "{text}");
        let edit = o.edit.clone().unwrap_or_default();
        let centre: f64 = edit
            .strip_prefix("add bump:")
            .and_then(|r| r.split(':').next())
            .and_then(|c| c.parse().ok())
            .unwrap_or_else(|| panic!("first edit is not a bump: {text}"));
        let fam = generate(&FamilyConfig::new(
            drive.clone(),
            &[HiddenEffect::Defect],
            seed,
            N,
        ))
        .unwrap();
        let truth = fam.truth("defect").unwrap();
        let k = (0..truth.len())
            .max_by(|&a, &b| truth[a].total_cmp(&truth[b]))
            .unwrap();
        let c_true = fam.log.tracks()[k];
        assert!(
            (centre - c_true).abs() < 0.5,
            "centre {centre} vs {c_true}: {text}"
        );
    }
}

/// The lag runs the verification missed before its z-score was taken on the noise part of the
/// paired loss difference (seeds 1–5 of the study in docs/validation.md): a lagged
/// temperature alone, and beside a position × direction effect. In each, `lag:temp_lag`
/// gained 19–56 % out of sample but at z = 1.8–2.8, under the unflagged-feature bar of 3
/// (the gain comes in episodes at set-point changes, which the block sums of the whole
/// difference counted as noise), so nothing or only `dbins:position` was verified (24–50 % of
/// the achievable). Reference: the generator's truth — the first-ranked feature reads
/// `temp_lag`, the first verified edit is the effect's own term `add lag:temp_lag`, and it
/// recovers ≥ 90 % of the reduction the best single true term achieves.
#[test]
#[ignore = "long study (minutes on 2 cores): cargo test --test it -- --ignored diagnose::study_; CI runs it"]
fn study_a_lagged_temperature_is_verified_first_also_beside_position_direction() {
    use HiddenEffect::{Lag, PositionDirection};
    let drives = FamilyDrive::members();
    let cases: [(usize, &[HiddenEffect], u64); 5] = [
        (0, &[Lag], 5),
        (1, &[Lag], 4),
        (2, &[Lag], 1),
        (0, &[Lag, PositionDirection], 5),
        (1, &[Lag, PositionDirection], 4),
    ];
    for (d, effects, seed) in cases {
        let o = run(&drives[d], effects, seed, N);
        let text = describe(&o);
        assert!(o.right_first, "{text}");
        assert_eq!(o.edit.as_deref(), Some("add lag:temp_lag"), "{text}");
        assert!(o.recovered().is_some_and(|r| r >= 0.9), "{text}");
    }
}

/// Saves `model` as `<name>.json` in `dir`, loads it back and asserts that the reloaded model
/// predicts `log` bit for bit as the original does (the model file round trip of a searched
/// term: its found centre, width or threshold must survive the text).
fn assert_reload_predicts_the_same_bits(
    model: &biasctl::FittedModel,
    log: &biasctl::Log,
    dir: &std::path::Path,
    name: &str,
) {
    let path = dir.join(format!("{name}.json"));
    model.save(&path).unwrap();
    let back = biasctl::FittedModel::load(&path).unwrap();
    let (x, y) = (
        model.predict_log(log).unwrap(),
        back.predict_log(log).unwrap(),
    );
    assert!(
        x.predicted
            .iter()
            .zip(&y.predicted)
            .all(|(u, v)| u.to_bits() == v.to_bits()),
        "{name}: the reloaded model predicts other bits"
    );
}

// ---- the diagnosis does not depend on the position unit

/// The log with its positions × `k`.
fn scaled(log: &Log, k: f64) -> Log {
    let mut log = log.clone();
    for x in log.tracks_mut() {
        *x *= k;
    }
    log
}

/// Whether number `a` (tracks) and `b` (in the unit × `k`) are the same figure up to `rel`: equal
/// once `b` is divided by `k^p` for a power p from −2 to 2 (a position, a slope per position,
/// a squared position, …), or both below 1e-12 after it (a figure that is rounding noise).
fn same_number(a: f64, b: f64, k: f64, rel: f64) -> bool {
    (-2..=2).any(|p| {
        let b = b / k.powi(p);
        (a - b).abs() <= rel * a.abs().max(b.abs()) + 1e-12
    })
}

/// `s` split into its text and its numbers (`memsum_L15.0` → `memsum_L#`, [15.0]).
fn tokens(s: &str) -> (String, Vec<f64>) {
    let c: Vec<char> = s.chars().collect();
    let digit = |i: usize| c.get(i).is_some_and(char::is_ascii_digit);
    let (mut text, mut nums, mut i) = (String::new(), Vec::new(), 0);
    while i < c.len() {
        let negative = c[i] == '-' && digit(i + 1) && (i == 0 || !c[i - 1].is_alphanumeric());
        if !(digit(i) || negative) {
            text.push(c[i]);
            i += 1;
            continue;
        }
        let start = i;
        i += usize::from(negative);
        while digit(i) || (c.get(i) == Some(&'.') && digit(i + 1)) {
            i += 1;
        }
        if c.get(i) == Some(&'e') && (digit(i + 1) || (c.get(i + 1) == Some(&'-') && digit(i + 2)))
        {
            i += 2;
            while digit(i) {
                i += 1;
            }
        }
        let number: String = c[start..i].iter().collect();
        nums.push(number.parse::<f64>().unwrap());
        text.push('#');
    }
    (text, nums)
}

/// Every difference between report `a` (tracks) and `b` (positions × `k`) under the rules of the
/// module doc, with its key path.
fn differences(a: &Value, b: &Value, k: f64, path: &str, out: &mut Vec<String>) {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            if !same_number(x, y, k, 1e-5) {
                out.push(format!("{path}: {x} vs {y}"));
            }
        }
        (Value::String(x), Value::String(y)) => {
            let ((tx, nx), (ty, ny)) = (tokens(x), tokens(y));
            let numbers_agree = nx.len() == ny.len()
                && nx.iter().zip(&ny).all(|(p, q)| {
                    // Printed to 3–4 significant digits.
                    same_number(*p, *q, k, 6e-3)
                });
            if tx != ty || !numbers_agree {
                out.push(format!("{path}: `{x}` vs `{y}`"));
            }
        }
        (Value::Array(x), Value::Array(y)) if x.len() == y.len() => {
            for (i, (p, q)) in x.iter().zip(y).enumerate() {
                differences(p, q, k, &format!("{path}[{i}]"), out);
            }
        }
        (Value::Object(x), Value::Object(y))
            if x.keys().collect::<Vec<_>>() == y.keys().collect::<Vec<_>>() =>
        {
            for (key, p) in x {
                differences(p, &y[key], k, &format!("{path}.{key}"), out);
            }
        }
        _ if a == b => {}
        _ => out.push(format!("{path}: {a} vs {b}")),
    }
}

#[test]
fn comparison_rules_catch_what_they_must() {
    // The failure this module is about, and a changed flag, are differences; a unit factor or
    // last-bit rounding is not.
    let a: Value = serde_json::json!({"x": 0.217089, "n": "memsum_L15.0", "f": true});
    let ok: Value = serde_json::json!({"x": 0.21708900000001, "n": "memsum_L0.750", "f": true});
    let moved: Value = serde_json::json!({"x": 0.217002, "n": "memsum_L0.750", "f": true});
    let flag: Value = serde_json::json!({"x": 0.217089, "n": "memsum_L0.750", "f": false});
    let name: Value = serde_json::json!({"x": 0.217089, "n": "memsum_L0.950", "f": true});
    let count = |b: &Value| {
        let mut out = Vec::new();
        differences(&a, b, 0.05, "", &mut out);
        out.len()
    };
    assert_eq!(
        [count(&ok), count(&moved), count(&flag), count(&name)],
        [0, 1, 1, 1]
    );
    assert_eq!(tokens("memsum_L3.750 ×dir").1, [3.75]);
    assert_eq!(tokens("step:position:-12.5").1, [-12.5]);
    assert_eq!(tokens("p = 1.2e-5,").1, [1.2e-5]);
}

/// The tie structure of every feature column (which rows are equal, which smaller) is the same
/// in tracks and in every unit: the cheap check of what the quantile bins see.
#[test]
fn derived_position_features_tie_alike_in_every_unit() {
    let drive = FamilyDrive::member("bw-sine-t").unwrap();
    let fam = generate(&FamilyConfig::new(drive, &[], 7, 1500)).unwrap();
    let ranks = |t: &FeatureTable, name: &str| -> Vec<(usize, Option<usize>)> {
        let col = t.column(name).unwrap();
        let mut defined: Vec<f64> = col.iter().flatten().collect();
        defined.sort_by(f64::total_cmp);
        defined.dedup_by(|a, b| a.to_bits() == b.to_bits());
        col.iter()
            .enumerate()
            .map(|(i, v)| {
                (
                    i,
                    v.map(|v| defined.partition_point(|d| d.total_cmp(&v).is_lt())),
                )
            })
            .collect()
    };
    let base = FeatureTable::from_log(&fam.log);
    for k in [0.05, 1e-3, 7.3, 4.0, 1e-6 / 3.0] {
        let t = FeatureTable::from_log(&scaled(&fam.log, k));
        for name in [
            "position",
            "seek_length",
            "seek_abs",
            "since_reversal",
            "rest_distance_od",
            "rest_distance_id",
        ] {
            assert!(
                ranks(&base, name) == ranks(&t, name),
                "{name} at × {k}: the ties or order differ from tracks"
            );
            // And the values are the tracks values × k (the grid is 2⁻³² of the largest position).
            for (a, b) in base
                .column(name)
                .unwrap()
                .iter()
                .zip(t.column(name).unwrap().iter())
            {
                if let (Some(a), Some(b)) = (a, b) {
                    assert!(
                        (a * k - b).abs() <= 1e-7 * 240.0 * k,
                        "{name} × {k}: {a} vs {b}"
                    );
                }
            }
        }
    }
}

/// The report itself: a family drive with summed memory (rest distances and seek lengths among
/// the strongest features), verified, in tracks and in four other units; and the user model's
/// predictions (`fit` then `predict` in each unit) against the tracks model's.
#[test]
fn diagnose_report_is_the_same_in_any_position_unit() {
    let drive = FamilyDrive::member("bw-sine-t").unwrap();
    let seed = 507;
    let fam = generate(&FamilyConfig::new(
        drive.clone(),
        &[HiddenEffect::SummedMemory],
        seed,
        900,
    ))
    .unwrap();
    let report = |k: f64| -> (Value, Vec<f64>) {
        let log = scaled(&fam.log, k);
        // The table's knot spacing in the same unit: span/24 tracks.
        let terms = vec![
            format!("table:{:?}", drive.span / 24.0 * k),
            "dahl:8".to_string(),
        ];
        let model = fit_terms(&terms, &log);
        let d = diagnose_verified(&model, &log, &config(seed), &CheckedVerifyConfig::default())
            .unwrap();
        let predicted = model.predict_log(&log).unwrap().predicted;
        (
            serde_json::from_str(&d.to_json().unwrap()).unwrap(),
            predicted,
        )
    };
    let (base, p0) = report(1.0);
    let spread = p0.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    // The run must exercise what the fix is about.
    let names: Vec<&str> = base["features"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["name"].as_str().unwrap())
        .collect();
    assert!(names.contains(&"rest_distance_od") && names.contains(&"seek_length"));
    for k in [0.05, 1e-3, 7.3, 4.0] {
        let (r, p) = report(k);
        // `fit` and `predict`: the same predictions (counts) in any unit, to 1e-9 of their spread.
        for (a, b) in p0.iter().zip(&p) {
            assert!(
                (a - b).abs() <= 1e-9 * spread,
                "positions × {k}: {a} vs {b}"
            );
        }
        let mut out = Vec::new();
        differences(&base, &r, k, "", &mut out);
        assert!(
            out.is_empty(),
            "positions × {k}: {} differences, first: {:#?}",
            out.len(),
            &out[..out.len().min(8)]
        );
    }
}

/// Positions far from zero (encoder counts near 1e12, a travel of 1e4) keep the lengths'
/// resolution: the grid is held at 2⁻²⁴ of the travel, so whole-count seek lengths stay exact.
/// Reference: the integer differences of the written positions.
#[test]
fn positions_far_from_zero_keep_their_lengths() {
    let steps: [f64; 8] = [0.0, 1.0, 2.0, 3.0, 5000.0, 7.0, 9999.0, 4.0];
    let mut text = String::from("time_s,track,bias\n");
    for (i, s) in steps.iter().enumerate() {
        text += &format!("{i},{},{}\n", 1e12 + s, i % 3);
    }
    let log = Log::from_reader("far.csv", text.as_bytes(), &Default::default()).unwrap();
    let table = FeatureTable::from_log(&log);
    let lengths: Vec<Option<f64>> = table.column("seek_abs").unwrap().iter().collect();
    for (i, l) in lengths.iter().enumerate().skip(1) {
        assert_eq!(
            l.map(f64::to_bits),
            Some((steps[i] - steps[i - 1]).abs().to_bits()),
            "row {i}: {l:?}"
        );
    }
}

// ---- output folders

/// `diagnose --out` must name a directory: an existing file is refused with that explanation.
#[test]
fn diagnose_out_that_is_a_file_is_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    ok(&[
        "simulate",
        "--sequence",
        "random",
        "--n",
        "200",
        "--seed",
        "5",
        "--out",
        &p("log.csv"),
    ]);
    ok(&[
        "fit",
        "--data",
        &p("log.csv"),
        "--model",
        "position-direction",
        "--out",
        &p("m.json"),
    ]);
    fails_with(
        &[
            "diagnose",
            "--model",
            &p("m.json"),
            "--data",
            &p("log.csv"),
            "--out",
            &p("log.csv"),
        ],
        &["--out", "is a file", "takes a directory"],
    );
}

/// A rig log as `pandas.DataFrame.to_csv` writes it: an unnamed index column, then `t [s]`
/// (row i at i·0.02 s computed in binary and printed shortest-round-trip, as pandas prints a
/// float: `4.0200000000000005`), `pos_mm`, `F_N`, `T_coil`. The force: a Bouc–Wen friction
/// state (3 N, characteristic length 2 mm), a spring (0.05 N/mm), gravity (2.94 N), the coil
/// temperature through a 40 s first-order lag (0.4 N/K), noise 0.2 N; the temperature steps to
/// a new set point every 30 s and follows it with a 5 s time constant.
fn pandas_rig_csv(n: usize, seed: u64) -> String {
    let mut rng = biasctl::SimRng::new(seed);
    let (dt, tau) = (0.02, 40.0);
    let (mut z, mut temp, mut lagged, mut set_point, mut prev) = (0.0, 25.0, 25.0, 25.0, 0.0);
    let mut text = String::from(",t [s],pos_mm,F_N,T_coil\n");
    for i in 0..n {
        let t = i as f64 * dt;
        let two_pi = 2.0 * std::f64::consts::PI;
        let x = 20.0 * (two_pi * t / 7.0).sin() + 5.0 * (two_pi * t / 2.3).sin();
        let dx: f64 = x - prev;
        prev = x;
        let zf: f64 = z;
        z += (dx - 0.5 * dx.abs() * zf - 0.5 * dx * zf.abs()) / 2.0;
        if i % 1500 == 0 {
            set_point = 25.0 + 30.0 * rng.uniform();
        }
        temp += (set_point - temp) * dt / 5.0 + 0.02 * rng.normal();
        lagged += (temp - lagged) * dt / tau;
        let force = 3.0 * z + 0.05 * x + 9.81 * 0.3 + 0.4 * (lagged - 25.0) + 0.2 * rng.normal();
        text.push_str(&format!("{i},{t},{x},{force},{temp}\n"));
    }
    text
}

#[test]
fn a_pandas_written_regular_clock_is_no_effect_and_nothing_blows_up() {
    // Reference: the log's clock is regular — every row 0.02 s after the one before, as
    // written in decimal; only the binary rounding of the written times varies (a dozen
    // variants of 0.02 s that change with the size of t). Time differences read on the time
    // grid are one value, so `dwell_s` explains nothing and no edit is scored for it; and no
    // number the diagnosis prints is blown up (the forces are tens of N: nothing it prints,
    // figures or percentages, reaches 1e7 in absolute value).
    let dir = tempfile::tempdir().unwrap();
    let csv = pandas_rig_csv(12_000, 5);
    assert!(
        csv.contains("\n201,4.0200000000000005,"),
        "not pandas' clock"
    );
    let data = write(dir.path(), "rig.csv", &csv);
    let model = dir.path().join("pd.json").display().to_string();
    let cols = [
        "--time-col",
        "t [s]",
        "--track-col",
        "pos_mm",
        "--bias-col",
        "F_N",
        "--bias-unit",
        "N",
    ];
    let run = |args: &[&str]| ok(&[args, &cols[..]].concat());
    run(&[
        "fit",
        "--data",
        &data,
        "--model",
        "position-direction",
        "--out",
        &model,
    ]);
    let text = run(&["diagnose", "--model", &model, "--data", &data]);
    let json: Value = serde_json::from_str(&run(&[
        "diagnose", "--model", &model, "--data", &data, "--json",
    ]))
    .unwrap();
    let dwell = json["features"]
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f["name"] == "dwell_s")
        .expect("dwell_s is a candidate");
    assert!(
        dwell["explained"].as_f64().unwrap() < 0.02 && dwell["flagged"] == false,
        "a regular clock read as an effect: {dwell}"
    );
    let v = &json["verification"];
    for e in v["edits"].as_array().unwrap() {
        assert_ne!(e["feature"], "dwell_s", "{e}");
    }
    let big: Vec<&str> = text
        .split(|c: char| c.is_whitespace() || c == '(' || c == ')' || c == ',')
        .filter(|w| w.parse::<f64>().is_ok_and(|v| v.abs() >= 1e7))
        .collect();
    assert!(big.is_empty(), "blown-up numbers {big:?} in:\n{text}");
}
