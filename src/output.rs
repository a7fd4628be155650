//! Atomic output: every file biasctl writes is written to a temporary name beside its target and
//! renamed into place only when it is complete, so an error never leaves a half-written file.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// An error while writing an output file, naming the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    /// The file (or its temporary sibling) could not be created, written or renamed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The output file that was being written.
        path: PathBuf,
        /// The operating-system error.
        #[source]
        source: io::Error,
    },
    /// The content producer failed; nothing was written to `path`.
    #[error("{message} (nothing written to {path})")]
    Producer {
        /// The output file that was not written.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

/// Writes `path` atomically: `produce` writes into a buffered temporary file in the same
/// directory, which is renamed to `path` only if `produce` and the flush succeed. On any error the
/// temporary file is removed and `path` is left as it was.
///
/// The producer returns `Result<(), E>` with any error type that converts to a message, so that a
/// domain error inside the producer also aborts the write.
pub fn write_atomic<E, F>(path: &Path, produce: F) -> Result<(), OutputError>
where
    E: std::fmt::Display,
    F: FnOnce(&mut BufWriter<File>) -> Result<(), E>,
{
    let tmp = temp_sibling(path);
    let io_err = |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = File::create(&tmp).map_err(io_err)?;
    let mut writer = BufWriter::new(file);
    let produced = produce(&mut writer);
    let finished = match produced {
        Ok(()) => writer
            .flush()
            .and_then(|_| writer.get_ref().sync_all())
            .map_err(io_err),
        Err(e) => Err(OutputError::Producer {
            path: path.to_path_buf(),
            message: e.to_string(),
        }),
    };
    drop(writer);
    match finished {
        Ok(()) => std::fs::rename(&tmp, path).map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            io_err(e)
        }),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// Writes a whole string atomically (see [`write_atomic`]).
pub fn write_string_atomic(path: &Path, text: &str) -> Result<(), OutputError> {
    write_atomic(path, |w| w.write_all(text.as_bytes()))
}

fn temp_sibling(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".to_string());
    let tmp_name = format!(".{name}.{}.tmp", std::process::id());
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir.join(tmp_name),
        _ => PathBuf::from(tmp_name),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn failed_producer_leaves_no_file_and_keeps_old_content() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.csv");
        write_string_atomic(&path, "old").unwrap();
        let res = write_atomic(&path, |w| {
            w.write_all(b"half").map_err(|e| e.to_string())?;
            Err::<(), _>("bad value on line 3".to_string())
        });
        assert!(matches!(res, Err(OutputError::Producer { .. })));
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
        let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(leftovers.len(), 1, "temporary file left behind");
    }
}
