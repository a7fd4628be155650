//! The measurement log: the one data format biasctl reads and writes.
//!
//! A log is a CSV file with a header row and one row per seek, in the order the seeks were made:
//!
//! | column   | unit   | meaning |
//! |----------|--------|---------|
//! | `time_s` | s      | time of the seek, non-decreasing |
//! | `track`  | tracks | target of the seek (0 = outer diameter; a positive seek moves inbound) |
//! | `bias`   | counts | measured bias at the target; an empty cell means "moved, not measured" |
//! | any other| any    | a named numeric covariate (for example `temp_c`) |
//!
//! The source of each seek is the previous row's track. Lines starting with `#` before the
//! header are metadata (generator, seed, drive parameters) and are kept in [`LogSchema::metadata`].
//! The three required columns can be renamed with a [`ColumnMap`] (the CLI's `--time-col`,
//! `--track-col` and `--bias-col`), so a rig that logs position in metres and force in newtons is
//! read as it is.
//!
//! The units of bias and position travel with the log as [`LogSchema::units`] ([`Units`]): the
//! metadata lines `# bias_unit = N` and `# position_unit = m` name them; without them a log
//! with the default columns `bias` and `track` is in counts and tracks, and a renamed column's
//! own name is its label (`force_N`). [`Units::resolve`] puts explicit labels (the CLI's
//! `--bias-unit` and `--track-unit`) first.
//!
//! Reading is streaming ([`LogReader`]) and strict about the data: every bad value in a column
//! with a role is an error that names the file, line and column. It is tolerant about the dialect:
//! the delimiter (`,` `;` or tab) is sniffed from the header unless [`ColumnMap::delimiter`]
//! names it; a `;`- or tab-separated file may use a decimal comma (`0,25`); header names match
//! ignoring case and surrounding spaces (an unknown name gets a "did you mean"); a column with no
//! name and no values (a spreadsheet's trailing comma) is ignored; a covariate column that is
//! not numeric in the first rows (notes, labels) is skipped. Every skip is told in
//! [`LogSchema::notes`]; nothing is skipped silently.
//!
//! ```
//! use biasctl::{ColumnMap, log::LogReader};
//! let text = "# seed 1\ntime_s,track,bias,temp_c\n0.0,100,12.5,40\n0.5,120,,40\n1.0,90,-3.25,41\n";
//! let mut reader = LogReader::from_reader("example.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
//! assert_eq!(reader.schema().covariates, vec!["temp_c".to_string()]);
//! let rows: Vec<_> = reader.by_ref().collect::<Result<_, _>>().unwrap();
//! assert_eq!(rows.len(), 3);
//! assert_eq!(rows[1].bias, None);
//! assert_eq!(reader.schema().units.bias, "counts");
//! ```

mod column_map;
mod columns;
mod dialect;
mod error;
mod fast_rows;
mod header;
pub(crate) mod limits;
pub(crate) mod lines;
mod plain;
mod reader;
mod schema;
mod source;
mod units;
mod writer;

pub use column_map::{ColumnMap, DEFAULT_BIAS_COL, DEFAULT_TIME_COL, DEFAULT_TRACK_COL};
pub use columns::{Covariates, Log, RowRef, Rows};
pub(crate) use dialect::{parse_cell, sniff_delimiter};
pub use error::LogError;
pub(crate) use limits::MAX_ABS_VALUE;
pub use reader::{LogReader, LogSummary};
pub use schema::{BiasColumn, EmptyCells, LogSchema, Row, STDIN_PATH};
pub use units::{DEFAULT_BIAS_UNIT, UnitError, Units, check_unit_label};
pub(crate) use writer::fmt_float;
pub use writer::{LogWriter, fmt_trimmed};
pub(crate) use writer::{csv_writer, fmt_fixed};

// The namespace's public items that live in its submodules (the crate root keeps only the
// names most users need; see `biasctl::prelude`).
pub use limits::check_toml_numbers;

#[cfg(test)]
mod tests;
