//! Where a [`LogReader`](super::LogReader)'s records come from: plain lines split here (the
//! fast path) or the csv crate's parser (the reference), and the hand-over between them.

use super::error::{malformed, source_failed};
use super::limits::LineLimit;
use super::{LogError, lines, plain};
use std::io::{self, BufReader, Read};

/// What the CSV parser of a [`LogReader`] reads: bytes already read (the header line, or the
/// buffered rest from the first line that is not plain), then the rest of the source, with the
/// physical line of each line's first byte noted ([`lines::LineStarts`]).
pub(super) type CsvSource<R> =
    lines::LineStarts<io::Chain<io::Cursor<Vec<u8>>, BufReader<LineLimit<R>>>>;

/// Where a [`LogReader`]'s records come from.
pub(super) enum Source<R: Read> {
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
    pub(super) fn read_record(
        &mut self,
        record: &mut csv::ByteRecord,
        file: &str,
    ) -> Result<bool, LogError> {
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

/// Field `idx` of a record checked by [`check_utf8`], trimmed of surrounding whitespace (as
/// `str::trim`); `None` past the record's end.
pub(super) fn field(record: &csv::ByteRecord, idx: usize) -> Option<&str> {
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

impl<R: Read> Source<R> {
    /// The source of the rows after `header` (the line `header_line`), with the header's
    /// fields. A plain header line (no quote, no carriage return: what the fast path splits) is
    /// parsed alone and the rows after it split line by line, while they are plain; any other
    /// header (or any header without `plain_lines`) is read with the rows by the csv parser.
    pub(super) fn after_header(
        header: String,
        buf: BufReader<LineLimit<R>>,
        delimiter: u8,
        header_line: u64,
        plain_lines: bool,
        file: &str,
    ) -> Result<(csv::StringRecord, Self), LogError> {
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
        if plain {
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
            Ok((headers, source))
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
            Ok((headers, source))
        }
    }
}
