//! The one integration-test binary: CLI contracts, paper reproduction, bad inputs, real data.
//! One module per area; helpers for running the binary live in `common`.

mod check;
mod common;
mod diagnose;
mod export;
mod extend;
mod family;
mod first_use;
mod fuzz;
mod invariance;
mod model;
mod outputs;
mod plot;
mod position_unit;
mod predict_plan;
mod property;
mod real;
mod report;
mod review;
mod scale;
mod selfcheck;
mod settings;
mod settle;
mod sim;
mod units;
