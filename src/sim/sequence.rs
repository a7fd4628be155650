//! Seek sequences: the paper's calibration Tables I–VII, random seeks, a dwell run, a user's
//! script, and the full calibration run.
//!
//! A sequence is a stream of [`Step`]s: seek to `target`, stay `dwell_s` seconds (the seek
//! starts right after the previous step's measurement, so `dwell_s` is the time at the target
//! when it is measured), and measure or not. "Far" is the drive's `far_tracks` (> 300: long
//! enough to put the pivot on its far curve). Tables are centred on `center` (default: the middle
//! of the stroke) and must fit in the stroke.
//!
//! | name | rows (as paper.md describes) |
//! |------|------------------------------|
//! | `table1` | for targets every `far/2` tracks across the stroke: from far OD → measure, from far ID → measure |
//! | `table2` | from far OD to `center` (measure), then 60 one-track steps outbound, then 60 back, measuring each |
//! | `table3` | far-curve references at `center`; for offsets o = ±10..±300: approach `center` moving towards the source, seek to `center+o`, back to `center`, measure |
//! | `table4` | for d = 10..300, both directions: approach the source `center−s·d` from `d+far` beyond it, continue to `center`, measure |
//! | `table5` | same sources, approached from beyond the target (`center+s·far`), reverse to `center`, measure |
//! | `table6` | reference from far OD; for p = center±5..±100: clear at far ID, rest 2 s at p, seek far OD, seek `center`, measure |
//! | `table7` | for N = 1..60: from far OD to `center`, one seek of N tracks outbound, measure |

use crate::numeric::rng::SimRng;
use std::path::Path;

/// One step of a sequence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// Target track.
    pub target: f64,
    /// Time from the previous row's measurement to this row's, s (≥ 0).
    pub dwell_s: f64,
    /// Whether the bias is measured at this row.
    pub measure: bool,
}

/// Dwell of a measured table row, s.
pub(crate) const TABLE_DWELL_S: f64 = 0.2;
/// Dwell of an unmeasured positioning move, s.
pub(crate) const MOVE_DWELL_S: f64 = 0.05;
/// Rest time at the intermediate position of Table VI, s.
pub(crate) const REST_DWELL_S: f64 = 2.0;
/// One-track steps per branch of the Table II loop (and largest N of Table VII).
pub(crate) const LOOP_STEPS: u32 = 60;

fn mv(target: f64) -> Step {
    Step {
        target,
        dwell_s: MOVE_DWELL_S,
        measure: false,
    }
}

fn meas(target: f64) -> Step {
    Step {
        target,
        dwell_s: TABLE_DWELL_S,
        measure: true,
    }
}

/// Table `n` (1..=7) centred on `center`, with far distance `far`, in a stroke `0..=max_track`.
/// Returns `None` for a table number outside 1..=7.
pub(crate) fn table(n: u8, center: f64, far: f64, max_track: f64) -> Option<Vec<Step>> {
    let c = center;
    let mut v = Vec::new();
    match n {
        1 => {
            let stepw = (far / 2.0).max(1.0).round();
            let mut x = far;
            while x + far <= max_track {
                v.extend([mv(x - far), meas(x), mv(x + far), meas(x)]);
                x += stepw;
            }
        }
        2 => {
            v.extend([mv(c - far), meas(c)]);
            for k in 1..=LOOP_STEPS {
                v.push(meas(c - f64::from(k)));
            }
            for k in (0..LOOP_STEPS).rev() {
                v.push(meas(c - f64::from(k)));
            }
        }
        3 => {
            v.extend([mv(c - far), meas(c), mv(c + far), meas(c)]);
            for o in (-30..=30).filter(|&o| o != 0) {
                let o = f64::from(o) * 10.0;
                let s = o.signum();
                v.extend([mv(c - s * far), mv(c), mv(c + o), meas(c)]);
            }
        }
        4 | 5 => {
            v.extend([mv(c - far), meas(c), mv(c + far), meas(c)]);
            for s in [1.0, -1.0] {
                for d in 1..=30 {
                    let d = f64::from(d) * 10.0;
                    let source = c - s * d;
                    let approach = if n == 4 {
                        source - s * far
                    } else {
                        c + s * far
                    };
                    v.extend([mv(approach), mv(source), meas(c)]);
                }
            }
        }
        6 => {
            v.extend([mv(c + far), mv(c - far), meas(c)]);
            for o in (-20..=20).filter(|&o| o != 0) {
                let p = c + f64::from(o) * 5.0;
                v.extend([
                    mv(c + far),
                    Step {
                        target: p,
                        dwell_s: REST_DWELL_S,
                        measure: false,
                    },
                    mv(c - far),
                    meas(c),
                ]);
            }
        }
        7 => {
            for k in 1..=LOOP_STEPS {
                v.extend([mv(c - far), mv(c), meas(c - f64::from(k))]);
            }
        }
        _ => return None,
    }
    Some(v)
}

/// Random seeks: `n` uniform whole-track targets in `[center − span/2, center + span/2]`, dwell
/// uniform in `[dwell_min_s, dwell_max_s]`, every row measured. Streams (no allocation per seek).
#[derive(Debug, Clone)]
pub(crate) struct RandomSeeks {
    lo: i64,
    width: u64,
    dwell_min_s: f64,
    dwell_max_s: f64,
    left: u64,
    rng: SimRng,
}

impl RandomSeeks {
    /// The generator; draws come from `rng`.
    pub(crate) fn new(
        n: u64,
        center: f64,
        span: f64,
        dwell_min_s: f64,
        dwell_max_s: f64,
        rng: SimRng,
    ) -> Self {
        let lo = (center - span / 2.0).ceil() as i64;
        let hi = (center + span / 2.0).floor() as i64;
        Self {
            lo,
            width: (hi - lo + 1).max(1) as u64,
            dwell_min_s,
            dwell_max_s,
            left: n,
            rng,
        }
    }
}

impl Iterator for RandomSeeks {
    type Item = Step;
    fn next(&mut self) -> Option<Step> {
        if self.left == 0 {
            return None;
        }
        self.left -= 1;
        let target = (self.lo + self.rng.below(self.width) as i64) as f64;
        let dwell_s = self.rng.range(self.dwell_min_s, self.dwell_max_s);
        Some(Step {
            target,
            dwell_s,
            measure: true,
        })
    }
}

/// The dwell run of Fig. 4: from far OD to `track`, then a measurement every `interval_s` for
/// `duration_s` (zero-length seeks: the head stays).
pub(crate) fn dwell_run(track: f64, far: f64, duration_s: f64, interval_s: f64) -> Vec<Step> {
    let mut v = vec![mv((track - far).max(0.0))];
    let n = (duration_s / interval_s).round().max(1.0) as u64;
    v.extend((0..n).map(|_| Step {
        target: track,
        dwell_s: interval_s,
        measure: true,
    }));
    v
}

/// An error in a script file; names the file, line and column.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScriptError {
    /// The file could not be read.
    #[error("{file}: cannot read script: {source}")]
    Io {
        /// The script file.
        file: String,
        /// The operating-system error.
        #[source]
        source: std::io::Error,
    },
    /// The header lacks a required column.
    #[error(
        "{file}: line {line}: missing column `{column}` (a script needs `track,dwell_s[,measure]`)"
    )]
    MissingColumn {
        /// The script file.
        file: String,
        /// 1-based line of the header.
        line: u64,
        /// The missing column.
        column: &'static str,
    },
    /// A cell is bad.
    #[error("{file}: line {line}, column {column_index} (`{column}`): {problem}: `{value}`")]
    BadValue {
        /// The script file.
        file: String,
        /// 1-based line.
        line: u64,
        /// 1-based column.
        column_index: usize,
        /// Column name.
        column: String,
        /// The cell's text.
        value: String,
        /// What is wrong.
        problem: String,
    },
    /// A row has the wrong shape.
    #[error("{file}: line {line}: {message}")]
    Malformed {
        /// The script file.
        file: String,
        /// 1-based line.
        line: u64,
        /// What is wrong.
        message: String,
    },
    /// The file is empty or holds only blank lines: no header row.
    #[error(
        "{file}: the script is empty (expected a header row `track,dwell_s[,measure]`, then one row per seek)"
    )]
    NoHeader {
        /// The script file.
        file: String,
    },
    /// No rows.
    #[error("{file}: the script has no rows")]
    Empty {
        /// The script file.
        file: String,
    },
    /// Every row has `measure` off: the log would hold no measurement, which every command
    /// that reads a log rejects.
    #[error(
        "{file}: no row of the script is measured (column `measure` is 0 on all {rows} rows): the log would have no bias to read"
    )]
    NothingMeasured {
        /// The script file.
        file: String,
        /// Rows in the script.
        rows: usize,
    },
}

/// Reads a script: CSV with header `track,dwell_s` and an optional `measure` column
/// (`1`/`0`/`true`/`false`/`yes`/`no`; default 1). Targets must lie in `0..=max_track`, dwell
/// times must be finite and ≥ 0. The spreadsheet dialects of a log are read as the log reader
/// reads them: a UTF-8 byte-order mark, the delimiter sniffed from the header (`,` `;` or tab;
/// with `;` or tab a decimal comma), header names ignoring case and surrounding spaces.
pub(crate) fn read_script(path: &Path, max_track: f64) -> Result<Vec<Step>, ScriptError> {
    let file = path.display().to_string();
    let text = crate::log::limits::read_text(path).map_err(|source| ScriptError::Io {
        file: file.clone(),
        source,
    })?;
    parse_script(&file, &text, max_track)
}

/// Parses script text (see [`read_script`]); `file` names it in messages, with the line an
/// editor shows (`\n`, `\r\n` and a lone `\r` each end one; blank lines and line breaks in
/// quoted cells count), as the log reader names it ([`crate::log::lines`]).
pub(crate) fn parse_script(
    file: &str,
    text: &str,
    max_track: f64,
) -> Result<Vec<Step>, ScriptError> {
    use crate::log::lines::{LineStarts, csv_problem};
    // A byte-order mark (spreadsheet exports write one) is not part of the header.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    // Empty or blank lines only: there is no header line to name (the csv parser would place
    // the missing header after the last line).
    if text.trim().is_empty() {
        return Err(ScriptError::NoHeader { file: file.into() });
    }
    let header = text
        .split(['\n', '\r'])
        .find(|l| !l.trim().is_empty())
        .unwrap_or("");
    let delimiter = crate::log::sniff_delimiter(header);
    let decimal_comma = delimiter != b',';
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .delimiter(delimiter)
        .from_reader(LineStarts::new(text.as_bytes(), 1));
    // The parser's own line numbers count from where it began a record (before blank lines,
    // within a CRLF); the record's physical line is the line start noted at or after that.
    let malformed =
        |rdr: &mut csv::Reader<LineStarts<&[u8]>>, e: csv::Error| ScriptError::Malformed {
            file: file.into(),
            line: e.position().map_or(0, |p| rdr.get_mut().line_at(p.byte())),
            message: csv_problem(&e),
        };
    let headers = match rdr.headers() {
        Ok(h) => h.clone(),
        Err(e) => return Err(malformed(&mut rdr, e)),
    };
    let header_line = rdr.get_mut().line_at(0);
    // The exact name, else the one name equal to it ignoring case (`Track`, `DWELL_S`).
    let col = |name: &'static str| {
        headers.iter().position(|h| h == name).or_else(|| {
            let same: Vec<usize> = (0..headers.len())
                .filter(|&i| headers[i].eq_ignore_ascii_case(name))
                .collect();
            if let [i] = same[..] { Some(i) } else { None }
        })
    };
    let missing = |column| ScriptError::MissingColumn {
        file: file.into(),
        line: header_line,
        column,
    };
    let ti = col("track").ok_or_else(|| missing("track"))?;
    let di = col("dwell_s").ok_or_else(|| missing("dwell_s"))?;
    let mi = col("measure");
    let mut steps = Vec::new();
    let mut rec = csv::StringRecord::new();
    loop {
        match rdr.read_record(&mut rec) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => return Err(malformed(&mut rdr, e)),
        }
        let line = rec
            .position()
            .map_or(0, |p| rdr.get_mut().line_at(p.byte()));
        let bad = |idx: usize, problem: String| ScriptError::BadValue {
            file: file.into(),
            line,
            column_index: idx + 1,
            column: headers[idx].to_string(),
            value: rec.get(idx).unwrap_or("").to_string(),
            problem,
        };
        let num = |idx: usize| -> Result<f64, ScriptError> {
            let v: f64 = crate::log::parse_cell(rec.get(idx).unwrap_or(""), decimal_comma)
                .ok_or_else(|| bad(idx, "not a number".into()))?;
            if v.is_finite() {
                Ok(v)
            } else {
                Err(bad(idx, "not a finite number".into()))
            }
        };
        let target = num(ti)?;
        if !(0.0..=max_track).contains(&target) {
            return Err(bad(ti, format!("track outside the stroke 0..={max_track}")));
        }
        let dwell_s = num(di)?;
        if !(0.0..=crate::log::limits::MAX_DWELL_S).contains(&dwell_s) {
            return Err(bad(di, "dwell must be within 0 … 1e6 s".into()));
        }
        let measure = match mi {
            None => true,
            Some(i) => match rec.get(i).unwrap_or("").to_ascii_lowercase().as_str() {
                "1" | "true" | "yes" | "" => true,
                "0" | "false" | "no" => false,
                _ => return Err(bad(i, "expected 1/0/true/false/yes/no".into())),
            },
        };
        steps.push(Step {
            target,
            dwell_s,
            measure,
        });
    }
    if steps.is_empty() {
        return Err(ScriptError::Empty { file: file.into() });
    }
    if !steps.iter().any(|s| s.measure) {
        return Err(ScriptError::NothingMeasured {
            file: file.into(),
            rows: steps.len(),
        });
    }
    Ok(steps)
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // whole-track positions; equality is meant
mod tests {
    use super::*;

    #[test]
    fn tables_stay_in_the_stroke_and_measure() {
        for n in 1..=7 {
            let t = table(n, 1500.0, 400.0, 2999.0).unwrap();
            assert!(t.iter().any(|s| s.measure), "table {n}");
            assert!(
                t.iter().all(|s| (0.0..=2999.0).contains(&s.target)),
                "table {n}"
            );
        }
        assert!(table(8, 1500.0, 400.0, 2999.0).is_none());
    }

    #[test]
    fn table3_reverses_at_every_source() {
        // Every measured row after the references is reached by a seek opposite to the move
        // into its source (the definition of Table III).
        let t = table(3, 1500.0, 400.0, 2999.0).unwrap();
        for w in t[4..].chunks(4) {
            let (into_src, back) = (w[2].target - w[1].target, w[3].target - w[2].target);
            assert!(into_src * back < 0.0, "{w:?}");
        }
        let t4 = table(4, 1500.0, 400.0, 2999.0).unwrap();
        for w in t4[4..].chunks(3) {
            let (into_src, on) = (w[1].target - w[0].target, w[2].target - w[1].target);
            assert!(into_src * on > 0.0, "{w:?}");
        }
        let t5 = table(5, 1500.0, 400.0, 2999.0).unwrap();
        for w in t5[4..].chunks(3) {
            let (into_src, on) = (w[1].target - w[0].target, w[2].target - w[1].target);
            assert!(into_src * on < 0.0, "{w:?}");
        }
    }

    #[test]
    fn random_seeks_cover_the_span_uniformly_with_varied_dwell() {
        let r: Vec<Step> =
            RandomSeeks::new(20_000, 1000.0, 250.0, 0.05, 0.5, SimRng::new(1)).collect();
        assert_eq!(r.len(), 20_000);
        let lo = r.iter().map(|s| s.target).fold(f64::INFINITY, f64::min);
        let hi = r.iter().map(|s| s.target).fold(f64::NEG_INFINITY, f64::max);
        assert_eq!((lo, hi), (875.0, 1125.0));
        assert!(r.iter().all(|s| (0.05..0.5).contains(&s.dwell_s)));
        // Uniform mean 1000 with std 250/√12 ≈ 72.5; standard error of the mean ≈ 0.5.
        let mean = r.iter().map(|s| s.target).sum::<f64>() / r.len() as f64;
        assert!((mean - 1000.0).abs() < 2.5, "{mean}");
    }

    #[test]
    fn spreadsheet_scripts_read_as_the_plain_one() {
        // Reference: the plain comma script; the same seeks saved by a spreadsheet (byte-order
        // mark, `;` or tab with decimal commas, CRLF or lone CR, quoted and capitalised
        // header names) must give the same steps.
        let plain = parse_script(
            "s.csv",
            "track,dwell_s,measure\n10,0.25,1\n20,1.5,no\n",
            99.0,
        )
        .unwrap();
        for text in [
            "\u{feff}track;dwell_s;measure\r\n10;0,25;1\r\n20;1,5;no\r\n",
            "\"Track\";\"Dwell_s\";\"Measure\"\r10;0,25;1\r20;1,5;no\r",
            "track\tdwell_s\tmeasure\n10\t0,25\t1\n20\t1.5\tno\n",
            "\n TRACK , DWELL_S ,measure\n10,2.5E-01,1\n20,1.5,no\n",
        ] {
            let got = parse_script("s.csv", text, 99.0).unwrap();
            assert_eq!(got.len(), plain.len(), "{text:?}");
            for (a, b) in got.iter().zip(&plain) {
                assert_eq!(
                    (a.target, a.dwell_s, a.measure),
                    (b.target, b.dwell_s, b.measure),
                    "{text:?}"
                );
            }
        }
    }

    #[test]
    fn script_errors_name_line_and_column() {
        let ok = parse_script(
            "s.csv",
            "track,dwell_s,measure\n10,0.1,1\n20,0.2,no\n",
            99.0,
        )
        .unwrap();
        assert_eq!(ok.len(), 2);
        assert!(!ok[1].measure);
        let cases = [
            ("dwell_s\n1\n", "missing column `track`"),
            (
                "track,dwell_s\n10,x\n",
                "line 2, column 2 (`dwell_s`): not a number",
            ),
            (
                "track,dwell_s\n10,0.1\n200,0.1\n",
                "line 3, column 1 (`track`): track outside",
            ),
            ("track,dwell_s\n10,-1\n", "dwell must be"),
            (
                "track,dwell_s,measure\n10,1,maybe\n",
                "column 3 (`measure`)",
            ),
            ("track,dwell_s\n", "no rows"),
            (
                "track,dwell_s\n1,2,3\n",
                "line 2: 3 fields, but the header has 2",
            ),
            // Blank lines, CRLF and lone-CR line ends: the line an editor shows.
            (
                "track,dwell_s\n\n10,0.1\n\n20,x\n",
                "line 5, column 2 (`dwell_s`)",
            ),
            (
                "track,dwell_s\r\n10,0.1\r\n\r\n20,x\r\n",
                "line 4, column 2 (`dwell_s`)",
            ),
            (
                "track,dwell_s\r10,0.1\r20,x\r",
                "line 3, column 2 (`dwell_s`)",
            ),
            ("\r\n\r\ntrack\r\n1\r\n", "line 3: missing column `dwell_s`"),
            (
                "track,dwell_s,measure\n10,0.1,0\n20,0.2,no\n",
                "no row of the script is measured",
            ),
            // Empty, or blank lines only: no header, and no line past the end is named
            // (it named line 3 of a two-line blank file).
            ("", "the script is empty"),
            ("\n\n", "the script is empty"),
            ("\r\n \r\n\t\n", "the script is empty"),
            ("\u{feff}", "the script is empty"),
            // A spreadsheet's `;`-separated script with decimal commas still names the line.
            (
                "\u{feff}Track;Dwell_s\r\n10;0,5\r\n20;x\r\n",
                "line 3, column 2 (`Dwell_s`)",
            ),
        ];
        for (text, want) in cases {
            let e = parse_script("s.csv", text, 99.0).unwrap_err().to_string();
            assert!(e.contains(want) && e.starts_with("s.csv"), "{text:?}: {e}");
        }
    }
}
