//! A log's head, read in order: the byte-order mark, the metadata lines before the header, the
//! header line itself, and the rows read ahead that tell which other columns are numeric
//! covariates.

use super::LogError;
use super::dialect::parse_field;
use super::error::not_utf8;
use super::lines;
use super::source::{Source, field};
use std::io::{self, BufRead, Read};

/// Rows the reader looks at, after the header, to find covariate columns that are not numeric.
pub(crate) const LOOKAHEAD_ROWS: usize = 64;

/// Skips a UTF-8 byte-order mark (as spreadsheet exports write: it is not part of the first
/// line) and refuses UTF-16 text.
pub(super) fn skip_byte_order_mark(buf: &mut impl BufRead, file: &str) -> Result<(), LogError> {
    let start = buf.fill_buf().map_err(|source| io_error(file, source))?;
    if start.starts_with(&[0xEF, 0xBB, 0xBF]) {
        buf.consume(3);
    } else if start.starts_with(&[0xFF, 0xFE]) || start.starts_with(&[0xFE, 0xFF]) {
        // Excel's "Unicode Text" and Windows tools write UTF-16 with this mark: every other
        // byte would be a NUL and no column would be found.
        return Err(LogError::Malformed {
            file: file.into(),
            line: 1,
            message: "the file is UTF-16 text (a byte-order mark FF FE or FE FF, as Excel's \
                      \"Unicode Text\" writes); biasctl reads UTF-8: save it as \"CSV UTF-8\" \
                      or convert it (`iconv -f UTF-16 -t UTF-8`)"
                .into(),
        });
    }
    Ok(())
}

/// An error of the source while reading the head.
pub(super) fn io_error(file: &str, source: io::Error) -> LogError {
    LogError::Io {
        file: file.to_string(),
        source,
    }
}

/// A line read whole as text, ended by `\n`, `\r\n` or a lone `\r` (an old Mac file's lines:
/// [`lines::read_line`]). A line that is not UTF-8 (a Windows code page's `µ` or `°` in a
/// header name) is refused naming its line (`line_no`) and where in it.
pub(super) fn read_text_line(
    buf: &mut impl BufRead,
    file: &str,
    line_no: u64,
) -> Result<String, LogError> {
    let mut line = Vec::new();
    lines::read_line(buf, &mut line).map_err(|source| io_error(file, source))?;
    String::from_utf8(line).map_err(|e| not_utf8(file, line_no, e.as_bytes(), e.utf8_error()))
}

/// The metadata: lines starting with '#' (blank lines are allowed) before the header, without
/// the `#` and surrounding space, and the number of lines read. A source that ends before a
/// header is [`LogError::Empty`].
pub(super) fn read_metadata(
    buf: &mut impl BufRead,
    file: &str,
) -> Result<(Vec<String>, u64), LogError> {
    let mut metadata = Vec::new();
    let mut line_no = 0u64;
    let mut after_cr = false;
    loop {
        let bytes = buf.fill_buf().map_err(|source| io_error(file, source))?;
        if bytes.is_empty() {
            return Err(LogError::Empty { file: file.into() });
        }
        if after_cr && bytes[0] == b'\n' {
            // The `\n` of a CRLF line end: that line is counted.
            buf.consume(1);
            after_cr = false;
            continue;
        }
        if bytes[0] == b'#' || bytes[0] == b'\n' || bytes[0] == b'\r' {
            let line = read_text_line(buf, file, line_no + 1)?;
            after_cr = line.ends_with('\r');
            line_no += 1;
            let text = line.trim_end_matches(['\n', '\r']);
            if let Some(rest) = text.strip_prefix('#') {
                metadata.push(rest.trim().to_string());
            }
        } else {
            break;
        }
    }
    Ok((metadata, line_no))
}

/// Refuses a model file or a TOML given as a log (a header line starting with `{` or `[`):
/// says what it is rather than list its `{` as the columns found.
pub(super) fn refuse_json_or_toml(header: &str, file: &str, line: u64) -> Result<(), LogError> {
    if let Some(c) = header
        .trim_start()
        .chars()
        .next()
        .filter(|c| ['{', '['].contains(c))
    {
        return Err(LogError::Malformed {
            file: file.into(),
            line,
            message: format!(
                "this is not a CSV log: its first line starts with `{c}`, as a JSON file (a \
                 biasctl model file) or a TOML file (a drive or plant) does; a log starts \
                 with a header row such as `time_s,track,bias`"
            ),
        });
    }
    Ok(())
}

/// The header's column names, checked: not empty, at most [`MAX_COLUMNS`](super::limits::MAX_COLUMNS),
/// no name twice (an empty name may repeat).
pub(super) fn header_columns(
    headers: &csv::StringRecord,
    file: &str,
    header_line: u64,
) -> Result<Vec<String>, LogError> {
    use super::limits::MAX_COLUMNS;
    if headers.is_empty() || headers.iter().all(str::is_empty) {
        return Err(LogError::Empty { file: file.into() });
    }
    if headers.len() > MAX_COLUMNS {
        return Err(io_error(
            file,
            io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "line {header_line}: the header has {} columns; biasctl reads at most {MAX_COLUMNS}",
                    headers.len()
                ),
            ),
        ));
    }
    let columns: Vec<String> = headers.iter().map(str::to_string).collect();
    for (i, c) in columns.iter().enumerate() {
        if !c.is_empty() && columns[..i].contains(c) {
            return Err(LogError::DuplicateColumn {
                file: file.into(),
                line: header_line,
                column: c.clone(),
            });
        }
    }
    Ok(columns)
}

/// Reads up to `rows` records ahead from `source`; a parse error stops the reading and is
/// returned beside the records before it, to be reported after them.
pub(super) fn read_ahead<R: Read>(
    source: &mut Source<R>,
    file: &str,
    rows: usize,
) -> (
    std::collections::VecDeque<csv::ByteRecord>,
    Option<LogError>,
) {
    let mut lookahead = std::collections::VecDeque::with_capacity(rows);
    let mut pending = None;
    while lookahead.len() < rows {
        let mut rec = csv::ByteRecord::new();
        match source.read_record(&mut rec, file) {
            Ok(true) => lookahead.push_back(rec),
            Ok(false) => break,
            Err(e) => {
                pending = Some(e);
                break;
            }
        }
    }
    (lookahead, pending)
}

/// The indices of the covariate columns: every column without a role (`roles`: the time,
/// track and bias columns) that is numeric in the rows read ahead. A column is skipped, with a
/// note in `notes`, when it has no name and values, is not numeric in these rows, or is
/// empty in all of them.
pub(super) fn covariate_columns(
    file: &str,
    columns: &[String],
    roles: [Option<usize>; 3],
    lookahead: &std::collections::VecDeque<csv::ByteRecord>,
    decimal_comma: bool,
    notes: &mut Vec<String>,
) -> Vec<usize> {
    let mut covariate_idx = Vec::new();
    for (i, name) in columns.iter().enumerate() {
        if roles.contains(&Some(i)) {
            continue;
        }
        let cells = || lookahead.iter().filter_map(|r| field(r, i));
        let text = lookahead.iter().find_map(|r| {
            let v = field(r, i)?;
            parse_field(v.as_bytes(), decimal_comma).is_err().then(|| {
                let line = r.position().map_or(0, |p| p.line());
                (line, v)
            })
        });
        let has_values = cells().any(|v| !v.is_empty());
        let why = if name.is_empty() {
            has_values.then(|| format!("column {} has no name", i + 1))
        } else if let Some((line, v)) = text {
            Some(format!(
                "column {} (`{name}`) is not numeric (line {line}: `{v}`)",
                i + 1
            ))
        } else if !has_values && !lookahead.is_empty() {
            Some(format!(
                "column {} (`{name}`) is empty in the first {} rows",
                i + 1,
                lookahead.len()
            ))
        } else {
            covariate_idx.push(i);
            continue;
        };
        if let Some(why) = why {
            notes.push(format!("{file}: {why}; skipped"));
        }
    }
    covariate_idx
}
