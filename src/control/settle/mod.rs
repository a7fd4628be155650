//! The settle-optimal integrator start value at the seek → track-following handoff (the paper's
//! Section IV, eq. 13–16) and our robust choice for an uncertain bias.
//!
//! ## Model
//! In deviation coordinates x̃ = x − x_ss(d) (x_ss the loop's equilibrium for the constant bias
//! d, see [`Controller`](crate::control::Controller)) the loop is x̃(k+1) = Acl x̃(k) and the measured position error
//! (e = y − r, µm) is linear in the integrator start value ζ = z0 − z_ss(d), which is the start
//! value **relative to its converged value** (µm·samples; zero feedforward is ζ = 0):
//! e(k) = a_k·ζ + c_k, with c_k = ce_k·e0 + cv_k·v0 + cu_k·(u_prev − d)   (flexible modes at rest).
//!
//! ## Settling
//! The settle index is one plus the last sample k < N (horizon) with |e(k)| > δ, or 0 if there is
//! none; the response is *settled* only if at least `hold` samples (M ≥ 1) at the end of the
//! horizon lie in the window, so a response still outside the window at k = N − 1 is "not
//! settled". Settle time = settle index × Ts.
//!
//! Per sample (eq. 14): for a_k > 0, L_k = (−δ − c_k)/a_k ≤ ζ ≤ (δ − c_k)/a_k = U_k, reversed
//! for a_k < 0. For a_k = 0 the sample constrains nothing if |c_k| ≤ δ (U = +∞, L = −∞) and
//! makes every settle index ≤ k infeasible otherwise (U = −∞, L = +∞).
//! Backward running bounds (eq. 15): U*(k) = min_{j ≥ k} U_j, L*(k) = max_{j ≥ k} L_j. The
//! minimum settle index k* is the first k ≤ N − M with L*(k) ≤ U*(k); every ζ in
//! [L*(k*), U*(k*)] achieves it (eq. 16). The width U* − L* grows with k, so a start value ζ
//! settles at the first k with L*(k) ≤ ζ ≤ U*(k).
//!
//! ## Robust choice for an uncertain bias (ours)
//! If the bias is only known to ±Δb, the converged value the start is referenced to is off by
//! up to s = |∂z/∂d|·Δb, so the true ζ lies anywhere in [ζ_chosen − s, ζ_chosen + s]. The
//! worst-case settle index of ζ_chosen is the first k with [ζ − s, ζ + s] ⊂ [L*(k), U*(k)]; it is
//! minimised by the first k with U*(k) − L*(k) ≥ 2s, at that interval's midpoint. (Assumption:
//! u_prev − d is known at handoff, as for a step from rest where the previous control equals the
//! actual bias.) [`worst_case_settle`] reports it together with zero feedforward's worst case.
//!
//! ## Fast path
//! [`HandoffTable`] precomputes, per controller and horizon, −ce_k/a_k, −cv_k/a_k, −cu_k/a_k and
//! 1/|a_k| as four plain arrays, so at handoff each sample's bounds are three multiply-adds plus
//! ±δ/|a_k| in a loop the compiler vectorises, and [`HandoffTable::solve`] finds k*, the optimal
//! interval, the robust choice and zero feedforward's worst case in one backward pass over
//! blocks of 8 samples that stops at the block where the interval empties: no allocation.
//! [`HandoffTable::bounds_into`] fills caller-provided [`Bounds`] buffers with the full curves
//! (Fig. 15). Both are tested against a slow obvious implementation (every bound, the running
//! min/max sample by sample, linear searches): identical results.

mod analyse;
mod bounds;
mod error;
mod handoff;
mod kernels;
mod report;
mod response;
mod robust;
mod spec;
mod table;

pub use analyse::analyse;
pub use bounds::Bounds;
pub use error::{AnalyseError, ConfigError, PlantFileError, SettleError};
pub use handoff::{Handoff, HandoffSolution, Interval};
pub use report::SettleReport;
pub(crate) use response::settle_ms;
pub use response::{Response, handoff_state, settle_index};
pub use robust::{PaperRobust, RobustChoice, WorstCase, worst_case_settle};
pub use spec::{Scenario, SettleConfig, SettleSpec, Window};
pub use table::HandoffTable;
