//! Which columns hold time, position and bias: the [`ColumnMap`], and the matching of its names
//! against a header (exact, then ignoring case) with the hints a missing name gets (the closest
//! name, a column whose name says it holds the role).

use super::{BiasColumn, LogError};
use crate::field::Field;

/// Names of the three required columns (defaults `time_s`, `track`, `bias`) and the field
/// delimiter (default: sniffed).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ColumnMap {
    /// Column holding the time of each seek in seconds.
    pub time: String,
    /// Column holding the seek target (tracks, or any position unit).
    pub track: String,
    /// Column holding the measured bias (counts, or any force/current unit).
    pub bias: String,
    /// Field delimiter (the CLI's `--delimiter`); `None` sniffs it from the header line: the most
    /// frequent of `,` `;` and tab outside quotes (a comma on a tie or when none occurs).
    pub delimiter: Option<u8>,
}

/// Default name of the time column (s).
pub const DEFAULT_TIME_COL: &str = "time_s";
/// Default name of the position column (tracks).
pub const DEFAULT_TRACK_COL: &str = "track";
/// Default name of the measured-bias column (counts).
pub const DEFAULT_BIAS_COL: &str = "bias";

impl Default for ColumnMap {
    fn default() -> Self {
        Self {
            time: DEFAULT_TIME_COL.into(),
            track: DEFAULT_TRACK_COL.into(),
            bias: DEFAULT_BIAS_COL.into(),
            delimiter: None,
        }
    }
}

/// The column most like `name` (edit distance at most a third of its length, at least 2, or one
/// name containing the other), for a "did you mean".
fn closest_column<'a>(name: &str, columns: &'a [String]) -> Option<&'a str> {
    let lower = name.to_lowercase();
    columns
        .iter()
        .filter(|c| !c.is_empty())
        .map(|c| (crate::io::words::edit_distance(name, c), c))
        .filter(|(d, c)| {
            *d <= (name.chars().count() / 3).max(2) || {
                // One name inside the other, neither of them a mere letter or two (`a` is in
                // `track`).
                let cl = c.to_lowercase();
                cl.chars().count().min(lower.chars().count()) >= 3
                    && (cl.contains(&lower) || lower.contains(&cl))
            }
        })
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c.as_str())
}

/// Words that make a column name a likely holder of a role, for a "did you mean" when no name is
/// close to the one looked for: a rig's `position_m` for the track, `force_N` for the bias.
fn role_words(field: Field) -> &'static [&'static str] {
    match field {
        Field::TimeColumn => &["time", "zeit", "temps"],
        Field::TrackColumn => &[
            "track", "pos", "angle", "theta", "enc", "displ", "stroke", "target",
        ],
        Field::BiasColumn => &[
            "bias", "force", "current", "torque", "effort", "dac", "control",
        ],
        _ => &[],
    }
}

/// The symbols a rig names a role's column by, each followed by nothing but a unit (`t`,
/// `t_s`, `t [s]`; `x_mm`, `q (rad)`; `F_N`, `i [A]`, `u_V`), and the units allowed after
/// them. A time column must be in seconds, so only `s` follows its symbols.
fn role_symbols(field: Field) -> (&'static [&'static str], &'static [&'static str]) {
    match field {
        Field::TimeColumn => (&["t", "sec", "secs", "seconds"], &["s", "sec"]),
        Field::TrackColumn => (
            &["x", "z", "q", "phi", "th", "trk"],
            &[
                "m", "mm", "um", "µm", "nm", "cm", "rad", "mrad", "deg", "counts", "tracks", "cnt",
            ],
        ),
        Field::BiasColumn => (
            &["f", "fm", "i", "u", "tau"],
            &[
                "n", "mn", "kn", "a", "ma", "v", "mv", "nm", "counts", "cnt", "pct", "%",
            ],
        ),
        _ => (&[], &[]),
    }
}

/// Whether `column` is a role's symbol followed by nothing but one of its units
/// ([`role_symbols`]), ignoring case and the separators between them (`t [s]`, `F_N`).
fn is_role_symbol(field: Field, column: &str) -> bool {
    let (symbols, units) = role_symbols(field);
    let lower = column.to_lowercase();
    let mut words = lower
        .split(|c: char| !(c.is_alphanumeric() || c == '%' || c == 'µ'))
        .filter(|w| !w.is_empty());
    let (Some(symbol), rest) = (words.next(), words.collect::<Vec<_>>()) else {
        return false;
    };
    symbols.contains(&symbol) && rest.len() <= 1 && rest.iter().all(|u| units.contains(u))
}

/// The first column whose name holds one of the role's words (ignoring case), else the first
/// that is the role's symbol with a unit (`t [s]`, `F_N`, `x_mm`), not one of `taken` (the
/// other roles' columns).
fn column_by_role<'a>(field: Field, columns: &'a [String], taken: &[usize]) -> Option<&'a str> {
    let free = || {
        columns
            .iter()
            .enumerate()
            .filter(|(i, c)| !c.is_empty() && !taken.contains(i))
    };
    let words = role_words(field);
    free()
        .find(|(_, c)| {
            let lower = c.to_lowercase();
            words.iter().any(|w| lower.contains(w))
        })
        .or_else(|| free().find(|(_, c)| is_role_symbol(field, c)))
        .map(|(_, c)| c.as_str())
}

/// The required columns found in a header, by index, and the notes on names matched ignoring
/// case (a name looked for twice is noted twice).
pub(super) struct RequiredColumns {
    pub(super) time: usize,
    pub(super) track: usize,
    /// `None` only for a plan ([`BiasColumn::Optional`]) without the bias column.
    pub(super) bias: Option<usize>,
    pub(super) case_notes: Vec<String>,
}

/// Looks for the required columns in a header (`columns`, the line `line` of `file`).
struct ColumnFinder<'a> {
    file: &'a str,
    line: u64,
    columns: &'a [String],
    map: &'a ColumnMap,
    /// The delimiter the header was split by.
    delimiter: u8,
    /// A note for each name matched ignoring case, each time it is looked for.
    case_notes: Vec<String>,
}

impl ColumnFinder<'_> {
    /// A required column: its exact name, else the one name equal to it ignoring case and
    /// surrounding spaces; else an error naming the header, with a "did you mean".
    fn find(&mut self, name: &str, field: Field) -> Result<usize, LogError> {
        let (file, columns, map) = (self.file, self.columns, self.map);
        let wanted = name.trim();
        if let Some(i) = columns.iter().position(|c| c == wanted) {
            return Ok(i);
        }
        let same: Vec<usize> = (0..columns.len())
            .filter(|&i| columns[i].to_lowercase() == wanted.to_lowercase())
            .collect();
        if let [i] = same[..] {
            self.case_notes.push(format!(
                "{file}: column `{}` used as `{wanted}` (matched ignoring case)",
                columns[i]
            ));
            return Ok(i);
        }
        // A header read as one column that holds a delimiter: the file is separated by
        // another one than the reader used (a `--delimiter` that does not fit, or `|`).
        if let [only] = columns
            && let Some(d) = only.chars().find(|c| [',', ';', '\t', '|'].contains(c))
        {
            return Err(LogError::Malformed {
                file: file.into(),
                line: self.line,
                message: format!(
                    "missing required column `{wanted}`: the header is one column, `{}`, \
                     that holds `{}`, so the fields are not separated by `{}`{}",
                    crate::io::quote(only),
                    d.escape_default(),
                    (self.delimiter as char).escape_default(),
                    if map.delimiter.is_some() {
                        " (--delimiter): leave the flag out to sniff the delimiter"
                    } else {
                        "; biasctl reads `,`, `;` or tab"
                    }
                ),
            });
        }
        // No name close to it: a column whose name says it holds the role (`position_m`
        // for the track), not one of the other required columns.
        let others: Vec<String> = [&map.time, &map.track, &map.bias]
            .iter()
            .map(|n| n.trim().to_lowercase())
            .collect();
        let taken: Vec<usize> = (0..columns.len())
            .filter(|&i| others.contains(&columns[i].to_lowercase()))
            .collect();
        Err(LogError::MissingColumn {
            file: file.into(),
            line: self.line,
            column: wanted.into(),
            found: columns.join(", "),
            field,
            suggestion: closest_column(wanted, columns)
                .or_else(|| column_by_role(field, columns, &taken))
                .map(str::to_string),
        })
    }
}

/// Finds the required columns of `map` in the header `columns` (line `line` of `file`, split
/// by `delimiter`): time and track, and bias unless `bias_column` is optional. Several missing
/// columns are named at once ([`LogError::MissingColumns`]); one keeps its own message.
pub(super) fn find_required(
    file: &str,
    line: u64,
    columns: &[String],
    map: &ColumnMap,
    delimiter: u8,
    bias_column: BiasColumn,
) -> Result<RequiredColumns, LogError> {
    let mut finder = ColumnFinder {
        file,
        line,
        columns,
        map,
        delimiter,
        case_notes: Vec::new(),
    };
    let roles = [
        (&map.time, Field::TimeColumn),
        (&map.track, Field::TrackColumn),
        (&map.bias, Field::BiasColumn),
    ];
    let need = if bias_column == BiasColumn::Optional {
        2
    } else {
        3
    };
    let missing: Vec<(String, Field, Option<String>)> = roles[..need]
        .iter()
        .filter_map(|&(name, field)| match finder.find(name, field) {
            Err(LogError::MissingColumn {
                column, suggestion, ..
            }) => Some((column, field, suggestion)),
            _ => None,
        })
        .collect();
    if missing.len() > 1 {
        return Err(missing_columns(file, line, columns, &missing));
    }
    let time = finder.find(&map.time, Field::TimeColumn)?;
    let track = finder.find(&map.track, Field::TrackColumn)?;
    let bias = match bias_column {
        BiasColumn::Optional => finder.find(&map.bias, Field::BiasColumn).ok(),
        _ => Some(finder.find(&map.bias, Field::BiasColumn)?),
    };
    Ok(RequiredColumns {
        time,
        track,
        bias,
        case_notes: finder.case_notes,
    })
}

/// [`LogError::MissingColumns`] for the `missing` columns (name, setting, suggestion), with a
/// hint naming each setting and the column that likely holds it, quoted for the shell.
fn missing_columns(
    file: &str,
    line: u64,
    columns: &[String],
    missing: &[(String, Field, Option<String>)],
) -> LogError {
    let shell = crate::io::shell_quote;
    LogError::MissingColumns {
        file: file.into(),
        line,
        missing: missing
            .iter()
            .map(|(c, _, _)| format!("`{c}`"))
            .collect::<Vec<_>>()
            .join(", "),
        found: columns.join(", "),
        hint: missing
            .iter()
            .enumerate()
            .map(|(i, (_, f, s))| {
                // A column suggested for an earlier role is not suggested again.
                let s = s
                    .as_deref()
                    .filter(|s| !missing[..i].iter().any(|m| m.2.as_deref() == Some(s)));
                format!("{f} {}", s.map_or("NAME".into(), shell))
            })
            .collect::<Vec<_>>()
            .join(" "),
    }
}
