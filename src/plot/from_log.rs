//! Quick-look plots of a measurement log with no model: the paper's Figs. 3–9/12 views of your
//! own data. The seek history is replayed over every row (unmeasured rows move the head too);
//! only rows with a measured bias are plotted. Axes are labelled in the log's units
//! ([`crate::log::LogSchema::units`]).
//!
//! ```
//! use biasctl::{ColumnMap, Log};
//! use biasctl::plot::from_log;
//! let text = "time_s,track,bias\n0,100,5\n1,400,9\n2,200,3\n3,300,7\n";
//! let log = Log::from_reader("t.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
//! let svg = from_log::bias_vs_position(&log);
//! assert!(svg.contains(r#"data-name="inbound""#));
//! assert!(svg.contains("bias (counts)") && svg.contains("position (tracks)"));
//! ```

use super::figures::{BiasVsPosition, BiasVsTime, bias_label, fig4_bias_vs_time, position_chart};
use super::svg::{Chart, Series, SeriesData};
use crate::history::{SeekFeatures, replay};
use crate::log::Log;

/// The history features and measured bias of every measured row.
fn measured(log: &Log) -> Vec<(SeekFeatures, f64)> {
    replay(log)
        .filter_map(|(_, r, f)| r.bias.map(|b| (f, b)))
        .collect()
}

/// Bias vs position, split by the direction of the last move (inbound, outbound; rows measured
/// before the head first moved form a third series "not moved yet" when there are any).
pub fn bias_vs_position(log: &Log) -> String {
    bias_vs_position_with_fit(log, Vec::new(), Vec::new())
}

/// [`bias_vs_position`] with fitted inbound and outbound curves `(track, bias)` drawn as lines
/// (an empty curve is left out).
pub fn bias_vs_position_with_fit(
    log: &Log,
    inbound_fit: Vec<(f64, f64)>,
    outbound_fit: Vec<(f64, f64)>,
) -> String {
    let mut d = BiasVsPosition {
        inbound_fit,
        outbound_fit,
        units: log.schema.units.clone(),
        ..Default::default()
    };
    let mut still = Vec::new();
    for (f, b) in measured(log) {
        match f.direction {
            1.. => d.inbound.push((f.target, b)),
            ..=-1 => d.outbound.push((f.target, b)),
            0 => still.push((f.target, b)),
        }
    }
    let mut c = position_chart(&d, &format!("{}: bias vs position", log.schema.file));
    if !still.is_empty() {
        c = c.series(Series::new("not moved yet", SeriesData::Scatter(still)).color(2));
    }
    c.to_svg()
}

/// The track with the most measured rows (the smallest such track on a tie); `None` without
/// measured rows.
pub fn busiest_track(log: &Log) -> Option<f64> {
    let mut tracks: Vec<f64> = log
        .rows()
        .filter(|r| r.bias.is_some())
        .map(|r| r.track)
        .collect();
    tracks.sort_by(f64::total_cmp);
    let mut best: Option<(f64, usize)> = None;
    for run in tracks.chunk_by(|a, b| a.total_cmp(b).is_eq()) {
        if best.is_none_or(|(_, n)| run.len() > n) {
            best = Some((run[0], run.len()));
        }
    }
    best.map(|(t, _)| t)
}

/// `plot time --track T` asked for a track where the log has no measured row.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "{file} has no measured row at {column} {track} {unit}; leave the track out to plot the most-measured one"
)]
pub struct NoDataAtTrack {
    /// The log file.
    pub file: String,
    /// The log's position column.
    pub column: String,
    /// The track asked for.
    pub track: f64,
    /// The log's position unit.
    pub unit: String,
}

/// Checks that `log` has a measured row at `track` (exactly), as [`bias_vs_time`] needs to draw
/// more than a "no data" panel.
pub fn check_track(log: &Log, track: f64) -> Result<(), NoDataAtTrack> {
    let measured = log
        .rows()
        .any(|r| r.bias.is_some() && r.track.total_cmp(&track).is_eq());
    if measured {
        Ok(())
    } else {
        Err(NoDataAtTrack {
            file: log.schema.file.clone(),
            column: log.schema.map.track.clone(),
            track,
            unit: log.schema.units.position.clone(),
        })
    }
}

/// Bias vs time at one track: the given one, or else the track with the most measured rows.
pub fn bias_vs_time(log: &Log, track: Option<f64>) -> String {
    let track = track.or_else(|| busiest_track(log));
    let points = match track {
        Some(t) => log
            .rows()
            .filter(|r| r.track.total_cmp(&t).is_eq())
            .filter_map(|r| r.bias.map(|b| (r.time_s, b)))
            .collect(),
        None => Vec::new(),
    };
    let fit = approach_fit(&points).map_or_else(Vec::new, |f| f.curve(&points));
    fig4_bias_vs_time(&BiasVsTime {
        track: track.unwrap_or(f64::NAN),
        points,
        fit,
        units: log.schema.units.clone(),
    })
}

/// An exponential approach to a constant, b(t) = c + a·e^(−(t − t0)/τ): the paper's time-at-track
/// effect (P3), fitted to the measurements at one track.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ApproachFit {
    /// The constant approached, bias unit.
    pub c: f64,
    /// The initial distance from it, bias unit.
    pub a: f64,
    /// The time constant, s.
    pub tau_s: f64,
    /// The time of the first measurement, s.
    pub t0: f64,
    /// Residual sum of squares, bias unit squared.
    pub rss: f64,
}

impl ApproachFit {
    /// The fitted value at `t` (s).
    pub fn at(&self, t: f64) -> f64 {
        self.c + self.a * (-(t - self.t0) / self.tau_s).exp()
    }

    /// The fitted curve at each point's time.
    pub fn curve(&self, points: &[(f64, f64)]) -> Vec<(f64, f64)> {
        points.iter().map(|&(t, _)| (t, self.at(t))).collect()
    }
}

/// Least-squares fit of [`ApproachFit`] to `(time s, bias)` points: for each τ on a
/// logarithmic grid from a tenth of a sample interval to ten times the span, c and a are the
/// closed-form least-squares solution; the τ with the smallest residual wins. `None` for fewer
/// than four points or no time span.
pub fn approach_fit(points: &[(f64, f64)]) -> Option<ApproachFit> {
    if points.len() < 4 {
        return None;
    }
    let t0 = points.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
    let t1 = points.iter().map(|p| p.0).fold(f64::NEG_INFINITY, f64::max);
    let span = t1 - t0;
    if span <= 0.0 {
        return None;
    }
    let n = points.len() as f64;
    let (lo, hi) = ((span / n / 10.0).ln(), (10.0 * span).ln());
    let mut best: Option<ApproachFit> = None;
    for i in 0..=400 {
        let tau_s = (lo + (hi - lo) * i as f64 / 400.0).exp();
        let (mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0);
        for &(t, b) in points {
            let x = (-(t - t0) / tau_s).exp();
            sx += x;
            sy += b;
            sxx += x * x;
            sxy += x * b;
        }
        let det = n * sxx - sx * sx;
        if det.abs() <= f64::EPSILON * n * sxx {
            continue;
        }
        let a = (n * sxy - sx * sy) / det;
        let c = (sy - a * sx) / n;
        let fit = ApproachFit {
            c,
            a,
            tau_s,
            t0,
            rss: 0.0,
        };
        let rss = points.iter().map(|&(t, b)| (b - fit.at(t)).powi(2)).sum();
        if best.is_none_or(|f| rss < f.rss) {
            best = Some(ApproachFit { rss, ..fit });
        }
    }
    best
}

/// Bias vs signed seek length (positive = inbound), split by whether the seek reversed the
/// direction of the move into its source.
pub fn bias_vs_seek_length(log: &Log) -> String {
    let (mut change, mut same) = (Vec::new(), Vec::new());
    for (f, b) in measured(log) {
        if f.direction_change {
            change.push((f.seek_length, b));
        } else {
            same.push((f.seek_length, b));
        }
    }
    let units = &log.schema.units;
    Chart::new(format!("{}: bias vs signed seek length", log.schema.file))
        .x_label(format!(
            "signed seek length, + inbound ({})",
            units.position
        ))
        .y_label(bias_label(units))
        .series(Series::new("direction change at source", SeriesData::Scatter(change)).color(0))
        .series(Series::new("no direction change", SeriesData::Scatter(same)).color(1))
        .to_svg()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: noise-free points from a known approach (c = 87, a = 12, τ = 2.5 s) must be
    /// recovered to the grid's resolution in τ (1 %) and c, a to well under a count.
    #[test]
    fn approach_fit_recovers_a_known_exponential() {
        let pts: Vec<(f64, f64)> = (0..100)
            .map(|i| {
                let t = 0.35 + 0.1 * i as f64;
                (t, 87.0 + 12.0 * (-(t - 0.35) / 2.5).exp())
            })
            .collect();
        let f = approach_fit(&pts).expect("fit");
        assert!((f.tau_s - 2.5).abs() < 0.025, "{f:?}");
        assert!(
            (f.c - 87.0).abs() < 0.05 && (f.a - 12.0).abs() < 0.05,
            "{f:?}"
        );
        assert!(approach_fit(&pts[..3]).is_none());
        assert!(approach_fit(&[(1.0, 1.0); 5]).is_none());
    }
}
