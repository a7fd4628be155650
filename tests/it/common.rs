//! Helpers shared by the integration tests: run the `biasctl` binary and inspect its output.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// The result of one `biasctl` run.
pub struct Run {
    pub code: i32,
    pub stdout: String,
    pub stderr: String,
}

/// Runs `biasctl` with `args` and captures its output.
pub fn biasctl(args: &[&str]) -> Run {
    capture(Command::new(env!("CARGO_BIN_EXE_biasctl")).args(args))
}

/// Runs `biasctl` with `args` in the working directory `dir` and captures its output.
pub fn biasctl_in(dir: &Path, args: &[&str]) -> Run {
    capture(
        Command::new(env!("CARGO_BIN_EXE_biasctl"))
            .args(args)
            .current_dir(dir),
    )
}

/// Runs `biasctl` with `args`, `input` written to its standard input, and captures its output.
pub fn biasctl_stdin(args: &[&str], input: &[u8]) -> Run {
    use std::io::Write;
    use std::process::Stdio;
    let mut c = Command::new(env!("CARGO_BIN_EXE_biasctl"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run biasctl");
    // biasctl may stop reading at an error before the input's end: a closed pipe is its answer.
    match c.stdin.take().expect("stdin").write_all(input) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => {}
        r => r.expect("write stdin"),
    }
    run_of(c.wait_with_output().expect("run biasctl"))
}

fn capture(cmd: &mut Command) -> Run {
    run_of(cmd.output().expect("run biasctl"))
}

fn run_of(out: std::process::Output) -> Run {
    Run {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

/// Runs `biasctl` and asserts it succeeded; returns stdout.
pub fn ok(args: &[&str]) -> String {
    let r = biasctl(args);
    assert_eq!(r.code, 0, "biasctl {args:?} failed:\n{}", r.stderr);
    r.stdout
}

/// Runs `biasctl`, asserts exit code 2 and that stderr contains every needle; returns stderr.
pub fn fails_with(args: &[&str], needles: &[&str]) -> String {
    let r = biasctl(args);
    assert_eq!(
        r.code, 2,
        "biasctl {args:?}: expected exit 2, got {}\n{}",
        r.code, r.stderr
    );
    for n in needles {
        assert!(
            r.stderr.contains(n),
            "biasctl {args:?}: stderr lacks `{n}`:\n{}",
            r.stderr
        );
    }
    r.stderr
}

/// Writes `text` to `dir/name` and returns the path as a String.
pub fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write fixture");
    p.display().to_string()
}

/// Path of a file under the repository's `data/` folder.
pub fn data(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("data")
        .join(name)
        .display()
        .to_string()
}

/// The folder of the real measurements (EMPS, pneumatic, MR damper; see `data/real/README.md`):
/// `$BIASCTL_REAL_DATA` if set, else `../shared/data/real` beside the crate root. `None` when
/// neither is set and present. They are other people's data and are not in the repository.
pub fn real_data_dir() -> Option<PathBuf> {
    if let Some(dir) = std::env::var_os("BIASCTL_REAL_DATA") {
        let dir = PathBuf::from(dir);
        assert!(
            dir.is_dir(),
            "BIASCTL_REAL_DATA={} is not a folder (see data/real/README.md)",
            dir.display()
        );
        return Some(dir);
    }
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real");
    dir.is_dir().then_some(dir)
}

/// True (after saying so on stderr) when the real data is not there: a real-data test then
/// returns at once and passes. Put `if skip_without_real_data() { return; }` first in it.
pub fn skip_without_real_data() -> bool {
    use std::io::Write;
    let skip = real_data_dir().is_none();
    if skip {
        // Straight to stderr, past the test harness's capture, so a plain `cargo test` shows it.
        let _ = writeln!(
            std::io::stderr(),
            "skipped: real data not found (see data/real/README.md)"
        );
    }
    skip
}

/// Path of a file in the real-data folder (see [`real_data_dir`]), if present.
pub fn real_data(rel: &str) -> Option<String> {
    let p = real_data_dir()?.join(rel);
    p.exists().then(|| p.display().to_string())
}

/// The arguments of `simulate --sequence random --n N --seed S --out OUT` on the default drive:
/// the random-seek log several tests start from.
pub fn simulate_random_args<'a>(n: &'a str, seed: &'a str, out: &'a str) -> [&'a str; 9] {
    [
        "simulate",
        "--sequence",
        "random",
        "--n",
        n,
        "--seed",
        seed,
        "--out",
        out,
    ]
}

/// The line an editor shows for byte `at` of `text`: 1 + the line ends before it, where `\r\n`,
/// `\n` and a lone `\r` each end one line. The reference for line numbers in error messages.
pub fn editor_line(text: &str, at: usize) -> usize {
    1 + text[..at]
        .replace("\r\n", "\n")
        .matches(['\n', '\r'])
        .count()
}

/// `text` with each `\n` line end written `end` instead (`\r\n`, `\r`, or `\n` itself).
pub fn with_line_ends(text: &str, end: &str) -> String {
    text.replace('\n', end)
}

/// `text` with its `\n` line ends written `\n`, `\r\n` and `\r` in turn (a file edited on
/// several systems).
pub fn mixed_line_ends(text: &str) -> String {
    let mut m = String::new();
    for (i, line) in text.split('\n').enumerate() {
        if i > 0 {
            m.push_str(["\n", "\r\n", "\r"][i % 3]);
        }
        m.push_str(line);
    }
    m
}

/// A small log with 60 measured rows spread over the stroke; `bias_scale` multiplies the bias.
pub fn log_text(bias_scale: f64) -> String {
    let mut s = String::from("time_s,track,bias\n");
    for i in 0..60u32 {
        let track = (i * 397) % 2999;
        let bias =
            (30.0 + 0.01 * f64::from(track) + if i % 2 == 0 { 5.0 } else { -5.0 }) * bias_scale;
        s.push_str(&format!("{:.1},{track},{bias}\n", f64::from(i) * 0.1));
    }
    s
}

pub fn no_nonfinite(text: &str, what: &str) {
    for cell in text.split([',', '\n', ' ', '"', ':']) {
        let c = cell.trim().to_ascii_lowercase();
        assert!(
            !matches!(c.as_str(), "nan" | "inf" | "-inf" | "+inf" | "infinity"),
            "{what} holds a non-finite value `{cell}`"
        );
    }
}

/// A random-seek log of `n` rows on the default drive (`r.csv` in `dir`) and the
/// `position-direction` model fitted to it (`m.json`): the start of the tests that need both.
pub fn random_log_and_model(dir: &std::path::Path, n: &str) -> (String, String) {
    let log = dir.join("r.csv").display().to_string();
    ok(&["simulate", "--sequence", "random", "--n", n, "--out", &log]);
    let model = dir.join("m.json").display().to_string();
    ok(&[
        "fit",
        "--data",
        &log,
        "--model",
        "position-direction",
        "--out",
        &model,
    ]);
    (log, model)
}
