//! Independent drives for testing diagnosis.
//!
//! Public as the namespace `biasctl::sim::family` because a user needs it: the examples and tests
//! that measure the diagnosis generate their logs from it (`family::generate`).
//!
//! A small generator, written apart from the built-in drive (`crate::sim::drive` and
//! `data/paper1997.toml`) so that a diagnosis tuned on that drive is checked on physics it has
//! never seen. Each [`FamilyDrive`] is a set of parameters:
//! - the **pivot hysteresis** is not Dahl: a Bouc–Wen element (smooth loading curve
//!   `dz/dx = (1 − (β·sgn(dx·z) + γ)·|z|ⁿ)/L`, a steeper, non-exponential unloading branch) or a
//!   Prandtl–Ishlinskii sum of stop operators (piecewise-linear loops);
//! - the **position trend** (flex cable) is a sinusoid or a cubic, not a parabola;
//! - the **noise** is Student-t (heavy tails) and/or AR(1) (correlated from seek to seek);
//! - the optional **memory law** sums over every uncrossed rest position, not only the nearest.
//!
//! On top, **hidden effects** ([`HiddenEffect`], switched on one or two at a time) of every
//! class diagnose must find: fast and slow covariates, a threshold, a lagged covariate,
//! covariate × direction, position × direction, a localized position defect, summed memory and
//! a covariate × position interaction. The log always carries every covariate column
//! ([`COVARIATES`]), among them three that have **no effect** ([`NO_EFFECT_COLUMNS`]: white
//! noise, a slow random walk, a warm-up curve), whether or not any hidden effect reads them.
//!
//! Conventions as everywhere in biasctl: positions in tracks (0 at the OD, positive seeks
//! inbound), bias in counts, time in s. Each random process draws from its own
//! [`SimRng::substream`](crate::numeric::rng::SimRng::substream) of the seed, so one seed gives a byte-identical log whatever effects
//! are switched on, and switching an effect on changes only the bias column.
//!
//! ```
//! use biasctl::{sim::family::FamilyConfig, sim::family::FamilyDrive, sim::family::HiddenEffect, sim::family::generate};
//! let cfg = FamilyConfig::new(FamilyDrive::members()[0].clone(), &[HiddenEffect::Lag], 3, 500);
//! let run = generate(&cfg).unwrap();
//! assert_eq!(run.log.len(), 500);
//! assert!(run.log.schema.covariate_index("walk").is_some());
//! let lag = run.truth("lag").unwrap();
//! assert!(lag.iter().any(|v| v.abs() > 0.0));
//! ```
//!
//! One concern per file: the drives and their covariate columns (`drive`), the hidden effects
//! (`effects`), the pivot physics and random processes (`physics`), and [`generate`] with its
//! configuration and run (`generate`).

mod drive;
mod effects;
mod generate;
mod physics;

pub use drive::{COVARIATES, FamilyDrive, NO_EFFECT_COLUMNS, Noise, Pivot, Trend};
pub use effects::HiddenEffect;
pub use generate::{FamilyConfig, FamilyError, FamilyRun, generate};
