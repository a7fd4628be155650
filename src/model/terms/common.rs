//! What several terms share: finding a covariate's column, and the checks a saved setting
//! passes when a model file is read back.

use crate::model::ModelError;

/// Reads a setting that must be finite and > 0 (a scale): a model file with 0, a negative or an
/// overflowing value is refused at load instead of predicting `NaN`.
pub(crate) fn positive_finite<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    let v = <f64 as serde::Deserialize>::deserialize(d)?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(serde::de::Error::custom(format!(
            "{v} must be finite and > 0"
        )))
    }
}

/// Reads rates that must each lie in [0, 1) (Dahl / Maxwell-slip elements; 0 is an element
/// whose characteristic length is below the float resolution of `exp(−1/L)`).
pub(crate) fn unit_rates<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
    let v = <Vec<f64> as serde::Deserialize>::deserialize(d)?;
    match v.iter().find(|r| !(**r >= 0.0 && **r < 1.0)) {
        None => Ok(v),
        Some(r) => Err(serde::de::Error::custom(format!(
            "rate {r} must lie in [0, 1)"
        ))),
    }
}

/// Position of covariate `column` among `names`, or the error a model reports for it.
pub fn covariate_position(names: &[String], column: &str, term: &str) -> Result<usize, ModelError> {
    names
        .iter()
        .position(|n| n == column)
        .ok_or_else(|| ModelError::MissingCovariate {
            term: term.to_string(),
            column: column.to_string(),
            available: if names.is_empty() {
                "none".into()
            } else {
                names.join(", ")
            },
        })
}
