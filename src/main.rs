//! The `biasctl` command line: a thin binary over the library's `cli` module (the `cli`
//! feature, on by default), which parses flags into the library's validated configs and calls
//! the library. Exit codes: 0 success (also when the reader of stdout goes away, as with
//! `biasctl … | head`), 2 bad input or a failed write (one message on stderr).

fn main() -> std::process::ExitCode {
    biasctl::cli::main()
}
