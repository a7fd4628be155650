//! The exceptions (`BiasctlError`, a `ValueError`, and one subclass per stage) and the one
//! boundary every call crosses: a library error becomes its exception with the library's
//! message; a panic is caught and raised as `BiasctlError`, never unwound into Python.

use biasctl::Field;
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
    /// The exception of the failure's kind, its message naming settings as Python sets them
    /// ([`with_keywords`]).
    fn from(f: Failure) -> PyErr {
        let message = with_keywords(&f.message);
        match f.kind {
            Kind::Base => BiasctlError::new_err(message),
            Kind::Log => LogError::new_err(message),
            Kind::Model => ModelError::new_err(message),
            Kind::Fit => FitError::new_err(message),
            Kind::Settle => SettleError::new_err(message),
        }
    }
}

/// The keyword argument of this package that sets each library setting (`read_log(...,
/// track_col=...)`, `fit(..., grid=...)`, `simulate(..., span=...)`, `diagnose(...,
/// verify_folds=...)`, …); a settle setting is `settle`'s keyword of its file key
/// ([`Field::file_key`]: `settle(window_um=...)`). A setting this package does not expose keeps
/// the library's name.
const KEYWORDS: [(Field, &str); 23] = [
    (Field::TimeColumn, "time_col"),
    (Field::TrackColumn, "track_col"),
    (Field::BiasColumn, "bias_col"),
    (Field::BiasUnit, "bias_unit"),
    (Field::PositionUnit, "track_unit"),
    (Field::Sequence, "sequence"),
    (Field::Disabled, "disable"),
    (Field::SeekCount, "n"),
    (Field::Span, "span"),
    (Field::Center, "center"),
    (Field::DwellMin, "dwell_min"),
    (Field::DwellMax, "dwell_max"),
    (Field::RankTolerance, "rank_tolerance"),
    (Field::Grid, "grid"),
    (Field::Refine, "refine"),
    (Field::Folds, "folds"),
    (Field::Alpha, "alpha"),
    (Field::Permutations, "permutations"),
    (Field::VerifyFolds, "verify_folds"),
    (Field::MaxSteps, "max_steps"),
    (Field::LadderTerms, "terms"),
    (Field::PanelTop, "top"),
    (Field::OutlierThreshold, "threshold"),
];

/// How this package names `field` in a message: its keyword (`track_col`, `window_um`), or
/// the library's name where no argument sets it.
fn keyword(field: Field) -> &'static str {
    KEYWORDS
        .iter()
        .find(|(f, _)| *f == field)
        .map(|(_, k)| *k)
        .or(field.file_key())
        .unwrap_or(field.name())
}

/// The length of the value a hint gives after a setting's name (`ColumnMap::track position_m`
/// in "name it with …" or "name them: … …"): the bytes of ` VALUE` where one word follows the
/// name and ends the clause (the text's end, `,`, `;`, `)`, or the next setting's name); 0
/// elsewhere.
fn hinted_value(rest: &str) -> usize {
    let Some(tail) = rest.strip_prefix(' ') else {
        return 0;
    };
    let word = tail
        .find(|c: char| c.is_whitespace() || matches!(c, ',' | ';' | ')'))
        .unwrap_or(tail.len());
    let after = &tail[word..];
    let next = after.trim_start();
    let ends = after.is_empty()
        || after.starts_with([',', ';', ')'])
        || Field::ALL.iter().any(|f| next.starts_with(f.name()));
    if word == 0 || !ends { 0 } else { 1 + word }
}

/// `text` with every whole occurrence of a library setting name replaced by this package's
/// name for it ([`keyword`], through [`Field::rename_in`]), and a hint's value after it written
/// as the argument (`ColumnMap::track position_m` → `track_col="position_m"`): the Python side
/// of the command line's `--track-col position_m` in the same messages.
pub(crate) fn with_keywords(text: &str) -> String {
    Field::rename_in(text, |f, rest| match hinted_value(rest) {
        0 => (keyword(f).to_string(), 0),
        n => (format!("{}=\"{}\"", keyword(f), &rest[1..n]), n),
    })
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
