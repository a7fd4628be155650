//! The computation of a report, with no HTML in it: [`DemoRun`] (the built-in drive) and
//! [`DataRun`] (a user's log) hold every log, fitted model, score, diagnosis, ladder, discovery
//! and settle analysis a report shows. The sections ([`super::sections`]) turn a run into HTML;
//! [`super::story`] computes a run, writes its files and assembles the sections.
//!
//! Steps a run cannot take on the data at hand (too few rows, a model that does not fit) are
//! kept as `Err(message)` in the run, so the page can say why; errors that make the whole run
//! meaningless (a simulation that fails, the built-in drive's models that do not fit) are
//! [`StoryError`]s.

mod data;
mod demo;
mod error;
mod options;
mod runs;
mod steps;

pub use data::compute_data;
pub(crate) use data::{DATA_MODELS, DATA_STEPS, data_run};
pub use demo::compute_demo;
pub(crate) use demo::{DEMO_STEPS, DISCOVER_TRAIN, STORY_MODELS, demo_run};
pub use error::StoryError;
pub(crate) use error::error_chain;
pub use options::{CheckedStoryOptions, MAX_SEEKS, Progress, StoryOptions};
pub(crate) use runs::Step;
pub use runs::{DataRun, DemoRun, DiagnosedRun, PaperRobustWhy, ScoredModel, SettleRun};
pub(crate) use steps::{DISCOVER_START, Steps};

#[cfg(test)]
mod tests;
