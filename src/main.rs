//! The `biasctl` command line: parses flags into the library's validated configs and calls the
//! library. Exit codes: 0 success (also when the reader of stdout goes away, as with
//! `biasctl … | head`), 2 bad input or a failed write (one message on stderr).

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    let args = match cli::parse() {
        Ok(args) => args,
        Err(e) => e.exit(),
    };
    let result = cli::run(args).and_then(|()| Ok(biasctl::flush_stdout()?));
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) if biasctl::is_broken_pipe(err.as_ref()) => ExitCode::SUCCESS,
        Err(err) => {
            // stderr gone too: nothing left to tell, the exit code still says it.
            let _ = std::io::Write::write_all(
                &mut std::io::stderr(),
                format!("error: {}\n", cli::message(err.as_ref())).as_bytes(),
            );
            ExitCode::from(2)
        }
    }
}
