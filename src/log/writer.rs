//! Writing a log ([`LogWriter`]) in the one CSV dialect biasctl writes, and the fixed-decimal
//! number formats it uses.

use super::column_map::{DEFAULT_BIAS_COL, DEFAULT_TIME_COL, DEFAULT_TRACK_COL};
use std::io::{self, Write};

/// A CSV writer in the dialect every file biasctl writes uses: comma-separated, a field quoted
/// only when it holds a comma, a quote or a line break (a covariate named `temp,C` is written
/// `"temp,C"`), `\n` line ends. Metadata lines (`# …`) go to the underlying writer before it is
/// wrapped. Call `flush` (or `into_inner`) before the writer is dropped: a drop cannot report an
/// error.
pub(crate) fn csv_writer<W: Write>(out: W) -> csv::Writer<W> {
    csv::WriterBuilder::new()
        .terminator(csv::Terminator::Any(b'\n'))
        .from_writer(out)
}

/// Writes a log: metadata lines, the header, then rows, through `csv_writer`. Numbers are
/// written with fixed decimals (time 6, track as given with up to 6, bias 4, covariates 6) so
/// output is byte-identical for identical values; every cell holds a decimal point (`100.0`),
/// so that CSV readers that guess a column's type from its first rows (pandas, polars) read
/// every column as floats.
pub struct LogWriter<W: Write> {
    out: csv::Writer<W>,
    n_covariates: usize,
}

impl<W: Write> LogWriter<W> {
    /// Writes `metadata` (each line prefixed with `# `) and the header `time_s,track,bias,<covariates>`.
    pub fn new(mut out: W, metadata: &[String], covariates: &[String]) -> io::Result<Self> {
        for m in metadata {
            writeln!(out, "# {m}")?;
        }
        let mut out = csv_writer(out);
        out.write_record(
            [DEFAULT_TIME_COL, DEFAULT_TRACK_COL, DEFAULT_BIAS_COL]
                .into_iter()
                .chain(covariates.iter().map(String::as_str)),
        )?;
        Ok(Self {
            out,
            n_covariates: covariates.len(),
        })
    }

    /// Writes one row. `covariates` must have as many values as the header named.
    pub fn write_row(
        &mut self,
        time_s: f64,
        track: f64,
        bias: Option<f64>,
        covariates: &[f64],
    ) -> io::Result<()> {
        debug_assert_eq!(covariates.len(), self.n_covariates);
        self.out.write_field(fmt_fixed(time_s, 6))?;
        self.out.write_field(fmt_float(track, 6))?;
        self.out
            .write_field(bias.map(|b| fmt_fixed(b, 4)).unwrap_or_default())?;
        for &c in covariates {
            self.out.write_field(fmt_float(c, 6))?;
        }
        self.out.write_record(None::<&[u8]>)?;
        Ok(())
    }

    /// Flushes the rows written so far and returns the underlying writer.
    pub fn into_inner(self) -> io::Result<W> {
        self.out.into_inner().map_err(|e| e.into_error())
    }
}

/// `x` with exactly `decimals` decimals; negative zero is written as zero.
pub(crate) fn fmt_fixed(x: f64, decimals: usize) -> String {
    let s = format!("{:.*}", decimals, x);
    if s.starts_with('-') && s[1..].bytes().all(|b| b == b'0' || b == b'.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// A float cell of a CSV file: [`fmt_trimmed`], with `.0` on a whole number (`120.0`, `0.25`),
/// so that a reader guessing the column's type from its first rows takes it as a float.
pub(crate) fn fmt_float(x: f64, decimals: usize) -> String {
    let mut s = fmt_trimmed(x, decimals);
    if !s.contains('.') {
        s.push_str(".0");
    }
    s
}

/// `x` with at most `decimals` decimals and trailing zeros removed (`120`, `0.25`).
pub fn fmt_trimmed(x: f64, decimals: usize) -> String {
    let s = fmt_fixed(x, decimals);
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // values parsed from short decimal text compare exactly
mod tests {
    use super::*;
    use crate::log::{ColumnMap, Log, LogError};

    fn read(text: &str) -> Result<Log, LogError> {
        Log::from_reader("t.csv", text.as_bytes(), &ColumnMap::default())
    }

    #[test]
    fn writer_output_reads_back() {
        let mut buf = Vec::new();
        let mut w = LogWriter::new(&mut buf, &["seed = 3".into()], &["temp_c".into()]).unwrap();
        w.write_row(0.0, 100.0, Some(-0.0), &[25.5]).unwrap();
        w.write_row(0.5, 101.25, None, &[25.0]).unwrap();
        w.into_inner().unwrap();
        let text = String::from_utf8(buf).unwrap();
        assert_eq!(
            text,
            "# seed = 3\ntime_s,track,bias,temp_c\n0.000000,100.0,0.0000,25.5\n0.500000,101.25,,25.0\n"
        );
        // A covariate name with a comma or a quote is quoted, and reads back as it was.
        let mut buf = Vec::new();
        let names = ["temp,C".to_string(), "say \"hi\"".to_string()];
        let mut w = LogWriter::new(&mut buf, &[], &names).unwrap();
        w.write_row(1.0, 2.0, Some(3.0), &[4.0, 5.0]).unwrap();
        w.into_inner().unwrap();
        let quoted = String::from_utf8(buf).unwrap();
        assert!(
            quoted.starts_with("time_s,track,bias,\"temp,C\",\"say \"\"hi\"\"\"\n"),
            "{quoted}"
        );
        assert_eq!(read(&quoted).unwrap().schema.covariates, names);
        let log = read(&text).unwrap();
        assert_eq!(log.row(1).track, 101.25);
    }
}
