//! Diagnose's JSON on fixed inputs, written to files, for a byte-for-byte comparison of two
//! builds (an optimisation must not change a byte):
//!
//! ```sh
//! cargo run --release --example diagnose_golden -- OUT_DIR [THREADS]
//! diff -r BEFORE_DIR AFTER_DIR   # no output: identical
//! ```
//!
//! Every family drive (`biasctl::sim::family`, the three members and the held-out drive of
//! `examples/diagnose_family.rs`) × every scenario on a fixed seed: the user's model, then
//! `diagnose_verified` (feature table, permutation tests, pair screening, verified refits —
//! among them `lag:` terms, whose refits search τ) → `family_<drive>_<scenario>.json`. Also a
//! model holding `lag:` itself (its replay runs the lag in every diagnosis), and the built-in
//! drive (`paper1997`, 4,000 random seeks, model `poly2,direction`) → `builtin.json`.

#[path = "diagnose_family.rs"]
#[allow(dead_code)]
mod diagnose_family;

use biasctl::ModelSpec;
use biasctl::fit;
use biasctl::sim::family::{FamilyConfig, FamilyDrive, HiddenEffect, generate};
use biasctl::{CheckedVerifyConfig, DiagnoseConfig, diagnose_verified};
use diagnose_family::{base_terms, config, fit_options, fit_terms, fresh_drive, scenarios};
use std::path::PathBuf;

fn main() {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(
        args.next()
            .expect("usage: diagnose_golden OUT_DIR [THREADS]"),
    );
    let threads: usize = args.next().map_or(1, |t| t.parse().expect("threads"));
    std::fs::create_dir_all(&out).expect("create OUT_DIR");
    biasctl::set_threads(threads).expect("threads");
    let write = |name: &str, json: String| {
        std::fs::write(out.join(name), json).expect("write");
        eprintln!("{name}");
    };
    let mut drives = FamilyDrive::members();
    drives.push(fresh_drive());
    for (d, drive) in drives.iter().enumerate() {
        for (s, effects) in scenarios().iter().enumerate() {
            // One seed per (drive, scenario); 1500 seeks as in tests/it/family.rs.
            let seed = 500 + 20 * d as u64 + s as u64;
            let fam =
                generate(&FamilyConfig::new(drive.clone(), effects, seed, 1500)).expect("generate");
            let mut terms = base_terms(drive);
            if effects.contains(&HiddenEffect::Lag) && effects.len() == 2 {
                // The model already holds the lag: its replay runs `lag:` in every step.
                terms.push("lag:temp_lag".into());
            }
            let model = fit_terms(&terms, &fam.log);
            let d = diagnose_verified(
                &model,
                &fam.log,
                &config(seed),
                &CheckedVerifyConfig::default(),
            )
            .expect("diagnose");
            let names: Vec<&str> = effects.iter().map(|e| e.name()).collect();
            write(
                &format!("family_{}_{}.json", drive.name, names.join("+")),
                d.to_json().expect("json"),
            );
        }
    }
    // The built-in drive: random seeks, the paper's position-direction model.
    let seq = biasctl::SequenceOptions {
        n: Some(4000),
        ..biasctl::SequenceOptions::default()
    };
    let sim = biasctl::SimConfig::new(biasctl::Drive::paper1997(), "random", &seq, 11, &[])
        .expect("sim config");
    let log = biasctl::simulate_log(&sim).expect("simulate");
    let model = fit(
        &ModelSpec::parse("poly2,direction").expect("spec"),
        &log,
        &fit_options(),
    )
    .expect("fit");
    let cfg = DiagnoseConfig {
        seed: 3,
        ..DiagnoseConfig::default()
    }
    .check()
    .expect("config");
    let d =
        diagnose_verified(&model, &log, &cfg, &CheckedVerifyConfig::default()).expect("diagnose");
    write("builtin.json", d.to_json().expect("json"));
}
