//! Fault injection for the output paths: a writer that fails with a chosen OS error after a
//! given number of bytes, armed per thread by the unit tests and inert otherwise.

use std::io::{self, Write};

thread_local! {
    static FAULT: std::cell::Cell<Option<(u64, i32)>> = const { std::cell::Cell::new(None) };
}

/// A writer that fails with `errno` once `at` bytes have been written through it.
pub(crate) struct Faulty<W> {
    inner: W,
    written: u64,
    fault: Option<(u64, i32)>,
}

impl<W> Faulty<W> {
    /// Wraps `inner`, armed with this thread's fault if one is set.
    pub(crate) fn armed(inner: W) -> Self {
        Faulty {
            inner,
            written: 0,
            fault: FAULT.with(std::cell::Cell::get),
        }
    }
}

impl<W: Write> Write for Faulty<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if let Some((at, errno)) = self.fault {
            if self.written >= at {
                return Err(io::Error::from_raw_os_error(errno));
            }
            let room = usize::try_from(at - self.written).unwrap_or(usize::MAX);
            let n = self.inner.write(&buf[..buf.len().min(room)])?;
            self.written += n as u64;
            return Ok(n);
        }
        let n = self.inner.write(buf)?;
        self.written += n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

/// Runs `f` with every output written on this thread (files and stdout) failing with the OS
/// error `errno` (e.g. `libc::ENOSPC`, `libc::EIO`) once `at_byte` bytes have gone into it: the
/// fault-injection hook of the unit tests.
#[cfg(test)]
pub(crate) fn with_write_fault<R>(at_byte: u64, errno: i32, f: impl FnOnce() -> R) -> R {
    let old = FAULT.with(|c| c.replace(Some((at_byte, errno))));
    let out = f();
    FAULT.with(|c| c.set(old));
    out
}
