//! The fleet table as CSV (`fleet fit --out`, read back by `fleet outliers --fits`): one row
//! per drive, `source,rows,terms`, each parameter and its standard error (`poly2.c1`,
//! `poly2.c1.se`), `std,warnings,error`. Numbers are written with the shortest digits that read
//! back as the same `f64`, so a table read back gives the same outliers as the rows it was
//! written from; an empty cell is a value the drive does not have.

use super::DriveFit;
use crate::model::Param;

/// The columns before the parameters.
const HEAD: [&str; 3] = ["source", "rows", "terms"];
/// The columns after the parameters.
const TAIL: [&str; 3] = ["std", "warnings", "error"];
/// The suffix of a standard-error column.
const SE: &str = ".se";
/// How a drive's warnings are joined in one cell (and split when read).
const WARNING_SEPARATOR: &str = "; ";

/// A fleet table that cannot be read: the file, the line and (where one is to blame) the column.
#[derive(Debug, thiserror::Error)]
#[error("{file}: line {line}{}: {message}", column.as_ref().map(|c| format!(", column `{c}`")).unwrap_or_default())]
pub struct FitsError {
    /// The table's file name.
    pub file: String,
    /// The 1-based line.
    pub line: u64,
    /// The column, if one is to blame.
    pub column: Option<String>,
    /// What is wrong.
    pub message: String,
}

/// Every parameter name of the fleet, in the order the drives first name them.
pub fn param_names(rows: &[DriveFit]) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for p in rows.iter().flat_map(|r| &r.params) {
        if !names.contains(&p.name) {
            names.push(p.name.clone());
        }
    }
    names
}

/// The fleet table as CSV text, in the dialect of every CSV biasctl writes (a cell quoted only
/// when it holds a comma, a quote or a line break).
pub fn fits_csv(rows: &[DriveFit]) -> String {
    let names = param_names(rows);
    let mut out = String::new();
    let mut header: Vec<String> = HEAD.iter().map(|s| s.to_string()).collect();
    for n in &names {
        header.push(n.clone());
        header.push(format!("{n}{SE}"));
    }
    header.extend(TAIL.iter().map(|s| s.to_string()));
    push_record(&mut out, &header);
    let num = |x: Option<f64>| x.map(number).unwrap_or_default();
    for r in rows {
        let mut cells = vec![
            r.source.clone(),
            r.rows.map(|n| n.to_string()).unwrap_or_default(),
            r.terms.clone(),
        ];
        for n in &names {
            let p = r.param(n);
            cells.push(num(p.map(|p| p.value)));
            cells.push(num(p.and_then(|p| p.se)));
        }
        cells.push(num(r.std));
        cells.push(r.warnings.join(WARNING_SEPARATOR));
        cells.push(r.error.clone().unwrap_or_default());
        push_record(&mut out, &cells);
    }
    out
}

/// A number's cell: the shortest digits that read back as `x` (empty if `x` is not finite).
pub(super) fn number(x: f64) -> String {
    let mut out = Vec::new();
    crate::io::number::write_shortest(x, &mut out);
    String::from_utf8(out).unwrap_or_default()
}

/// Appends one CSV record and its line end.
pub(super) fn push_record(out: &mut String, cells: &[String]) {
    for (i, c) in cells.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        if c.contains([',', '"', '\n', '\r']) {
            out.push('"');
            out.push_str(&c.replace('"', "\"\""));
            out.push('"');
        } else {
            out.push_str(c);
        }
    }
    out.push('\n');
}

/// A count of rows as a table cell holds it: `600`, or `600.0` as pandas writes an integer
/// column that has an empty cell.
fn count(cell: &str) -> Option<usize> {
    if let Ok(n) = cell.parse::<usize>() {
        return Some(n);
    }
    let whole = cell.strip_suffix(".0")?;
    whole.parse::<usize>().ok()
}

/// Reads a fleet table written by [`fits_csv`] (or by `biasctl.fleet.fit_many(...).to_csv`):
/// `file` names it in messages.
pub fn read_fits(text: &str, file: &str) -> Result<Vec<DriveFit>, FitsError> {
    let err = |line: u64, column: Option<&str>, message: String| FitsError {
        file: file.to_string(),
        line,
        column: column.map(str::to_string),
        message,
    };
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(text.as_bytes());
    let mut records = reader.records();
    let header = match records.next() {
        Some(Ok(h)) => h,
        Some(Err(e)) => return Err(err(1, None, e.to_string())),
        None => return Err(err(1, None, "empty file: no header".into())),
    };
    let header: Vec<String> = header.iter().map(str::to_string).collect();
    let names = param_columns(&header).map_err(|m| err(1, None, m))?;
    let mut rows = Vec::new();
    for (i, rec) in records.enumerate() {
        let line = i as u64 + 2;
        let rec = rec.map_err(|e| err(line, None, e.to_string()))?;
        if rec.len() != header.len() {
            return Err(err(
                line,
                None,
                format!("{} cells for {} columns", rec.len(), header.len()),
            ));
        }
        let cell = |k: usize| rec.get(k).unwrap_or("");
        let number = |k: usize| -> Result<Option<f64>, FitsError> {
            let c = cell(k).trim();
            if c.is_empty() {
                return Ok(None);
            }
            match c.parse::<f64>() {
                Ok(x) if x.is_finite() => Ok(Some(x)),
                _ => Err(err(
                    line,
                    Some(&header[k]),
                    format!("`{}` is not a finite number", crate::io::quote(c)),
                )),
            }
        };
        let rows_used = match cell(1).trim() {
            "" => None,
            c => Some(count(c).ok_or_else(|| {
                err(
                    line,
                    Some("rows"),
                    format!("`{}` is not a count of rows", crate::io::quote(c)),
                )
            })?),
        };
        let mut params = Vec::new();
        for (j, name) in names.iter().enumerate() {
            let k = HEAD.len() + 2 * j;
            if let Some(value) = number(k)? {
                params.push(Param {
                    name: name.clone(),
                    value,
                    se: number(k + 1)?,
                });
            }
        }
        let t = header.len() - TAIL.len();
        let warnings = cell(t + 1);
        let error = cell(t + 2);
        rows.push(DriveFit {
            source: cell(0).to_string(),
            rows: rows_used,
            terms: cell(2).to_string(),
            params,
            std: number(t)?,
            warnings: if warnings.is_empty() {
                Vec::new()
            } else {
                warnings
                    .split(WARNING_SEPARATOR)
                    .map(str::to_string)
                    .collect()
            },
            error: (!error.is_empty()).then(|| error.to_string()),
        });
    }
    Ok(rows)
}

/// The parameter names of a fleet table's header, checked: `source,rows,terms`, pairs
/// `NAME,NAME.se`, then `std,warnings,error`. A leading unnamed column (a pandas index) is
/// refused with the way out.
fn param_columns(header: &[String]) -> Result<Vec<String>, String> {
    let expected = || {
        format!(
            "expected the columns {}, pairs NAME,NAME{SE}, then {}",
            HEAD.join(","),
            TAIL.join(",")
        )
    };
    if header.first().is_some_and(String::is_empty) {
        return Err(format!(
            "the first column has no name (a DataFrame written with its index: use \
             to_csv(path, index=False)); {}",
            expected()
        ));
    }
    let n = header.len();
    if n < HEAD.len() + TAIL.len()
        || header[..HEAD.len()] != HEAD
        || header[n - TAIL.len()..] != TAIL
        || !(n - HEAD.len() - TAIL.len()).is_multiple_of(2)
    {
        return Err(format!("not a fleet table: {}", expected()));
    }
    let middle = &header[HEAD.len()..n - TAIL.len()];
    let mut names = Vec::new();
    for pair in middle.chunks(2) {
        if pair[1] != format!("{}{SE}", pair[0]) {
            return Err(format!(
                "column `{}` must be followed by `{}{SE}`, not `{}`",
                pair[0], pair[0], pair[1]
            ));
        }
        names.push(pair[0].clone());
    }
    Ok(names)
}
