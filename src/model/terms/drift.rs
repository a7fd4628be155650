//! `drift[:ALPHA]`: the continually re-estimated constant of eq. 2 (paper P7), as a causal
//! offset: after each measured row the drift estimate `m` moves a fraction `alpha` of the way
//! towards the row's residual without drift, `m ← m + alpha·(y − ŷ)` where `ŷ` already includes
//! `m` (exponential forgetting; a time constant of about `1/alpha` measurements). A row's
//! contribution is `m` from the rows before it only; it starts at 0.
//!
//! `alpha` is given (`drift:0.05`) or chosen on the training data: a 1-D search on
//! `ln alpha ∈ [ln 1e-4, 0]` (16-point grid, then five zooms around the best), minimising the one-step-ahead squared error
//! of the other terms' residuals. It has no standard error (reported as `null`).

use crate::codegen::{CContext, CTerm};
use crate::model::ModelError;
use crate::model::cue::{Answer, Cue};
use crate::model::data::{FitData, FitError};
use crate::model::term::{Param, Seek, Term, TermCaps, TermSpec, TermState};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The head of the term's spec text (`drift`).
pub(crate) const HEAD: &str = "drift";

/// Spec of the `drift` term.
#[derive(Debug, Clone, Copy)]
pub struct DriftSpec {
    /// Fixed forgetting factor, or `None` to choose it on the training data.
    pub alpha: Option<f64>,
}

impl TermSpec for DriftSpec {
    fn name(&self) -> String {
        match self.alpha {
            Some(a) => format!("drift:{a}"),
            None => HEAD.into(),
        }
    }
    fn prepare(&self, _data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        Ok(Arc::new(DriftTerm {
            name: self.name(),
            alpha: self.alpha.unwrap_or(0.05),
            fixed: self.alpha.is_some(),
        }))
    }
}

/// The fitted `drift` term.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct DriftTerm {
    /// Spec string.
    pub name: String,
    /// Forgetting factor per measured row, in (0, 1].
    pub alpha: f64,
    /// Whether `alpha` was given rather than searched.
    pub fixed: bool,
}

/// One-step-ahead sum of squared errors of exponential forgetting with factor `alpha` on `e`.
pub fn forgetting_sse(e: &[f64], alpha: f64) -> f64 {
    let (mut m, mut sse) = (0.0, 0.0);
    for &v in e {
        let d = v - m;
        sse += d * d;
        m += alpha * d;
    }
    sse
}

/// Candidates evaluated together in one pass over the residuals.
const LANES: usize = 16;

/// One-step-ahead SSE for `LANES` forgetting factors at once (independent recursions, so the
/// pass is not latency bound). Runs the AVX2 copy when the CPU has it: the same operations in
/// the same order four lanes to a register instead of two (Rust contracts no multiply and add
/// into a fused one), so each SSE is the same bits as [`forgetting_sse`] of its factor alone
/// (tested); the portable copy spills its 16 lanes out of the 16 SSE registers and is bound
/// by its additions, the AVX2 one by the sub–mul–add chain of one row.
fn forgetting_sse_many(e: &[f64], alphas: &[f64; LANES]) -> [f64; LANES] {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { forgetting_sse_many_avx2(e, alphas) };
    }
    forgetting_sse_many_portable(e, alphas)
}

/// [`forgetting_sse_many`] compiled for AVX2.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn forgetting_sse_many_avx2(e: &[f64], alphas: &[f64; LANES]) -> [f64; LANES] {
    forgetting_sse_many_portable(e, alphas)
}

/// [`forgetting_sse_many`] for any CPU.
#[inline(always)]
fn forgetting_sse_many_portable(e: &[f64], alphas: &[f64; LANES]) -> [f64; LANES] {
    let mut m = [0.0; LANES];
    let mut sse = [0.0; LANES];
    for &v in e {
        for i in 0..LANES {
            let d = v - m[i];
            sse[i] += d * d;
            m[i] += alphas[i] * d;
        }
    }
    sse
}

/// Minimises the one-step SSE over `ln alpha ∈ [lo, hi]`: a 16-point grid, then five zooms into
/// the bracket around the best point (resolution (hi − lo)·(2/15)⁵ ≈ 4e-4 in ln alpha).
fn zoom_search(e: &[f64], mut lo: f64, mut hi: f64) -> f64 {
    let mut best = 0.5 * (lo + hi);
    for _ in 0..6 {
        let step = (hi - lo) / (LANES - 1) as f64;
        let ts: [f64; LANES] = std::array::from_fn(|i| lo + step * i as f64);
        let sse = forgetting_sse_many(e, &ts.map(f64::exp));
        let i = (0..LANES)
            .min_by(|&a, &b| sse[a].total_cmp(&sse[b]))
            .unwrap_or(0);
        best = ts[i];
        lo = ts[i.saturating_sub(1)];
        hi = ts[(i + 1).min(LANES - 1)];
    }
    best
}

impl Term for DriftTerm {
    fn name(&self) -> String {
        self.name.clone()
    }
    fn param_names(&self) -> Vec<String> {
        Vec::new()
    }
    fn start(&self, _covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        Ok(Box::new(DriftState {
            alpha: self.alpha,
            m: 0.0,
        }))
    }
    fn caps(&self) -> TermCaps {
        TermCaps {
            adaptive: true,
            reads_only_residuals: true,
            ..TermCaps::DEFAULT
        }
    }
    fn forgetting_factor(&self) -> Option<f64> {
        // `DriftState`: offset `m` (from 0), update `m += alpha · e`.
        Some(self.alpha)
    }
    fn tune_on_residuals(&self, residuals: &[f64]) -> Option<Arc<dyn Term>> {
        if self.fixed || residuals.is_empty() {
            return None;
        }
        let t = zoom_search(residuals, (1e-4f64).ln(), 0.0);
        Some(Arc::new(DriftTerm {
            name: self.name.clone(),
            alpha: t.exp(),
            fixed: false,
        }))
    }
    fn report(&self, _coef: &[f64], _cov: &[f64], _nl: Option<f64>) -> Vec<Param> {
        vec![Param {
            name: format!("{}.alpha", self.name),
            value: self.alpha,
            se: None,
        }]
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn export_c(&self, ctx: &CContext) -> Option<CTerm> {
        Some(CTerm {
            state: "bias_real m;".into(),
            offset: "$S.m".into(),
            update: format!("if (measured) $S.m += {} * resid;", ctx.real(self.alpha)),
            ..CTerm::default()
        })
    }
}

#[derive(Debug, Clone)]
struct DriftState {
    alpha: f64,
    m: f64,
}

impl TermState for DriftState {
    fn basis(&self, _seek: &Seek<'_>, _out: &mut [f64]) {}
    fn offset(&self, _seek: &Seek<'_>) -> f64 {
        self.m
    }
    fn update(&mut self, _seek: &Seek<'_>, residual: Option<f64>) {
        if let Some(e) = residual {
            self.m += self.alpha * e;
        }
    }
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(self.clone())
    }
}

/// Parses `drift[:ALPHA]` (forgetting factor in (0, 1]); the registry's parser.
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    let alpha = match t.arg {
        None => None,
        Some(a) => match a.parse::<f64>() {
            Ok(v) if v > 0.0 && v <= 1.0 => Some(v),
            _ => {
                return Err(t.bad(format!(
                    "the forgetting factor must be in (0, 1], got `{a}`"
                )));
            }
        },
    };
    Ok(Arc::new(DriftSpec { alpha }))
}

/// The patterns `drift` answers: a residual that moves with time or the seek count.
pub(crate) fn answers(cue: Cue) -> Option<Answer> {
    use crate::history::Feature::{ElapsedS, SeekIndex};
    match cue {
        Cue::Feature(ElapsedS | SeekIndex, _) => Answer::fixed(0),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::rng::SimRng;

    /// Reference: [`forgetting_sse`], one factor at a time in the obvious loop. The 16-lane
    /// pass (AVX2 where the CPU has it, and the portable copy) gives each factor's SSE bit for
    /// bit, on residuals with a drift, outliers and a run of zeros, for factors from 1e-4 to 1.
    #[test]
    fn many_lane_sse_equals_one_factor_at_a_time_bit_for_bit() {
        let mut rng = SimRng::new(17);
        for case in 0..6 {
            let n = [0, 1, 7, 1000, 40_000, 3][case];
            let e: Vec<f64> = (0..n)
                .map(|i| {
                    let drift = 5.0 * (i as f64 * 1e-3).sin();
                    match i % 97 {
                        0 => 1e3 * rng.normal(),
                        1..=5 => 0.0,
                        _ => drift + 2.0 * rng.normal(),
                    }
                })
                .collect();
            let ts: [f64; LANES] = std::array::from_fn(|i| {
                (1e-4f64).ln() * (1.0 - i as f64 / (LANES - 1) as f64) + rng.range(-1e-3, 0.0)
            });
            let alphas = ts.map(f64::exp);
            let want = alphas.map(|a| forgetting_sse(&e, a).to_bits());
            assert_eq!(
                forgetting_sse_many(&e, &alphas).map(f64::to_bits),
                want,
                "case {case}"
            );
            assert_eq!(
                forgetting_sse_many_portable(&e, &alphas).map(f64::to_bits),
                want,
                "case {case}"
            );
        }
    }
}
