//! Numbers in CSV output without allocating: the layout of Rust's `Display` (`x.to_string()`:
//! the shortest digits that read back as exactly `x`, never an exponent) produced through `zmij`
//! (before: `ryu`; the same digits, tested on 2.4 million values, about twice as fast), which is
//! several times faster than `Display` and writes into a reused buffer. A whole number keeps
//! `.0` (`12.0`), so that CSV readers that guess a column's type from its first rows (pandas,
//! polars) read the column as floats.
//!
//! `ryu` and `Display` both write the shortest digit string that reads back as exactly `x`, and
//! of several such strings the one closest to `x`; they differ only in layout (`1.0`, `1e-7`,
//! `1.5e20`), which [`write_shortest`] undoes (`1`, `0.0000001`, `150000000000000000000`), and
//! in one rare case: when `x` lies exactly halfway between two shortest candidates, ryu rounds
//! the last digit to even and `Display` up (`-808126719656951.25` is written `…951.2` here and
//! `…951.3` by `Display`). Either text reads back as the same `x`; the tests check that and
//! the agreement with `to_string()` everywhere else.

/// Appends the text of finite `x` to `out` as `x.to_string()` lays it out (`-0` for negative
/// zero; no exponent), with ryu's shortest round-trip digits (see the module docs for the one
/// rare difference from `Display`), allocating nothing beyond `out`'s growth, except that a
/// whole number ends in `.0` (`12.0`, `-0.0`): a CSV reader guessing a column's type from its
/// first rows (pandas, polars) then reads it as floats. A non-finite `x` appends nothing
/// (callers write an empty cell for it, as the CSV writers do).
#[inline]
pub(crate) fn write_shortest(x: f64, out: &mut Vec<u8>) {
    if !x.is_finite() {
        return;
    }
    let mut buf = zmij::Buffer::new();
    if let Some(text) = zmij_as_is(x, &mut buf) {
        out.extend_from_slice(text);
        return;
    }
    let start = out.len();
    lay_out(buf.format_finite(x).as_bytes(), out);
    if !out[start..].contains(&b'.') {
        out.extend_from_slice(b".0");
    }
}

/// The text of finite `x` as [`write_shortest`] writes it, when that is zmij's own text:
/// between 1e-4 and 1e15 (and at zero) zmij writes `I.F`, an integer as `I.0`, already the
/// layout wanted, taken as it is without looking for an exponent or a point (the general
/// layout is the reference; tested equal on millions of values either side of both ends).
/// `None` elsewhere.
#[inline]
fn zmij_as_is(x: f64, buf: &mut zmij::Buffer) -> Option<&[u8]> {
    let a = x.abs();
    ((1e-4..1e15).contains(&a) || a.to_bits() == 0).then(|| buf.format_finite(x).as_bytes())
}

/// Copies `src` (at most [`SHORT`] bytes) to the start of `dst` (at least [`SHORT`] bytes)
/// with fixed-size moves, two that overlap for the lengths between (no call of `memcpy` for
/// a number's few bytes).
#[inline(always)]
fn copy_short(dst: &mut [u8], src: &[u8]) {
    let n = src.len();
    let dst = &mut dst[..SHORT];
    if n >= 16 {
        dst[..16].copy_from_slice(&src[..16]);
        dst[n - 16..n].copy_from_slice(&src[n - 16..]);
    } else if n >= 8 {
        dst[..8].copy_from_slice(&src[..8]);
        dst[n - 8..n].copy_from_slice(&src[n - 8..]);
    } else if n >= 4 {
        dst[..4].copy_from_slice(&src[..4]);
        dst[n - 4..n].copy_from_slice(&src[n - 4..]);
    } else {
        for (d, &b) in dst.iter_mut().zip(src) {
            *d = b;
        }
    }
}

/// The longest text [`copy_short`] copies (a number's text has at most 24 bytes).
const SHORT: usize = 32;

/// Appends the shortest-digits `text` of a finite number, as zmij or ryu write it (`I[.F]` or
/// `I[.F]e[±]E`), in `Display`'s layout (no exponent, no `.0` on an integer).
#[inline]
fn lay_out(text: &[u8], out: &mut Vec<u8>) {
    // Without an exponent the text is Display's, except that an integer ends in `.0`.
    if !text.contains(&b'e') {
        out.extend_from_slice(text.strip_suffix(b".0").unwrap_or(text));
        return;
    }
    lay_out_exponent(text, out);
}

/// [`lay_out`] for a text with an exponent (rare: |x| < 1e-5 or ≥ 1e16).
#[cold]
fn lay_out_exponent(text: &[u8], out: &mut Vec<u8>) {
    let (negative, text) = match text.split_first() {
        Some((b'-', rest)) => (true, rest),
        _ => (false, text),
    };
    // With an exponent, ryu writes `I[.F]eE`: the digits are I then F; the decimal point sits
    // after |I| + E of them.
    let (mantissa, exponent) = match text.iter().position(|&b| b == b'e') {
        Some(i) => (&text[..i], parse_exponent(&text[i + 1..])),
        None => (text, 0),
    };
    let (int, frac) = match mantissa.iter().position(|&b| b == b'.') {
        Some(i) => (&mantissa[..i], &mantissa[i + 1..]),
        None => (mantissa, &mantissa[..0]),
    };
    let mut digits = [0u8; 40];
    let mut n = 0;
    for &d in int.iter().chain(frac) {
        if n < digits.len() {
            digits[n] = d;
            n += 1;
        }
    }
    let mut point = int.len() as i64 + exponent;
    // Leading zeros move the point; trailing zeros are dropped.
    let mut start = 0;
    while start < n && digits[start] == b'0' {
        start += 1;
        point -= 1;
    }
    while n > start && digits[n - 1] == b'0' {
        n -= 1;
    }
    if negative {
        out.push(b'-');
    }
    let d = &digits[start..n];
    if d.is_empty() {
        out.push(b'0');
        return;
    }
    if point <= 0 {
        out.extend_from_slice(b"0.");
        out.extend(std::iter::repeat_n(b'0', point.unsigned_abs() as usize));
        out.extend_from_slice(d);
    } else if point as usize >= d.len() {
        out.extend_from_slice(d);
        out.extend(std::iter::repeat_n(b'0', point as usize - d.len()));
    } else {
        let (a, b) = d.split_at(point as usize);
        out.extend_from_slice(a);
        out.push(b'.');
        out.extend_from_slice(b);
    }
}

/// Rows of numeric CSV cells gathered as text in a reused byte buffer: the text a
/// `csv::Writer` in biasctl's dialect (`log::csv_writer`) writes for the same cells, without its
/// per-field quoting scan — a number's text ([`write_shortest`]: digits, `-`, `.`) never needs
/// quoting, and every row has several cells, so an empty cell is written empty. A non-finite
/// value is written as an empty cell, never as text. Nothing is allocated per row.
/// [`NumberRows`] hands the text to a writer in pieces; `predict`'s formatting thread hands
/// whole chunks of it on ([`RowText::take`]).
pub(crate) struct RowText {
    /// The gathered text is `buf[..len]`; the rest is room (initialised, its contents unused),
    /// so a number is copied in with fixed-size moves ([`copy_short`]).
    buf: Vec<u8>,
    len: usize,
    /// A number outside [`zmij_as_is`]'s range, laid out by [`write_shortest`].
    scratch: Vec<u8>,
    row_start: bool,
}

/// Values [`RowText::cells`] formats before it copies their texts.
const BATCH: usize = 8;

impl RowText {
    /// An empty text with room for about `room` bytes before it grows.
    pub(crate) fn new(room: usize) -> Self {
        Self {
            buf: vec![0; room.max(BATCH * (SHORT + 1))],
            len: 0,
            scratch: Vec::new(),
            row_start: true,
        }
    }

    /// The rows gathered so far.
    pub(crate) fn text(&self) -> &[u8] {
        &self.buf[..self.len]
    }

    /// Forgets the gathered rows (keeps the room).
    pub(crate) fn clear(&mut self) {
        self.len = 0;
    }

    /// The gathered rows as a vector of their length; gathering goes on in `room` (any vector,
    /// its contents unused: one taken before, handed back to be reused).
    pub(crate) fn take(&mut self, mut room: Vec<u8>) -> Vec<u8> {
        room.resize(room.capacity().max(BATCH * (SHORT + 1)), 0);
        let mut text = std::mem::replace(&mut self.buf, room);
        text.truncate(self.len);
        self.len = 0;
        text
    }

    /// Appends one cell per value of `xs`: its text ([`write_shortest`]), or nothing for NaN or
    /// another non-finite value (an empty cell); cells are separated by `,`. The values are
    /// formatted in batches of [`BATCH`], each into its own buffer, and copied after the batch:
    /// a number's bytes are read back long after zmij stored them, not while its stores are
    /// still on their way (a read of 16 bytes over stores of a few bytes each must wait for
    /// them: at the copy right after the formatting, that wait was a third of the row writer's
    /// time).
    #[inline]
    pub(crate) fn cells(&mut self, xs: &[f64]) {
        let mut bufs = [(); BATCH].map(|_| zmij::Buffer::new());
        for batch in xs.chunks(BATCH) {
            // Room for every cell of the batch, with its comma and the fixed-size moves.
            if self.len + BATCH * (SHORT + 1) > self.buf.len() {
                self.buf.resize(2 * self.buf.len() + BATCH * (SHORT + 1), 0);
            }
            let mut texts: [Option<&[u8]>; BATCH] = [None; BATCH];
            for ((t, b), &v) in texts.iter_mut().zip(bufs.iter_mut()).zip(batch) {
                if v.is_finite() {
                    *t = zmij_as_is(v, b);
                }
            }
            for (t, &v) in texts.iter().zip(batch) {
                if !self.row_start {
                    self.buf[self.len] = b',';
                    self.len += 1;
                }
                self.row_start = false;
                match t {
                    Some(text) => {
                        copy_short(&mut self.buf[self.len..], text);
                        self.len += text.len();
                    }
                    None if v.is_finite() => {
                        self.scratch.clear();
                        write_shortest(v, &mut self.scratch);
                        self.write(self.scratch.len());
                    }
                    None => {}
                }
            }
        }
    }

    /// Appends `scratch[..n]` to the gathered text.
    fn write(&mut self, n: usize) {
        if self.len + n + SHORT > self.buf.len() {
            self.buf.resize(2 * (self.len + n + SHORT), 0);
        }
        self.buf[self.len..self.len + n].copy_from_slice(&self.scratch[..n]);
        self.len += n;
    }

    /// Ends the row (`\n`).
    #[inline]
    pub(crate) fn end_row(&mut self) {
        if self.len == self.buf.len() {
            self.buf.resize(2 * self.buf.len(), 0);
        }
        self.buf[self.len] = b'\n';
        self.len += 1;
        self.row_start = true;
    }
}

/// [`RowText`] rows handed to `out` in pieces of about 64 KiB.
pub(crate) struct NumberRows<'a> {
    out: &'a mut dyn std::io::Write,
    text: RowText,
}

/// Bytes gathered before [`NumberRows`] hands them on.
const ROWS_FLUSH_AT: usize = 1 << 16;

impl<'a> NumberRows<'a> {
    /// Writes rows to `out`.
    pub(crate) fn new(out: &'a mut dyn std::io::Write) -> Self {
        Self {
            out,
            text: RowText::new(ROWS_FLUSH_AT + 4096),
        }
    }

    /// Appends one cell per value of `xs` ([`RowText::cells`]).
    #[inline]
    pub(crate) fn cells(&mut self, xs: &[f64]) {
        self.text.cells(xs);
    }

    /// Ends the row (`\n`); hands the gathered rows on when there are enough.
    #[inline]
    pub(crate) fn end_row(&mut self) -> std::io::Result<()> {
        self.text.end_row();
        if self.text.len >= ROWS_FLUSH_AT {
            self.out.write_all(self.text.text())?;
            self.text.clear();
        }
        Ok(())
    }

    /// Hands every gathered row on and flushes `out`.
    pub(crate) fn flush(&mut self) -> std::io::Result<()> {
        self.out.write_all(self.text.text())?;
        self.text.clear();
        self.out.flush()
    }
}

/// The signed decimal exponent ryu wrote after `e` (at most three digits).
fn parse_exponent(text: &[u8]) -> i64 {
    let (sign, digits) = match text.split_first() {
        Some((b'-', rest)) => (-1, rest),
        Some((b'+', rest)) => (1, rest),
        _ => (1, text),
    };
    sign * digits
        .iter()
        .fold(0i64, |acc, &d| acc * 10 + i64::from(d.wrapping_sub(b'0')))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::rng::SimRng;

    fn text(x: f64) -> String {
        let mut out = Vec::new();
        write_shortest(x, &mut out);
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn equals_display_on_edge_cases_and_random_bit_patterns() {
        // Reference: Rust's own `Display` (`to_string()`), which the predict CSV used before, and
        // `str::parse` reading the text back.
        let mut xs = vec![
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.1,
            1e-7,
            -1.5e-7,
            1e15,
            1e16,
            1.5e20,
            123456.789,
            f64::MAX,
            f64::MIN,
            f64::MIN_POSITIVE,
            5e-324,
            -5e-324,
            0.30000000000000004,
            1e300,
            2.5e-300,
            1e-5,
            1e-4,
            f64::from_bits(1e16_f64.to_bits() - 1), // the largest double below 1e16
        ];
        let mut rng = SimRng::new(16);
        for _ in 0..100_000 {
            // Uniform bit patterns cover every exponent; decimal-looking values cover logs.
            xs.push(f64::from_bits(rng.next_u64()));
            xs.push(rng.below(1_000_000) as f64 / 1000.0 - 500.0);
            xs.push(rng.range(-1e6, 1e6));
            xs.push(rng.range(-1.0, 1.0) * 10f64.powi(rng.below(60) as i32 - 30));
        }
        let mut ties = 0;
        let n = xs.len();
        for x in xs.into_iter().filter(|x| x.is_finite()) {
            let display = x.to_string();
            // Display's text, with `.0` on a whole number.
            let display = if display.contains('.') {
                display
            } else {
                display + ".0"
            };
            let mine = text(x);
            // Reads back as exactly x, in Display's layout and length.
            let back: f64 = mine.parse().unwrap();
            assert_eq!(
                back.to_bits(),
                x.to_bits(),
                "{mine} for bits {:#x}",
                x.to_bits()
            );
            assert!(
                !mine.contains('e') && mine.len() == display.len(),
                "{mine} vs {display}"
            );
            if mine != display {
                // Only the halfway case: the texts differ in the last digit, by one.
                let (a, b) = (mine.as_bytes(), display.as_bytes());
                let k = a.len() - 1;
                assert!(
                    a[..k] == b[..k] && a[k].abs_diff(b[k]) == 1,
                    "{mine} vs {display}"
                );
                ties += 1;
            }
        }
        assert!(ties * 1000 < n, "{ties} of {n} differ from Display");
    }

    /// Reference: the same layout fed by `ryu` (what `write_shortest` used before zmij): the
    /// text must be the same byte for byte, so predict's CSV stays the same file.
    #[test]
    fn zmij_text_equals_the_ryu_text() {
        let ryu_text = |x: f64| {
            let mut out = Vec::new();
            lay_out(ryu::Buffer::new().format_finite(x).as_bytes(), &mut out);
            if !out.contains(&b'.') {
                out.extend_from_slice(b".0");
            }
            String::from_utf8(out).unwrap()
        };
        let mut rng = SimRng::new(61);
        let mut checked = 0;
        for k in 0..600_000u64 {
            let xs = [
                f64::from_bits(rng.next_u64()),
                rng.below(100_000_000) as f64 / 10_000.0 - 5000.0,
                rng.range(-1.0, 1.0) * 10f64.powi(rng.below(44) as i32 - 22),
                // Halfway-prone: integers near 2^53 and values with few significant bits.
                (rng.below(1 << 20) as f64 + 0.25) * 2f64.powi((k % 80) as i32 - 20),
                // Either side of the ends of the copied range (1e-4, 1e15), and whole numbers.
                [1e-4, 1e15][(k % 2) as usize] * (1.0 + rng.range(-1e-3, 1e-3)),
                f64::from_bits(
                    [1e-4f64, 1e15][(k % 2) as usize]
                        .to_bits()
                        .wrapping_add(rng.below(9))
                        .wrapping_sub(4),
                ),
                -(rng.below(1 << 50) as f64),
            ];
            for x in xs.into_iter().filter(|x| x.is_finite()) {
                assert_eq!(text(x), ryu_text(x), "bits {:#x}", x.to_bits());
                checked += 1;
            }
        }
        assert!(checked > 4_000_000);
    }

    #[test]
    fn number_rows_equal_cells_written_one_by_one() {
        // Reference: `write_shortest` of each cell (an empty cell for NaN), `,` between cells, `\n` after each row,
        // collected in one vector. Rows of every kind of cell (empty, non-finite, zeros,
        // numbers in and out of the copied range, the longest texts), many times the flush
        // size, handed on in pieces to a writer that keeps them.
        let mut rng = SimRng::new(53);
        let (mut want, mut got) = (Vec::new(), Vec::new());
        {
            let mut rows = NumberRows::new(&mut got);
            let mut cells = Vec::new();
            let (mut text, mut taken, mut spare) = (RowText::new(64), Vec::new(), Vec::new());
            for r in 0..60_000 {
                cells.clear();
                for c in 0..1 + r % 23 {
                    let x = match rng.below(9) {
                        0 => None,
                        1 => Some([f64::NAN, f64::INFINITY, 0.0, -0.0][rng.below(4) as usize]),
                        2 => Some(f64::from_bits(rng.next_u64())),
                        3 => Some(-2.2250738585072014e-308),
                        4 => Some(rng.below(5000) as f64),
                        5 => Some(rng.range(-1.0, 1.0) * 10f64.powi(rng.below(40) as i32 - 20)),
                        _ => Some(rng.range(-500.0, 500.0)),
                    };
                    if c > 0 {
                        want.push(b',');
                    }
                    if let Some(v) = x {
                        write_shortest(v, &mut want);
                    }
                    cells.push(x.unwrap_or(f64::NAN));
                }
                // A row in one call or in two (the second may be empty).
                let (a, b) = cells.split_at(if r % 3 == 0 { r % cells.len() } else { 0 });
                rows.cells(a);
                rows.cells(b);
                want.push(b'\n');
                rows.end_row().unwrap();
                // The same rows gathered in a `RowText` and taken every 37 rows, the taken
                // vector handed back as room.
                text.cells(a);
                text.cells(b);
                text.end_row();
                if r % 37 == 0 {
                    let t = text.take(std::mem::take(&mut spare));
                    taken.extend_from_slice(&t);
                    spare = t;
                }
            }
            rows.flush().unwrap();
            taken.extend_from_slice(text.text());
            assert!(
                taken == want,
                "the taken rows differ from the cells written one by one"
            );
        }
        assert!(want.len() > 10 * ROWS_FLUSH_AT, "{}", want.len());
        assert!(
            got == want,
            "the rows differ from the cells written one by one"
        );
    }

    #[test]
    fn non_finite_writes_nothing() {
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(text(x), "");
        }
    }
}
