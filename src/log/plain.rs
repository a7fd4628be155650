//! The reader's fast path: the lines of a log that hold no quote and no carriage return,
//! split here instead of by the csv crate's parser, and the numbers of the common cell shape
//! (`-12.345`) converted here instead of by the general float parser.
//!
//! Both are fast paths with the general code as their reference: a line that is not plain
//! (a quote, a carriage return, an empty line) hands the rest of the file to the csv crate's
//! parser, started at that line as the old reader would have met it; a cell this parser does
//! not take ([`parse_plain`] returns `None`) goes to `parse_field`. Tests in `super` compare
//! whole logs read both ways, values bit for bit and errors word for word.

use std::io::{self, Read};

/// Bytes asked of the source per read: the size the csv crate's reader asked for, so a
/// source that fails part way (a line over the length limit) fails after the same rows.
const READ_BYTES: usize = 1 << 16;

/// Lines of a source, each borrowed from one growing buffer (no allocation per line).
pub(super) struct PlainLines<R> {
    src: R,
    buf: Vec<u8>,
    /// Start of the current line in `buf`.
    start: usize,
    /// End of the bytes read into `buf`.
    end: usize,
    /// End of the current line (its `\n`, or `end` for a last line without one, or just past
    /// its first `\r`), once peeked.
    line_end: Option<usize>,
    /// End of the last whole line (just past its `\n`) in `buf[..end]`, or at most `start`
    /// when none is buffered.
    complete: usize,
    /// The source returned no more bytes.
    eof: bool,
    /// The source failed: no more lines (as the csv reader ends after an I/O error).
    failed: bool,
    /// 1-based line number of the current line.
    line: u64,
    /// Bytes before the current line (counted from the header's first byte, as the csv reader
    /// counted them).
    byte: u64,
}

impl<R: Read> PlainLines<R> {
    /// Lines of `src`, the first of them numbered `line`, `byte` bytes after the header's start.
    pub(super) fn new(src: R, line: u64, byte: u64) -> Self {
        Self {
            src,
            buf: Vec::new(),
            start: 0,
            end: 0,
            line_end: None,
            complete: 0,
            eof: false,
            failed: false,
            line,
            byte,
        }
    }

    /// The current line without its `\n` (not consumed; [`PlainLines::advance`] moves on),
    /// `None` at the end of the source or after it failed.
    #[inline]
    pub(super) fn peek(&mut self) -> io::Result<Option<&[u8]>> {
        if self.failed {
            return Ok(None);
        }
        loop {
            if let Some(e) = self.line_end {
                return Ok(Some(&self.buf[self.start..e]));
            }
            if let Some(k) = memchr::memchr2(b'\n', b'\r', &self.buf[self.start..self.end]) {
                // A `\r` ends the search too, kept in the line: a line with one is not plain
                // (the caller hands it to the csv parser, never advancing past it), and a file
                // with lone-`\r` line ends is not read whole looking for a `\n`.
                let e = self.start + k;
                self.line_end = Some(e + usize::from(self.buf[e] == b'\r'));
                continue;
            }
            if self.eof {
                if self.start == self.end {
                    return Ok(None);
                }
                self.line_end = Some(self.end);
                continue;
            }
            self.fill()?;
        }
    }

    /// Moves past the current line (after [`PlainLines::peek`] returned it).
    #[inline]
    pub(super) fn advance(&mut self) {
        if let Some(e) = self.line_end.take() {
            let next = (e + 1).min(self.end);
            self.byte += (next - self.start) as u64;
            self.line += 1;
            self.start = next;
        }
    }

    /// The whole lines buffered from the current one on, each ending in `\n` (reading more
    /// when none is); empty at the end of the source, after it failed, when only a last
    /// line without a `\n` is left, or when the bytes buffered without a `\n` hold a `\r`
    /// (lone-`\r` line ends: not read on looking for a `\n`; [`PlainLines::peek`] returns
    /// that line).
    #[inline]
    pub(super) fn ready(&mut self) -> io::Result<&[u8]> {
        while self.complete <= self.start
            && !self.eof
            && !self.failed
            && memchr::memchr(b'\r', &self.buf[self.start..self.end]).is_none()
        {
            self.fill()?;
        }
        if self.failed || self.complete <= self.start {
            return Ok(&[]);
        }
        Ok(&self.buf[self.start..self.complete])
    }

    /// Moves past `rows` whole lines, `bytes` bytes in all, of [`PlainLines::ready`]'s window.
    #[inline]
    pub(super) fn consume(&mut self, bytes: usize, rows: u64) {
        debug_assert!(self.line_end.is_none() && self.start + bytes <= self.complete);
        self.start += bytes;
        self.byte += bytes as u64;
        self.line += rows;
    }

    /// 1-based line number of the current line.
    #[inline]
    pub(super) fn line(&self) -> u64 {
        self.line
    }

    /// Bytes before the current line, from the header's first byte.
    #[inline]
    pub(super) fn byte(&self) -> u64 {
        self.byte
    }

    /// Reads [`READ_BYTES`] more, keeping the current line's start.
    fn fill(&mut self) -> io::Result<()> {
        if self.start > 0 {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.complete = self.complete.saturating_sub(self.start);
            self.start = 0;
        }
        if self.buf.len() < self.end + READ_BYTES {
            self.buf.resize(self.end + READ_BYTES, 0);
        }
        loop {
            match self
                .src
                .read(&mut self.buf[self.end..self.end + READ_BYTES])
            {
                Ok(0) => self.eof = true,
                Ok(n) => {
                    self.end += n;
                    self.complete = memchr::memrchr(b'\n', &self.buf[self.start..self.end])
                        .map_or(self.start, |k| self.start + k + 1);
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    self.failed = true;
                    return Err(e);
                }
            }
            return Ok(());
        }
    }

    /// The unread bytes (from the current line on), the source, whether the source is at its
    /// end, and the current line's number and byte offset: what the csv parser needs to take
    /// over at this line.
    pub(super) fn into_parts(self) -> (Vec<u8>, R, bool, u64, u64) {
        let rest = self.buf[self.start..self.end].to_vec();
        (rest, self.src, self.eof, self.line, self.byte)
    }
}

/// Powers of ten that are exact in an `f64` (10⁰ … 10²²).
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// The number at `line[i..]` in the plain shape `[-]digits[.digits]` (at least one digit, at
/// most 19, no exponent, no `+`, no space) whose digits form an integer `m` ≤ 2⁵³ with at most
/// 22 decimals, and the index after it. Such a number is `m / 10^d` with both operands exact
/// in an `f64`, so the one division is the correctly rounded value — the value `str::parse`
/// gives (Clinger's fast path; tested against `str::parse`). Anything else is `None`, for the
/// general parser. What follows the number is the caller's to check.
#[inline(always)]
pub(super) fn parse_plain(line: &[u8], mut i: usize) -> Option<(f64, usize)> {
    let neg = line.get(i) == Some(&b'-');
    i += usize::from(neg);
    let mut m: u64 = 0;
    let mut digits = 0u32;
    while let Some(&b) = line.get(i) {
        let d = b.wrapping_sub(b'0');
        if d > 9 {
            break;
        }
        m = m.wrapping_mul(10).wrapping_add(u64::from(d));
        digits += 1;
        i += 1;
    }
    let mut decimals = 0usize;
    if line.get(i) == Some(&b'.') {
        i += 1;
        while let Some(&b) = line.get(i) {
            let d = b.wrapping_sub(b'0');
            if d > 9 {
                break;
            }
            m = m.wrapping_mul(10).wrapping_add(u64::from(d));
            digits += 1;
            decimals += 1;
            i += 1;
        }
    }
    if digits == 0 || digits > 19 || m > 1 << 53 || decimals > 22 {
        return None;
    }
    let v = m as f64 / POW10[decimals];
    Some((if neg { -v } else { v }, i))
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // values parsed from short decimal text compare exactly
mod tests {
    use super::*;

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
            let Some((v, end)) = parse_plain(c.as_bytes(), 0) else {
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
            let (v, end) = parse_plain(c.as_bytes(), 0).expect(c);
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
            assert!(parse_plain(c.as_bytes(), 0).is_none(), "{c}");
        }
    }
}
