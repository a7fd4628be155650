//! `biasctl check`'s streamed sampling of a log (`summarise_sampling`), with the temporary
//! file its later passes read.

use super::{Sampling, SamplingStream};

/// Streams the log `reader` was opened on (from `path` with `map`) and returns its summary
/// ([`LogReader::summarise`](crate::log::LogReader::summarise)) and its [`sampling`](super::sampling()), in memory
/// independent of the number of rows (`biasctl check`): the exact quantiles (the same bits as
/// [`sampling`](super::sampling()) of every row in memory) need a few passes of radix selection (one on logs
/// whose quantiles take few distinct values and whose clock the first pass settles, three on a
/// dense 1 kHz log with noisy positions, more when a jittered clock's spread must be read).
/// The log itself is read once: while it is, the time and position of every row (16 bytes per
/// row) are written to a temporary file in [`std::env::temp_dir`], which the later passes read
/// and which is removed at the end. Should that file not be made or written, a regular file is
/// read again from `path` instead (every pass validates the rows as the first; a file whose row
/// count changes between passes is an error); for standard input (`path` `-`) it is an error.
pub fn summarise_sampling(
    reader: &mut crate::log::LogReader<Box<dyn std::io::Read>>,
    path: &std::path::Path,
    map: &crate::log::ColumnMap,
) -> Result<(crate::log::LogSummary, Sampling), crate::log::LogError> {
    use crate::log::{LogError, LogReader, Row, STDIN_PATH};
    use std::io::{BufWriter, Read, Seek, Write};
    let file = reader.schema().file.clone();
    let io = |source: std::io::Error| LogError::Io {
        file: file.clone(),
        source,
    };
    let stdin = path.as_os_str() == STDIN_PATH;
    // Standard input cannot be read again: its passes need the temporary file.
    let spool_failed = |e: std::io::Error| {
        let dir = std::env::temp_dir();
        io(std::io::Error::new(
            e.kind(),
            format!(
                "the later passes need a temporary file in {} (set TMPDIR to a writable folder with room for 16 bytes per row): {e}",
                dir.display()
            ),
        ))
    };
    let mut stream = SamplingStream::new();
    let mut spool = match Spool::create() {
        Ok(s) => Some(s),
        Err(e) if stdin => return Err(spool_failed(e)),
        Err(_) => None,
    };
    let mut spool_err = None;
    let summary = {
        let mut out = spool.as_mut().map(|s| BufWriter::new(&mut s.file));
        let summary = reader.summarise_each(|r| {
            stream.push(r.time_s, r.track);
            if let Some(w) = out.as_mut()
                && spool_err.is_none()
            {
                let mut rec = [0u8; 16];
                rec[..8].copy_from_slice(&r.time_s.to_le_bytes());
                rec[8..].copy_from_slice(&r.track.to_le_bytes());
                if let Err(e) = w.write_all(&rec) {
                    spool_err = Some(e);
                }
            }
        })?;
        let flushed = out.map(|w| w.into_inner().map(|_| ()).map_err(|e| e.into_error()));
        spool_err = spool_err.or(flushed.and_then(Result::err));
        summary
    };
    if let Some(e) = spool_err {
        if stdin {
            return Err(spool_failed(e));
        }
        // A full or failing temporary directory: read the file again instead.
        spool = None;
    }
    let changed = || {
        io(std::io::Error::other(
            "the file changed while it was read (its row count differs between passes)",
        ))
    };
    while stream.end_pass() {
        let mut rows = 0u64;
        match spool.as_mut() {
            Some(s) => {
                s.file.rewind().map_err(io)?;
                // Whole records from a block buffer (a short read may split one).
                let mut buf = vec![0u8; 1 << 16];
                let mut filled = 0;
                loop {
                    let got = s.file.read(&mut buf[filled..]).map_err(io)?;
                    filled += got;
                    let whole = filled - filled % 16;
                    for rec in buf[..whole].chunks_exact(16) {
                        let (t, x) = rec.split_at(8);
                        let f = |b: &[u8]| f64::from_le_bytes(b.try_into().unwrap_or([0; 8]));
                        stream.push(f(t), f(x));
                    }
                    rows += (whole / 16) as u64;
                    buf.copy_within(whole..filled, 0);
                    filled -= whole;
                    if got == 0 {
                        break;
                    }
                }
                if filled != 0 {
                    return Err(changed());
                }
            }
            None => {
                let mut again = LogReader::open(path, map)?;
                let mut row = Row::empty(again.schema().covariates.len());
                while again.read_into(&mut row)? {
                    stream.push(row.time_s, row.track);
                    rows += 1;
                }
            }
        }
        if rows != summary.rows {
            return Err(changed());
        }
    }
    let sampling = stream.finish().ok_or_else(changed)?;
    Ok((summary, sampling))
}

/// A temporary file of `summarise_sampling`, removed when dropped.
struct Spool {
    file: std::fs::File,
    path: std::path::PathBuf,
}

impl Spool {
    /// A new file in the temporary directory, named after the process and the time.
    fn create() -> std::io::Result<Self> {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        let path =
            std::env::temp_dir().join(format!("biasctl-check-{}-{nanos}.bin", std::process::id()));
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&path)?;
        Ok(Self { file, path })
    }
}

impl Drop for Spool {
    fn drop(&mut self) {
        // Best effort: a file that cannot be removed stays in the temporary directory.
        let _ = std::fs::remove_file(&self.path);
    }
}
