//! Model terms, fit, predict and score: recovery of known parameters, reference implementations,
//! causality, the online predictor, and the CLI contract of `fit`/`predict`/`score`.

use crate::common::{fails_with, ok, write};
use biasctl::History;
use biasctl::SimRng;
use biasctl::terms::intercept::InterceptTerm;
use biasctl::{ColumnMap, Log};
use biasctl::{ColumnsUsed, FittedModel, FittedTerm, ModelSpec, Predictor};
use biasctl::{FitData, FitOptions, fit};
use biasctl::{terms::dahl::DahlPredictor, terms::dahl::DahlState};
use std::sync::Arc;

/// A random seek sequence: mixed short and long seeks over `range` tracks, times 0.1 s apart,
/// a temperature covariate drifting slowly.
fn tracks(seed: u64, n: usize, range: f64) -> Vec<(f64, f64, f64)> {
    let mut rng = SimRng::new(seed);
    let mut x = range / 2.0;
    let mut t = 0.0;
    (0..n)
        .map(|k| {
            let step = if rng.uniform() < 0.5 {
                (rng.below(21) as f64) - 10.0
            } else {
                (rng.below(range as u64) as f64) - x
            };
            x = (x + step).clamp(0.0, range);
            t += ((0.05 + rng.uniform() * 0.2) * 1e6).round() / 1e6; // exact in the CSV
            let c = ((30.0 + 5.0 * (k as f64 / n as f64) + rng.uniform()) * 1e6).round() / 1e6;
            (t, x, c)
        })
        .collect()
}

fn csv(rows: &[(f64, f64, f64)], bias: &[f64]) -> String {
    let mut s = String::from("# synthetic\ntime_s,track,bias,temp_c\n");
    for (i, &(t, x, c)) in rows.iter().enumerate() {
        s += &format!("{t:.6},{x},{:.12},{c:.6}\n", bias[i]);
    }
    s
}

fn parse(text: &str) -> Log {
    Log::from_reader("synth.csv", text.as_bytes(), &ColumnMap::default()).unwrap()
}

/// Generates a log from known parameters: prepares `spec`'s terms on the seek sequence, sets
/// each term's coefficients with `coef`, replays causally with N(0, noise²) added.
fn synth(
    rows: &[(f64, f64, f64)],
    spec: &str,
    coef: &dyn Fn(&str, usize) -> f64,
    nonlinear: Option<f64>,
    noise: f64,
    seed: u64,
) -> (Log, FittedModel) {
    let skeleton = parse(&csv(rows, &vec![0.0; rows.len()]));
    let data = FitData::new(&skeleton);
    let spec = ModelSpec::parse(spec).unwrap();
    let mut terms: Vec<_> = spec
        .terms
        .iter()
        .map(|t| t.prepare(&data).unwrap())
        .collect();
    if !terms.iter().any(|t| t.provides_intercept()) {
        terms.insert(0, Arc::new(InterceptTerm));
    }
    for t in &mut terms {
        if let (Some(v), Some(_)) = (nonlinear, t.nonlinear()) {
            *t = with_rate(t, 1.0 - v.exp());
        }
    }
    let truth = FittedModel {
        spec: spec.clone(),
        columns: ColumnsUsed {
            time: "time_s".into(),
            track: "track".into(),
            bias: "bias".into(),
            covariates: vec![],
        },
        terms: terms
            .iter()
            .map(|t| FittedTerm {
                term: t.clone(),
                coefficients: (0..t.param_names().len())
                    .map(|i| coef(&t.name(), i))
                    .collect(),
                params: vec![],
            })
            .collect(),
        fit: fit(
            &ModelSpec::parse("").unwrap(),
            &skeleton,
            &FitOptions::default().check().unwrap(),
        )
        .unwrap()
        .fit,
        warnings: vec![],
        direction: Default::default(),
    };
    let mut p = Predictor::new(&truth, &["temp_c".to_string()]).unwrap();
    let mut rng = SimRng::new(seed);
    let bias: Vec<f64> = rows
        .iter()
        .map(|&(t, x, c)| {
            let y = p.peek(t, x, &[c]) + noise * rng.normal();
            p.step(t, x, &[c], Some(y));
            y
        })
        .collect();
    (parse(&csv(rows, &bias)), truth)
}

/// The Dahl rate `r` a term with a searched rate reports (its `.r` parameter).
fn reported_rate(t: &Arc<dyn biasctl::Term>) -> f64 {
    let n = t.param_names().len();
    t.report(&vec![1.0; n], &vec![0.0; n * n], None)
        .iter()
        .find(|p| p.name.ends_with(".r"))
        .map_or(f64::NAN, |p| p.value)
}

/// The term with its searched coordinate set so that its rate is `r` (to the coordinate's
/// quantisation): the search coordinate is ln L scaled to the log's range, not `ln(1 − r)`, so
/// the truth is placed by bisection (the rate rises with the coordinate).
fn with_rate(t: &Arc<dyn biasctl::Term>, r: f64) -> Arc<dyn biasctl::Term> {
    let (mut lo, mut hi) = (0.0f64, 1.0f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if reported_rate(&t.with_nonlinear(mid).unwrap()) < r {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    t.with_nonlinear(hi).unwrap()
}

fn coef_table(term: &str, i: usize) -> f64 {
    let h = term.bytes().map(u64::from).sum::<u64>() as f64;
    match term {
        "intercept" => 12.0,
        "poly2" => [20.0, -8.0, 3.0][i],
        "direction" => 15.0,
        "dahl" => 14.0,
        _ => ((h + 3.0 * i as f64).sin() * 10.0).round() + 1.0 + i as f64,
    }
}

#[test]
fn exact_recovery_of_every_term_from_noise_free_data() {
    // Reference: the generating coefficients themselves (noise-free data, the true function is in
    // the span of each term's basis, so least squares must return them to rounding).
    let rows = tracks(1, 3000, 600.0);
    for (spec, nl) in [
        ("poly2,direction", None),
        ("table:60", None),
        ("poly2,direction,seek", None),
        ("poly2,memory", None),
        ("poly2,dahl", Some((0.05f64).ln())),
        ("poly2,dahl:3", None),
        ("poly2,col:temp_c", None),
        ("poly2,bins:dwell_s", None),
        ("direction,bins:position", None),
    ] {
        let (log, truth) = synth(&rows, spec, &coef_table, nl, 0.0, 0);
        let model = fit(
            &ModelSpec::parse(spec).unwrap(),
            &log,
            &FitOptions::default().check().unwrap(),
        )
        .unwrap();
        for (ft, tt) in model.terms.iter().zip(&truth.terms) {
            assert_eq!(ft.term.name(), tt.term.name());
            for (a, b) in ft.coefficients.iter().zip(&tt.coefficients) {
                assert!(
                    (a - b).abs() < 1e-5 * b.abs().max(1.0),
                    "{spec}: {} fitted {a} true {b}",
                    ft.term.name()
                );
            }
        }
        if nl.is_some() {
            // Reference: the rate the generating term reports.
            let r = model.param("dahl.r").unwrap().value;
            let r_true = truth
                .terms
                .iter()
                .find(|t| t.term.name() == "dahl")
                .map(|t| reported_rate(&t.term))
                .unwrap();
            assert!((r - r_true).abs() < 1e-6, "{spec}: r {r} vs {r_true}");
        }
        assert!(
            model.fit.residual_std < 1e-6,
            "{spec}: {}",
            model.fit.residual_std
        );
    }
}

#[test]
fn noisy_recovery_within_reported_standard_errors() {
    // Reference: the generating parameters; each estimate must lie within 4 reported standard
    // errors (a 4-sigma band; seeds fixed).
    let rows = tracks(2, 4000, 800.0);
    let t_true = (0.1f64).ln();
    let (log, truth) = synth(
        &rows,
        "poly2,direction,col:temp_c,dahl",
        &coef_table,
        Some(t_true),
        2.0,
        9,
    );
    let model = fit(
        &ModelSpec::parse("poly2,direction,col:temp_c,dahl").unwrap(),
        &log,
        &FitOptions::default().check().unwrap(),
    )
    .unwrap();
    let mut checked = 0;
    for (ft, tt) in model.terms.iter().zip(&truth.terms) {
        let n = tt.coefficients.len();
        let truth_params = tt.term.report(&tt.coefficients, &vec![0.0; n * n], None);
        for (p, q) in ft.params.iter().zip(&truth_params) {
            let se = p.se.expect("standard error");
            assert!(
                (p.value - q.value).abs() < 4.0 * se,
                "{}: {} vs {} (se {se})",
                p.name,
                p.value,
                q.value
            );
            checked += 1;
        }
    }
    assert!(checked >= 8);
    assert!(
        (model.fit.residual_std - 2.0).abs() < 0.15,
        "{}",
        model.fit.residual_std
    );
}

#[test]
fn dahl_one_track_runs_equal_eq7_closed_form() {
    // Reference: eq. 7, F_n = s·Fc + (F_0 − s·Fc)·r^n for n one-track seeks in direction s.
    let r: f64 = 0.93;
    let mut st = DahlState::new(r);
    for _ in 0..7 {
        st.step(1.0);
    }
    let f0 = st.value();
    for n in 1..=40 {
        let g = st.step(-1.0);
        let closed = -1.0 + (f0 + 1.0) * r.powi(n);
        assert!((g - closed).abs() < 1e-12, "n {n}: {g} vs {closed}");
    }
}

#[test]
fn dahl_state_matches_naive_one_track_loop_and_stays_within_fc() {
    // Reference: eq. 6 applied |dx| times, one track at a time (slow, obvious); eq. 8 must agree,
    // and |F| ≤ Fc always.
    let mut rng = SimRng::new(5);
    let (fc, sigma) = (12.0, 1.5);
    let r = 1.0 - sigma / fc;
    let mut fast = DahlState::new(r);
    let mut naive = 0.0f64;
    for _ in 0..3000 {
        let dx = rng.below(601) as f64 - 300.0;
        let g = fast.step(dx);
        let s = dx.signum();
        for _ in 0..dx.abs() as usize {
            naive = r * naive + sigma * s;
        }
        assert!((fc * g - naive).abs() < 1e-9 * fc, "{} vs {naive}", fc * g);
        assert!((fc * g).abs() <= fc + 1e-12);
    }
    // Non-integer lengths use the exponential, still inside ±Fc.
    for _ in 0..1000 {
        let g = fast.step(rng.range(-1000.5, 1000.5));
        assert!(g.abs() <= 1.0);
    }
}

#[test]
fn dahl_predictor_fast_paths_match_eq8_and_each_other() {
    // Reference: eq. 8-9 written out with powf, G = s + (G - s)·r^|dx| (slow, obvious). The
    // per-seek `step` and the blocked `step_many` must agree with it to 1e-12 relative (of Fc,
    // the scale of G's contribution) and with each other bit for bit; the seeks mix integer
    // lengths (the table), non-integer and long ones (exp), zero-length ones and blocks that
    // do not divide STEP_BLOCK, split across calls.
    let (c, fc, sigma) = ([5.0, 0.01, -1e-6], 15.0, 1.2);
    let r: f64 = 1.0 - sigma / fc;
    let mut rng = SimRng::new(21);
    let mut x = 1000.0;
    let targets: Vec<f64> = (0..5000)
        .map(|i| {
            x += match i % 4 {
                0 => rng.below(501) as f64 - 250.0,
                1 => 0.0,
                2 => rng.range(-40.5, 40.5),
                _ => rng.below(3001) as f64 - 1500.0,
            };
            x
        })
        .collect();
    let (mut g, mut prev) = (0.0f64, None::<f64>);
    let reference: Vec<f64> = targets
        .iter()
        .map(|&x| {
            let dx = prev.map_or(0.0, |p| x - p);
            prev = Some(x);
            if dx.abs() > 0.0 {
                let s = dx.signum();
                g = s + (g - s) * r.powf(dx.abs());
            }
            c[0] + c[1] * x + c[2] * x * x + fc * g
        })
        .collect();
    let mut one = DahlPredictor::new(c, fc, sigma).unwrap();
    let stepped: Vec<f64> = targets.iter().map(|&x| one.step(x)).collect();
    let mut many = DahlPredictor::new(c, fc, sigma).unwrap();
    let mut blocked = Vec::new();
    for part in [
        &targets[..1],
        &targets[1..700],
        &targets[700..],
        &targets[..0],
    ] {
        many.step_many(part, &mut blocked);
    }
    assert_eq!(blocked.len(), targets.len());
    for i in 0..targets.len() {
        let (a, b, want) = (stepped[i], blocked[i], reference[i]);
        assert_eq!(
            a.to_bits(),
            b.to_bits(),
            "seek {i}: step {a} vs step_many {b}"
        );
        assert!(
            (a - want).abs() <= 1e-12 * fc,
            "seek {i}: {a} vs eq. 8 {want}"
        );
    }
    // Both leave the predictor in the same state.
    assert_eq!(one.peek(1234.0).to_bits(), many.peek(1234.0).to_bits());
}

#[test]
fn dahl_predictor_equals_generic_model_replay() {
    // Reference: the generic term-sum predictor on the same parameters.
    let rows = tracks(3, 500, 300.0);
    let (log, _) = synth(
        &rows,
        "poly2,dahl",
        &coef_table,
        Some((0.2f64).ln()),
        0.5,
        1,
    );
    let model = fit(
        &ModelSpec::preset("dahl").unwrap(),
        &log,
        &FitOptions::default().check().unwrap(),
    )
    .unwrap();
    let c = ["poly2.c0", "poly2.c1", "poly2.c2"].map(|n| model.param(n).unwrap().value);
    let fc = model.param("dahl.Fc").unwrap().value;
    let sigma = model.param("dahl.sigma").unwrap().value;
    let mut fast = DahlPredictor::new(c, fc, sigma).unwrap();
    let pred = model.predict_log(&log).unwrap();
    for (i, &r) in pred.rows.iter().enumerate() {
        let y = fast.step(log.row(r).track);
        assert!(
            (y - pred.predicted[i]).abs() < 1e-6,
            "row {r}: {y} vs {}",
            pred.predicted[i]
        );
    }
}

#[test]
fn memory_term_matches_full_history_scan() {
    // Reference: for every seek, scan the whole history for the nearest uncrossed rest position
    // ahead (a rest position is crossed if any later move's closed interval from its source
    // covers it), then apply the hinge formula.
    let rows = tracks(4, 800, 80.0);
    let (log, truth) = synth(&rows, "memory", &coef_table, None, 0.0, 0);
    let pred = truth.predict_log(&log).unwrap();
    let mem = truth
        .terms
        .iter()
        .find(|t| t.term.name() == "memory")
        .unwrap();
    let knots: Vec<f64> = serde_json::from_value(mem.term.settings()["knots"].clone()).unwrap();
    let k = knots.len();
    let mut moves: Vec<(f64, f64)> = Vec::new();
    let mut prev = rows[0].1;
    for (i, &(_, x, _)) in rows.iter().enumerate() {
        if i > 0 {
            moves.push((prev, x));
        }
        let dir = moves
            .iter()
            .rev()
            .map(|&(a, b)| b - a)
            .find(|d| d.abs() > 0.0)
            .map_or(0.0, f64::signum);
        let mut best: Option<f64> = None;
        for j in 0..moves.len().saturating_sub(1) {
            let (p, t) = moves[j];
            if (p - t).abs() <= 0.0 {
                continue;
            }
            let crossed = moves[j + 1..].iter().any(|&(a, b)| {
                (a - b).abs() > 0.0 && (p - a).abs() > 0.0 && p >= a.min(b) && p <= a.max(b)
            });
            let ahead = if dir > 0.0 { p > x } else { p < x };
            if !crossed && ahead && dir != 0.0 {
                let d = (p - x).abs();
                best = Some(best.map_or(d, |b: f64| b.min(d)));
            }
        }
        let side = usize::from(dir > 0.0);
        let expect: f64 = match best {
            Some(d) if dir != 0.0 => (0..k)
                .map(|j| mem.coefficients[side * k + j] * (knots[j] - d).max(0.0) / knots[k - 1])
                .sum(),
            _ => 0.0,
        };
        let c = pred.contributions[pred.term_names.iter().position(|n| n == "memory").unwrap()][i];
        assert!((c - expect).abs() < 1e-9, "row {i}: {c} vs {expect}");
        prev = x;
    }
}

#[test]
fn hinge_fit_reproduces_a_known_piecewise_linear_function() {
    // Reference: f(v) = 2 + 0.5·v − 1.5·(v − 40)₊ + 2·(v − 70)₊ on since_reversal (approximate,
    // knots from quantiles), then an exact case whose quantile knots are the true breakpoints.
    let rows = tracks(6, 2000, 200.0);
    let mut h = History::new();
    let feats: Vec<f64> = rows
        .iter()
        .map(|&(t, x, _)| h.step(t, x).since_reversal)
        .collect();
    let f = |v: f64| 2.0 + 0.5 * v - 1.5 * (v - 40.0).max(0.0) + 2.0 * (v - 70.0).max(0.0);
    let bias: Vec<f64> = feats.iter().map(|&v| f(v)).collect();
    let log = parse(&csv(&rows, &bias));
    // Knots at data quantiles do not hit 40 and 70 exactly: with 30 knots the fit is close.
    let model = fit(
        &ModelSpec::parse("bins:since_reversal:30").unwrap(),
        &log,
        &FitOptions::default().check().unwrap(),
    )
    .unwrap();
    assert!(model.fit.residual_rms < 0.8, "{}", model.fit.residual_rms);
    // Exact case: targets sweep 0..=99 uniformly (each position 20 times), so the interior
    // quantiles j/3 of position are 33 and 66 exactly.
    let sweep: Vec<(f64, f64, f64)> = (0..2000)
        .map(|i| (i as f64, ((i * 37) % 100) as f64, 0.0))
        .collect();
    let g = |v: f64| 1.0 - 0.2 * v + 0.7 * (v - 33.0).max(0.0) - 0.9 * (v - 66.0).max(0.0);
    let log = parse(&csv(
        &sweep,
        &sweep.iter().map(|r| g(r.1)).collect::<Vec<_>>(),
    ));
    let model = fit(
        &ModelSpec::parse("bins:position:2").unwrap(),
        &log,
        &FitOptions::default().check().unwrap(),
    )
    .unwrap();
    assert!(model.fit.residual_rms < 1e-9, "{}", model.fit.residual_rms);
    let knots: Vec<f64> =
        serde_json::from_value(model.terms[1].term.settings()["knots"].clone()).unwrap();
    assert_eq!(knots, vec![33.0, 66.0]);
}

#[test]
fn drift_forgetting_factor_near_the_kalman_gain_of_a_random_walk() {
    // Reference: for a random-walk offset (step sd q) plus white noise (sd s), the optimal
    // steady-state exponential-forgetting gain is the local-level Kalman gain α with
    // α²/(1 − α) = q²/s².
    let rows = tracks(7, 20000, 400.0);
    let (q, s) = (0.3, 2.0);
    let mut rng = SimRng::new(11);
    let mut w = 0.0;
    let bias: Vec<f64> = rows
        .iter()
        .map(|&(_, x, _)| {
            w += q * rng.normal();
            5.0 + 0.01 * x + w + s * rng.normal()
        })
        .collect();
    let log = parse(&csv(&rows, &bias));
    let model = fit(
        &ModelSpec::parse("poly2,drift").unwrap(),
        &log,
        &FitOptions::default().check().unwrap(),
    )
    .unwrap();
    let alpha = model.param("drift.alpha").unwrap().value;
    let l = (q / s) * (q / s);
    let kalman = 0.5 * (-l + (l * l + 4.0 * l).sqrt());
    assert!(
        (alpha / kalman - 1.0).abs() < 0.35,
        "alpha {alpha}, Kalman gain {kalman}"
    );
    let without = fit(
        &ModelSpec::parse("poly2").unwrap(),
        &log,
        &FitOptions::default().check().unwrap(),
    )
    .unwrap();
    assert!(model.fit.residual_std < 0.8 * without.fit.residual_std);
}

#[test]
fn prediction_is_causal() {
    // Reference: predictions of rows before k must not change when row k's bias changes.
    let rows = tracks(8, 600, 300.0);
    let (log, _) = synth(
        &rows,
        "poly2,direction,seek,memory",
        &coef_table,
        None,
        1.0,
        3,
    );
    let model = fit(
        &ModelSpec::preset("calibration").unwrap(),
        &log,
        &FitOptions::default().check().unwrap(),
    )
    .unwrap();
    let a = model.predict_log(&log).unwrap();
    let mut changed = log.clone();
    changed.set_bias(400, Some(1e4));
    let b = model.predict_log(&changed).unwrap();
    assert_eq!(a.predicted[..=400], b.predicted[..=400]);
    assert!(
        a.predicted[401..]
            .iter()
            .zip(&b.predicted[401..])
            .any(|(x, y)| (x - y).abs() > 1e-9),
        "drift should react"
    );
}

/// Reference: the log reader's range of a position (finite, within ±1e15). `predict_next`
/// refuses a target outside it (it gave a NaN prediction for a NaN target) and predicts a
/// finite bias at any target inside it.
#[test]
fn predict_next_refuses_a_target_that_is_no_position() {
    let rows = tracks(9, 300, 300.0);
    let (log, _) = synth(&rows, "poly2,direction", &coef_table, None, 1.0, 4);
    let model = fit(
        &ModelSpec::preset("position-direction").unwrap(),
        &log,
        &FitOptions::default().check().unwrap(),
    )
    .unwrap();
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 2e15, -1.5e15] {
        let e = biasctl::predict_next(&model, &log, Some(bad)).unwrap_err();
        assert!(
            matches!(e, biasctl::ModelError::BadTarget { .. }),
            "{bad}: {e}"
        );
        assert!(
            e.to_string().contains("finite position within ±1e15"),
            "{e}"
        );
    }
    for good in [None, Some(0.0), Some(150.5), Some(-1e15), Some(1e15)] {
        let next = biasctl::predict_next(&model, &log, good).unwrap();
        assert!(next.bias.is_finite(), "{good:?}: {next:?}");
    }
}

#[test]
fn online_peek_equals_step() {
    // Reference: Predictor::step after peek for the same seek.
    let rows = tracks(9, 400, 300.0);
    let (log, _) = synth(
        &rows,
        "poly2,direction,seek,memory,col:temp_c",
        &coef_table,
        None,
        1.0,
        3,
    );
    let model = fit(
        &ModelSpec::parse("poly2,direction,seek,memory,drift,dahl:2,col:temp_c").unwrap(),
        &log,
        &FitOptions::default().check().unwrap(),
    )
    .unwrap();
    let mut p = Predictor::new(&model, &log.schema.covariates).unwrap();
    for r in log.rows() {
        let candidates = [r.track - 7.0, r.track + 100.0, r.track];
        let peeks: Vec<f64> = candidates
            .iter()
            .map(|&c| p.peek(r.time_s, c, &r.covariates.to_vec()))
            .collect();
        let stepped = p.step(r.time_s, r.track, &r.covariates.to_vec(), r.bias);
        assert_eq!(peeks[2].to_bits(), stepped.to_bits());
    }
}

#[test]
fn spec_parsing_errors_are_clear() {
    let e = ModelSpec::parse("poly2,wobble").unwrap_err().to_string();
    assert!(e.contains("unknown term `wobble`"), "{e}");
    assert!(
        ModelSpec::parse("dahl:0")
            .unwrap_err()
            .to_string()
            .contains("from 1 to 16")
    );
    assert!(
        ModelSpec::parse("poly2,poly2")
            .unwrap_err()
            .to_string()
            .contains("twice")
    );
    assert!(
        ModelSpec::parse("table:-3")
            .unwrap_err()
            .to_string()
            .contains("positive")
    );
    assert!(
        ModelSpec::preset("nope")
            .unwrap_err()
            .to_string()
            .contains("calibration")
    );
    assert_eq!(ModelSpec::preset("dahl").unwrap().to_string(), "poly2,dahl");
}

fn sample_log(dir: &std::path::Path) -> String {
    let rows = tracks(10, 800, 300.0);
    let (log, _) = synth(
        &rows,
        "poly2,direction,col:temp_c",
        &coef_table,
        None,
        1.0,
        4,
    );
    let bias: Vec<f64> = log.rows().map(|r| r.bias.unwrap()).collect();
    write(dir, "log.csv", &csv(&rows, &bias))
}

#[test]
fn cli_fit_predict_score_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let data = sample_log(dir.path());
    let model = dir.path().join("m.json").display().to_string();
    let out = ok(&[
        "fit",
        "--data",
        &data,
        "--terms",
        "poly2,direction,col:temp_c",
        "--out",
        &model,
    ]);
    assert!(out.contains("direction.Fc"), "{out}");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    assert_eq!(m["version"], 1);
    assert_eq!(m["columns"]["covariates"][0], "temp_c");
    assert!(m["fit"]["residual_std"].as_f64().unwrap() < 1.2);
    assert!(m["warnings"].is_array());
    let pred = dir.path().join("p.csv").display().to_string();
    ok(&[
        "predict", "--model", &model, "--data", &data, "--out", &pred,
    ]);
    let text = std::fs::read_to_string(&pred).unwrap();
    assert!(
        text.starts_with(
            "time_s,track,bias,temp_c,predicted,residual,poly2,direction,col:temp_c\n"
        ),
        "{}",
        &text[..80]
    );
    assert_eq!(text.lines().count(), 801);
    let js = ok(&["score", "--model", &model, "--data", &data, "--json"]);
    let s: serde_json::Value = serde_json::from_str(&js).unwrap();
    for key in [
        "n",
        "mean",
        "std",
        "rms",
        "histogram",
        "bimodality",
        "trend",
    ] {
        assert!(s.get(key).is_some(), "missing {key}");
    }
    assert_eq!(s["n"], 800);
    assert!(
        s["histogram"]["edges"].as_array().unwrap().len()
            == s["histogram"]["counts"].as_array().unwrap().len() + 1
    );
    // The dip test: an object, and `bimodal` is its verdict at 5 %.
    let dip = &s["dip"];
    let p = dip["p_value"].as_f64().unwrap();
    assert!(dip["statistic"].as_f64().unwrap() > 0.0 && (0.0..=1.0).contains(&p));
    assert_eq!(dip["n"], 800);
    assert_eq!(dip["modal_interval"].as_array().unwrap().len(), 2);
    assert_eq!(s["bimodal"].as_bool().unwrap(), p < 0.05);
    let txt = ok(&["score", "--model", &model, "--data", &data]);
    assert!(txt.contains("rms"), "{txt}");
    assert!(
        txt.contains("bimodality coefficient") && txt.contains("dip test D "),
        "{txt}"
    );
}

#[test]
fn cli_bad_inputs_exit_2_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("m.json").display().to_string();
    let one = write(
        dir.path(),
        "one.csv",
        &(0..20).fold("time_s,track,bias\n".to_string(), |s, i| {
            s + &format!("{i},100,{}\n", i % 3)
        }),
    );
    fails_with(
        &[
            "fit",
            "--data",
            &one,
            "--model",
            "position-direction",
            "--out",
            &out,
        ],
        &["one.csv", "poly2.a1", "cannot be determined"],
    );
    let short = write(
        dir.path(),
        "short.csv",
        "time_s,track,bias\n0,1,1\n1,5,2\n2,3,1\n",
    );
    fails_with(
        &[
            "fit",
            "--data",
            &short,
            "--model",
            "calibration",
            "--out",
            &out,
        ],
        &["short.csv", "3 measured rows", "needs at least"],
    );
    let data = sample_log(dir.path());
    fails_with(
        &[
            "fit",
            "--data",
            &data,
            "--terms",
            "poly2,bogus",
            "--out",
            &out,
        ],
        &["--terms", "unknown term `bogus`"],
    );
    fails_with(
        &[
            "fit",
            "--data",
            &data,
            "--terms",
            "col:humidity",
            "--out",
            &out,
        ],
        &["humidity", "temp_c"],
    );
    assert!(!std::path::Path::new(&out).exists());

    ok(&[
        "fit",
        "--data",
        &data,
        "--terms",
        "poly2,col:temp_c",
        "--out",
        &out,
    ]);
    let text = std::fs::read_to_string(&out).unwrap();
    let pred = dir.path().join("p.csv").display().to_string();
    let v2 = write(
        dir.path(),
        "v2.json",
        &text.replace("\"version\": 1", "\"version\": 2"),
    );
    fails_with(
        &["predict", "--model", &v2, "--data", &data, "--out", &pred],
        &["v2.json", "version 2", "refit"],
    );
    let bad = write(dir.path(), "bad.json", &text[..text.len() / 2]);
    fails_with(
        &["score", "--model", &bad, "--data", &data],
        &["bad.json", "not a valid biasctl model"],
    );
    let nocov = write(
        dir.path(),
        "nocov.csv",
        "time_s,track,bias\n0,1,1\n1,5,2\n2,3,1\n",
    );
    fails_with(
        &["predict", "--model", &out, "--data", &nocov, "--out", &pred],
        &["col:temp_c", "`temp_c`", "lacks"],
    );
    assert!(!std::path::Path::new(&pred).exists());
}

#[test]
fn calibration_preset_survives_a_table_dominated_training_run() {
    // Regression: with knots up to the farthest training value, the seek and memory curves were
    // non-zero on every training row and nearly duplicated the direction term; on a calibration
    // run of Tables I–VII plus only 500 random seeks that gave memory coefficients of ±500
    // counts and a test error of 28 counts. Reference: the same preset fitted on the default
    // calibration run (2000 random seeks) scores 7.8 counts on this test run; the drive's memory
    // effect is at most 18 counts, so the fitted memory curve must stay within a few times that.
    use biasctl::{Drive, SequenceOptions, SimConfig, simulate_log};
    let sim = |seq: &str, n: u64, seed: u64| {
        let opts = SequenceOptions {
            n: Some(n),
            ..SequenceOptions::default()
        };
        simulate_log(&SimConfig::new(Drive::paper1997(), seq, &opts, seed, &[]).unwrap()).unwrap()
    };
    let test = sim("random", 2000, 2);
    let spec = ModelSpec::preset("calibration").unwrap();
    let test_std = |n: u64| {
        let model = fit(
            &spec,
            &sim("calibration", n, 1),
            &FitOptions::default().check().unwrap(),
        )
        .unwrap();
        let p = model.predict_log(&test).unwrap();
        let sd = biasctl::std_dev(&p.residual).unwrap();
        let k = p.term_names.iter().position(|n| n == "memory").unwrap();
        let largest = p.contributions[k]
            .iter()
            .fold(0.0f64, |m, c| m.max(c.abs()));
        (sd, largest)
    };
    let (full, _) = test_std(2000);
    assert!(full < 8.5, "reference run {full}");
    for n in [300, 500, 1000] {
        let (sd, largest) = test_std(n);
        assert!(sd < 1.2 * full, "n = {n}: {sd} vs {full}");
        assert!(
            largest < 50.0,
            "n = {n}: memory contribution up to {largest}"
        );
    }
}

#[test]
fn model_files_record_the_fitted_position_range_and_older_files_still_load() {
    // Reference: the training log's measured targets span [1400, 1650] by construction.
    let rows: Vec<(f64, f64, f64)> = (0..200)
        .map(|i| (i as f64, 1400.0 + ((i * 37) % 251) as f64, 0.0))
        .collect();
    let bias: Vec<f64> = rows.iter().map(|r| 0.01 * r.1).collect();
    let log = parse(&csv(&rows, &bias));
    let model = fit(
        &ModelSpec::parse("poly2,direction").unwrap(),
        &log,
        &FitOptions::default().check().unwrap(),
    )
    .unwrap();
    assert_eq!(model.fit.position_range, Some([1400.0, 1650.0]));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.json");
    model.save(&path).unwrap();
    let again = FittedModel::load(&path).unwrap();
    assert_eq!(again.fit.position_range, Some([1400.0, 1650.0]));
    let w = again.outside_range(&[1390.0, 1500.0, 1700.0]).unwrap();
    assert_eq!((w.outside, w.total, w.seen), (2, 3, [1390.0, 1700.0]));
    assert!(w.to_string().contains("2 of 3 targets"), "{w}");
    // A model file written before the range was recorded: loads, and cannot warn.
    let mut v: serde_json::Value = serde_json::from_str(&model.to_json().unwrap()).unwrap();
    v["fit"].as_object_mut().unwrap().remove("position_range");
    std::fs::write(&path, v.to_string()).unwrap();
    let old = FittedModel::load(&path).unwrap();
    assert_eq!(old.fit.position_range, None);
    assert!(old.outside_range(&[0.0, 1e9]).is_none());
}

#[test]
fn dbins_without_a_direction_term_warns_and_with_one_does_not() {
    // Reference: `dbins` has no direction×constant column by design; the warning says so.
    let rows = tracks(9, 400, 200.0);
    let mut h = History::new();
    let bias: Vec<f64> = rows
        .iter()
        .map(|&(t, x, _)| {
            let f = h.step(t, x);
            0.01 * x + 5.0 * f64::from(f.direction) * (1.0 - (-f.dwell_s).exp())
        })
        .collect();
    let log = parse(&csv(&rows, &bias));
    let warns = |spec: &str| {
        fit(
            &ModelSpec::parse(spec).unwrap(),
            &log,
            &FitOptions::default().check().unwrap(),
        )
        .unwrap()
        .warnings
        .join("\n")
    };
    assert!(warns("poly2,dbins:dwell_s").contains("no direction×constant column"));
    assert!(!warns("poly2,direction,dbins:dwell_s").contains("direction×constant"));
    assert!(!warns("poly2,dahl,dbins:dwell_s").contains("direction×constant"));
}

#[test]
fn a_required_column_named_as_a_covariate_is_explained_not_called_missing() {
    let dir = tempfile::tempdir().unwrap();
    let log = sample_log(dir.path());
    let out = dir.path().join("m.json").display().to_string();
    for (terms, needles) in [
        ("poly2,col:track", ["`track`", "position column", "poly2"]),
        (
            "poly2,bins:bias",
            ["`bias`", "bias column", "cannot be one of its inputs"],
        ),
        ("poly2,dbins:time_s", ["`time_s`", "time column", "drift"]),
    ] {
        fails_with(
            &["fit", "--data", &log, "--terms", terms, "--out", &out],
            &needles,
        );
        assert!(!std::path::Path::new(&out).exists(), "nothing written");
    }
    // A real covariate still works.
    ok(&[
        "fit",
        "--data",
        &log,
        "--terms",
        "poly2,col:temp_c",
        "--out",
        &out,
    ]);
}

#[test]
fn commands_warn_when_a_log_goes_beyond_the_fitted_position_range() {
    // Reference: the model is fitted on targets in [0, 300] (tracks()), the second log is the
    // same seeks shifted by +1000 tracks: every target lies outside.
    let dir = tempfile::tempdir().unwrap();
    let log = sample_log(dir.path());
    let rows = tracks(10, 800, 300.0);
    let shifted: Vec<(f64, f64, f64)> = rows.iter().map(|r| (r.0, r.1 + 1000.0, r.2)).collect();
    let bias: Vec<f64> = shifted.iter().map(|r| 0.01 * r.1).collect();
    let far = write(dir.path(), "far.csv", &csv(&shifted, &bias));
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
    let inside = crate::common::biasctl(&["score", "--model", &model, "--data", &log]);
    assert_eq!(inside.code, 0);
    assert!(!inside.stderr.contains("warning"), "{}", inside.stderr);
    let pred = dir.path().join("p.csv").display().to_string();
    for args in [
        vec!["score", "--model", &model, "--data", &far],
        vec!["predict", "--model", &model, "--data", &far, "--out", &pred],
        vec!["diagnose", "--model", &model, "--data", &far],
    ] {
        let r = crate::common::biasctl(&args);
        assert_eq!(r.code, 0, "{args:?}: {}", r.stderr);
        assert!(
            r.stderr.contains("warning: ")
                && r.stderr.contains("800 of 800 targets")
                && r.stderr.contains("outside the position range"),
            "{args:?}: {}",
            r.stderr
        );
    }
    // The report on such a log says it in the page.
    let rep = dir.path().join("rep");
    let rep_s = rep.display().to_string();
    ok(&["report", "--data", &far, "--model", &model, "--out", &rep_s]);
    let html = std::fs::read_to_string(rep.join("report.html")).unwrap();
    assert!(
        html.contains("Warning about your model: 800 of 800 targets"),
        "no warning in the report"
    );
}
