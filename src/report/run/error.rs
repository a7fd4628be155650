//! Why a story run fails as a whole ([`StoryError`]), and an error's causes as one line.

use crate::control::ServoError;
use crate::control::settle::{AnalyseError, SettleError};
use crate::diagnose::ModelDiagnosisError;
use crate::field::Field;
use crate::fit::FitError;
use crate::io::OutputError;
use crate::log::LogError;
use crate::model::{ModelError, SpecError};
use crate::score::ScoreError;
use crate::sim::SimError;

/// Why a story could not be told.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StoryError {
    /// A story setting is out of range ([`StoryOptions::check`](super::StoryOptions::check)).
    #[error("{field} {message}")]
    InvalidConfig {
        /// The setting.
        field: Field,
        /// The value, what is wrong and what is allowed.
        message: String,
    },
    /// A simulation setting was rejected.
    #[error("simulation setting")]
    SimConfig(#[from] crate::sim::ConfigError),
    /// A simulation failed.
    #[error("simulation")]
    Sim(#[from] SimError),
    /// A log could not be read back.
    #[error("reading a log")]
    Log(#[from] LogError),
    /// A model spec was rejected.
    #[error("model spec")]
    Spec(#[from] SpecError),
    /// A model could not be fitted.
    #[error("fitting `{model}` on {file}")]
    Fit {
        /// The model.
        model: String,
        /// The training log.
        file: String,
        /// Why.
        #[source]
        source: Box<FitError>,
    },
    /// A model could not be replayed.
    #[error("replaying a model")]
    Model(#[from] ModelError),
    /// A score could not be computed.
    #[error("scoring")]
    Score(#[from] ScoreError),
    /// The diagnosis or the ladder failed.
    #[error("diagnosis")]
    Diagnose(#[from] ModelDiagnosisError),
    /// The settle preset is not valid.
    #[error("settle preset")]
    SettleConfig(#[from] crate::control::settle::ConfigError),
    /// The settle analysis failed.
    #[error("settle analysis")]
    Analyse(#[from] AnalyseError),
    /// The worst-case settle computation failed.
    #[error("worst-case settle")]
    Settle(#[from] SettleError),
    /// The controller could not be designed.
    #[error("controller design")]
    Servo(#[from] ServoError),
    /// A file could not be written.
    #[error("writing the report")]
    Output(#[from] OutputError),
}

/// The error and its causes on one line.
pub(crate) fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cur = e.source();
    while let Some(c) = cur {
        s.push_str(": ");
        s.push_str(&c.to_string());
        cur = c.source();
    }
    s
}
