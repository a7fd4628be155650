//! `settle`: the paper's Section IV golden values, the handoff fast path against a naive
//! simulation, the robust choice against simulated biases, CLI contracts and bad plant files.

use crate::common::{
    biasctl, data, fails_with, no_nonfinite, ok, random_log_and_model, simulate_random_args, write,
};
use biasctl::{
    HandoffTable, SettleSpec, SimRng, analyse, control::Bounds, control::Controller,
    control::Handoff, control::Window, control::handoff_state, control::settle_index,
};

fn controller(preset: &str) -> Controller {
    let cfg = SettleSpec::preset(preset).unwrap().check().unwrap();
    Controller::design(&cfg.plant, &cfg.weights).unwrap()
}

fn close(got: f64, want: f64, tol: f64) -> bool {
    (got - want).abs() <= tol
}

/// Reference: golden values from python-control `dlqr` and a direct simulation of the paper's
/// test bed; paper text: one-track settle < 3 ms with < 30 % overshoot.
#[test]
fn paper1997_golden_values() {
    let cfg = SettleSpec::preset("paper1997").unwrap().check().unwrap();
    let r = analyse(&cfg).unwrap();
    let k_want = [3.30099, 35.5194, 0.0143960, 0.550064];
    for (g, w) in r.gain.iter().zip(k_want) {
        assert!(close(*g, w, 2e-5 * w.abs().max(1.0)), "K = {:?}", r.gain);
    }
    let p_want = [0.0, 0.20245, 0.86726, 0.86726];
    for (p, w) in r.poles_abs.iter().zip(p_want) {
        assert!(close(*p, w, 1e-5), "poles {:?}", r.poles_abs);
    }
    assert!(close(r.dz_dbias, -0.46958, 1e-5));
    assert_eq!(r.k_star, Some(14));
    assert!(close(r.optimal_settle_ms.unwrap(), 1.4, 1e-9));
    assert!(close(r.zero_ff_settle_ms.unwrap(), 2.8, 1e-9));
    let [lo, hi] = r.ff_interval.unwrap();
    assert!(
        close(lo, 83.55, 5e-3) && close(hi, 89.36, 5e-3),
        "[{lo}, {hi}]"
    );

    let mut spec = SettleSpec::preset("paper1997").unwrap();
    spec.step_um = 5.0;
    let r5 = analyse(&spec.check().unwrap()).unwrap();
    assert!(close(r5.zero_ff_settle_ms.unwrap(), 2.2, 1e-9));
    assert!(
        close(r5.zero_ff_overshoot_pct, 25.0, 0.5),
        "{}",
        r5.zero_ff_overshoot_pct
    );
}

/// The fast path (precomputed coefficients, one backward pass, no allocation) against a naive
/// reference that simulates the loop twice (ζ = 0 and ζ = 1) to get a_k and c_k, builds eq. 14's
/// bounds and eq. 15's running min/max directly, and settles simulated responses by definition.
#[test]
fn fast_path_equals_naive_simulation() {
    let mut rng = SimRng::new(4);
    for preset in ["paper1997", "modern"] {
        let ctl = controller(preset);
        let spec = SettleSpec::preset(preset).unwrap();
        let scale = spec.step_um;
        let dz = ctl.dz_dbias().abs();
        for case in 0..60 {
            let n = 1 + rng.below(200) as usize;
            let hold = 1 + rng.below(4.min(n as u64)) as usize;
            let delta = scale * rng.range(0.005, 0.3);
            let window = Window::new(delta, hold).unwrap();
            let h = Handoff {
                e0_um: scale * rng.range(-2.0, 2.0),
                v0_um_s: scale * rng.range(-2000.0, 2000.0),
                u_prev_counts: rng.range(-20.0, 20.0),
                bias_counts: rng.range(-20.0, 20.0),
            };
            let db = rng.range(0.0, 3.0);
            let table = HandoffTable::new(&ctl, n).unwrap();
            let mut buf = Bounds::new(n);
            table.bounds_into(&h, &window, &mut buf).unwrap();
            let sol = table.solve(&h, &window, db);

            // Naive reference.
            let (mut e0, mut e1) = (Vec::new(), Vec::new());
            ctl.simulate_error(&handoff_state(&ctl, &h, 0.0), n, &mut e0);
            ctl.simulate_error(&handoff_state(&ctl, &h, 1.0), n, &mut e1);
            let (mut umin, mut lmax) = (f64::INFINITY, f64::NEG_INFINITY);
            let mut run = vec![(0.0, 0.0); n];
            for k in (0..n).rev() {
                let a = e1[k] - e0[k];
                let c = e0[k];
                let (lo, up) = if a.abs() <= 1e-12 * (1.0 + c.abs()) {
                    if c.abs() <= delta {
                        (f64::NEG_INFINITY, f64::INFINITY)
                    } else {
                        (f64::INFINITY, f64::NEG_INFINITY)
                    }
                } else if a > 0.0 {
                    ((-delta - c) / a, (delta - c) / a)
                } else {
                    ((delta - c) / a, (-delta - c) / a)
                };
                if lo.is_finite() {
                    let tol = 1e-7 * (1.0 + lo.abs());
                    assert!(close(buf.lower()[k], lo, tol), "{preset} case {case} k {k}");
                    assert!(close(buf.upper()[k], up, 1e-7 * (1.0 + up.abs())));
                }
                umin = umin.min(up);
                lmax = lmax.max(lo);
                run[k] = (lmax, umin);
            }
            let naive_opt = (0..=n - hold).find(|&k| run[k].0 <= run[k].1);
            let fast_opt = sol.optimal.map(|i| i.k);
            assert_eq!(fast_opt, naive_opt, "{preset} case {case}: k*");
            assert_eq!(buf.optimal().map(|i| i.k), naive_opt);
            if let Some(o) = sol.optimal {
                // The midpoint settles exactly at k* in a direct simulation.
                let mut e = Vec::new();
                ctl.simulate_error(&handoff_state(&ctl, &h, o.choice(0.0)), n, &mut e);
                if o.hi - o.lo > 1e-9 * (1.0 + o.lo.abs()) {
                    assert_eq!(settle_index(&e, &window), Some(o.k), "{preset} case {case}");
                }
            }
            let s = dz * db;
            let naive_rob = (0..=n - hold).find(|&k| run[k].1 - run[k].0 >= 2.0 * s);
            assert_eq!(
                sol.robust.map(|i| i.k),
                naive_rob,
                "{preset} case {case}: robust"
            );
            let naive_zero = (0..=n - hold).find(|&k| run[k].0 <= -s && s <= run[k].1);
            assert_eq!(
                sol.zero_ff_worst, naive_zero,
                "{preset} case {case}: zero ff"
            );
            // Any start value: settle index from the running bounds = settle of the simulation.
            for _ in 0..3 {
                let zeta =
                    sol.optimal.map_or(0.0, |o| o.choice(0.0)) + scale * rng.range(-5.0, 5.0);
                let mut e = Vec::new();
                ctl.simulate_error(&handoff_state(&ctl, &h, zeta), n, &mut e);
                assert_eq!(buf.settle_index_of(zeta), settle_index(&e, &window));
            }
        }
    }
}

/// a_0 = 0 always (the integrator reaches e one sample later): the first sample constrains
/// nothing when |e0| ≤ δ and rules out settling at 0 otherwise.
#[test]
fn zero_gain_sample_is_handled() {
    let ctl = controller("paper1997");
    let table = HandoffTable::new(&ctl, 64).unwrap();
    let window = Window::new(0.5, 1).unwrap();
    let rest = Handoff {
        e0_um: 0.0,
        v0_um_s: 0.0,
        u_prev_counts: 3.0,
        bias_counts: 3.0,
    };
    let sol = table.solve(&rest, &window, 0.0);
    let o = sol.optimal.unwrap();
    assert_eq!(o.k, 0);
    assert!(o.lo <= 0.0 && 0.0 <= o.hi);
    assert_eq!(sol.zero_ff_worst, Some(0));
    let mut buf = Bounds::new(64);
    let off = Handoff { e0_um: 0.6, ..rest };
    table.bounds_into(&off, &window, &mut buf).unwrap();
    assert_eq!(buf.upper()[0], f64::NEG_INFINITY);
    assert!(table.solve(&off, &window, 0.0).optimal.unwrap().k >= 1);
}

/// Our robust choice: simulate 201 biases across ±Δb with the start value computed for the
/// predicted bias; the worst settle equals the reported worst case, no start value does better
/// (the interval one sample earlier is narrower than 2|∂z/∂d|Δb), and zero feedforward's worst
/// case matches its simulation too.
#[test]
fn robust_choice_worst_case_verified_by_simulation() {
    let cfg = SettleSpec::preset("paper1997").unwrap().check().unwrap();
    let ctl = Controller::design(&cfg.plant, &cfg.weights).unwrap();
    let sc = cfg.scenario;
    let n = sc.horizon;
    let h = sc.handoff();
    let table = HandoffTable::new(&ctl, n).unwrap();
    for db in [2.0, 8.0, 20.0] {
        let wc = biasctl::control::worst_case_settle(&table, &h, &sc.window, db).unwrap();
        let ff = wc.robust_ff.unwrap();
        let worst_sim = |start: f64| {
            (0..=200)
                .map(|j| {
                    let err = db * (j as f64 / 100.0 - 1.0);
                    let mut e = Vec::new();
                    ctl.simulate_error(
                        &handoff_state(&ctl, &h, start + ctl.dz_dbias() * err),
                        n,
                        &mut e,
                    );
                    settle_index(&e, &sc.window).unwrap_or(usize::MAX)
                })
                .max()
                .unwrap()
        };
        assert_eq!(worst_sim(ff), wc.robust_k.unwrap(), "Δb = {db}");
        assert_eq!(worst_sim(0.0), wc.zero_ff_k.unwrap(), "Δb = {db}");
        let mut buf = Bounds::new(n);
        table.bounds_into(&h, &sc.window, &mut buf).unwrap();
        let k = wc.robust_k.unwrap();
        let before = buf.upper_min()[k - 1] - buf.lower_max()[k - 1];
        assert!(
            before < 2.0 * wc.shift,
            "Δb = {db}: a shorter worst case exists"
        );
        // The midpoint beats an off-centre start in the same interval.
        assert!(worst_sim(buf.upper_min()[k] - 1e-3) > k || before < 0.0);
    }
}

#[test]
fn settle_json_has_the_documented_keys() {
    let out = ok(&["settle", "--preset", "paper1997", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    for key in [
        "gain",
        "poles_abs",
        "dz_dbias",
        "k_star",
        "optimal_settle_ms",
        "ff_interval",
        "zero_ff_settle_ms",
    ] {
        assert!(!v[key].is_null(), "missing {key}");
    }
    assert!(v["paper_robust"]["ff"].is_number() && v["paper_robust"]["settle_ms"].is_number());
    assert!(v["robust"]["ff"].is_number() && v["robust"]["worst_settle_ms"].is_number());
    assert_eq!(v["k_star"], 14);
    assert_eq!(v["gain"].as_array().unwrap().len(), 4);
}

#[test]
fn settle_writes_bounds_and_responses_and_plant_file_matches_preset() {
    let dir = tempfile::tempdir().unwrap();
    let b = dir.path().join("b.csv").display().to_string();
    let r = dir.path().join("r.csv").display().to_string();
    let plant = data("plant_paper1997.toml");
    let out = ok(&[
        "settle",
        "--plant",
        &plant,
        "--json",
        "--bounds-out",
        &b,
        "--response-out",
        &r,
    ]);
    let from_file: serde_json::Value = serde_json::from_str(&out).unwrap();
    let preset: serde_json::Value =
        serde_json::from_str(&ok(&["settle", "--preset", "paper1997", "--json"])).unwrap();
    assert_eq!(from_file, preset);
    let bounds = std::fs::read_to_string(&b).unwrap();
    assert!(bounds.starts_with("k,time_s,upper,lower,upper_min,lower_max\n"));
    assert_eq!(bounds.lines().count(), 129);
    let resp = std::fs::read_to_string(&r).unwrap();
    assert!(resp.starts_with("k,time_s,e_zero_ff_um,e_optimal_um,e_paper_robust_um,e_robust_um\n"));
    // A float cell keeps its decimal point (`-15.0`): CSV readers then infer a float column.
    assert!(
        resp.lines()
            .nth(1)
            .unwrap()
            .starts_with("0,0.0000000,-15.0,")
    );
    let modern = ok(&["settle", "--plant", &data("plant_modern.toml"), "--json"]);
    let m: serde_json::Value = serde_json::from_str(&modern).unwrap();
    assert!(m["k_star"].is_number() && m["zero_ff_settle_ms"].is_number());
}

const GOOD: &str = "ts_s = 100e-6\ntau_s = 40e-6\nkp = 1e6\nq = [1e-4, 1.78e-3, 1e-9, 0.0]\n\
r = 1e-6\nstep_um = 15.0\nwindow_um = 0.5\nhorizon = 128\n";

#[test]
fn settle_bad_plant_descriptions_exit_2_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("b.csv");
    let out_s = out.display().to_string();
    let cases: [(&str, &str, &[&str]); 7] = [
        ("r0", "r = 1e-6", &["r:", "> 0"]),
        ("tau", "tau_s = 40e-6", &["tau_s"]),
        ("window", "window_um = 0.5", &["window_um", "--window-um"]),
        ("horizon", "horizon = 128", &["horizon", "--horizon"]),
        ("nan", "kp = 1e6", &["kp", "finite"]),
        ("modes", "horizon = 128", &["not stabilisable"]),
        ("unknown", "horizon = 128", &["unknown field"]),
    ];
    let replacement = |name: &str| match name {
        "r0" => "r = 0.0",
        "tau" => "tau_s = 100e-6",
        "window" => "window_um = -0.1",
        "horizon" => "horizon = 0",
        "nan" => "kp = nan",
        // An undamped mode the input cannot reach: (A, B) is not stabilisable.
        "modes" => "horizon = 128\n[[modes]]\nfreq_hz = 3000.0\ndamping = 0.0\ngain = 0.0",
        _ => "horizon = 128\nspeed = 3",
    };
    for (name, line, needles) in cases {
        let text = GOOD.replace(line, replacement(name));
        let p = write(dir.path(), &format!("{name}.toml"), &text);
        fails_with(&["settle", "--plant", &p, "--bounds-out", &out_s], needles);
        assert!(!out.exists(), "{name}: output written");
    }
    fails_with(&["settle", "--window-um", "0"], &["--window-um"]);
    fails_with(&["settle", "--hold", "0"], &["--hold"]);
    fails_with(
        &["settle", "--bias-uncertainty", "-1"],
        &["--bias-uncertainty"],
    );
    fails_with(&["settle", "--step-um", "NaN"], &["--step-um"]);
    fails_with(&["settle", "--preset", "nope"], &["paper1997"]);
    assert_eq!(
        biasctl(&["settle", "--preset", "modern", "--horizon", "0"]).code,
        2
    );
}

/// `simulate --sequence random --n n --seed seed --out out` on the default drive.
fn simulate_random(n: &str, seed: &str, out: &str) {
    ok(&simulate_random_args(n, seed, out));
}

/// `fit --data data --model preset --out out`.
fn fit_preset(data: &str, preset: &str, out: &str) {
    ok(&["fit", "--data", data, "--model", preset, "--out", out]);
}

/// `settle --model --data`: the handoff bias is the model's causal prediction for the log's last
/// row. Reference: the `predict` command's `predicted` column for that row (the same replay by
/// another path), and Δb is the fit's residual std from the model file; the worst case must equal
/// a plain `settle --bias-uncertainty Δb` run.
#[test]
fn settle_with_model_uses_the_prediction_for_the_last_target_and_the_error_std() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    simulate_random("400", "3", &p("train.csv"));
    simulate_random("200", "4", &p("test.csv"));
    fit_preset(&p("train.csv"), "calibration", &p("m.json"));
    ok(&[
        "predict",
        "--model",
        &p("m.json"),
        "--data",
        &p("test.csv"),
        "--out",
        &p("pred.csv"),
    ]);
    let pred = std::fs::read_to_string(p("pred.csv")).unwrap();
    let mut lines = pred.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == "predicted").unwrap();
    let last: Vec<&str> = lines.next_back().unwrap().split(',').collect();
    let predicted: f64 = last[col].parse().unwrap();

    let out = ok(&[
        "settle",
        "--model",
        &p("m.json"),
        "--data",
        &p("test.csv"),
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let bias = v["prediction"]["bias"].as_f64().unwrap();
    assert!(
        (bias - predicted).abs() < 1e-3 * predicted.abs().max(1.0),
        "{bias} vs {predicted}"
    );

    let model: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(p("m.json")).unwrap()).unwrap();
    let std = model["fit"]["residual_std"].as_f64().unwrap();
    let delta_b = v["prediction"]["delta_b"].as_f64().unwrap();
    assert!((delta_b - std).abs() < 1e-12, "{delta_b} vs {std}");

    let plain = ok(&["settle", "--bias-uncertainty", &format!("{std}"), "--json"]);
    let w: serde_json::Value = serde_json::from_str(&plain).unwrap();
    assert_eq!(
        v["robust"]["worst_settle_ms"],
        w["robust"]["worst_settle_ms"]
    );
    assert_eq!(
        v["prediction"]["zero_ff_worst_settle_ms"],
        w["worst_case"]["zero_ff_worst_settle_ms"]
    );
    // --target predicts a seek after the last row; a different target gives a different bias.
    let t = ok(&[
        "settle",
        "--model",
        &p("m.json"),
        "--data",
        &p("test.csv"),
        "--target",
        "1000",
        "--json",
    ]);
    let tv: serde_json::Value = serde_json::from_str(&t).unwrap();
    assert_eq!(tv["prediction"]["target"].as_f64(), Some(1000.0));
    assert_eq!(tv["prediction"]["rows_replayed"].as_u64(), Some(200));
}

#[test]
fn settle_with_model_bad_inputs_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).display().to_string();
    simulate_random("200", "3", &p("log.csv"));
    fit_preset(&p("log.csv"), "position-direction", &p("m.json"));
    fails_with(&["settle", "--model", &p("m.json")], &["--data"]);
    fails_with(
        &[
            "settle",
            "--model",
            &p("nope.json"),
            "--data",
            &p("log.csv"),
        ],
        &["nope.json"],
    );
    fails_with(
        &[
            "settle",
            "--model",
            &p("m.json"),
            "--data",
            &p("log.csv"),
            "--bias-col",
            "force",
        ],
        &["missing required column `force`", "--bias-col"],
    );
}

// ---- outputs that do not settle

#[test]
fn settle_bounds_csv_has_no_infinities() {
    let dir = tempfile::tempdir().unwrap();
    let bounds = dir.path().join("b.csv").display().to_string();
    let resp = dir.path().join("r.csv").display().to_string();
    ok(&["settle", "--bounds-out", &bounds, "--response-out", &resp]);
    let b = std::fs::read_to_string(&bounds).unwrap();
    no_nonfinite(&b, "bounds CSV");
    // k = 0 has no bound: empty cells, and the row keeps its six fields.
    let row0 = b.lines().nth(1).unwrap();
    assert_eq!(row0, "0,0.0000000,,,,", "{row0}");
    no_nonfinite(&std::fs::read_to_string(&resp).unwrap(), "responses CSV");
}

#[test]
fn settle_text_says_when_zero_feedforward_does_not_settle() {
    let out = ok(&["settle", "--horizon", "5"]);
    assert!(
        out.contains("zero feedforward: does not settle within the horizon"),
        "{out}"
    );
    assert!(!out.contains("settles in not settled"), "{out}");
}

// ---- flags named as given

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
