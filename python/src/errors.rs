//! The exceptions (`BiasctlError`, a `ValueError`, and one subclass per stage) and the one
//! boundary every call crosses: a library error becomes its exception with the library's
//! message; a panic is caught and raised as `BiasctlError`, never unwound into Python.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use std::panic::{AssertUnwindSafe, catch_unwind};

pyo3::create_exception!(
    _biasctl,
    BiasctlError,
    PyValueError,
    "Every error biasctl raises: bad input, a setting out of range, a failed write."
);
pyo3::create_exception!(
    _biasctl,
    LogError,
    BiasctlError,
    "A log that cannot be read or used: names the file (or column), line and column."
);
pyo3::create_exception!(
    _biasctl,
    ModelError,
    BiasctlError,
    "A model spec, model file or model that cannot be applied to a log."
);
pyo3::create_exception!(
    _biasctl,
    FitError,
    BiasctlError,
    "A fit that cannot run: its settings, or a log it cannot determine."
);
pyo3::create_exception!(
    _biasctl,
    SettleError,
    BiasctlError,
    "A settle description that cannot be analysed: names the setting."
);

/// Which exception a failure raises.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Kind {
    Base,
    Log,
    Model,
    Fit,
    Settle,
}

/// A failure computed without the GIL, raised as its exception once the GIL is back.
#[derive(Debug)]
pub(crate) struct Failure {
    kind: Kind,
    message: String,
}

impl Failure {
    pub(crate) fn new(kind: Kind, message: impl Into<String>) -> Self {
        Self {
            kind,
            message: message.into(),
        }
    }

    /// The message.
    pub(crate) fn message(&self) -> &str {
        &self.message
    }
}

impl From<Failure> for PyErr {
    fn from(f: Failure) -> PyErr {
        match f.kind {
            Kind::Base => BiasctlError::new_err(f.message),
            Kind::Log => LogError::new_err(f.message),
            Kind::Model => ModelError::new_err(f.message),
            Kind::Fit => FitError::new_err(f.message),
            Kind::Settle => SettleError::new_err(f.message),
        }
    }
}

/// Maps a library error to a [`Failure`] of `kind` with the library's message (its causes
/// included, as the command line prints them).
pub(crate) fn fail<E: std::error::Error + 'static>(kind: Kind) -> impl Fn(E) -> Failure {
    move |e| Failure::new(kind, biasctl::io::message(&e))
}

/// Runs `f`, turning a panic into a `BiasctlError` naming it an internal error.
pub(crate) fn guard<T>(f: impl FnOnce() -> Result<T, Failure>) -> Result<T, Failure> {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|payload| {
        let what = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".into());
        Err(Failure::new(
            Kind::Base,
            format!("internal error in biasctl (please report it): {what}"),
        ))
    })
}

/// Runs `f` without the GIL (other Python threads run meanwhile) behind [`guard`].
pub(crate) fn detached<T: Send>(
    py: Python<'_>,
    f: impl FnOnce() -> Result<T, Failure> + Send,
) -> PyResult<T> {
    Ok(py.detach(|| guard(f))?)
}

/// Runs `f` with the GIL behind [`guard`].
pub(crate) fn attached<T>(f: impl FnOnce() -> Result<T, Failure>) -> PyResult<T> {
    Ok(guard(f)?)
}

/// Runs `f` with the library's parallel parts on a pool of `threads` workers (`None`: the
/// process-wide pool, one worker per core). One worker per call lets several Python threads
/// each keep one core busy.
pub(crate) fn on_threads<T: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> Result<T, Failure> + Send,
) -> Result<T, Failure> {
    match threads {
        None => f(),
        Some(t) => biasctl::with_threads(t, f).map_err(fail(Kind::Base))?,
    }
}
