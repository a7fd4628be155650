//! The simulated drive: a physical model of every bias effect of the paper (P1–P8), measured the
//! way the paper measures (one-revolution average of a track-following servo's control effort),
//! driven by the paper's calibration sequences.
//!
//! - `drive`: the drive description (TOML) and the physics of each effect; see its docs for
//!   the pivot model (Dahl + Maxwell-slip elements with deceleration back-drive).
//! - `measure`: the closed-loop servo and the one-revolution average (slow reference loop and
//!   the fast superposition path).
//! - `sequence`: Tables I–VII, random, dwell, script.
//! - `config`: the switchable effects, the sequence options and [`SimConfig`].
//! - `state`: the drive's evolving physical state, one step per row.
//! - `run`: [`simulate`] and the log and truth files it writes.
//! - [`family`]: independent drives for testing diagnosis.
//!
//! ## Log semantics
//! A row's `time_s` is when its bias is measured. The seek to the row's track starts right after
//! the previous row's measurement, so `dwell_s` (time since the previous row) is the time the head
//! has spent at the target when it is measured (for a zero-length seek the head stays, and its
//! time at the track keeps growing). Unmeasured rows (`bias` empty) are positioning moves.
//!
//! ## Effects and switches
//! Every effect can be switched off by name ([`Effect`]): `position` (P1), `direction` (P2),
//! `overshoot` (P4/P5), `time` (P3), `memory` (P6), `drift` (P7), `scatter` (P8: force scatter
//! and sensor noise), `runout`, `temperature` (the `temp_c` covariate; only in drives that enable
//! it). Each random effect draws from its own [`SimRng::substream`](crate::SimRng::substream) of the seed, so switching one
//! off leaves the others' draws unchanged.
//!
//! ```
//! use biasctl::{Drive, SequenceOptions, SimConfig, simulate_log};
//! let opts = SequenceOptions { n: Some(500), ..SequenceOptions::default() };
//! let cfg = SimConfig::new(Drive::paper1997(), "random", &opts, 7, &[]).unwrap();
//! let log = simulate_log(&cfg).unwrap();
//! assert_eq!(log.len(), 500);
//! assert_eq!(log.schema.metadata_value("seed"), Some("7"));
//! ```

pub(crate) mod drive;
pub mod family;
pub(crate) mod measure;
pub(crate) mod sequence;

pub use drive::Drive;
pub(crate) use measure::{Handoff, Servo};
mod config;
mod run;
mod state;

pub use config::{
    ConfigError, DEFAULT_N, Effect, MeasureMode, RandomSpec, Sequence, SequenceOptions, SimConfig,
};
pub use run::{
    SimError, SimRow, SimSummary, TRUTH_COLUMNS, Truth, simulate, simulate_log, simulate_to_files,
};

// The namespace's public items that live in its submodules (the crate root keeps only the
// names most users need; see `biasctl::prelude`).
pub use drive::{
    DirectionParams, DriftParams, DriveError, Element, ElementKind, Harmonic, MemoryParams,
    OvershootParams, PositionParams, RunoutParams, ScatterParams, ServoParams, TemperatureParams,
    TimeParams,
};
pub use sequence::{ScriptError, Step};

/// Test support: the log of `n` random seeks on the built-in `paper1997` drive with every
/// effect on, simulated with `seed` (the setup unit tests share).
#[cfg(test)]
pub(crate) fn random_log(n: u64, seed: u64) -> crate::log::Log {
    let opts = SequenceOptions {
        n: Some(n),
        ..SequenceOptions::default()
    };
    let cfg = SimConfig::new(Drive::paper1997(), "random", &opts, seed, &[])
        .expect("the built-in drive and the random sequence are valid");
    simulate_log(&cfg).expect("a simulated log")
}

#[cfg(test)]
mod tests;
