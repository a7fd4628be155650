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
//! (`tests/it/layers.rs` checks it, and that no files import each other in a circle). They are
//! crate-private (the source's layout, not the API); what each holds:
//!
//! - `field`: the names of settings that errors carry ([`Field`]).
//! - `numeric`: shared numerics below everything: statistics (moments, histogram, bimodality
//!   and dip tests, trend and whiteness tests), the golden-section search, the QR kernels, the
//!   worker threads and the seeded, portable random generator.
//! - `io`: the one output layer: text, JSON and CSV, atomic and safe file writing,
//!   finite-only numbers.
//! - `log`: the measurement log (CSV): column mapping, units, dialect, the streaming reader and
//!   writer, and the input limits (`log::limits`) every reader enforces.
//! - `history`: the seek-history state machine: direction, reversals, uncrossed rest
//!   positions; the history-column cache and the sampling analysis.
//! - `codegen`: what a term needs to write its own C for the firmware export.
//! - `sim`: the simulated drive (effects P1–P8, servo measurement, Tables I–VII and random
//!   sequences) and the drive family the diagnosis is measured on.
//! - `model`: bias models as sums of terms (one file per term, one registry row each),
//!   presets, the online predictor.
//! - `fit`: one least-squares solve (streaming QR) for all linear parameters, variable
//!   projection for the nonlinear ones.
//! - `output_check`: every number a model's prediction or replay produces is finite.
//! - `score`: error statistics of a model on a log: moments, percentiles, histogram,
//!   bimodality (Sarle's coefficient, Hartigans' dip test), trend.
//! - `diagnose`: the residual engine: which missing effect the residual follows
//!   (cross-validated smoother per feature, permutation test, pairs, advice).
//! - `select`: model-structure selection on top of it: verified refits, discover, ladder.
//! - `control`: plant → controller → settle: continuous plant with modes, ZOH with
//!   fractional delay, DARE/LQR, (`control::settle`) the settle-optimal integrator start
//!   value at handoff (eq. 14–16), robust choices, the allocation-free handoff table, and the
//!   start values a predictor gives at handoff.
//! - `export`: the fitted model and the handoff table as C99, checked against the predictor.
//! - [`plot`]: hand-written SVG charts, one builder per paper figure, quick-look plots of a log.
//! - `report`: one self-contained `report.html` (inline SVG and CSS, no script, no network).
//! - [`cli`]: the command line (the `cli` feature).
//!
//! ## Settings: unchecked → checked (linfa's `ParamGuard`)
//! Every settings type is written freely and checked once, before any numerics, into a checked
//! type; the entry points accept only the checked one, so no numerics run on unchecked
//! settings: [`FitOptions::check`] → [`CheckedFitOptions`] for [`fit()`],
//! [`DiagnoseConfig::check`] → [`CheckedDiagnoseConfig`] for [`diagnose()`] and
//! [`diagnose_model`], [`VerifyConfig::check`] → [`CheckedVerifyConfig`] for
//! [`diagnose_verified`], [`DiscoverConfig::check`] → [`CheckedDiscoverConfig`] for
//! [`discover()`], [`SettleSpec::check`] → [`SettleConfig`] for [`analyse`] and
//! [`StartValues::new`], [`StoryOptions::check`] → [`CheckedStoryOptions`] for [`demo_report`],
//! [`data_report`], [`compute_demo`] and [`compute_data`], [`ladder_terms`] → [`LadderTerms`]
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
//! Everything a user needs is one `use biasctl::Name` away, re-exported here at the top ([`Log`],
//! [`replay`], [`simulate_log`], [`ModelSpec`], [`FittedModel`], [`Predictor`], [`Term`],
//! [`fit()`], [`score()`], [`diagnose_model`], [`discover()`], [`analyse`], [`StartValues`],
//! [`c_source`], [`write_atomic`], …), together with the types their signatures use (errors,
//! results, parameters). Three namespaces stay whole because a user needs them as namespaces:
//! [`plot`] (one builder per figure, and the chart builder), [`terms`] (the built-in terms, for a
//! user writing their own [`Term`]) and [`family`] (the drive family the diagnosis is measured
//! on). The modules themselves are crate-private, and so are the internal numerics (statistics
//! kernels, the golden-section search, incomplete beta and gamma functions, the matrix
//! exponential, the smoother); the few numerics that are public ([`SimRng`], [`std_dev`],
//! [`dip_test`], [`set_threads`]) say why. `#![warn(unreachable_pub)]` keeps every `pub` item
//! reachable from here: a new public item is added to the re-export list at the end of this
//! file, anything else is `pub(crate)`.
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

pub(crate) mod numeric;

pub(crate) mod io;

pub(crate) mod log;

pub(crate) mod history;

pub(crate) mod codegen;

pub(crate) mod sim;

pub(crate) mod model;

pub(crate) mod fit;

pub(crate) mod output_check;

pub(crate) mod score;

pub(crate) mod diagnose;

pub(crate) mod select;

pub(crate) mod control;

pub(crate) mod export;

pub mod plot;

pub(crate) mod report;

/// The `biasctl` command line (the `cli` feature, on by default): flags parsed into the
/// library's checked settings, one file per command. Its one public item is [`cli::main`],
/// what the binary runs.
#[cfg(feature = "cli")]
pub mod cli;

// The curated public API: what a user of the library needs, one `use biasctl::…` away. The
// modules above are crate-private; `plot` stays a namespace (one builder per figure), and two
// namespaces are re-exported whole: `terms` (the built-in terms, for a user writing their own
// `Term`) and `family` (the drive family the diagnosis is measured on).
pub use control::settle::{
    Bounds, Handoff, HandoffTable, SettleConfig, SettleReport, SettleSpec, Window, analyse,
    handoff_state, settle_index, worst_case_settle,
};
pub use control::{
    Controller, LqrWeights, StartValues,
    plant::{Plant, PlantSpec},
};
pub use diagnose::{
    CheckedDiagnoseConfig, DiagnoseConfig, Diagnosis, FeatureReport, FeatureTable, diagnose,
    diagnose_model, diagnose_residual, model_spec, replay_model,
};
pub use export::{
    C_FILES, CContext, CHandoff, COptions, CPrecision, CSource, CTerm, ExportError, c_source,
};
pub use field::Field;
pub use fit::{CheckedFitOptions, FitData, FitError, FitOptions, FitReport, fit};
pub use history::{
    DirectionSetting, DirectionSource, Feature, History, SeekFeatures, log_sampling, replay,
    sampling, summarise_sampling,
};
pub use io::json::to_string_pretty;
pub use io::{
    NonFinite, OutputError, StagedDir, check_paths, check_text, flush_stdout, is_broken_pipe,
    message, message_with, quote, write_atomic, write_stdout, write_string_atomic,
};
pub use log::limits::{check_toml_numbers, read_text};
pub use log::{
    BiasColumn, ColumnMap, DEFAULT_BIAS_COL, DEFAULT_BIAS_UNIT, DEFAULT_TIME_COL,
    DEFAULT_TRACK_COL, Log, LogError, LogReader, LogSchema, LogWriter, STDIN_PATH, Units,
    check_unit_label, fmt_trimmed,
};
pub use model::preset::{CALIBRATION, preset_terms};
pub use model::registry::builtin_names;
pub use model::term::{
    Nonlinear, Param, SearchBasis, SearchContext, Searched, Seek, Term, TermSpec, TermState,
};
pub use model::terms;
pub use model::{
    ColumnsUsed, Feedback, FittedModel, FittedTerm, IntegratorStart, ModelEdit, ModelError,
    ModelSpec, NextPrediction, Prediction, Predictor, ReplaySummary, RowPrediction, SpecError,
    predict_next, replay_stream, write_predictions_csv,
};
/// The worker-thread count of the parallel parts (diagnosis permutations, cross-validation):
/// public for the binary's `--threads` and for tests that pin a thread count.
pub use numeric::parallel::{ThreadsError, set_threads, with_threads};
/// The seeded, portable random generator: public so that a user's simulation, bench or test
/// draws the same numbers as the crate's own for the same seed.
pub use numeric::rng::SimRng;
/// Summary statistics public on purpose: the examples summarise residuals with them, and the
/// dip test (Hartigans') is benched on its own against the peer implementation.
pub use numeric::stats::{dip_test, dip_test_sorted, mean, sorted, std_dev};
pub use output_check::{check_prediction, check_replay};
pub use report::story::{
    CheckedStoryOptions, Progress, StoryOptions, StoryOutcome, data_report, demo_report,
};
pub use report::{Cell, Report, Table};
pub use score::{Score, grouped_warnings, score, score_model, score_with_units};
pub use select::{
    CheckedDiscoverConfig, CheckedVerifyConfig, DiscoverConfig, Ladder, LadderStep, LadderTerms,
    PathStep, VerifyConfig, diagnose_verified, discover, ladder_fit, ladder_terms, suggestion_path,
    suggestion_path_from,
};
pub use sim::family;
pub use sim::{
    DEFAULT_N, Drive, MeasureMode, SequenceOptions, SimConfig, TRUTH_COLUMNS, simulate,
    simulate_log, simulate_to_files,
};
// Types that appear in the public items above (errors, results, parameters), nameable here.
pub use control::lqr::DareError;
pub use control::plant::{DiscretePlant, Mode, ModeSpec, PlantError};
pub use control::settle::{
    AnalyseError, ConfigError as SettleConfigError, HandoffSolution, Interval, PaperRobust,
    Response, RobustChoice, Scenario, SettleError, WorstCase,
};
pub use control::{ExpmError, ServoError};
pub use diagnose::{
    Absorption, CombinedEdit, CurveBin, DERIVED_VELOCITY, DiagnoseError, FeatureColumn,
    FeatureOrigin, GlobalCheck, Interaction, ModelDiagnosisError, RejectedEdit, SecondRound, Shape,
    Verification, VerifiedEdit, Whiteness,
};
pub use history::{DirectionError, Replay, RestMemory, Sampling};
pub use io::file::Sink;
pub use log::{Covariates, LogSummary, Row, RowRef, Rows, UnitError};
pub use model::RangeWarning;
pub use model::predictor::ReplayError;
pub use numeric::stats::{Dip, DipTest, Histogram, Trend};
pub use report::run::{
    DataRun, DemoRun, DiagnosedRun, MAX_SEEKS, PaperRobustWhy, ScoredModel, SettleRun, StoryError,
    compute_data, compute_demo,
};
pub use report::{Block, Section};
pub use score::{ModelScore, ModelScoreError, ScoreError};
pub use select::{DiscoverError, DiscoverStep, Discovery};
pub use sim::drive::{
    DirectionParams, DriftParams, DriveError, Element, ElementKind, Harmonic, MemoryParams,
    OvershootParams, PositionParams, RunoutParams, ScatterParams, ServoParams, TemperatureParams,
    TimeParams,
};
pub use sim::sequence::{ScriptError, Step};
pub use sim::{
    ConfigError as SimConfigError, Effect, RandomSpec, Sequence, SimError, SimRow, SimSummary,
    Truth,
};
