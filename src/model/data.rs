//! What the model layer needs to be fitted, below the solver ([`crate::fit`](mod@crate::fit)): the training
//! data as terms see it while they prepare ([`FitData`]), the error a fit (and a term's
//! [`TermSpec::prepare`](super::term::TermSpec::prepare)) returns ([`FitError`]) and the record
//! of how a fit ended ([`FitReport`], saved in the model file). `crate::fit` re-exports all three.

use super::{ModelError, SpecError};
use crate::history::{DirectionSource, HistoryColumns, Replay, SeekFeatures};
use crate::log::Log;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// An error fitting a model. Nothing is written when a fit fails.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FitError {
    /// The spec string is invalid.
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// The direction setting cannot be used with the log.
    #[error(transparent)]
    Direction(#[from] crate::history::DirectionError),
    /// Fewer measured rows than the model needs.
    #[error(
        "{file}: {measured} measured {}, but the model `{spec}` needs at least {needed} measured rows: it has {params} linear parameters on {} (a term whose size follows the data, such as `table` or `bins` with knots over the positions or values seen, has more on a log that spans more)",
        if *.measured == 1 { "row" } else { "rows" },
        if *.measured == 1 { "this row" } else { "these rows" }
    )]
    TooShort {
        /// The log file.
        file: String,
        /// Measured rows in the log.
        measured: usize,
        /// Linear parameters of the model as prepared on these rows (a term whose size follows
        /// the data, such as `table`'s knots over the position range, may have more on a longer
        /// log: `needed` is a lower bound).
        params: usize,
        /// Rows needed (at least).
        needed: usize,
        /// The model.
        spec: String,
    },
    /// A parameter the log cannot determine (for example `poly2` on a log at one position).
    #[error(
        "{file}: parameter `{param}` cannot be determined from this log: its column is zero or a combination of the others ({hint})"
    )]
    RankDeficient {
        /// The log file.
        file: String,
        /// Full parameter name.
        param: String,
        /// What usually causes it.
        hint: String,
    },
    /// The log lacks a covariate column a term needs.
    #[error(
        "{file}: term `{term}` needs column `{column}`, which the log lacks (covariates in the log: {available})"
    )]
    MissingCovariate {
        /// The log file.
        file: String,
        /// The term.
        term: String,
        /// The missing column.
        column: String,
        /// The covariates present.
        available: String,
    },
    /// A term reads a covariate column that has empty cells (missing values).
    #[error(
        "{file}: term `{term}` reads {cells}; a term needs a value on every row: fill the cells, or leave the term out"
    )]
    EmptyCovariate {
        /// The log file.
        file: String,
        /// The term.
        term: String,
        /// The column and its empty cells.
        cells: crate::log::EmptyCells,
    },
    /// A term names one of the log's required columns (time, position, bias) as a covariate.
    #[error(
        "{file}: term `{term}` reads column `{column}`, which is the log's {role} column, not a covariate: {hint}"
    )]
    NotACovariate {
        /// The log file.
        file: String,
        /// The term.
        term: String,
        /// The column.
        column: String,
        /// Its role: `time`, `position` or `bias`.
        role: &'static str,
        /// What to use instead.
        hint: &'static str,
    },
    /// A fit setting ([`crate::fit::FitOptions`]) is out of range.
    #[error("fit setting {field}: {message}")]
    InvalidOptions {
        /// The setting ([`Field::RankTolerance`](crate::field::Field::RankTolerance), `Grid`,
        /// `Refine`).
        field: crate::field::Field,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// A term's setting does not suit the data.
    #[error("term `{term}`: {why}")]
    BadSetting {
        /// The term.
        term: String,
        /// What is wrong.
        why: String,
    },
    /// A term could not start on this log.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The values are so large that the fit's sums of squares overflow.
    #[error(
        "{file}: the fit overflows: its residual sum of squares is not a finite number (largest |bias| {max_abs:.3e}, largest |position| {max_pos:.3e}); rescale the bias or position column"
    )]
    Overflow {
        /// The log file.
        file: String,
        /// Largest measured |bias| in the log.
        max_abs: f64,
        /// Largest |position| in the log.
        max_pos: f64,
    },
    /// A parameter in the log's units is not a finite number although the fit in centred,
    /// scaled columns succeeded: the positions' spread is so small (or large) that its powers
    /// underflow (or overflow) when the parameter is converted back.
    #[error(
        "{file}: parameter `{param}` is {value} in the log's units (position spread {spread:.3e}); rescale the position column"
    )]
    ParamOverflow {
        /// The log file.
        file: String,
        /// The parameter (`poly2.c2`, …).
        param: String,
        /// Its non-finite value.
        value: f64,
        /// Largest minus smallest position in the log.
        spread: f64,
    },
}

/// How a fit ended (saved in the model file under `fit`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FitReport {
    /// Measured rows used.
    pub rows_used: usize,
    /// Linear parameters fitted (after dropping undetermined hinge columns).
    pub parameters: usize,
    /// Standard deviation of the causal residuals on the training log, counts.
    pub residual_std: f64,
    /// RMS of the causal residuals, counts.
    pub residual_rms: f64,
    /// 1 − SS(residual)/SS(bias about its mean), causal prediction.
    pub r2: f64,
    /// Residual sum of squares of the least-squares solve (no causal offsets), counts².
    pub ls_rss: f64,
    /// Parameters fixed at 0 because the log cannot determine them.
    pub dropped: Vec<String>,
    /// Objective evaluations of the nonlinear search (0 if none).
    pub evaluations: usize,
    /// Whether every nonlinear search ended inside its interval.
    pub converged: bool,
    /// Smallest and largest target position of the measured training rows, tracks: where the
    /// position terms were fitted ([`crate::model::FittedModel::outside_range`] warns when a
    /// log goes beyond it). `null` in model files written before it was recorded.
    #[serde(default)]
    pub position_range: Option<[f64; 2]>,
}

/// A log's replayed history as refits of its rows share it ([`FitData::sharing`]): one of two
/// by the log's length ([`FEATURE_CACHE_ROWS`]).
#[derive(Debug, Clone)]
pub(crate) enum SharedHistory {
    /// A short log's replayed features.
    Features(Arc<[SeekFeatures]>),
    /// A long log's history columns, 13 B/row.
    Columns(Arc<HistoryColumns>),
}

/// The training data as terms see it while they prepare: the log, and its seek history
/// replayed on demand ([`FitData::replay`]). A log of at most 2¹⁸ rows keeps the features of
/// its first full replay (at most 27 MB) and serves the later ones from them; a longer log
/// keeps only the features that depend on the history, compactly (13 B/row,
/// `HistoryColumns`: direction, reversal, and the rows whose targets are the turning point
/// and the nearest rest positions), and steps the rest from its columns. Either way the same
/// values, bit for bit, as stepping the history (tested); a fit replays a long log three
/// times (the memory knots, the solve, the static prediction), and only the first steps the
/// direction tracker and the rest memory. The columns are built by the fit's passes over the
/// measured rows (`FitData::replay_reading`), never by a one-off [`FitData::replay`], and the
/// fit frees them after its last full replay.
#[derive(Debug, Clone)]
pub struct FitData<'a> {
    log: &'a Log,
    direction: DirectionSource,
    /// The velocity column of `direction` ([`DirectionSource::column_index`], checked).
    velocity: Option<usize>,
    /// Every row's features, kept after the first full replay of a log of at most
    /// [`FEATURE_CACHE_ROWS`] rows (a bounded cache: at most 27 MB), so the fit's later passes
    /// and the many small refits of `diagnose`'s verification read them instead of stepping
    /// the history again.
    cache: std::sync::OnceLock<Option<Arc<[SeekFeatures]>>>,
    /// Most bytes a variable-projection search may hold of the fixed block's columns
    /// (`crate::fit`'s `Projection`; beyond it they are replayed per pass: the same bits).
    fixed_budget: usize,
    /// The history features of a log of more than [`FEATURE_CACHE_ROWS`] rows, kept after
    /// the first full replay of the fit's passes (13 B/row; [`FitData::replay_reading`]).
    columns: std::sync::OnceLock<Option<Arc<HistoryColumns>>>,
}

/// Logs of at most this many rows keep their replayed seek features in [`FitData`]
/// (104 B/row: at most 27 MB); longer logs replay the history on each pass and hold nothing
/// per row.
pub(crate) const FEATURE_CACHE_ROWS: usize = 1 << 18;

/// A variable-projection search of the fit keeps its fixed block row by row up to this many
/// bytes (64 MiB; [`FitData::with_fixed_budget`]); a larger one is replayed from its terms on
/// every pass instead: the same rows and the same bits, for the CPU time of a replay of the
/// fixed terms per pass.
pub(crate) const STORED_FIXED_BYTES: usize = 64 << 20;

impl<'a> FitData<'a> {
    /// The log, its direction from raw position steps.
    pub fn new(log: &'a Log) -> Self {
        Self {
            log,
            direction: DirectionSource::Steps,
            velocity: None,
            cache: std::sync::OnceLock::new(),
            fixed_budget: STORED_FIXED_BYTES,
            columns: std::sync::OnceLock::new(),
        }
    }

    /// The log with direction read as `direction` says; an error when its velocity column is
    /// missing.
    pub fn with_direction(log: &'a Log, direction: &DirectionSource) -> Result<Self, FitError> {
        let velocity = direction.column_index(&log.schema.file, &log.schema.covariates)?;
        Ok(Self {
            log,
            direction: direction.clone(),
            velocity,
            cache: std::sync::OnceLock::new(),
            fixed_budget: STORED_FIXED_BYTES,
            columns: std::sync::OnceLock::new(),
        })
    }

    /// This data reading `shared`, the replayed history of another log with the same rows'
    /// times, positions and covariates (only the bias may differ: a history never reads it),
    /// replayed with the same direction source, instead of replaying its own: where it is the
    /// kind this log would keep (a short log's features, a long log's history columns, by
    /// [`FEATURE_CACHE_ROWS`]) and the row count matches, else unchanged. The verification's
    /// refits share one (a long log's 13 B/row once, not once per refit in flight); the same
    /// bits, so the same fit (tested in `diagnose::tests_verify`).
    pub(crate) fn sharing(self, shared: &SharedHistory) -> Self {
        let n = self.log.len();
        match shared {
            SharedHistory::Features(f) if n <= FEATURE_CACHE_ROWS && f.len() == n => {
                let _ = self.cache.set(Some(f.clone()));
            }
            SharedHistory::Columns(c) if n > FEATURE_CACHE_ROWS && c.len() == n => {
                let _ = self.columns.set(Some(c.clone()));
            }
            _ => {}
        }
        self
    }

    /// This log's replayed history as [`FitData::sharing`] takes it: a short log's features or
    /// a long log's history columns (built now if not yet); `None` where a long log has no
    /// columns (`HistoryColumns::build` refused it).
    pub(crate) fn shared_history(&self) -> Option<SharedHistory> {
        match self.cached() {
            Some(f) => Some(SharedHistory::Features(f)),
            None => self.history_columns().map(SharedHistory::Columns),
        }
    }

    /// This data with the fixed-block budget of a variable-projection search set to `bytes`
    /// (see the field).
    pub(crate) fn with_fixed_budget(mut self, bytes: usize) -> Self {
        self.fixed_budget = bytes;
        self
    }

    /// Most bytes a variable-projection search may store of its fixed block.
    pub(crate) fn fixed_budget(&self) -> usize {
        self.fixed_budget
    }

    /// The log.
    pub fn log(&self) -> &'a Log {
        self.log
    }

    /// One replay of the log's seek history (every row, measured or not, in log order), the
    /// direction read as this data's source says.
    /// On a long log it reads the history columns where the fit's passes have built them, but
    /// never builds them itself: a one-off replay (`reversal_amplitudes` in `dahl`'s
    /// preparation) would hold their 13 B/row for nothing.
    pub fn replay(&self) -> Replay<'a> {
        self.replay_building(true, false)
    }

    /// The cached features of a short log ([`FEATURE_CACHE_ROWS`]), filled by one full replay
    /// on first use; `None` for a longer log.
    fn cached(&self) -> Option<Arc<[SeekFeatures]>> {
        self.cache
            .get_or_init(|| {
                (self.log.len() <= FEATURE_CACHE_ROWS).then(|| {
                    crate::history::replay_checked(self.log, &self.direction, self.velocity, false)
                        .map(|(_, _, f)| f)
                        .collect()
                })
            })
            .clone()
    }

    /// A replay with the direction tracker and rest memory only if `reads_history` (else
    /// [`crate::history::History::step_light`]: the positional features alone). A full one of
    /// a long log builds the history columns on first use and reads them: the passes of a fit
    /// over its measured rows (a term's per-row question, the solve, the static predictions)
    /// come three to a fit.
    pub(crate) fn replay_reading(&self, reads_history: bool) -> Replay<'a> {
        self.replay_building(reads_history, true)
    }

    /// [`FitData::replay_reading`]; a full replay of a long log builds the history columns
    /// only if `build` (else it reads them if they exist and steps the history if not).
    fn replay_building(&self, reads_history: bool, build: bool) -> Replay<'a> {
        let replay = crate::history::replay_checked(
            self.log,
            &self.direction,
            self.velocity,
            !reads_history,
        );
        // A short log reads its cached features (a full replay's, which include the light
        // ones bit for bit); a light replay of a long log steps the light history, a full one
        // reads the history columns.
        match self.cached() {
            Some(c) => replay.reading_cache(c),
            None if reads_history => match if build {
                self.history_columns()
            } else {
                self.columns.get().cloned().flatten()
            } {
                Some(c) => replay.reading_columns(c, self.log),
                None => replay,
            },
            None => replay,
        }
    }

    /// The history columns of a log longer than [`FEATURE_CACHE_ROWS`], built by one full
    /// replay on first use; `None` for a shorter log (or one `HistoryColumns::build` refuses).
    fn history_columns(&self) -> Option<Arc<HistoryColumns>> {
        #[cfg(test)]
        if tests::STEP_HISTORY.load(std::sync::atomic::Ordering::Relaxed) {
            return None;
        }
        self.columns
            .get_or_init(|| {
                (self.log.len() > FEATURE_CACHE_ROWS)
                    .then(|| HistoryColumns::build(self.log, &self.direction, self.velocity))
                    .flatten()
                    .map(Arc::new)
            })
            .clone()
    }

    /// Frees the history columns and keeps later replays from building them again (they step
    /// the history): for a fit once no later replay reads them ([`crate::fit::fit`] calls it
    /// after its last full replay, or after the terms' preparation when its solve reads no
    /// history), so that their 13 B/row never add to a later peak.
    pub(crate) fn forget_history_columns(&mut self) {
        self.columns = std::sync::OnceLock::from(None);
    }

    /// Standard deviation of the measured bias (the log's bias unit; 0 with fewer than two).
    pub fn measured_bias_std(&self) -> f64 {
        let b: Vec<f64> = self.log.rows().filter_map(|r| r.bias).collect();
        crate::numeric::stats::std_dev(&b).unwrap_or(0.0)
    }

    /// Direction changes in the replayed history.
    pub fn reversals(&self) -> usize {
        self.replay().filter(|(_, _, f)| f.direction_change).count()
    }

    /// The reversal amplitudes of the replayed history: distances between consecutive turning
    /// points, position unit (`crate::history::reversal_amplitudes`).
    pub fn reversal_amplitudes(&self) -> Vec<f64> {
        crate::history::reversal_amplitudes(self.replay().map(|(_, _, f)| f))
    }

    /// `f` of every measured row, as `Option`s (in log order); one replay.
    pub fn measured_map(&self, f: impl Fn(&Seek<'_>) -> Option<f64>) -> Vec<Option<f64>> {
        let mut out = Vec::with_capacity(self.log.measured_count());
        self.each_measured(false, |s| out.push(f(s)));
        out
    }

    /// The defined values of `f` over the measured rows; one replay (into a vector sized for
    /// every measured row at once: no regrowth).
    pub fn measured_values(&self, f: impl Fn(&Seek<'_>) -> Option<f64>) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.log.measured_count());
        self.each_measured(false, |s| out.extend(f(s)));
        out
    }

    /// [`FitData::measured_values`] of [`SeekFeatures::rest_distance_ahead`]: the same values,
    /// read straight from a long log's history columns (built now if not yet) where it has
    /// them, without a replay ([`HistoryColumns::measured_rest_distances_ahead`]; tested).
    pub(crate) fn measured_rest_distances_ahead(&self) -> Vec<f64> {
        if self.cached().is_none()
            && let Some(c) = self.history_columns()
        {
            return c.measured_rest_distances_ahead(self.log.tracks(), self.log.bias_raw());
        }
        self.measured_values(|s| s.features.rest_distance_ahead())
    }

    /// [`FitData::measured_values`] of a function of the features a log's times and positions
    /// give row by row (`seek_index`, `time_s`, `elapsed_s`, `dwell_s`, `source`, `target`,
    /// `seek_length`; see [`TermCaps::reads_history`](crate::model::TermCaps::reads_history)) and the covariates: the same values, from a
    /// replay without the direction tracker and rest memory.
    pub fn measured_positional(&self, f: impl Fn(&Seek<'_>) -> Option<f64>) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.log.measured_count());
        self.each_measured(true, |s| out.extend(f(s)));
        out
    }

    /// Calls `each` with every measured row's seek, in log order.
    fn each_measured(&self, light: bool, mut each: impl FnMut(&Seek<'_>)) {
        let mut cov = Vec::with_capacity(self.log.schema.covariates.len());
        for (_, row, feat) in self.replay_reading(!light) {
            if row.bias.is_some() {
                each(&Seek {
                    features: &feat,
                    covariates: row.covariates.gather(&mut cov),
                });
            }
        }
    }

    /// Index of covariate `column`, or the error naming `term`.
    pub fn covariate(&self, column: &str, term: &str) -> Result<usize, FitError> {
        let s = &self.log.schema;
        let role = [
            (
                &s.map.time,
                "time",
                "for slow change over time use `drift` or `bins:elapsed_s`",
            ),
            (
                &s.map.track,
                "position",
                "position enters through `poly2` or `table` (or `bins:position`)",
            ),
            (
                &s.map.bias,
                "bias",
                "the bias is what the model predicts and cannot be one of its inputs",
            ),
        ]
        .into_iter()
        .find(|(name, _, _)| name.as_str() == column);
        if let Some((_, role, hint)) = role {
            return Err(FitError::NotACovariate {
                file: s.file.clone(),
                term: term.into(),
                column: column.into(),
                role,
                hint,
            });
        }
        if let Some(cells) = s.empty_cells_of(column) {
            return Err(FitError::EmptyCovariate {
                file: s.file.clone(),
                term: term.into(),
                cells: cells.clone(),
            });
        }
        s.covariate_index(column)
            .ok_or_else(|| FitError::MissingCovariate {
                file: s.file.clone(),
                term: term.into(),
                column: column.into(),
                available: if s.covariates.is_empty() {
                    "none".into()
                } else {
                    s.covariates.join(", ")
                },
            })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Makes every [`FitData`] step the history on every replay (no history columns): the
    /// reference the columns are tested against. Other tests running meanwhile only replay
    /// more slowly (the same values, bit for bit).
    pub(crate) static STEP_HISTORY: std::sync::atomic::AtomicBool =
        std::sync::atomic::AtomicBool::new(false);

    /// Held by the tests that set [`STEP_HISTORY`] or look for the columns it turns off.
    pub(crate) static STEP_LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());

    /// Reference: the stepped full replay (`history::replay_checked`), its
    /// `rest_distance_ahead` of every measured row. On a log longer than
    /// [`FEATURE_CACHE_ROWS`] with unmeasured rows, read from the history columns
    /// (`HistoryColumns::measured_rest_distances_ahead`), for position steps and a deadband,
    /// they are the same values bit for bit; on a short log (the cached features) too.
    #[test]
    fn rest_distances_ahead_from_the_columns_equal_the_stepped_replay() {
        let _lock = STEP_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        for (n, seed) in [(FEATURE_CACHE_ROWS as u64 + 3001, 4), (1500, 5)] {
            let mut log = crate::sim::random_log(n, seed);
            for i in (3..log.len()).step_by(7) {
                log.set_bias(i, None);
            }
            for direction in [
                DirectionSource::Steps,
                DirectionSource::Deadband { deadband: 2.5 },
            ] {
                let want: Vec<u64> = crate::history::replay_checked(&log, &direction, None, false)
                    .filter(|(_, row, _)| row.bias.is_some())
                    .filter_map(|(_, _, f)| f.rest_distance_ahead())
                    .map(f64::to_bits)
                    .collect();
                let data = FitData::with_direction(&log, &direction).unwrap();
                let got: Vec<u64> = data
                    .measured_rest_distances_ahead()
                    .into_iter()
                    .map(f64::to_bits)
                    .collect();
                assert!(want.len() > n as usize / 2);
                assert_eq!(got, want, "{n} rows, {direction:?}");
                let long = n as usize > FEATURE_CACHE_ROWS;
                assert_eq!(
                    data.columns.get().is_some_and(|c| c.is_some()),
                    long,
                    "{n} rows"
                );
            }
        }
    }

    /// Reference: the uncached replays (`history::replay_checked`, full and light). A short
    /// log's replays read its cache after the first: every feature of the full replay equals
    /// the stepped one bit for bit, and a light replay's positional features (what a term that
    /// reads no history may use) equal the light stepping's; the cache is filled once and
    /// shared by clones. A log above the bound keeps no cache.
    #[test]
    fn cached_replays_equal_the_stepped_ones() {
        let log = crate::sim::random_log(2000, 3);
        let data = FitData::new(&log);
        let stepped = |light: bool| -> Vec<SeekFeatures> {
            crate::history::replay_checked(&log, &DirectionSource::Steps, None, light)
                .map(|(_, _, f)| f)
                .collect()
        };
        let full = stepped(false);
        for _ in 0..2 {
            let got: Vec<SeekFeatures> = data.replay().map(|(_, _, f)| f).collect();
            assert_eq!(got.len(), full.len());
            for (a, b) in got.iter().zip(&full) {
                assert_eq!(format!("{a:?}"), format!("{b:?}"));
            }
        }
        assert!(data.cache.get().is_some_and(|c| c.is_some()));
        let light = stepped(true);
        let key = |f: &SeekFeatures| {
            [
                f.time_s,
                f.elapsed_s,
                f.dwell_s,
                f.source,
                f.target,
                f.seek_length,
            ]
            .map(f64::to_bits)
        };
        let clone = data.clone();
        let got: Vec<SeekFeatures> = clone.replay_reading(false).map(|(_, _, f)| f).collect();
        for (a, b) in got.iter().zip(&light) {
            assert_eq!(key(a), key(b));
            assert_eq!(a.seek_index, b.seek_index);
        }
        assert!(log.len() <= FEATURE_CACHE_ROWS);
        let mut text = String::from("time_s,track,bias\n");
        for i in 0..=FEATURE_CACHE_ROWS {
            text += &format!("{i},{},1\n", i % 97);
        }
        let long = Log::from_reader("long.csv", text.as_bytes(), &Default::default()).unwrap();
        let _only = STEP_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        let mut data = FitData::new(&long);
        assert_eq!(data.replay().count(), FEATURE_CACHE_ROWS + 1);
        assert!(data.cache.get().is_some_and(|c| c.is_none()));
        // Above the bound the history columns serve the full replays of the fit's passes: the
        // same features as stepping, bit for bit; a one-off replay (`replay`) and a light one
        // do not build them, and none does after `forget_history_columns`.
        assert!(data.columns.get().is_none());
        let light = FitData::new(&long);
        assert_eq!(light.replay_reading(false).count(), FEATURE_CACHE_ROWS + 1);
        assert!(light.columns.get().is_none());
        assert_eq!(data.replay_reading(true).count(), FEATURE_CACHE_ROWS + 1);
        assert!(data.columns.get().is_some_and(|c| c.is_some()));
        let stepped =
            || crate::history::replay_checked(&long, &DirectionSource::Steps, None, false);
        for ((_, _, a), (_, _, b)) in stepped().zip(data.replay()) {
            assert_eq!(format!("{a:?}"), format!("{b:?}"));
        }
        data.forget_history_columns();
        for ((_, _, a), (_, _, b)) in stepped().zip(data.replay_reading(true)) {
            assert_eq!(format!("{a:?}"), format!("{b:?}"));
        }
        assert!(data.columns.get().is_some_and(|c| c.is_none()));
    }
}

/// One seek as the terms see it: the history features and the row's covariates.
#[derive(Debug, Clone, Copy)]
pub struct Seek<'a> {
    /// Features of the seek's history ([`SeekFeatures`]).
    pub features: &'a SeekFeatures,
    /// The row's covariate values, in the order of the covariate names given to [`Term::start`](crate::model::Term::start).
    pub covariates: &'a [f64],
}
