//! Fitting a [`ModelSpec`] to a measurement log.
//!
//! 1. **Prepare**: every [`TermSpec`](crate::model::term::TermSpec) looks at the training data
//!    once ([`FitData`]) and fixes its knots/centring; an `intercept` is added unless a term
//!    spans a constant.
//! 2. **One linear least-squares solve** for all linear parameters of all terms: the basis rows
//!    of the measured rows are streamed through a chunked Householder QR (TSQR: the running
//!    `R` factor stacked on 1024 new rows, re-factorised), so memory is O(p²) and nothing like
//!    normal equations is ever formed; rows sparse in recurring patterns are factorised per
//!    pattern on their non-zero columns (`numeric::qr::PatternQr`). Terms supply
//!    centred/scaled columns (`poly2` uses `(x − centre)/scale`, hinges are divided by their
//!    largest knot). Columns whose `R` diagonal falls below `rank_tolerance` × their norm
//!    cannot be determined from the log:
//!    for hinge terms they are fixed at 0 with a warning, otherwise the fit fails naming the
//!    parameter. Covariance `s²·R⁻¹R⁻ᵀ`, `s² = RSS/(n − rank)`.
//! 3. **Variable projection** for a term's nonlinear parameter (the Dahl rate): a 1-D search
//!    (grid, then golden section) on the least-squares RSS with the linear parameters refitted
//!    at each candidate. The other terms' columns are factorised once and each candidate's RSS
//!    comes in closed form from its own columns' sums (`Projection`; a full solve where a column
//!    nears the rank tolerance); the chosen value is then solved in full. Its standard error
//!    comes from the curvature of the RSS (three full solves). A term that searches its own
//!    parameters ([`Term::search`](crate::model::term::Term::search), `bump`'s centre and
//!    width) is handed the residual of the other terms and this RSS for any version of itself
//!    instead.
//! 4. **Causal offsets** (`drift`) are tuned on the residual series of the other terms.
//! 5. The fitted model is replayed causally over the training log for the fit statistics
//!    (only its adaptive terms, over the others' stored prediction, where those read nothing
//!    but residuals: `statistics::adaptive_tail`).
//!
//! One concern a file, in the order of the steps: `options` (the settings), `sharing` (the
//! steps in order, and what many refits of one log share), `design` (the design rows replayed),
//! `search` (the nonlinear searches), `projection` and `kernels` (variable projection and its
//! accumulation kernels), `solve`, `statistics` (the residuals' statistics) and `assemble`
//! (the fitted model and its warnings). The linear algebra below them is in
//! `numeric::{qr, search}`.

mod assemble;
mod design;
mod kernels;
mod options;
mod projection;
mod search;
mod sharing;
mod solve;
mod statistics;

use crate::log::Log;
use crate::model::{FittedModel, ModelSpec};

pub use crate::model::data::{FitData, FitError, FitReport};
pub use options::{CheckedFitOptions, FitOptions};
pub(crate) use sharing::{Refits, fit_sharing};

/// Fits `spec` to the measured rows of `log`.
pub fn fit(spec: &ModelSpec, log: &Log, opts: &CheckedFitOptions) -> Result<FittedModel, FitError> {
    fit_sharing(spec, log, opts, &Refits::default(), &[])
}
