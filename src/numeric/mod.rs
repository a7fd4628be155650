//! Shared numerics below everything else: statistics and special functions ([`stats`], with
//! Hartigan's dip test), and the seeded random-number generator ([`rng`]) that makes every
//! simulation byte-identical for a given seed; the thread pool ([`parallel`]); least squares by
//! streaming QR ([`qr`], its inner loops in [`kernels`]) and one-dimensional minimisation
//! ([`search`]).

pub(crate) mod kernels;
pub(crate) mod parallel;
pub(crate) mod qr;
pub(crate) mod rng;
pub(crate) mod search;
pub(crate) mod stats;
