//! The units of a log ([`Units`]): bias and position from explicit labels, the metadata or the
//! column names, the check every unit label passes, and the note on a time column whose name
//! states a unit other than seconds.

use super::LogSchema;
use super::column_map::{DEFAULT_BIAS_COL, DEFAULT_TRACK_COL};
use serde::{Deserialize, Serialize};

/// Bias unit of a log whose bias column is the default `bias` and whose metadata names none.
pub const DEFAULT_BIAS_UNIT: &str = "counts";
/// Position unit of a log whose track column is the default `track` and whose metadata names
/// none.
pub(crate) const DEFAULT_POSITION_UNIT: &str = "tracks";
/// Metadata key naming the bias unit (`# bias_unit = N`).
pub(crate) const BIAS_UNIT_KEY: &str = "bias_unit";
/// Metadata key naming the position unit (`# position_unit = m`).
pub(crate) const POSITION_UNIT_KEY: &str = "position_unit";

/// The unit labels of a log's bias and position, for every text, table and axis that shows
/// log data. JSON: `{"bias": "N", "position": "m"}`.
///
/// ```
/// use biasctl::{ColumnMap, Log, Units};
/// let map = ColumnMap { track: "position_m".into(), bias: "force_N".into(), ..ColumnMap::default() };
/// let log = Log::from_reader("r.csv", "time_s,position_m,force_N\n0,0.1,2\n".as_bytes(), &map).unwrap();
/// assert_eq!(log.schema.units, Units { bias: "force_N".into(), position: "position_m".into() });
/// let flags = Units::resolve(Some("N"), Some("m"), &log.schema).unwrap();
/// assert_eq!((flags.bias.as_str(), flags.per_position().as_str()), ("N", "N/m"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Units {
    /// Unit of the measured bias, e.g. `counts`, `N`, `mA`.
    pub bias: String,
    /// Unit of the position (seek target), e.g. `tracks`, `m`.
    pub position: String,
}

impl Default for Units {
    /// Counts and tracks: the simulator's units.
    fn default() -> Self {
        Self {
            bias: DEFAULT_BIAS_UNIT.into(),
            position: DEFAULT_POSITION_UNIT.into(),
        }
    }
}

/// A unit label that cannot be used (given explicitly or from a log's metadata).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{origin} `{label}`: {problem}; give a plain label such as `N`, `mA` or `counts`")]
pub struct UnitError {
    /// Where the label came from: the setting (`Units::bias`, a [`crate::field::Field`]) or the
    /// log's metadata line.
    pub origin: String,
    /// The label as given.
    pub label: String,
    /// What is wrong with it.
    pub problem: &'static str,
}

/// Checks a unit label: non-empty (after trimming), no control character (newline, tab, …) and
/// no comma, so it fits an axis label, a text line and a CSV metadata line. Returns the trimmed
/// label, or what is wrong with it.
pub fn check_unit_label(label: &str) -> Result<&str, &'static str> {
    let trimmed = label.trim();
    if trimmed.is_empty() {
        Err("a unit label must not be empty")
    } else if trimmed.chars().any(char::is_control) {
        Err("a unit label must not hold a control character (newline, tab, …)")
    } else if trimmed.contains(',') {
        Err("a unit label must not hold a comma")
    } else {
        Ok(trimmed)
    }
}

impl Units {
    /// Resolves the units of a log: an explicit label (`bias`, `position`: the CLI's
    /// `--bias-unit` and `--track-unit`) first, then the log's metadata (`bias_unit`,
    /// `position_unit`), then a default from the column: `counts` for the default bias column
    /// `bias`, else the bias column's name (`force_N`); `tracks` for the default track column
    /// `track`, else its name (`position_m`). A bad label (empty, a control character or a
    /// comma) is an error naming its setting ([`Field::BiasUnit`](crate::field::Field::BiasUnit),
    /// [`Field::PositionUnit`](crate::field::Field::PositionUnit)) or the log file and metadata
    /// key.
    pub fn resolve(
        bias: Option<&str>,
        position: Option<&str>,
        schema: &LogSchema,
    ) -> Result<Units, UnitError> {
        let one = |flag_value: Option<&str>,
                   field: crate::field::Field,
                   key: &str,
                   column: &str,
                   default_column: &str,
                   default_unit: &str|
         -> Result<String, UnitError> {
            let (label, origin) = match (flag_value, schema.metadata_value(key)) {
                (Some(l), _) => (l, field.to_string()),
                (None, Some(m)) => (m, format!("{}: metadata `{key}`", schema.file)),
                (None, None) if column == default_column => return Ok(default_unit.into()),
                // `position [um]` is in `um`; a name without a unit in brackets is its label.
                (None, None) => return Ok(unit_in_name(column).unwrap_or(column).into()),
            };
            check_unit_label(label)
                .map(str::to_string)
                .map_err(|problem| UnitError {
                    origin,
                    label: label.to_string(),
                    problem,
                })
        };
        Ok(Units {
            bias: one(
                bias,
                crate::field::Field::BiasUnit,
                BIAS_UNIT_KEY,
                &schema.map.bias,
                DEFAULT_BIAS_COL,
                DEFAULT_BIAS_UNIT,
            )?,
            position: one(
                position,
                crate::field::Field::PositionUnit,
                POSITION_UNIT_KEY,
                &schema.map.track,
                DEFAULT_TRACK_COL,
                DEFAULT_POSITION_UNIT,
            )?,
        })
    }

    /// The units of a log read for a model fitted in `fitted`: a unit given explicitly
    /// (`bias_given`, `position_given`: the CLI's `--bias-unit`, `--track-unit`) or by the log's
    /// metadata stays as [`Units::resolve`] gave it; one that came from the column name is the
    /// model's. (Whether the result is the model's is for `FittedModel::check_units` to say.)
    pub fn for_model(
        mut self,
        fitted: &Units,
        bias_given: bool,
        position_given: bool,
        schema: &LogSchema,
    ) -> Units {
        if !bias_given && schema.metadata_value(BIAS_UNIT_KEY).is_none() {
            self.bias = fitted.bias.clone();
        }
        if !position_given && schema.metadata_value(POSITION_UNIT_KEY).is_none() {
            self.position = fitted.position.clone();
        }
        self
    }

    /// The unit of a slope of bias against position, `<bias>/<position>` (`N/m`); a plural
    /// count noun below the slash is made singular (`counts/track`, not `counts/tracks`).
    pub fn per_position(&self) -> String {
        let per = match self.position.as_str() {
            "tracks" => "track",
            "steps" => "step",
            "counts" => "count",
            p => p,
        };
        format!("{}/{per}", self.bias)
    }
}

/// The unit a column name states: the text in brackets or parentheses at its end (`position
/// [um]`, `Force (N)`), if it is a usable label ([`check_unit_label`]).
pub(crate) fn unit_in_name(name: &str) -> Option<&str> {
    let name = name.trim();
    let (open, close) = if name.ends_with(']') {
        ('[', ']')
    } else if name.ends_with(')') {
        ('(', ')')
    } else {
        return None;
    };
    let inner = &name[name.rfind(open)? + 1..name.len() - close.len_utf8()];
    check_unit_label(inner).ok()
}

/// The time unit a column name states other than seconds (`time_ms`, `t [ms]`, `Time (min)`),
/// for a note: biasctl reads every time in seconds.
pub(super) fn time_unit_not_seconds(name: &str) -> Option<&'static str> {
    let unit = unit_in_name(name)
        .or_else(|| {
            name.trim()
                .rsplit_once(['_', ' ', '-', '.'])
                .map(|(_, u)| u)
        })?
        .to_lowercase();
    match unit.as_str() {
        "ms" | "msec" | "millisecond" | "milliseconds" => Some("milliseconds"),
        "us" | "µs" | "μs" | "usec" | "microsecond" | "microseconds" => Some("microseconds"),
        "ns" => Some("nanoseconds"),
        "min" | "mins" | "minute" | "minutes" => Some("minutes"),
        "h" | "hr" | "hour" | "hours" => Some("hours"),
        _ => None,
    }
}

/// The note told when the time column's name states a unit other than seconds.
pub(super) fn time_unit_note(file: &str, name: &str) -> Option<String> {
    let unit = time_unit_not_seconds(name)?;
    Some(format!(
        "{file}: column `{name}` is read in seconds, biasctl's time unit, but its name says \
         {unit}: convert it to seconds, else every time biasctl prints or fits (dwell_s, \
         rows/s, a lag's tau, a velocity) is off by that factor"
    ))
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
    fn units_come_from_flags_then_metadata_then_columns() {
        let plain = read("time_s,track,bias\n0,1,2\n").unwrap();
        assert_eq!(plain.schema.units, Units::default());
        assert_eq!(plain.schema.units.per_position(), "counts/track");
        let meta =
            read("# bias_unit = mA\n# position_unit: um\ntime_s,track,bias\n0,1,2\n").unwrap();
        assert_eq!(
            meta.schema.units,
            Units {
                bias: "mA".into(),
                position: "um".into()
            }
        );
        let map = ColumnMap {
            time: "t".into(),
            track: "position_m".into(),
            bias: "force_N".into(),
            delimiter: None,
        };
        let mut renamed =
            Log::from_reader("r.csv", "t,position_m,force_N\n0,0.1,2\n".as_bytes(), &map).unwrap();
        assert_eq!(renamed.schema.units.bias, "force_N");
        assert_eq!(renamed.schema.units.position, "position_m");
        // Flags win over the column default; `None` keeps it; labels are trimmed.
        renamed.schema.set_units(Some(" N "), None).unwrap();
        assert_eq!(renamed.schema.units.bias, "N");
        assert_eq!(renamed.schema.units.position, "position_m");
        // Flags win over metadata too.
        let u = Units::resolve(Some("kN"), Some("mm"), &meta.schema).unwrap();
        assert_eq!(u.per_position(), "kN/mm");
    }

    #[test]
    fn bad_unit_labels_name_their_flag_or_metadata_key() {
        for (label, want) in [
            ("", "must not be empty"),
            ("  ", "must not be empty"),
            ("N,m", "comma"),
            ("N\nm", "control character"),
            ("a\tb", "control character"),
        ] {
            let problem = check_unit_label(label).unwrap_err();
            assert!(problem.contains(want), "{label:?}: {problem}");
        }
        assert_eq!(check_unit_label(" N·m "), Ok("N·m"));
        let log = read("time_s,track,bias\n0,1,2\n").unwrap();
        let e = Units::resolve(Some(""), None, &log.schema).unwrap_err();
        // The library names the setting; the CLI renders it as its flag (tests/it/units.rs).
        assert!(e.to_string().starts_with("Units::bias ``: "), "{e}");
        let e = Units::resolve(None, Some("a,b"), &log.schema).unwrap_err();
        assert!(e.to_string().starts_with("Units::position `a,b`: "), "{e}");
        let err = read("# bias_unit =\ntime_s,track,bias\n0,1,2\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("t.csv: metadata `bias_unit` ``: a unit label must not be empty"),
            "{err}"
        );
    }
}
