//! How a story run is set up ([`StoryOptions`], checked into [`CheckedStoryOptions`], and the
//! diagnosis settings it implies) and how it reports its progress.

use super::error::StoryError;
use crate::control::settle::SettleSpec;
use crate::diagnose::{CheckedDiagnoseConfig, DiagnoseConfig, ModelDiagnosisError};
use crate::field::Field;

/// Settings of a story run.
#[derive(Debug, Clone, PartialEq)]
pub struct StoryOptions {
    /// Seed of every simulation and of the diagnosis (printed in the report).
    pub seed: u64,
    /// Random seeks of the test run and of the calibration run's random tail (default 2000).
    pub random_seeks: u64,
    /// Permutations of the diagnosis' significance test (default 199).
    pub permutations: usize,
    /// Settle preset (default `paper1997`).
    pub settle_preset: String,
}

impl Default for StoryOptions {
    fn default() -> Self {
        StoryOptions {
            seed: 1,
            random_seeks: crate::sim::DEFAULT_N,
            permutations: 199,
            settle_preset: "paper1997".into(),
        }
    }
}

/// Largest [`StoryOptions::random_seeks`]: keeps the in-memory logs (and the files beside the
/// report) to a few hundred MB.
pub const MAX_SEEKS: u64 = 1_000_000;

impl StoryOptions {
    /// Checks every setting once, before anything runs: `random_seeks` from the diagnosis' minimum
    /// of measured rows ([`DiagnoseConfig::min_rows`]) to [`MAX_SEEKS`], `permutations` as
    /// the diagnosis accepts them (with the default `alpha`), and `settle_preset` a known preset
    /// ([`SettleSpec::preset`]). Any `seed` is valid.
    pub fn check(self) -> Result<CheckedStoryOptions, StoryError> {
        // The diagnosis of the test run needs its cross-validation's minimum of measured rows.
        let min = DiagnoseConfig::default().min_rows() as u64;
        if !(min..=MAX_SEEKS).contains(&self.random_seeks) {
            return Err(StoryError::InvalidConfig {
                field: Field::RandomSeeks,
                message: format!(
                    "{}: give {min} to {MAX_SEEKS} random seeks (the diagnosis of the test run \
                     needs at least {min} measured rows)",
                    self.random_seeks
                ),
            });
        }
        if let Err(e) = diagnose_config(&self) {
            return Err(StoryError::InvalidConfig {
                field: Field::StoryPermutations,
                message: format!("{}: {}", self.permutations, crate::io::message(&e)),
            });
        }
        if let Err(e) = SettleSpec::preset(&self.settle_preset) {
            return Err(StoryError::InvalidConfig {
                field: Field::SettlePreset,
                message: crate::io::message(&e),
            });
        }
        Ok(CheckedStoryOptions(self))
    }

    /// A smaller, faster run (300 random seeks, 99 permutations) for tests and quick looks.
    pub fn quick(seed: u64) -> Self {
        StoryOptions {
            seed,
            random_seeks: 300,
            permutations: 99,
            ..Default::default()
        }
    }
}

checked_settings! {
    /// Settings that passed [`StoryOptions::check`]; read them through `Deref`. `Default` is the
    /// checked default. The story's entry points ([`crate::demo_report`], [`crate::data_report`],
    /// [`compute_demo`](super::compute_demo), [`compute_data`](super::compute_data)) accept
    /// only these.
    #[derive(Debug, Clone, PartialEq, Default)]
    pub struct CheckedStoryOptions(StoryOptions);
}

/// One progress report: step `done` of `total` is starting, described by `step`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress<'a> {
    /// What is being done now.
    pub step: &'a str,
    /// Steps finished so far.
    pub done: usize,
    /// Steps in all.
    pub total: usize,
}

pub(super) fn diagnose_config(
    opts: &StoryOptions,
) -> Result<CheckedDiagnoseConfig, ModelDiagnosisError> {
    let config = DiagnoseConfig {
        permutations: opts.permutations,
        seed: opts.seed,
        ..DiagnoseConfig::default()
    };
    Ok(config.check()?)
}
