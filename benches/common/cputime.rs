//! A criterion measurement of the benchmarking thread's CPU time (`CLOCK_THREAD_CPUTIME_ID`),
//! reported in the same units as wall time. On a shared machine (the project's 2-core VM runs
//! several builds at once) wall time measures the queue for a core as much as the code; the
//! thread's CPU time is the work a dedicated core would do, so per-core throughputs from it are
//! comparable across runs. Select it with `BIASCTL_BENCH_CPU=1` (else wall time, criterion's
//! default). Shared memory bandwidth and caches still vary with the load. Work that runs on a
//! `rayon` pool runs on the pool's threads, not the benchmarking one: measure it with
//! `BIASCTL_BENCH_CPU=process` (the CPU time of every thread of the process,
//! `CLOCK_PROCESS_CPUTIME_ID`; with `RAYON_NUM_THREADS=1` that is one core's work).

use criterion::measurement::{Measurement, ValueFormatter, WallTime};
use std::time::Duration;

/// The CPU time of one clock: the calling thread's (`CLOCK_THREAD_CPUTIME_ID`) or the whole
/// process's (`CLOCK_PROCESS_CPUTIME_ID`), see the module docs.
pub struct CpuTime(libc::clockid_t);

/// The calling thread's CPU time.
pub const THREAD_CPU_TIME: CpuTime = CpuTime(libc::CLOCK_THREAD_CPUTIME_ID);

/// The CPU time of every thread of the process.
pub const PROCESS_CPU_TIME: CpuTime = CpuTime(libc::CLOCK_PROCESS_CPUTIME_ID);

impl CpuTime {
    /// The clock's CPU time so far.
    fn now(&self) -> Duration {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `ts` is a valid timespec; the clock ids are constants Linux and macOS know.
        let rc = unsafe { libc::clock_gettime(self.0, &mut ts) };
        assert_eq!(rc, 0, "clock_gettime({}) failed", self.0);
        Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
    }
}

/// Wall time's formatter (values are nanoseconds in both).
static WALL: WallTime = WallTime;

impl Measurement for CpuTime {
    type Intermediate = Duration;
    type Value = Duration;
    fn start(&self) -> Duration {
        self.now()
    }
    fn end(&self, start: Duration) -> Duration {
        self.now().saturating_sub(start)
    }
    fn add(&self, a: &Duration, b: &Duration) -> Duration {
        *a + *b
    }
    fn zero(&self) -> Duration {
        Duration::ZERO
    }
    fn to_f64(&self, v: &Duration) -> f64 {
        v.as_nanos() as f64
    }
    fn formatter(&self) -> &dyn ValueFormatter {
        WALL.formatter()
    }
}

/// Whether `BIASCTL_BENCH_CPU` asks for CPU time (of the thread, or with `process` of the
/// whole process).
pub fn cpu_time_requested() -> bool {
    std::env::var_os("BIASCTL_BENCH_CPU").is_some_and(|v| v != "0")
}

/// Whether `BIASCTL_BENCH_CPU=process` asks for the whole process's CPU time.
pub fn process_cpu_time_requested() -> bool {
    std::env::var_os("BIASCTL_BENCH_CPU").is_some_and(|v| v == "process")
}

/// `fn main` of a bench whose one function `$bench` is generic over the measurement: thread
/// CPU time with `BIASCTL_BENCH_CPU=1`, the process's with `BIASCTL_BENCH_CPU=process`, else wall time; the usual criterion flags apply.
#[macro_export]
macro_rules! bench_main {
    ($bench:ident) => {
        fn main() {
            if cputime::cpu_time_requested() {
                let clock = if cputime::process_cpu_time_requested() {
                    cputime::PROCESS_CPU_TIME
                } else {
                    cputime::THREAD_CPU_TIME
                };
                let mut c = criterion::Criterion::default()
                    .with_measurement(clock)
                    .configure_from_args();
                $bench(&mut c);
                c.final_summary();
            } else {
                let mut c = criterion::Criterion::default().configure_from_args();
                $bench(&mut c);
                c.final_summary();
            }
        }
    };
}
