//! Two small value helpers shared by the feature table, the smoother and the messages: NaN as
//! the mark of an undefined value, and a number written in about four significant digits.

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
