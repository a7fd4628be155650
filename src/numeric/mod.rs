//! Shared numerics below everything else: statistics and special functions ([`stats`], with
//! Hartigan's dip test), and the seeded random-number generator ([`rng`]) that makes every
//! simulation byte-identical for a given seed; the thread pool ([`parallel`]).

pub(crate) mod parallel;
pub(crate) mod rng;
pub(crate) mod stats;
