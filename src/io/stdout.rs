//! The one path to standard output. Every command prints through [`write_stdout`] (or writes a
//! file named `-` through [`super::write_atomic`]), so a closed pipe (`biasctl … | head`) and a
//! full disk behind `> file` are handled once: [`OutputError::BrokenPipe`] (the CLI exits 0
//! quietly, as ripgrep does) or [`OutputError::Stdout`] (one line on stderr, exit 2) — never a
//! panic.

use super::OutputError;
use super::fault::Faulty;
use std::io::{self, Write};

/// A handle on the process's stdout for [`super::write_atomic`]'s `-` target.
pub(crate) fn stdout_sink() -> io::Stdout {
    io::stdout()
}

/// Maps a stdout write error: a closed pipe is [`OutputError::BrokenPipe`], the rest
/// [`OutputError::Stdout`].
pub(crate) fn map_stdout_error(e: io::Error) -> OutputError {
    if e.kind() == io::ErrorKind::BrokenPipe {
        OutputError::BrokenPipe
    } else {
        OutputError::Stdout(e)
    }
}

/// Writes `text` to stdout (and flushes it, so a failure surfaces here, at the line that
/// caused it).
/// A text holding a non-finite number (`NaN`, `inf`) is refused whole
/// ([`OutputError::NonFinite`]) and nothing of it is printed.
#[cfg_attr(not(feature = "cli"), allow(dead_code))] // used by the CLI only
pub(crate) fn write_stdout(text: &str) -> Result<(), OutputError> {
    super::check_text(text, "stdout")?;
    let mut out = Faulty::armed(io::stdout().lock());
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(map_stdout_error)
}

/// Flushes stdout at the end of a run; errors mapped as [`write_stdout`]'s.
#[cfg_attr(not(feature = "cli"), allow(dead_code))] // used by the CLI only
pub(crate) fn flush_stdout() -> Result<(), OutputError> {
    io::stdout().flush().map_err(map_stdout_error)
}

/// Whether `err` or one of its causes is a closed stdout pipe ([`OutputError::BrokenPipe`], or
/// an I/O error of kind `BrokenPipe`), also behind `#[error(transparent)]` wrappers (which
/// show the same text): the CLI then ends quietly with exit 0.
#[cfg_attr(not(feature = "cli"), allow(dead_code))] // used by the CLI only
pub(crate) fn is_broken_pipe(err: &(dyn std::error::Error + 'static)) -> bool {
    let pipe_text = OutputError::BrokenPipe.to_string();
    let mut cur = Some(err);
    while let Some(e) = cur {
        if e.downcast_ref::<OutputError>()
            .is_some_and(OutputError::is_broken_pipe)
            || e.downcast_ref::<io::Error>()
                .is_some_and(|io| io.kind() == io::ErrorKind::BrokenPipe)
            || e.to_string() == pipe_text
        {
            return true;
        }
        cur = e.source();
    }
    false
}
