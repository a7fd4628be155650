//! Running a simulation: the rows it makes ([`SimRow`], with each effect's [`Truth`]), and the
//! log and truth files it writes.

use super::SimConfig;
use super::state::DriveState;
use crate::io::{OutputError, write_atomic};
use crate::log::{Log, LogError, LogWriter, fmt_fixed};
use std::io::Write;
use std::path::Path;

/// Each effect's true contribution to one row's bias, counts.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Truth {
    /// P1.
    pub position: f64,
    /// P2: the main pivot element.
    pub direction: f64,
    /// P4/P5: the extra pivot elements.
    pub overshoot: f64,
    /// P3.
    pub time: f64,
    /// P6.
    pub memory: f64,
    /// P7.
    pub drift: f64,
    /// Temperature covariate effect.
    pub temperature: f64,
    /// P8 force scatter of this measurement (0 on unmeasured rows).
    pub scatter: f64,
    /// What the repeatable runout left in the one-revolution average (0 on unmeasured rows).
    pub runout: f64,
    /// The noiseless true bias: position + direction + overshoot + time + memory + drift +
    /// temperature.
    pub total: f64,
}

/// The truth CSV's header.
pub const TRUTH_COLUMNS: &str = "time_s,track,measured,position,direction,overshoot,time,memory,drift,temperature,scatter,runout,bias_true";

/// One simulated row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimRow {
    /// Time of the measurement, s.
    pub time_s: f64,
    /// Target track.
    pub track: f64,
    /// Measured bias, counts (`None` for a positioning move).
    pub bias: Option<f64>,
    /// Logged ambient temperature, °C (when the temperature effect is on).
    pub temp_c: Option<f64>,
    /// The true contributions.
    pub truth: Truth,
}

/// What a simulation produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimSummary {
    /// Rows.
    pub rows: u64,
    /// Measured rows.
    pub measured: u64,
    /// Simulated time at the last row, s.
    pub end_time_s: f64,
}

/// Runs the simulation, handing each row to `sink` as it is made (memory independent of the
/// number of rows). A sink error stops the run and is returned.
pub fn simulate<E>(
    config: &SimConfig,
    mut sink: impl FnMut(&SimRow) -> Result<(), E>,
) -> Result<SimSummary, E> {
    let mut state = DriveState::new(config);
    let mut summary = SimSummary {
        rows: 0,
        measured: 0,
        end_time_s: 0.0,
    };
    for step in config.steps() {
        let row = state.step(step);
        summary.rows += 1;
        summary.measured += u64::from(row.bias.is_some());
        summary.end_time_s = row.time_s;
        sink(&row)?;
    }
    Ok(summary)
}

/// An error of a simulation run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// An output file could not be written (nothing was left half-written).
    #[error(transparent)]
    Output(#[from] OutputError),
    /// The in-memory log could not be read back (a defect).
    #[error("reading the simulated log back: {0}")]
    Log(#[from] LogError),
    /// Writing to memory failed.
    #[error("writing the simulated log: {0}")]
    Io(#[from] std::io::Error),
}

fn write_log_row<W: Write>(w: &mut LogWriter<W>, row: &SimRow) -> std::io::Result<()> {
    match row.temp_c {
        Some(t) => w.write_row(row.time_s, row.track, row.bias, &[(t * 1e4).round() / 1e4]),
        None => w.write_row(row.time_s, row.track, row.bias, &[]),
    }
}

fn write_truth_row<W: Write>(w: &mut csv::Writer<W>, row: &SimRow) -> std::io::Result<()> {
    let t = &row.truth;
    w.write_record([
        fmt_fixed(row.time_s, 6),
        crate::log::fmt_float(row.track, 6),
        u8::from(row.bias.is_some()).to_string(),
        fmt_fixed(t.position, 4),
        fmt_fixed(t.direction, 4),
        fmt_fixed(t.overshoot, 4),
        fmt_fixed(t.time, 4),
        fmt_fixed(t.memory, 4),
        fmt_fixed(t.drift, 4),
        fmt_fixed(t.temperature, 4),
        fmt_fixed(t.scatter, 4),
        fmt_fixed(t.runout, 4),
        fmt_fixed(t.total, 4),
    ])?;
    Ok(())
}

/// Simulates into an in-memory [`Log`] (quick for a few thousand seeks: for other modules' tests).
pub fn simulate_log(config: &SimConfig) -> Result<Log, SimError> {
    let mut buf = Vec::new();
    {
        let mut w = LogWriter::new(&mut buf, &config.metadata(), &config.covariates())?;
        simulate(config, |row| write_log_row(&mut w, row))?;
        w.into_inner()?;
    }
    Ok(Log::from_reader(
        &format!("simulated {}", config.sequence.name()),
        buf.as_slice(),
        &crate::log::ColumnMap::default(),
    )?)
}

/// Simulates and writes the log to `out` and, if given, each effect's true contribution per row
/// to `truth` (columns [`TRUTH_COLUMNS`]). Both files are written atomically.
pub fn simulate_to_files(
    config: &SimConfig,
    out: &Path,
    truth: Option<&Path>,
) -> Result<SimSummary, SimError> {
    let mut summary = None;
    write_atomic(out, |w| -> Result<(), String> {
        let mut log = LogWriter::new(w, &config.metadata(), &config.covariates())
            .map_err(|e| e.to_string())?;
        let s = match truth {
            None => {
                simulate(config, |row| write_log_row(&mut log, row)).map_err(|e| e.to_string())?
            }
            Some(tp) => {
                let mut inner = None;
                write_atomic(tp, |tw| -> Result<(), std::io::Error> {
                    for m in config.metadata() {
                        writeln!(tw, "# {m}")?;
                    }
                    let mut tw = crate::log::csv_writer(tw);
                    tw.write_record(TRUTH_COLUMNS.split(','))?;
                    inner = Some(simulate(config, |row| {
                        write_log_row(&mut log, row)?;
                        write_truth_row(&mut tw, row)
                    })?);
                    tw.flush()?;
                    Ok(())
                })
                .map_err(|e| e.to_string())?;
                inner.ok_or("no summary")?
            }
        };
        log.into_inner().map_err(|e| e.to_string())?;
        summary = Some(s);
        Ok(())
    })?;
    Ok(summary.unwrap_or(SimSummary {
        rows: 0,
        measured: 0,
        end_time_s: 0.0,
    }))
}
