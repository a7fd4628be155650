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

/// Path of a file under the project's real-data folder (`data/real/`, see its README), if present.
pub fn real_data(rel: &str) -> Option<String> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("data/real")
        .join(rel);
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
