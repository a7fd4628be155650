//! The errors of a settle analysis: an out-of-range setting, an invalid description, a failed
//! analysis.

use super::spec::PRESETS;
use crate::control::ServoError;
use crate::control::plant::PlantError;

/// A settle window or handoff setting that is out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SettleError {
    /// A value is out of range; names the setting.
    #[error("{field} must be {what}, got {value}")]
    Invalid {
        /// The setting.
        field: crate::field::Field,
        /// The accepted range.
        what: &'static str,
        /// The value given.
        value: f64,
    },
    /// A caller-provided buffer does not fit the table's horizon.
    #[error("bounds buffer holds {got} samples, the table's horizon is {want}")]
    BufferLength {
        /// Buffer length.
        got: usize,
        /// Horizon of the table.
        want: usize,
    },
}

/// An invalid settle description (plant TOML or preset plus flags).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// Unknown preset name.
    #[error(
        "unknown preset `{0}`{hint} (known: {names})",
        hint = crate::io::words::did_you_mean(.0, PRESETS),
        names = PRESETS.join(", ")
    )]
    UnknownPreset(String),
    /// The plant part is invalid.
    #[error("invalid plant: {0}")]
    Plant(#[from] PlantError),
    /// The LQR weights are invalid.
    #[error("invalid weights: {0}")]
    Weights(ServoError),
    /// The settle part is invalid.
    #[error("invalid settle settings: {0}")]
    Settle(#[from] SettleError),
}

/// Why a settle analysis failed after validation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum AnalyseError {
    /// The controller could not be designed (for example an unstabilisable plant).
    #[error(transparent)]
    Servo(#[from] ServoError),
    /// The settle computation rejected a setting.
    #[error(transparent)]
    Settle(#[from] SettleError),
}

/// A plant TOML file that cannot be read or parsed ([`super::SettleSpec::from_toml_file`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlantFileError {
    /// The file could not be read (or is larger than biasctl reads).
    #[error("cannot read plant file {file}")]
    Io {
        /// The plant file.
        file: String,
        /// The operating-system error.
        #[source]
        source: std::io::Error,
    },
    /// The TOML is malformed, a number is out of range, or a field is missing or unknown.
    #[error("invalid plant file {file}")]
    Parse {
        /// The plant file.
        file: String,
        /// The parser's message (names the field and line).
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}
