//! # biasctl — predict, diagnose and compensate actuator bias
//!
//! A rotary actuator needs a small holding current at every track: its **bias**, from flex-cable
//! force, windage and the hysteretic friction of the pivot bearing. biasctl simulates a drive,
//! fits bias models to measurement logs, finds which physical effect a model is missing, and
//! computes the integrator start value that settles fastest at the seek-to-track handoff
//! (K. Eddy, J. Steele, W. Messner, *Bias in disk drive rotary actuators*, IEEE Trans. Magn. 1997).
//!
//! ## Conventions (used everywhere)
//! - **Position** in tracks; track 0 is the outer diameter (OD), numbers grow towards the inner
//!   diameter (ID). A **positive signed seek moves inbound** (towards ID); direction +1 is inbound.
//! - **Bias** in counts (DAC counts of the voice-coil driver; the paper's normalised current units).
//! - **Time** in seconds. Position error in the servo is `e = y − r` in µm.
//! - The integrator start value at handoff is reported **relative to its converged value**, so
//!   "zero feedforward" is 0.
//! - Tracks and counts are the simulator's units. A measured log carries its own labels
//!   ([`log::Units`]: metadata `bias_unit` / `position_unit`, or the column names), and every
//!   score, diagnosis, plot and report made from it is labelled with them.
//!
//! ## The pipeline, one module per step
//! The modules in the order `lib.rs` declares them, each importing only modules above it
//! (`tests/it/layers.rs` checks it, and that no files import each other in a circle). Each
//! pipeline step is a public namespace (`biasctl::log`, `biasctl::sim`, `biasctl::model`, …);
//! `field`, `codegen` and `output_check` are crate-private. What each holds:
//!
//! - `field`: the names of settings that errors carry ([`Field`]).
//! - [`numeric`]: shared numerics below everything: statistics (moments, histogram, bimodality
//!   and dip tests, trend and whiteness tests), the golden-section search, the QR kernels, the
//!   worker threads and the seeded, portable random generator.
//! - [`io`]: the one output layer: text, JSON and CSV, atomic and safe file writing,
//!   finite-only numbers.
//! - [`log`]: the measurement log (CSV): column mapping, units, dialect, the streaming reader and
//!   writer, and the input limits (`log::limits`) every reader enforces.
//! - [`history`]: the seek-history state machine: direction, reversals, uncrossed rest
//!   positions; the history-column cache and the sampling analysis.
//! - `codegen`: what a term needs to write its own C for the firmware export.
//! - [`sim`]: the simulated drive (effects P1–P8, servo measurement, Tables I–VII and random
//!   sequences) and the drive family the diagnosis is measured on.
//! - [`model`]: bias models as sums of terms (one file per term, one registry row each),
//!   presets, the online predictor.
//! - [`fit`](mod@fit): one least-squares solve (streaming QR) for all linear parameters, variable
//!   projection for the nonlinear ones.
//! - `output_check`: every number a model's prediction or replay produces is finite.
//! - [`score`](mod@score): error statistics of a model on a log: moments, percentiles, histogram,
//!   bimodality (Sarle's coefficient, Hartigans' dip test), trend.
//! - [`diagnose`](mod@diagnose): the residual engine: which missing effect the residual follows
//!   (cross-validated smoother per feature, permutation test, pairs, advice).
//! - [`select`]: model-structure selection on top of it: verified refits, discover, ladder.
//! - [`control`]: plant → controller → settle: continuous plant with modes, ZOH with
//!   fractional delay, DARE/LQR, (`control::settle`) the settle-optimal integrator start
//!   value at handoff (eq. 14–16), robust choices, the allocation-free handoff table, and the
//!   start values a predictor gives at handoff.
//! - [`export`]: the fitted model and the handoff table as C99, checked against the predictor.
//! - [`plot`]: hand-written SVG charts, one builder per paper figure, quick-look plots of a log.
//! - [`report`]: one self-contained `report.html` (inline SVG and CSS, no script, no network).
//! - [`cli`]: the command line (the `cli` feature).
//!
//! ## Settings: unchecked → checked (linfa's `ParamGuard`)
//! Every settings type is written freely and checked once, before any numerics, into a checked
//! type; the entry points accept only the checked one, so no numerics run on unchecked
//! settings: [`FitOptions::check`] → [`CheckedFitOptions`] for [`fit()`],
//! [`DiagnoseConfig::check`] → [`CheckedDiagnoseConfig`] for [`diagnose()`] and
//! [`diagnose_model`], [`VerifyConfig::check`] → [`CheckedVerifyConfig`] for
//! [`diagnose_verified`], [`DiscoverConfig::check`] → [`CheckedDiscoverConfig`] for
//! [`discover()`], [`SettleSpec::check`] → [`control::SettleConfig`] for [`analyse`] and
//! [`StartValues::new`], [`StoryOptions::check`] → [`report::CheckedStoryOptions`] for [`demo_report`],
//! [`data_report`], [`report::compute_demo`] and [`report::compute_data`], [`ladder_terms`] →
//! [`select::LadderTerms`]
//! for [`ladder_fit`], [`plot::views::PanelOptions::check`] →
//! [`plot::views::CheckedPanelOptions`] for [`plot::views::diagnose_panel`], [`SimConfig::new`]
//! (a [`SimConfig`] exists only checked) for [`simulate_log`]. The `Default` of a checked type
//! is the checked default. ([`COptions`] has no setting that can be out of range.)
//!
//! ## Errors name settings, not flags
//! An error about a setting carries a [`Field`] (`SettleSpec::step_um`, `ColumnMap::bias`,
//! `SequenceOptions::span`, …) and prints its name. The library never names a command-line
//! flag: the `biasctl` binary holds the one table field → flag and prints `--step-um` there.
//!
//! ## The public API
//! The crate root holds the names most users need ([`Log`], [`simulate_log`], [`ModelSpec`],
//! [`FittedModel`], [`Predictor`], [`Term`], [`fit()`], [`score()`], [`diagnose_model`],
//! [`discover()`], [`analyse`], [`StartValues`], [`c_source`], [`write_atomic`], …), and
//! [`prelude`] the names of a first session in one `use biasctl::prelude::*;`. Everything else
//! is reached through its pipeline namespace: the types a signature uses (errors, results,
//! parameters) beside the function (`biasctl::diagnose::FeatureReport`,
//! `biasctl::control::Bounds`), the built-in terms in [`model::terms`] (for a user
//! writing their own [`Term`]), the drive family in [`sim::family`], the figures in [`plot`].
//! The internal numerics (statistics kernels, the golden-section search, incomplete beta and
//! gamma functions, the matrix exponential, the smoother) are crate-private; the few that are
//! public ([`SimRng`], [`numeric::stats::std_dev`], [`numeric::stats::dip_test`],
//! [`set_threads`]) say why. `#![warn(unreachable_pub)]` keeps every `pub` item reachable: a
//! new public item is re-exported by its namespace's `mod.rs`, anything else is `pub(crate)`.
//!
//! ## The whole pipeline in one example
//!
//! Simulate the built-in drive, fit the paper's calibration model (eq. 1), score it on a fresh
//! random run, ask the diagnosis which effect a poorer model misses, and compute the
//! settle-optimal integrator start value for the paper's test bed.
//!
//! ```
//! use biasctl::{DiagnoseConfig, diagnose_model};
//! use biasctl::{FitOptions, fit};
//! use biasctl::ModelSpec;
//! use biasctl::{SettleSpec, analyse};
//! use biasctl::{Drive, SequenceOptions, SimConfig, simulate_log};
//!
//! // 1. Simulate: a training run and a test run with another seed (tracks, counts, s).
//! let opts = SequenceOptions { n: Some(600), ..Default::default() };
//! let train = simulate_log(&SimConfig::new(Drive::paper1997(), "random", &opts, 1, &[])?)?;
//! let test = simulate_log(&SimConfig::new(Drive::paper1997(), "random", &opts, 2, &[])?)?;
//!
//! // 2. Fit two models: position + direction (1997 practice) and eq. 1.
//! let pd = fit(&ModelSpec::preset("position-direction")?, &train, &FitOptions::default().check()?)?;
//! let cal = fit(&ModelSpec::preset("calibration")?, &train, &FitOptions::default().check()?)?;
//!
//! // 3. Score causally on the test run: the full model leaves a smaller error.
//! let p_pd = pd.predict_log(&test)?;
//! let p_cal = cal.predict_log(&test)?;
//! let s_pd = biasctl::score(&p_pd.residual, &p_pd.positions)?;
//! let s_cal = biasctl::score(&p_cal.residual, &p_cal.positions)?;
//! assert!(s_cal.std < s_pd.std);
//!
//! // 4. Diagnose the poorer model: features ranked by out-of-sample explained variance.
//! let d = diagnose_model(&pd, &test, &DiagnoseConfig::default().check()?)?;
//! assert!(d.features[0].explained > 0.0);
//!
//! // 5. Settle: the paper's 10 kHz test bed, 15 µm step, ±0.5 µm window.
//! let report = analyse(&SettleSpec::preset("paper1997")?.check()?)?;
//! assert_eq!(report.k_star, Some(14)); // 1.4 ms instead of 2.8 ms at zero feedforward
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(clippy::float_cmp)]
#![warn(missing_docs)]
#![warn(unnameable_types)]
#![warn(unreachable_pub)]

/// Defines a checked-settings newtype: the struct as written (its docs and derives), holding
/// the settings type it wraps, and `Deref` to that type (its fields are read through it). The
/// only way to make one besides its `Default` is the settings type's `check()`, which stays
/// beside each use.
macro_rules! checked_settings {
    ($(#[$meta:meta])* $vis:vis struct $checked:ident($inner:ty);) => {
        $(#[$meta])*
        $vis struct $checked($inner);

        impl std::ops::Deref for $checked {
            type Target = $inner;
            fn deref(&self) -> &$inner {
                &self.0
            }
        }
    };
}

// Modules in the order a log travels through them; a module imports only modules above it
// (tests/it/layers.rs checks it).
pub(crate) mod field;

pub mod numeric;

pub mod io;

pub mod log;

pub mod history;

pub(crate) mod codegen;

pub mod sim;

pub mod model;

pub mod fit;

pub(crate) mod output_check;

pub mod score;

pub mod diagnose;

pub mod select;

pub mod control;

pub mod export;

pub mod plot;

pub mod report;

pub mod fleet;

/// The `biasctl` command line (the `cli` feature, on by default): flags parsed into the
/// library's checked settings, one file per command. Its one public item is [`cli::main`],
/// what the binary runs.
#[cfg(feature = "cli")]
pub mod cli;

// The crate root: the names most users need. Everything else is reached
// through its pipeline namespace (`biasctl::control::HandoffTable`, `biasctl::sim::family`,
// `biasctl::model::terms`, …); `prelude` holds the names of a first session.
pub use control::StartValues;
pub use control::settle::{HandoffTable, SettleReport, SettleSpec, analyse};
pub use diagnose::{CheckedDiagnoseConfig, DiagnoseConfig, Diagnosis, diagnose, diagnose_model};
pub use export::{COptions, ExportError, c_source};
pub use field::Field;
pub use fit::{CheckedFitOptions, FitData, FitError, FitOptions, fit};
pub use history::{History, replay};
pub use io::{OutputError, write_atomic};
pub use log::{ColumnMap, Log, LogError, Units};
pub use model::term::{Term, TermSpec};
pub use model::{FittedModel, ModelError, ModelSpec, Prediction, Predictor, SpecError};
/// The worker-thread count of the parallel parts (diagnosis permutations, cross-validation):
/// public for the binary's `--threads` and for tests that pin a thread count.
pub use numeric::parallel::{ThreadsError, set_threads, with_threads};
/// The seeded, portable random generator: public so that a user's simulation, bench or test
/// draws the same numbers as the crate's own for the same seed.
pub use numeric::rng::SimRng;
pub use report::story::{StoryOptions, data_report, demo_report};
pub use score::{Score, score, score_model};
pub use select::{
    CheckedDiscoverConfig, CheckedVerifyConfig, DiscoverConfig, Discovery, VerifyConfig,
    diagnose_verified, discover, ladder_fit, ladder_terms,
};
pub use sim::{Drive, SequenceOptions, SimConfig, simulate_log};

/// The names a first session needs, in one `use biasctl::prelude::*;`.
pub mod prelude {
    pub use crate::{
        COptions, ColumnMap, DiagnoseConfig, DiscoverConfig, Drive, FitOptions, FittedModel, Log,
        ModelSpec, Predictor, SequenceOptions, SettleSpec, SimConfig, StartValues, Units,
        VerifyConfig, analyse, c_source, diagnose_model, diagnose_verified, discover, fit, score,
        score_model, simulate_log,
    };
}
