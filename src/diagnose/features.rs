//! The candidate features of every measured row: the seek history replayed over the whole log,
//! plus every covariate column, aligned with the rows that carry a measured bias.

use std::sync::Arc;

use crate::history::{Feature, replay};
use crate::log::{Log, Units};
use crate::model::terms::lag::FirstOrderLag;
use crate::model::terms::memsum::MemsumState;

use super::DiagnoseError;

/// Where a candidate feature comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FeatureOrigin {
    /// A built-in feature of the seek history.
    BuiltIn(Feature),
    /// A covariate column of the log (or any column added with [`FeatureTable::push_column`]).
    Covariate,
    /// `memsum_L<L>`: the summed-kernel rest memory of the `memsum` term at one length scale
    /// L (the log's position unit): `Σ_p sgn(x − p)·exp(−|x − p|/L)` over every uncrossed rest
    /// position p ([`crate::model::terms::memsum`]).
    SummedMemory,
    /// `<COL>@lag<τ>s`: a covariate column through a first-order lag of time constant τ (s), as
    /// the `lag:COL` term computes it ([`crate::model::terms::lag`]).
    Lagged,
    /// [`DERIVED_VELOCITY`]: on a dense time series ([`crate::history::Sampling::dense`]) the
    /// velocity derived from position and time as the `viscous`/`stribeck` terms derive it
    /// without a column (`seek_length / dwell_s`, [`crate::model::terms::viscous::velocity`]),
    /// so velocity friction is found on a log with no velocity column.
    DerivedVelocity,
}

/// Name of the derived-velocity feature ([`FeatureOrigin::DerivedVelocity`]), position units
/// per second.
pub const DERIVED_VELOCITY: &str = "velocity_derived";

/// Length scales of the `memsum_L` features, as fractions of the log's travel (the range of
/// positions it visits): short, medium and long memory.
pub(super) const MEMSUM_FRACTIONS: [f64; 3] = [1.0 / 64.0, 1.0 / 16.0, 1.0 / 4.0];

/// Time constants of the lagged covariates, as points on a log scale of `[median Δt, span/16]`
/// (the log's sampling interval and a sixteenth of its duration): half-way and at the top. A
/// longer lag would be a proxy for time itself (on a random-walk drift a lag of 2/3 of the
/// span explained 38 % of it and smeared the drift onto the covariate).
pub(super) const LAG_POINTS: [f64; 2] = [0.5, 1.0];

/// Share of a column's variance a lagged copy must keep to become a feature (see [`LAG_POINTS`]):
/// a lag of a fast or noisy column keeps little of it and is only a slow random series.
pub(super) const LAG_MIN_VARIANCE: f64 = 0.5;

/// Fraction of the log's duration that is the longest lag of a lagged-covariate feature.
pub(super) const LAG_MAX_FRACTION: f64 = 1.0 / 16.0;

/// The covariate a lagged feature (`<COL>@lag<τ>s`) was made from.
pub(super) fn lagged_column(name: &str) -> Option<&str> {
    name.rsplit_once("@lag").map(|(c, _)| c)
}

/// One candidate feature's values, one per measured row; undefined (missing) on some rows.
///
/// The values are stored as plain `f64` with NaN marking an undefined row (8 bytes a row
/// instead of the 16 of an `Option<f64>`); a defined value is never NaN. Read them with
/// [`FeatureColumn::get`] or [`FeatureColumn::iter`], which give `None` for an undefined row.
/// The values are shared: a clone (as in [`FeatureTable::without`]) does not copy them.
#[derive(Debug, Clone)]
pub struct FeatureColumn {
    /// The feature's name: a built-in name (`seek_length`, …) or the covariate's header name.
    pub name: String,
    /// Built-in or covariate.
    pub origin: FeatureOrigin,
    /// One value per measured row, in log order; NaN = undefined (missing).
    values: Arc<[f64]>,
}

/// `Some(x)` unless `x` is NaN, the mark of an undefined value in a [`FeatureColumn`].
#[inline]
pub(crate) fn defined(x: f64) -> Option<f64> {
    (!x.is_nan()).then_some(x)
}

/// `v` as a stored value: NaN for `None`.
#[inline]
fn stored(v: Option<f64>) -> f64 {
    v.unwrap_or(f64::NAN)
}

impl PartialEq for FeatureColumn {
    /// Same name, origin and values, an undefined row equal to an undefined row (and a
    /// defined value equal only to the same value).
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
            && self.origin == other.origin
            && self.values.len() == other.values.len()
            && self
                .values
                .iter()
                .zip(other.values.iter())
                .all(|(&a, &b)| defined(a).map(f64::to_bits) == defined(b).map(f64::to_bits))
    }
}

impl FeatureColumn {
    /// Number of measured rows (defined or not).
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Whether the column has no rows.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// The value at measured row `i` (0-based); `None` where it is undefined or `i` is out
    /// of range.
    pub fn get(&self, i: usize) -> Option<f64> {
        self.values.get(i).copied().and_then(defined)
    }

    /// Every row's value in log order; `None` where it is undefined.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = Option<f64>> + '_ {
        self.values.iter().map(|&x| defined(x))
    }

    /// Number of rows with a defined value.
    pub fn defined_count(&self) -> usize {
        self.values.iter().filter(|x| !x.is_nan()).count()
    }

    /// The stored values: NaN = undefined (never passed on to an output).
    pub(crate) fn raw(&self) -> &[f64] {
        &self.values
    }
}

/// Candidate features aligned with the measured rows of a log.
///
/// Built with [`FeatureTable::from_log`]: the [`History`](crate::history::History) is replayed over **all** rows (a move
/// that was not measured still changes direction, reversals and rest memory), and the values are
/// kept only for rows with a measured bias, so they line up with one residual per measured row.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FeatureTable {
    lines: Arc<[u64]>,
    columns: Vec<FeatureColumn>,
    units: Units,
}

/// The `memsum_L` features at [`MEMSUM_FRACTIONS`] of the log's travel (none if it never moves).
fn summed_memory(log: &Log) -> Vec<FeatureColumn> {
    let tracks: Vec<f64> = log.rows().map(|r| r.track).collect();
    let Some(travel) = crate::numeric::stats::range(&tracks)
        .map(|[a, b]| b - a)
        .filter(|t| *t > 0.0)
    else {
        return Vec::new();
    };
    MEMSUM_FRACTIONS
        .iter()
        .map(|f| {
            let l = f * travel;
            let mut state = MemsumState::new(l);
            let mut source = None;
            let mut values = Vec::with_capacity(log.measured_count());
            for row in log.rows() {
                let from = source.unwrap_or(row.track);
                if row.bias.is_some() {
                    values.push(state.value_after_move(from, row.track));
                }
                state.apply_move(from, row.track);
                source = Some(row.track);
            }
            FeatureColumn {
                name: format!("memsum_L{}", super::advice::short(l)),
                origin: FeatureOrigin::SummedMemory,
                values: values.into(),
            }
        })
        .collect()
}

/// Every covariate through first-order lags at [`LAG_POINTS`] of `[median Δt, span/16]`
/// (none if that range is empty: a log too short or too coarse for a lag to show). `measured` holds each covariate's values at
/// the measured rows (for the skip of non-finite ones); the lag runs over every row.
fn lagged(log: &Log, measured: &[Vec<f64>]) -> Vec<FeatureColumn> {
    let times = log.times();
    let steps: Vec<f64> = times
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    let median =
        crate::numeric::stats::percentile_sorted(&crate::numeric::stats::sorted(&steps), 50.0);
    let span = times.last().map_or(0.0, |t| *t) - times.first().map_or(0.0, |t| *t);
    let hi = LAG_MAX_FRACTION * span;
    let Some(lo) = median.filter(|&m| m > 0.0 && hi > m) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (k, name) in log.schema.covariates.iter().enumerate() {
        if measured
            .get(k)
            .is_some_and(|v| v.iter().any(|x| x.is_nan()))
        {
            continue; // a gap in the column would stall the lag
        }
        let raw: &[f64] = &measured[k];
        let raw_var = crate::numeric::stats::std_dev(raw).map_or(0.0, |s| s * s);
        for p in LAG_POINTS {
            let tau = lo * (hi / lo).powf(p);
            let mut lag = FirstOrderLag::new(tau);
            let lagged: Vec<f64> = log
                .rows()
                .filter_map(|r| {
                    let z = lag.step(r.time_s, r.covariates.get(k).unwrap_or(0.0));
                    r.bias.is_some().then_some(z)
                })
                .collect();
            // A lag that keeps less than LAG_MIN_VARIANCE of the column's variance mostly
            // averages the column's own noise into a slow random series, which would match any
            // slow residual by chance: no feature then.
            let var = crate::numeric::stats::std_dev(&lagged).map_or(0.0, |s| s * s);
            if !(var >= LAG_MIN_VARIANCE * raw_var && var > 0.0) {
                continue;
            }
            out.push(FeatureColumn {
                name: format!("{name}@lag{}s", super::advice::short(tau)),
                origin: FeatureOrigin::Lagged,
                values: lagged.into(),
            });
        }
    }
    out
}

impl FeatureTable {
    /// Replays the seek history over every row of `log` and collects, for every measured row,
    /// every built-in feature ([`Feature::ALL`]), the summed-memory features `memsum_L<L>` at
    /// `MEMSUM_FRACTIONS` of the log's travel, every covariate through lags at `LAG_POINTS`
    /// (`<COL>@lag<τ>s`), and every covariate column under its header name. Non-finite covariate values are kept as missing. The log's units
    /// ([`crate::log::LogSchema::units`]) come along and label the diagnosis.
    pub fn from_log(log: &Log) -> FeatureTable {
        Self::from_replay(log, replay(log))
    }

    /// [`FeatureTable::from_log`] with the seek history of `log` replayed by `history` (for
    /// direction read another way: `crate::history::replay_with`).
    pub fn from_replay(log: &Log, history: crate::history::Replay<'_>) -> FeatureTable {
        let measured = log.measured_count();
        let mut builtin: Vec<Vec<f64>> = Feature::ALL
            .iter()
            .map(|_| Vec::with_capacity(measured))
            .collect();
        let mut covariates: Vec<Vec<f64>> = log
            .schema
            .covariates
            .iter()
            .map(|_| Vec::with_capacity(measured))
            .collect();
        let mut lines = Vec::with_capacity(measured);
        let mut velocity = Vec::with_capacity(measured);
        for (_, row, f) in history {
            if row.bias.is_none() {
                continue;
            }
            lines.push(row.line);
            // The rule of `viscous::velocity` without a column: 0 at a zero dwell or a
            // quotient that is not finite.
            let v = match (f.value(Feature::SeekLength), f.value(Feature::DwellS)) {
                (Some(l), Some(d)) if d > 0.0 && (l / d).is_finite() => l / d,
                _ => 0.0,
            };
            velocity.push(v);
            for (col, &feature) in builtin.iter_mut().zip(Feature::ALL.iter()) {
                col.push(stored(f.value(feature)));
            }
            for (k, col) in covariates.iter_mut().enumerate() {
                col.push(stored(row.covariates.get(k).filter(|v| v.is_finite())));
            }
        }
        let mut columns: Vec<FeatureColumn> = Feature::ALL
            .iter()
            .zip(builtin)
            .map(|(&feature, values)| FeatureColumn {
                name: feature.name().to_string(),
                origin: FeatureOrigin::BuiltIn(feature),
                values: values.into(),
            })
            .collect();
        let times: Vec<f64> = log.rows().map(|r| r.time_s).collect();
        let tracks: Vec<f64> = log.rows().map(|r| r.track).collect();
        if crate::history::sampling(&times, &tracks).dense {
            columns.push(FeatureColumn {
                name: DERIVED_VELOCITY.to_string(),
                origin: FeatureOrigin::DerivedVelocity,
                values: velocity.into(),
            });
        }
        columns.extend(summed_memory(log));
        columns.extend(lagged(log, &covariates));
        columns.extend(
            log.schema
                .covariates
                .iter()
                .zip(covariates)
                .map(|(name, values)| FeatureColumn {
                    name: name.clone(),
                    origin: FeatureOrigin::Covariate,
                    values: values.into(),
                }),
        );
        FeatureTable {
            lines: lines.into(),
            columns,
            units: log.schema.units.clone(),
        }
    }

    /// A table without features for measured rows whose log lines are `lines` (one per row,
    /// used in messages); add features with [`FeatureTable::push_column`]. Its units are counts
    /// and tracks until [`FeatureTable::with_units`] says otherwise.
    pub fn with_lines(lines: Vec<u64>) -> FeatureTable {
        FeatureTable {
            lines: lines.into(),
            columns: Vec::new(),
            units: Units::default(),
        }
    }

    /// The table with the residual's and position's units set to `units`.
    pub fn with_units(mut self, units: Units) -> FeatureTable {
        self.units = units;
        self
    }

    /// The units of the residual (bias) and of the position-like features.
    pub fn units(&self) -> &Units {
        &self.units
    }

    /// Adds a covariate-like feature column. Errors if its length differs from the number of
    /// measured rows or its name is already taken. Non-finite values are kept as missing.
    pub fn push_column(
        &mut self,
        name: &str,
        values: Vec<Option<f64>>,
    ) -> Result<(), DiagnoseError> {
        if values.len() != self.len() {
            return Err(DiagnoseError::ColumnLength {
                name: name.to_string(),
                values: values.len(),
                rows: self.len(),
            });
        }
        if self.column(name).is_some() {
            return Err(DiagnoseError::DuplicateColumn {
                name: name.to_string(),
            });
        }
        let values: Arc<[f64]> = values
            .into_iter()
            .map(|v| stored(v.filter(|x| x.is_finite())))
            .collect();
        self.columns.push(FeatureColumn {
            name: name.to_string(),
            origin: FeatureOrigin::Covariate,
            values,
        });
        Ok(())
    }

    /// Number of measured rows.
    pub fn len(&self) -> usize {
        self.lines.len()
    }

    /// Whether the table has no measured rows.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }

    /// The log line of each measured row.
    pub fn lines(&self) -> &[u64] {
        &self.lines
    }

    /// All feature columns: built-in features in [`Feature::ALL`] order, then covariates.
    pub fn columns(&self) -> &[FeatureColumn] {
        &self.columns
    }

    /// The column called `name`, if any.
    pub fn column(&self, name: &str) -> Option<&FeatureColumn> {
        self.columns.iter().find(|c| c.name == name)
    }

    /// This table without the columns for which `drop` is true (rows, units and origins kept).
    pub fn without(&self, drop: impl Fn(&FeatureColumn) -> bool) -> FeatureTable {
        FeatureTable {
            lines: self.lines.clone(),
            columns: self.columns.iter().filter(|c| !drop(c)).cloned().collect(),
            units: self.units.clone(),
        }
    }
}
