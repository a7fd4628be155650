//! The errors of reading a log ([`LogError`]) and the messages that name the file, line and
//! column of each.

use super::UnitError;
use super::lines;
use std::io;

/// An error reading a measurement log. Every variant names the file; value errors name the line
/// (1-based, counting metadata lines) and the column.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LogError {
    /// The file could not be opened or read.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// The log file.
        file: String,
        /// The operating-system error.
        #[source]
        source: io::Error,
    },
    /// The file holds no header row.
    #[error("{file}: the file is empty (expected a header row such as `time_s,track,bias`)")]
    Empty {
        /// The log file.
        file: String,
    },
    /// A required column is not in the header.
    #[error(
        "{file}: line {line}: missing required column `{column}` (columns found: {found}){}; name it with {field} {}",
        did_you_mean(.suggestion),
        .suggestion.as_deref().map_or("NAME".into(), crate::io::shell_quote)
    )]
    MissingColumn {
        /// The log file.
        file: String,
        /// Line of the header.
        line: u64,
        /// The column that was looked for.
        column: String,
        /// The columns the header holds.
        found: String,
        /// The setting that renames it.
        field: crate::field::Field,
        /// The header's column most like the one looked for, if any.
        suggestion: Option<String>,
    },
    /// Several required columns are not in the header: all are named at once, with the flags
    /// that would name them (a rig's `time_s,position_m,force_N` needs two).
    #[error(
        "{file}: line {line}: missing required columns {missing} (columns found: {found}); name them: {hint}"
    )]
    MissingColumns {
        /// The log file.
        file: String,
        /// Line of the header.
        line: u64,
        /// The columns looked for, quoted and listed (`` `track`, `bias` ``).
        missing: String,
        /// The columns the header holds.
        found: String,
        /// Each missing column's setting and the header's column that most likely holds it
        /// (`ColumnMap::track position_m`), `NAME` where none does.
        hint: String,
    },
    /// Two columns share a name.
    #[error("{file}: line {line}: column `{column}` appears twice in the header")]
    DuplicateColumn {
        /// The log file.
        file: String,
        /// Line of the header.
        line: u64,
        /// The repeated name.
        column: String,
    },
    /// A cell is not a finite number.
    #[error(
        "{file}: line {line}, column {column_index} (`{column}`): {problem}{}",
        if .value.is_empty() { String::new() } else { format!(": `{}`", .value) }
    )]
    BadValue {
        /// The log file.
        file: String,
        /// 1-based line number.
        line: u64,
        /// 1-based column number.
        column_index: usize,
        /// Column name.
        column: String,
        /// The cell's text (empty for an empty cell, which the message then does not quote).
        value: String,
        /// What is wrong with it.
        problem: &'static str,
    },
    /// Time decreased from one row to the next.
    #[error(
        "{file}: line {line}, column {column_index} (`{column}`): time goes backwards ({value} after {previous})"
    )]
    TimeBackwards {
        /// The log file.
        file: String,
        /// 1-based line number.
        line: u64,
        /// 1-based column number.
        column_index: usize,
        /// Column name.
        column: String,
        /// Time on the previous row.
        previous: f64,
        /// Time on this row.
        value: f64,
    },
    /// A row's shape is wrong (for example a different number of fields than the header).
    #[error("{file}: line {line}: {message}")]
    Malformed {
        /// The log file.
        file: String,
        /// 1-based line number.
        line: u64,
        /// The CSV parser's description.
        message: String,
    },
    /// The log has a header but no row under it.
    #[error("{file}: no rows under the header (a log holds one row per seek)")]
    NoRows {
        /// The log file.
        file: String,
    },
    /// The log has rows but none with a measured bias.
    #[error("{file}: no measured rows: every `{column}` cell is empty")]
    NoMeasuredRows {
        /// The log file.
        file: String,
        /// The bias column's name.
        column: String,
    },
    /// A unit label in the metadata (`bias_unit`, `position_unit`) cannot be used.
    #[error(transparent)]
    Unit(#[from] UnitError),
}

/// `; did you mean `x`?` or nothing (for [`LogError::MissingColumn`]).
fn did_you_mean(suggestion: &Option<String>) -> String {
    suggestion
        .as_ref()
        .map(|s| format!("; did you mean `{s}`?"))
        .unwrap_or_default()
}

/// A metadata or header line that is not UTF-8: names the line, the character where the text
/// stops being UTF-8 and the byte there, and how to save the file.
pub(super) fn not_utf8(file: &str, line: u64, bytes: &[u8], e: std::str::Utf8Error) -> LogError {
    let at = e.valid_up_to();
    let column = String::from_utf8_lossy(&bytes[..at]).chars().count() + 1;
    LogError::Malformed {
        file: file.into(),
        line,
        message: format!(
            "character {column} (byte 0x{:02X}) is not UTF-8 text; the file is likely in a \
             Windows code page (Excel's plain \"CSV\" writes `µ` as 0xB5): save it as \
             \"CSV UTF-8\" or convert it (`iconv -f CP1252 -t UTF-8`)",
            bytes.get(at).copied().unwrap_or(0)
        ),
    }
}

/// An I/O error of the source while reading rows, as the csv parser reported it: no line.
pub(super) fn source_failed(file: &str, e: &io::Error) -> LogError {
    LogError::Malformed {
        file: file.into(),
        line: 0,
        message: e.to_string(),
    }
}

pub(super) fn malformed(file: &str, line: u64, e: &csv::Error) -> LogError {
    LogError::Malformed {
        file: file.into(),
        line,
        message: lines::csv_problem(e),
    }
}
