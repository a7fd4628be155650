//! Small value helpers shared by the feature table, the smoother and the messages: NaN as
//! the mark of an undefined value, a number written in about four significant digits, and a
//! figure beside the bar it failed, written so the two differ.

/// `Some(x)` unless `x` is NaN, the mark of an undefined value in a [`FeatureColumn`](super::FeatureColumn).
#[inline]
pub(crate) fn defined(x: f64) -> Option<f64> {
    (!x.is_nan()).then_some(x)
}

/// A number with about four significant digits for messages.
pub(crate) fn short(x: f64) -> String {
    let a = x.abs();
    if a >= 1000.0 || a <= 0.0 {
        format!("{x:.0}")
    } else if a >= 10.0 {
        format!("{x:.1}")
    } else if a >= 0.1 {
        format!("{x:.3}")
    } else {
        format!("{x:.2e}")
    }
}

/// `value` and the `bar` it is compared with, each × `scale` with `decimals` decimals, or more
/// (up to three more) while the two texts are equal but the numbers are not: a verdict never
/// reads "2.0 % … below the practical minimum of 2.0 %" for a gain of 1.96 %.
pub(crate) fn apart(value: f64, bar: f64, scale: f64, decimals: usize) -> (String, String) {
    let fmt = |x: f64, d: usize| format!("{:.*}", d, scale * x);
    let mut d = decimals;
    while d < decimals + 3 && value.total_cmp(&bar).is_ne() && fmt(value, d) == fmt(bar, d) {
        d += 1;
    }
    (fmt(value, d), fmt(bar, d))
}

#[cfg(test)]
mod tests {
    use super::apart;

    #[test]
    fn a_figure_and_its_bar_are_written_apart() {
        // Reference: the values themselves, 1.96 % < 2 % and z 1.996 < 2.
        assert_eq!(
            apart(0.0196, 0.02, 100.0, 1),
            ("1.96".into(), "2.00".into())
        );
        assert_eq!(apart(1.996, 2.0, 1.0, 1), ("1.996".into(), "2.000".into()));
        assert_eq!(apart(0.012, 0.02, 100.0, 1), ("1.2".into(), "2.0".into()));
        assert_eq!(apart(0.02, 0.02, 100.0, 1), ("2.0".into(), "2.0".into()));
        // At most three more decimals.
        assert_eq!(
            apart(0.0199999999, 0.02, 100.0, 1),
            ("2.0000".into(), "2.0000".into())
        );
    }
}
