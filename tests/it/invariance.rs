//! Unit invariance (issue #11): the same log with its position column in another unit and its
//! bias in another scale gives the same predictions (in the new bias unit) and the same
//! diagnosis. Every nonlinear search and grid takes its range from the data.
//!
//! Reference: the model fitted on the unscaled log; predictions of the scaled one, divided by the
//! bias factor, must agree to 1e-9 of the bias spread. The logs are synthetic (fixed seed): a
//! random sequence of moves of mixed length through a two-element stop-operator hysteresis, a
//! quadratic position curve and noise, so every term has something to fit.

use biasctl::ModelSpec;
use biasctl::{CheckedDiagnoseConfig, diagnose_model};
use biasctl::{CheckedFitOptions, fit};
use biasctl::{ColumnMap, Log};

/// A small deterministic generator (SplitMix64), so the test does not depend on the crate's.
struct Mix(u64);
impl Mix {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `n` rows of (time, position, bias) in tracks and counts.
fn rows(seed: u64, n: usize) -> Vec<(f64, f64, f64)> {
    let mut g = Mix(seed);
    let (mut x, mut t) = (500.0f64, 0.0);
    let mut z = [x, x];
    let r = [8.0, 60.0];
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let len = if g.next() < 0.5 {
            1.0 + 20.0 * g.next()
        } else {
            200.0 * g.next()
        };
        let dir = if g.next() < 0.5 { -1.0 } else { 1.0 };
        x = (x + dir * len.round()).clamp(200.0, 800.0);
        t += 0.05 + 0.2 * g.next();
        for (zi, ri) in z.iter_mut().zip(r) {
            *zi = zi.clamp(x - ri, x + ri);
        }
        let hyst = 12.0 * (x - z[0]) / r[0] - 5.0 * (x - z[1]) / r[1];
        let bias =
            30.0 + 0.02 * (x - 500.0) + 3e-5 * (x - 500.0).powi(2) + hyst + 2.0 * (g.next() - 0.5);
        out.push((t, x, bias));
    }
    out
}

fn log(rows: &[(f64, f64, f64)], xs: f64, bs: f64) -> Log {
    let mut text = String::from("time_s,track,bias\n");
    for (t, x, b) in rows {
        text += &format!("{t:?},{:?},{:?}\n", x * xs, b * bs);
    }
    Log::from_reader("scaled.csv", text.as_bytes(), &ColumnMap::default()).unwrap()
}

#[test]
fn predictions_and_diagnosis_do_not_depend_on_units() {
    let (train, test) = (rows(11, 600), rows(12, 300));
    let base = (log(&train, 1.0, 1.0), log(&test, 1.0, 1.0));
    let specs = [
        "position-direction",
        "calibration",
        "dahl",
        "poly2,dahl:4",
        "poly2,play:8",
        "table,direction",
    ];
    let opts = CheckedFitOptions::default();
    for spec_text in specs {
        let spec = biasctl::preset_terms(spec_text)
            .map_or_else(|| ModelSpec::parse(spec_text), ModelSpec::parse)
            .unwrap();
        let m0 = fit(&spec, &base.0, &opts).unwrap();
        let p0 = m0.predict_log(&base.1).unwrap();
        let spread = p0.measured.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let d0 = diagnose_model(&m0, &base.1, &CheckedDiagnoseConfig::default()).unwrap();
        for (xs, bs) in [(1e-6, 1.0), (1e6, 1e-3), (0.01, 1e4), (1e3, 2.5)] {
            let scaled = (log(&train, xs, bs), log(&test, xs, bs));
            let m = fit(&spec, &scaled.0, &opts).unwrap();
            let p = m.predict_log(&scaled.1).unwrap();
            for (a, b) in p0.predicted.iter().zip(&p.predicted) {
                assert!(
                    (a - b / bs).abs() <= 1e-9 * spread,
                    "{spec_text} at position×{xs}, bias×{bs}: {a} vs {}",
                    b / bs
                );
            }
            let d = diagnose_model(&m, &scaled.1, &CheckedDiagnoseConfig::default()).unwrap();
            // The top of the ranking (the three strongest features explaining at least 5 %; weak
            // features are near ties whose order rounding may flip), with the suggested terms.
            // A summed-memory feature is named by its length in the log's position unit
            // (`memsum_L<L>`): compared as L divided by the position factor.
            let names = |d: &biasctl::Diagnosis, xs: f64| -> Vec<(String, Option<String>)> {
                d.features
                    .iter()
                    .filter(|f| f.explained >= 0.05)
                    .take(3)
                    .map(|f| (unit_free_name(&f.name, xs), f.suggested_term.clone()))
                    .collect()
            };
            assert_eq!(
                names(&d0, 1.0),
                names(&d, xs),
                "{spec_text} at position×{xs}, bias×{bs}"
            );
            assert!((d0.residual_std - d.residual_std / bs).abs() <= 1e-9 * spread);
        }
    }
}

/// A feature name with a length in the position unit (`memsum_L<L>`) restated in the unscaled
/// unit (L / `xs`, 2 significant digits: the name itself is rounded to 3 or 4); other names unchanged.
fn unit_free_name(name: &str, xs: f64) -> String {
    match name
        .strip_prefix("memsum_L")
        .and_then(|l| l.parse::<f64>().ok())
    {
        Some(l) => format!("memsum_L{:.1e}", l / xs),
        None => name.to_string(),
    }
}

/// A dense log (1 kHz, 4 s) of a 0.5 Hz sine stroke of amplitude 100 with position noise of
/// std 0.4, a velocity column `vel` (the true velocity) and a bias of 2 + 10·(true direction)
/// + 0.01·x + noise 0.2: the true direction reverses at every velocity zero (t = 1, 2, 3 s).
fn dense_rows() -> String {
    let mut g = Mix(21);
    let gauss = |g: &mut Mix| {
        // Box–Muller from two uniforms.
        let (u, v) = (g.next().max(1e-300), g.next());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    };
    let mut text = String::from("time_s,track,bias,vel\n");
    for i in 0..4000 {
        let t = i as f64 * 1e-3;
        let w = std::f64::consts::PI; // 0.5 Hz
        let x = 100.0 * (w * t).sin();
        let v = 100.0 * w * (w * t).cos();
        let dir = if v >= 0.0 { 1.0 } else { -1.0 };
        let xm = x + 0.4 * gauss(&mut g);
        let b = 2.0 + 10.0 * dir + 0.01 * x + 0.2 * gauss(&mut g);
        text += &format!("{t:?},{xm:?},{b:?},{v:?}\n");
    }
    text
}

fn dense_log() -> Log {
    Log::from_reader("dense.csv", dense_rows().as_bytes(), &ColumnMap::default()).unwrap()
}

fn direction_coefficient(m: &biasctl::FittedModel) -> f64 {
    m.params()
        .into_iter()
        .find(|p| p.name.starts_with("direction"))
        .map_or(f64::NAN, |p| p.value)
}

#[test]
fn dense_log_direction_from_a_deadband_or_a_velocity_column() {
    use biasctl::FitOptions;
    use biasctl::{DirectionSetting, DirectionSource, log_sampling};
    // Reference: the generating model, a direction step of ±10 that reverses 3 times (the
    // velocity zeros of the sine at t = 1, 2, 3 s).
    let log = dense_log();
    let s = log_sampling(&log);
    assert!(s.dense && s.regular_clock, "{s:?}");
    assert!(s.raw_reversals > 500, "noise fakes reversals: {s:?}");
    // The three velocity zeros; a noise excursion near a slow turning point may add one.
    assert!((3..=4).contains(&s.reversals), "{s:?}");
    let spec = ModelSpec::parse("poly2,direction").unwrap();
    let with = |d: DirectionSetting| {
        let opts = FitOptions {
            direction: d,
            ..FitOptions::default()
        }
        .check()
        .unwrap();
        fit(&spec, &log, &opts).unwrap()
    };
    // Default: the deadband estimated from the noise; the model file records it.
    let auto = with(DirectionSetting::Auto);
    assert!(
        // 2·√(2 ln 4000) ≈ 8.1 noise std of 0.4: about 3.3.
        matches!(auto.direction, DirectionSource::Deadband { deadband } if deadband > 2.0 && deadband < 5.0),
        "{:?}",
        auto.direction
    );
    // The deadband delays each detected reversal until the stroke has come back 3.3 units
    // (about 80 ms of the 1 s half period here), so about 6 % of the rows carry the wrong
    // direction and the step is learned about 12 % short; the velocity column has no delay.
    assert!(
        (direction_coefficient(&auto) - 10.0).abs() < 1.5,
        "{}",
        direction_coefficient(&auto)
    );
    // Raw steps (deadband 0): direction learns a fraction of the step, and the fit says why.
    let raw = with(DirectionSetting::Deadband(0.0));
    assert!(
        direction_coefficient(&raw).abs() < 5.0,
        "{}",
        direction_coefficient(&raw)
    );
    assert!(
        raw.warnings.iter().any(|w| w.contains("faking reversals")),
        "{:?}",
        raw.warnings
    );
    assert!(!auto.warnings.iter().any(|w| w.contains("faking reversals")));
    // A velocity column.
    let vel = with(DirectionSetting::Velocity("vel".into()));
    assert!(
        (direction_coefficient(&vel) - 10.0).abs() < 0.5,
        "{}",
        direction_coefficient(&vel)
    );
    // Saved and loaded, the model replays direction the same way: identical predictions.
    let dir = tempfile::tempdir().unwrap();
    for m in [&auto, &vel] {
        let path = dir.path().join("m.json");
        m.save(&path).unwrap();
        let back = biasctl::FittedModel::load(&path).unwrap();
        assert_eq!(back.direction, m.direction);
        let (a, b) = (
            m.predict_log(&log).unwrap(),
            back.predict_log(&log).unwrap(),
        );
        assert!(
            a.predicted
                .iter()
                .zip(&b.predicted)
                .all(|(x, y)| (x - y).abs() <= 1e-12 * x.abs().max(1.0))
        );
    }
    // A missing velocity column is refused, naming it.
    let opts = FitOptions {
        direction: DirectionSetting::Velocity("nope".into()),
        ..FitOptions::default()
    }
    .check()
    .unwrap();
    let e = fit(&spec, &log, &opts).unwrap_err().to_string();
    assert!(
        e.contains("--velocity-col nope") && e.contains("vel"),
        "{e}"
    );
    // A seek log (irregular times) keeps raw steps.
    let (train, _) = (rows(11, 600), ());
    let seek = with_log(&log_of(&train));
    assert_eq!(seek, DirectionSource::Steps);
}

fn log_of(r: &[(f64, f64, f64)]) -> Log {
    log(r, 1.0, 1.0)
}

fn with_log(l: &Log) -> biasctl::DirectionSource {
    fit(
        &ModelSpec::parse("poly2,direction").unwrap(),
        l,
        &CheckedFitOptions::default(),
    )
    .unwrap()
    .direction
}

#[test]
fn cli_direction_flags_are_checked_and_recorded() {
    use crate::common::{fails_with, ok, write};
    let dir = tempfile::tempdir().unwrap();
    let data = write(dir.path(), "dense.csv", &dense_rows());
    let model = dir.path().join("m.json").display().to_string();
    fails_with(
        &[
            "fit",
            "--data",
            &data,
            "--terms",
            "direction",
            "--deadband",
            "-1",
            "--out",
            &model,
        ],
        &["--deadband -1"],
    );
    fails_with(
        &[
            "fit",
            "--data",
            &data,
            "--terms",
            "direction",
            "--velocity-col",
            "speed",
            "--out",
            &model,
        ],
        &["--velocity-col speed", "vel"],
    );
    ok(&[
        "fit",
        "--data",
        &data,
        "--terms",
        "poly2,direction",
        "--velocity-col",
        "vel",
        "--out",
        &model,
    ]);
    let text = std::fs::read_to_string(&model).unwrap();
    assert!(
        text.contains("\"velocity\"") && text.contains("\"vel\""),
        "{text}"
    );
    let out = ok(&["score", "--model", &model, "--data", &data]);
    assert!(out.contains("dense.csv"), "{out}");
    let check = ok(&["check", "--data", &data]);
    assert!(check.contains("mode: dense time series"), "{check}");
}
