//! The replay of a log's seek history: the `Replay` iterator over every row with its
//! features, and the turning points read from one.

use super::{DirectionError, DirectionSource, History, HistoryColumns, SeekFeatures};

/// Replays a log's seek history with direction read as `source` says; `Err` when a velocity
/// column is missing.
pub(crate) fn replay_with<'a>(
    log: &'a crate::log::Log,
    source: &DirectionSource,
) -> Result<Replay<'a>, DirectionError> {
    let velocity = source.column_index(&log.schema.file, &log.schema.covariates)?;
    Ok(replay_checked(log, source, velocity, false))
}

/// [`replay_with`] for a source already checked against `log`: `velocity` is
/// [`DirectionSource::column_index`]'s answer. With `light`, only the features a log's times
/// and positions give without the seek history are computed ([`History::step_light`]).
pub(crate) fn replay_checked<'a>(
    log: &'a crate::log::Log,
    source: &DirectionSource,
    velocity: Option<usize>,
    light: bool,
) -> Replay<'a> {
    Replay {
        rows: log.rows().enumerate(),
        history: source.history(),
        velocity,
        light,
        cached: None,
        columns: None,
    }
}

/// The turning points of a replayed log, in order: where each direction change began
/// (`target − direction·since_reversal` of every seek with `direction_change`), position unit.
pub(crate) fn turning_points(features: impl IntoIterator<Item = SeekFeatures>) -> Vec<f64> {
    features
        .into_iter()
        .filter(|f| f.direction_change)
        .map(|f| f.reversal_position())
        .collect()
}

/// The reversal amplitudes of a replayed log: distances between consecutive turning points
/// ([`turning_points`]), position unit; the travel a hysteresis loop of the log spans. Empty
/// with fewer than two reversals.
pub(crate) fn reversal_amplitudes(features: impl IntoIterator<Item = SeekFeatures>) -> Vec<f64> {
    turning_points(features)
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|a| *a > 0.0)
        .collect()
}

/// The one replay of a log's seek history: every row of `log` in order, with its index in
/// the log and its [`SeekFeatures`]. Unmeasured rows move the head too, so they are yielded
/// as well; callers that want only measured rows filter on `row.bias`. Used by the fit
/// ([`crate::model::data::FitData`]), diagnose, the plots and the report.
///
/// ```
/// use biasctl::replay;
/// use biasctl::{ColumnMap, Log};
/// let text = "time_s,track,bias\n0,100,5\n1,150,\n2,120,3\n";
/// let log = Log::from_reader("t.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
/// let seeks: Vec<f64> = replay(&log).map(|(_, _, f)| f.seek_length).collect();
/// assert_eq!(seeks, [0.0, 50.0, -30.0]);
/// let (i, row, f) = replay(&log).filter(|(_, r, _)| r.bias.is_some()).last().unwrap();
/// assert_eq!((i, row.track, f.direction), (2, 120.0, -1));
/// ```
pub fn replay(log: &crate::log::Log) -> Replay<'_> {
    Replay {
        rows: log.rows().enumerate(),
        history: History::new(),
        velocity: None,
        light: false,
        cached: None,
        columns: None,
    }
}

/// The iterator of [`replay`]: yields `(index, row, features)` for every row of a log.
#[derive(Debug, Clone)]
pub struct Replay<'a> {
    rows: std::iter::Enumerate<crate::log::Rows<'a>>,
    history: History,
    velocity: Option<usize>,
    /// Only the features of [`History::step_light`].
    light: bool,
    /// Every row's features, replayed before (`crate::model::FitData`'s bounded cache): read
    /// instead of stepping the history (the same values, bit for bit).
    cached: Option<std::sync::Arc<[SeekFeatures]>>,
    /// The history features of every row, replayed before ([`HistoryColumns`]), and the log's
    /// tracks they name: read instead of stepping the history (the same values, bit for bit).
    columns: Option<(std::sync::Arc<HistoryColumns>, &'a [f64])>,
}

impl<'a> Replay<'a> {
    /// This replay reading `features` (one per row of the log, from a full replay of it with
    /// the same direction source) instead of stepping the history.
    pub(crate) fn reading_cache(mut self, features: std::sync::Arc<[SeekFeatures]>) -> Self {
        self.cached = Some(features);
        self
    }

    /// This full replay (not light) reading `columns` (built by [`HistoryColumns::build`]
    /// from `log`, the log this replays, with the same direction source) for the history
    /// features; the positional ones are stepped ([`History::step_light`]).
    pub(crate) fn reading_columns(
        mut self,
        columns: std::sync::Arc<HistoryColumns>,
        log: &'a crate::log::Log,
    ) -> Self {
        debug_assert_eq!(columns.flags.len(), log.len());
        self.columns = (!self.light).then_some((columns, log.tracks()));
        self
    }
}

impl<'a> Iterator for Replay<'a> {
    type Item = (usize, crate::log::RowRef<'a>, SeekFeatures);

    #[inline(always)]
    fn next(&mut self) -> Option<Self::Item> {
        let (i, row) = self.rows.next()?;
        if let Some(c) = &self.cached {
            return Some((i, row, c[i]));
        }
        if self.light {
            return Some((i, row, self.history.step_light(row.time_s, row.track)));
        }
        if let Some((c, x)) = &self.columns {
            let mut f = self.history.step_light(row.time_s, row.track);
            c.fill(i, x, &mut f);
            return Some((i, row, f));
        }
        let moved = self
            .velocity
            .map(|k| DirectionSource::moved(row.covariates.get(k)));
        Some((
            i,
            row,
            self.history.step_moved(row.time_s, row.track, moved),
        ))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.rows.size_hint()
    }
}

impl ExactSizeIterator for Replay<'_> {}
