//! `scale:COL:TERM` (issue #11, item 4: a covariate scaling another term): recovery of the
//! interaction on a log simulated independently of the term's code, a fit `by:` cannot match,
//! model-file round trip, the C export's refusal and bad specs at the CLI.

use crate::common::{fails_with, write};
use biasctl::terms::dahl::DahlState;
use biasctl::{COptions, ExportError, c_source};
use biasctl::{CheckedDiagnoseConfig, CheckedVerifyConfig, diagnose_verified};
use biasctl::{ColumnMap, FitOptions, FittedModel, Log, ModelSpec, SimRng, fit};

/// Truth of the simulated logs: `bias = 5 + 0.01·x − 4e-6·x² + 0.8·c + FC·G + K·c·G + N(0, NOISE²)`
/// with `G` one Dahl element of characteristic length [`L`] tracks (unit amplitude, eq. 8)
/// driven by the seeks and `c` the `supply` column: main effects (position curve, covariate,
/// friction) plus `K·c` times the friction state.
const FC: f64 = 20.0;
/// The interaction: counts per unit of `supply` per unit of G.
const K: f64 = 3.0;
/// Characteristic length of the Dahl element, tracks.
const L: f64 = 30.0;
/// Noise std, counts.
const NOISE: f64 = 0.5;

/// A log of `n` seeks (half short ±10 tracks, half long over 0..1000), `supply` drifting from
/// 30 to 35 with a uniform jitter of 1, the bias of the truth above; values exact in the CSV.
fn simulate(n: usize, seed: u64) -> (String, Log) {
    simulate_k(n, seed, K)
}

/// As [`simulate`] with the interaction `k` in place of [`K`].
fn simulate_k(n: usize, seed: u64, k: f64) -> (String, Log) {
    let mut rng = SimRng::new(seed);
    let mut g = DahlState::with_length(L);
    let mut text = String::from("time_s,track,bias,supply\n");
    let mut x = 500.0f64;
    for i in 0..n {
        let prev = x;
        x = if rng.uniform() < 0.5 {
            x + rng.below(21) as f64 - 10.0
        } else {
            rng.below(1001) as f64
        }
        .clamp(0.0, 1000.0);
        let c = ((30.0 + 5.0 * i as f64 / n as f64 + rng.uniform()) * 1e6).round() / 1e6;
        let gv = g.step(if i == 0 { 0.0 } else { x - prev });
        let y =
            5.0 + 0.01 * x - 4e-6 * x * x + 0.8 * c + FC * gv + k * c * gv + NOISE * rng.normal();
        text += &format!("{i},{x},{y:.12},{c:.6}\n");
    }
    let log = Log::from_reader("scale.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
    (text, log)
}

/// RMS of the causal prediction error of `m` on `log`.
fn test_rms(m: &FittedModel, log: &Log) -> f64 {
    let p = m.predict_log(log).unwrap();
    (p.residual.iter().map(|e| e * e).sum::<f64>() / p.residual.len() as f64).sqrt()
}

/// `spec` fitted on `log` with the default options.
fn fitted(spec: &str, log: &Log) -> FittedModel {
    fit(
        &ModelSpec::parse(spec).unwrap(),
        log,
        &FitOptions::default().check().unwrap(),
    )
    .unwrap()
}

/// Reference: the simulation's own constants (the log is made by `DahlState` and the formula
/// above, not by the term). `poly2,col:supply,dahl,scale:supply:dahl` recovers `K` (reported
/// per unit of the column as `scale:supply:dahl.Fc`) within 3 of its reported standard errors,
/// the standard error below 2 % of K, the scaled copy's searched rate within 2 % of
/// `exp(−1/L)`'s `1 − r`, and its error on a fresh log falls to the noise (< 1.1·NOISE). The
/// best a `by:` interaction can do (supply × direction, × position, × seek length) stays above
/// 3·NOISE: it multiplies features, not the Dahl state.
#[test]
fn recovers_the_interaction_that_by_cannot_express() {
    let (_, train) = simulate(4000, 1);
    let (_, test) = simulate(2000, 2);
    let m = fitted("poly2,col:supply,dahl,scale:supply:dahl", &train);
    let k = m.param("scale:supply:dahl.Fc").unwrap();
    let se = k.se.unwrap();
    assert!(
        (k.value - K).abs() < 3.0 * se && se < 0.02 * K,
        "{k:?}\n{:?}",
        m.warnings
    );
    let r_true = (-1.0 / L).exp();
    let r = m.param("scale:supply:dahl.r").unwrap().value;
    assert!(
        ((1.0 - r) / (1.0 - r_true) - 1.0).abs() < 0.02,
        "r {r} vs {r_true}"
    );
    let rms = test_rms(&m, &test);
    assert!(rms < 1.1 * NOISE, "test rms {rms} vs noise {NOISE}");
    for by in ["direction", "position", "seek_length"] {
        let spec = format!("poly2,col:supply,dahl,by:supply:{by}");
        let rms_by = test_rms(&fitted(&spec, &train), &test);
        assert!(rms_by > 3.0 * NOISE, "{spec}: test rms {rms_by}");
    }
}

/// Reference: the fitted model itself. Saved and loaded, a model with scaled `dahl` (searched
/// rate), `play:4` and `direction` gives bit-identical predictions on a fresh log and writes the
/// same file again; `export c` refuses it naming the scale term.
#[test]
fn model_file_round_trip_is_bit_identical() {
    let (_, train) = simulate(1500, 3);
    let (test_text, test) = simulate(500, 4);
    let spec =
        "poly2,col:supply,dahl,scale:supply:dahl,play:4,scale:supply:play:4,scale:supply:direction";
    let m = fitted(spec, &train);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.json");
    m.save(&path).unwrap();
    let back = FittedModel::load(&path).unwrap();
    assert_eq!(back.to_json().unwrap(), m.to_json().unwrap());
    let (a, b) = (
        m.predict_log(&test).unwrap(),
        back.predict_log(&test).unwrap(),
    );
    assert_eq!(a.predicted.len(), 500);
    for (x, y) in a.predicted.iter().zip(&b.predicted) {
        assert_eq!(x.to_bits(), y.to_bits());
    }
    for (name, c) in a.term_names.iter().zip(&a.contributions) {
        if name.starts_with("scale:") {
            assert!(
                c.iter().any(|v| v.abs() > 1e-3),
                "{name} contributes nothing"
            );
        }
    }
    match c_source(&back, &COptions::default()) {
        Err(ExportError::NotExportable { term }) => assert!(term.starts_with("scale:supply:")),
        other => panic!("export of a scale term: {:?}", other.map(|_| ())),
    }
    // The CLI's `export c` refuses it by name too (exit 2).
    let model = path.display().to_string();
    let out = dir.path().join("m.c").display().to_string();
    fails_with(
        &["export", "c", "--model", &model, "--out", &out],
        &["scale:supply:"],
    );
    let _ = write(dir.path(), "test.csv", &test_text);
}

/// Bad specs exit 2 naming the term and the problem: no column or term, an unknown inner term,
/// a nested scale, a missing column.
#[test]
fn bad_specs_exit_2_naming_the_term() {
    let (text, _) = simulate(100, 5);
    let dir = tempfile::tempdir().unwrap();
    let data = write(dir.path(), "s.csv", &text);
    let out = dir.path().join("m.json").display().to_string();
    for (terms, needles) in [
        ("poly2,scale:", vec!["`scale:`", "scale:COL:TERM"]),
        (
            "poly2,scale:supply",
            vec!["`scale:supply`", "scale:COL:TERM"],
        ),
        (
            "poly2,scale:supply:nope",
            vec!["`scale:supply:nope`", "unknown term `nope`"],
        ),
        (
            "poly2,scale:supply:scale:supply:dahl",
            vec![
                "`scale:supply:scale:supply:dahl`",
                "cannot scale another `scale`",
            ],
        ),
        (
            "poly2,scale:humidity:dahl",
            vec!["scale:humidity:dahl", "humidity"],
        ),
        (
            "poly2,scale:supply:drift",
            vec!["scale:supply:drift", "no linear basis"],
        ),
    ] {
        fails_with(
            &["fit", "--data", &data, "--terms", terms, "--out", &out],
            &needles,
        );
    }
    assert!(!dir.path().join("m.json").exists(), "nothing half-written");
}

/// Diagnose suggests the scale term where a covariate's effect flips with the direction and the
/// model has a direction-signed state term: on the log with the interaction, the `supply`
/// feature of `poly2,col:supply,dahl` suggests `scale:supply:dahl` and its refit is the best
/// verified edit; on the same seeks without the interaction (k = 0, the reference) no
/// `scale:` edit is verified.
#[test]
fn diagnose_suggests_and_verifies_the_scale_term() {
    for (k, expected) in [(K, true), (0.0, false)] {
        let (_, log) = simulate_k(2000, 6, k);
        let base = fitted("poly2,col:supply,dahl", &log);
        let d = diagnose_verified(
            &base,
            &log,
            &CheckedDiagnoseConfig::default(),
            &CheckedVerifyConfig::default(),
        )
        .unwrap();
        let v = d.verification.as_ref().unwrap();
        let scale_verified = v
            .edits
            .iter()
            .any(|e| e.verified && e.edit.contains("scale:"));
        assert_eq!(scale_verified, expected, "k = {k}\n{}", d.to_text());
        if expected {
            let f = d.features.iter().find(|f| f.name == "supply").unwrap();
            assert_eq!(f.suggested_term.as_deref(), Some("scale:supply:dahl"));
            let best = v.best().unwrap();
            assert_eq!(best.edit, "add scale:supply:dahl", "{}", d.to_text());
            assert!(best.std_after < 1.2 * NOISE, "{best:?}");
        }
    }
}
