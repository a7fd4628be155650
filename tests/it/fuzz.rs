//! The fuzz and fault harness, kept in the repository.
//!
//! Mutation fuzzing of a seed corpus (`tests/corpus/seed/`: simulated logs (a drive and two rigs), a model
//! file, drive and plant TOMLs, a seek script, a term list) drives every reader and the library
//! entry points behind the commands in-process: each mutated input must either be refused with an
//! error whose message is under 300 characters, or be accepted and then give only finite
//! numbers and no non-finite word in any text, and leave no stray file. A panic, a long message
//! or a non-finite output is a finding. Every past finding is a file in `tests/corpus/findings/`
//! and is replayed on every `cargo test`.
//!
//! `cargo test` runs a bounded campaign (a few hundred cases, fixed seed) plus a few CLI runs
//! with fault injection (full stdout, closed pipe, SIGKILL at random moments, two writers on one
//! target); `cargo run --release --example fuzz -- --cases N` runs long campaigns with this same
//! code (the example includes this file).

#![allow(dead_code)] // the example uses the campaign, the test binary the tests

use biasctl::io::check_text;
use biasctl::{ColumnMap, Log};
use biasctl::{Drive, SequenceOptions, SimConfig, sim::simulate_to_files, simulate_log};
use biasctl::{FitOptions, fit};
use biasctl::{FittedModel, ModelSpec};
use biasctl::{SettleSpec, analyse};
use std::error::Error;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Longest acceptable error message (characters).
pub const MAX_MESSAGE: usize = 300;

/// The folder of the corpus.
pub fn corpus_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/corpus")
}

/// A small deterministic generator (SplitMix64): the campaign is reproducible from its seed.
pub struct Rng(u64);

impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }
    /// The next 64 random bits.
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `0..n` (`n` > 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    /// A finite number spread log-uniformly over 1e-300 … 1e300, either sign.
    pub fn wide_number(&mut self) -> f64 {
        let exp = (self.next() % 601) as i32 - 300;
        let mant = 1.0 + (self.next() % 9000) as f64 / 1000.0;
        let sign = if self.next().is_multiple_of(2) {
            1.0
        } else {
            -1.0
        };
        sign * mant * 10f64.powi(exp)
    }
}

/// What a corpus file feeds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A measurement log (`log_*.csv`).
    Log,
    /// A model file (`model_*.json`).
    Model,
    /// A drive TOML (`drive_*.toml`).
    Drive,
    /// A plant TOML (`plant_*.toml`).
    Plant,
    /// A seek script (`script_*.csv`).
    Script,
    /// A term list (`terms_*.txt`).
    Terms,
}

/// One corpus file.
#[derive(Debug, Clone)]
pub struct Input {
    /// File name.
    pub name: String,
    /// What it feeds.
    pub kind: Kind,
    /// Its bytes.
    pub bytes: Vec<u8>,
}

/// The kind of a corpus file, from its name's prefix.
fn kind_of(name: &str) -> Option<Kind> {
    let prefix = name.split(['_', '.']).next()?;
    Some(match prefix {
        "log" => Kind::Log,
        "model" => Kind::Model,
        "drive" => Kind::Drive,
        "plant" => Kind::Plant,
        "script" => Kind::Script,
        "terms" => Kind::Terms,
        _ => return None,
    })
}

/// Every corpus file in `dir` (sorted by name).
pub fn load(dir: &Path) -> Vec<Input> {
    let mut v: Vec<Input> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("corpus {}: {e}", dir.display()))
        .filter_map(|e| {
            let p = e.ok()?.path();
            let name = p.file_name()?.to_string_lossy().into_owned();
            Some(Input {
                kind: kind_of(&name)?,
                bytes: std::fs::read(&p).ok()?,
                name,
            })
        })
        .collect();
    v.sort_by(|a, b| a.name.cmp(&b.name));
    v
}

/// Values a hostile user types: extremes, non-numbers, huge words.
const NASTY: [&str; 16] = [
    "1e300", "-1e300", "1e308", "-1e308", "1e-300", "NaN", "inf", "-inf", "0", "-0", "1e15",
    "9e15", "1e11", "", "\"", "#",
];

/// One to four random mutations of `bytes`: a numeric token replaced by an extreme or a wide
/// random number, a byte flipped, a range deleted or duplicated, a line repeated, a separator
/// swapped, the file cut short, a long word inserted.
pub fn mutate(rng: &mut Rng, bytes: &[u8]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    for _ in 0..1 + rng.below(4) {
        let n = b.len().max(1);
        match rng.below(9) {
            0..=2 => {
                // Replace a number (a run of digits, '.', 'e', '-', '+') with an extreme.
                let starts: Vec<usize> = (0..b.len())
                    .filter(|&i| b[i].is_ascii_digit() && (i == 0 || !b[i - 1].is_ascii_digit()))
                    .collect();
                if starts.is_empty() {
                    continue;
                }
                let s = starts[rng.below(starts.len())];
                let mut e = s;
                while e < b.len() && (b[e].is_ascii_digit() || b"+-.eE".contains(&b[e])) {
                    e += 1;
                }
                let with = if rng.below(2) == 0 {
                    NASTY[rng.below(NASTY.len())].to_string()
                } else {
                    format!("{:e}", rng.wide_number())
                };
                b.splice(s..e, with.into_bytes());
            }
            3 => {
                let i = rng.below(n);
                if i < b.len() {
                    b[i] ^= 1 << rng.below(8);
                }
            }
            4 => {
                let i = rng.below(n);
                let len = rng.below(64).min(b.len().saturating_sub(i));
                b.drain(i..i + len);
            }
            5 => {
                let i = rng.below(n);
                let len = rng.below(256).min(b.len().saturating_sub(i));
                let chunk = b[i..i + len].to_vec();
                b.splice(i..i, chunk);
            }
            6 => {
                let i = rng.below(n);
                let sep = [b',', b';', b'\t', b'\n', b'\r', 0u8, b'['][rng.below(7)];
                if i < b.len() {
                    b[i] = sep;
                }
            }
            7 => {
                let keep = rng.below(n);
                b.truncate(keep);
            }
            _ => {
                let i = rng.below(n).min(b.len());
                let word = "x".repeat(1 + rng.below(5000));
                b.splice(i..i, word.into_bytes());
            }
        }
    }
    b
}

/// What the harness found wrong with one case.
#[derive(Debug, Clone)]
pub struct Finding {
    /// Corpus file the case came from.
    pub input: String,
    /// What went wrong.
    pub what: String,
    /// The input that did it.
    pub bytes: Vec<u8>,
}

/// How a case ended when nothing was wrong.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Accepted; every output finite.
    Accepted,
    /// Refused with a short message.
    Refused,
}

type Res = Result<(), Box<dyn Error>>;

/// A wrong result inside an accepted case (not an input error): becomes a [`Finding`].
#[derive(Debug)]
struct Wrong(String);
impl std::fmt::Display for Wrong {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}
impl Error for Wrong {}

fn finite(what: &str, values: impl IntoIterator<Item = f64>) -> Res {
    match values.into_iter().find(|v| !v.is_finite()) {
        None => Ok(()),
        Some(v) => Err(Box::new(Wrong(format!("{what} is {v}")))),
    }
}

fn text_ok(what: &str, text: &str) -> Res {
    check_text(text, what).map_err(|e| Box::new(Wrong(e.to_string())) as Box<dyn Error>)
}

/// The seed log and model every model, term list and log case is checked against.
pub struct Ctx {
    log: Log,
    model: FittedModel,
    dir: tempfile::TempDir,
}

impl Ctx {
    /// Reads the seed log and model of the corpus.
    pub fn new() -> Self {
        let seed = corpus_dir().join("seed");
        Ctx {
            log: Log::read(&seed.join("log_sim.csv"), &ColumnMap::default()).expect("seed log"),
            model: FittedModel::load(&seed.join("model_dahl.json")).expect("seed model"),
            dir: tempfile::tempdir().expect("temp dir"),
        }
    }
}

impl Default for Ctx {
    fn default() -> Self {
        Self::new()
    }
}

/// The column names of a corpus log (the rig logs keep their own).
fn map_for(name: &str) -> ColumnMap {
    let mut m = ColumnMap::default();
    if name.contains("rig_si_units") {
        m.track = "position_m".into();
        m.bias = "force_N".into();
    } else if name.contains("rig_mm_pressure") {
        m.track = "position_mm".into();
        m.bias = "force_N".into();
    }
    m
}

/// Replays `model` over `log` and checks every number and text that `predict` and `score`
/// would write.
fn predict_and_score(model: &FittedModel, log: &Log) -> Res {
    let pred = model.predict_log(log)?;
    biasctl::score::check_prediction(&pred, log)?;
    let s = biasctl::score::score_with_units(&pred.residual, &pred.positions, &log.schema.units)?;
    finite("score", [s.mean, s.std, s.rms, s.median_abs])?;
    finite("score percentiles", s.percentiles.iter().map(|p| p.1))?;
    if let Some(t) = &s.trend {
        finite(
            "score trend",
            [t.slope, t.intercept, t.slope_se, t.t, t.p_value, t.r2],
        )?;
    }
    text_ok("score text", &s.to_text())?;
    let json = serde_json::to_string(&s)?;
    for key in ["mean", "std", "rms", "t", "slope", "slope_se"] {
        if json.contains(&format!("\"{key}\":null")) {
            return Err(Box::new(Wrong(format!("score JSON has \"{key}\": null"))));
        }
    }
    Ok(())
}

/// Fits `spec` on `log`, saves the model through the output layer and reads it back.
fn fit_save_load(spec: &ModelSpec, log: &Log, dir: &Path) -> Res {
    let model = fit(spec, log, &FitOptions::default().check()?)?;
    finite("fitted parameters", model.params().map(|p| p.value))?;
    let path = dir.join("m.json");
    model.save(&path)?;
    text_ok("model file", &std::fs::read_to_string(&path)?)?;
    let back = FittedModel::load(&path)?;
    predict_and_score(&back, log)
}

/// Runs one input of `kind` through its reader and everything behind it.
fn exercise(kind: Kind, name: &str, bytes: &[u8], ctx: &Ctx) -> Res {
    let dir = ctx.dir.path();
    match kind {
        Kind::Log => {
            let log = Log::from_reader(name, bytes, &map_for(name))?;
            for r in log.rows() {
                finite("log row", [r.time_s, r.track, r.bias.unwrap_or(0.0)])?;
            }
            if log.len() <= 400 {
                let spec = ModelSpec::parse("poly2,direction")?;
                fit_save_load(&spec, &log, dir)?;
            }
            if map_for(name) == ColumnMap::default() && log.schema.covariates.is_empty() {
                predict_and_score(&ctx.model, &log)?;
            }
            Ok(())
        }
        Kind::Model => {
            let text = std::str::from_utf8(bytes)?;
            let model = FittedModel::from_json(text, Path::new(name), &|_, _| None)?;
            predict_and_score(&model, &ctx.log)
        }
        Kind::Terms => {
            let text = std::str::from_utf8(bytes)?;
            let spec = ModelSpec::parse(text.trim())?;
            fit_save_load(&spec, &ctx.log, dir)
        }
        Kind::Drive => {
            let text = std::str::from_utf8(bytes)?;
            let drive = Drive::from_toml_str(name, text)?;
            let opts = SequenceOptions {
                n: Some(30),
                ..SequenceOptions::default()
            };
            let cfg = SimConfig::new(drive, "random", &opts, 1, &[])?;
            let log = simulate_log(&cfg)?;
            finite("simulated log", log.rows().map(|r| r.track))?;
            let out = dir.join("sim.csv");
            simulate_to_files(&cfg, &out, Some(&dir.join("truth.csv")))?;
            text_ok("simulated log file", &std::fs::read_to_string(&out)?)
        }
        Kind::Script => {
            let path = dir.join("script.csv");
            std::fs::write(&path, bytes)?;
            let opts = SequenceOptions {
                script: Some(path),
                ..SequenceOptions::default()
            };
            let cfg = SimConfig::new(Drive::paper1997(), "script", &opts, 1, &[])?;
            let out = dir.join("sim.csv");
            simulate_to_files(&cfg, &out, None)?;
            text_ok("simulated log file", &std::fs::read_to_string(&out)?)
        }
        Kind::Plant => {
            let text = std::str::from_utf8(bytes)?;
            biasctl::log::check_toml_numbers(text).map_err(Box::<dyn Error>::from)?;
            let spec: SettleSpec = toml::from_str(text)?;
            let report = analyse(&spec.check()?)?;
            finite("LQR gain", report.gain.iter().copied())?;
            text_ok("settle text", &report.to_text())?;
            text_ok("bounds CSV", &report.bounds_csv())?;
            text_ok("responses CSV", &report.responses_csv())
        }
    }
}

/// Files other than the harness's own outputs left in `dir`: temporaries of a failed write.
fn strays(dir: &Path) -> Vec<String> {
    let own = ["m.json", "sim.csv", "truth.csv", "script.csv"];
    std::fs::read_dir(dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| !own.contains(&n.as_str()))
                .collect()
        })
        .unwrap_or_default()
}

/// Runs one case: `Ok` if it was accepted with finite outputs or refused with a short message;
/// a [`Finding`] for a panic, a long or empty message, a non-finite output or a stray file.
pub fn run_case(input: &Input, bytes: &[u8], ctx: &Ctx) -> Result<Outcome, Finding> {
    let finding = |what: String| Finding {
        input: input.name.clone(),
        what,
        bytes: bytes.to_vec(),
    };
    let ran = catch_unwind(AssertUnwindSafe(|| {
        exercise(input.kind, &input.name, bytes, ctx)
    }));
    if let Some(s) = Some(strays(ctx.dir.path())).filter(|s| !s.is_empty()) {
        return Err(finding(format!("stray files after the case: {s:?}")));
    }
    match ran {
        Err(p) => {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            Err(finding(format!("panic: {msg}")))
        }
        Ok(Ok(())) => Ok(Outcome::Accepted),
        Ok(Err(e)) => {
            if let Some(w) = e.downcast_ref::<Wrong>() {
                return Err(finding(format!("accepted, but {w}")));
            }
            let m = biasctl::io::message(e.as_ref());
            let n = m.chars().count();
            if n == 0 || n >= MAX_MESSAGE {
                return Err(finding(format!(
                    "message of {n} characters: {}",
                    biasctl::io::quote(&m)
                )));
            }
            Ok(Outcome::Refused)
        }
    }
}

/// What a campaign did.
#[derive(Debug, Default)]
pub struct Campaign {
    /// Cases run.
    pub cases: u64,
    /// Cases accepted (all outputs finite).
    pub accepted: u64,
    /// Cases refused with a short message.
    pub refused: u64,
    /// Everything wrong.
    pub findings: Vec<Finding>,
    /// Wall time.
    pub elapsed: Duration,
}

/// Runs up to `cases` mutated cases of the seed corpus (round robin over its files, mutations
/// from `seed`), stopping early at `budget`.
pub fn campaign(cases: u64, seed: u64, budget: Duration) -> Campaign {
    let ctx = Ctx::new();
    let corpus = load(&corpus_dir().join("seed"));
    let mut rng = Rng::new(seed);
    let start = Instant::now();
    let mut c = Campaign::default();
    // Hostile users are loud, and the panics we catch are findings anyway.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    for i in 0..cases {
        if start.elapsed() > budget {
            break;
        }
        let input = &corpus[(i as usize) % corpus.len()];
        let bytes = mutate(&mut rng, &input.bytes);
        c.cases += 1;
        match run_case(input, &bytes, &ctx) {
            Ok(Outcome::Accepted) => c.accepted += 1,
            Ok(Outcome::Refused) => c.refused += 1,
            Err(f) => c.findings.push(f),
        }
    }
    std::panic::set_hook(hook);
    c.elapsed = start.elapsed();
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::process::{Command, Stdio};

    fn bin() -> Command {
        Command::new(env!("CARGO_BIN_EXE_biasctl"))
    }

    fn show(f: &[Finding]) -> String {
        f.iter()
            .map(|f| format!("{}: {}", f.input, f.what))
            .collect::<Vec<_>>()
            .join("\n")
    }

    #[test]
    fn every_seed_and_every_past_finding_is_accepted_finite_or_refused_cleanly() {
        let ctx = Ctx::new();
        let seeds = load(&corpus_dir().join("seed"));
        assert!(seeds.len() >= 8, "seed corpus incomplete");
        for s in &seeds {
            assert_eq!(
                run_case(s, &s.bytes, &ctx).map_err(|f| f.what),
                Ok(Outcome::Accepted),
                "seed {} must be accepted",
                s.name
            );
        }
        let findings = load(&corpus_dir().join("findings"));
        assert!(findings.len() >= 9);
        let bad: Vec<Finding> = findings
            .iter()
            .filter_map(|f| run_case(f, &f.bytes, &ctx).err())
            .collect();
        assert!(bad.is_empty(), "{}", show(&bad));
        // The findings of #17 that must be refused (not merely survived): reference the issue.
        for name in [
            "log_position_1e300.csv",
            "drive_pes_noise_1e308.toml",
            "plant_ts_1e308.toml",
            "script_dwell_1e308.csv",
            "model_scale_0.json",
            "model_dahl_rate_negative.json",
            "model_coefficient_1e308.json",
        ] {
            let f = findings.iter().find(|f| f.name == name).expect(name);
            assert_eq!(
                run_case(f, &f.bytes, &ctx).ok(),
                Some(Outcome::Refused),
                "{name}"
            );
        }
    }

    #[test]
    fn bounded_mutation_campaign_finds_nothing() {
        // 20 s budget on 2 shared cores; fixed seed, so a finding reproduces.
        let c = campaign(600, 17, Duration::from_secs(20));
        assert!(c.cases >= 100, "only {} cases in {:?}", c.cases, c.elapsed);
        assert!(c.accepted > 0 && c.refused > 0, "{c:?}");
        assert!(c.findings.is_empty(), "{}", show(&c.findings));
    }

    #[test]
    fn the_mutator_changes_inputs_and_is_reproducible() {
        let seed = b"time_s,track,bias\n0.1,120,35.5\n".to_vec();
        let a: Vec<Vec<u8>> = (0..20).map(|i| mutate(&mut Rng::new(i), &seed)).collect();
        let b: Vec<Vec<u8>> = (0..20).map(|i| mutate(&mut Rng::new(i), &seed)).collect();
        assert_eq!(a, b);
        assert!(a.iter().filter(|m| **m != seed).count() >= 15);
        let mut r = Rng::new(1);
        let w: Vec<f64> = (0..1000).map(|_| r.wide_number().abs()).collect();
        assert!(
            w.iter()
                .all(|v| v.is_finite() && *v >= 1e-300 && *v < 1e301)
        );
        assert!(w.iter().any(|v| *v > 1e200) && w.iter().any(|v| *v < 1e-200));
    }

    #[test]
    fn hostile_sizes_end_in_clear_errors_quickly() {
        let dir = tempfile::tempdir().unwrap();
        let t = Instant::now();
        // A model "file" of 70 MB (sparse), a 2 MB line, a 100,000-column header, nesting.
        let big = dir.path().join("model_big.json");
        std::fs::File::create(&big)
            .unwrap()
            .set_len(70 << 20)
            .unwrap();
        let e = FittedModel::load(&big).unwrap_err().to_string();
        assert!(e.contains("64 MiB"), "{e}");
        let line = format!("time_s,track,bias\n0,{},1\n", "1".repeat(2 << 20));
        let e = Log::from_reader("long", line.as_bytes(), &ColumnMap::default()).unwrap_err();
        assert!(biasctl::io::message(&e).contains("1 MiB"), "{e}");
        let header: Vec<String> = (0..100_000).map(|i| format!("c{i}")).collect();
        let wide = format!("time_s,track,bias,{}\n0,1,1\n", header.join(","));
        let e = Log::from_reader("wide", wide.as_bytes(), &ColumnMap::default()).unwrap_err();
        assert!(biasctl::io::message(&e).contains("at most 1000"), "{e}");
        let nested = format!("{}{}", "[".repeat(100_000), "]".repeat(100_000));
        let e = FittedModel::from_json(&nested, Path::new("n.json"), &|_, _| None).unwrap_err();
        assert!(
            biasctl::io::message(&e).chars().count() < MAX_MESSAGE,
            "{e}"
        );
        let terms = format!("poly2,{}", "t".repeat(100_000));
        let e = ModelSpec::parse(&terms).unwrap_err();
        assert!(biasctl::io::message(&e).chars().count() < MAX_MESSAGE);
        assert!(t.elapsed() < Duration::from_secs(10), "{:?}", t.elapsed());
    }

    #[test]
    fn stdout_errors_exit_2_and_a_closed_pipe_exits_0_never_a_panic() {
        if Path::new("/dev/full").exists() {
            let seed = corpus_dir().join("seed/log_sim.csv");
            let seed = seed.to_str().unwrap();
            for args in [&["settle", "--json"][..], &["check", "--data", seed][..]] {
                let full = std::fs::OpenOptions::new()
                    .write(true)
                    .open("/dev/full")
                    .unwrap();
                let out = bin().args(args).stdout(full).output().unwrap();
                let err = String::from_utf8_lossy(&out.stderr);
                assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
                assert!(
                    err.contains("No space left") && !err.contains("panicked"),
                    "{err}"
                );
                assert_eq!(err.lines().count(), 1, "{err}");
            }
        }
        // A reader that goes away after a few bytes: exit 0, nothing on stderr.
        let mut child = bin()
            .args([
                "simulate",
                "--sequence",
                "random",
                "--n",
                "20000",
                "--out",
                "-",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut first = [0u8; 16];
        std::io::Read::read_exact(child.stdout.as_mut().unwrap(), &mut first).unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        assert_eq!(
            out.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            out.stderr.is_empty(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    fn simulate(dir: &Path, seed: &str, n: &str, out: &str) -> Command {
        let mut c = bin();
        c.current_dir(dir)
            .args(crate::common::simulate_random_args(n, seed, out));
        c
    }

    #[cfg(unix)]
    #[test]
    fn sigkill_at_random_moments_keeps_the_old_target_and_leaves_nothing_after_the_next_run() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        assert!(simulate(d, "1", "300", "t.csv").status().unwrap().success());
        let old = std::fs::read(d.join("t.csv")).unwrap();
        assert!(
            simulate(d, "2", "20000", "new.csv")
                .status()
                .unwrap()
                .success()
        );
        let new = std::fs::read(d.join("new.csv")).unwrap();
        std::fs::remove_file(d.join("new.csv")).unwrap();
        let mut rng = Rng::new(7);
        for _ in 0..6 {
            let mut child = simulate(d, "2", "20000", "t.csv")
                .stdout(Stdio::null())
                .spawn()
                .unwrap();
            std::thread::sleep(Duration::from_millis(rng.below(400) as u64));
            let _ = child.kill(); // SIGKILL
            let _ = child.wait();
            let now = std::fs::read(d.join("t.csv")).unwrap();
            assert!(
                now == old || now == new,
                "t.csv is neither the old nor the new log"
            );
            if now == new {
                std::fs::write(d.join("t.csv"), &old).unwrap();
            }
        }
        // The next run sweeps what the killed ones left.
        assert!(simulate(d, "1", "300", "t.csv").status().unwrap().success());
        assert_eq!(names(d), ["t.csv"]);
    }

    #[test]
    fn two_concurrent_writers_leave_one_complete_file() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let mut refs = Vec::new();
        for seed in ["3", "4"] {
            let name = format!("ref{seed}.csv");
            assert!(simulate(d, seed, "3000", &name).status().unwrap().success());
            refs.push(std::fs::read(d.join(&name)).unwrap());
        }
        let kids: Vec<_> = ["3", "4"]
            .iter()
            .map(|s| {
                simulate(d, s, "3000", "same.csv")
                    .stdout(Stdio::null())
                    .spawn()
                    .unwrap()
            })
            .collect();
        for mut k in kids {
            assert!(k.wait().unwrap().success());
        }
        let got = std::fs::read(d.join("same.csv")).unwrap();
        assert!(refs.contains(&got), "the target is not one complete run");
        assert_eq!(names(d), ["ref3.csv", "ref4.csv", "same.csv"]);
    }

    #[test]
    fn an_output_on_an_input_is_refused_before_anything_runs() {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("log.csv");
        std::fs::copy(corpus_dir().join("seed/log_sim.csv"), &log).unwrap();
        let before = std::fs::read(&log).unwrap();
        let l = log.to_str().unwrap();
        let out = bin()
            .args(["fit", "--data", l, "--terms", "poly2", "--out", l])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--data and --out"), "{err}");
        assert_eq!(std::fs::read(&log).unwrap(), before);
    }
}
