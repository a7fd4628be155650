//! Finite out: no writer emits `NaN`, `inf` or a JSON `null` standing for one. Numbers are
//! checked where they are made ([`check_finite`], naming the row and column) and, as a last
//! guard, whole texts before they are written ([`check_text`]).

/// A non-finite number met on its way out: an internal overflow (or a model or input that the
/// readers should have refused). Names what it was (row and column, or the file).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
#[error("{what} is {value}, not a finite number (the arithmetic overflowed); nothing was written")]
pub struct NonFinite {
    /// Where the number was: `row 12 (line 14), column `poly2``, or the output's name.
    pub what: String,
    /// The value (`NaN`, `inf` or `-inf`).
    pub value: f64,
}

/// `Ok(value)` if it is finite, else a [`NonFinite`] naming it by `what()` (called only then).
pub(crate) fn check_finite(value: f64, what: impl FnOnce() -> String) -> Result<f64, NonFinite> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(NonFinite {
            what: what(),
            value,
        })
    }
}

/// Checks a text about to be written (`what` names it: a file or `stdout`) for a number Rust
/// formats as `NaN`, `inf` or `-inf`: a whole word, so `info` or `Infinity` in prose pass.
pub fn check_text(text: &str, what: &str) -> Result<(), NonFinite> {
    let bad = text
        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .find_map(|w| match w {
            "NaN" => Some(f64::NAN),
            "inf" => Some(f64::INFINITY),
            _ => None,
        });
    match bad {
        None => Ok(()),
        Some(value) => Err(NonFinite {
            what: format!("a number in {what}"),
            value,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_text_finds_formatted_non_finite_numbers_only() {
        // Reference: Rust's own formatting of the three non-finite values.
        for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let svg = format!("<circle cx=\"{v}\" cy=\"1\"/>");
            assert!(check_text(&svg, "fig.svg").is_err(), "{svg}");
            let csv = format!("1,{v:.4},2\n");
            assert!(check_text(&csv, "p.csv").is_err(), "{csv}");
        }
        check_text("info: Infinity and NaNa are words; 1e308 is a number", "x").unwrap();
        assert!(check_finite(1.0, || "x".into()).is_ok());
        let e = check_finite(f64::NAN, || "row 3, column `poly2`".into()).unwrap_err();
        assert!(
            e.to_string().contains("row 3, column `poly2` is NaN"),
            "{e}"
        );
    }
}
