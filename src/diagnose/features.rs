//! The candidate features of every measured row: the seek history replayed over the whole log,
//! plus every covariate column, aligned with the rows that carry a measured bias.

use std::sync::Arc;

use crate::history::{Feature, replay};
use crate::log::{Log, Units};
use crate::model::terms::lag::FirstOrderLag;
use crate::model::terms::memsum::MemsumState;

use super::DiagnoseError;
pub(crate) use super::column::FeatureOrigin;
use super::column::{Builder, FeatureColumn, PositionGrid, TimesBuilder, Values, grid_of, stored};
use super::values::short;

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
pub(crate) fn lagged_column(name: &str) -> Option<&str> {
    name.rsplit_once("@lag").map(|(c, _)| c)
}

/// Candidate features aligned with the measured rows of a log.
///
/// Built with [`FeatureTable::from_log`]: the [`History`](crate::history::History) is replayed over **all** rows (a move
/// that was not measured still changes direction, reversals and rest memory), and the values are
/// kept only for rows with a measured bias, so they line up with one residual per measured row.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FeatureTable {
    lines: Lines,
    columns: Vec<FeatureColumn>,
    units: Units,
}

/// The log line numbers of the measured rows, as runs of consecutive lines (a log without
/// comment lines or unmeasured rows between its rows is one run): a few bytes in all instead
/// of 8 a row.
#[derive(Debug, Clone, PartialEq, Default)]
struct Lines {
    /// `(first row, its line)` of each run, rows increasing; row `i` of the run starting at
    /// row `r` with line `l` is on line `l + (i − r)`. Maximal runs, so equal line lists have
    /// equal runs.
    runs: Arc<[(usize, u64)]>,
    len: usize,
}

impl Lines {
    fn new(lines: impl IntoIterator<Item = u64>) -> Lines {
        let mut b = LinesBuilder::default();
        lines.into_iter().for_each(|l| b.push(l));
        b.finish()
    }

    fn get(&self, i: usize) -> Option<u64> {
        if i >= self.len {
            return None;
        }
        let run = self.runs.partition_point(|&(r, _)| r <= i);
        let (r, l) = self.runs[run.checked_sub(1)?];
        Some(l + (i - r) as u64)
    }
}

/// [`Lines`] built line by line.
#[derive(Debug, Default)]
struct LinesBuilder {
    runs: Vec<(usize, u64)>,
    len: usize,
}

impl LinesBuilder {
    #[inline]
    fn push(&mut self, line: u64) {
        let continues = self
            .runs
            .last()
            .is_some_and(|&(r, l)| l.checked_add((self.len - r) as u64) == Some(line));
        if !continues {
            self.runs.push((self.len, line));
        }
        self.len += 1;
    }

    fn finish(self) -> Lines {
        Lines {
            runs: self.runs.into(),
            len: self.len,
        }
    }
}

/// The `memsum_L` features at [`MEMSUM_FRACTIONS`] of the log's travel (none if it never moves).
fn summed_memory(log: &Log) -> Vec<FeatureColumn> {
    let Some(travel) = crate::numeric::stats::range(log.tracks())
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
            let mut values = Builder::with_capacity(log.measured_count());
            for row in log.rows() {
                let from = source.unwrap_or(row.track);
                if row.bias.is_some() {
                    values.push(state.value_after_move(from, row.track));
                }
                state.apply_move(from, row.track);
                source = Some(row.track);
            }
            FeatureColumn {
                name: format!("memsum_L{}", short(l)),
                origin: FeatureOrigin::SummedMemory,
                values: values.finish(),
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
                name: format!("{name}@lag{}s", short(tau)),
                origin: FeatureOrigin::Lagged,
                values: Values::from(lagged),
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
        let mut builtin: Vec<Builder> = Feature::ALL
            .iter()
            .map(|_| Builder::with_capacity(measured))
            .collect();
        let mut covariates: Vec<Vec<f64>> = log
            .schema
            .covariates
            .iter()
            .map(|_| Vec::with_capacity(measured))
            .collect();
        let mut lines = LinesBuilder::default();
        let dense = crate::history::sampling(log.times(), log.tracks()).dense;
        let mut velocity = Builder::with_capacity(if dense { measured } else { 0 });
        let grid = PositionGrid::of(log);
        let time_grid = PositionGrid::of_times(log);
        let mut times = TimesBuilder::new(log.times().first().copied(), measured, time_grid);
        let snapped: Vec<Option<PositionGrid>> = Feature::ALL
            .iter()
            .map(|&f| grid_of(f, grid, time_grid))
            .collect();
        for (_, row, f) in history {
            if row.bias.is_none() {
                continue;
            }
            lines.push(row.line);
            let dwell = f.value(Feature::DwellS).map(|d| time_grid.snap(d));
            times.push(
                row.time_s,
                stored(f.value(Feature::ElapsedS)),
                stored(dwell),
            );
            if dense {
                // The rule of `viscous::velocity` without a column: 0 at a zero dwell or a
                // quotient that is not finite.
                let l = f.value(Feature::SeekLength).map(|l| grid.snap(l));
                let v = match (l, dwell) {
                    (Some(l), Some(d)) if d > 0.0 && (l / d).is_finite() => l / d,
                    _ => 0.0,
                };
                velocity.push(v);
            }
            for ((col, &feature), &snap) in builtin.iter_mut().zip(&Feature::ALL).zip(&snapped) {
                let v = stored(f.value(feature));
                col.push(snap.map_or(v, |g| g.snap(v)));
            }
            for (k, col) in covariates.iter_mut().enumerate() {
                col.push(stored(row.covariates.get(k).filter(|v| v.is_finite())));
            }
        }
        let times = times.finish();
        let mut columns: Vec<FeatureColumn> = Feature::ALL
            .iter()
            .zip(builtin)
            .map(|(&feature, values)| FeatureColumn {
                name: feature.name().to_string(),
                origin: FeatureOrigin::BuiltIn(feature),
                values: times.values(feature).unwrap_or_else(|| values.finish()),
            })
            .collect();
        if dense {
            columns.push(FeatureColumn {
                name: DERIVED_VELOCITY.to_string(),
                origin: FeatureOrigin::DerivedVelocity,
                values: velocity.finish(),
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
            lines: lines.finish(),
            columns,
            units: log.schema.units.clone(),
        }
    }

    /// A table without features for measured rows whose log lines are `lines` (one per row,
    /// used in messages); add features with [`FeatureTable::push_column`]. Its units are counts
    /// and tracks until [`FeatureTable::with_units`] says otherwise.
    pub fn with_lines(lines: Vec<u64>) -> FeatureTable {
        FeatureTable {
            lines: Lines::new(lines),
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
        let mut stored_values = Builder::with_capacity(values.len());
        for v in values {
            stored_values.push(stored(v.filter(|x| x.is_finite())));
        }
        let values = stored_values.finish();
        self.columns.push(FeatureColumn {
            name: name.to_string(),
            origin: FeatureOrigin::Covariate,
            values,
        });
        Ok(())
    }

    /// Number of measured rows.
    pub fn len(&self) -> usize {
        self.lines.len
    }

    /// Whether the table has no measured rows.
    pub fn is_empty(&self) -> bool {
        self.lines.len == 0
    }

    /// The log line of each measured row (made from the table's runs of consecutive lines).
    pub fn lines(&self) -> Vec<u64> {
        (0..self.len()).filter_map(|i| self.line(i)).collect()
    }

    /// The log line of measured row `i` (0-based); `None` out of range.
    pub fn line(&self, i: usize) -> Option<u64> {
        self.lines.get(i)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_runs_give_back_every_line() {
        for lines in [
            vec![],
            vec![5],
            vec![2, 3, 4, 5],
            vec![2, 4, 5, 6, 9, 10, 11, 12, 40],
            vec![7, 7, 8, u64::MAX - 1, u64::MAX, 0, 1],
        ] {
            let t = FeatureTable::with_lines(lines.clone());
            assert_eq!(t.len(), lines.len());
            assert_eq!(t.lines(), lines);
            for (i, &l) in lines.iter().enumerate() {
                assert_eq!(t.line(i), Some(l));
            }
            assert_eq!(t.line(lines.len()), None);
        }
        // A run per gap, not per row.
        let t = FeatureTable::with_lines((10..1000).chain(2000..3000).collect());
        assert_eq!(t.lines.runs.len(), 2);
    }
}
