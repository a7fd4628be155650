//! The two-effect study of the second verification round (`verification.second_round`), on
//! drives and effect pairs beyond the ones the round was built on.
//!
//! ```sh
//! cargo run --release --example second_round_study -- 80 2 2000 > study.jsonl
//! ```
//! (first seed, seeds, seeks per log; the README's runs add `all rotate`: every scenario once
//! per seed on a rotating drive, 40 runs a seed, 5–15 s each on 2 threads of a loaded
//! machine; `all rotate,singles` runs only the one-effect and no-effect scenarios, the
//! false-alarm half; a 6th argument `drive/effect+effect/scale/seed;…` reruns only the runs
//! named). For every drive (the three family members, the held-out
//! drive of `diagnose_family` and three more drives with other hysteresis, trend and noise),
//! every effect pair below with the second effect at 100 %, 60 % and 35 % of its size, every
//! single effect and no effect at all, and every seed: generate the log, fit the user's model
//! (`diagnose_family::base_terms`), run `diagnose_verified`, and print one JSON line with
//! - the residual std of the user's model, of the advice (the combined terms of the second
//!   round when an edit holds on top, else the best verified edit's terms) and of the model
//!   with the true terms of every effect present, each refitted on the whole log (counts);
//! - `of_all`: the advice's std reduction over that of the true terms together (the figure the
//!   study scores: ≥ 0.9 counts as reached);
//! - the first round's edits and the second round's, each with whether its feature names an
//!   effect of the log (`HiddenEffect::is_right_feature`): a verified edit on top that names
//!   none, or names the effect the first edit already holds, is a false alarm;
//! - the no-effect columns flagged;
//! - `truth_features`: what the screen said of each feature that names an effect (rank,
//!   flagged, explained, raw p, direction-signed, suggested term), and `second_tried`: every
//!   edit the second round scored (where a second effect's own term was never a candidate,
//!   these say why).
//!
//! A second effect is scaled by subtracting `(1 − scale)` × its truth column
//! (`FamilyRun::truth`) from the bias, so its size varies while everything else stays the
//! generator's.

#[path = "diagnose_family.rs"]
#[allow(dead_code)]
mod diagnose_family;

use biasctl::sim::family::{FamilyConfig, FamilyDrive, HiddenEffect, NO_EFFECT_COLUMNS, generate};
use biasctl::{CheckedVerifyConfig, ModelSpec, diagnose_verified};
use diagnose_family::{base_terms, config, fit_terms, fresh_drive, residual_std, with_term};

/// Drives none of the members is: other Bouc–Wen shapes, a two-stop Prandtl–Ishlinskii pivot,
/// a cubic trend with Gaussian white noise, heavier AR(1) noise.
fn other_drives() -> Vec<FamilyDrive> {
    use biasctl::sim::family::{Noise, Pivot, Trend};
    vec![
        FamilyDrive {
            name: "bw15-cubic-w".into(),
            pivot: Pivot::BoucWen {
                amplitude: 11.0,
                length: 18.0,
                beta: 0.6,
                n: 1.5,
            },
            trend: Trend::Cubic {
                c: [10.0, -5.0, 4.0, -2.0],
            },
            noise: Noise {
                std: 1.2,
                nu: None,
                rho: 0.0,
            },
            centre: 900.0,
            span: 280.0,
            dwell_s: [0.05, 0.4],
            effect_scale: 1.0,
        },
        FamilyDrive {
            name: "pi2-sine-ar".into(),
            pivot: Pivot::Prandtl {
                thresholds: vec![5.0, 20.0],
                weights: vec![6.0, 4.0],
            },
            trend: Trend::Sine {
                offset: 0.0,
                slope: 3.0,
                amplitude: 6.0,
                cycles: 2.0,
                phase: 0.0,
            },
            noise: Noise {
                std: 2.2,
                nu: Some(6),
                rho: 0.5,
            },
            centre: 1800.0,
            span: 320.0,
            dwell_s: [0.1, 0.8],
            effect_scale: 1.0,
        },
        FamilyDrive {
            name: "bw2-sine-small".into(),
            pivot: Pivot::BoucWen {
                amplitude: 6.0,
                length: 8.0,
                beta: 0.85,
                n: 2.0,
            },
            trend: Trend::Sine {
                offset: -8.0,
                slope: 2.0,
                amplitude: 4.0,
                cycles: 1.0,
                phase: 2.0,
            },
            noise: Noise {
                std: 1.6,
                nu: Some(4),
                rho: 0.2,
            },
            centre: 400.0,
            span: 220.0,
            dwell_s: [0.05, 0.6],
            effect_scale: 0.8,
        },
    ]
}

/// Effect pairs: the study's own (lag + position × direction) and pairs of other classes.
fn pairs() -> Vec<[HiddenEffect; 2]> {
    use HiddenEffect::*;
    vec![
        [Lag, PositionDirection],
        [PositionDirection, Lag],
        [FastCovariate, Defect],
        [SummedMemory, Threshold],
        [SlowCovariate, CovariateDirection],
        [Threshold, Lag],
        [FastCovariate, Interaction],
        [Defect, SummedMemory],
        [CovariateDirection, FastCovariate],
        [SlowCovariate, PositionDirection],
    ]
}

fn edit_json(e: &biasctl::diagnose::VerifiedEdit, right: bool) -> serde_json::Value {
    serde_json::json!({
        "feature": e.feature, "edit": e.edit, "gain": e.gain, "z": e.z,
        "within": e.gain_within_folds, "verified": e.verified, "right": right,
    })
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let from: u64 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(80);
    let seeds: u64 = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(2);
    let n: usize = args.get(3).and_then(|a| a.parse().ok()).unwrap_or(2000);
    // Optional 4th argument: only the drives named in it (comma-separated; `all`: every one).
    let only: Option<Vec<String>> = args
        .get(4)
        .filter(|a| a.as_str() != "all")
        .map(|a| a.split(',').map(str::to_string).collect());
    let mut drives = FamilyDrive::members();
    drives.push(fresh_drive());
    drives.extend(other_drives());
    drives.retain(|d| only.as_ref().is_none_or(|o| o.contains(&d.name)));
    let mut scenarios: Vec<(Vec<HiddenEffect>, f64)> = Vec::new();
    for p in pairs() {
        for s in [1.0, 0.6, 0.35] {
            scenarios.push((p.to_vec(), s));
        }
    }
    for e in HiddenEffect::ALL {
        scenarios.push((vec![e], 1.0));
    }
    scenarios.push((Vec::new(), 1.0));
    // `rotate` as the 5th argument: every scenario once per seed, on drive (i + 3·seed) mod
    // the number of drives (a study that is cut short still covers every scenario and drive).
    // `singles` (with or without `rotate`): only the scenarios with one effect or none, the
    // false-alarm half of the study.
    let rotate = args.get(5).is_some_and(|a| a.contains("rotate"));
    if args.get(5).is_some_and(|a| a.contains("singles")) {
        scenarios.retain(|(e, _)| e.len() < 2);
    }
    // Optional 6th argument: only the runs named in it, `;`-separated, each
    // `drive/effect+effect/scale/seed` as the JSON lines print them (to look at a few runs again).
    let picked: Option<Vec<String>> = args
        .get(6)
        .map(|a| a.split(';').map(str::to_string).collect());
    let mut runs: Vec<(&FamilyDrive, &Vec<HiddenEffect>, f64, u64)> = Vec::new();
    for seed in from..from + seeds {
        for (i, (effects, scale)) in scenarios.iter().enumerate() {
            if rotate {
                let k = (i + 3 * seed as usize) % drives.len();
                runs.push((&drives[k], effects, *scale, seed));
            } else {
                runs.extend(drives.iter().map(|d| (d, effects, *scale, seed)));
            }
        }
    }
    runs.retain(|(d, e, s, seed)| {
        let names: Vec<&str> = e.iter().map(|e| e.name()).collect();
        let key = format!("{}/{}/{s}/{seed}", d.name, names.join("+"));
        picked.as_ref().is_none_or(|p| p.contains(&key))
    });
    {
        for (drive, effects, scale, seed) in runs {
            let scale = &scale;
            {
                let t0 = std::time::Instant::now();
                let fam = generate(&FamilyConfig::new(drive.clone(), effects, seed, n))
                    .expect("generate");
                let mut log = fam.log.clone();
                if effects.len() == 2 && *scale < 1.0 {
                    let t = fam.truth(effects[1].name()).expect("truth column");
                    for (i, v) in t.iter().enumerate() {
                        let b = log.bias(i).expect("every row measured");
                        log.set_bias(i, Some(b - (1.0 - scale) * v));
                    }
                }
                let base = base_terms(drive);
                let model = fit_terms(&base, &log);
                let d =
                    diagnose_verified(&model, &log, &config(seed), &CheckedVerifyConfig::default())
                        .expect("diagnose");
                let right = |f: &str| effects.iter().position(|e| e.is_right_feature(f));
                let v = d.verification.as_ref();
                let best = v.and_then(|v| v.best()).cloned();
                let best_effect = best.as_ref().and_then(|b| right(&b.feature));
                let first: Vec<serde_json::Value> = v
                    .map(|v| {
                        v.edits
                            .iter()
                            .map(|e| edit_json(e, right(&e.feature).is_some()))
                            .collect()
                    })
                    .unwrap_or_default();
                let std_of = |terms: &str| {
                    let t: Vec<String> = terms.split(',').map(str::to_string).collect();
                    residual_std(&fit_terms(&t, &log), &log)
                };
                let std_base = d.residual_std;
                let std_best = best.as_ref().map_or(std_base, |b| std_of(&b.terms));
                let round = v.and_then(|v| v.second_round.as_ref());
                // Every edit on top: its own combined terms and their std (the advice had it
                // been the best on top).
                let second: Vec<serde_json::Value> = round
                    .map(|r| {
                        r.edits
                            .iter()
                            .map(|e| {
                                let k = right(&e.feature);
                                let mut j = edit_json(e, k.is_some() && k != best_effect);
                                // What the gate saw: the first-round edit of this feature (its
                                // gain over the best's), else the feature's explained share over
                                // the best feature's.
                                let b = best.as_ref().expect("a round has a best edit");
                                let f1 =
                                    v.and_then(|v| v.edits.iter().find(|x| x.feature == e.feature));
                                match f1 {
                                    Some(x) => {
                                        j["ratio"] = (x.gain / b.gain).into();
                                        j["first_z"] = x.z.into();
                                        j["first_verified"] = x.verified.into();
                                        j["from"] = "edit".into();
                                    }
                                    None => {
                                        let ex = |n: &str| {
                                            d.feature(n).map_or(f64::NAN, |f| f.explained)
                                        };
                                        j["ratio"] = (ex(&e.feature) / ex(&b.feature)).into();
                                        j["p_raw"] = d
                                            .feature(&e.feature)
                                            .map_or(f64::NAN, |f| f.p_value_raw)
                                            .into();
                                        j["from"] = "pool".into();
                                    }
                                }
                                let combined = best
                                    .as_ref()
                                    .and_then(|b| ModelSpec::parse(&b.terms).ok())
                                    .zip(e.model_edit.as_ref())
                                    .and_then(|(s, m)| s.apply(m).ok())
                                    .map(|s| s.to_string());
                                if let Some(c) = combined.filter(|_| e.verified) {
                                    j["std_combined"] = std_of(&c).into();
                                    j["combined"] = c.into();
                                }
                                j
                            })
                            .collect()
                    })
                    .unwrap_or_default();
                let advice = round
                    .and_then(|r| r.combined.as_ref())
                    .map(|c| c.terms.clone())
                    .or_else(|| best.as_ref().map(|b| b.terms.clone()));
                let std_advice = advice.as_deref().map_or(std_base, std_of);
                let true_terms: Vec<&str> = effects.iter().filter_map(|e| e.true_term()).collect();
                let std_all_true = (!true_terms.is_empty()).then(|| {
                    let mut terms = base.clone();
                    for t in &true_terms {
                        terms = with_term(&terms, t);
                    }
                    residual_std(&fit_terms(&terms, &log), &log)
                });
                let of_all = std_all_true
                    .map(|t| (std_base - std_advice) / (std_base - t))
                    .filter(|r| r.is_finite());
                let no_effect: Vec<&str> = d
                    .features
                    .iter()
                    .filter(|f| f.flagged && NO_EFFECT_COLUMNS.contains(&f.name.as_str()))
                    .map(|f| f.name.as_str())
                    .collect();
                let names: Vec<&str> = effects.iter().map(|e| e.name()).collect();
                // What the screen said of the features that name an effect (where the second
                // effect's term comes from, or why it does not).
                let truth_features: Vec<serde_json::Value> = d
                    .features
                    .iter()
                    .enumerate()
                    .filter(|(_, f)| effects.iter().any(|e| e.is_right_feature(&f.name)))
                    .map(|(rank, f)| {
                        serde_json::json!({
                            "name": f.name, "rank": rank, "flagged": f.flagged,
                            "explained": f.explained, "beyond": f.explained_beyond_previous,
                            "p_raw": f.p_value_raw, "by_direction": f.by_direction,
                            "suggested": f.suggested_term, "alternatives": f.alternatives,
                        })
                    })
                    .collect();
                let second_tried: Vec<String> = round
                    .map(|r| {
                        r.edits
                            .iter()
                            .map(|e| e.edit.clone())
                            .chain(r.rejected.iter().map(|x| format!("rejected {}", x.term)))
                            .collect()
                    })
                    .unwrap_or_default();
                let line = serde_json::json!({
                    "drive": drive.name, "effects": names, "scale": scale, "seed": seed,
                    "std_base": std_base, "std_best": std_best, "std_advice": std_advice,
                    "std_all_true": std_all_true, "of_all": of_all, "advice": advice,
                    "best": best.as_ref().map(|b| b.edit.clone()),
                    "best_right": best_effect.is_some(),
                    "first": first, "round_ran": round.is_some(), "second": second,
                    "no_effect_flagged": no_effect, "truth_features": truth_features,
                    "second_tried": second_tried, "secs": t0.elapsed().as_secs_f64(),
                });
                println!("{line}");
            }
        }
    }
}
