//! Model-structure selection: which terms a model should have, decided by refitting. It sits
//! on the residual engine ([`crate::diagnose`](mod@crate::diagnose)) and calls the fit: every suggested edit is
//! applied, refitted and scored out of sample ([`diagnose_verified`]), the verified edits are
//! applied one at a time ([`discover()`]), and a list of terms is climbed one rung at a time
//! ([`ladder_fit`], [`suggestion_path`]).

mod candidates;
mod discover;
mod edit_score;
mod gain;
mod ladder;
mod path;
mod refit;
mod second_round;
mod verified;
mod verify;

pub(crate) use candidates::{candidates, edit_for, table_spacing, tries_every_term};
pub use discover::{
    CheckedDiscoverConfig, DiscoverConfig, DiscoverError, DiscoverStep, Discovery, discover,
};
pub(crate) use edit_score::score_edits;
pub use ladder::{Ladder, LadderStep, LadderTerms, ladder_fit, ladder_terms};
pub use path::{PathStep, suggestion_path, suggestion_path_from};
pub(crate) use second_round::verify_two_rounds;
pub use verified::diagnose_verified;
pub(crate) use verify::verify;
pub use verify::{CheckedVerifyConfig, VerifyConfig};

#[cfg(test)]
mod tests_verify;
