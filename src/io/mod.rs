//! The one output layer: every byte biasctl writes goes through here.
//!
//! - [`write_atomic`] / [`write_string_atomic`] write one file safely (see `file`): a regular
//!   file is replaced atomically (temporary file in the target's directory, renamed into place,
//!   the target's permissions kept, a symlink's target written); a device, FIFO or `/dev/stdout`
//!   is written directly; `-` is stdout.
//! - `StagedDir` builds a multi-file output (report, `diagnose --out`) in one temporary folder
//!   and moves it into place only when complete.
//! - `check_paths` refuses an output that is also an input, or two outputs on one file, before
//!   anything runs.
//! - `write_stdout` is the one path to standard output: a closed pipe becomes
//!   [`OutputError::BrokenPipe`] (the CLI ends quietly with exit 0), any other write error a
//!   clear [`OutputError::Stdout`].
//! - `number::write_shortest` writes a CSV number as `Display` would, through `ryu`.
//! - [`json::to_string_pretty`] is the one JSON writer: a non-finite number (which serde_json
//!   would write as `null`) is refused naming its key path.
//! - `finite` refuses to emit a non-finite number; [`quote`] and [`message`] keep error
//!   messages short whatever the user typed; [`shell_quote`] quotes a value for a suggested
//!   command line.

pub(crate) mod fault;
pub(crate) mod file;
pub(crate) mod finite;
pub(crate) mod json;
pub(crate) mod number;
pub(crate) mod stdout;
pub(crate) mod words;

pub use {file::write_atomic, file::write_string_atomic, words::shell_quote};

pub(crate) use file::StagedDir;
pub use finite::{NonFinite, check_text};
#[cfg(feature = "cli")]
pub(crate) use {
    file::check_paths, stdout::flush_stdout, stdout::is_broken_pipe, stdout::write_stdout,
};

use std::io;
use std::path::PathBuf;

// The namespace's public items that live in its submodules (the crate root keeps only the
// names most users need; see `biasctl::prelude`).
pub use file::Sink;
pub use json::to_string_pretty;

/// At most this many characters of a user's value are quoted in a message ([`quote`]).
pub(crate) const QUOTE_CHARS: usize = 80;

/// An error while writing output, naming the file (or stdout).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    /// The file (or its temporary sibling) could not be created, written or renamed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The output file that was being written.
        path: PathBuf,
        /// The operating-system error.
        #[source]
        source: io::Error,
    },
    /// The content producer failed; nothing was written to `path`.
    #[error("{message} (nothing written to {path})")]
    Producer {
        /// The output file that was not written.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// Standard output could not be written (other than a closed pipe).
    #[error("cannot write to stdout: {0}")]
    Stdout(#[source] io::Error),
    /// The reader of standard output went away (`biasctl … | head`): not a failure; the CLI
    /// stops quietly with exit 0.
    #[error("stdout was closed by its reader")]
    BrokenPipe,
    /// An output path is also an input, or two outputs name one file. `first` and `second` are
    /// the roles the caller gave the two paths (the CLI passes its flag names).
    #[error("{first} and {second} name the same file {path}; {why}")]
    SamePath {
        /// The role (flag) of the first path.
        first: String,
        /// The role (flag) of the second path.
        second: String,
        /// The file both name.
        path: PathBuf,
        /// What would go wrong.
        why: &'static str,
    },
    /// A non-finite number would have been written.
    #[error(transparent)]
    NonFinite(#[from] NonFinite),
}

impl OutputError {
    /// Whether this is a closed stdout pipe (end quietly, exit 0).
    #[cfg_attr(not(feature = "cli"), allow(dead_code))] // used by the CLI only
    pub(crate) fn is_broken_pipe(&self) -> bool {
        matches!(self, OutputError::BrokenPipe)
    }
}

/// `value` quoted for a message: the whole value if it has at most `QUOTE_CHARS` characters,
/// else its first 60 and last 12 characters around `…` and the full length, so that a 300 kB
/// value never floods the terminal.
pub fn quote(value: &str) -> String {
    let n = value.chars().count();
    if n <= QUOTE_CHARS {
        return value.to_string();
    }
    let head: String = value.chars().take(60).collect();
    let tail: String = value.chars().skip(n - 12).collect();
    format!("{head}…{tail} ({n} characters)")
}

/// The text of an error and its causes, one per line (a cause whose text the lines above
/// already contain is not repeated), every whitespace-separated word longer than
/// `QUOTE_CHARS` shortened by [`quote`] and every line cut to `MESSAGE_LINE_CHARS`: what
/// the CLI prints after `error: `.
pub fn message(err: &(dyn std::error::Error + 'static)) -> String {
    message_with(err, &|line| line.to_string())
}

/// As [`message`], with each error's text passed through `rewrite` before it is shortened (the
/// CLI renders the library's setting names as its flags there).
pub(crate) fn message_with(
    err: &(dyn std::error::Error + 'static),
    rewrite: &dyn Fn(&str) -> String,
) -> String {
    let mut text = shorten_line(&rewrite(&err.to_string()));
    let mut cause = err.source();
    while let Some(c) = cause {
        let line = shorten_line(&rewrite(&c.to_string()));
        if !text.contains(&line) {
            text.push_str("\n  caused by: ");
            text.push_str(&line);
        }
        cause = c.source();
    }
    // The whole message, causes included, stays under MESSAGE_CHARS.
    let n = text.chars().count();
    if n > MESSAGE_CHARS {
        text = cut_middle(&text, MESSAGE_CHARS - 70, 60);
    }
    text
}

/// `text` (longer than `head + tail` characters) as its first `head` and last `tail`
/// characters around ` … `, each cut back to a word boundary (whitespace) when one lies in the
/// last (first) third of it, so that no word is cut in two.
fn cut_middle(text: &str, head: usize, tail: usize) -> String {
    let chars: Vec<char> = text.chars().collect();
    let n = chars.len();
    let mut h = head.min(n);
    if let Some(i) = (h * 2 / 3..h).rev().find(|&i| chars[i].is_whitespace()) {
        h = i;
    }
    let mut t = n.saturating_sub(tail).max(h);
    if let Some(i) = (t..(t + tail / 3).min(n)).find(|&i| chars[i].is_whitespace()) {
        t = i + 1;
    }
    let a: String = chars[..h].iter().collect();
    let b: String = chars[t..].iter().collect();
    format!("{} … {}", a.trim_end(), b.trim_start())
}

/// Most characters of a whole error message ([`message`]), its causes included.
pub(crate) const MESSAGE_CHARS: usize = 280;

/// Most characters of one line of an error message ([`message`]).
pub(crate) const MESSAGE_LINE_CHARS: usize = 240;

/// `text` through [`shorten_words`], then cut in the middle to [`MESSAGE_LINE_CHARS`].
fn shorten_line(text: &str) -> String {
    let t = shorten_words(text);
    let n = t.chars().count();
    if n <= MESSAGE_LINE_CHARS {
        return t;
    }
    cut_middle(&t, MESSAGE_LINE_CHARS - 60, 50)
}

/// `text` with every word (run of non-whitespace) longer than [`QUOTE_CHARS`] passed through
/// [`quote`].
pub(crate) fn shorten_words(text: &str) -> String {
    let mut out = String::with_capacity(text.len().min(4096));
    let mut word = String::new();
    let flush = |word: &mut String, out: &mut String| {
        out.push_str(&quote(word));
        word.clear();
    };
    for ch in text.chars() {
        if ch.is_whitespace() {
            flush(&mut word, &mut out);
            out.push(ch);
        } else {
            word.push(ch);
        }
    }
    flush(&mut word, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quote_keeps_short_values_and_cuts_long_ones_to_under_100_chars() {
        assert_eq!(quote("poly2"), "poly2");
        let long = "x".repeat(100_000);
        let q = quote(&long);
        assert!(q.chars().count() < 100, "{q}");
        assert!(q.contains("100000 characters"));
        // Multi-byte characters are cut on character boundaries (no panic).
        let wide = "µ".repeat(500);
        assert!(quote(&wide).starts_with("µµµ"));
    }

    /// Reference: the words of the text. A long message is cut between words, never inside
    /// one, and keeps its start and end.
    #[test]
    fn a_long_message_is_cut_between_words() {
        let words: Vec<String> = (0..120).map(|i| format!("word{i:03}")).collect();
        let err = io::Error::other(words.join(" "));
        let m = message(&err);
        assert!(m.chars().count() <= MESSAGE_LINE_CHARS, "{m}");
        assert!(
            m.starts_with("word000 word001") && m.ends_with("word118 word119"),
            "{m}"
        );
        for w in m.split_whitespace().filter(|w| *w != "…") {
            assert!(words.iter().any(|x| x == w), "`{w}` is a cut word in {m}");
        }
        // Without whitespace to cut at, the cut stays at the limit.
        let one = io::Error::other("ab,".repeat(200));
        assert!(message(&one).chars().count() <= MESSAGE_LINE_CHARS);
    }

    #[test]
    fn message_shortens_every_long_word_and_keeps_the_rest() {
        let err = io::Error::other(format!("unknown term `{}` in --terms", "a".repeat(300_000)));
        let m = message(&err);
        assert!(m.len() < 200, "{} bytes", m.len());
        assert!(m.starts_with("unknown term `aaa") && m.ends_with("in --terms"));
    }
}
