//! Text and number layout: the font metrics the layout assumes, compact number formatting and
//! XML escaping.

use crate::log::fmt_trimmed;

pub(super) const FONT: f64 = 12.0;

pub(super) const CHAR_W: f64 = 0.6 * FONT;

/// A compact number: up to four significant digits, trailing zeros removed, exponent form for
/// magnitudes of a million and more or below 0.001; `"n/a"` for non-finite values.
pub fn fmt_num(x: f64) -> String {
    if !x.is_finite() {
        return "n/a".into();
    }
    let a = x.abs();
    if a < 1e-300 {
        return "0".into();
    }
    if !(1e-3..1e6).contains(&a) {
        let s = format!("{x:.3e}");
        let (mantissa, exp) = s.split_once('e').unwrap_or((&s, "0"));
        let mantissa = if mantissa.contains('.') {
            mantissa.trim_end_matches('0').trim_end_matches('.')
        } else {
            mantissa
        };
        return format!("{mantissa}e{exp}");
    }
    let decimals = (3.0 - a.log10().floor()).clamp(0.0, 6.0) as usize;
    fmt_trimmed(x, decimals)
}

/// A pixel coordinate: at most two decimals.
pub(super) fn n(x: f64) -> String {
    fmt_trimmed(x, 2)
}

pub(super) fn text_width(s: &str, size: f64) -> f64 {
    s.chars().count() as f64 * CHAR_W * size / FONT
}

/// Escapes text for XML/HTML content and attribute values.
pub(crate) fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c if (c as u32) < 0x20 && c != '\n' && c != '\t' => out.push(' '),
            c => out.push(c),
        }
    }
    out
}
