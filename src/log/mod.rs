//! The measurement log: the one data format biasctl reads and writes.
//!
//! A log is a CSV file with a header row and one row per seek, in the order the seeks were made:
//!
//! | column   | unit   | meaning |
//! |----------|--------|---------|
//! | `time_s` | s      | time of the seek, non-decreasing |
//! | `track`  | tracks | target of the seek (0 = outer diameter; a positive seek moves inbound) |
//! | `bias`   | counts | measured bias at the target; an empty cell means "moved, not measured" |
//! | any other| any    | a named numeric covariate (for example `temp_c`) |
//!
//! The source of each seek is the previous row's track. Lines starting with `#` before the
//! header are metadata (generator, seed, drive parameters) and are kept in [`LogSchema::metadata`].
//! The three required columns can be renamed with a [`ColumnMap`] (the CLI's `--time-col`,
//! `--track-col` and `--bias-col`), so a rig that logs position in metres and force in newtons is
//! read as it is.
//!
//! The units of bias and position travel with the log as [`LogSchema::units`] ([`Units`]): the
//! metadata lines `# bias_unit = N` and `# position_unit = m` name them; without them a log
//! with the default columns `bias` and `track` is in counts and tracks, and a renamed column's
//! own name is its label (`force_N`). [`Units::resolve`] puts explicit labels (the CLI's
//! `--bias-unit` and `--track-unit`) first.
//!
//! Reading is streaming ([`LogReader`]) and strict about the data: every bad value in a column
//! with a role is an error that names the file, line and column. It is tolerant about the dialect:
//! the delimiter (`,` `;` or tab) is sniffed from the header unless [`ColumnMap::delimiter`]
//! names it; a `;`- or tab-separated file may use a decimal comma (`0,25`); header names match
//! ignoring case and surrounding spaces (an unknown name gets a "did you mean"); a column with no
//! name and no values (a spreadsheet's trailing comma) is ignored; a covariate column that is
//! not numeric in the first rows (notes, labels) is skipped. Every skip is told in
//! [`LogSchema::notes`]; nothing is skipped silently.
//!
//! ```
//! use biasctl::{ColumnMap, LogReader};
//! let text = "# seed 1\ntime_s,track,bias,temp_c\n0.0,100,12.5,40\n0.5,120,,40\n1.0,90,-3.25,41\n";
//! let mut reader = LogReader::from_reader("example.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
//! assert_eq!(reader.schema().covariates, vec!["temp_c".to_string()]);
//! let rows: Vec<_> = reader.by_ref().collect::<Result<_, _>>().unwrap();
//! assert_eq!(rows.len(), 3);
//! assert_eq!(rows[1].bias, None);
//! assert_eq!(reader.schema().units.bias, "counts");
//! ```

mod columns;
pub(crate) mod limits;
pub(crate) mod lines;
mod plain;

pub use columns::{Covariates, Log, RowRef, Rows};

use crate::log::limits::{LineLimit, MAX_COLUMNS};
use std::fs::File;
use std::io::{self, BufRead, BufReader, Read, Write};
use std::path::Path;

use serde::{Deserialize, Serialize};

/// Names of the three required columns (defaults `time_s`, `track`, `bias`) and the field
/// delimiter (default: sniffed).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ColumnMap {
    /// Column holding the time of each seek in seconds.
    pub time: String,
    /// Column holding the seek target (tracks, or any position unit).
    pub track: String,
    /// Column holding the measured bias (counts, or any force/current unit).
    pub bias: String,
    /// Field delimiter (the CLI's `--delimiter`); `None` sniffs it from the header line: the most
    /// frequent of `,` `;` and tab outside quotes (a comma on a tie or when none occurs).
    pub delimiter: Option<u8>,
}

/// Default name of the time column (s).
pub const DEFAULT_TIME_COL: &str = "time_s";
/// Default name of the position column (tracks).
pub const DEFAULT_TRACK_COL: &str = "track";
/// Default name of the measured-bias column (counts).
pub const DEFAULT_BIAS_COL: &str = "bias";

impl Default for ColumnMap {
    fn default() -> Self {
        Self {
            time: DEFAULT_TIME_COL.into(),
            track: DEFAULT_TRACK_COL.into(),
            bias: DEFAULT_BIAS_COL.into(),
            delimiter: None,
        }
    }
}

/// The delimiters the reader sniffs and `--delimiter` accepts, with their names.
pub(crate) const DELIMITERS: [(u8, &str); 3] =
    [(b',', "comma"), (b';', "semicolon"), (b'\t', "tab")];

/// Rows the reader looks at, after the header, to find covariate columns that are not numeric.
pub(crate) const LOOKAHEAD_ROWS: usize = 64;

/// The delimiter of a header line: the most frequent of `,` `;` and tab outside double quotes;
/// a comma when none occurs or on a tie.
pub(crate) fn sniff_delimiter(header: &str) -> u8 {
    let mut counts = [0usize; DELIMITERS.len()];
    let mut quoted = false;
    for b in header.bytes() {
        if b == b'"' {
            quoted = !quoted;
        } else if !quoted && let Some(i) = DELIMITERS.iter().position(|d| d.0 == b) {
            counts[i] += 1;
        }
    }
    let mut best = 0;
    for i in 1..counts.len() {
        if counts[i] > counts[best] {
            best = i;
        }
    }
    DELIMITERS[best].0
}

/// Parses a cell as a number; with `decimal_comma` a cell holding a comma and no point is read
/// with the comma as the decimal separator (`0,25` = 0.25).
pub(crate) fn parse_cell(text: &str, decimal_comma: bool) -> Option<f64> {
    if decimal_comma && text.contains(',') && !text.contains('.') {
        text.replacen(',', ".", 1).parse().ok()
    } else {
        text.parse().ok()
    }
}

/// The number in a raw cell (the bytes between delimiters): `Ok(None)` for an empty cell
/// (nothing but whitespace), `Err(())` for text that is not a number. The fast path trims ASCII
/// whitespace and parses the bytes with `fast-float2` (correctly rounded, as `str::parse`);
/// anything it does not take — a decimal comma, Unicode whitespace, text, an error — goes the
/// reference way ([`parse_cell`] on the `str::trim`med text), so both paths accept the same
/// cells with the same values (tested).
fn parse_field(raw: &[u8], decimal_comma: bool) -> Result<Option<f64>, ()> {
    let t = raw.trim_ascii();
    if t.is_empty() {
        return Ok(None);
    }
    if !(decimal_comma && t.contains(&b','))
        && let Ok(v) = fast_float2::parse::<f64, _>(t)
    {
        return Ok(Some(v));
    }
    let text = std::str::from_utf8(raw).map_err(|_| ())?.trim();
    if text.is_empty() {
        return Ok(None);
    }
    parse_cell(text, decimal_comma).map(Some).ok_or(())
}

/// Case-insensitive edit distance between two column names (for "did you mean").
fn name_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.to_lowercase().chars().collect();
    let b: Vec<char> = b.to_lowercase().chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.iter().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            cur[j + 1] = (prev[j] + usize::from(ca != cb))
                .min(prev[j + 1] + 1)
                .min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

/// The column most like `name` (edit distance at most a third of its length, at least 2, or one
/// name containing the other), for a "did you mean".
fn closest_column<'a>(name: &str, columns: &'a [String]) -> Option<&'a str> {
    let lower = name.to_lowercase();
    columns
        .iter()
        .filter(|c| !c.is_empty())
        .map(|c| (name_distance(name, c), c))
        .filter(|(d, c)| {
            *d <= (name.chars().count() / 3).max(2) || {
                // One name inside the other, neither of them a mere letter or two (`a` is in
                // `track`).
                let cl = c.to_lowercase();
                cl.chars().count().min(lower.chars().count()) >= 3
                    && (cl.contains(&lower) || lower.contains(&cl))
            }
        })
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c.as_str())
}

/// Words that make a column name a likely holder of a role, for a "did you mean" when no name is
/// close to the one looked for: a rig's `position_m` for the track, `force_N` for the bias.
fn role_words(field: crate::field::Field) -> &'static [&'static str] {
    use crate::field::Field;
    match field {
        Field::TimeColumn => &["time", "zeit", "temps"],
        Field::TrackColumn => &[
            "track", "pos", "angle", "theta", "enc", "displ", "stroke", "target",
        ],
        Field::BiasColumn => &[
            "bias", "force", "current", "torque", "effort", "dac", "control",
        ],
        _ => &[],
    }
}

/// The first column whose name holds one of `words` (ignoring case), not one of `taken` (the
/// other roles' columns).
fn column_by_role<'a>(words: &[&str], columns: &'a [String], taken: &[usize]) -> Option<&'a str> {
    columns
        .iter()
        .enumerate()
        .filter(|(i, c)| !c.is_empty() && !taken.contains(i))
        .find(|(_, c)| {
            let lower = c.to_lowercase();
            words.iter().any(|w| lower.contains(w))
        })
        .map(|(_, c)| c.as_str())
}

/// The unit a column name states: the text in brackets or parentheses at its end (`position
/// [um]`, `Force (N)`), if it is a usable label ([`check_unit_label`]).
pub(crate) fn unit_in_name(name: &str) -> Option<&str> {
    let name = name.trim();
    let (open, close) = if name.ends_with(']') {
        ('[', ']')
    } else if name.ends_with(')') {
        ('(', ')')
    } else {
        return None;
    };
    let inner = &name[name.rfind(open)? + 1..name.len() - close.len_utf8()];
    check_unit_label(inner).ok()
}

/// The time unit a column name states other than seconds (`time_ms`, `t [ms]`, `Time (min)`),
/// for a note: biasctl reads every time in seconds.
fn time_unit_not_seconds(name: &str) -> Option<&'static str> {
    let unit = unit_in_name(name)
        .or_else(|| {
            name.trim()
                .rsplit_once(['_', ' ', '-', '.'])
                .map(|(_, u)| u)
        })?
        .to_lowercase();
    match unit.as_str() {
        "ms" | "msec" | "millisecond" | "milliseconds" => Some("milliseconds"),
        "us" | "µs" | "μs" | "usec" | "microsecond" | "microseconds" => Some("microseconds"),
        "ns" => Some("nanoseconds"),
        "min" | "mins" | "minute" | "minutes" => Some("minutes"),
        "h" | "hr" | "hour" | "hours" => Some("hours"),
        _ => None,
    }
}

/// `; did you mean `x`?` or nothing (for [`LogError::MissingColumn`]).
fn did_you_mean(suggestion: &Option<String>) -> String {
    suggestion
        .as_ref()
        .map(|s| format!("; did you mean `{s}`?"))
        .unwrap_or_default()
}

/// Bias unit of a log whose bias column is the default `bias` and whose metadata names none.
pub const DEFAULT_BIAS_UNIT: &str = "counts";
/// Position unit of a log whose track column is the default `track` and whose metadata names
/// none.
pub(crate) const DEFAULT_POSITION_UNIT: &str = "tracks";
/// Metadata key naming the bias unit (`# bias_unit = N`).
pub(crate) const BIAS_UNIT_KEY: &str = "bias_unit";
/// Metadata key naming the position unit (`# position_unit = m`).
pub(crate) const POSITION_UNIT_KEY: &str = "position_unit";

/// The unit labels of a log's bias and position, for every text, table and axis that shows
/// log data. JSON: `{"bias": "N", "position": "m"}`.
///
/// ```
/// use biasctl::{ColumnMap, Log, Units};
/// let map = ColumnMap { track: "position_m".into(), bias: "force_N".into(), ..ColumnMap::default() };
/// let log = Log::from_reader("r.csv", "time_s,position_m,force_N\n0,0.1,2\n".as_bytes(), &map).unwrap();
/// assert_eq!(log.schema.units, Units { bias: "force_N".into(), position: "position_m".into() });
/// let flags = Units::resolve(Some("N"), Some("m"), &log.schema).unwrap();
/// assert_eq!((flags.bias.as_str(), flags.per_position().as_str()), ("N", "N/m"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Units {
    /// Unit of the measured bias, e.g. `counts`, `N`, `mA`.
    pub bias: String,
    /// Unit of the position (seek target), e.g. `tracks`, `m`.
    pub position: String,
}

impl Default for Units {
    /// Counts and tracks: the simulator's units.
    fn default() -> Self {
        Self {
            bias: DEFAULT_BIAS_UNIT.into(),
            position: DEFAULT_POSITION_UNIT.into(),
        }
    }
}

/// A unit label that cannot be used (given explicitly or from a log's metadata).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{origin} `{label}`: {problem}; give a plain label such as `N`, `mA` or `counts`")]
pub struct UnitError {
    /// Where the label came from: the setting (`Units::bias`, a [`crate::field::Field`]) or the
    /// log's metadata line.
    pub origin: String,
    /// The label as given.
    pub label: String,
    /// What is wrong with it.
    pub problem: &'static str,
}

/// Checks a unit label: non-empty (after trimming), no control character (newline, tab, …) and
/// no comma, so it fits an axis label, a text line and a CSV metadata line. Returns the trimmed
/// label, or what is wrong with it.
pub fn check_unit_label(label: &str) -> Result<&str, &'static str> {
    let trimmed = label.trim();
    if trimmed.is_empty() {
        Err("a unit label must not be empty")
    } else if trimmed.chars().any(char::is_control) {
        Err("a unit label must not hold a control character (newline, tab, …)")
    } else if trimmed.contains(',') {
        Err("a unit label must not hold a comma")
    } else {
        Ok(trimmed)
    }
}

impl Units {
    /// Resolves the units of a log: an explicit label (`bias`, `position`: the CLI's
    /// `--bias-unit` and `--track-unit`) first, then the log's metadata (`bias_unit`,
    /// `position_unit`), then a default from the column: `counts` for the default bias column
    /// `bias`, else the bias column's name (`force_N`); `tracks` for the default track column
    /// `track`, else its name (`position_m`). A bad label (empty, a control character or a
    /// comma) is an error naming its setting ([`Field::BiasUnit`](crate::field::Field::BiasUnit),
    /// [`Field::PositionUnit`](crate::field::Field::PositionUnit)) or the log file and metadata
    /// key.
    pub fn resolve(
        bias: Option<&str>,
        position: Option<&str>,
        schema: &LogSchema,
    ) -> Result<Units, UnitError> {
        let one = |flag_value: Option<&str>,
                   field: crate::field::Field,
                   key: &str,
                   column: &str,
                   default_column: &str,
                   default_unit: &str|
         -> Result<String, UnitError> {
            let (label, origin) = match (flag_value, schema.metadata_value(key)) {
                (Some(l), _) => (l, field.to_string()),
                (None, Some(m)) => (m, format!("{}: metadata `{key}`", schema.file)),
                (None, None) if column == default_column => return Ok(default_unit.into()),
                // `position [um]` is in `um`; a name without a unit in brackets is its label.
                (None, None) => return Ok(unit_in_name(column).unwrap_or(column).into()),
            };
            check_unit_label(label)
                .map(str::to_string)
                .map_err(|problem| UnitError {
                    origin,
                    label: label.to_string(),
                    problem,
                })
        };
        Ok(Units {
            bias: one(
                bias,
                crate::field::Field::BiasUnit,
                BIAS_UNIT_KEY,
                &schema.map.bias,
                DEFAULT_BIAS_COL,
                DEFAULT_BIAS_UNIT,
            )?,
            position: one(
                position,
                crate::field::Field::PositionUnit,
                POSITION_UNIT_KEY,
                &schema.map.track,
                DEFAULT_TRACK_COL,
                DEFAULT_POSITION_UNIT,
            )?,
        })
    }

    /// The unit of a slope of bias against position, `<bias>/<position>` (`N/m`); a plural
    /// count noun below the slash is made singular (`counts/track`, not `counts/tracks`).
    pub fn per_position(&self) -> String {
        let per = match self.position.as_str() {
            "tracks" => "track",
            "steps" => "step",
            "counts" => "count",
            p => p,
        };
        format!("{}/{per}", self.bias)
    }
}

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
        "{file}: line {line}: missing required column `{column}` (columns found: {found}){}; name it with {field}",
        did_you_mean(.suggestion)
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
    #[error("{file}: line {line}, column {column_index} (`{column}`): {problem}: `{value}`")]
    BadValue {
        /// The log file.
        file: String,
        /// 1-based line number.
        line: u64,
        /// 1-based column number.
        column_index: usize,
        /// Column name.
        column: String,
        /// The cell's text.
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

/// What a log's header says: metadata, column names and which column is which.
#[derive(Debug, Clone, PartialEq)]
pub struct LogSchema {
    /// The file name used in error messages.
    pub file: String,
    /// Metadata lines before the header, without the leading `#` and surrounding space.
    pub metadata: Vec<String>,
    /// All column names in file order.
    pub columns: Vec<String>,
    /// The column map the log was read with.
    pub map: ColumnMap,
    /// Names of the covariate columns (the numeric columns other than the three required), in
    /// file order.
    pub covariates: Vec<String>,
    /// The field delimiter read with (sniffed or given).
    pub delimiter: u8,
    /// What the reader did that the user should know: columns skipped (no name with values, not
    /// numeric, empty in the first rows), a delimiter other than a comma, a column matched
    /// ignoring case. The CLI prints them on stderr.
    pub notes: Vec<String>,
    /// The units of bias and position: from the metadata or the columns when read
    /// ([`Units::resolve`] without explicit labels); [`LogSchema::set_units`] applies explicit
    /// ones.
    pub units: Units,
    time_idx: usize,
    track_idx: usize,
    bias_idx: Option<usize>,
    covariate_idx: Vec<usize>,
}

impl LogSchema {
    /// Whether the log has a bias column (a plan read with [`BiasColumn::Optional`] may not).
    pub fn has_bias(&self) -> bool {
        self.bias_idx.is_some()
    }

    /// Index of covariate `name` in [`Row::covariates`], if the log has it.
    pub fn covariate_index(&self, name: &str) -> Option<usize> {
        self.covariates.iter().position(|c| c == name)
    }

    /// Resolves the units again with explicit labels (the CLI's `--bias-unit` and
    /// `--track-unit`; `None` keeps the metadata or column default), see [`Units::resolve`].
    pub fn set_units(
        &mut self,
        bias: Option<&str>,
        position: Option<&str>,
    ) -> Result<(), UnitError> {
        self.units = Units::resolve(bias, position, self)?;
        Ok(())
    }

    /// The value of metadata key `key` from a line `key = value` or `key: value`.
    pub fn metadata_value(&self, key: &str) -> Option<&str> {
        self.metadata.iter().find_map(|line| {
            let (k, v) = line.split_once('=').or_else(|| line.split_once(':'))?;
            (k.trim() == key).then(|| v.trim())
        })
    }
}

/// One seek of the log.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// 1-based line number in the file (for messages).
    pub line: u64,
    /// Time of the seek, s.
    pub time_s: f64,
    /// Target track of the seek.
    pub track: f64,
    /// Measured bias in counts, `None` when the move was made but not measured.
    pub bias: Option<f64>,
    /// Covariate values in the order of [`LogSchema::covariates`].
    pub covariates: Vec<f64>,
}

impl Row {
    /// A row to read into ([`LogReader::read_into`]), with room for `covariates` values.
    pub fn empty(covariates: usize) -> Self {
        Row {
            line: 0,
            time_s: 0.0,
            track: 0.0,
            bias: None,
            covariates: Vec::with_capacity(covariates),
        }
    }
}

/// Whether a log must hold measurements.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum BiasColumn {
    /// The bias column must exist and at least one row must be measured (fitting, scoring,
    /// diagnosing): a missing column or a log without a measured row is an error.
    #[default]
    Required,
    /// A plan (`predict`): the bias column may be missing or empty; every row is then read as
    /// "moved, not measured".
    Optional,
}

/// The path that means standard input (`--data -`).
pub const STDIN_PATH: &str = "-";
/// The name standard input has in messages.
pub(crate) const STDIN_NAME: &str = "<stdin>";

/// What the CSV parser of a [`LogReader`] reads: bytes already read (the header line, or the
/// buffered rest from the first line that is not plain), then the rest of the source, with the
/// physical line of each line's first byte noted ([`lines::LineStarts`]).
type CsvSource<R> = lines::LineStarts<io::Chain<io::Cursor<Vec<u8>>, BufReader<LineLimit<R>>>>;

/// Where a [`LogReader`]'s records come from.
enum Source<R: Read> {
    /// Lines without a quote or a carriage return, split by the delimiter here: the fast path,
    /// from the first row on while every line is plain ([`plain`]).
    Plain {
        lines: plain::PlainLines<BufReader<LineLimit<R>>>,
        delimiter: u8,
        /// Fields of the header (every record must have as many).
        columns: usize,
    },
    /// The csv crate's parser, the reference: from the header on when the header line is not
    /// plain, or from the first line that is not plain to the end.
    Csv {
        csv: csv::Reader<CsvSource<R>>,
        /// Bytes before the parser's first byte, from the header's first byte.
        byte_offset: u64,
        /// Fields a record must have, when the parser started after the header (it does not
        /// know the header then).
        columns: Option<usize>,
    },
    /// Only while the plain source hands over to the csv parser.
    Switching,
}

impl<R: Read> Source<R> {
    /// Reads the next record into `record` (reusing it), its position's line the line in the
    /// file (1-based, counting metadata lines); `Ok(false)` at the end. A record with a field
    /// that is not valid UTF-8 is refused naming its line and field, as reading text records
    /// did; a record with another number of fields than the header is refused naming both.
    fn read_record(&mut self, record: &mut csv::ByteRecord, file: &str) -> Result<bool, LogError> {
        loop {
            match self {
                Source::Plain {
                    lines,
                    delimiter,
                    columns,
                } => {
                    let line = match lines.peek() {
                        Ok(Some(line)) => line,
                        Ok(None) => return Ok(false),
                        Err(e) => return Err(source_failed(file, &e)),
                    };
                    if line.is_empty() || line.iter().any(|&b| b == b'"' || b == b'\r') {
                        self.switch_to_csv();
                        continue;
                    }
                    record.clear();
                    for field in line.split(|&b| b == *delimiter) {
                        record.push_field(field);
                    }
                    let mut pos = csv::Position::new();
                    pos.set_line(lines.line()).set_byte(lines.byte());
                    record.set_position(Some(pos));
                    let line_no = lines.line();
                    lines.advance();
                    if record.len() != *columns {
                        return Err(LogError::Malformed {
                            file: file.into(),
                            line: line_no,
                            message: lines::unequal_lengths(record.len(), *columns),
                        });
                    }
                    check_utf8(record, file)?;
                    return Ok(true);
                }
                Source::Csv {
                    csv,
                    byte_offset,
                    columns,
                } => {
                    let byte_offset = *byte_offset;
                    // The parser's own line numbers count from where it starts reading a
                    // record: before the blank lines it skips, before the `\n` of a CRLF line
                    // end (so one line early). The physical line of the record's first byte
                    // is the one noted at or after that start.
                    let more = match csv.read_byte_record(record) {
                        Ok(more) => more,
                        Err(e) => {
                            let line = e.position().map_or(0, |p| csv.get_mut().line_at(p.byte()));
                            return Err(malformed(file, line, &e));
                        }
                    };
                    if let Some(p) = record.position() {
                        let mut p = p.clone();
                        let byte = p.byte();
                        p.set_line(csv.get_mut().line_at(byte))
                            .set_byte(byte + byte_offset);
                        record.set_position(Some(p));
                    }
                    if more
                        && let Some(columns) = *columns
                        && record.len() != columns
                    {
                        return Err(LogError::Malformed {
                            file: file.into(),
                            line: record.position().map_or(0, |p| p.line()),
                            message: lines::unequal_lengths(record.len(), columns),
                        });
                    }
                    if more {
                        check_utf8(record, file)?;
                    }
                    return Ok(more);
                }
                Source::Switching => unreachable!("the switch to the csv parser completes"),
            }
        }
    }

    /// Hands the rest of the source, from the current line on, to the csv parser: started at
    /// a line's start as the parser that read the lines before would have been.
    fn switch_to_csv(&mut self) {
        if !matches!(self, Source::Plain { .. }) {
            return;
        }
        let Source::Plain {
            lines,
            delimiter,
            columns,
        } = std::mem::replace(self, Source::Switching)
        else {
            return;
        };
        let (rest, mut src, eof, line, byte) = lines.into_parts();
        if eof {
            // The source said it has ended: not asked again (a terminal would wait).
            src.get_mut().finish();
        }
        let csv = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .delimiter(delimiter)
            .buffer_capacity(1 << 16)
            .from_reader(lines::LineStarts::new(
                io::Cursor::new(rest).chain(src),
                line,
            ));
        *self = Source::Csv {
            csv,
            byte_offset: byte,
            columns: Some(columns),
        };
    }
}

/// A streaming reader of a measurement log: constant memory in the number of rows.
///
/// It yields `Result<Row, LogError>`; after the last row it yields one
/// [`LogError::NoMeasuredRows`] if no row held a bias (unless read with
/// [`BiasColumn::Optional`]), then ends.
pub struct LogReader<R: Read> {
    schema: LogSchema,
    source: Source<R>,
    /// The current record, reused row after row (no allocation per row); every field is valid
    /// UTF-8 ([`Source::read_record`]).
    record: csv::ByteRecord,
    /// Records read ahead to classify the columns, yielded before the rest of the file.
    lookahead: std::collections::VecDeque<csv::ByteRecord>,
    /// A parse error met while reading ahead, returned after the records before it.
    pending: Option<LogError>,
    prev_time: Option<f64>,
    measured: u64,
    bias_column: BiasColumn,
    done: bool,
}

impl LogReader<Box<dyn Read>> {
    /// Opens `path` (or standard input when `path` is `-`, named `<stdin>` in messages) and
    /// reads its metadata and header.
    pub fn open(path: &Path, map: &ColumnMap) -> Result<Self, LogError> {
        Self::open_with(path, map, BiasColumn::Required)
    }

    /// As [`LogReader::open`], with the bias column required or optional.
    pub fn open_with(path: &Path, map: &ColumnMap, bias: BiasColumn) -> Result<Self, LogError> {
        if path.as_os_str() == STDIN_PATH {
            // A stream is answered row by row: no look-ahead, the header alone classifies the
            // columns (a text column without a role then fails at its first row).
            return Self::from_reader_lookahead(
                STDIN_NAME,
                Box::new(io::stdin().lock()),
                map,
                bias,
                0,
            );
        }
        let file_name = path.display().to_string();
        let file = File::open(path).map_err(|source| LogError::Io {
            file: file_name.clone(),
            source,
        })?;
        Self::from_reader_with(&file_name, Box::new(file), map, bias)
    }
}

/// What `biasctl check` reports about a log ([`LogReader::summarise`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogSummary {
    /// Data rows.
    pub rows: u64,
    /// Rows with a measured bias.
    pub measured: u64,
    /// Smallest and largest target position, in the log's position unit.
    pub positions: [f64; 2],
    /// First and last time, s.
    pub times_s: [f64; 2],
}

impl<R: Read> LogReader<R> {
    /// Reads metadata and header from any reader; `file` names the source in messages.
    pub fn from_reader(file: &str, reader: R, map: &ColumnMap) -> Result<Self, LogError> {
        Self::from_reader_with(file, reader, map, BiasColumn::Required)
    }

    /// As [`LogReader::from_reader`], with the bias column required or optional.
    pub fn from_reader_with(
        file: &str,
        reader: R,
        map: &ColumnMap,
        bias_column: BiasColumn,
    ) -> Result<Self, LogError> {
        Self::from_reader_lookahead(file, reader, map, bias_column, LOOKAHEAD_ROWS)
    }

    /// As [`LogReader::from_reader_with`], reading `lookahead_rows` rows ahead to find the
    /// covariate columns that are not numeric.
    fn from_reader_lookahead(
        file: &str,
        reader: R,
        map: &ColumnMap,
        bias_column: BiasColumn,
        lookahead_rows: usize,
    ) -> Result<Self, LogError> {
        Self::from_reader_source(file, reader, map, bias_column, lookahead_rows, true)
    }

    /// As [`LogReader::from_reader_lookahead`]; without `plain_lines` every line goes through
    /// the csv parser (the reference the plain lines are tested against).
    fn from_reader_source(
        file: &str,
        reader: R,
        map: &ColumnMap,
        bias_column: BiasColumn,
        lookahead_rows: usize,
        plain_lines: bool,
    ) -> Result<Self, LogError> {
        let mut buf = BufReader::new(LineLimit::new(reader));
        let io_err = |source| LogError::Io {
            file: file.to_string(),
            source,
        };
        // A UTF-8 byte-order mark (as spreadsheet exports write) is not part of the first line.
        let start = buf.fill_buf().map_err(io_err)?;
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
        let mut metadata = Vec::new();
        let mut line_no = 0u64;
        // A line read whole as text, ended by `\n`, `\r\n` or a lone `\r` (an old Mac file's
        // lines: [`lines::read_line`]).
        // A line that is not UTF-8 (a Windows code page's `µ` or `°` in a header name) is
        // refused naming its line and where in it.
        let read_line = |buf: &mut BufReader<LineLimit<R>>, line_no: u64| {
            let mut line = Vec::new();
            lines::read_line(buf, &mut line).map_err(io_err)?;
            String::from_utf8(line)
                .map_err(|e| not_utf8(file, line_no, e.as_bytes(), e.utf8_error()))
        };
        // Metadata: lines starting with '#' (blank lines are allowed) before the header.
        let mut after_cr = false;
        loop {
            let bytes = buf.fill_buf().map_err(io_err)?;
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
                let line = read_line(&mut buf, line_no + 1)?;
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
        let header = read_line(&mut buf, line_no + 1)?;
        // A model file or a TOML given as a log: say what it is rather than list its `{` as
        // the columns found.
        if let Some(c) = header
            .trim_start()
            .chars()
            .next()
            .filter(|c| ['{', '['].contains(c))
        {
            return Err(LogError::Malformed {
                file: file.into(),
                line: line_no + 1,
                message: format!(
                    "this is not a CSV log: its first line starts with `{c}`, as a JSON file (a \
                     biasctl model file) or a TOML file (a drive or plant) does; a log starts \
                     with a header row such as `time_s,track,bias`"
                ),
            });
        }
        let delimiter = map.delimiter.unwrap_or_else(|| sniff_delimiter(&header));
        let decimal_comma = delimiter != b',';
        let mut notes = Vec::new();
        if delimiter != b',' {
            let name = DELIMITERS
                .iter()
                .find(|d| d.0 == delimiter)
                .map_or("other", |d| d.1);
            notes.push(format!(
                "{file}: fields separated by {name} (`{}`){}",
                (delimiter as char).escape_default(),
                if map.delimiter.is_some() {
                    ""
                } else {
                    ", sniffed from the header; a comma in a number is its decimal separator"
                }
            ));
        }
        let header_line = line_no + 1;
        // A plain header line (no quote, no carriage return: what the fast path splits) is
        // parsed alone and the rows after it split line by line, while they are plain; any
        // other header is read with the rows by the csv parser, as it always was.
        let plain = plain_lines
            && !header.bytes().any(|b| b == b'"' || b == b'\r')
            && ![b'"', b'\r', b'\n'].contains(&delimiter);
        let builder = || {
            let mut b = csv::ReaderBuilder::new();
            b.has_headers(true)
                .delimiter(delimiter)
                // Headers are trimmed here; cells as they are read ([`field`]): the parser's
                // own trimming of records rebuilds each record (an allocation per row).
                .trim(csv::Trim::Headers)
                .buffer_capacity(1 << 16);
            b
        };
        let header_bytes = header.len() as u64;
        let (headers, mut source) = if plain {
            let mut csv = builder().from_reader(header.as_bytes());
            let headers = csv
                .headers()
                .map_err(|e| malformed(file, header_line, &e))?
                .clone();
            let source = Source::Plain {
                lines: plain::PlainLines::new(buf, header_line + 1, header_bytes),
                delimiter,
                columns: headers.len(),
            };
            (headers, source)
        } else {
            let mut csv = builder().from_reader(lines::LineStarts::new(
                io::Cursor::new(header.into_bytes()).chain(buf),
                header_line,
            ));
            let headers = csv
                .headers()
                .map_err(|e| malformed(file, header_line, &e))?
                .clone();
            let source = Source::Csv {
                csv,
                byte_offset: 0,
                columns: None,
            };
            (headers, source)
        };
        if headers.is_empty() || headers.iter().all(str::is_empty) {
            return Err(LogError::Empty { file: file.into() });
        }
        if headers.len() > MAX_COLUMNS {
            return Err(io_err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "line {header_line}: the header has {} columns; biasctl reads at most {MAX_COLUMNS}",
                    headers.len()
                ),
            )));
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
        // A required column: its exact name, else the one name equal to it ignoring case and
        // surrounding spaces.
        let mut case_notes: Vec<String> = Vec::new();
        let mut find = |name: &str, field: crate::field::Field| {
            let wanted = name.trim();
            if let Some(i) = columns.iter().position(|c| c == wanted) {
                return Ok(i);
            }
            let same: Vec<usize> = (0..columns.len())
                .filter(|&i| columns[i].to_lowercase() == wanted.to_lowercase())
                .collect();
            if let [i] = same[..] {
                case_notes.push(format!(
                    "{file}: column `{}` used as `{wanted}` (matched ignoring case)",
                    columns[i]
                ));
                return Ok(i);
            }
            // A header read as one column that holds a delimiter: the file is separated by
            // another one than the reader used (a `--delimiter` that does not fit, or `|`).
            if let [only] = &columns[..]
                && let Some(d) = only.chars().find(|c| [',', ';', '\t', '|'].contains(c))
            {
                return Err(LogError::Malformed {
                    file: file.into(),
                    line: header_line,
                    message: format!(
                        "missing required column `{wanted}`: the header is one column, `{}`, \
                         that holds `{}`, so the fields are not separated by `{}`{}",
                        crate::render::quote(only),
                        d.escape_default(),
                        (delimiter as char).escape_default(),
                        if map.delimiter.is_some() {
                            " (--delimiter): leave the flag out to sniff the delimiter"
                        } else {
                            "; biasctl reads `,`, `;` or tab"
                        }
                    ),
                });
            }
            // No name close to it: a column whose name says it holds the role (`position_m`
            // for the track), not one of the other required columns.
            let others: Vec<String> = [&map.time, &map.track, &map.bias]
                .iter()
                .map(|n| n.trim().to_lowercase())
                .collect();
            let taken: Vec<usize> = (0..columns.len())
                .filter(|&i| others.contains(&columns[i].to_lowercase()))
                .collect();
            Err(LogError::MissingColumn {
                file: file.into(),
                line: header_line,
                column: wanted.into(),
                found: columns.join(", "),
                field,
                suggestion: closest_column(wanted, &columns)
                    .or_else(|| column_by_role(role_words(field), &columns, &taken))
                    .map(str::to_string),
            })
        };
        use crate::field::Field;
        let roles = [
            (&map.time, Field::TimeColumn),
            (&map.track, Field::TrackColumn),
            (&map.bias, Field::BiasColumn),
        ];
        let need = if bias_column == BiasColumn::Optional {
            2
        } else {
            3
        };
        let missing: Vec<(String, Field, Option<String>)> = roles[..need]
            .iter()
            .filter_map(|&(name, field)| match find(name, field) {
                Err(LogError::MissingColumn {
                    column, suggestion, ..
                }) => Some((column, field, suggestion)),
                _ => None,
            })
            .collect();
        if missing.len() > 1 {
            let shell = |s: &str| {
                if !s.is_empty()
                    && s.chars()
                        .all(|c| c.is_alphanumeric() || "_.-/+".contains(c))
                {
                    s.to_string()
                } else {
                    format!("'{}'", s.replace('\'', "'\\''"))
                }
            };
            return Err(LogError::MissingColumns {
                file: file.into(),
                line: header_line,
                missing: missing
                    .iter()
                    .map(|(c, _, _)| format!("`{c}`"))
                    .collect::<Vec<_>>()
                    .join(", "),
                found: columns.join(", "),
                hint: missing
                    .iter()
                    .enumerate()
                    .map(|(i, (_, f, s))| {
                        // A column suggested for an earlier role is not suggested again.
                        let s = s
                            .as_deref()
                            .filter(|s| !missing[..i].iter().any(|m| m.2.as_deref() == Some(s)));
                        format!("{f} {}", s.map_or("NAME".into(), shell))
                    })
                    .collect::<Vec<_>>()
                    .join(" "),
            });
        }
        let time_idx = find(&map.time, Field::TimeColumn)?;
        let track_idx = find(&map.track, Field::TrackColumn)?;
        let bias_idx = match bias_column {
            BiasColumn::Optional => find(&map.bias, Field::BiasColumn).ok(),
            _ => Some(find(&map.bias, Field::BiasColumn)?),
        };
        // Once each (the columns were looked for twice when one was missing).
        for n in case_notes {
            if !notes.contains(&n) {
                notes.push(n);
            }
        }
        if let Some(unit) = time_unit_not_seconds(&columns[time_idx]) {
            notes.push(format!(
                "{file}: column `{}` is read in seconds, biasctl's time unit, but its name says \
                 {unit}: convert it to seconds, else every time biasctl prints or fits (dwell_s, \
                 rows/s, a lag's tau, a velocity) is off by that factor",
                columns[time_idx]
            ));
        }
        // Read ahead to classify the other columns: a column is a numeric covariate unless it has
        // no name and no values, or no values, or a value that is not a number in these rows.
        let mut lookahead = std::collections::VecDeque::with_capacity(lookahead_rows);
        let mut pending = None;
        while lookahead.len() < lookahead_rows {
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
        let mut covariate_idx = Vec::new();
        for (i, name) in columns.iter().enumerate() {
            if [time_idx, track_idx].contains(&i) || Some(i) == bias_idx {
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
        let covariates = covariate_idx.iter().map(|&i| columns[i].clone()).collect();
        let mut schema = LogSchema {
            file: file.into(),
            metadata,
            columns,
            map: map.clone(),
            covariates,
            delimiter,
            notes,
            units: Units::default(),
            time_idx,
            track_idx,
            bias_idx,
            covariate_idx,
        };
        schema.set_units(None, None)?;
        Ok(Self {
            schema,
            source,
            record: csv::ByteRecord::new(),
            lookahead,
            pending,
            prev_time: None,
            measured: 0,
            bias_column,
            done: false,
        })
    }

    /// Average bytes per row over the rows read ahead (from their byte offsets); `None` with
    /// fewer than two of them.
    fn bytes_per_row(&self) -> Option<f64> {
        let first = self.lookahead.front()?.position()?.byte();
        let last = self.lookahead.back()?.position()?.byte();
        let n = self.lookahead.len();
        (n >= 2 && last > first).then(|| (last - first) as f64 / (n - 1) as f64)
    }

    /// The log's metadata and columns.
    pub fn schema(&self) -> &LogSchema {
        &self.schema
    }

    /// Streams the rest of the log (constant memory) and summarises it: row counts, position
    /// and time ranges. Every row is validated as [`LogReader::read_into`] does.
    pub fn summarise(&mut self) -> Result<LogSummary, LogError> {
        self.summarise_each(|_| {})
    }

    /// [`LogReader::summarise`], handing every row to `each` as it is read (one pass, so a
    /// log on standard input is read once).
    pub fn summarise_each(&mut self, mut each: impl FnMut(&Row)) -> Result<LogSummary, LogError> {
        let mut row = Row::empty(self.schema.covariates.len());
        let mut s = LogSummary {
            rows: 0,
            measured: 0,
            positions: [f64::INFINITY, f64::NEG_INFINITY],
            times_s: [0.0, 0.0],
        };
        let mut take = |row: &Row| {
            if s.rows == 0 {
                s.times_s[0] = row.time_s;
            }
            s.times_s[1] = row.time_s;
            s.rows += 1;
            s.measured += u64::from(row.bias.is_some());
            s.positions = [s.positions[0].min(row.track), s.positions[1].max(row.track)];
            each(row);
        };
        let roles = self.roles();
        loop {
            self.plain_rows(&roles, &mut row, &mut take)?;
            if !self.read_into(&mut row)? {
                break;
            }
            take(&row);
        }
        Ok(s)
    }

    /// Reads the next row into `row` (reusing its allocation). Returns `Ok(false)` at the end of
    /// the file; errors with [`LogError::NoMeasuredRows`] at the end if no row was measured
    /// (unless the bias column is [`BiasColumn::Optional`]).
    pub fn read_into(&mut self, row: &mut Row) -> Result<bool, LogError> {
        let file = &self.schema.file;
        let more = if let Some(rec) = self.lookahead.pop_front() {
            self.record = rec;
            true
        } else if let Some(e) = self.pending.take() {
            return Err(e);
        } else {
            self.source.read_record(&mut self.record, file)?
        };
        if !more {
            if self.prev_time.is_none() && self.bias_column == BiasColumn::Required {
                // A header alone: "every bias cell is empty" would speak of cells that are not
                // there.
                return Err(LogError::NoRows { file: file.clone() });
            }
            if self.measured == 0 && self.bias_column == BiasColumn::Required {
                return Err(LogError::NoMeasuredRows {
                    file: file.clone(),
                    column: self.schema.map.bias.clone(),
                });
            }
            return Ok(false);
        }
        let line = self.record.position().map(|p| p.line()).unwrap_or(0);
        let s = &self.schema;
        let decimal_comma = s.delimiter != b',';
        let number = |idx: usize| -> Result<Option<f64>, LogError> {
            let raw = self.record.get(idx).unwrap_or(b"");
            let bad = |problem| LogError::BadValue {
                file: file.clone(),
                line,
                column_index: idx + 1,
                column: s.columns[idx].clone(),
                value: field(&self.record, idx).unwrap_or("").to_string(),
                problem,
            };
            let Some(v) = parse_field(raw, decimal_comma).map_err(|()| bad("not a number"))? else {
                return Ok(None);
            };
            if !v.is_finite() {
                Err(bad("not a finite number"))
            } else if v.abs() > MAX_ABS_VALUE {
                Err(bad(
                    "outside ±1e15, the range whose squares and sums stay exact enough",
                ))
            } else {
                Ok(Some(v))
            }
        };
        let required = |idx: usize| -> Result<f64, LogError> {
            number(idx)?.ok_or_else(|| LogError::BadValue {
                file: file.clone(),
                line,
                column_index: idx + 1,
                column: s.columns[idx].clone(),
                value: String::new(),
                problem: "empty cell in a required column",
            })
        };
        let time_s = required(s.time_idx)?;
        if let Some(prev) = self.prev_time
            && time_s < prev
        {
            return Err(LogError::TimeBackwards {
                file: file.clone(),
                line,
                column_index: s.time_idx + 1,
                column: s.columns[s.time_idx].clone(),
                previous: prev,
                value: time_s,
            });
        }
        let track = required(s.track_idx)?;
        let bias = match s.bias_idx {
            Some(idx) => number(idx)?,
            None => None,
        };
        row.covariates.clear();
        for &idx in &s.covariate_idx {
            row.covariates.push(required(idx)?);
        }
        row.line = line;
        row.time_s = time_s;
        row.track = track;
        row.bias = bias;
        self.prev_time = Some(time_s);
        if bias.is_some() {
            self.measured += 1;
        }
        Ok(true)
    }
}

impl<R: Read> LogReader<R> {
    /// Reads the rest of the log into columns, with room for `expected` rows.
    fn read_all(self, expected: usize) -> Result<Log, LogError> {
        self.read_all_with(expected, true)
    }

    /// [`LogReader::read_all`]; with `fast` the plain rows go the fast way
    /// ([`LogReader::plain_rows`]), without it every row goes through
    /// [`LogReader::read_into`] (the reference the fast way is tested against).
    fn read_all_with(mut self, expected: usize, fast: bool) -> Result<Log, LogError> {
        let mut row = Row::empty(self.schema.covariates.len());
        let mut log = Log::with_capacity(self.schema.clone(), expected);
        let roles = fast.then(|| self.roles());
        loop {
            if let Some(roles) = &roles {
                self.plain_rows(roles, &mut row, |row| log.push(row))?;
            }
            // The row the fast way left (not plain, an error to name, or the end).
            if !self.read_into(&mut row)? {
                break;
            }
            log.push(&row);
        }
        log.shrink_to_fit();
        Ok(log)
    }

    /// What each column of the file is, in file order.
    fn roles(&self) -> Vec<Role> {
        let s = &self.schema;
        (0..s.columns.len())
            .map(|i| {
                if i == s.time_idx {
                    Role::Time
                } else if i == s.track_idx {
                    Role::Track
                } else if Some(i) == s.bias_idx {
                    Role::Bias
                } else if let Some(k) = s.covariate_idx.iter().position(|&c| c == i) {
                    Role::Covariate(k)
                } else {
                    Role::Skipped
                }
            })
            .collect()
    }

    /// Hands rows to `take` the fast way while they are plain and valid: the line split and
    /// its numbers converted in one pass ([`plain::parse_plain`]), straight from the read
    /// buffer. Returns at the end, at an error of the source, or at the first line it does not
    /// take — a quote, a carriage return, a byte beyond ASCII, another number of fields, a
    /// cell of another shape, a value out of range, time going backwards — without consuming
    /// it: [`LogReader::read_into`] then reads that line as every line was read before
    /// (the same row, or the same error).
    fn plain_rows(
        &mut self,
        roles: &[Role],
        row: &mut Row,
        mut take: impl FnMut(&Row),
    ) -> Result<(), LogError> {
        if !self.lookahead.is_empty() || self.pending.is_some() {
            return Ok(());
        }
        let Source::Plain {
            lines, delimiter, ..
        } = &mut self.source
        else {
            return Ok(());
        };
        let delimiter = *delimiter;
        row.covariates.resize(self.schema.covariate_idx.len(), 0.0);
        loop {
            // Whole lines, each ending in `\n`: no search for the line's end, the cells' own
            // scan finds it.
            let base_line = lines.line();
            let window = match lines.ready() {
                Ok([]) => return Ok(()),
                Ok(window) => window,
                Err(e) => return Err(source_failed(&self.schema.file, &e)),
            };
            let (mut at, mut rows, mut stop) = (0, 0, false);
            while at < window.len() {
                match plain_row(window, at, roles, delimiter, &mut row.covariates) {
                    Some((time_s, track, bias, next))
                        if self.prev_time.is_none_or(|prev| time_s >= prev) =>
                    {
                        row.line = base_line + rows;
                        row.time_s = time_s;
                        row.track = track;
                        row.bias = bias;
                        take(row);
                        self.prev_time = Some(time_s);
                        self.measured += u64::from(bias.is_some());
                        rows += 1;
                        at = next;
                    }
                    _ => {
                        stop = true;
                        break;
                    }
                }
            }
            lines.consume(at, rows);
            if stop {
                return Ok(());
            }
        }
    }
}

/// The row of the plain line at `window[at..]` (which ends in `\n`): time, position, bias
/// (covariates into `covariates`) and the start of the next line; `None` for a line the fast
/// way does not take (see [`LogReader::plain_rows`]).
#[inline(always)]
fn plain_row(
    window: &[u8],
    at: usize,
    roles: &[Role],
    delimiter: u8,
    covariates: &mut [f64],
) -> Option<(f64, f64, Option<f64>, usize)> {
    let (mut time_s, mut track, mut bias) = (f64::NAN, f64::NAN, None);
    let mut i = at;
    for (c, role) in roles.iter().enumerate() {
        if c > 0 {
            if window.get(i) != Some(&delimiter) {
                return None;
            }
            i += 1;
        }
        let value = match role {
            Role::Skipped => {
                // Any text but what would change the split or needs a UTF-8 check.
                while let Some(&b) = window.get(i)
                    && b != delimiter
                    && b != b'\n'
                {
                    if b == b'"' || b == b'\r' || !b.is_ascii() {
                        return None;
                    }
                    i += 1;
                }
                continue;
            }
            Role::Bias if window.get(i).is_none_or(|&b| b == delimiter || b == b'\n') => continue,
            _ => {
                let (v, next) = plain::parse_plain(window, i)?;
                if v.abs() > MAX_ABS_VALUE {
                    return None;
                }
                i = next;
                v
            }
        };
        match *role {
            Role::Time => time_s = value,
            Role::Track => track = value,
            Role::Bias => bias = Some(value),
            Role::Covariate(k) => covariates[k] = value,
            Role::Skipped => {}
        }
    }
    (window.get(i) == Some(&b'\n')).then_some((time_s, track, bias, i + 1))
}

/// What a column of a log is, for [`LogReader::plain_rows`].
#[derive(Debug, Clone, Copy)]
enum Role {
    Time,
    Track,
    Bias,
    /// Covariate `k` of [`LogSchema::covariates`].
    Covariate(usize),
    /// A column read past (no name, not numeric, empty in the first rows).
    Skipped,
}

impl<R: Read> Iterator for LogReader<R> {
    type Item = Result<Row, LogError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let mut row = Row::empty(self.schema.covariates.len());
        match self.read_into(&mut row) {
            Ok(true) => Some(Ok(row)),
            Ok(false) => {
                self.done = true;
                None
            }
            Err(e) => {
                self.done = true;
                Some(Err(e))
            }
        }
    }
}

/// Field `idx` of a record checked by [`check_utf8`], trimmed of surrounding whitespace (as
/// `str::trim`); `None` past the record's end.
fn field(record: &csv::ByteRecord, idx: usize) -> Option<&str> {
    let bytes = record.get(idx)?;
    // check_utf8 refused any record with a field that is not UTF-8.
    Some(std::str::from_utf8(bytes).unwrap_or("").trim())
}

/// Refuses a record with a field that is not valid UTF-8, naming its line (the record's
/// position) and field.
fn check_utf8(record: &csv::ByteRecord, file: &str) -> Result<(), LogError> {
    if !record.as_slice().is_ascii()
        && let Some(i) = record.iter().position(|f| std::str::from_utf8(f).is_err())
    {
        return Err(LogError::Malformed {
            file: file.into(),
            line: record.position().map_or(0, |p| p.line()),
            message: format!("field {} is not valid UTF-8 text", i + 1),
        });
    }
    Ok(())
}

/// A metadata or header line that is not UTF-8: names the line, the character where the text
/// stops being UTF-8 and the byte there, and how to save the file.
fn not_utf8(file: &str, line: u64, bytes: &[u8], e: std::str::Utf8Error) -> LogError {
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
fn source_failed(file: &str, e: &io::Error) -> LogError {
    LogError::Malformed {
        file: file.into(),
        line: 0,
        message: e.to_string(),
    }
}

fn malformed(file: &str, line: u64, e: &csv::Error) -> LogError {
    LogError::Malformed {
        file: file.into(),
        line,
        message: lines::csv_problem(e),
    }
}

impl Log {
    /// Reads a whole log file (`-`: standard input).
    pub fn read(path: &Path, map: &ColumnMap) -> Result<Self, LogError> {
        Self::read_with(path, map, BiasColumn::Required)
    }

    /// Reads a whole log file (`-`: standard input) with the bias column required or optional.
    pub fn read_with(path: &Path, map: &ColumnMap, bias: BiasColumn) -> Result<Self, LogError> {
        let reader = LogReader::open_with(path, map, bias)?;
        // Room for the rows the file's size suggests (its bytes over the look-ahead rows'
        // bytes per row, plus 1/16): the vector then grows by doubling rarely or never, which
        // would copy every row read so far and hold both copies at once.
        let expected = std::fs::metadata(path)
            .ok()
            .filter(|m| m.is_file())
            .zip(reader.bytes_per_row())
            .map_or(0, |(m, per_row)| {
                let rows = m.len() as f64 / per_row;
                (rows + rows / 16.0).min(1e9) as usize
            });
        reader.read_all(expected)
    }

    /// Reads a whole log from a reader; `file` names it in messages.
    pub fn from_reader<R: Read>(file: &str, reader: R, map: &ColumnMap) -> Result<Self, LogError> {
        Self::from_reader_with(file, reader, map, BiasColumn::Required)
    }

    /// As [`Log::from_reader`], with the bias column required or optional.
    pub fn from_reader_with<R: Read>(
        file: &str,
        reader: R,
        map: &ColumnMap,
        bias: BiasColumn,
    ) -> Result<Self, LogError> {
        LogReader::from_reader_with(file, reader, map, bias)?.read_all(0)
    }
}

/// A CSV writer in the dialect every file biasctl writes uses: comma-separated, a field quoted
/// only when it holds a comma, a quote or a line break (a covariate named `temp,C` is written
/// `"temp,C"`), `\n` line ends. Metadata lines (`# …`) go to the underlying writer before it is
/// wrapped. Call `flush` (or `into_inner`) before the writer is dropped: a drop cannot report an
/// error.
pub(crate) fn csv_writer<W: Write>(out: W) -> csv::Writer<W> {
    csv::WriterBuilder::new()
        .terminator(csv::Terminator::Any(b'\n'))
        .from_writer(out)
}

/// Writes a log: metadata lines, the header, then rows, through `csv_writer`. Numbers are
/// written with fixed decimals (time 6, track as given with up to 6, bias 4, covariates 6) so
/// output is byte-identical for identical values.
pub struct LogWriter<W: Write> {
    out: csv::Writer<W>,
    n_covariates: usize,
}

impl<W: Write> LogWriter<W> {
    /// Writes `metadata` (each line prefixed with `# `) and the header `time_s,track,bias,<covariates>`.
    pub fn new(mut out: W, metadata: &[String], covariates: &[String]) -> io::Result<Self> {
        for m in metadata {
            writeln!(out, "# {m}")?;
        }
        let mut out = csv_writer(out);
        out.write_record(
            [DEFAULT_TIME_COL, DEFAULT_TRACK_COL, DEFAULT_BIAS_COL]
                .into_iter()
                .chain(covariates.iter().map(String::as_str)),
        )?;
        Ok(Self {
            out,
            n_covariates: covariates.len(),
        })
    }

    /// Writes one row. `covariates` must have as many values as the header named.
    pub fn write_row(
        &mut self,
        time_s: f64,
        track: f64,
        bias: Option<f64>,
        covariates: &[f64],
    ) -> io::Result<()> {
        debug_assert_eq!(covariates.len(), self.n_covariates);
        self.out.write_field(fmt_fixed(time_s, 6))?;
        self.out.write_field(fmt_trimmed(track, 6))?;
        self.out
            .write_field(bias.map(|b| fmt_fixed(b, 4)).unwrap_or_default())?;
        for &c in covariates {
            self.out.write_field(fmt_trimmed(c, 6))?;
        }
        self.out.write_record(None::<&[u8]>)?;
        Ok(())
    }

    /// Flushes the rows written so far and returns the underlying writer.
    pub fn into_inner(self) -> io::Result<W> {
        self.out.into_inner().map_err(|e| e.into_error())
    }
}

/// `x` with exactly `decimals` decimals; negative zero is written as zero.
pub(crate) fn fmt_fixed(x: f64, decimals: usize) -> String {
    let s = format!("{:.*}", decimals, x);
    if s.starts_with('-') && s[1..].bytes().all(|b| b == b'0' || b == b'.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// Largest |value| a log cell may hold (every column: time, position, bias, covariates). Models
/// square positions and sum squares over up to millions of rows; below 1e15 those stay finite
/// and keep more than one unit of resolution (f64 carries 15–16 significant digits). No rig
/// logs a larger number; a larger one is a unit mistake or a corrupted cell.
pub(crate) const MAX_ABS_VALUE: f64 = 1e15;

/// `x` with at most `decimals` decimals and trailing zeros removed (`120`, `0.25`).
pub fn fmt_trimmed(x: f64, decimals: usize) -> String {
    let s = fmt_fixed(x, decimals);
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // values parsed from short decimal text compare exactly
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Log, LogError> {
        Log::from_reader("t.csv", text.as_bytes(), &ColumnMap::default())
    }

    #[test]
    fn summary_counts_rows_and_ranges_by_hand() {
        // Reference: 4 rows, 3 measured (the third has an empty bias), tracks 50..400, time 0.5..3.
        let text = "time_s,track,bias\n0.5,100,1\n1,400,2\n2,50,\n3,200,4\n";
        let mut r =
            LogReader::from_reader("t.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
        let s = r.summarise().unwrap();
        assert_eq!((s.rows, s.measured), (4, 3));
        assert_eq!((s.positions, s.times_s), ([50.0, 400.0], [0.5, 3.0]));
        // Bad rows fail the summary just as they fail reading.
        let bad = "time_s,track,bias\n1,100,1\n0,200,2\n";
        let mut r = LogReader::from_reader("t.csv", bad.as_bytes(), &ColumnMap::default()).unwrap();
        assert!(r.summarise().unwrap_err().to_string().contains("line 3"));
    }

    #[test]
    fn reads_metadata_covariates_and_unmeasured_rows() {
        let log =
            read("# generator = biasctl\n# seed: 7\ntime_s,track,bias,temp_c\n0,1,2,3\n1,2,,4\n")
                .unwrap();
        assert_eq!(log.schema.metadata_value("seed"), Some("7"));
        assert_eq!(log.schema.metadata_value("generator"), Some("biasctl"));
        assert_eq!(log.len(), 2);
        assert_eq!(log.row(0).line, 4);
        assert_eq!(log.row(1).line, 5);
        assert_eq!(log.row(1).bias, None);
        assert_eq!(log.row(1).covariates, vec![4.0]);
        assert_eq!(log.measured_count(), 1);
    }

    #[test]
    fn column_map_renames_required_columns() {
        let map = ColumnMap {
            time: "t".into(),
            track: "position_m".into(),
            bias: "force_N".into(),
            delimiter: None,
        };
        let log = Log::from_reader(
            "r.csv",
            "force_N,t,position_m,v\n1.5,0,0.001,2\n".as_bytes(),
            &map,
        )
        .unwrap();
        assert_eq!(log.row(0).track, 0.001);
        assert_eq!(log.row(0).bias, Some(1.5));
        assert_eq!(log.schema.covariates, vec!["v".to_string()]);
    }

    #[test]
    fn every_bad_input_names_line_and_column() {
        let cases: &[(&str, &str)] = &[
            ("", "empty"),
            ("# only metadata\n", "empty"),
            ("time_s,track\n0,1\n", "missing required column `bias`"),
            (
                "time_s,track,bias\n0,1,x\n",
                "line 2, column 3 (`bias`): not a number: `x`",
            ),
            (
                "time_s,track,bias\n0,NaN,1\n",
                "line 2, column 2 (`track`): not a finite number",
            ),
            ("time_s,track,bias\n0,inf,1\n", "not a finite number"),
            (
                "time_s,track,bias\n1,1,1\n0.5,2,1\n",
                "line 3, column 1 (`time_s`): time goes backwards",
            ),
            ("time_s,track,bias\n0,1,\n1,2,\n", "no measured rows"),
            ("time_s,track,bias\n", "no rows under the header"),
            ("time_s,track,bias\n0,1,1,5\n", "line 2: 4 fields"),
            (
                "time_s,track,bias\n0,,1\n",
                "line 2, column 2 (`track`): empty cell",
            ),
            ("time_s,track,bias,track\n0,1,1,1\n", "appears twice"),
        ];
        for (text, want) in cases {
            let err = read(text).expect_err(text).to_string();
            assert!(
                err.contains(want),
                "input {text:?}: got `{err}`, want `{want}`"
            );
            assert!(err.starts_with("t.csv"), "{err}");
        }
    }

    /// The physical line of byte `at` of `text`: 1 + the line ends before it, as an editor
    /// shows them (`\n`, a lone `\r`, and `\r\n` as one, counted at its `\n`). The slow,
    /// obvious reference for line numbers.
    fn physical_line(text: &[u8], at: usize) -> u64 {
        let lone_cr = |i: usize| text[i] == b'\r' && text.get(i + 1) != Some(&b'\n');
        1 + (0..at).filter(|&i| text[i] == b'\n' || lone_cr(i)).count() as u64
    }

    #[test]
    fn errors_name_the_physical_line_after_blank_lines_crlf_and_quoted_newlines() {
        // Reference: each bad cell is marked `x` (or `@` for a row of the wrong length); its
        // line is counted by hand in the raw bytes (`physical_line`), its column is the field.
        // Read every way: all through the csv parser (reference), plain lines row by row, fast
        // rows, the streaming summary (`check`), from sources handing out 1, 3 or all bytes.
        let cases: &[(&str, &str)] = &[
            // Blank lines before the bad row (the csv fallback).
            (
                "time_s,track,bias\n0,1,1\n\n\n1,x,1\n",
                "line 5, column 2 (`track`)",
            ),
            // Blank lines after it.
            (
                "time_s,track,bias\n0,1,1\n1,1,x\n\n\n2,1,1\n",
                "line 3, column 3 (`bias`)",
            ),
            // Blank lines before and after, then a later bad row.
            (
                "time_s,track,bias\n\n0,1,1\n\n1,1,1\n\n\n2,x,1\n\n",
                "line 8, column 2 (`track`)",
            ),
            // Blank lines right after the header.
            (
                "time_s,track,bias\n\n\n0,1,x\n",
                "line 4, column 3 (`bias`)",
            ),
            // CRLF: the bad value on line k = 2, 3, 4.
            (
                "time_s,track,bias\r\n0,x,1\r\n1,1,1\r\n",
                "line 2, column 2 (`track`)",
            ),
            (
                "time_s,track,bias\r\n0,1,1\r\n1,1,x\r\n",
                "line 3, column 3 (`bias`)",
            ),
            (
                "time_s,track,bias\r\n0,1,1\r\n1,1,1\r\n2,x,1\r\n",
                "line 4, column 2 (`track`)",
            ),
            // A plain header and plain rows, then CRLF (the switch to the csv parser).
            (
                "time_s,track,bias\n0,1,1\n1,1,1\r\n2,1,1\r\n3,x,1\r\n",
                "line 5, column 2 (`track`)",
            ),
            // CRLF with blank CRLF lines.
            (
                "time_s,track,bias\r\n\r\n0,1,1\r\n\r\n\r\n1,1,x\r\n",
                "line 6, column 3 (`bias`)",
            ),
            // Lone CR (old Mac): each `\r` ends a line, as an editor shows it.
            (
                "time_s,track,bias\r0,1,1\r1,x,1\r",
                "line 3, column 2 (`track`)",
            ),
            (
                "# a\r\r# b\rtime_s,track,bias\r\r0,1,1\r\r1,1,x\r",
                "line 8, column 3 (`bias`)",
            ),
            // Mixed: LF rows, then lone CR, then CRLF (a plain start handing over).
            (
                "time_s,track,bias\n0,1,1\n1,1,1\r2,1,1\r\n\r3,x,1\n",
                "line 6, column 2 (`track`)",
            ),
            ("time_s,track,bias\r0,1,1\r\r1,1\r", "line 4: 2 fields"),
            // A quoted cell with an embedded newline before the bad row.
            (
                "time_s,track,bias,note\n0,1,1,\"a\nb\"\n1,x,1,c\n",
                "line 4, column 2 (`track`)",
            ),
            (
                "time_s,track,bias,note\n0,1,1,\"a\r\nb\r\nc\"\r\n1,1,x,c\r\n",
                "line 5, column 3 (`bias`)",
            ),
            // A quoted header, blank lines, then the bad row.
            (
                "\"time_s\",track,bias\n0,1,1\n\n1,1,x\n",
                "line 4, column 3 (`bias`)",
            ),
            // Metadata and blank lines before the header.
            (
                "# a\n\n# b\r\n\ntime_s,track,bias\n\n0,1,1\n\n1,x,1\n",
                "line 9, column 2 (`track`)",
            ),
            // Time backwards after blank lines.
            (
                "time_s,track,bias\n1,1,1\n\n0,1,1\n",
                "line 4, column 1 (`time_s`): time goes backwards",
            ),
            // A row of the wrong length after blank lines / in CRLF (no column: the row).
            (
                "time_s,track,bias\n0,1,1\n\n\n1,1,1,1\n",
                "line 5: 4 fields",
            ),
            (
                "\"time_s\",track,bias\r\n0,1,1\r\n1,1\r\n",
                "line 3: 2 fields",
            ),
            (
                "time_s,track,bias\r\n0,1,1\r\n\r\n1,1\r\n",
                "line 4: 2 fields",
            ),
        ];
        let map = ColumnMap::default();
        for (text, want) in cases {
            // The hand count agrees with the raw bytes: the marked row's line.
            let bad = text.find(['x', '@']).unwrap_or(text.len() - 2);
            if want.contains("column 2") || want.contains("column 3") {
                assert!(
                    want.starts_with(&format!("line {}", physical_line(text.as_bytes(), bad))),
                    "{text:?}: {want}"
                );
            }
            for name in ["t.csv", STDIN_NAME] {
                for (plain, fast) in [(false, false), (true, false), (true, true)] {
                    for max in [1, 3, 1 << 16] {
                        let src = Pieces {
                            data: text.as_bytes(),
                            max,
                            rng: crate::numeric::rng::SimRng::new(max as u64),
                        };
                        let err = LogReader::from_reader_source(
                            name,
                            src,
                            &map,
                            BiasColumn::Required,
                            LOOKAHEAD_ROWS,
                            plain,
                        )
                        .and_then(|r| r.read_all_with(0, fast))
                        .expect_err(text)
                        .to_string();
                        let full = format!("{name}: {want}");
                        assert!(
                            err.starts_with(&full),
                            "{text:?} ({plain}, {fast}, {max}): got `{err}`, want `{full}`"
                        );
                    }
                    let mut r = LogReader::from_reader_source(
                        name,
                        text.as_bytes(),
                        &map,
                        BiasColumn::Required,
                        LOOKAHEAD_ROWS,
                        plain,
                    )
                    .unwrap();
                    let err = r.summarise_each(|_| ()).expect_err(text).to_string();
                    assert!(
                        err.starts_with(&format!("{name}: {want}")),
                        "summary {text:?}: `{err}`"
                    );
                }
            }
        }
    }

    #[test]
    fn lone_cr_rows_after_a_plain_start_are_not_read_whole() {
        // A log whose header and first 200 rows end in `\n` and whose 4 MiB of rows after them
        // end in a lone `\r` (no `\n`): the plain lines hand over to the csv parser at the
        // first `\r` rather than read on looking for a `\n`, row by row and in the fast rows.
        // Reference: the bytes asked of the source when the first lone-CR row comes out stay
        // within the buffers' sizes (far below 4 MiB); the rows are the ones written, on the
        // lines counted while writing them.
        struct Counted<'a>(&'a [u8], std::rc::Rc<std::cell::Cell<usize>>);
        impl Read for Counted<'_> {
            fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
                let n = self.0.len().min(buf.len());
                buf[..n].copy_from_slice(&self.0[..n]);
                self.0 = &self.0[n..];
                self.1.set(self.1.get() + n);
                Ok(n)
            }
        }
        const PLAIN: u64 = 200;
        let mut text = String::from("time_s,track,bias\n");
        let mut rows = 0u64;
        while text.len() < 4 << 20 {
            let end = if rows < PLAIN { '\n' } else { '\r' };
            text.push_str(&format!("{rows},{},2.5{end}", rows % 1000));
            rows += 1;
        }
        for fast in [false, true] {
            let read = std::rc::Rc::new(std::cell::Cell::new(0));
            let mut r = LogReader::from_reader_source(
                "t.csv",
                Counted(text.as_bytes(), read.clone()),
                &ColumnMap::default(),
                BiasColumn::Required,
                LOOKAHEAD_ROWS,
                true,
            )
            .unwrap();
            let (mut n, mut read_at_first_cr) = (0u64, 0);
            let mut each = |row: &Row| {
                assert_eq!((row.track, row.line), ((n % 1000) as f64, n + 2), "{fast}");
                if n == PLAIN {
                    read_at_first_cr = read.get();
                }
                n += 1;
            };
            if fast {
                r.summarise_each(&mut each).unwrap();
            } else {
                for row in r {
                    each(&row.unwrap());
                }
            }
            assert_eq!(n, rows);
            assert!(
                read_at_first_cr < 1 << 20,
                "{fast}: {read_at_first_cr} bytes read"
            );
        }
    }

    #[test]
    fn rows_carry_the_physical_line() {
        // Reference: the line of each row's first byte counted in the raw bytes.
        let text = "# m\r\n\r\ntime_s,track,bias,note\r\n\r\n0,1,1,\"a\r\nb\"\r\n\r\n1,2,2,c\r\n2,3,3,d\n\n3,4,4,\"\"\n";
        let log = read(text).unwrap();
        let starts: Vec<u64> = ["0,1", "1,2", "2,3", "3,4"]
            .iter()
            .map(|s| physical_line(text.as_bytes(), text.find(s).unwrap()))
            .collect();
        assert_eq!(starts, [5, 8, 9, 11]);
        let lines: Vec<u64> = (0..log.len()).map(|i| log.row(i).line).collect();
        assert_eq!(lines, starts);
    }

    #[test]
    fn header_problems_name_the_header_line() {
        let cases: &[(&str, &str)] = &[
            (
                "# a\n\ntime_s,track,bias,track\n0,1,1,1\n",
                "t.csv: line 3: column `track` appears twice",
            ),
            (
                "# a\r\n\r\ntime_s,track\r\n0,1\r\n",
                "t.csv: line 3: missing required column `bias`",
            ),
            (
                "\n\n\"time_s\",track\n0,1\n",
                "t.csv: line 3: missing required column `bias`",
            ),
            (
                "# a\r\rtime_s,track\r0,1\r",
                "t.csv: line 3: missing required column `bias`",
            ),
            (
                "# a\r\n\rtime_s,track\r\n0,1\r\n",
                "t.csv: line 3: missing required column `bias`",
            ),
        ];
        for (text, want) in cases {
            let err = read(text).expect_err(text).to_string();
            assert!(
                err.starts_with(want),
                "{text:?}: got `{err}`, want `{want}`"
            );
        }
    }

    #[test]
    fn a_plan_may_lack_the_bias_column_or_every_measurement() {
        // Reference: the rows as written; with BiasColumn::Optional nothing is measured and
        // no error is raised, and a covariate keeps its place.
        let read_plan = |text: &str| {
            Log::from_reader_with(
                "p.csv",
                text.as_bytes(),
                &ColumnMap::default(),
                BiasColumn::Optional,
            )
        };
        let plan = read_plan("time_s,track,temp_c\n0,100,25\n0.5,120,26\n").unwrap();
        assert!(!plan.schema.has_bias());
        assert_eq!(plan.schema.covariates, vec!["temp_c".to_string()]);
        assert_eq!(plan.row(1).covariates, vec![26.0]);
        assert_eq!(plan.measured_count(), 0);
        let empty = read_plan("time_s,track,bias\n0,100,\n0.5,120,\n").unwrap();
        assert!(empty.schema.has_bias() && empty.measured_count() == 0);
        // Other bad input is still an error naming line and column.
        let e = read_plan("time_s,track\n0,100\n0.5,x\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("p.csv: line 3, column 2 (`track`)"), "{e}");
        // Required (the default) keeps both errors.
        assert!(read("time_s,track\n0,1\n").is_err());
    }

    #[test]
    fn byte_order_mark_before_metadata_or_header_is_skipped() {
        for text in [
            "\u{feff}# seed = 1\ntime_s,track,bias\n0,1,2\n",
            "\u{feff}time_s,track,bias\n0,1,2\n",
        ] {
            let log = read(text).expect(text);
            assert_eq!(log.row(0).bias, Some(2.0), "{text:?}");
        }
        assert_eq!(
            read("\u{feff}# seed = 1\ntime_s,track,bias\n0,1,2\n")
                .unwrap()
                .schema
                .metadata_value("seed"),
            Some("1")
        );
    }

    #[test]
    fn units_come_from_flags_then_metadata_then_columns() {
        let plain = read("time_s,track,bias\n0,1,2\n").unwrap();
        assert_eq!(plain.schema.units, Units::default());
        assert_eq!(plain.schema.units.per_position(), "counts/track");
        let meta =
            read("# bias_unit = mA\n# position_unit: um\ntime_s,track,bias\n0,1,2\n").unwrap();
        assert_eq!(
            meta.schema.units,
            Units {
                bias: "mA".into(),
                position: "um".into()
            }
        );
        let map = ColumnMap {
            time: "t".into(),
            track: "position_m".into(),
            bias: "force_N".into(),
            delimiter: None,
        };
        let mut renamed =
            Log::from_reader("r.csv", "t,position_m,force_N\n0,0.1,2\n".as_bytes(), &map).unwrap();
        assert_eq!(renamed.schema.units.bias, "force_N");
        assert_eq!(renamed.schema.units.position, "position_m");
        // Flags win over the column default; `None` keeps it; labels are trimmed.
        renamed.schema.set_units(Some(" N "), None).unwrap();
        assert_eq!(renamed.schema.units.bias, "N");
        assert_eq!(renamed.schema.units.position, "position_m");
        // Flags win over metadata too.
        let u = Units::resolve(Some("kN"), Some("mm"), &meta.schema).unwrap();
        assert_eq!(u.per_position(), "kN/mm");
    }

    #[test]
    fn bad_unit_labels_name_their_flag_or_metadata_key() {
        for (label, want) in [
            ("", "must not be empty"),
            ("  ", "must not be empty"),
            ("N,m", "comma"),
            ("N\nm", "control character"),
            ("a\tb", "control character"),
        ] {
            let problem = check_unit_label(label).unwrap_err();
            assert!(problem.contains(want), "{label:?}: {problem}");
        }
        assert_eq!(check_unit_label(" N·m "), Ok("N·m"));
        let log = read("time_s,track,bias\n0,1,2\n").unwrap();
        let e = Units::resolve(Some(""), None, &log.schema).unwrap_err();
        // The library names the setting; the CLI renders it as its flag (tests/it/units.rs).
        assert!(e.to_string().starts_with("Units::bias ``: "), "{e}");
        let e = Units::resolve(None, Some("a,b"), &log.schema).unwrap_err();
        assert!(e.to_string().starts_with("Units::position `a,b`: "), "{e}");
        let err = read("# bias_unit =\ntime_s,track,bias\n0,1,2\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("t.csv: metadata `bias_unit` ``: a unit label must not be empty"),
            "{err}"
        );
    }

    #[test]
    fn fast_cell_parser_equals_the_reference_on_every_kind_of_cell() {
        // Reference: the text path the reader used before (`str::trim`, then `parse_cell`,
        // i.e. `str::parse::<f64>` with the decimal-comma rewrite). The fast path must accept
        // the same cells with bit-identical values and refuse the same ones.
        let reference = |raw: &[u8], dc: bool| -> Result<Option<f64>, ()> {
            let text = std::str::from_utf8(raw).map_err(|_| ())?.trim();
            if text.is_empty() {
                return Ok(None);
            }
            parse_cell(text, dc).map(Some).ok_or(())
        };
        let mut cells: Vec<Vec<u8>> = [
            "",
            " ",
            "\t",
            "0",
            "-0",
            "+1",
            "1.",
            ".5",
            "-.5",
            "1e5",
            "1E+5",
            "1e-5",
            "1e",
            "e5",
            ".",
            "-",
            "+",
            "1.5.2",
            "0x10",
            "1_000",
            "inf",
            "-inf",
            "Infinity",
            "NaN",
            "nan",
            "infinit",
            "1e400",
            "1e-400",
            "abc",
            " 12.5 ",
            "\u{b}7\u{b}",
            "\u{a0}3.25",
            "3.25\u{a0}",
            "\u{3000}4",
            "１",
            "0,25",
            "-1,5",
            "1,5e3",
            "1.234,5",
            "1,2,3",
            "12345678901234567890",
            "0.1000000000000000055511151231257827",
            "2.2250738585072011e-308",
            "4.9e-324",
            "1.7976931348623157e308",
            "\"1\"",
            "1 2",
        ]
        .iter()
        .map(|s| s.as_bytes().to_vec())
        .collect();
        cells.push(vec![b'1', 0xff]);
        cells.push(vec![0xc3, b'1']);
        let mut rng = crate::numeric::rng::SimRng::new(16);
        for _ in 0..20_000 {
            let x = rng.range(-1.0, 1.0) * 10f64.powi(rng.below(40) as i32 - 20);
            for text in [
                x.to_string(),
                format!("{x:e}"),
                format!("{x:.3}"),
                format!("  {x:.7E}\t"),
                format!("{x}").replace('.', ","),
            ] {
                cells.push(text.into_bytes());
            }
            cells.push(f64::from_bits(rng.next_u64()).to_string().into_bytes());
        }
        for raw in &cells {
            for dc in [false, true] {
                let (fast, slow) = (parse_field(raw, dc), reference(raw, dc));
                let same = match (fast, slow) {
                    (Ok(Some(a)), Ok(Some(b))) => {
                        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
                    }
                    (a, b) => {
                        a.is_err() == b.is_err()
                            && a.ok().flatten().is_none() == b.ok().flatten().is_none()
                    }
                };
                assert!(
                    same,
                    "{:?} (decimal comma {dc}): {fast:?} vs {slow:?}",
                    String::from_utf8_lossy(raw)
                );
            }
        }
    }

    #[test]
    fn plain_number_parser_equals_str_parse() {
        // Reference: `str::parse::<f64>` (correctly rounded). Every cell the plain parser takes
        // whole must have the very bits `str::parse` gives; the common shapes must be taken.
        let mut rng = crate::numeric::rng::SimRng::new(29);
        let mut cells: Vec<String> = [
            "0",
            "-0",
            "0.0",
            "-0.000",
            "1.",
            ".5",
            "-.5",
            "5.",
            "0.086173",
            "1481",
            "110.2882",
            "-3.25",
            "9007199254740992",
            "9007199254740993",
            "0.1234567890123456789",
            "1234567890123456789",
            "12345678901234567890",
            "0.0000000000000000000001",
            "0.00000000000000000000001",
            "-",
            ".",
            "-.",
            "",
            "+1",
            "1e5",
            "1.5.2",
            "--1",
            "0x1",
        ]
        .iter()
        .map(|c| c.to_string())
        .collect();
        for _ in 0..50_000 {
            let x = rng.range(-1.0, 1.0) * 10f64.powi(rng.below(34) as i32 - 16);
            let decimals = rng.below(24) as usize;
            cells.push(format!("{x:.decimals$}"));
            cells.push(format!("{}", rng.below(1 << 54)));
            cells.push(x.to_string());
        }
        let mut taken = 0;
        for c in &cells {
            let Some((v, end)) = plain::parse_plain(c.as_bytes(), 0) else {
                continue;
            };
            if end != c.len() {
                continue;
            }
            taken += 1;
            let want: f64 = c.parse().expect(c);
            assert_eq!(v.to_bits(), want.to_bits(), "{c:?}: {v:e} vs {want:e}");
        }
        for c in [
            "0.086173",
            "1481",
            "-110.2882",
            "-0",
            ".5",
            "5.",
            "9007199254740992",
        ] {
            let (v, end) = plain::parse_plain(c.as_bytes(), 0).expect(c);
            assert_eq!(
                (v.to_bits(), end),
                (c.parse::<f64>().unwrap().to_bits(), c.len())
            );
        }
        assert!(taken > cells.len() / 3, "{taken} of {}", cells.len());
        for c in [
            "9007199254740993",
            "12345678901234567890",
            "0.00000000000000000000001",
        ] {
            assert!(plain::parse_plain(c.as_bytes(), 0).is_none(), "{c}");
        }
    }

    /// A source handing out `data` in pieces of 1 to `max` bytes.
    struct Pieces<'a> {
        data: &'a [u8],
        max: usize,
        rng: crate::numeric::rng::SimRng,
    }

    impl Read for Pieces<'_> {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let n = (1 + self.rng.below(self.max as u64) as usize)
                .min(buf.len())
                .min(self.data.len());
            buf[..n].copy_from_slice(&self.data[..n]);
            self.data = &self.data[n..];
            Ok(n)
        }
    }

    /// A random log text: plain rows with, now and then, a cell or line of another kind —
    /// ones the reader takes (spaces, exponents, quotes, `+`, CRLF, blank lines, text in a
    /// skipped column, long digit strings) and ones it refuses (text, NaN, inf, out of range,
    /// time backwards, empty required cells, other field counts, bytes that are not UTF-8).
    fn random_log_text(rng: &mut crate::numeric::rng::SimRng) -> Vec<u8> {
        let (header, sep, dc) = match rng.below(5) {
            0 => ("time_s,track,bias", ',', false),
            1 => ("time_s,track,bias,temp_c", ',', false),
            2 => ("time_s,track,notes,bias,temp_c", ',', false),
            3 => ("time_s;track;bias;temp_c", ';', true),
            _ => ("bias\ttime_s\ttrack", '\t', true),
        };
        let names: Vec<&str> = header.split(sep).collect();
        let mut text = format!("# seed = 1\n{header}\n").into_bytes();
        let rows = 1 + rng.below(2500);
        // Defects: rare enough that most logs read far, often enough that every kind is met.
        let odd = 0.0005 + 0.002 * rng.uniform();
        let mut t = 0.0;
        for _ in 0..rows {
            t += rng.range(0.0, 0.5);
            let mut cells: Vec<String> = names
                .iter()
                .map(|&name| match name {
                    "time_s" => format!("{t:.6}"),
                    "track" => format!("{}", rng.below(3000)),
                    "bias" if rng.uniform() < 0.1 => String::new(),
                    "bias" => format!("{:.4}", rng.range(-200.0, 200.0)),
                    "temp_c" => format!("{:.2}", rng.range(20.0, 60.0)),
                    _ => ["start", "", "x y", "ok"][rng.below(4) as usize].to_string(),
                })
                .collect();
            if dc {
                for c in &mut cells {
                    if rng.uniform() < 0.3 {
                        *c = c.replace('.', ",");
                    }
                }
            }
            let mut end = "\n";
            if rng.uniform() < odd {
                let k = rng.below(cells.len() as u64) as usize;
                let odd_cells = [
                    "x",
                    "NaN",
                    "inf",
                    "-inf",
                    "1e400",
                    "2e15",
                    "-3e15",
                    "2000000000000000",
                    "-1000000000000000.5",
                    " 12.5 ",
                    "1e3",
                    "+5",
                    "\"7.5\"",
                    "\"1,5\"",
                    "0,5",
                    "",
                    "  ",
                    "-",
                    ".",
                    "5.",
                    "-0",
                    ".25",
                    "123456789012345678901234",
                    "0.000000000000000000000000123",
                    "é",
                    "\u{a0}4",
                    "1\"2",
                    "99999999",
                ];
                match rng.below(8) {
                    0 => end = ["\r\n", "\r"][rng.below(2) as usize],
                    1 => end = "\n\n",
                    2 => cells.push("1".into()),
                    3 => {
                        cells.pop();
                    }
                    4 => t -= 1.0,
                    5 => cells[k] = "\u{ff}".into(),
                    _ => cells[k] = odd_cells[rng.below(odd_cells.len() as u64) as usize].into(),
                }
            }
            let mut line = cells.join(&sep.to_string()).into_bytes();
            if line.ends_with("\u{ff}".as_bytes()) {
                // A byte that is not UTF-8 (the cell above marks where).
                line.truncate(line.len() - 2);
                line.push(0xff);
            }
            text.extend_from_slice(&line);
            text.extend_from_slice(end.as_bytes());
        }
        if rng.uniform() < 0.2 {
            text.pop(); // no line end after the last row
        }
        text
    }

    #[test]
    fn fast_reading_equals_the_csv_parser_and_the_row_by_row_read() {
        // Reference: every line through the csv crate's parser and every row through
        // `read_into` (the reader before the fast path). The plain lines (row by row) and the
        // fast rows must give the same log — values bit for bit, line numbers, notes — or the
        // same error word for word, whatever pieces the source hands out; and so must the
        // streaming summary (`check`'s read) and the rows it hands on.
        let mut rng = crate::numeric::rng::SimRng::new(1616);
        let map = ColumnMap::default();
        let read = |text: &[u8], plain: bool, fast: bool, max: usize, seed: u64| {
            let src = Pieces {
                data: text,
                max,
                rng: crate::numeric::rng::SimRng::new(seed),
            };
            let r = LogReader::from_reader_source(
                "t.csv",
                src,
                &map,
                BiasColumn::Required,
                LOOKAHEAD_ROWS,
                plain,
            )?;
            r.read_all_with(0, fast)
        };
        let (mut read_whole, mut errors) = (0, 0);
        for case in 0..400 {
            let text = random_log_text(&mut rng);
            let max = [1 << 16, 7, 1000][case % 3];
            let reference = read(&text, false, false, max, case as u64);
            for (plain, fast) in [(true, false), (true, true)] {
                let got = read(&text, plain, fast, max, case as u64 + 1);
                let show = || String::from_utf8_lossy(&text).into_owned();
                match (&reference, &got) {
                    (Ok(a), Ok(b)) => {
                        assert!(
                            a == b,
                            "case {case} ({plain}, {fast}): logs differ\n{}",
                            show()
                        );
                        for i in 0..a.len() {
                            let bits = |l: &Log| l.bias(i).map(f64::to_bits);
                            assert_eq!(bits(a), bits(b), "case {case} row {i}");
                        }
                    }
                    (Err(a), Err(b)) => {
                        assert_eq!(a.to_string(), b.to_string(), "case {case}\n{}", show())
                    }
                    (a, b) => panic!(
                        "case {case} ({plain}, {fast}): {:?} vs {:?}\n{}",
                        a.as_ref().map(Log::len).map_err(ToString::to_string),
                        b.as_ref().map(Log::len).map_err(ToString::to_string),
                        show()
                    ),
                }
            }
            // The streaming summary (`check`'s read) with the rows it hands out, the same way.
            let summarise = |plain: bool, seed: u64, rows: &mut Vec<_>| {
                let src = Pieces {
                    data: &text,
                    max,
                    rng: crate::numeric::rng::SimRng::new(seed),
                };
                let mut r = LogReader::from_reader_source(
                    "t.csv",
                    src,
                    &map,
                    BiasColumn::Required,
                    LOOKAHEAD_ROWS,
                    plain,
                )?;
                let bits = |x: f64| x.to_bits();
                let summary = r.summarise_each(|row| {
                    rows.push((
                        row.line,
                        bits(row.time_s),
                        bits(row.track),
                        row.bias.map(bits),
                        row.covariates.iter().map(|&c| bits(c)).collect::<Vec<_>>(),
                    ))
                })?;
                Ok::<_, LogError>(summary)
            };
            let (mut rows_a, mut rows_b) = (Vec::new(), Vec::new());
            let (sa, sb) = (
                summarise(false, case as u64, &mut rows_a),
                summarise(true, case as u64 + 2, &mut rows_b),
            );
            // Line numbers against the raw bytes, the slow obvious way: the csv crate parses
            // the whole text (metadata line and header as records too) for the records'
            // bounds; a record's line is 1 + the `\n`s before its first byte, found by
            // skipping the line ends from where the parser began it.
            let delimiter = [b';', b'\t']
                .into_iter()
                .find(|d| text.split(|&b| b == b'\n').nth(1).unwrap().contains(d))
                .unwrap_or(b',');
            let mut raw = csv::ReaderBuilder::new()
                .has_headers(false)
                .flexible(true)
                .delimiter(delimiter)
                .from_reader(&text[..]);
            let mut record_lines = Vec::new();
            for record in raw.byte_records() {
                let Ok(record) = record else { break };
                let mut at = record.position().unwrap().byte() as usize;
                while at < text.len() && (text[at] == b'\n' || text[at] == b'\r') {
                    at += 1;
                }
                record_lines.push(physical_line(&text, at));
            }
            let record_lines = &record_lines[2..]; // after `# seed = 1` and the header
            // Rows handed on before an error are the records before the bad one.
            let lines_a: Vec<u64> = rows_a.iter().map(|r| r.0).collect();
            assert_eq!(lines_a, record_lines[..lines_a.len()], "case {case}");
            if let Err(e) = &sa
                && let Some(rest) = e.to_string().split(": line ").nth(1)
            {
                let n: u64 = rest
                    .split(|c: char| !c.is_ascii_digit())
                    .next()
                    .unwrap()
                    .parse()
                    .unwrap();
                assert_eq!(n, record_lines[lines_a.len()], "case {case}: {e}");
            }
            assert!(rows_a == rows_b, "case {case}: rows differ");
            match (sa, sb) {
                (Ok(a), Ok(b)) => {
                    assert!(a == b, "case {case}: summaries differ");
                    assert_eq!(lines_a, record_lines, "case {case}");
                }
                (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "case {case}"),
                (a, b) => panic!("case {case}: {:?} vs {:?}", a.is_ok(), b.is_ok()),
            }
            match reference {
                Ok(_) => read_whole += 1,
                Err(_) => errors += 1,
            }
        }
        // Both outcomes are exercised many times.
        assert!(
            read_whole > 50 && errors > 50,
            "{read_whole} read, {errors} errors"
        );
    }

    #[test]
    fn dialects_read_to_the_same_rows() {
        // Reference: the plain comma file; every dialect below holds the same numbers.
        let plain = read("time_s,track,bias,temp_c\n0,100,12.5,40\n0.5,120,-3.25,41\n").unwrap();
        let dialects = [
            "time_s;track;bias;temp_c\n0;100;12,5;40\n0,5;120;-3,25;41\n",
            "time_s\ttrack\tbias\ttemp_c\n0\t100\t12.5\t40\n0.5\t120\t-3.25\t41\n",
            " Time_S , TRACK ,Bias,temp_c\n0,100,12.5,40\n0.5,120,-3.25,41\n",
            "time_s,track,bias,temp_c,\n0,100,12.5,40,\n0.5,120,-3.25,41,\n",
            "time_s,track,notes,bias,temp_c\n0,100,start,12.5,40\n0.5,120,,-3.25,41\n",
        ];
        for text in dialects {
            let log = read(text).expect(text);
            assert!(
                log.rows()
                    .map(|r| r.to_row())
                    .eq(plain.rows().map(|r| r.to_row())),
                "{text:?}"
            );
            assert_eq!(log.schema.covariates, ["temp_c"], "{text:?}");
        }
        let notes = read(dialects[0]).unwrap().schema.notes;
        assert!(notes[0].contains("semicolon"), "{notes:?}");
        let notes = read(dialects[4]).unwrap().schema.notes;
        assert!(
            notes[0].contains("column 3 (`notes`) is not numeric (line 2: `start`); skipped"),
            "{notes:?}"
        );
        // A trailing empty column is ignored without a note; a case match is told.
        assert!(read(dialects[3]).unwrap().schema.notes.is_empty());
        assert!(read(dialects[2]).unwrap().schema.notes[0].contains("ignoring case"));
        // An explicit delimiter wins over sniffing: read as commas, `;` text is one column.
        let map = ColumnMap {
            delimiter: Some(b','),
            ..ColumnMap::default()
        };
        let e = Log::from_reader("t.csv", dialects[0].as_bytes(), &map).unwrap_err();
        assert!(
            e.to_string().contains("missing required column `time_s`"),
            "{e}"
        );
        // A numeric covariate that turns to text after the look-ahead is still an error.
        let mut late = String::from("time_s,track,bias,v\n");
        for i in 0..LOOKAHEAD_ROWS {
            late.push_str(&format!("{i},1,2,3\n"));
        }
        late.push_str("100,1,2,x\n");
        let e = read(&late).unwrap_err().to_string();
        assert!(
            e.contains(&format!(
                "line {}, column 4 (`v`): not a number",
                LOOKAHEAD_ROWS + 2
            )),
            "{e}"
        );
        // A comma file keeps the point as the only decimal separator.
        assert!(read("time_s,track,bias\n0,\"1,5\",2\n").is_err());
    }

    #[test]
    fn a_rig_header_names_every_missing_column_and_the_flags_at_once() {
        // Reference: the header itself; each role's column is the one a reader would pick.
        let e = read("time_s,position_m,force_N,velocity_m_s\n0,1,2,3\n")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "t.csv: line 1: missing required columns `track`, `bias` (columns found: time_s, \
             position_m, force_N, velocity_m_s); name them: ColumnMap::track position_m \
             ColumnMap::bias force_N"
        );
        // Names with spaces are quoted for the shell; a column is offered for one role only;
        // no column for a role: NAME.
        let e = read("time [s],position [um],bias [counts]\n0,1,2\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.ends_with(
                "name them: ColumnMap::time 'time [s]' ColumnMap::track 'position [um]' \
                 ColumnMap::bias 'bias [counts]'"
            ),
            "{e}"
        );
        let e = read("a,b,c\n1,2,3\n").unwrap_err().to_string();
        assert!(
            e.ends_with("ColumnMap::time NAME ColumnMap::track NAME ColumnMap::bias NAME"),
            "{e}"
        );
        // One missing column keeps its own message (and a plan needs no bias column).
        let plan = Log::from_reader_with(
            "p.csv",
            "t,position_m\n0,1\n".as_bytes(),
            &ColumnMap::default(),
            BiasColumn::Optional,
        )
        .unwrap_err()
        .to_string();
        assert!(
            plan.contains("missing required columns `time_s`, `track`"),
            "{plan}"
        );
        // A header that is one column holding a delimiter: the delimiter is named.
        let e = read("time_s|track|bias\n0|1|2\n").unwrap_err().to_string();
        assert!(
            e.contains("line 1: missing required column `time_s`: the header is one column")
                && e.contains("that holds `|`"),
            "{e}"
        );
    }

    #[test]
    fn a_unit_in_brackets_is_the_label_and_a_time_column_in_ms_is_told() {
        let map = ColumnMap {
            time: "t (ms)".into(),
            track: "position [um]".into(),
            bias: "Force (N)".into(),
            delimiter: None,
        };
        let log = Log::from_reader(
            "u.csv",
            "t (ms),position [um],Force (N)\n0,1,2\n".as_bytes(),
            &map,
        )
        .unwrap();
        assert_eq!(
            log.schema.units,
            Units {
                bias: "N".into(),
                position: "um".into()
            }
        );
        assert!(
            log.schema.notes.iter().any(|n| n
                .contains("column `t (ms)` is read in seconds, biasctl's time unit, but its name says milliseconds")),
            "{:?}",
            log.schema.notes
        );
        // Metadata and flags still win over the bracket; a name without one is its own label;
        // seconds raise no note.
        let mut schema = log.schema.clone();
        schema.set_units(Some("mN"), None).unwrap();
        assert_eq!(schema.units.bias, "mN");
        assert_eq!(unit_in_name("position_m"), None);
        assert_eq!(unit_in_name("x []"), None);
        assert_eq!(unit_in_name(" angle (rad) "), Some("rad"));
        for name in ["time_s", "time [s]", "t", "timestamp", "time_sec"] {
            assert_eq!(time_unit_not_seconds(name), None, "{name}");
        }
        for (name, unit) in [
            ("time_ms", "milliseconds"),
            ("t [us]", "microseconds"),
            ("Time (min)", "minutes"),
            ("time_h", "hours"),
        ] {
            assert_eq!(time_unit_not_seconds(name), Some(unit), "{name}");
        }
    }

    #[test]
    fn a_header_without_rows_is_told_apart_from_rows_without_a_bias() {
        let e = read("# m\ntime_s,track,bias\n\n").unwrap_err().to_string();
        assert_eq!(
            e,
            "t.csv: no rows under the header (a log holds one row per seek)"
        );
        let e = read("time_s,track,bias\n0,1,\n").unwrap_err().to_string();
        assert_eq!(e, "t.csv: no measured rows: every `bias` cell is empty");
        // A plan may be a header alone.
        let plan = Log::from_reader_with(
            "p.csv",
            "time_s,track\n".as_bytes(),
            &ColumnMap::default(),
            BiasColumn::Optional,
        );
        assert!(plan.is_ok(), "{plan:?}");
    }

    #[test]
    fn a_json_or_toml_file_given_as_a_log_is_named_as_such() {
        for text in [
            "{\n  \"format\": \"biasctl-model\"\n}\n",
            "# drive\n[servo]\nts_s = 1e-4\n",
        ] {
            let e = read(text).unwrap_err().to_string();
            assert!(e.contains("this is not a CSV log"), "{e}");
        }
        let e = read("# drive\n[servo]\n").unwrap_err().to_string();
        assert!(e.starts_with("t.csv: line 2:"), "{e}");
    }

    #[test]
    fn text_that_is_not_utf8_names_its_line_and_how_to_save_it() {
        // Excel's "Unicode Text": UTF-16 with its byte-order mark.
        let utf16: Vec<u8> = "\u{feff}time_s\ttrack\tbias\r\n0\t1\t2\r\n"
            .encode_utf16()
            .flat_map(u16::to_le_bytes)
            .collect();
        let e = Log::from_reader("u.txt", &utf16[..], &ColumnMap::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("u.txt: line 1: the file is UTF-16 text"),
            "{e}"
        );
        // A Windows code page's `µ` (0xB5) in the header, after a metadata line: line 2,
        // character 24.
        let cp1252 = b"# rig 3\ntime_s,track,position [\xb5m],bias\n0,1,1,2\n";
        let e = Log::from_reader("c.csv", &cp1252[..], &ColumnMap::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("c.csv: line 2: character 24 (byte 0xB5) is not UTF-8 text"),
            "{e}"
        );
        let meta = b"# temperature in \xb0C\ntime_s,track,bias\n0,1,2\n";
        let e = Log::from_reader("m.csv", &meta[..], &ColumnMap::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("m.csv: line 1: character 18 (byte 0xB0)"),
            "{e}"
        );
    }

    #[test]
    fn missing_column_suggests_the_closest_name() {
        let e = read("time,trk,bais\n0,1,2\n").unwrap_err().to_string();
        assert!(
            e.ends_with(
                "name them: ColumnMap::time time ColumnMap::track trk ColumnMap::bias bais"
            ),
            "{e}"
        );
        let e = read("time_s,trk,bias\n0,1,2\n").unwrap_err().to_string();
        assert!(
            e.contains("missing required column `track`") && e.contains("did you mean `trk`?"),
            "{e}"
        );
        // No name is close to `bias`, but `force` says it holds the role.
        let e = read("time_s,track,force\n0,1,2\n").unwrap_err().to_string();
        assert!(e.contains("did you mean `force`?"), "{e}");
        let e = read("time_s,track,note\n0,1,2\n").unwrap_err().to_string();
        assert!(!e.contains("did you mean"), "{e}");
        // A one- or two-letter name is not "in" the name looked for (`a` in `track`).
        let e = read("time_s,a,bias\n0,1,2\n").unwrap_err().to_string();
        assert!(!e.contains("did you mean"), "{e}");
        assert_eq!(sniff_delimiter("a;b,c;d"), b';');
        assert_eq!(sniff_delimiter("\"a;b\",c"), b',');
        assert_eq!(sniff_delimiter("abc"), b',');
    }

    #[test]
    fn writer_output_reads_back() {
        let mut buf = Vec::new();
        let mut w = LogWriter::new(&mut buf, &["seed = 3".into()], &["temp_c".into()]).unwrap();
        w.write_row(0.0, 100.0, Some(-0.0), &[25.5]).unwrap();
        w.write_row(0.5, 101.25, None, &[25.0]).unwrap();
        w.into_inner().unwrap();
        let text = String::from_utf8(buf).unwrap();
        assert_eq!(
            text,
            "# seed = 3\ntime_s,track,bias,temp_c\n0.000000,100,0.0000,25.5\n0.500000,101.25,,25\n"
        );
        // A covariate name with a comma or a quote is quoted, and reads back as it was.
        let mut buf = Vec::new();
        let names = ["temp,C".to_string(), "say \"hi\"".to_string()];
        let mut w = LogWriter::new(&mut buf, &[], &names).unwrap();
        w.write_row(1.0, 2.0, Some(3.0), &[4.0, 5.0]).unwrap();
        w.into_inner().unwrap();
        let quoted = String::from_utf8(buf).unwrap();
        assert!(
            quoted.starts_with("time_s,track,bias,\"temp,C\",\"say \"\"hi\"\"\"\n"),
            "{quoted}"
        );
        assert_eq!(read(&quoted).unwrap().schema.covariates, names);
        let log = read(&text).unwrap();
        assert_eq!(log.row(1).track, 101.25);
    }
}
