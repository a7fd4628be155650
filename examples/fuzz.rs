//! Long fuzz campaigns with the harness of `tests/it/fuzz.rs` (the same code `cargo test` runs
//! for a bounded time):
//!
//! ```sh
//! cargo run --release --example fuzz -- --cases 20000 --seed 1 --minutes 15
//! ```
//!
//! Prints the cases run, accepted and refused, and every finding; writes each finding's input to
//! `target/fuzz-findings/` (copy it into `tests/corpus/findings/` with its kind's prefix, fix the
//! bug, and `cargo test` replays it from then on). Exit code 1 if anything was found.

#[path = "../tests/it/fuzz.rs"]
#[allow(unused_imports)]
mod fuzz;

use std::time::Duration;

fn main() {
    let mut cases = 2000u64;
    let mut seed = 1u64;
    let mut minutes = 60.0f64;
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < args.len() {
        let value = args.get(i + 1).map(String::as_str).unwrap_or("");
        let bad = |flag: &str| -> ! {
            eprintln!("error: {flag} needs a number, got `{value}`");
            std::process::exit(2)
        };
        match args[i].as_str() {
            "--cases" => cases = value.parse().unwrap_or_else(|_| bad("--cases")),
            "--seed" => seed = value.parse().unwrap_or_else(|_| bad("--seed")),
            "--minutes" => minutes = value.parse().unwrap_or_else(|_| bad("--minutes")),
            other => {
                eprintln!("error: unknown flag `{other}` (--cases N --seed S --minutes M)");
                std::process::exit(2)
            }
        }
        i += 2;
    }
    let budget = Duration::from_secs_f64((minutes * 60.0).clamp(1.0, 7.0 * 86_400.0));
    let c = fuzz::campaign(cases, seed, budget);
    println!(
        "fuzz: {} cases (seed {seed}) in {:.1} s: {} accepted with finite outputs, {} refused with a short message, {} findings",
        c.cases,
        c.elapsed.as_secs_f64(),
        c.accepted,
        c.refused,
        c.findings.len()
    );
    let out = std::path::Path::new("target/fuzz-findings");
    for (k, f) in c.findings.iter().enumerate() {
        println!("finding {k}: {}: {}", f.input, fuzz_quote(&f.what));
        let _ = std::fs::create_dir_all(out);
        let _ = std::fs::write(out.join(format!("{k}_{}", f.input)), &f.bytes);
    }
    if !c.findings.is_empty() {
        std::process::exit(1);
    }
}

fn fuzz_quote(s: &str) -> String {
    biasctl::io::quote(s)
}
