//! Bias models: sums of [`term::Term`]s, their unfitted specs, fitted models, replay over a log
//! and the online [`Predictor`].
//!
//! ```
//! use biasctl::ModelSpec;
//! let spec = ModelSpec::parse("poly2,dahl:4,col:temp_c").unwrap();
//! assert_eq!(spec.to_string(), "poly2,dahl:4,col:temp_c");
//! assert_eq!(ModelSpec::preset("calibration").unwrap().to_string(), "poly2,direction,seek,memory,drift");
//! assert!(ModelSpec::parse("poly2,frobnicate").is_err());
//! ```

pub(crate) mod cue;
pub(crate) mod data;
mod error;
mod predict_csv;
pub(crate) mod predictor;
pub(crate) mod preset;
pub(crate) mod registry;
mod spec;
pub(crate) mod term;
pub(crate) mod term_text;
pub mod terms;

pub use predict_csv::write_predictions_csv;
pub use predictor::{
    IntegratorStart, NextPrediction, Predictor, ReplaySummary, RowPrediction, predict_next,
    replay_stream,
};

use crate::io::{OutputError, write_string_atomic};
use crate::log::Log;
use data::FitReport;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::Path;
use std::sync::Arc;

// The namespace's public items that live in its submodules (the crate root keeps only the
// names most users need; see `biasctl::prelude`).
pub use error::{ModelError, SpecError};
pub use predictor::ReplayError;
pub use preset::{CALIBRATION, preset_terms};
pub use registry::builtin_names;
pub use spec::{ModelEdit, ModelSpec};
pub use term::{
    Nonlinear, Param, SearchBasis, SearchContext, Searched, Seek, Term, TermCaps, TermSpec,
    TermState,
};

/// Format name written into every model file.
pub(crate) const FORMAT: &str = "biasctl-model";
/// Version of the model file layout this build reads and writes.
pub(crate) const FORMAT_VERSION: u32 = 1;

/// The log columns a model was fitted on.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ColumnsUsed {
    /// Time column name.
    pub time: String,
    /// Position column name.
    pub track: String,
    /// Bias column name.
    pub bias: String,
    /// Covariate columns the terms read.
    pub covariates: Vec<String>,
    /// The units of bias and position of the log the model was fitted on (the model predicts
    /// in them); `None` in a model file written before they were recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub units: Option<crate::log::Units>,
}

/// One fitted term: the term, its coefficients (basis order) and its reported parameters.
#[derive(Debug, Clone)]
pub struct FittedTerm {
    /// The term with its data-dependent settings.
    pub term: Arc<dyn Term>,
    /// Coefficients of its basis, in [`Term::param_names`] order (0 for dropped columns).
    pub coefficients: Vec<f64>,
    /// Reported parameters with standard errors.
    pub params: Vec<Param>,
}

/// A term of a loaded model file whose spec is not built in (a user's term, rebuilt by the
/// `restore` of [`FittedModel::load_with`]): preparing it returns the fitted term as saved, so
/// a re-fit (`diagnose --path`) keeps it, with the data-dependent settings of the first fit.
#[derive(Debug, Clone)]
pub(crate) struct FittedSpec(pub Arc<dyn Term>);

impl TermSpec for FittedSpec {
    fn name(&self) -> String {
        self.0.name()
    }
    fn prepare(&self, _data: &data::FitData<'_>) -> Result<Arc<dyn Term>, data::FitError> {
        Ok(self.0.clone())
    }
}

/// A fitted model: what `biasctl fit` writes and `predict`/`score` read.
#[derive(Debug, Clone)]
pub struct FittedModel {
    /// The spec the model was fitted from, as [`TermSpec`] objects (so a user's term survives a
    /// re-fit); written to the model file as its string ([`ModelSpec`]'s `Display`).
    pub spec: ModelSpec,
    /// The columns of the training log.
    pub columns: ColumnsUsed,
    /// Fitted terms (with an `intercept` first if the spec had no term spanning a constant).
    pub terms: Vec<FittedTerm>,
    /// How the fit ended.
    pub fit: FitReport,
    /// Warnings (parameters the log cannot determine, …).
    pub warnings: Vec<String>,
    /// How the direction of motion was read from the training log; every replay of the model
    /// (predict, score, diagnose) reads it the same way. Model files without it: raw steps.
    pub direction: crate::history::DirectionSource,
}

#[derive(Serialize, Deserialize)]
struct ModelFile {
    format: String,
    version: u32,
    spec: String,
    columns: ColumnsUsed,
    terms: Vec<TermFile>,
    fit: FitReport,
    warnings: Vec<String>,
    #[serde(default)]
    direction: crate::history::DirectionSource,
}

#[derive(Serialize, Deserialize)]
struct TermFile {
    term: String,
    settings: serde_json::Value,
    coefficients: Vec<f64>,
    params: Vec<Param>,
}

/// Rebuilds a user term from its name and saved settings ([`Term::settings`]); `None` for a
/// name it does not know.
pub(crate) type RestoreFn = dyn Fn(&str, &serde_json::Value) -> Option<Arc<dyn Term>>;

/// Rows of a log that lie outside the position range a model was fitted on
/// ([`FittedModel::outside_range`]); its `Display` is the warning a command prints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeWarning {
    /// Rows outside the fitted range.
    pub outside: usize,
    /// Rows checked.
    pub total: usize,
    /// The fitted range `[min, max]`, tracks.
    pub fitted: [f64; 2],
    /// The smallest and largest of the rows outside it, tracks.
    pub seen: [f64; 2],
}

impl fmt::Display for RangeWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let fmt = |x: f64| crate::log::fmt_trimmed(x, 6);
        write!(
            f,
            "{} of {} targets ({:.1} %) lie outside the position range the model was fitted \
             on, [{}, {}] (they reach [{}, {}]): its position terms are extrapolated there",
            self.outside,
            self.total,
            100.0 * self.outside as f64 / self.total.max(1) as f64,
            fmt(self.fitted[0]),
            fmt(self.fitted[1]),
            fmt(self.seen[0]),
            fmt(self.seen[1]),
        )
    }
}

/// Per-row output of replaying a model over a log (measured rows only, in log order).
#[derive(Debug, Clone, Default)]
pub struct Prediction {
    /// Names of the terms, in contribution order.
    pub term_names: Vec<String>,
    /// Index into the log of each measured row.
    pub rows: Vec<usize>,
    /// Target position of each row, tracks.
    pub positions: Vec<f64>,
    /// Measured bias, counts.
    pub measured: Vec<f64>,
    /// Causal prediction (from earlier rows and this row's seek/time/covariates), counts.
    pub predicted: Vec<f64>,
    /// measured − predicted, counts.
    pub residual: Vec<f64>,
    /// `contributions[t][i]`: term `t`'s contribution to row `i`, counts.
    pub contributions: Vec<Vec<f64>>,
}

impl FittedModel {
    /// All reported parameters, term by term.
    pub fn params(&self) -> impl Iterator<Item = &Param> {
        self.terms.iter().flat_map(|t| t.params.iter())
    }

    /// The parameter named `name` (`poly2.c1`, `dahl.Fc`, …).
    pub fn param(&self, name: &str) -> Option<&Param> {
        self.params().find(|p| p.name == name)
    }

    /// The model file as JSON text, through the one JSON writer
    /// ([`crate::io::json::to_string_pretty`]): a non-finite coefficient or parameter is
    /// refused naming its key path (`terms[1].coefficients[0]`).
    pub fn to_json(&self) -> Result<String, OutputError> {
        let file = ModelFile {
            format: FORMAT.into(),
            version: FORMAT_VERSION,
            spec: self.spec.to_string(),
            columns: self.columns.clone(),
            direction: self.direction.clone(),
            terms: self
                .terms
                .iter()
                .map(|t| TermFile {
                    term: t.term.name(),
                    settings: t.term.settings(),
                    coefficients: t.coefficients.clone(),
                    params: t.params.clone(),
                })
                .collect(),
            fit: self.fit.clone(),
            warnings: self.warnings.clone(),
        };
        Ok(crate::io::json::to_string_pretty(&file)? + "\n")
    }

    /// Writes the model file atomically.
    pub fn save(&self, path: &Path) -> Result<(), ModelError> {
        Ok(write_string_atomic(path, &self.to_json()?)?)
    }

    /// Reads a model file with built-in terms only.
    pub fn load(path: &Path) -> Result<Self, ModelError> {
        Self::load_with(path, &|_, _| None)
    }

    /// Reads a model file; `restore` rebuilds user terms from their name and saved settings
    /// (return `None` for names it does not know; built-ins are tried after it).
    pub fn load_with(path: &Path, restore: &RestoreFn) -> Result<Self, ModelError> {
        let text = crate::log::limits::read_text(path).map_err(|source| ModelError::Io {
            path: path.into(),
            source,
        })?;
        Self::from_json(&text, path, restore)
    }

    /// Parses model JSON; `path` names it in messages.
    pub fn from_json(text: &str, path: &Path, restore: &RestoreFn) -> Result<Self, ModelError> {
        let corrupt = |why: String| ModelError::Corrupt {
            path: path.into(),
            why,
        };
        let value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| corrupt(e.to_string()))?;
        if value.get("format").and_then(|v| v.as_str()) != Some(FORMAT) {
            return Err(corrupt(format!("no `\"format\": \"{FORMAT}\"` field")));
        }
        let found = value
            .get("version")
            .and_then(|v| v.as_u64())
            .ok_or_else(|| corrupt("no version".into()))?;
        if found != u64::from(FORMAT_VERSION) {
            return Err(ModelError::Version {
                path: path.into(),
                found,
                expected: FORMAT_VERSION,
            });
        }
        let file: ModelFile = serde_json::from_value(value).map_err(|e| corrupt(e.to_string()))?;
        let mut terms = Vec::with_capacity(file.terms.len());
        for t in file.terms {
            let term = match restore(&t.term, &t.settings) {
                Some(term) => term,
                None => terms::restore_term(&t.term, &t.settings)?,
            };
            let n = term.param_names().len();
            if t.coefficients.len() != n || t.coefficients.iter().any(|c| !c.is_finite()) {
                return Err(corrupt(format!(
                    "term `{}` has {} coefficients, expected {n} finite values",
                    t.term,
                    t.coefficients.len()
                )));
            }
            terms.push(FittedTerm {
                term,
                coefficients: t.coefficients,
                params: t.params,
            });
        }
        if terms.is_empty() {
            return Err(corrupt("no terms".into()));
        }
        let spec = Self::spec_from_file(&file.spec, &terms).map_err(corrupt)?;
        if let crate::history::DirectionSource::Deadband { deadband } = file.direction
            && !(deadband.is_finite() && deadband > 0.0)
        {
            return Err(corrupt(format!(
                "direction deadband {deadband} must be finite and > 0"
            )));
        }
        Ok(FittedModel {
            spec,
            columns: file.columns,
            terms,
            fit: file.fit,
            warnings: file.warnings,
            direction: file.direction,
        })
    }

    /// The typed spec of a model file's `spec` string: built-in terms are parsed; any other
    /// item must name one of the file's (restored) terms and becomes a [`FittedSpec`].
    fn spec_from_file(list: &str, terms: &[FittedTerm]) -> Result<ModelSpec, String> {
        let mut spec = ModelSpec::default();
        if list.trim().is_empty() {
            return Ok(spec);
        }
        for item in list.split(',') {
            let term = match terms::parse_term(item) {
                Ok(t) => t,
                Err(e) => match terms.iter().find(|t| t.term.name() == item.trim()) {
                    Some(t) => Arc::new(FittedSpec(t.term.clone())),
                    None => return Err(format!("spec `{list}`: {e}")),
                },
            };
            spec = spec.with_term(term);
        }
        Ok(spec)
    }

    /// Checks that `log` has the columns this model was fitted on (names of the three required
    /// columns as read, and every covariate the terms use).
    pub fn check_log(&self, log: &Log) -> Result<(), ModelError> {
        self.check_schema(&log.schema)
    }

    /// As [`FittedModel::check_log`] for a log's header alone (a streamed log); the bias
    /// column's name is not compared when the log has none (a plan).
    pub fn check_schema(&self, schema: &crate::log::LogSchema) -> Result<(), ModelError> {
        let map = &schema.map;
        use crate::field::Field;
        for (what, model, now, field) in [
            ("time", &self.columns.time, &map.time, Field::TimeColumn),
            ("track", &self.columns.track, &map.track, Field::TrackColumn),
            ("bias", &self.columns.bias, &map.bias, Field::BiasColumn),
        ] {
            if model != now && (what != "bias" || schema.has_bias()) {
                return Err(ModelError::ColumnMismatch {
                    what,
                    model: model.clone(),
                    log: now.clone(),
                    field,
                });
            }
        }
        for (term, column) in self.covariates_read() {
            if let Some(cells) = schema.empty_cells_of(&column) {
                return Err(ModelError::EmptyCovariate {
                    file: schema.file.clone(),
                    term,
                    cells: cells.clone(),
                });
            }
        }
        Ok(())
    }

    /// Checks that `units` (a log's) are the ones the model was fitted in, when the model file
    /// records them ([`ColumnsUsed::units`]).
    pub fn check_units(&self, units: &crate::log::Units) -> Result<(), ModelError> {
        let Some(fitted) = &self.columns.units else {
            return Ok(());
        };
        use crate::field::Field;
        for (what, model, log, field) in [
            ("bias", &fitted.bias, &units.bias, Field::BiasUnit),
            (
                "position",
                &fitted.position,
                &units.position,
                Field::PositionUnit,
            ),
        ] {
            if model != log {
                return Err(ModelError::UnitMismatch {
                    what,
                    model: model.clone(),
                    log: log.clone(),
                    field,
                });
            }
        }
        Ok(())
    }

    /// Every covariate column the model reads, with the term that reads it (the direction
    /// source for a velocity column): (term, column).
    pub fn covariates_read(&self) -> Vec<(String, String)> {
        let mut read: Vec<(String, String)> = self
            .terms
            .iter()
            .flat_map(|t| {
                let name = t.term.name();
                t.term
                    .covariates()
                    .into_iter()
                    .map(move |c| (name.clone(), c))
            })
            .collect();
        if let crate::history::DirectionSource::Velocity { column } = &self.direction {
            read.push((terms::direction::HEAD.into(), column.clone()));
        }
        read
    }

    /// Which of `positions` (tracks) lie outside the position range the model was fitted on
    /// ([`FitReport::position_range`]); `None` if all lie inside or the model file predates the
    /// record. The position terms (`poly2`, `table`) are extrapolated there, so a prediction may
    /// be far off without any other sign.
    ///
    /// ```
    /// # use biasctl::{ColumnMap, FitOptions, Log, ModelSpec, fit};
    /// let csv = "time_s,track,bias\n0,100,1\n1,200,2\n2,150,1.5\n3,120,1.2\n4,180,1.8\n";
    /// let log = Log::from_reader("a.csv", csv.as_bytes(), &ColumnMap::default()).unwrap();
    /// let model = fit(&ModelSpec::parse("poly2").unwrap(), &log, &FitOptions::default().check().unwrap()).unwrap();
    /// assert_eq!(model.fit.position_range, Some([100.0, 200.0]));
    /// assert!(model.outside_range(&[120.0, 199.0]).is_none());
    /// let w = model.outside_range(&[50.0, 150.0, 260.0, 300.0]).unwrap();
    /// assert_eq!((w.outside, w.total, w.seen), (3, 4, [50.0, 300.0]));
    /// ```
    pub fn outside_range(&self, positions: &[f64]) -> Option<RangeWarning> {
        let [lo, hi] = self.fit.position_range?;
        let outside: Vec<f64> = positions
            .iter()
            .copied()
            .filter(|&x| x < lo || x > hi)
            .collect();
        let seen = crate::numeric::stats::range(&outside)?;
        Some(RangeWarning {
            outside: outside.len(),
            total: positions.len(),
            fitted: [lo, hi],
            seen,
        })
    }

    /// Replays the model over `log` from its first row (causal: each row's prediction uses only
    /// earlier rows and the row's own seek, time and covariates). Adaptive terms (`drift`) see
    /// every measured bias after its row's prediction: the one-step figure ([`Feedback::EveryRow`]).
    pub fn predict_log(&self, log: &Log) -> Result<Prediction, ModelError> {
        self.predict_log_with(log, Feedback::EveryRow)
    }

    /// Whether a term adapts to the measured bias while replaying ([`TermCaps::adaptive`]): then the
    /// one-step error ([`Feedback::EveryRow`]) and the free-run error differ.
    pub fn adaptive(&self) -> bool {
        self.terms.iter().any(|t| t.term.caps().adaptive)
    }

    /// As [`FittedModel::predict_log`], with the measured bias passed to the adaptive terms as
    /// `feedback` says (the residuals are always measured − predicted of every measured row).
    pub fn predict_log_with(
        &self,
        log: &Log,
        feedback: Feedback,
    ) -> Result<Prediction, ModelError> {
        let nt = self.terms.len();
        let m = log.measured_count();
        let mut out = Prediction {
            term_names: self.terms.iter().map(|t| t.term.name()).collect(),
            contributions: vec![Vec::with_capacity(m); nt],
            ..Default::default()
        };
        self.replay_measured(log, feedback, |row, predicted, contrib| {
            out.rows.push(row.index);
            out.positions.push(row.position);
            out.measured.push(row.measured);
            out.predicted.push(predicted);
            out.residual.push(row.measured - predicted);
            for (c, v) in out.contributions.iter_mut().zip(contrib) {
                c.push(*v);
            }
        })?;
        Ok(out)
    }

    /// The replay of [`FittedModel::predict_log_with`], streamed: `each` gets every measured
    /// row (its index, position and measured bias), its causal prediction and every term's
    /// contribution to it, in log order; nothing per row is held.
    pub(crate) fn replay_measured(
        &self,
        log: &Log,
        feedback: Feedback,
        each: impl FnMut(MeasuredRow, f64, &[f64]),
    ) -> Result<(), ModelError> {
        self.replay_measured_until(log, log.len(), feedback, each)
    }

    /// [`FittedModel::replay_measured`] of the log's first `end` rows only (the replay is
    /// causal: the same predictions for those rows as the whole log's replay gives them).
    pub(crate) fn replay_measured_until(
        &self,
        log: &Log,
        end: usize,
        feedback: Feedback,
        mut each: impl FnMut(MeasuredRow, f64, &[f64]),
    ) -> Result<(), ModelError> {
        self.check_log(log)?;
        let mut p = Predictor::new(self, &log.schema.covariates)?;
        let mut contrib = vec![0.0; self.terms.len()];
        let mut seen = 0u64;
        let mut cov = Vec::with_capacity(log.schema.covariates.len());
        for (i, row) in log.rows().enumerate().take(end) {
            let shown = row.bias.filter(|_| {
                seen += 1;
                feedback.shows(seen - 1)
            });
            let pred = p.step_detailed(
                row.time_s,
                row.track,
                row.covariates.gather(&mut cov),
                shown,
                &mut contrib,
            )?;
            if let Some(y) = row.bias {
                let row = MeasuredRow {
                    index: i,
                    position: row.track,
                    measured: y,
                };
                each(row, pred, &contrib);
            }
        }
        Ok(())
    }
}

/// A measured row as [`FittedModel::replay_measured`] hands it over.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MeasuredRow {
    /// Index of the row in the log.
    pub(crate) index: usize,
    /// Its target position.
    pub(crate) position: f64,
    /// Its measured bias.
    pub(crate) measured: f64,
}

/// How often a replay shows the measured bias to the model's adaptive terms (`drift`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum Feedback {
    /// After every measured row: the one-step-ahead error. On a densely sampled log an adaptive
    /// term then re-learns the offset from the previous sample, which flatters the model.
    #[default]
    EveryRow,
    /// After every N-th measured row only (N ≥ 1; the first measured row is shown).
    Every(u64),
    /// Never: the free-run error, what the model predicts from the positions alone.
    Never,
}

impl Feedback {
    /// From a row count: 0 = never (free run), 1 = every row, N = every N-th measured row.
    pub fn every(n: u64) -> Self {
        match n {
            0 => Feedback::Never,
            1 => Feedback::EveryRow,
            n => Feedback::Every(n),
        }
    }

    /// Whether the `k`-th measured row (0-based) is shown.
    pub fn shows(self, k: u64) -> bool {
        match self {
            Feedback::EveryRow => true,
            Feedback::Every(n) => k.is_multiple_of(n.max(1)),
            Feedback::Never => false,
        }
    }

    /// A label for texts: `one-step`, `free run`, `free run, measured bias every N rows`.
    pub fn label(self) -> String {
        match self {
            Feedback::EveryRow => "one-step".into(),
            Feedback::Every(n) => format!("free run, measured bias every {n} rows"),
            Feedback::Never => "free run".into(),
        }
    }
}
