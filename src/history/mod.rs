//! The seek history: a state machine fed one seek at a time that yields, for every seek, the
//! features of its history that bias depends on (the paper's P1–P7).
//!
//! Conventions: positions in tracks (0 at the outer diameter, OD); a positive seek length moves
//! inbound, towards the inner diameter (ID); direction `+1` is inbound, `-1` outbound, `0` before
//! the first move. Times in seconds.
//!
//! The *uncrossed rest positions* (the paper's memory effect, P6) are kept in [`RestMemory`]: two
//! stacks, one on each side of the head, each sorted with the nearest position on top. A seek pops
//! the positions it crosses from the stack ahead of it and pushes its source onto the stack behind,
//! so an update costs amortised O(1) whatever the length of the history.
//!
//! ```
//! use biasctl::History;
//! let mut h = History::new();
//! h.step(0.0, 100.0);          // first row: the head starts at track 100
//! h.step(1.0, 150.0);          // rest at 100, move inbound to 150
//! let f = h.step(2.0, 120.0);  // reverse: outbound to 120
//! assert_eq!(f.seek_length, -30.0);
//! assert!(f.direction_change);
//! // 100 (OD side of 120) was never crossed since the head rested there:
//! assert_eq!(f.rest_distance_od, Some(20.0));
//! ```
//!
//! One concern per file:
//! - `features`: [`SeekFeatures`], the features of one seek's history, and [`Feature`], their names;
//! - `machine`: the state machine [`History`] and its [`RestMemory`];
//! - `direction`: the deadband tracker, [`DirectionSource`] and [`DirectionSetting`];
//! - `replay`: [`replay`] of a whole log, and its turning points;
//! - `columns`: the compact history columns a long log's replays read;
//! - `sampling`: [`Sampling`], how a log samples the motion ([`sampling`], [`log_sampling`]);
//! - `stream`: the same analysis in passes, in memory independent of the log's length;
//! - `spool`: [`summarise_sampling`], `biasctl check`'s streamed analysis with its temporary file.

mod columns;
mod direction;
mod features;
mod machine;
mod replay;
mod sampling;
mod spool;
mod stream;

pub(crate) use columns::HistoryColumns;
pub use direction::{DirectionError, DirectionSetting, DirectionSource};
pub(crate) use direction::{DirectionTracker, sign};
pub use features::{Feature, SeekFeatures};
pub use machine::{History, RestMemory};
pub use replay::{Replay, replay};
pub(crate) use replay::{replay_checked, replay_with, reversal_amplitudes};
pub use sampling::{Sampling, log_sampling, sampling};
pub use spool::summarise_sampling;
pub(crate) use stream::SamplingStream;
