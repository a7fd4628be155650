//! Physical lines, as an editor shows them: a `\n`, a `\r\n` and a lone `\r` (old Mac files,
//! Excel's "CSV (Macintosh)") each end one line. Shared by the log reader (every path) and the
//! seek-script reader, so that errors name the line the user sees in both.

use std::io::{self, BufRead};

/// Reads one line of `src` into `out` (appended), through its line end: the first `\n` or `\r`
/// (a `\n` after that `\r` is left in `src`, so that a reader of a terminal does not wait for
/// it; the caller skips it, see [`LineStarts`] for the same rule). Returns the bytes read, 0 at
/// the end of `src`.
pub(crate) fn read_line(src: &mut impl BufRead, out: &mut Vec<u8>) -> io::Result<usize> {
    let mut read = 0;
    loop {
        let (done, used) = {
            let available = match src.fill_buf() {
                Ok(b) => b,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            match memchr::memchr2(b'\n', b'\r', available) {
                Some(i) => {
                    out.extend_from_slice(&available[..=i]);
                    (true, i + 1)
                }
                None => {
                    out.extend_from_slice(available);
                    (available.is_empty(), available.len())
                }
            }
        };
        src.consume(used);
        read += used;
        if done {
            return Ok(read);
        }
    }
}

/// A source for the csv parser that notes the physical line (1-based, as an editor shows it:
/// `\n`, `\r\n` and a lone `\r` each end one line) of each line's first byte that is not itself
/// a line end: where any record the parser reads starts. The parser names the byte where it
/// started reading a record, before the blank lines it skips and the `\n` of a CRLF line end it
/// had not yet read; the record starts at the first noted byte from there
/// ([`LineStarts::line_at`]).
pub(crate) struct LineStarts<R> {
    src: R,
    /// Bytes handed out so far.
    byte: u64,
    /// Physical line of the next byte handed out.
    line: u64,
    /// Whether the last byte handed out was a line end (`\n` or `\r`), or none was yet.
    after_end: bool,
    /// Whether the last byte handed out was a `\r` (a `\n` right after it ends no new line).
    after_cr: bool,
    /// Byte offset and line of each line start handed out that the parser has not passed.
    starts: std::collections::VecDeque<(u64, u64)>,
}

impl<R> LineStarts<R> {
    /// `src`, whose first byte starts physical line `line` (a line's first byte: not the `\n`
    /// of a CRLF whose `\r` was before `src`).
    pub(crate) fn new(src: R, line: u64) -> Self {
        Self {
            src,
            byte: 0,
            line,
            after_end: true,
            after_cr: false,
            starts: std::collections::VecDeque::new(),
        }
    }

    /// The physical line of the first line start at or after byte `at` of this source (the
    /// parser's position when it began a record): the record's own line. Starts before `at`
    /// are forgotten (the parser reads on), so memory stays within what the parser buffers.
    pub(crate) fn line_at(&mut self, at: u64) -> u64 {
        while self.starts.front().is_some_and(|&(b, _)| b < at) {
            self.starts.pop_front();
        }
        self.starts.front().map_or(self.line, |&(_, line)| line)
    }
}

impl<R: io::Read> io::Read for LineStarts<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.src.read(buf)?;
        for &b in &buf[..n] {
            match b {
                b'\n' => {
                    self.line += u64::from(!self.after_cr);
                    self.after_end = true;
                    self.after_cr = false;
                }
                b'\r' => {
                    self.line += 1;
                    self.after_end = true;
                    self.after_cr = true;
                }
                _ => {
                    if self.after_end {
                        self.starts.push_back((self.byte, self.line));
                        self.after_end = false;
                    }
                    self.after_cr = false;
                }
            }
            self.byte += 1;
        }
        Ok(n)
    }
}

/// The problem of a csv parser's error without its own position (which counts lines its own
/// way): a record of the wrong length names both lengths.
pub(crate) fn csv_problem(e: &csv::Error) -> String {
    match e.kind() {
        csv::ErrorKind::UnequalLengths {
            expected_len, len, ..
        } => unequal_lengths(*len as usize, *expected_len as usize),
        _ => e.to_string(),
    }
}

/// The message of a record with `len` fields where the header has `expected` (the csv
/// parser's `UnequalLengths`, as [`csv_problem`] words it).
pub(crate) fn unequal_lengths(len: usize, expected: usize) -> String {
    format!("{len} fields, but the header has {expected}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    /// The editor's line of byte `at`: 1 + the line ends in `text[..at]`, a `\r\n` one end
    /// (counted at its `\n`), a lone `\r` one. The slow, obvious reference.
    fn editor_line(text: &[u8], at: usize) -> u64 {
        let mut line = 1;
        for (i, &b) in text[..at].iter().enumerate() {
            let crlf = b == b'\r' && text.get(i + 1) == Some(&b'\n');
            if b == b'\n' || (b == b'\r' && !crlf) {
                line += 1;
            }
        }
        line
    }

    /// Hands out at most `max` bytes per read.
    struct Chunks<'a>(&'a [u8], usize);
    impl Read for Chunks<'_> {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let n = self.0.len().min(self.1).min(buf.len());
            buf[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }

    #[test]
    fn line_starts_count_lf_crlf_and_lone_cr_as_an_editor_does() {
        // Reference: `editor_line` of each line start (a byte that is not a line end, after one
        // or at the start), whatever pieces the source hands out (a CRLF split between reads).
        let mut rng = crate::numeric::rng::SimRng::new(7);
        for case in 0..300 {
            let text: Vec<u8> = (0..rng.below(80))
                .map(|_| [b'a', b'b', b'\n', b'\r', b','][rng.below(5) as usize])
                .collect();
            let want: Vec<(u64, u64)> = (0..text.len())
                .filter(|&i| {
                    !matches!(text[i], b'\n' | b'\r')
                        && (i == 0 || matches!(text[i - 1], b'\n' | b'\r'))
                })
                .map(|i| (i as u64, editor_line(&text, i)))
                .collect();
            let mut starts = LineStarts::new(Chunks(&text, 1 + case % 4), 1);
            starts.read_to_end(&mut Vec::new()).unwrap();
            let got: Vec<(u64, u64)> = starts.starts.iter().copied().collect();
            assert_eq!(got, want, "{:?}", String::from_utf8_lossy(&text));
            assert_eq!(starts.line, editor_line(&text, text.len()), "{text:?}");
        }
    }

    #[test]
    fn read_line_stops_at_either_line_end() {
        // Reference: the lines written by hand.
        let mut src = io::BufReader::with_capacity(2, &b"# a\r# b\r\nx\ny"[..]);
        let mut lines = Vec::new();
        loop {
            let mut line = Vec::new();
            if read_line(&mut src, &mut line).unwrap() == 0 {
                break;
            }
            lines.push(String::from_utf8(line).unwrap());
        }
        assert_eq!(lines, ["# a\r", "# b\r", "\n", "x\n", "y"]);
    }
}
