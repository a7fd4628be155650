//! The paper's headline numbers, ours beside the paper's, and what better bias prediction buys
//! in settle time. Prints two markdown tables (the README's).
//!
//! ```sh
//! cargo run --release --example paper_table                    # built-in drive, 5 seed pairs
//! cargo run --release --example paper_table -- --seeds 10 --drive my_drive.toml
//! ```
//!
//! Protocol: fit each model on a calibration run (`simulate --sequence
//! calibration --seed 2k−1`), score it on a separate random run of 2000 seeks in a 250-track span
//! (`simulate --sequence random --seed 2k --n 2000 --span 250`), k = 1..seeds. The first pair is
//! the issue's (seeds 1 and 2). Numbers are mean ± sample standard deviation over the pairs.
//! position-direction is calibrated as the paper (and 1997 industry practice) does it: b_p and Fc
//! from the two Fig. 3 curves of the Table I run (same seed); a last row refits it on the whole
//! calibration run for comparison. "Two humps" is Hartigans' dip test rejecting a unimodal error
//! distribution at 1 % on that seed pair's test run.

use biasctl::ModelSpec;
use biasctl::control::Controller;
use biasctl::{Drive, SequenceOptions, SimConfig, simulate_log};
use biasctl::{FitOptions, fit};
use biasctl::{HandoffTable, SettleSpec, control::worst_case_settle};
use biasctl::{Score, score};
use biasctl::{numeric::mean, numeric::std_dev};

/// (label, term list or preset, training sequence, the paper's error std in counts). The first
/// row is the paper's baseline: position+direction calibrated the 1997 way, b_p and Fc from the
/// two far curves of Table I.
const MODELS: [(&str, &str, &str, Option<f64>); 5] = [
    (
        "position-direction, calibrated on Table I (1997 practice)",
        "position-direction",
        "table1",
        Some(19.0),
    ),
    ("calibration", "calibration", "calibration", Some(7.9)),
    ("dahl", "dahl", "calibration", Some(11.5)),
    ("poly2,dahl:4", "poly2,dahl:4", "calibration", None),
    (
        "position-direction, refit on the calibration run",
        "position-direction",
        "calibration",
        None,
    ),
];

fn spec(s: &str) -> Result<ModelSpec, biasctl::SpecError> {
    ModelSpec::preset(s).or_else(|_| ModelSpec::parse(s))
}

fn pm(v: &[f64], digits: usize) -> String {
    let m = mean(v).unwrap_or(f64::NAN);
    match std_dev(v) {
        Some(s) if v.len() > 1 => format!("{m:.digits$} ± {s:.digits$}"),
        _ => format!("{m:.digits$}"),
    }
}

/// A p-value for the table; the dip test's table resolves p down to 1e-5.
fn fmt_p(p: f64) -> String {
    if p < 1e-5 {
        "< 1e-5".into()
    } else {
        format!("{p:.2}")
    }
}

fn main() -> anyhow::Result<()> {
    let mut drive = Drive::paper1997();
    let mut seeds = 5u64;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--drive" => {
                let p = args
                    .next()
                    .ok_or_else(|| anyhow::anyhow!("--drive FILE.toml"))?;
                drive = Drive::from_toml_file(std::path::Path::new(&p))?;
            }
            "--seeds" => {
                seeds = args
                    .next()
                    .and_then(|s| s.parse().ok())
                    .filter(|&n| n >= 1)
                    .ok_or_else(|| anyhow::anyhow!("--seeds N (N ≥ 1)"))?;
            }
            _ => anyhow::bail!(
                "unknown argument {a}; usage: paper_table [--drive FILE.toml] [--seeds N]"
            ),
        }
    }
    let test_opts = SequenceOptions {
        n: Some(2000),
        span: Some(250.0),
        ..SequenceOptions::default()
    };
    // scores[model][pair]
    let mut scores: Vec<Vec<Score>> = vec![Vec::new(); MODELS.len()];
    for k in 1..=seeds {
        let train_log = |sequence: &str| {
            let cfg = SimConfig::new(
                drive.clone(),
                sequence,
                &SequenceOptions::default(),
                2 * k - 1,
                &[],
            )?;
            anyhow::Ok(simulate_log(&cfg)?)
        };
        let (calibration, table1) = (train_log("calibration")?, train_log("table1")?);
        let test_cfg = SimConfig::new(drive.clone(), "random", &test_opts, 2 * k, &[])?;
        let test = simulate_log(&test_cfg)?;
        for (m, (_, s, train, _)) in MODELS.iter().enumerate() {
            let train = if *train == "table1" {
                &table1
            } else {
                &calibration
            };
            let model = fit(&spec(s)?, train, &FitOptions::default().check()?)?;
            let p = model.predict_log(&test)?;
            scores[m].push(score(&p.residual, &p.positions)?);
        }
    }
    let col =
        |m: usize, f: &dyn Fn(&Score) -> f64| -> Vec<f64> { scores[m].iter().map(f).collect() };
    let pd_std = col(0, &|s| s.std);
    println!(
        "Error of each model on random seeks in a 250-track span (n = {} per run; mean ± std over {seeds} training/test seed pairs; first pair: seeds 1/2)\n",
        scores[0][0].n
    );
    println!(
        "| model | paper std | our std (counts) | seeds 1/2 | reduction vs pd (Table I) | paper | two humps (dip test p < 0.01) | dip p (median) | Sarle's BC | trend p (median) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (m, (label, _, _, paper)) in MODELS.iter().enumerate() {
        let std = col(m, &|s| s.std);
        let red: Vec<f64> = std
            .iter()
            .zip(&pd_std)
            .map(|(s, p)| 100.0 * (1.0 - s / p))
            .collect();
        let bc = col(m, &|s| s.bimodality.unwrap_or(f64::NAN));
        let mut dp = col(m, &|s| s.dip.as_ref().map_or(f64::NAN, |d| d.p_value));
        dp.sort_by(f64::total_cmp);
        let humps = dp.iter().filter(|&&p| p < 0.01).count();
        let mut tp = col(m, &|s| s.trend.map_or(f64::NAN, |t| t.p_value));
        tp.sort_by(f64::total_cmp);
        let paper_red = paper.map_or("–".to_string(), |p| {
            if *paper == Some(19.0) {
                "–".into()
            } else {
                format!("{:.0} %", 100.0 * (1.0 - p / 19.0))
            }
        });
        println!(
            "| `{label}` | {} | {} | {:.2} | {} | {paper_red} | {humps}/{seeds} | {} | {} | {:.2e} |",
            paper.map_or("–".to_string(), |p| format!("≈ {p}")),
            pm(&std, 2),
            std[0],
            if m == 0 {
                "–".to_string()
            } else {
                format!("{} %", pm(&red, 0))
            },
            fmt_p(dp[dp.len() / 2]),
            pm(&bc, 2),
            tp[tp.len() / 2],
        );
    }
    // Prediction → settling: Δb = the model's test-run error std.
    let cfg = SettleSpec::preset("paper1997")?.check()?;
    let ctl = Controller::design(&cfg.plant, &cfg.weights)?;
    let table = HandoffTable::new(&ctl, cfg.scenario.horizon)?;
    let h = cfg.scenario.handoff();
    println!(
        "\nWorst-case settle time (paper1997 settle preset: 15 µm step, ±0.5 µm window) when the bias is known to ± Δb, Δb = the model's error std on the test runs (mean over seeds)\n"
    );
    println!(
        "| model | Δb = test error std (counts) | worst-case settle, robust choice (ms) | worst-case settle, zero feedforward (ms) |"
    );
    println!("|---|---|---|---|");
    let ms = |v: Option<f64>| v.map_or("not settled".to_string(), |m| format!("{m:.2}"));
    for (m, (label, _, _, _)) in MODELS.iter().enumerate() {
        let db = mean(&col(m, &|s| s.std)).unwrap_or(f64::NAN);
        let wc = worst_case_settle(&table, &h, &cfg.scenario.window, db)?;
        println!(
            "| `{label}` | {db:.2} | {} | {} |",
            ms(wc.robust_worst_settle_ms),
            ms(wc.zero_ff_worst_settle_ms)
        );
    }
    // Where prediction error starts to cost settle time on this loop.
    println!(
        "\nWorst-case settle time against the bias uncertainty Δb (same preset; the robust start value is chosen for each Δb)\n"
    );
    println!("| Δb (counts) | robust choice (ms) | zero feedforward (ms) |");
    println!("|---|---|---|");
    for db in [0.0, 4.0, 8.0, 13.0, 19.0, 30.0, 50.0, 80.0] {
        let wc = worst_case_settle(&table, &h, &cfg.scenario.window, db)?;
        println!(
            "| {db} | {} | {} |",
            ms(wc.robust_worst_settle_ms),
            ms(wc.zero_ff_worst_settle_ms)
        );
    }
    Ok(())
}
