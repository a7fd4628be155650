//! The `biasctl` command line: parses flags into the library's validated configs and calls the
//! library. Every error is printed with its cause chain and exits with code 2.

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    restore_sigpipe();
    let args = match cli::parse() {
        Ok(args) => args,
        Err(e) => e.exit(),
    };
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("{}", error_text(&err));
            ExitCode::from(2)
        }
    }
}

/// The error and its causes, one per line; a cause whose text the lines above already contain
/// (an error that prints its source inside its own message) is not repeated.
fn error_text(err: &anyhow::Error) -> String {
    let mut text = format!("error: {err}");
    for cause in err.chain().skip(1) {
        let c = cause.to_string();
        if !text.contains(&c) {
            text.push_str(&format!("\n  caused by: {c}"));
        }
    }
    text
}

/// Restores the default action of SIGPIPE, so that `biasctl … | head` ends quietly when the
/// reader goes away, as other Unix tools do, instead of panicking in `println!` (the Rust
/// runtime ignores SIGPIPE by default).
#[cfg(unix)]
fn restore_sigpipe() {
    // SAFETY: called first thing in `main`, before any other thread exists; SIG_DFL is a valid
    // disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

#[cfg(not(unix))]
fn restore_sigpipe() {}
