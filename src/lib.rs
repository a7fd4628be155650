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
//!
//! ## The pipeline, one module per step
//! log → seek history → simulated drive → model terms → fit → score/diagnose → plant/controller →
//! settle → plots/report.
//!
//! - [`log`]: the measurement log (CSV), streaming reader with column mapping, atomic writer.
//! - [`history`]: the seek-history state machine: direction, reversals, uncrossed rest positions.
//! - [`rng`]: the seeded, portable random generator every simulation uses.
//! - [`output`]: atomic file output.
//! - [`stats`]: moments, histogram, bimodality, trend and whiteness tests shared by score and diagnose.
//! - [`servo`]: plant (rigid body + modes, ZOH with fractional delay), DARE/LQR, closed loop.
//! - [`settle`]: eq. 14–16 bounds, start-value choices (optimal, paper robust, worst-case robust), the allocation-free handoff.
#![deny(clippy::float_cmp)]
#![warn(missing_docs)]

pub mod history;
pub mod log;
pub mod output;
pub mod rng;
pub mod servo;
pub mod settle;
pub mod stats;
