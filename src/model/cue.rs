//! The vocabulary between the diagnosis and the terms: the residual patterns ([`Cue`]) a
//! diagnosis finds, how a term answers one ([`Answer`]) and how a model's term covers a
//! suggested one ([`Cover`]). Each term declares its answers in its own file; the registry row
//! points at them.

use crate::history::Feature;

/// The residual patterns a term answers: its rank among the terms that answer `cue`, and how
/// the suggestion is written; `None` for a pattern it does not answer.
pub(crate) type AnswersFn = fn(Cue) -> Option<Answer>;

/// The law a residual's curve against a covariate (or the derived velocity) follows, the first
/// that applies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Law {
    /// A line in the signed value whose sign is the direction's (viscous friction).
    OddLinear,
    /// Its sign is the direction's but the law is not that line (friction falling off from a
    /// breakaway level at low speed).
    Velocity,
    /// A line.
    Linear,
    /// Any other curve.
    Other,
}

/// A residual pattern the diagnosis finds, for which the registry names the terms that answer
/// it ([`candidates`]). `signed`: the residual follows the value times the direction of the
/// last move (the effect flips with the approach direction).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Cue {
    /// A history feature.
    Feature(Feature, bool),
    /// A covariate column, its curve following a [`Law`].
    Covariate(Law, bool),
    /// The summed rest-memory feature.
    SummedMemory(bool),
    /// A covariate column seen through a first-order lag (the name is the column).
    Lagged,
    /// The velocity derived from the positions and times, its curve following a [`Law`]
    /// ([`Law::Velocity`]: the friction falls off at low speed; any other: a line first).
    DerivedVelocity(Law),
}

/// How a term answers a [`Cue`]: its rank among the terms that answer it (lowest first) and
/// whether the suggestion names the feature or column (`HEAD:NAME`) or is the term's
/// [`BuiltinTerm::suggest`] text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Answer {
    /// Rank among the terms answering the same cue; distinct per cue.
    pub rank: u8,
    /// `HEAD:NAME` (else the term's suggestion text).
    pub named: bool,
    /// Offered only when its spec text parses.
    pub parsed: bool,
}

impl Answer {
    /// The term's suggestion text, at `rank`.
    pub(crate) const fn fixed(rank: u8) -> Option<Self> {
        Some(Self {
            rank,
            named: false,
            parsed: false,
        })
    }
    /// `HEAD:NAME`, at `rank`.
    pub(crate) const fn named(rank: u8) -> Option<Self> {
        Some(Self {
            rank,
            named: true,
            parsed: false,
        })
    }
    /// `HEAD:NAME`, at `rank`, offered only when it parses.
    pub(crate) const fn named_if_parses(rank: u8) -> Option<Self> {
        Some(Self {
            rank,
            named: true,
            parsed: true,
        })
    }
}

/// When a model's term `e` covers a suggested term `t` of the same head.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Cover {
    /// Only the same text.
    Exact,
    /// Any term of the head covers any other (`play:N` holds the play family).
    Family,
    /// The head's argument counts elements (none: one) and `e` covers `t` with at least as
    /// many (`dahl:4` covers `dahl`).
    Count,
}
