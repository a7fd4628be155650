//! A fleet of drives: one model fitted to every drive's log, the table of their parameters, the
//! drives whose parameters stand out from the fleet, and the pooled screen that names an effect
//! too weak for any one drive.
//!
//! On one machine the drives run side by side on rayon's pool ([`fit_paths`]); the Python
//! package's `biasctl.fleet` calls the same per-drive functions ([`fit_path`], [`fit_log`]) on a
//! thread pool or a Dask cluster, so a row is the same bytes whichever runs it. One drive that
//! cannot be read or fitted never fails the fleet: its row carries the message
//! ([`DriveFit::error`]).
//!
//! ```
//! use biasctl::fleet::{self, DriveFit};
//! use biasctl::sim::{Drive, SequenceOptions, SimConfig};
//! use biasctl::{FitOptions, ModelSpec};
//! let spec = ModelSpec::parse("poly2,direction").unwrap();
//! let opts = FitOptions::default().check().unwrap();
//! let seeks = SequenceOptions { n: Some(300), ..SequenceOptions::default() };
//! let rows: Vec<DriveFit> = (1..=3)
//!     .map(|seed| {
//!         let sim = SimConfig::new(Drive::paper1997(), "random", &seeks, seed, &[]).unwrap();
//!         let log = biasctl::simulate_log(&sim).unwrap();
//!         fleet::fit_log(&format!("drive{seed}"), &log, &spec, &opts)
//!     })
//!     .collect();
//! assert!(rows.iter().all(|r| r.error.is_none()));
//! let csv = fleet::fits_csv(&rows);
//! assert_eq!(fleet::read_fits(&csv, "fits.csv").unwrap(), rows);
//! ```

mod fits;
mod outliers;
mod pattern;
mod pooled;
mod table;
mod verdict;
mod verify;

pub use fits::{DriveError, DriveFit, ReadSettings, fit_log, fit_path, fit_paths};
pub use outliers::{
    MIN_DRIVES, OUTLIER_THRESHOLD, Outlier, OutlierRule, ThresholdError, outliers, outliers_csv,
};
pub use pattern::{PatternError, expand};
pub use pooled::{
    DriveScreen, DriveStatistics, FleetDiagnosis, PoolError, PooledFeature, pool, screen_drive,
    screen_path,
};
pub use table::{FitsError, fits_csv, param_names, read_fits};
pub use verdict::{diagnose_paths, pool_verifications};
pub use verify::{
    DriveEdit, DriveVerification, FleetVerification, TriedEdit, verify_drive, verify_path,
};

#[cfg(test)]
mod tests;
