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
//! log → seek history → simulated drive → model terms → fit → score/diagnose → plant/controller →
//! settle → plots/report.
//!
//! - [`numeric`]: shared numerics below everything: statistics (moments, histogram, bimodality
//!   and dip tests, trend and whiteness tests) and the seeded, portable random generator.
//! - [`log`]: the measurement log (CSV), streaming reader with column mapping, and the input
//!   limits ([`log::limits`]) every reader enforces.
//! - [`history`]: the seek-history state machine: direction, reversals, uncrossed rest positions.
//! - [`sim`]: the simulated drive (effects P1–P8, servo measurement, Tables I–VII and random sequences).
//! - [`model`]: bias models as sums of terms (poly2, table, direction, seek, memory, drift, dahl,
//!   col, bins), presets, the online predictor.
//! - [`fit`]: one least-squares solve (streaming QR) for all linear parameters, variable
//!   projection for the Dahl rate.
//! - [`score`]: error statistics of a model on a log: moments, percentiles, histogram,
//!   bimodality (Sarle's coefficient, Hartigans' dip test), trend.
//! - [`diagnose`]: which missing effect the residual follows: cross-validated smoother per
//!   feature, permutation test, advice, ladder.
//! - [`control`]: plant → controller → settle: continuous plant with modes, ZOH with
//!   fractional delay, DARE/LQR, and ([`control::settle`]) the settle-optimal integrator start
//!   value at handoff (eq. 14–16), robust choices, the allocation-free handoff table.
//! - [`export`]: the fitted model and the handoff table as C99, checked against the predictor.
//! - [`render`]: the one output layer: text, JSON and CSV, atomic and safe file writing,
//!   finite-only numbers.
//! - [`plot`]: hand-written SVG charts, one builder per paper figure, quick-look plots of a log.
//! - [`report`]: one self-contained `report.html` (inline SVG and CSS, no script, no network).
//!
//! ## The whole pipeline in one example
//!
//! Simulate the built-in drive, fit the paper's calibration model (eq. 1), score it on a fresh
//! random run, ask the diagnosis which effect a poorer model misses, and compute the
//! settle-optimal integrator start value for the paper's test bed.
//!
//! ```
//! use biasctl::diagnose::{DiagnoseConfig, diagnose_model};
//! use biasctl::fit::{FitOptions, fit};
//! use biasctl::model::ModelSpec;
//! use biasctl::control::settle::{SettleSpec, analyse};
//! use biasctl::sim::{Drive, SequenceOptions, SimConfig, simulate_log};
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
//! let s_pd = biasctl::score::score(&p_pd.residual, &p_pd.positions)?;
//! let s_cal = biasctl::score::score(&p_cal.residual, &p_cal.positions)?;
//! assert!(s_cal.std < s_pd.std);
//!
//! // 4. Diagnose the poorer model: features ranked by out-of-sample explained variance.
//! let d = diagnose_model(&pd, &test, &DiagnoseConfig::default().check()?)?;
//! assert!(d.features[0].explained > 0.0);
//!
//! // 5. Settle: the paper's 10 kHz test bed, 15 µm step, ±0.5 µm window.
//! let report = analyse(&SettleSpec::preset("paper1997")?.validate()?)?;
//! assert_eq!(report.k_star, Some(14)); // 1.4 ms instead of 2.8 ms at zero feedforward
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![deny(clippy::float_cmp)]
#![warn(missing_docs)]

// Modules in the order a log travels through them; a module imports only modules above it.
pub mod numeric;

pub mod log;

pub mod history;

pub mod sim;

pub mod model;

pub mod fit;

pub mod score;

pub mod diagnose;

pub mod control;

pub mod export;

pub mod render;

pub mod plot;

pub mod report;
