//! Shared numerics below everything else: statistics and special functions (`stats`, with
//! Hartigan's dip test), and the seeded random-number generator (`rng`) that makes every
//! simulation byte-identical for a given seed; the thread pool (`parallel`); least squares by
//! streaming QR (`qr`, its inner loops in `kernels`) and one-dimensional minimisation
//! (`search`).

pub(crate) mod kernels;
pub(crate) mod parallel;
pub(crate) mod qr;
pub(crate) mod rng;
pub(crate) mod runs;
pub(crate) mod search;
pub(crate) mod stats;
// The namespace's public items that live in its submodules (the crate root keeps only the
// names most users need; see `biasctl::prelude`).
pub use parallel::{ThreadsError, set_threads, with_threads};
pub use rng::SimRng;
pub use stats::{Dip, DipTest, Histogram, Trend, dip_test, dip_test_sorted, mean, sorted, std_dev};
