//! `biasctl predict`'s CSV: the replay ([`replay_stream`]) on the calling thread, the rows'
//! text formatted on a second thread in chunks of [`CHUNK_ROWS`] rows and written back on the
//! calling thread, so that the replay overlaps the formatting (the larger share: shortest
//! digits for ten numbers a row) on a machine with a second core.

use super::FittedModel;
use super::predictor::{IntegratorStart, ReplayError, ReplaySummary, RowPrediction, replay_stream};
use crate::io::number::{NumberRows, RowText};
use crate::log::{LogReader, Row};
use std::io::{Read, Write};
use std::sync::mpsc;

/// Rows per chunk handed to the formatting thread: about 80 KB of values and 160 KB of text
/// (both stay in the caches), a thousand hand-offs per million rows.
const CHUNK_ROWS: usize = 1024;

/// Chunks of values waiting for the formatting thread before the replay waits for it.
const CHUNKS_QUEUED: usize = 2;

/// Streams `reader` through `model` ([`replay_stream`]) and writes `biasctl predict`'s CSV to
/// `out`: the header (time, track and bias columns as the log names them, its covariates,
/// `predicted`, `residual`, with `start` also `integrator_start`, then one column per term),
/// then one row per log row. Numbers are written with every digit they need to read back
/// exactly (`crate::io::number::write_shortest`, the text of `to_string()`); an unmeasured
/// bias, its residual, a missing covariate value, or a start value that does not exist is an
/// empty cell. With `flush_each`, every row is written and flushed as soon as it is read (a
/// stream answered row by row), all on the calling thread; without, the rows are formatted on
/// a second thread in chunks and written in order on the calling thread (the same bytes).
/// Nothing is allocated per row.
pub fn write_predictions_csv<R: Read>(
    model: &FittedModel,
    reader: &mut LogReader<R>,
    start: Option<&dyn IntegratorStart>,
    out: &mut dyn Write,
    flush_each: bool,
) -> Result<ReplaySummary, ReplayError> {
    let s = reader.schema().clone();
    let mut w = crate::log::csv_writer(out);
    let mut header: Vec<String> = vec![s.map.time.clone(), s.map.track.clone(), s.map.bias.clone()];
    header.extend(s.covariates.iter().cloned());
    header.extend(["predicted".to_string(), "residual".to_string()]);
    if start.is_some() {
        header.push("integrator_start".into());
    }
    header.extend(model.terms.iter().map(|t| t.term.name()));
    let sink_err = |e: csv::Error| ReplayError::Sink(e.into());
    w.write_record(&header).map_err(sink_err)?;
    w.flush().map_err(ReplayError::Sink)?;
    // The rows: numbers only, written without the csv writer's quoting scan (same text).
    let out = w
        .into_inner()
        .map_err(|e| ReplayError::Sink(e.into_error()))?;
    if flush_each {
        return row_by_row(model, reader, start, out, true);
    }
    pipelined(model, reader, start, out, header.len())
}

/// Appends the cells of one row of the CSV to `cells`: NaN for an empty one (a non-finite
/// value is written as an empty cell).
#[inline]
fn row_cells(cells: &mut Vec<f64>, row: &Row, p: &RowPrediction, start: bool, contrib: &[f64]) {
    // A missing covariate value (NaN: an empty cell of a covariate no term reads) stays empty.
    cells.extend([row.time_s, row.track, row.bias.unwrap_or(f64::NAN)]);
    cells.extend_from_slice(&row.covariates);
    cells.extend([p.predicted, p.residual.unwrap_or(f64::NAN)]);
    if start {
        cells.push(p.integrator_start.unwrap_or(f64::NAN));
    }
    cells.extend_from_slice(contrib);
}

/// The rows formatted and written on the calling thread, each flushed with `flush_each` (the
/// reference [`pipelined`] is tested against).
fn row_by_row<R: Read>(
    model: &FittedModel,
    reader: &mut LogReader<R>,
    start: Option<&dyn IntegratorStart>,
    out: &mut dyn Write,
    flush_each: bool,
) -> Result<ReplaySummary, ReplayError> {
    let mut rows = NumberRows::new(out);
    let mut cells: Vec<f64> = Vec::new();
    let summary = replay_stream(model, reader, start, |row, p: &RowPrediction, contrib| {
        cells.clear();
        row_cells(&mut cells, row, p, start.is_some(), contrib);
        rows.cells(&cells);
        rows.end_row()?;
        if flush_each {
            rows.flush()?;
        }
        Ok(())
    })?;
    rows.flush().map_err(ReplayError::Sink)?;
    Ok(summary)
}

/// The rows replayed on the calling thread into chunks of [`CHUNK_ROWS`] rows of `width` values,
/// formatted on a second thread ([`format_chunks`]), and written to `out` in order on the
/// calling thread as they come back, one write per chunk. The vectors go round (values back
/// with their text, the text's vector back once written): nothing is allocated per chunk
/// after the first few. Without a second thread (it cannot be started), [`row_by_row`].
fn pipelined<R: Read>(
    model: &FittedModel,
    reader: &mut LogReader<R>,
    start: Option<&dyn IntegratorStart>,
    out: &mut dyn Write,
    width: usize,
) -> Result<ReplaySummary, ReplayError> {
    let (to_format, values) = mpsc::sync_channel::<Vec<f64>>(CHUNKS_QUEUED);
    let (formatted, texts) = mpsc::channel::<(Vec<u8>, Vec<f64>)>();
    let (written, spent) = mpsc::channel::<Vec<u8>>();
    std::thread::scope(|scope| {
        let worker = std::thread::Builder::new()
            .name("predict-csv".into())
            .spawn_scoped(scope, move || {
                format_chunks(width, &values, &formatted, &spent)
            });
        if worker.is_err() {
            return row_by_row(model, reader, start, out, false);
        }
        // Writes every chunk formatted so far (all of them, once `to_format` is dropped, with
        // `wait`); their values' vectors go to `free`.
        let write_ready = |out: &mut dyn Write, wait: bool, free: &mut Vec<Vec<f64>>| {
            loop {
                let next = if wait {
                    texts.recv().ok()
                } else {
                    texts.try_recv().ok()
                };
                let Some((text, mut vals)) = next else {
                    return Ok::<(), std::io::Error>(());
                };
                out.write_all(&text)?;
                // The formatting thread has gone when it cannot take its vector back.
                let _ = written.send(text);
                vals.clear();
                free.push(vals);
            }
        };
        let mut free: Vec<Vec<f64>> = Vec::new();
        let mut chunk: Vec<f64> = Vec::with_capacity(CHUNK_ROWS * width);
        let summary = replay_stream(model, reader, start, |row, p: &RowPrediction, contrib| {
            row_cells(&mut chunk, row, p, start.is_some(), contrib);
            if chunk.len() >= CHUNK_ROWS * width {
                write_ready(out, false, &mut free)?;
                let next = free
                    .pop()
                    .unwrap_or_else(|| Vec::with_capacity(CHUNK_ROWS * width));
                let full = std::mem::replace(&mut chunk, next);
                // The formatting thread does not stop while the values come.
                to_format.send(full).map_err(std::io::Error::other)?;
            }
            Ok(())
        });
        // The last rows (also after an error: the thread then ends with the channel).
        if summary.is_ok() && !chunk.is_empty() {
            let _ = to_format.send(chunk);
        }
        drop(to_format);
        let summary = summary?;
        write_ready(out, true, &mut free).map_err(ReplayError::Sink)?;
        out.flush().map_err(ReplayError::Sink)?;
        Ok(summary)
    })
}

/// The formatting thread of [`pipelined`]: each chunk of values (`width` a row) becomes its
/// rows' text ([`RowText`]), sent back with the values' vector, until the values' channel
/// closes. Text vectors already written come back through `spent` and are reused.
fn format_chunks(
    width: usize,
    values: &mpsc::Receiver<Vec<f64>>,
    formatted: &mpsc::Sender<(Vec<u8>, Vec<f64>)>,
    spent: &mpsc::Receiver<Vec<u8>>,
) {
    let mut text = RowText::new(CHUNK_ROWS * 200);
    for vals in values {
        for row in vals.chunks(width) {
            text.cells(row);
            text.end_row();
        }
        let room = spent
            .try_recv()
            .unwrap_or_else(|_| Vec::with_capacity(CHUNK_ROWS * 200));
        if formatted.send((text.take(room), vals)).is_err() {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::{BiasColumn, ColumnMap};
    use crate::{Drive, FitOptions, ModelSpec, SequenceOptions, SimConfig, SimRng};

    /// Start values for the test: half the predicted bias, none where it is negative.
    struct Half;
    impl IntegratorStart for Half {
        fn integrator_start(&self, bias: f64) -> Option<f64> {
            (bias >= 0.0).then_some(bias / 2.0)
        }
    }

    /// A log of `n` seeks with a covariate no term reads: unmeasured rows (an empty bias) and
    /// missing covariate values (empty cells), numbers of several lengths.
    fn log_text(n: usize, seed: u64) -> String {
        let mut rng = SimRng::new(seed);
        let mut text = String::from("time_s,track,bias,temp_c\n");
        let mut t = 0.0;
        for k in 0..n {
            t += rng.range(0.01, 0.5);
            let track = rng.below(3000) as f64;
            let bias = match k % 7 {
                3 => String::new(),
                5 => format!("{}", rng.range(-200.0, 200.0)),
                _ => format!("{:.4}", rng.range(-200.0, 200.0)),
            };
            let temp = if k % 5 == 2 {
                String::new()
            } else {
                format!("{:.2}", rng.range(20.0, 60.0))
            };
            text += &format!("{t:.6},{track:.1},{bias},{temp}\n");
        }
        text
    }

    fn csv(model: &FittedModel, text: &str, start: bool, flush_each: bool) -> Vec<u8> {
        let map = ColumnMap::default();
        let mut reader =
            LogReader::from_reader_with("t.csv", text.as_bytes(), &map, BiasColumn::Optional)
                .unwrap();
        let mut out = Vec::new();
        let start = start.then_some(&Half as &dyn IntegratorStart);
        let s = write_predictions_csv(model, &mut reader, start, &mut out, flush_each).unwrap();
        assert_eq!(s.rows as usize, text.lines().count() - 1);
        out
    }

    #[test]
    fn pipelined_rows_equal_the_rows_written_one_by_one() {
        // Reference: every row formatted and written on the calling thread (`flush_each`).
        // Logs of no rows, fewer than a chunk, a chunk's worth either side, several chunks.
        let cal = SimConfig::new(
            Drive::paper1997(),
            "calibration",
            &SequenceOptions::default(),
            1,
            &[],
        )
        .unwrap();
        let model = crate::fit::fit(
            &ModelSpec::preset("calibration").unwrap(),
            &crate::simulate_log(&cal).unwrap(),
            &FitOptions::default().check().unwrap(),
        )
        .unwrap();
        for (i, n) in [
            1,
            2,
            CHUNK_ROWS - 1,
            CHUNK_ROWS,
            CHUNK_ROWS + 1,
            5 * CHUNK_ROWS + 17,
        ]
        .into_iter()
        .enumerate()
        {
            let text = log_text(n, i as u64);
            for start in [false, true] {
                let (mine, want) = (
                    csv(&model, &text, start, false),
                    csv(&model, &text, start, true),
                );
                assert_eq!(want.iter().filter(|&&b| b == b'\n').count(), n + 1);
                assert!(
                    mine == want,
                    "{n} rows, start values {start}: the texts differ"
                );
            }
        }
    }
}
