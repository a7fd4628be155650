//! `Log`: a measurement log held by the library ([`biasctl::Log`]), read from a file with the
//! command line's reader or built from arrays through the same reader (its checks and messages).

use crate::errors::{Failure, Kind, attached, fail};
use biasctl::log::{BiasColumn, LogReader};
use biasctl::{ColumnMap, FittedModel, Log, LogError, Units};
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::borrow::Cow;
use std::io::Write;

/// A float64 numpy array handed to Python.
pub(crate) type F64Array<'py> = Bound<'py, PyArray1<f64>>;

/// A measurement log (time, position, bias and covariate columns), immutable.
#[pyclass(frozen, module = "biasctl._biasctl", name = "Log")]
pub(crate) struct PyLog {
    pub(crate) inner: Log,
    /// The reader's message for a log without its bias column (a plan): raised by the calls
    /// that need a measured bias.
    missing_bias: Option<String>,
    /// Whether the bias and position units were given as arguments (the CLI's unit flags).
    units_given: (bool, bool),
}

impl PyLog {
    /// A log made by the library (measured).
    pub(crate) fn from_log(inner: Log) -> Self {
        Self {
            inner,
            missing_bias: None,
            units_given: (false, false),
        }
    }

    /// The log, or the reader's error when it has no bias column (fit, score, diagnose need one).
    pub(crate) fn measured(&self) -> Result<&Log, Failure> {
        match &self.missing_bias {
            Some(m) => Err(Failure::new(Kind::Log, m.clone())),
            None => Ok(&self.inner),
        }
    }

    /// The units of this log read for `model`, as the command line takes them
    /// (`Units::for_model`, then `FittedModel::check_units`).
    pub(crate) fn units_for(&self, model: &FittedModel) -> Result<Units, Failure> {
        let s = &self.inner.schema;
        let mut units = s.units.clone();
        if let Some(fitted) = &model.columns.units {
            units = units.for_model(fitted, self.units_given.0, self.units_given.1, s);
        }
        model.check_units(&units).map_err(fail(Kind::Model))?;
        Ok(units)
    }

    /// The measured log in the units it has for `model` ([`PyLog::units_for`]).
    pub(crate) fn measured_for(&self, model: &FittedModel) -> Result<Cow<'_, Log>, Failure> {
        let log = self.measured()?;
        let units = self.units_for(model)?;
        if units == log.schema.units {
            return Ok(Cow::Borrowed(log));
        }
        let mut log = log.clone();
        log.schema.units = units;
        Ok(Cow::Owned(log))
    }

    /// The log as CSV text that reads back to exactly the same values (every digit a value
    /// needs; an unmeasured bias as an empty cell), with its metadata and column names.
    pub(crate) fn csv_bytes(&self) -> Vec<u8> {
        let log = &self.inner;
        let s = &log.schema;
        let mut out = Vec::with_capacity(log.len() * (24 + 8 * s.covariates.len()) + 256);
        for m in &s.metadata {
            let _ = writeln!(out, "# {m}");
        }
        let mut header = vec![s.map.time.as_str(), s.map.track.as_str()];
        if s.has_bias() {
            header.push(s.map.bias.as_str());
        }
        header.extend(s.covariates.iter().map(String::as_str));
        write_header(&mut out, &header);
        let k = s.covariates.len();
        let covs: Vec<&[f64]> = (0..k).map(|j| log.covariate(j)).collect();
        for i in 0..log.len() {
            let r = log.row(i);
            number(&mut out, r.time_s);
            out.push(b',');
            number(&mut out, r.track);
            if s.has_bias() {
                out.push(b',');
                if let Some(b) = r.bias {
                    number(&mut out, b);
                }
            }
            for c in &covs {
                out.push(b',');
                if !c[i].is_nan() {
                    number(&mut out, c[i]);
                }
            }
            out.push(b'\n');
        }
        out
    }

    /// A streaming reader over [`PyLog::csv_bytes`] (what `predict` replays, as the command
    /// line streams its file).
    pub(crate) fn reader(&self) -> Result<LogReader<std::io::Cursor<Vec<u8>>>, Failure> {
        let s = &self.inner.schema;
        let map = ColumnMap {
            time: s.map.time.clone(),
            track: s.map.track.clone(),
            bias: s.map.bias.clone(),
            delimiter: Some(b','),
        };
        let r = LogReader::from_reader_with(
            &s.file,
            std::io::Cursor::new(self.csv_bytes()),
            &map,
            BiasColumn::Optional,
        )
        .map_err(fail(Kind::Log))?;
        Ok(r)
    }
}

/// A header row in the CSV dialect biasctl reads (a name quoted when it needs it).
fn write_header(out: &mut Vec<u8>, names: &[&str]) {
    for (i, n) in names.iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        if n.contains([',', '"', '\n', '\r']) {
            out.push(b'"');
            out.extend_from_slice(n.replace('"', "\"\"").as_bytes());
            out.push(b'"');
        } else {
            out.extend_from_slice(n.as_bytes());
        }
    }
    out.push(b'\n');
}

/// A number with every digit it needs to read back exactly; non-finite as `NaN`/`inf` text,
/// which the reader refuses naming the line and column.
fn number(out: &mut Vec<u8>, x: f64) {
    let a = x.abs();
    if x.is_finite() && a != 0.0 && !(1e-5..1e16).contains(&a) {
        let _ = write!(out, "{x:e}");
    } else {
        let _ = write!(out, "{x}");
    }
}

/// The column map the readers take, from the Python arguments.
pub(crate) fn column_map(
    time_col: Option<String>,
    track_col: Option<String>,
    bias_col: Option<String>,
    delimiter: Option<&str>,
) -> Result<ColumnMap, Failure> {
    let d = ColumnMap::default();
    let delimiter = match delimiter {
        None => None,
        Some("," | "comma") => Some(b','),
        Some(";" | "semicolon") => Some(b';'),
        Some("tab" | "\\t" | "\t") => Some(b'\t'),
        Some(other) => {
            return Err(Failure::new(
                Kind::Log,
                format!(
                    "delimiter `{other}` is not a delimiter biasctl reads; use `,`, `;` or `tab`"
                ),
            ));
        }
    };
    Ok(ColumnMap {
        time: time_col.unwrap_or(d.time),
        track: track_col.unwrap_or(d.track),
        bias: bias_col.unwrap_or(d.bias),
        delimiter,
    })
}

/// Reads a log (the bias column required, as the command line does); a log whose only missing
/// column is the bias column is read as a plan, keeping the message for the calls that need it.
fn read_plan_or_log(
    read: impl Fn(BiasColumn) -> Result<Log, LogError>,
    bias_col: &str,
) -> Result<(Log, Option<String>), Failure> {
    match read(BiasColumn::Required) {
        Ok(log) => Ok((log, None)),
        Err(e @ LogError::MissingColumn { .. })
            if e.to_string().contains(&format!("`{bias_col}`")) =>
        {
            let message = biasctl::io::message(&e);
            let log = read(BiasColumn::Optional).map_err(fail(Kind::Log))?;
            Ok((log, Some(message)))
        }
        Err(e) => Err(fail(Kind::Log)(e)),
    }
}

/// Applies explicit unit labels (else the metadata or column defaults).
fn set_units(
    log: &mut Log,
    bias_unit: Option<&str>,
    track_unit: Option<&str>,
) -> Result<(), Failure> {
    log.schema.units =
        Units::resolve(bias_unit, track_unit, &log.schema).map_err(fail(Kind::Log))?;
    Ok(())
}

/// `read_log`: the command line's reader.
#[pyfunction]
#[pyo3(signature = (path, time_col=None, track_col=None, bias_col=None, bias_unit=None, track_unit=None, delimiter=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn read_log(
    py: Python<'_>,
    path: std::path::PathBuf,
    time_col: Option<String>,
    track_col: Option<String>,
    bias_col: Option<String>,
    bias_unit: Option<String>,
    track_unit: Option<String>,
    delimiter: Option<String>,
) -> PyResult<PyLog> {
    let map = column_map(time_col, track_col, bias_col, delimiter.as_deref())?;
    crate::errors::detached(py, || {
        let (mut log, missing_bias) =
            read_plan_or_log(|b| Log::read_with(&path, &map, b), &map.bias)?;
        set_units(&mut log, bias_unit.as_deref(), track_unit.as_deref())?;
        Ok(PyLog {
            inner: log,
            missing_bias,
            units_given: (bias_unit.is_some(), track_unit.is_some()),
        })
    })
}

/// `Log.from_arrays` / `Log.from_pandas`: float64 columns written as exact CSV text and read by
/// the library's reader (its checks: finite values, limits, time order; its messages name the
/// column and the line, line 2 being row 0).
#[pyfunction]
#[pyo3(signature = (source, names, columns, bias_unit=None, track_unit=None, metadata=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn log_from_columns(
    py: Python<'_>,
    source: String,
    names: Vec<String>,
    columns: Vec<PyReadonlyArray1<'_, f64>>,
    bias_unit: Option<String>,
    track_unit: Option<String>,
    metadata: Option<Vec<String>>,
) -> PyResult<PyLog> {
    // names: time, track, bias ("" when there is none), then the covariates.
    if names.len() != columns.len() + usize::from(names.get(2).is_some_and(String::is_empty))
        || names.len() < 3
    {
        return Err(Failure::new(Kind::Log, "internal: names and columns disagree").into());
    }
    let has_bias = !names[2].is_empty();
    let header: Vec<&str> = names
        .iter()
        .map(String::as_str)
        .filter(|n| !n.is_empty())
        .collect();
    let n = columns[0].len()?;
    for (name, c) in header.iter().zip(&columns) {
        let len = c.len()?;
        if len != n {
            return Err(Failure::new(
                Kind::Log,
                format!(
                    "{source}: column `{name}` has {len} values, column `{}` {n}",
                    header[0]
                ),
            )
            .into());
        }
    }
    let views: Vec<_> = columns.iter().map(|c| c.as_array()).collect();
    let mut text = Vec::with_capacity(n * 16 * views.len() + 64);
    for m in metadata.iter().flatten() {
        if m.contains(['\n', '\r']) {
            return Err(Failure::new(Kind::Log, "a metadata line holds a line break").into());
        }
        let _ = writeln!(text, "# {m}");
    }
    write_header(&mut text, &header);
    for i in 0..n {
        for (j, v) in views.iter().enumerate() {
            if j > 0 {
                text.push(b',');
            }
            let x = v[i];
            // A NaN bias is a move that was not measured, a NaN covariate a missing value: an
            // empty cell, as pandas writes it (a NaN time or position is refused by the reader).
            if !(j >= 2 && x.is_nan()) {
                number(&mut text, x);
            }
        }
        text.push(b'\n');
    }
    drop(views);
    let map = ColumnMap {
        time: names[0].clone(),
        track: names[1].clone(),
        bias: if has_bias {
            names[2].clone()
        } else {
            ColumnMap::default().bias
        },
        delimiter: Some(b','),
    };
    crate::errors::detached(py, || {
        let read = |b| Log::from_reader_with(&source, text.as_slice(), &map, b);
        let (mut log, missing_bias) = if has_bias {
            (read(BiasColumn::Required).map_err(fail(Kind::Log))?, None)
        } else {
            read_plan_or_log(read, &map.bias)?
        };
        set_units(&mut log, bias_unit.as_deref(), track_unit.as_deref())?;
        Ok(PyLog {
            inner: log,
            missing_bias,
            units_given: (bias_unit.is_some(), track_unit.is_some()),
        })
    })
}

#[pymethods]
impl PyLog {
    fn __len__(&self) -> usize {
        self.inner.len()
    }

    /// The column names: time, position, bias (when the log has one), covariates.
    #[getter]
    fn columns(&self) -> Vec<String> {
        let s = &self.inner.schema;
        let mut c = vec![s.map.time.clone(), s.map.track.clone()];
        if s.has_bias() {
            c.push(s.map.bias.clone());
        }
        c.extend(s.covariates.iter().cloned());
        c
    }

    /// The time, position and bias column names (the bias one even when absent).
    #[getter]
    fn roles(&self) -> (String, String, String) {
        let m = &self.inner.schema.map;
        (m.time.clone(), m.track.clone(), m.bias.clone())
    }

    #[getter]
    fn covariates(&self) -> Vec<String> {
        self.inner.schema.covariates.clone()
    }

    /// Whether the bias and position units were given as arguments.
    #[getter]
    fn units_given(&self) -> (bool, bool) {
        self.units_given
    }

    #[getter]
    fn has_bias(&self) -> bool {
        self.inner.schema.has_bias()
    }

    /// `{"bias": …, "position": …}`.
    #[getter]
    fn units<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("bias", &self.inner.schema.units.bias)?;
        d.set_item("position", &self.inner.schema.units.position)?;
        Ok(d)
    }

    #[getter]
    fn file(&self) -> String {
        self.inner.schema.file.clone()
    }

    #[getter]
    fn notes(&self) -> Vec<String> {
        self.inner.schema.notes.clone()
    }

    #[getter]
    fn metadata(&self) -> Vec<String> {
        self.inner.schema.metadata.clone()
    }

    /// The columns as float64 arrays, in [`PyLog::columns`] order (an unmeasured bias is NaN).
    fn arrays<'py>(&self, py: Python<'py>) -> Vec<Bound<'py, PyArray1<f64>>> {
        let log = &self.inner;
        let mut out = vec![
            PyArray1::from_slice(py, log.times()),
            PyArray1::from_slice(py, log.tracks()),
        ];
        if log.schema.has_bias() {
            let b: Vec<f64> = (0..log.len())
                .map(|i| log.bias(i).unwrap_or(f64::NAN))
                .collect();
            out.push(PyArray1::from_vec(py, b));
        }
        for k in 0..log.schema.covariates.len() {
            out.push(PyArray1::from_slice(py, log.covariate(k)));
        }
        out
    }

    /// The log as CSV text that reads back to the same values.
    fn to_csv(&self) -> PyResult<String> {
        attached(|| {
            String::from_utf8(self.csv_bytes()).map_err(|e| Failure::new(Kind::Base, e.to_string()))
        })
    }

    fn __repr__(&self) -> String {
        let s = &self.inner.schema;
        format!(
            "<biasctl.Log {}: {} rows, columns {:?}, bias in {}, position in {}>",
            s.file,
            self.inner.len(),
            self.columns(),
            s.units.bias,
            s.units.position
        )
    }
}
