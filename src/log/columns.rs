//! A whole log in memory, held as columns ([`Log`]): time, position and bias as plain `f64`
//! vectors, one vector per covariate, and the rows' line numbers as runs (a log read from a
//! file numbers its rows consecutively, so one run usually covers them all). 24 bytes per row
//! plus 8 per covariate, where a vector of rows took 64 plus the covariates' own vector.
//! [`Log::row`] and [`Log::rows`] hand out light [`RowRef`]s with the fields a
//! [`Row`](super::Row) has.

use super::{LogSchema, Row};

/// A whole log in memory: what the fitting and diagnosis commands work on. Held as columns;
/// read a row with [`Log::row`] or all of them with [`Log::rows`].
///
/// ```
/// use biasctl::{ColumnMap, Log};
/// let text = "time_s,track,bias,temp_c\n0,100,5,40\n1,150,,41\n";
/// let log = Log::from_reader("t.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
/// assert_eq!(log.len(), 2);
/// let r = log.row(1);
/// assert_eq!((r.line, r.track, r.bias, r.covariates[0]), (3, 150.0, None, 41.0));
/// assert_eq!(log.tracks(), [100.0, 150.0]);
/// ```
#[derive(Debug, Clone)]
pub struct Log {
    /// Metadata and columns.
    pub schema: LogSchema,
    time_s: Vec<f64>,
    track: Vec<f64>,
    /// The measured bias, NaN for a row moved but not measured (a read value is always finite).
    bias: Vec<f64>,
    /// One column per covariate, in the order of [`LogSchema::covariates`].
    covariates: Vec<Vec<f64>>,
    /// Runs of consecutive line numbers: `(first row, its line)`, rows in increasing order;
    /// row `i` of the run starting at row `r` with line `l` is on line `l + (i − r)`.
    lines: Vec<(usize, u64)>,
}

impl PartialEq for Log {
    fn eq(&self, other: &Self) -> bool {
        self.schema == other.schema
            && self.lines == other.lines
            && self.time_s == other.time_s
            && self.track == other.track
            && self.covariates == other.covariates
            // Unmeasured rows are NaN on both sides; measured values compare as numbers.
            && self.len() == other.len()
            && (0..self.len()).all(|i| self.bias(i) == other.bias(i))
    }
}

impl Log {
    /// An empty log of `schema`'s columns, with room for `rows` rows.
    pub(crate) fn with_capacity(schema: LogSchema, rows: usize) -> Self {
        let k = schema.covariates.len();
        Self {
            schema,
            time_s: Vec::with_capacity(rows),
            track: Vec::with_capacity(rows),
            bias: Vec::with_capacity(rows),
            covariates: (0..k).map(|_| Vec::with_capacity(rows)).collect(),
            lines: Vec::new(),
        }
    }

    /// Appends `row` (its covariates in the order of [`LogSchema::covariates`]).
    pub(crate) fn push(&mut self, row: &Row) {
        let i = self.len();
        let follows = self
            .lines
            .last()
            .is_some_and(|&(r, l)| l + (i - r) as u64 == row.line);
        if !follows {
            self.lines.push((i, row.line));
        }
        self.time_s.push(row.time_s);
        self.track.push(row.track);
        self.bias.push(row.bias.unwrap_or(f64::NAN));
        for (col, &v) in self.covariates.iter_mut().zip(&row.covariates) {
            col.push(v);
        }
    }

    /// Leaves the covariates with empty cells ([`LogSchema::empty_cells`]) out of the log, each
    /// with a note: every covariate column a whole log holds is complete, and a term that
    /// reads a left-out column is refused by name.
    pub(super) fn drop_empty_covariates(&mut self) {
        let s = &mut self.schema;
        for e in &s.empty_cells {
            let Some(k) = s.covariates.iter().position(|c| *c == e.column) else {
                continue;
            };
            s.covariates.remove(k);
            s.covariate_idx.remove(k);
            self.covariates.remove(k);
            s.notes.push(format!(
                "{e}, read as missing values: `{}` is left out of the covariates (a term that \
                 reads it needs every cell)",
                e.column
            ));
        }
    }

    /// Gives back the room reserved beyond the rows (one column at a time).
    pub(crate) fn shrink_to_fit(&mut self) {
        self.time_s.shrink_to_fit();
        self.track.shrink_to_fit();
        self.bias.shrink_to_fit();
        self.covariates.iter_mut().for_each(Vec::shrink_to_fit);
        self.lines.shrink_to_fit();
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.time_s.len()
    }

    /// Whether the log has no rows.
    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }

    /// Row `i` (panics past the end, as indexing does).
    #[inline]
    pub fn row(&self, i: usize) -> RowRef<'_> {
        self.row_on_line(i, self.line(i))
    }

    /// Row `i`, its line number already known.
    #[inline(always)]
    fn row_on_line(&self, i: usize, line: u64) -> RowRef<'_> {
        RowRef {
            line,
            time_s: self.time_s[i],
            track: self.track[i],
            bias: self.bias(i),
            covariates: Covariates {
                columns: &self.covariates,
                row: i,
            },
        }
    }

    /// Row `i`, `None` past the end.
    pub fn get(&self, i: usize) -> Option<RowRef<'_>> {
        (i < self.len()).then(|| self.row(i))
    }

    /// The first row.
    pub fn first(&self) -> Option<RowRef<'_>> {
        self.get(0)
    }

    /// The last row.
    pub fn last(&self) -> Option<RowRef<'_>> {
        self.len().checked_sub(1).map(|i| self.row(i))
    }

    /// Every row in file order.
    pub fn rows(&self) -> Rows<'_> {
        Rows {
            log: self,
            range: 0..self.len(),
            run: 0,
        }
    }

    /// 1-based line number of row `i` in its file.
    pub fn line(&self, i: usize) -> u64 {
        let run = self.lines.partition_point(|&(r, _)| r <= i);
        match run.checked_sub(1).map(|k| self.lines[k]) {
            Some((r, l)) => l + (i - r) as u64,
            None => 0,
        }
    }

    /// The measured bias of row `i`, `None` if it was not measured.
    #[inline(always)]
    pub fn bias(&self, i: usize) -> Option<f64> {
        let b = self.bias[i];
        (!b.is_nan()).then_some(b)
    }

    /// Sets the measured bias of row `i` (`None`: not measured). A NaN is stored as "not
    /// measured".
    pub fn set_bias(&mut self, i: usize, bias: Option<f64>) {
        self.bias[i] = bias.unwrap_or(f64::NAN);
    }

    /// The time of every row, s.
    pub fn times(&self) -> &[f64] {
        &self.time_s
    }

    /// The target position of every row.
    pub fn tracks(&self) -> &[f64] {
        &self.track
    }

    /// The target positions, to change in place (a test rescaling a log's positions).
    pub fn tracks_mut(&mut self) -> &mut [f64] {
        &mut self.track
    }

    /// Covariate `k`'s column (in the order of [`LogSchema::covariates`]).
    pub fn covariate(&self, k: usize) -> &[f64] {
        &self.covariates[k]
    }

    /// Removes every row (the schema stays).
    pub fn clear(&mut self) {
        self.time_s.clear();
        self.track.clear();
        self.bias.clear();
        self.covariates.iter_mut().for_each(Vec::clear);
        self.lines.clear();
    }

    /// The rows in `range`, as a log of their own with the same schema and line numbers.
    pub fn slice(&self, range: std::ops::Range<usize>) -> Log {
        let mut lines: Vec<(usize, u64)> = Vec::new();
        if !range.is_empty() {
            lines.push((0, self.line(range.start)));
            for &(r, l) in &self.lines {
                if r > range.start && r < range.end {
                    lines.push((r - range.start, l));
                }
            }
        }
        Log {
            schema: self.schema.clone(),
            time_s: self.time_s[range.clone()].to_vec(),
            track: self.track[range.clone()].to_vec(),
            bias: self.bias[range.clone()].to_vec(),
            covariates: self
                .covariates
                .iter()
                .map(|c| c[range.clone()].to_vec())
                .collect(),
            lines,
        }
    }

    /// Number of rows with a measured bias.
    pub fn measured_count(&self) -> usize {
        self.bias.iter().filter(|b| !b.is_nan()).count()
    }

    /// The bias column as stored: NaN where a row is not measured (crate-internal; never
    /// written out).
    pub(crate) fn bias_raw(&self) -> &[f64] {
        &self.bias
    }

    /// Target positions of the rows with a measured bias, in log order.
    pub fn measured_positions(&self) -> Vec<f64> {
        self.track
            .iter()
            .zip(&self.bias)
            .filter(|(_, b)| !b.is_nan())
            .map(|(&x, _)| x)
            .collect()
    }
}

/// One row of a [`Log`], by value (the fields of a [`Row`], the covariates read in place).
#[derive(Debug, Clone, Copy)]
pub struct RowRef<'a> {
    /// 1-based line number in the file (for messages).
    pub line: u64,
    /// Time of the seek, s.
    pub time_s: f64,
    /// Target track of the seek.
    pub track: f64,
    /// Measured bias in counts, `None` when the move was made but not measured.
    pub bias: Option<f64>,
    /// Covariate values in the order of [`LogSchema::covariates`].
    pub covariates: Covariates<'a>,
}

impl RowRef<'_> {
    /// The row as an owned [`Row`].
    pub fn to_row(&self) -> Row {
        Row {
            line: self.line,
            time_s: self.time_s,
            track: self.track,
            bias: self.bias,
            covariates: self.covariates.to_vec(),
        }
    }
}

/// The covariate values of one [`RowRef`], read from the log's columns: index them
/// (`row.covariates[k]`), [`Covariates::get`] them or copy them into a slice.
#[derive(Clone, Copy)]
pub struct Covariates<'a> {
    columns: &'a [Vec<f64>],
    row: usize,
}

impl std::fmt::Debug for Covariates<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

impl Covariates<'_> {
    /// Number of covariates.
    pub fn len(&self) -> usize {
        self.columns.len()
    }

    /// Whether the log has no covariates.
    pub fn is_empty(&self) -> bool {
        self.columns.is_empty()
    }

    /// Covariate `k`, `None` past the last.
    pub fn get(&self, k: usize) -> Option<f64> {
        self.columns.get(k).map(|c| c[self.row])
    }

    /// The values in order.
    pub fn iter(&self) -> impl Iterator<Item = f64> + '_ {
        self.columns.iter().map(|c| c[self.row])
    }

    /// The values as a vector.
    pub fn to_vec(&self) -> Vec<f64> {
        self.iter().collect()
    }

    /// Copies the values into `buf` (cleared first; no allocation once it has room) and
    /// returns them as a slice (what [`Seek::covariates`](crate::model::Seek::covariates) and the
    /// predictor take).
    pub fn gather<'b>(&self, buf: &'b mut Vec<f64>) -> &'b [f64] {
        buf.clear();
        buf.extend(self.iter());
        buf
    }
}

impl std::ops::Index<usize> for Covariates<'_> {
    type Output = f64;
    fn index(&self, k: usize) -> &f64 {
        &self.columns[k][self.row]
    }
}

impl PartialEq for Covariates<'_> {
    fn eq(&self, other: &Self) -> bool {
        self.len() == other.len() && self.iter().zip(other.iter()).all(|(a, b)| a == b)
    }
}

impl PartialEq<Vec<f64>> for Covariates<'_> {
    fn eq(&self, other: &Vec<f64>) -> bool {
        self.len() == other.len() && self.iter().zip(other).all(|(a, &b)| a == b)
    }
}

/// The iterator of [`Log::rows`]: every row in file order.
#[derive(Debug, Clone)]
pub struct Rows<'a> {
    log: &'a Log,
    range: std::ops::Range<usize>,
    /// The run of line numbers (`Log::lines`) the next row from the front is in, or before it.
    run: usize,
}

impl<'a> Iterator for Rows<'a> {
    type Item = RowRef<'a>;

    #[inline(always)]
    fn next(&mut self) -> Option<RowRef<'a>> {
        let i = self.range.next()?;
        // Walk the runs forward with the rows (no search per row).
        let lines = &self.log.lines;
        while self.run + 1 < lines.len() && lines[self.run + 1].0 <= i {
            self.run += 1;
        }
        let line = match lines.get(self.run) {
            Some(&(r, l)) if r <= i => l + (i - r) as u64,
            _ => self.log.line(i),
        };
        Some(self.log.row_on_line(i, line))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.range.size_hint()
    }

    fn nth(&mut self, n: usize) -> Option<RowRef<'a>> {
        self.range.nth(n).map(|i| self.log.row(i))
    }
}

impl DoubleEndedIterator for Rows<'_> {
    fn next_back(&mut self) -> Option<Self::Item> {
        self.range.next_back().map(|i| self.log.row(i))
    }
}

impl ExactSizeIterator for Rows<'_> {}

#[cfg(test)]
#[allow(clippy::float_cmp)] // values parsed from short decimal text compare exactly
mod tests {
    use super::super::{ColumnMap, LogReader};
    use super::*;

    /// Reference: the rows the streaming reader yields, one `Row` each (what `Log` held before
    /// it held columns): every field of every row, line numbers across a quoted line break and
    /// a slice of the log.
    #[test]
    fn columns_give_back_the_rows_read() {
        let text = "# m\ntime_s,track,bias,temp_c,v\n0,1,2,3,-1\n1,2,,4,\"5\"\n2,3,1,\"4\n\",7\n3,4,5,6,7\n4,5,,6,8\n";
        let rows: Vec<Row> =
            LogReader::from_reader("t.csv", text.as_bytes(), &ColumnMap::default())
                .unwrap()
                .collect::<Result<_, _>>()
                .unwrap();
        let log = Log::from_reader("t.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
        assert_eq!(log.len(), rows.len());
        let got: Vec<Row> = log.rows().map(|r| r.to_row()).collect();
        assert_eq!(got, rows);
        assert_eq!(
            log.rows().rev().map(|r| r.line).collect::<Vec<_>>(),
            [8, 7, 5, 4, 3]
        );
        assert_eq!(log.measured_count(), 3);
        assert_eq!(log.measured_positions(), [1.0, 3.0, 4.0]);
        let part = log.slice(1..4);
        assert_eq!(
            part.rows().map(|r| r.to_row()).collect::<Vec<_>>(),
            rows[1..4]
        );
        assert_eq!(part, part.clone());
        assert_ne!(part, log);
        let mut m = log.clone();
        m.set_bias(1, Some(9.0));
        assert_eq!(m.row(1).bias, Some(9.0));
        assert_ne!(m, log);
        m.set_bias(1, None);
        assert_eq!(m, log);
        m.clear();
        assert!(m.is_empty() && m.first().is_none() && m.last().is_none());
    }
}
