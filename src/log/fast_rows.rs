//! The reader's fast row path: whole rows of plain lines ([`PlainLines`](super::plain::PlainLines))
//! turned into time, position, bias and covariates without the csv crate's parser, for the
//! columns whose [`Role`] the header gave; any line it does not take goes to the general path.

use super::error::source_failed;
use super::limits::MAX_ABS_VALUE;
use super::plain::parse_plain;
use super::source::Source;
use super::{LogError, LogReader, Row};
use std::io::Read;

impl<R: Read> LogReader<R> {
    /// What each column of the file is, in file order.
    pub(super) fn roles(&self) -> Vec<Role> {
        let s = &self.schema;
        (0..s.columns.len())
            .map(|i| {
                if i == s.time_idx {
                    Role::Time
                } else if i == s.track_idx {
                    Role::Track
                } else if Some(i) == s.bias_idx {
                    Role::Bias
                } else if let Some(k) = s.covariate_idx.iter().position(|&c| c == i) {
                    Role::Covariate(k)
                } else {
                    Role::Skipped
                }
            })
            .collect()
    }

    /// Hands rows to `take` the fast way while they are plain and valid: the line split and
    /// its numbers converted in one pass ([`parse_plain`]), straight from the read
    /// buffer. Returns at the end, at an error of the source, or at the first line it does not
    /// take — a quote, a carriage return, a byte beyond ASCII, another number of fields, a
    /// cell of another shape, a value out of range, time going backwards — without consuming
    /// it: [`LogReader::read_into`] then reads that line as every line was read before
    /// (the same row, or the same error). Also returns, right after the row, when `take`
    /// returns `false`.
    pub(super) fn plain_rows(
        &mut self,
        roles: &[Role],
        row: &mut Row,
        mut take: impl FnMut(&Row) -> bool,
    ) -> Result<(), LogError> {
        if !self.lookahead.is_empty() || self.pending.is_some() {
            return Ok(());
        }
        let Source::Plain {
            lines, delimiter, ..
        } = &mut self.source
        else {
            return Ok(());
        };
        let delimiter = *delimiter;
        row.covariates.resize(self.schema.covariate_idx.len(), 0.0);
        loop {
            // Whole lines, each ending in `\n`: no search for the line's end, the cells' own
            // scan finds it.
            let base_line = lines.line();
            let window = match lines.ready() {
                Ok([]) => return Ok(()),
                Ok(window) => window,
                Err(e) => return Err(source_failed(&self.schema.file, &e)),
            };
            let (mut at, mut rows, mut stop) = (0, 0, false);
            while at < window.len() {
                match plain_row(window, at, roles, delimiter, &mut row.covariates) {
                    Some((time_s, track, bias, next))
                        if self.prev_time.is_none_or(|prev| time_s >= prev) =>
                    {
                        row.line = base_line + rows;
                        row.time_s = time_s;
                        row.track = track;
                        row.bias = bias;
                        let more = take(row);
                        self.prev_time = Some(time_s);
                        self.measured += u64::from(bias.is_some());
                        rows += 1;
                        at = next;
                        if !more {
                            stop = true;
                            break;
                        }
                    }
                    _ => {
                        stop = true;
                        break;
                    }
                }
            }
            lines.consume(at, rows);
            if stop {
                return Ok(());
            }
        }
    }
}

/// The row of the plain line at `window[at..]` (which ends in `\n`): time, position, bias
/// (covariates into `covariates`) and the start of the next line; `None` for a line the fast
/// way does not take (see [`LogReader::plain_rows`]).
#[inline(always)]
fn plain_row(
    window: &[u8],
    at: usize,
    roles: &[Role],
    delimiter: u8,
    covariates: &mut [f64],
) -> Option<(f64, f64, Option<f64>, usize)> {
    let (mut time_s, mut track, mut bias) = (f64::NAN, f64::NAN, None);
    let mut i = at;
    for (c, role) in roles.iter().enumerate() {
        if c > 0 {
            if window.get(i) != Some(&delimiter) {
                return None;
            }
            i += 1;
        }
        let value = match role {
            Role::Skipped => {
                // Any text but what would change the split or needs a UTF-8 check.
                while let Some(&b) = window.get(i)
                    && b != delimiter
                    && b != b'\n'
                {
                    if b == b'"' || b == b'\r' || !b.is_ascii() {
                        return None;
                    }
                    i += 1;
                }
                continue;
            }
            Role::Bias if window.get(i).is_none_or(|&b| b == delimiter || b == b'\n') => continue,
            _ => {
                let (v, next) = parse_plain(window, i)?;
                if v.abs() > MAX_ABS_VALUE {
                    return None;
                }
                i = next;
                v
            }
        };
        match *role {
            Role::Time => time_s = value,
            Role::Track => track = value,
            Role::Bias => bias = Some(value),
            Role::Covariate(k) => covariates[k] = value,
            Role::Skipped => {}
        }
    }
    (window.get(i) == Some(&b'\n')).then_some((time_s, track, bias, i + 1))
}

/// What a column of a log is, for [`LogReader::plain_rows`].
#[derive(Debug, Clone, Copy)]
pub(super) enum Role {
    Time,
    Track,
    Bias,
    /// Covariate `k` of [`LogSchema::covariates`].
    Covariate(usize),
    /// A column read past (no name, not numeric, empty in the first rows).
    Skipped,
}
