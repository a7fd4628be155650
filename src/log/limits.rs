//! Input limits: what biasctl refuses to read, so that a hostile or corrupted file (1 GB of
//! JSON, a 1 GB line, 100,000 columns) ends in a clear error within bounded time and memory.
//! The README's "Reliability" section lists them.

use std::io::{self, Read};
use std::path::Path;

/// Largest model file, drive or plant TOML or seek script read whole into memory: 64 MiB (a
/// model of a million table cells is a few tens of MB).
pub(crate) const MAX_TEXT_FILE_BYTES: u64 = 64 << 20;

/// Longest line of a measurement log (header, metadata or row): 1 MiB.
pub(crate) const MAX_LINE_BYTES: u64 = 1 << 20;

/// Most columns in a log's header.
pub(crate) const MAX_COLUMNS: usize = 1000;

/// Largest |number| in a drive or plant TOML file: far beyond any physical parameter (the
/// largest in the shipped files is Kp = 1e6), small enough that the simulator's and the
/// discretisation's products stay finite.
pub(crate) const MAX_TOML_NUMBER: f64 = 1e12;

/// Longest dwell of a seek script row, s (11.6 days).
pub(crate) const MAX_DWELL_S: f64 = 1e6;

/// Checks every number of a TOML text (integers and floats, at any depth) against
/// `MAX_TOML_NUMBER`; the message names the first offending key path (`modes[1].gain`).
/// A text that does not parse passes: the typed parse reports that with its line and column.
pub fn check_toml_numbers(text: &str) -> Result<(), String> {
    fn walk(v: &toml::Value, path: &mut String) -> Result<(), String> {
        let bad = |x: f64| !x.is_finite() || x.abs() > MAX_TOML_NUMBER;
        match v {
            toml::Value::Float(x) if !x.is_finite() => {
                Err(format!("`{path}` = {x} is not a finite number"))
            }
            toml::Value::Float(x) if bad(*x) => Err(format!(
                "`{path}` = {x:e} is outside ±{MAX_TOML_NUMBER:e}, the range biasctl's arithmetic carries"
            )),
            toml::Value::Integer(i) if bad(*i as f64) => Err(format!(
                "`{path}` = {i} is outside ±{MAX_TOML_NUMBER:e}, the range biasctl's arithmetic carries"
            )),
            toml::Value::Array(items) => {
                for (k, item) in items.iter().enumerate() {
                    let len = path.len();
                    path.push_str(&format!("[{k}]"));
                    walk(item, path)?;
                    path.truncate(len);
                }
                Ok(())
            }
            toml::Value::Table(t) => {
                for (key, item) in t {
                    let len = path.len();
                    if !path.is_empty() {
                        path.push('.');
                    }
                    path.push_str(key);
                    walk(item, path)?;
                    path.truncate(len);
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }
    match text.parse::<toml::Table>() {
        Ok(t) => walk(&toml::Value::Table(t), &mut String::new()),
        Err(_) => Ok(()),
    }
}

/// Reads a whole text file of at most `MAX_TEXT_FILE_BYTES`; a larger one is an
/// `InvalidData` error saying so (nothing beyond the limit is read).
pub(crate) fn read_text(path: &Path) -> io::Result<String> {
    let file = std::fs::File::open(path)?;
    let mut text = String::new();
    file.take(MAX_TEXT_FILE_BYTES + 1)
        .read_to_string(&mut text)?;
    if text.len() as u64 > MAX_TEXT_FILE_BYTES {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!(
                "larger than {} MiB, the most biasctl reads",
                MAX_TEXT_FILE_BYTES >> 20
            ),
        ));
    }
    Ok(text)
}

/// A reader that fails with `InvalidData` once a line (bytes since the last `\n` or `\r`, the
/// line ends of [`super::lines`]) grows beyond [`MAX_LINE_BYTES`], so that a log with one
/// endless line cannot fill memory, and a log with lone-`\r` line ends reads whatever its size.
pub(crate) struct LineLimit<R> {
    inner: R,
    run: u64,
    /// The source has ended: every read returns 0 without asking it again.
    finished: bool,
}

impl<R> LineLimit<R> {
    /// Wraps `inner`.
    pub(crate) fn new(inner: R) -> Self {
        LineLimit {
            inner,
            run: 0,
            finished: false,
        }
    }

    /// Marks the source as ended (it returned 0): later reads return 0 at once (a terminal on
    /// standard input would otherwise wait for more).
    pub(crate) fn finish(&mut self) {
        self.finished = true;
    }
}

impl<R: Read> Read for LineLimit<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.finished {
            return Ok(0);
        }
        let n = self.inner.read(buf)?;
        // No line can pass the limit within this chunk: only the run after its last newline
        // matters (found from the end, a line's length away), not a scan of every byte.
        if self.run + n as u64 <= MAX_LINE_BYTES {
            self.run = match memchr::memrchr2(b'\n', b'\r', &buf[..n]) {
                Some(i) => (n - 1 - i) as u64,
                None => self.run + n as u64,
            };
            return Ok(n);
        }
        for &b in &buf[..n] {
            if b == b'\n' || b == b'\r' {
                self.run = 0;
            } else {
                self.run += 1;
                if self.run > MAX_LINE_BYTES {
                    return Err(io::Error::new(
                        io::ErrorKind::InvalidData,
                        format!("a line longer than {} MiB", MAX_LINE_BYTES >> 20),
                    ));
                }
            }
        }
        Ok(n)
    }
}

/// Largest |value| a log cell may hold (every column: time, position, bias, covariates). Models
/// square positions and sum squares over up to millions of rows; below 1e15 those stay finite
/// and keep more than one unit of resolution (f64 carries 15–16 significant digits). No rig
/// logs a larger number; a larger one is a unit mistake or a corrupted cell.
pub(crate) const MAX_ABS_VALUE: f64 = 1e15;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_over_the_limit_fails_and_shorter_lines_pass() {
        // Reference: the limit itself — MAX_LINE_BYTES bytes pass, one more fails.
        let ok = vec![b'a'; MAX_LINE_BYTES as usize];
        let mut out = Vec::new();
        LineLimit::new([ok.as_slice(), b"\nb\n"].concat().as_slice())
            .read_to_end(&mut out)
            .unwrap();
        let long = vec![b'a'; MAX_LINE_BYTES as usize + 1];
        let e = LineLimit::new(long.as_slice())
            .read_to_end(&mut Vec::new())
            .unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidData);
        // A lone `\r` ends a line too (old Mac files): lines of the limit, then one past it.
        let mac = [ok.as_slice(), b"\r", ok.as_slice(), b"\r\n", ok.as_slice()].concat();
        LineLimit::new(mac.as_slice())
            .read_to_end(&mut out)
            .unwrap();
        let e = LineLimit::new([mac.as_slice(), b"a"].concat().as_slice())
            .read_to_end(&mut Vec::new())
            .unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidData);
    }

    #[test]
    fn toml_numbers_beyond_the_limit_are_named_by_key_path() {
        check_toml_numbers("kp = 1e6\n[[modes]]\ngain = 0.3\n").unwrap();
        let e = check_toml_numbers("kp = 1e6\n[[modes]]\ngain = 0.3\n[[modes]]\ngain = 1e308\n")
            .unwrap_err();
        assert!(e.contains("`modes[1].gain` = 1e308"), "{e}");
        assert!(check_toml_numbers("x = nan").unwrap_err().contains("`x`"));
        assert!(check_toml_numbers("x = 20000000000000").is_err());
    }

    #[test]
    fn text_files_over_the_limit_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.json");
        let f = std::fs::File::create(&p).unwrap();
        f.set_len(MAX_TEXT_FILE_BYTES + 1).unwrap(); // sparse: no disk used
        let e = read_text(&p).unwrap_err();
        assert!(e.to_string().contains("64 MiB"), "{e}");
    }
}
