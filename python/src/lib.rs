//! `biasctl._biasctl`: the Python extension module of the `biasctl` package, a thin layer over
//! the Rust library (`biasctl` without its command line). The Python package `biasctl`
//! (python/biasctl/) wraps it in pandas and numpy; every long call releases the GIL, every
//! error is a `BiasctlError` with the library's message, and no panic reaches Python.

mod analysis;
mod errors;
mod fleet;
mod log;
mod model;
mod settle;

use pyo3::prelude::*;

/// A deliberate panic behind the boundary (for the tests): raises `BiasctlError`, never
/// unwinds into Python.
#[pyfunction]
fn _panic(py: Python<'_>) -> PyResult<()> {
    errors::detached(py, || -> Result<(), errors::Failure> {
        panic!("deliberate panic (test hook)")
    })
}

#[pymodule]
fn _biasctl(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    let exceptions = [
        ("BiasctlError", py.get_type::<errors::BiasctlError>()),
        ("LogError", py.get_type::<errors::LogError>()),
        ("ModelError", py.get_type::<errors::ModelError>()),
        ("FitError", py.get_type::<errors::FitError>()),
        ("SettleError", py.get_type::<errors::SettleError>()),
    ];
    for (name, ty) in exceptions {
        // Shown as `biasctl.LogError`, where users import it from.
        ty.setattr("__module__", "biasctl")?;
        m.add(name, ty)?;
    }
    m.add_class::<log::PyLog>()?;
    m.add_class::<model::PyModel>()?;
    m.add_class::<model::PyPredictor>()?;
    m.add_class::<analysis::PyDiagnosis>()?;
    m.add_function(wrap_pyfunction!(log::read_log, m)?)?;
    m.add_function(wrap_pyfunction!(log::log_from_columns, m)?)?;
    m.add_function(wrap_pyfunction!(model::fit, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::discover, m)?)?;
    m.add_function(wrap_pyfunction!(analysis::ladder, m)?)?;
    m.add_function(wrap_pyfunction!(settle::settle, m)?)?;
    m.add_function(wrap_pyfunction!(fleet::fit_drive, m)?)?;
    m.add_function(wrap_pyfunction!(fleet::fleet_outliers, m)?)?;
    m.add_function(wrap_pyfunction!(fleet::fits_csv, m)?)?;
    m.add_function(wrap_pyfunction!(fleet::screen_drive, m)?)?;
    m.add_function(wrap_pyfunction!(fleet::pool_screens, m)?)?;
    m.add_function(wrap_pyfunction!(fleet::verify_drive, m)?)?;
    m.add_function(wrap_pyfunction!(_panic, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
