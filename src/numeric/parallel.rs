//! Threads: the process has one `rayon` pool, one worker per core unless `--threads N`
//! ([`set_threads`]) says otherwise. Parallel work in biasctl gives each task its own inputs
//! (and its own seed where it draws random numbers) and collects results in task order, so every
//! result is identical for any thread count; [`with_threads`] runs a closure on a pool of a given
//! size, which is how the tests prove it.

/// An invalid thread count, or a pool that could not be started.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ThreadsError {
    /// `--threads 0`.
    #[error("--threads must be at least 1 (got 0)")]
    Zero,
    /// The operating system refused the threads, or the global pool was already started.
    #[error("cannot start a pool of {threads} threads: {message}")]
    Pool {
        /// Threads asked for.
        threads: usize,
        /// rayon's reason.
        message: String,
    },
}

/// Sizes the process-wide pool to `threads` workers (call once, before any parallel work).
pub fn set_threads(threads: usize) -> Result<(), ThreadsError> {
    if threads == 0 {
        return Err(ThreadsError::Zero);
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global()
        .map_err(|e| ThreadsError::Pool {
            threads,
            message: e.to_string(),
        })
}

/// Runs `f` with its parallel work on a pool of exactly `threads` workers.
pub fn with_threads<T: Send>(
    threads: usize,
    f: impl FnOnce() -> T + Send,
) -> Result<T, ThreadsError> {
    if threads == 0 {
        return Err(ThreadsError::Zero);
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| ThreadsError::Pool {
            threads,
            message: e.to_string(),
        })?;
    Ok(pool.install(f))
}
