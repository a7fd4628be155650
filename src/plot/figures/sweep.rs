//! The calibration sweeps (Figs. 5–9, 12): one model-error statistic against a sweep setting,
//! one series per model.

use super::BIAS;
use crate::plot::svg::{Chart, Series, SeriesData};

/// Which calibration-table figure a [`Sweep`] is; it fixes the title and the x axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SweepFigure {
    /// Fig. 5 (Table II): bias vs tracks moved since a reversal, one-track steps (the loop).
    Fig5SeekLength,
    /// Fig. 6 (Table III): bias at a fixed target vs source offset, direction change at the
    /// source every time (overshoot/undershoot).
    Fig6SourceOffset,
    /// Fig. 7 (Table IV): bias vs source offset, no direction change at the source.
    Fig7NoDirectionChange,
    /// Fig. 8 (Table V): bias vs source offset, direction change at the source.
    Fig8DirectionChange,
    /// Fig. 9 (Table VI): bias vs offset of an earlier rest position from the target.
    Fig9RestOffset,
    /// Fig. 12 (Table VII): one N-track seek vs N one-track seeks, bias vs N.
    Fig12SeekCount,
}

impl SweepFigure {
    /// The chart title.
    pub fn title(self) -> &'static str {
        match self {
            SweepFigure::Fig5SeekLength => "Fig. 5 — bias vs tracks moved since reversal",
            SweepFigure::Fig6SourceOffset => {
                "Fig. 6 — bias vs source offset (overshoot/undershoot)"
            }
            SweepFigure::Fig7NoDirectionChange => {
                "Fig. 7 — bias vs source offset, no direction change at source"
            }
            SweepFigure::Fig8DirectionChange => {
                "Fig. 8 — bias vs source offset, direction change at source"
            }
            SweepFigure::Fig9RestOffset => "Fig. 9 — bias vs rest-position offset",
            SweepFigure::Fig12SeekCount => "Fig. 12 — one N-track seek vs N one-track seeks",
        }
    }

    /// The x-axis label, with unit.
    pub fn x_label(self) -> &'static str {
        match self {
            SweepFigure::Fig5SeekLength => "tracks moved since reversal (tracks)",
            SweepFigure::Fig6SourceOffset
            | SweepFigure::Fig7NoDirectionChange
            | SweepFigure::Fig8DirectionChange => "source offset, source − target (tracks)",
            SweepFigure::Fig9RestOffset => "rest-position offset, rest − target (tracks)",
            SweepFigure::Fig12SeekCount => "seek length N (tracks)",
        }
    }
}

/// One series of a calibration sweep.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SweepSeries {
    /// Legend name (for example "inbound", "simulated", "one N-track seek").
    pub name: String,
    /// `(x, bias counts)` with x in the figure's unit (see [`SweepFigure::x_label`]).
    pub points: Vec<(f64, f64)>,
    /// Join the points by lines in the given order (a loop or a sweep); markers only otherwise.
    pub joined: bool,
}

/// Data of Figs. 5–9 and 12: several series against one calibration variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    /// Which figure.
    pub figure: SweepFigure,
    /// The series, drawn in palette order.
    pub series: Vec<SweepSeries>,
    /// Horizontal reference levels `(label, bias counts)`, for example the inbound and outbound
    /// asymptotic curves at the target.
    pub levels: Vec<(String, f64)>,
}

/// Figs. 5–9 and 12: bias vs the sweep variable, one series per entry, reference levels dashed.
pub fn calibration_sweep(s: &Sweep) -> String {
    let mut c = Chart::new(s.figure.title())
        .x_label(s.figure.x_label())
        .y_label(BIAS);
    for (i, ser) in s.series.iter().enumerate() {
        let data = if ser.joined {
            SeriesData::Line(ser.points.clone())
        } else {
            SeriesData::Scatter(ser.points.clone())
        };
        c = c.series(Series::new(ser.name.clone(), data).color(i).markers());
    }
    for (label, y) in &s.levels {
        c = c.hline(*y, label.clone());
    }
    c.to_svg()
}
