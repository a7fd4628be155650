//! Kept for the paths other modules and branches use: the output layer is [`crate::render`].

pub use crate::render::{OutputError, write_atomic, write_string_atomic};
