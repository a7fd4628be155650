//! Quick-look plots of a measurement log with no model: the paper's Figs. 3–9/12 views of your
//! own data. The seek history is replayed over every row (unmeasured rows move the head too);
//! only rows with a measured bias are plotted.
//!
//! ```
//! use biasctl::log::{ColumnMap, Log};
//! use biasctl::plot::from_log;
//! let text = "time_s,track,bias\n0,100,5\n1,400,9\n2,200,3\n3,300,7\n";
//! let log = Log::from_reader("t.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
//! let svg = from_log::bias_vs_position(&log);
//! assert!(svg.contains(r#"data-name="inbound""#));
//! ```

use super::figures::{BIAS, BiasVsPosition, BiasVsTime, fig4_bias_vs_time, position_chart};
use super::svg::{Chart, Series, SeriesData};
use crate::history::{History, SeekFeatures};
use crate::log::Log;

/// The history features and measured bias of every measured row.
fn measured(log: &Log) -> Vec<(SeekFeatures, f64)> {
    let mut h = History::new();
    log.rows
        .iter()
        .filter_map(|r| {
            let f = h.step(r.time_s, r.track);
            r.bias.map(|b| (f, b))
        })
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
        .rows
        .iter()
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

/// Bias vs time at one track: the given one, or else the track with the most measured rows.
pub fn bias_vs_time(log: &Log, track: Option<f64>) -> String {
    let track = track.or_else(|| busiest_track(log));
    let points = match track {
        Some(t) => log
            .rows
            .iter()
            .filter(|r| r.track.total_cmp(&t).is_eq())
            .filter_map(|r| r.bias.map(|b| (r.time_s, b)))
            .collect(),
        None => Vec::new(),
    };
    fig4_bias_vs_time(&BiasVsTime {
        track: track.unwrap_or(f64::NAN),
        points,
        fit: Vec::new(),
    })
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
    Chart::new(format!("{}: bias vs signed seek length", log.schema.file))
        .x_label("signed seek length, + inbound (tracks)")
        .y_label(BIAS)
        .series(Series::new("direction change at source", SeriesData::Scatter(change)).color(0))
        .series(Series::new("no direction change", SeriesData::Scatter(same)).color(1))
        .to_svg()
}
