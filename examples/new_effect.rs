//! Adding an effect the tool does not know: P3, time at track.
//!
//! ```sh
//! cargo run --release --example new_effect
//! ```
//!
//! The simulated drive (`data/diag_base.toml`, every effect on, dwell 0.05–4 s so P3 matters)
//! adds `−dir·A·(1 − e^(−t/τ))` to the bias, `t` the time at the track (the log's `dwell_s`) and
//! `dir` the approach direction. No built-in term models it. The example fits a model lacking
//! it, lets `diagnose_model` name the missing feature (`dwell_s`, by direction), then fixes the
//! model two ways and prints the test error std of each:
//! - with code: [`TimeAtTrack`] below, a physical term written through the public
//!   [`Term`]/[`TermSpec`]/[`TermState`] traits, amplitude linear and τ searched by the fit;
//! - without code: the generic term `dbins:dwell_s` (direction × piecewise-linear in `dwell_s`).
//!
//! `tests/it/extend.rs` includes this file to reuse [`TimeAtTrack`] as its reference term.

use biasctl::Log;
use biasctl::{DiagnoseConfig, Diagnosis, diagnose_model};
use biasctl::{Drive, SequenceOptions, SimConfig, simulate_log};
use biasctl::{FitData, FitError, FitOptions, fit};
use biasctl::{FittedModel, ModelError, ModelSpec};
use biasctl::{Term, TermSpec, model::Nonlinear, model::Seek, model::TermState};
use std::sync::Arc;

// ---------------------------------------------------------------------------------------------
// The new term: P3 time at track, `A · dir · (1 − e^(−dwell_s/τ))`. One type is the spec, the
// fitted term and its (stateless) per-log state. A is linear (counts; the simulator's law gives
// A = −amplitude), τ (s) is the nonlinear parameter, searched as ln τ over [0.05 s, 100 s].

/// Search interval of ln τ (τ in seconds).
const LN_TAU: (f64, f64) = (-2.995_732_273_553_991, 4.605_170_185_988_092);

/// The time-at-track term `A · dir · (1 − e^(−dwell_s/τ))`, with τ in seconds.
#[derive(Debug, Clone, Copy)]
pub struct TimeAtTrack {
    /// Time constant, s (the starting point of the search; the fit replaces it).
    pub tau_s: f64,
}

impl TermSpec for TimeAtTrack {
    fn name(&self) -> String {
        "time_at_track".into()
    }
    fn prepare(&self, _data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        Ok(Arc::new(*self))
    }
}

impl Term for TimeAtTrack {
    fn name(&self) -> String {
        "time_at_track".into()
    }
    fn param_names(&self) -> Vec<String> {
        vec!["A".into()]
    }
    fn start(&self, _covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        Ok(Box::new(*self))
    }
    fn nonlinear(&self) -> Option<Nonlinear> {
        Some(Nonlinear {
            name: "ln_tau_s".into(),
            value: self.tau_s.ln(),
            lo: LN_TAU.0,
            hi: LN_TAU.1,
        })
    }
    fn with_nonlinear(&self, ln_tau: f64) -> Option<Arc<dyn Term>> {
        let tau_s = ln_tau.clamp(LN_TAU.0, LN_TAU.1).exp();
        Some(Arc::new(TimeAtTrack { tau_s }))
    }
}

impl TermState for TimeAtTrack {
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        let f = seek.features;
        out[0] = f64::from(f.direction) * (1.0 - (-f.dwell_s.max(0.0) / self.tau_s).exp());
    }
    fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(*self)
    }
}

// ---------------------------------------------------------------------------------------------
// The demonstration.

/// The model lacking the time-at-track term.
pub const BASE: &str = "poly2,dahl:4,memory,drift";

/// Random seeks on `data/diag_base.toml` with dwell 0.05–4 s, every effect but `disabled` on.
pub fn p3_log(n: u64, seed: u64, disabled: &[&str]) -> anyhow::Result<Log> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/data/diag_base.toml");
    let drive = Drive::from_toml_file(std::path::Path::new(path))?;
    let opts = SequenceOptions {
        n: Some(n),
        dwell_min_s: Some(0.05),
        dwell_max_s: Some(4.0),
        ..SequenceOptions::default()
    };
    Ok(simulate_log(&SimConfig::new(
        drive, "random", &opts, seed, disabled,
    )?)?)
}

/// Fits `BASE` plus `extra` (built-in term strings) plus `user` (user terms) on `train`.
pub fn fit_with(
    train: &Log,
    extra: &[&str],
    user: &[Arc<dyn TermSpec>],
) -> anyhow::Result<FittedModel> {
    let mut list = vec![BASE];
    list.extend_from_slice(extra);
    let mut spec = ModelSpec::parse(&list.join(","))?;
    for t in user {
        spec = spec.with_term(t.clone());
    }
    Ok(fit(&spec, train, &FitOptions::default().check()?)?)
}

/// Standard deviation of the causal prediction error of `model` on `test`, counts.
pub fn test_std(model: &FittedModel, test: &Log) -> anyhow::Result<f64> {
    let p = model.predict_log(test)?;
    biasctl::numeric::std_dev(&p.residual).ok_or_else(|| anyhow::anyhow!("too few test rows"))
}

fn print_top(d: &Diagnosis, k: usize) {
    println!("  rank feature              explained  by_direction  flagged  suggested");
    for (i, f) in d.features.iter().take(k).enumerate() {
        println!(
            "  {:>4} {:<20} {:>8.1} %  {:<12}  {:<7}  {}",
            i + 1,
            f.name,
            100.0 * f.explained,
            f.by_direction,
            f.flagged,
            f.suggested_term.as_deref().unwrap_or("-")
        );
    }
}

#[allow(dead_code)]
fn main() -> anyhow::Result<()> {
    let (train, test) = (p3_log(3000, 1, &[])?, p3_log(3000, 2, &[])?);
    let config = DiagnoseConfig::default().check()?;
    println!(
        "drive data/diag_base.toml, every effect on, dwell 0.05–4 s, 3000 train / 3000 test seeks\n"
    );

    let base = fit_with(&train, &[], &[])?;
    let s_base = test_std(&base, &test)?;
    println!("1. `{BASE}`: test error std {s_base:.2} counts; diagnosis:");
    print_top(&diagnose_model(&base, &test, &config)?, 3);

    let time: Arc<dyn TermSpec> = Arc::new(TimeAtTrack { tau_s: 1.0 });
    let with_time = fit_with(&train, &[], &[time])?;
    let s_time = test_std(&with_time, &test)?;
    let a = with_time
        .param("time_at_track.A")
        .map_or(f64::NAN, |p| p.value);
    let tau = with_time
        .param("time_at_track.ln_tau_s")
        .map_or(f64::NAN, |p| p.value.exp());
    println!(
        "\n2. `{BASE}` + time_at_track (the term above, through the traits): A = {a:.2} counts, \
         τ = {tau:.2} s (drive: −15, 2.5 s); test error std {s_time:.2}; diagnosis:"
    );
    print_top(&diagnose_model(&with_time, &test, &config)?, 3);

    let with_dbins = fit_with(&train, &["dbins:dwell_s"], &[])?;
    let s_dbins = test_std(&with_dbins, &test)?;
    println!("\n3. `{BASE},dbins:dwell_s` (no code): test error std {s_dbins:.2}; diagnosis:");
    print_top(&diagnose_model(&with_dbins, &test, &config)?, 3);

    let time: Arc<dyn TermSpec> = Arc::new(TimeAtTrack { tau_s: 1.0 });
    let truth = fit_with(&train, &["seek"], &[time])?;
    let s_truth = test_std(&truth, &test)?;
    println!(
        "\n4. truth-matching term set `{BASE},seek` + time_at_track (seek for the overshoot \
         the Dahl elements miss): test error std {s_truth:.2}"
    );

    println!("\ntest error std, counts:");
    println!("  {:<44} {s_base:>6.2}", "without a time-at-track term");
    println!("  {:<44} {s_dbins:>6.2}", "+ dbins:dwell_s (no code)");
    println!("  {:<44} {s_time:>6.2}", "+ time_at_track (the new term)");
    println!("  {:<44} {s_truth:>6.2}", "truth-matching term set");
    println!("  (the drive's measurement scatter alone: 4 counts)");
    Ok(())
}
