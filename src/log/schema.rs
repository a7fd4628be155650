//! What a log's header says ([`LogSchema`]), one row of it ([`Row`]), and whether the bias
//! column is required ([`BiasColumn`]).

use super::{ColumnMap, LogError, UnitError, Units};

/// What a log's header says: metadata, column names and which column is which.
#[derive(Debug, Clone, PartialEq)]
pub struct LogSchema {
    /// The file name used in error messages.
    pub file: String,
    /// Metadata lines before the header, without the leading `#` and surrounding space.
    pub metadata: Vec<String>,
    /// All column names in file order.
    pub columns: Vec<String>,
    /// The column map the log was read with.
    pub map: ColumnMap,
    /// Names of the covariate columns (the numeric columns other than the three required), in
    /// file order.
    pub covariates: Vec<String>,
    /// The field delimiter read with (sniffed or given).
    pub delimiter: u8,
    /// What the reader did that the user should know: columns skipped (no name with values, not
    /// numeric, empty in the first rows), a delimiter other than a comma, a column matched
    /// ignoring case. The CLI prints them on stderr.
    pub notes: Vec<String>,
    /// The units of bias and position: from the metadata or the columns when read
    /// ([`Units::resolve`] without explicit labels); [`LogSchema::set_units`] applies explicit
    /// ones.
    pub units: Units,
    /// The covariate columns with empty cells, each read as a missing value: a streamed row
    /// holds `NaN` there; a whole [`Log`](super::Log) leaves such a column out of its
    /// covariates (and says so in [`LogSchema::notes`]). Only a term that reads the column
    /// needs every cell ([`LogSchema::require_covariates`]). Filled in as rows are read.
    pub empty_cells: Vec<EmptyCells>,
    pub(super) time_idx: usize,
    pub(super) track_idx: usize,
    pub(super) bias_idx: Option<usize>,
    pub(super) covariate_idx: Vec<usize>,
}

impl LogSchema {
    /// Whether the log has a bias column (a plan read with [`BiasColumn::Optional`] may not).
    pub fn has_bias(&self) -> bool {
        self.bias_idx.is_some()
    }

    /// Index of covariate `name` in [`Row::covariates`], if the log has it.
    pub fn covariate_index(&self, name: &str) -> Option<usize> {
        self.covariates.iter().position(|c| c == name)
    }

    /// The empty cells of column `name`, if it has any ([`LogSchema::empty_cells`]).
    pub fn empty_cells_of(&self, name: &str) -> Option<&EmptyCells> {
        self.empty_cells.iter().find(|e| e.column == name)
    }

    /// Refuses `row` if one of the covariates `used` (indices into [`Row::covariates`]) is
    /// empty there: what a streamed replay checks for the columns its terms read.
    pub fn require_covariates(&self, row: &Row, used: &[usize]) -> Result<(), LogError> {
        match used
            .iter()
            .find(|&&k| row.covariates.get(k).is_some_and(|v| v.is_nan()))
        {
            None => Ok(()),
            Some(&k) => Err(LogError::BadValue {
                file: self.file.clone(),
                line: row.line,
                column_index: self.covariate_idx.get(k).map_or(0, |i| i + 1),
                column: self.covariates.get(k).cloned().unwrap_or_default(),
                value: String::new(),
                problem: "empty cell in a covariate the model reads",
            }),
        }
    }

    /// Records an empty cell of covariate `k` on line `line`.
    pub(super) fn note_empty_cell(&mut self, k: usize, line: u64) {
        let column = &self.covariates[k];
        match self.empty_cells.iter_mut().find(|e| &e.column == column) {
            Some(e) => e.count += 1,
            None => self.empty_cells.push(EmptyCells {
                column: column.clone(),
                column_index: self.covariate_idx[k] + 1,
                count: 1,
                first_line: line,
            }),
        }
    }

    /// Resolves the units again with explicit labels (the CLI's `--bias-unit` and
    /// `--track-unit`; `None` keeps the metadata or column default), see [`Units::resolve`].
    pub fn set_units(
        &mut self,
        bias: Option<&str>,
        position: Option<&str>,
    ) -> Result<(), UnitError> {
        self.units = Units::resolve(bias, position, self)?;
        Ok(())
    }

    /// The value of metadata key `key` from a line `key = value` or `key: value`.
    pub fn metadata_value(&self, key: &str) -> Option<&str> {
        self.metadata.iter().find_map(|line| {
            let (k, v) = line.split_once('=').or_else(|| line.split_once(':'))?;
            (k.trim() == key).then(|| v.trim())
        })
    }
}

/// A covariate column with empty cells ([`LogSchema::empty_cells`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EmptyCells {
    /// The column's name.
    pub column: String,
    /// Its 1-based position in the header.
    pub column_index: usize,
    /// How many of its cells are empty.
    pub count: u64,
    /// The line of the first empty cell.
    pub first_line: u64,
}

impl std::fmt::Display for EmptyCells {
    /// `column 6 (`humidity`): 1 empty cell (line 102 first)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "column {} (`{}`): {} empty cell{} (line {}{})",
            self.column_index,
            self.column,
            self.count,
            if self.count == 1 { "" } else { "s" },
            self.first_line,
            if self.count == 1 { "" } else { " first" }
        )
    }
}

/// One seek of the log.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// 1-based line number in the file (for messages).
    pub line: u64,
    /// Time of the seek, s.
    pub time_s: f64,
    /// Target track of the seek.
    pub track: f64,
    /// Measured bias in counts, `None` when the move was made but not measured.
    pub bias: Option<f64>,
    /// Covariate values in the order of [`LogSchema::covariates`].
    pub covariates: Vec<f64>,
}

impl Row {
    /// A row to read into ([`LogReader::read_into`](super::LogReader::read_into)), with room for `covariates` values.
    pub fn empty(covariates: usize) -> Self {
        Row {
            line: 0,
            time_s: 0.0,
            track: 0.0,
            bias: None,
            covariates: Vec::with_capacity(covariates),
        }
    }
}

/// Whether a log must hold measurements.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum BiasColumn {
    /// The bias column must exist and at least one row must be measured (fitting, scoring,
    /// diagnosing): a missing column or a log without a measured row is an error.
    #[default]
    Required,
    /// A plan (`predict`): the bias column may be missing or empty; every row is then read as
    /// "moved, not measured".
    Optional,
}

/// The path that means standard input (`--data -`).
pub const STDIN_PATH: &str = "-";
/// The name standard input has in messages.
pub(crate) const STDIN_NAME: &str = "<stdin>";
