//! The logs of a fleet named by a pattern: `logs/*.csv` (a `*` or `?` in the file name), as a
//! shell would expand it, for shells and callers that pass the pattern through.

use std::path::{Path, PathBuf};

/// A pattern that names no log, or a folder that cannot be listed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PatternError {
    /// No file matches the pattern.
    #[error("{pattern}: no file matches")]
    NoMatch {
        /// The pattern as given.
        pattern: String,
    },
    /// The pattern's folder could not be listed.
    #[error("{pattern}: cannot list {folder}: {source}")]
    Folder {
        /// The pattern as given.
        pattern: String,
        /// Its folder.
        folder: PathBuf,
        /// The operating-system error.
        #[source]
        source: std::io::Error,
    },
    /// A wildcard outside the file name (`logs/*/a.csv`).
    #[error("{pattern}: a wildcard (* or ?) is allowed in the file name only")]
    FolderWildcard {
        /// The pattern as given.
        pattern: String,
    },
}

/// The files `pattern` names: itself when it has no wildcard, else every file of its folder
/// whose name matches (`*`: any run of characters, `?`: one character), sorted by name.
pub fn expand(pattern: &str) -> Result<Vec<PathBuf>, PatternError> {
    let wild = |s: &str| s.contains(['*', '?']);
    if !wild(pattern) {
        return Ok(vec![PathBuf::from(pattern)]);
    }
    let path = Path::new(pattern);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if wild(&folder.to_string_lossy()) {
        return Err(PatternError::FolderWildcard {
            pattern: pattern.to_string(),
        });
    }
    let entries = std::fs::read_dir(&folder).map_err(|source| PatternError::Folder {
        pattern: pattern.to_string(),
        folder: folder.clone(),
        source,
    })?;
    let mut found: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .filter(|e| e.file_type().is_ok_and(|t| !t.is_dir()))
        .filter(|e| matches(name.as_bytes(), e.file_name().to_string_lossy().as_bytes()))
        .map(|e| match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.join(e.file_name()),
            _ => PathBuf::from(e.file_name()),
        })
        .collect();
    found.sort();
    if found.is_empty() {
        return Err(PatternError::NoMatch {
            pattern: pattern.to_string(),
        });
    }
    Ok(found)
}

/// Whether `name` matches `pattern` (`*`, `?`; every other byte literal).
fn matches(pattern: &[u8], name: &[u8]) -> bool {
    match (pattern.first(), name.first()) {
        (None, None) => true,
        (Some(b'*'), _) => {
            matches(&pattern[1..], name) || (!name.is_empty() && matches(pattern, &name[1..]))
        }
        (Some(b'?'), Some(_)) => matches(&pattern[1..], &name[1..]),
        (Some(p), Some(n)) if p == n => matches(&pattern[1..], &name[1..]),
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::matches;

    #[test]
    fn wildcards_match_as_a_shell_does() {
        assert!(matches(b"*.csv", b"drive1.csv"));
        assert!(matches(b"drive?.csv", b"drive1.csv"));
        assert!(!matches(b"drive?.csv", b"drive12.csv"));
        assert!(matches(b"d*e*.csv", b"drive12.csv"));
        assert!(!matches(b"*.csv", b"drive1.csv.bak"));
        assert!(matches(b"*", b""));
    }
}
