//! The one integration-test binary, one module per pipeline stage or command: reading a log,
//! simulating, fitting, predicting, diagnosing, exporting, settling, plotting and reporting, the
//! command line as a whole, real data, and the properties every input must keep (with the fuzz
//! harness). Helpers for running the binary live in `common`.

mod cli;
mod common;
mod diagnose;
mod docs;
mod export;
mod fit_model;
mod fleet;
mod fuzz;
mod layers;
mod log_reading;
mod plot_report;
mod predict;
mod properties;
mod real_data;
mod settle;
mod simulate;
mod term_names;
