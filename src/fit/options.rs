//! The fit's settings: [`FitOptions`] as given, checked once into the [`CheckedFitOptions`]
//! that [`fit`](fn@crate::fit::fit) accepts.

use crate::field::Field;
use crate::model::data::FitError;

/// Fit settings as given (unchecked). [`FitOptions::check`] validates them once into the
/// [`CheckedFitOptions`] that [`fit`](fn@crate::fit::fit) accepts (linfa's `ParamGuard` pattern).
///
/// ```
/// use biasctl::FitOptions;
/// let opts = FitOptions { grid: 48, ..FitOptions::default() }.check().unwrap();
/// assert_eq!(opts.grid, 48);
/// assert!(FitOptions { rank_tolerance: f64::NAN, ..FitOptions::default() }.check().is_err());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct FitOptions {
    /// Relative size of an `R` diagonal below which a column is called undetermined; in (0, 1)
    /// (default 1e-9).
    pub rank_tolerance: f64,
    /// Grid points of the nonlinear search before golden-section refinement, 3..=10000
    /// (default 24).
    pub grid: usize,
    /// Golden-section iterations, 0..=1000 (default 40).
    pub refine: usize,
    /// How the direction of motion is read (`--deadband X`, `--velocity-col NAME`; default:
    /// a deadband estimated from the position noise on a dense time series, raw steps on a
    /// log of seeks). The fitted model records what it resolved to.
    pub direction: crate::history::DirectionSetting,
}

impl FitOptions {
    /// Checks every setting's range; the error names the setting and what is allowed.
    pub fn check(self) -> Result<CheckedFitOptions, FitError> {
        let bad = |field, message: String| Err(FitError::InvalidOptions { field, message });
        if !(self.rank_tolerance > 0.0 && self.rank_tolerance < 1.0) {
            return bad(
                Field::RankTolerance,
                format!("{} is not in (0, 1)", self.rank_tolerance),
            );
        }
        if !(3..=10_000).contains(&self.grid) {
            return bad(Field::Grid, format!("{} is not in 3..=10000", self.grid));
        }
        if self.refine > 1000 {
            return bad(Field::Refine, format!("{} is not in 0..=1000", self.refine));
        }
        self.direction.validate()?;
        Ok(CheckedFitOptions(self))
    }
}

checked_settings! {
    /// Fit settings that passed [`FitOptions::check`]; the only settings
    /// [`fit`](fn@crate::fit::fit) accepts. Read them through `Deref` ([`FitOptions`]'s fields).
    /// `Default` is the checked default.
    #[derive(Debug, Clone, PartialEq, Default)]
    pub struct CheckedFitOptions(FitOptions);
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            rank_tolerance: 1e-9,
            grid: 24,
            refine: 40,
            direction: crate::history::DirectionSetting::Auto,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_options_check_names_the_bad_setting() {
        // Reference: the documented ranges; the default passes and equals the checked default.
        assert_eq!(
            FitOptions::default().check().unwrap(),
            CheckedFitOptions::default()
        );
        for (opts, field) in [
            (
                FitOptions {
                    rank_tolerance: 0.0,
                    ..FitOptions::default()
                },
                "rank_tolerance",
            ),
            (
                FitOptions {
                    rank_tolerance: f64::INFINITY,
                    ..FitOptions::default()
                },
                "rank_tolerance",
            ),
            (
                FitOptions {
                    grid: 2,
                    ..FitOptions::default()
                },
                "grid",
            ),
            (
                FitOptions {
                    refine: 1001,
                    ..FitOptions::default()
                },
                "refine",
            ),
        ] {
            match opts.check() {
                Err(FitError::InvalidOptions { field: f, .. }) => {
                    assert_eq!(f.name().rsplit("::").next(), Some(field))
                }
                other => panic!("{field}: {other:?}"),
            }
        }
    }
}
