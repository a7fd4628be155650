//! Flags shared by several commands.

use biasctl::log::ColumnMap;
use clap::Args;
use std::path::PathBuf;

/// Column-name flags accepted by every command that reads a log.
#[derive(Debug, Clone, Args)]
pub struct ColumnArgs {
    /// Name of the time column (seconds).
    #[arg(long, default_value = "time_s", value_name = "NAME")]
    pub time_col: String,
    /// Name of the position column (the seek target; tracks or any position unit).
    #[arg(long, default_value = "track", value_name = "NAME")]
    pub track_col: String,
    /// Name of the measured-bias column (counts or any force unit).
    #[arg(long, default_value = "bias", value_name = "NAME")]
    pub bias_col: String,
}

impl ColumnArgs {
    /// The validated column map.
    pub fn map(&self) -> ColumnMap {
        ColumnMap {
            time: self.time_col.clone(),
            track: self.track_col.clone(),
            bias: self.bias_col.clone(),
        }
    }
}

/// A log to read (`--data`) and its column names.
#[derive(Debug, Clone, Args)]
pub struct LogArgs {
    /// The measurement log (CSV with `time_s`, `track`, `bias` and optional covariate columns).
    #[arg(long, value_name = "LOG.csv")]
    pub data: PathBuf,
    #[command(flatten)]
    pub columns: ColumnArgs,
}
