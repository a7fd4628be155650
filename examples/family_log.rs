//! Writes a family drive's log as CSV, for timing the command line on an independent drive:
//!
//! ```sh
//! cargo run --release --example family_log -- OUT.csv [SEEKS] [SEED] [EFFECT,...]
//! ```
//!
//! The first family member (`biasctl::sim::family::FamilyDrive::members`), `SEEKS` seeks
//! (default 6000), seed `SEED` (default 7), the hidden effects named (default `lag`; `none` for
//! none). The log carries the family's covariate columns, three of which have no effect on the
//! bias (`white`, `walk`, `warmup`: decoys for the diagnosis).

use biasctl::log::LogWriter;
use biasctl::sim::family::{FamilyConfig, FamilyDrive, HiddenEffect, generate};

fn main() {
    let mut args = std::env::args().skip(1);
    let out = args
        .next()
        .expect("usage: family_log OUT.csv [SEEKS] [SEED] [EFFECT,...]");
    let n: usize = args.next().map_or(6000, |s| s.parse().expect("SEEKS"));
    let seed: u64 = args.next().map_or(7, |s| s.parse().expect("SEED"));
    let names = args.next().unwrap_or_else(|| "lag".to_string());
    let effects: Vec<HiddenEffect> = if names == "none" {
        Vec::new()
    } else {
        names
            .split(',')
            .map(|e| HiddenEffect::from_name(e).unwrap_or_else(|| panic!("no effect `{e}`")))
            .collect()
    };
    let drive = FamilyDrive::members().remove(0);
    let run = generate(&FamilyConfig::new(drive, &effects, seed, n)).expect("generate");
    let log = &run.log;
    let file = std::fs::File::create(&out).expect("create OUT.csv");
    let mut w = LogWriter::new(
        std::io::BufWriter::new(file),
        &log.schema.metadata,
        &log.schema.covariates,
    )
    .expect("header");
    let mut cov = vec![0.0; log.schema.covariates.len()];
    for i in 0..log.len() {
        for (k, c) in cov.iter_mut().enumerate() {
            *c = log.covariate(k)[i];
        }
        w.write_row(log.times()[i], log.tracks()[i], log.bias(i), &cov)
            .expect("row");
    }
    use std::io::Write;
    w.into_inner().expect("flush").flush().expect("flush");
}
