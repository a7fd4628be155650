//! The CSV dialect a log is read in: the delimiter (`,` `;` or tab, sniffed from the header
//! unless named), and the numbers of its cells (a decimal comma in a `;`- or tab-separated
//! file).

/// The delimiters the reader sniffs and `--delimiter` accepts, with their names.
pub(crate) const DELIMITERS: [(u8, &str); 3] =
    [(b',', "comma"), (b';', "semicolon"), (b'\t', "tab")];

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
pub(super) fn parse_field(raw: &[u8], decimal_comma: bool) -> Result<Option<f64>, ()> {
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

/// The note told when the fields are not separated by commas: the delimiter's name, and
/// whether it was sniffed (`given`: named by [`ColumnMap::delimiter`](super::ColumnMap::delimiter)).
pub(super) fn delimiter_note(file: &str, delimiter: u8, given: bool) -> Option<String> {
    if delimiter == b',' {
        return None;
    }
    let name = DELIMITERS
        .iter()
        .find(|d| d.0 == delimiter)
        .map_or("other", |d| d.1);
    Some(format!(
        "{file}: fields separated by {name} (`{}`){}",
        (delimiter as char).escape_default(),
        if given {
            ""
        } else {
            ", sniffed from the header; a comma in a number is its decimal separator"
        }
    ))
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // values parsed from short decimal text compare exactly
mod tests {
    use super::*;

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
}
