//! The scoreboard of diagnose on independent drives (`biasctl::sim::family`).
//!
//! ```sh
//! cargo run --release --example diagnose_family            # 3 drives × every scenario × 10 seeds
//! cargo run --release --example diagnose_family -- 20 2000  # seeds, seeks per log
//! cargo run --release --example diagnose_family -- 1 2000 full  # only the full-model flags
//! cargo run --release --example diagnose_family -- 5 1500 all 1 lag  # lag scenarios, each run
//! ```
//!
//! For every family drive, every hidden effect alone and a few pairs, and every seed: generate a
//! log, fit the user's model (a fine position table and `dahl:4`, which hold the drive's own
//! trend and pivot but not the hidden effect), diagnose it, and score
//! - **right first**: the first-ranked flagged feature is the effect's ([`HiddenEffect::is_right_feature`]);
//! - **recovered**: the first edit diagnose proposes (refitted on the same log) cuts the residual
//!   std by what fraction of the cut that adding the effect's true term achieves
//!   ([`HiddenEffect::true_term`]), `(std_before − std_edit)/(std_before − std_true)`;
//! - **no-effect flags**: whether any of the three no-effect columns is flagged;
//! - **clean full model**: with every effect present held by its true term, nothing flagged.
//!
//! `tests/it/family.rs` includes this file, so the test and the README numbers come from the
//! same code.

use biasctl::Log;
use biasctl::{
    CheckedDiagnoseConfig, CheckedVerifyConfig, DiagnoseConfig, Diagnosis, diagnose_verified,
    select::suggestion_path_from,
};
use biasctl::{CheckedFitOptions, FitOptions, fit};
use biasctl::{FittedModel, ModelSpec};
use biasctl::{
    sim::family::FamilyConfig, sim::family::FamilyDrive, sim::family::HiddenEffect,
    sim::family::NO_EFFECT_COLUMNS, sim::family::generate,
};

/// A held-out drive for checking that nothing was tuned to the three members: parameters
/// none of them has (a Prandtl–Ishlinskii pivot with other thresholds, a wider sinusoidal
/// trend, Student-t ν = 5 innovations with AR(1) ρ = 0.45, longer dwells, another span).
pub fn fresh_drive() -> FamilyDrive {
    use biasctl::{sim::family::Noise, sim::family::Pivot, sim::family::Trend};
    FamilyDrive {
        name: "fresh-pi-sine".into(),
        pivot: Pivot::Prandtl {
            thresholds: vec![3.0, 10.0, 25.0],
            weights: vec![5.0, 3.0, 2.5],
        },
        trend: Trend::Sine {
            offset: -12.0,
            slope: 4.0,
            amplitude: 7.0,
            cycles: 2.5,
            phase: 1.1,
        },
        noise: Noise {
            std: 1.8,
            nu: Some(5),
            rho: 0.45,
        },
        centre: 3000.0,
        span: 360.0,
        dwell_s: [0.08, 0.9],
        effect_scale: 1.0,
    }
}

/// The scenarios: every hidden effect alone, then pairs (two effects at once).
pub fn scenarios() -> Vec<Vec<HiddenEffect>> {
    use HiddenEffect::*;
    let mut s: Vec<Vec<HiddenEffect>> = HiddenEffect::ALL.iter().map(|&e| vec![e]).collect();
    s.push(vec![FastCovariate, Defect]);
    s.push(vec![Lag, PositionDirection]);
    s.push(vec![SummedMemory, Threshold]);
    s
}

/// The user's model for a drive: a position table with knots every span/24 (holds the trend)
/// and `dahl:8` (holds the pivot: with `dahl:4` the Bouc–Wen n = 2 loop of `bw-sine-t` leaves
/// a residual that diagnose rightly flags against `since_reversal`).
pub fn base_terms(drive: &FamilyDrive) -> Vec<String> {
    vec![
        format!("table:{}", biasctl::log::fmt_trimmed(drive.span / 24.0, 3)),
        "dahl:8".to_string(),
    ]
}

/// `terms` with `term` added; a `table:` term replaces the table already there.
pub fn with_term(terms: &[String], term: &str) -> Vec<String> {
    let head = |t: &str| t.split(':').next().unwrap_or("").to_string();
    let mut out: Vec<String> = terms
        .iter()
        .filter(|t| !(head(term) == "table" && head(t) == "table"))
        .cloned()
        .collect();
    out.push(term.to_string());
    out
}

/// The fit settings (the defaults, checked).
pub fn fit_options() -> CheckedFitOptions {
    FitOptions::default().check().expect("default fit options")
}

/// Fits `terms` on `log`.
pub fn fit_terms(terms: &[String], log: &Log) -> FittedModel {
    let spec = ModelSpec::parse(&terms.join(",")).expect("family terms parse");
    fit(&spec, log, &fit_options()).expect("family fit")
}

/// Residual std of `model`'s causal replay over `log`, counts.
pub fn residual_std(model: &FittedModel, log: &Log) -> f64 {
    let p = model.predict_log(log).expect("replay");
    biasctl::numeric::std_dev(&p.residual).unwrap_or(0.0)
}

/// What one scenario on one seed gave.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The drive's name.
    pub drive: String,
    /// The hidden effects.
    pub effects: Vec<HiddenEffect>,
    /// The seed.
    pub seed: u64,
    /// First-ranked flagged feature, if any.
    pub first: Option<String>,
    /// The term diagnose proposed first, if any.
    pub edit: Option<String>,
    /// Whether `first` names one of the hidden effects.
    pub right_first: bool,
    /// Residual std of the user's model, after diagnose's first edit, and with the true term
    /// (the best over the effects present), counts.
    pub std_base: f64,
    /// See `std_base`.
    pub std_edit: f64,
    /// See `std_base`; `None` if no effect has a true term.
    pub std_true: Option<f64>,
    /// No-effect columns flagged on the user's model.
    pub no_effect_flagged: Vec<String>,
    /// The first (unverified) suggestion's term and the residual std after refitting with it,
    /// counts: what `std_edit` was before the edits were verified, kept for comparison.
    pub suggested: Option<String>,
    /// See `suggested`.
    pub std_suggested: f64,
    /// The feature (or `term → feature`, `A × B`) of the best verified edit, if one is verified.
    pub verified_feature: Option<String>,
    /// Every scored edit in one line (`edit gain/z`, `*` = verified) and the rejected ones.
    pub verification: String,
    /// The second verification round in one line (`on top of E: edit gain/z; …`), empty when
    /// it did not run.
    pub second_round: String,
    /// The advice a user applies: the combined terms when an edit holds on top of the best
    /// one (the second round), else the best verified edit's terms; `None` when nothing is
    /// verified.
    pub advice: Option<String>,
    /// Residual std after refitting `advice` on the whole log (counts; `std_base` without one).
    pub std_advice: f64,
    /// Residual std with every effect's true term at once (counts; `None` unless two effects
    /// with true terms).
    pub std_all_true: Option<f64>,
}

impl Outcome {
    /// Fraction of the achievable std reduction the first verified edit recovers (`None` when
    /// nothing is achievable).
    pub fn recovered(&self) -> Option<f64> {
        self.recovered_by(self.std_edit)
    }

    /// The same for the advice (`advice`): above 100 % when it holds two effects.
    pub fn recovered_by_advice(&self) -> Option<f64> {
        self.recovered_by(self.std_advice)
    }

    /// The advice's reduction over the reduction with every effect's true term at once.
    pub fn recovered_of_all(&self) -> Option<f64> {
        let achievable = self.std_base - self.std_all_true?;
        (achievable > 0.0).then(|| (self.std_base - self.std_advice) / achievable)
    }

    /// The same for the first unverified suggestion (the scoring before #10's item 4).
    pub fn recovered_by_suggestion(&self) -> Option<f64> {
        self.recovered_by(self.std_suggested)
    }

    fn recovered_by(&self, std: f64) -> Option<f64> {
        let achievable = self.std_base - self.std_true?;
        (achievable > 0.0).then(|| (self.std_base - std) / achievable)
    }
}

/// The diagnosis settings of the scoreboard (the defaults, seeded).
pub fn config(seed: u64) -> CheckedDiagnoseConfig {
    DiagnoseConfig {
        seed,
        ..DiagnoseConfig::default()
    }
    .check()
    .expect("default diagnosis settings")
}

/// The first flagged feature of a diagnosis.
pub fn first_flagged(d: &Diagnosis) -> Option<&biasctl::diagnose::FeatureReport> {
    d.features.first().filter(|f| f.flagged)
}

/// Runs one scenario on one seed.
pub fn run(drive: &FamilyDrive, effects: &[HiddenEffect], seed: u64, n: usize) -> Outcome {
    let fam = generate(&FamilyConfig::new(drive.clone(), effects, seed, n)).expect("generate");
    let log = &fam.log;
    let base = base_terms(drive);
    let model = fit_terms(&base, log);
    let d = diagnose_verified(&model, log, &config(seed), &CheckedVerifyConfig::default())
        .expect("diagnose");
    let first = first_flagged(&d).map(|f| f.name.clone());
    let right_first = first
        .as_deref()
        .is_some_and(|f| effects.iter().any(|e| e.is_right_feature(f)));
    let no_effect_flagged = d
        .features
        .iter()
        .filter(|f| f.flagged && NO_EFFECT_COLUMNS.contains(&f.name.as_str()))
        .map(|f| f.name.clone())
        .collect();
    let std_base = d.residual_std;
    // The first verified edit, refitted on the whole log (as the true term is); nothing
    // verified recovers nothing.
    let best = d.verification.as_ref().and_then(|v| v.best()).cloned();
    let verified_feature = best.as_ref().map(|b| b.feature.clone());
    let verification = d
        .verification
        .as_ref()
        .map(|v| {
            let mut parts: Vec<String> = v
                .edits
                .iter()
                .map(|e| {
                    format!(
                        "{}{} {:.1} %/z {:.1}/w {:.1}",
                        if e.verified { "*" } else { "" },
                        e.edit,
                        100.0 * e.gain,
                        e.z,
                        100.0 * e.gain_within_folds
                    )
                })
                .collect();
            parts.extend(v.rejected.iter().map(|r| format!("rejected {}", r.term)));
            parts.extend(v.not_run.clone());
            parts.join("; ")
        })
        .unwrap_or_default();
    let fmt_edit = |e: &biasctl::diagnose::VerifiedEdit| {
        format!(
            "{}{} {:.1} %/z {:.1}/w {:.1}",
            if e.verified { "*" } else { "" },
            e.edit,
            100.0 * e.gain,
            e.z,
            100.0 * e.gain_within_folds
        )
    };
    let round2 = d.verification.as_ref().and_then(|v| v.second_round.clone());
    let second_round = round2
        .as_ref()
        .map(|r| {
            let mut parts: Vec<String> = r.edits.iter().map(fmt_edit).collect();
            parts.extend(r.rejected.iter().map(|x| format!("rejected {}", x.term)));
            format!("on top of {}: {}", r.on_top_of, parts.join("; "))
        })
        .unwrap_or_default();
    let advice = round2
        .and_then(|r| r.combined)
        .map(|c| c.terms)
        .or_else(|| best.as_ref().map(|b| b.terms.clone()));
    let std_advice = advice.as_ref().map_or(std_base, |t| {
        let terms: Vec<String> = t.split(',').map(str::to_string).collect();
        residual_std(&fit_terms(&terms, log), log)
    });
    let true_terms: Vec<&str> = effects.iter().filter_map(|e| e.true_term()).collect();
    let std_all_true = (true_terms.len() > 1).then(|| {
        let mut terms = base.clone();
        for t in &true_terms {
            terms = with_term(&terms, t);
        }
        residual_std(&fit_terms(&terms, log), log)
    });
    let (edit, std_edit) = match &best {
        Some(b) => {
            let terms: Vec<String> = b.terms.split(',').map(str::to_string).collect();
            (
                Some(b.edit.clone()),
                residual_std(&fit_terms(&terms, log), log),
            )
        }
        None => (None, std_base),
    };
    let top = first_flagged(&d).and_then(|f| f.suggested_term.clone());
    // An edit that cannot be fitted (a term the model already holds under another setting)
    // recovers nothing.
    let (suggested, std_suggested) =
        match suggestion_path_from(&model, log, d, &config(seed), 1, &fit_options()) {
            Ok(path) => path
                .first()
                .map_or((None, std_base), |s| (Some(s.term.clone()), s.std_after)),
            Err(_) => (top.map(|t| format!("{t} (fit fails)")), std_base),
        };
    let std_true = effects
        .iter()
        .filter_map(|e| e.true_term())
        .map(|t| residual_std(&fit_terms(&with_term(&base, t), log), log))
        .reduce(f64::min);
    Outcome {
        drive: drive.name.clone(),
        effects: effects.to_vec(),
        seed,
        first,
        edit,
        right_first,
        std_base,
        std_edit,
        std_true,
        no_effect_flagged,
        suggested,
        std_suggested,
        verified_feature,
        verification,
        second_round,
        advice,
        std_advice,
        std_all_true,
    }
}

/// The model holding every effect present (base + each effect's true term), diagnosed with
/// verification: the names of the flagged features and the verified edits.
pub fn full_model_flags(
    drive: &FamilyDrive,
    effects: &[HiddenEffect],
    seed: u64,
    n: usize,
) -> Vec<String> {
    let fam = generate(&FamilyConfig::new(drive.clone(), effects, seed, n)).expect("generate");
    let mut terms = base_terms(drive);
    for t in effects.iter().filter_map(|e| e.true_term()) {
        terms = with_term(&terms, t);
    }
    let model = fit_terms(&terms, &fam.log);
    let d = diagnose_verified(
        &model,
        &fam.log,
        &config(seed),
        &CheckedVerifyConfig::default(),
    )
    .expect("diagnose");
    let mut flags: Vec<String> = d
        .features
        .iter()
        .filter(|f| f.flagged)
        .map(|f| f.name.clone())
        .collect();
    // A verified edit is a flag too (its own false-alarm check: the verification of the
    // strongest unflagged features must not cry wolf either).
    flags.extend(
        d.verification
            .iter()
            .flat_map(|v| v.edits.iter().filter(|e| e.verified))
            .map(|e| format!("verified {}", e.edit)),
    );
    flags.extend(
        d.verification
            .iter()
            .flat_map(|v| v.second_round.iter())
            .flat_map(|r| r.edits.iter().filter(|e| e.verified))
            .map(|e| format!("verified on top {}", e.edit)),
    );
    flags
}

fn names(effects: &[HiddenEffect]) -> String {
    effects
        .iter()
        .map(|e| e.name())
        .collect::<Vec<_>>()
        .join("+")
}

#[allow(dead_code)]
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seeds: u64 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(10);
    let n: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(2000);
    // Mode: `full` (only the full-model flags), `fresh` (the held-out drive only), else the
    // three members; the 5th argument is the first seed (default 1), for held-out seeds.
    let mode = args.get(3).map(String::as_str).unwrap_or("all");
    let from: u64 = args.get(4).and_then(|a| a.parse().ok()).unwrap_or(1);
    // 6th argument: only the scenarios whose name (`lag`, `lag+position_direction`) contains
    // it; every run's verification is then printed too.
    let only = args.get(5).cloned();
    let scenarios = || -> Vec<Vec<HiddenEffect>> {
        scenarios()
            .into_iter()
            .filter(|e| only.as_deref().is_none_or(|o| names(e).contains(o)))
            .collect()
    };
    let drives = if mode == "fresh" {
        vec![fresh_drive()]
    } else {
        FamilyDrive::members()
    };
    let seed_range = from..from + seeds;
    let t0 = std::time::Instant::now();
    if mode == "full" {
        for drive in FamilyDrive::members() {
            for effects in scenarios() {
                for s in seed_range.clone() {
                    let f = full_model_flags(&drive, &effects, s, n);
                    println!("{} {} seed {s}: {:?}", drive.name, names(&effects), f);
                }
            }
        }
        return;
    }
    let mut all = Vec::new();
    println!(
        "{:<14} {:<34} {:>6} {:>9} {:>10} {:>9}   most common first feature -> edit",
        "drive", "hidden effect", "right", "recov.med", "recov.min", "no-eff"
    );
    for drive in &drives {
        for effects in scenarios() {
            let outs: Vec<Outcome> = seed_range
                .clone()
                .map(|s| run(drive, &effects, s, n))
                .collect();
            if only.is_some() {
                for o in &outs {
                    let pct = |x: Option<f64>| {
                        x.map_or("-".to_string(), |r| format!("{:.0} %", 100.0 * r))
                    };
                    println!(
                        "  seed {} first {:?} edit {:?} recovered {} | {}",
                        o.seed,
                        o.first,
                        o.edit,
                        pct(o.recovered()),
                        o.verification
                    );
                    if !o.second_round.is_empty() {
                        println!(
                            "    second round {} | advice {:?} recovers {} of the best single \
                             true term, {} of all true terms",
                            o.second_round,
                            o.advice,
                            pct(o.recovered_by_advice()),
                            pct(o.recovered_of_all())
                        );
                    }
                }
            }
            let right = outs.iter().filter(|o| o.right_first).count();
            let mut rec: Vec<f64> = outs.iter().filter_map(Outcome::recovered).collect();
            rec.sort_by(f64::total_cmp);
            let med = rec.get(rec.len() / 2).copied();
            let min = rec.first().copied();
            let noeff = outs
                .iter()
                .filter(|o| !o.no_effect_flagged.is_empty())
                .count();
            let mut firsts: Vec<(String, usize)> = Vec::new();
            for o in &outs {
                let key = format!(
                    "{} -> {}",
                    o.first.as_deref().unwrap_or("-"),
                    o.edit.as_deref().unwrap_or("-")
                );
                match firsts.iter_mut().find(|(k, _)| *k == key) {
                    Some((_, c)) => *c += 1,
                    None => firsts.push((key, 1)),
                }
            }
            firsts.sort_by_key(|f| std::cmp::Reverse(f.1));
            let fmt = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{:.0} %", 100.0 * v));
            println!(
                "{:<14} {:<34} {:>3}/{:<2} {:>9} {:>10} {:>6}/{:<2}  {} ({})",
                drive.name,
                names(&effects),
                right,
                seeds,
                fmt(med),
                fmt(min),
                noeff,
                seeds,
                firsts[0].0,
                firsts[0].1
            );
            all.extend(outs);
        }
    }
    let total = all.len();
    let right = all.iter().filter(|o| o.right_first).count();
    let rec: Vec<f64> = all.iter().filter_map(Outcome::recovered).collect();
    let mean_rec = rec.iter().sum::<f64>() / rec.len().max(1) as f64;
    let ge90 = rec.iter().filter(|&&r| r >= 0.9).count();
    let noeff = all
        .iter()
        .filter(|o| !o.no_effect_flagged.is_empty())
        .count();
    println!();
    println!(
        "right feature first: {right}/{total} ({:.0} %)",
        100.0 * right as f64 / total as f64
    );
    println!(
        "first verified edit recovers: mean {:.0} % of the achievable reduction; ≥ 90 % in \
         {ge90}/{} runs",
        100.0 * mean_rec,
        rec.len()
    );
    let adv: Vec<f64> = all
        .iter()
        .filter_map(Outcome::recovered_by_advice)
        .collect();
    let ran = all.iter().filter(|o| !o.second_round.is_empty()).count();
    let held = all
        .iter()
        .filter(|o| o.second_round.contains(": *") || o.second_round.contains("; *"))
        .count();
    println!(
        "advice (both edits when one holds on top of the best): mean {:.0} %; ≥ 90 % in {}/{} \
         runs; second round ran in {ran}/{total}, something held on top in {held}",
        100.0 * adv.iter().sum::<f64>() / adv.len().max(1) as f64,
        adv.iter().filter(|&&r| r >= 0.9).count(),
        adv.len()
    );
    let sug: Vec<f64> = all
        .iter()
        .filter_map(Outcome::recovered_by_suggestion)
        .collect();
    println!(
        "first unverified suggestion recovers: mean {:.0} %; ≥ 90 % in {}/{} runs",
        100.0 * sug.iter().sum::<f64>() / sug.len().max(1) as f64,
        sug.iter().filter(|&&r| r >= 0.9).count(),
        sug.len()
    );
    println!(
        "a no-effect column flagged: {noeff}/{total} runs ({:.0} %)",
        100.0 * noeff as f64 / total as f64
    );
    let mut clean = 0;
    let mut flagged_runs = 0;
    for drive in &drives {
        for effects in scenarios() {
            for s in seed_range.clone() {
                let f = full_model_flags(drive, &effects, s, n);
                if f.is_empty() {
                    clean += 1;
                } else {
                    flagged_runs += 1;
                    if flagged_runs <= 12 {
                        println!(
                            "  full model flags {:?} ({} {} seed {s})",
                            f,
                            drive.name,
                            names(&effects)
                        );
                    }
                }
            }
        }
    }
    println!(
        "model holding every effect: nothing flagged in {clean}/{} runs",
        clean + flagged_runs
    );
    println!("({:.1} s)", t0.elapsed().as_secs_f64());
}
