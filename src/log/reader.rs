//! The streaming reader of a log ([`LogReader`]): its head read into a [`LogSchema`], then
//! one checked [`Row`] at a time; and [`Log`]'s readers of a whole file.

use super::column_map::{self, ColumnMap};
use super::dialect::{delimiter_note, parse_field, sniff_delimiter};
use super::header::{self, LOOKAHEAD_ROWS};
use super::limits::{LineLimit, MAX_ABS_VALUE};
use super::schema::{STDIN_NAME, STDIN_PATH};
use super::source::{Source, field};
use super::units;
use super::{BiasColumn, Log, LogError, LogSchema, Row, Units};
use std::fs::File;
use std::io::{self, BufReader, Read};
use std::path::Path;

/// A streaming reader of a measurement log: constant memory in the number of rows.
///
/// It yields `Result<Row, LogError>`; after the last row it yields one
/// [`LogError::NoMeasuredRows`] if no row held a bias (unless read with
/// [`BiasColumn::Optional`]), then ends.
pub struct LogReader<R: Read> {
    pub(super) schema: LogSchema,
    pub(super) source: Source<R>,
    /// The current record, reused row after row (no allocation per row); every field is valid
    /// UTF-8 ([`Source::read_record`]).
    pub(super) record: csv::ByteRecord,
    /// Records read ahead to classify the columns, yielded before the rest of the file.
    pub(super) lookahead: std::collections::VecDeque<csv::ByteRecord>,
    /// A parse error met while reading ahead, returned after the records before it.
    pub(super) pending: Option<LogError>,
    pub(super) prev_time: Option<f64>,
    pub(super) measured: u64,
    pub(super) bias_column: BiasColumn,
    pub(super) done: bool,
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
    pub(super) fn from_reader_lookahead(
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
    pub(super) fn from_reader_source(
        file: &str,
        reader: R,
        map: &ColumnMap,
        bias_column: BiasColumn,
        lookahead_rows: usize,
        plain_lines: bool,
    ) -> Result<Self, LogError> {
        let mut buf = BufReader::new(LineLimit::new(reader));
        header::skip_byte_order_mark(&mut buf, file)?;
        let (metadata, line_no) = header::read_metadata(&mut buf, file)?;
        let header_line = line_no + 1;
        let header = header::read_text_line(&mut buf, file, header_line)?;
        header::refuse_json_or_toml(&header, file, header_line)?;
        let delimiter = map.delimiter.unwrap_or_else(|| sniff_delimiter(&header));
        let decimal_comma = delimiter != b',';
        let mut notes: Vec<String> = delimiter_note(file, delimiter, map.delimiter.is_some())
            .into_iter()
            .collect();
        let (headers, mut source) =
            Source::after_header(header, buf, delimiter, header_line, plain_lines, file)?;
        let columns = header::header_columns(&headers, file, header_line)?;
        let required =
            column_map::find_required(file, header_line, &columns, map, delimiter, bias_column)?;
        let (time_idx, track_idx, bias_idx) = (required.time, required.track, required.bias);
        // Once each (the columns were looked for twice when one was missing).
        for n in required.case_notes {
            if !notes.contains(&n) {
                notes.push(n);
            }
        }
        notes.extend(units::time_unit_note(file, &columns[time_idx]));
        // Read ahead to classify the other columns: a column is a numeric covariate unless it
        // has no name and no values, or no values, or a value that is not a number in these
        // rows.
        let (lookahead, pending) = header::read_ahead(&mut source, file, lookahead_rows);
        let covariate_idx = header::covariate_columns(
            file,
            &columns,
            [Some(time_idx), Some(track_idx), bias_idx],
            &lookahead,
            decimal_comma,
            &mut notes,
        );
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
            empty_cells: Vec::new(),
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
            true
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

    /// Hands every remaining row to `each`, in order, and stops at the first error of the log
    /// or of `each`: the rows and the error of calling [`LogReader::read_into`] until it
    /// returns `Ok(false)` (tested), but faster, the plain lines split and converted in one
    /// pass straight from the read buffer. The row handed to `each` is reused.
    pub fn try_for_each_row<E: From<LogError>>(
        &mut self,
        mut each: impl FnMut(&Row) -> Result<(), E>,
    ) -> Result<(), E> {
        let roles = self.roles();
        let mut row = Row::empty(self.schema.covariates.len());
        loop {
            let mut failed = None;
            self.plain_rows(&roles, &mut row, |r| match each(r) {
                Ok(()) => true,
                Err(e) => {
                    failed = Some(e);
                    false
                }
            })?;
            if let Some(e) = failed {
                return Err(e);
            }
            if !self.read_into(&mut row)? {
                return Ok(());
            }
            each(&row)?;
        }
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
            // An empty covariate cell is a missing value; only a term that reads the column
            // needs it (`LogSchema::require_covariates`).
            row.covariates.push(number(idx)?.unwrap_or(f64::NAN));
        }
        let empty: Vec<usize> = (0..row.covariates.len())
            .filter(|&k| row.covariates[k].is_nan())
            .collect();
        for k in empty {
            self.schema.note_empty_cell(k, line);
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
    pub(super) fn read_all(self, expected: usize) -> Result<Log, LogError> {
        self.read_all_with(expected, true)
    }

    /// [`LogReader::read_all`]; with `fast` the plain rows go the fast way
    /// ([`LogReader::plain_rows`]), without it every row goes through
    /// [`LogReader::read_into`] (the reference the fast way is tested against).
    pub(super) fn read_all_with(mut self, expected: usize, fast: bool) -> Result<Log, LogError> {
        let mut row = Row::empty(self.schema.covariates.len());
        let mut log = Log::with_capacity(self.schema.clone(), expected);
        let roles = fast.then(|| self.roles());
        loop {
            if let Some(roles) = &roles {
                self.plain_rows(roles, &mut row, |row| {
                    log.push(row);
                    true
                })?;
            }
            // The row the fast way left (not plain, an error to name, or the end).
            if !self.read_into(&mut row)? {
                break;
            }
            log.push(&row);
        }
        log.schema.empty_cells = std::mem::take(&mut self.schema.empty_cells);
        log.drop_empty_covariates();
        log.shrink_to_fit();
        Ok(log)
    }
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
