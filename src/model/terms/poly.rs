//! `poly2`: the position curve of eq. 2, `c0 + c1·x + c2·x²` (x = target track, counts).
//!
//! Internally the basis is `1, u, u²` with `u = (x − centre)/scale` (centre = mean measured
//! position, scale = half the position range), so the least-squares problem is well conditioned
//! on raw track numbers; the reported `c0, c1, c2` are converted back to tracks, with standard
//! errors carried through the exact linear map.

use crate::codegen::{CContext, CTerm};
use crate::model::ModelError;
use crate::model::data::{FitData, FitError};
use crate::model::term::{Param, Seek, Term, TermCaps, TermSpec, TermState, se_from_cov};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The head of the term's spec text (`poly2`).
pub(crate) const HEAD: &str = "poly2";

/// Spec of the `poly2` term.
#[derive(Debug, Clone, Copy)]
pub struct Poly2Spec;

impl TermSpec for Poly2Spec {
    fn name(&self) -> String {
        HEAD.into()
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let (centre, half) = centre_and_half_range(data.log());
        let scale = if half > 0.0 { half } else { 1.0 };
        Ok(Arc::new(Poly2Term { centre, scale }))
    }
}

/// The mean of the measured rows' positions and half their finite range (0 without any):
/// `stats::mean` and `stats::range` of `Log::measured_positions`, the same folds over the
/// same values in the same order (so the same bits; tested), read from the log's columns in
/// place instead of from a copy (8 B/row at the fit's busiest moment, the terms' parallel
/// preparation).
fn centre_and_half_range(log: &crate::log::Log) -> (f64, f64) {
    // One pass doing the three folds side by side: the count, the sum (from the start of
    // every `Iterator::sum` of f64, in row order) and the range of the finite values.
    let zero = crate::numeric::stats::sum_start();
    let (mut n, mut sum) = (0usize, zero);
    let mut range: Option<[f64; 2]> = None;
    for (&x, b) in log.tracks().iter().zip(log.bias_raw()) {
        if b.is_nan() {
            continue;
        }
        n += 1;
        sum += x;
        if x.is_finite() {
            range = Some(match range {
                None => [x, x],
                Some([lo, hi]) => [lo.min(x), hi.max(x)],
            });
        }
    }
    let centre = if n == 0 { 0.0 } else { sum / n as f64 };
    (centre, range.map_or(0.0, |[lo, hi]| 0.5 * (hi - lo)))
}

/// The fitted `poly2` term.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct Poly2Term {
    /// Centre of the scaled position, tracks.
    pub centre: f64,
    /// Scale of the scaled position, tracks (> 0; a model file with another is refused).
    #[serde(deserialize_with = "super::common::positive_finite")]
    pub scale: f64,
}

impl Term for Poly2Term {
    fn caps(&self) -> TermCaps {
        TermCaps {
            // Its state reads `target` / `seek_length` only.
            reads_history: false,
            provides_intercept: true,
            ..TermCaps::DEFAULT
        }
    }
    fn name(&self) -> String {
        HEAD.into()
    }
    fn param_names(&self) -> Vec<String> {
        vec!["a0".into(), "a1".into(), "a2".into()]
    }
    fn start(&self, _covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        Ok(Box::new(*self))
    }
    fn report(&self, coef: &[f64], cov: &[f64], _nl: Option<f64>) -> Vec<Param> {
        // c(x) = a0 + a1 u + a2 u², u = (x − m)/s  ⇒  c = J a.
        let (m, s) = (self.centre, self.scale);
        let j = [
            [1.0, -m / s, m * m / (s * s)],
            [0.0, 1.0 / s, -2.0 * m / (s * s)],
            [0.0, 0.0, 1.0 / (s * s)],
        ];
        let mut c = [0.0; 3];
        let mut cc = [0.0; 9];
        for r in 0..3 {
            c[r] = (0..3).map(|k| j[r][k] * coef[k]).sum();
            for q in 0..3 {
                cc[r * 3 + q] = (0..3)
                    .flat_map(|a| (0..3).map(move |b| (a, b)))
                    .map(|(a, b)| j[r][a] * cov[a * 3 + b] * j[q][b])
                    .sum();
            }
        }
        ["c0", "c1", "c2"]
            .iter()
            .enumerate()
            .map(|(i, n)| Param {
                name: format!("poly2.{n}"),
                value: c[i],
                se: se_from_cov(&cc, 3, i),
            })
            .collect()
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn export_c(&self, ctx: &CContext) -> Option<CTerm> {
        Some(CTerm {
            basis: format!(
                "{{ bias_real u_ = (f->target - {}) / {}; b[0] = 1; b[1] = u_; b[2] = u_ * u_; }}\n",
                ctx.real(self.centre),
                ctx.real(self.scale)
            ),
            ..CTerm::default()
        })
    }
}

impl TermState for Poly2Term {
    fn constant(&self) -> bool {
        true
    }
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        let u = (seek.features.target - self.centre) / self.scale;
        out[0] = 1.0;
        out[1] = u;
        out[2] = u * u;
    }
    fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(*self)
    }
}

/// Parses `poly2` (no argument); the registry's parser.
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    t.no_arg(Arc::new(Poly2Spec))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: `stats::mean` and `stats::range` of the copied measured positions (what
    /// `prepare` computed before). The in-place folds give the same bits on logs with
    /// unmeasured rows, signed zeros, large and tiny positions, one row, and one measured row
    /// after an unmeasured one.
    #[test]
    fn centre_and_range_in_place_equal_those_of_the_copy() {
        use crate::log::{ColumnMap, Log};
        let cases = [
            "0,10,1\n1,-0.0,\n2,0.0,2\n3,7.25,3\n4,1e14,\n5,-3.5,4\n",
            "0,-0.0,1\n",
            "0,5,\n1,6,2\n",
            "0,0.1,1\n1,0.2,1\n2,0.30000000000000004,1\n3,1e-300,1\n",
        ];
        for (k, rows) in cases.iter().enumerate() {
            let text = format!("time_s,track,bias\n{rows}");
            let log = Log::from_reader("p.csv", text.as_bytes(), &ColumnMap::default()).unwrap();
            let x = log.measured_positions();
            let want_centre = crate::numeric::stats::mean(&x).unwrap_or(0.0);
            let want_half =
                crate::numeric::stats::range(&x).map_or(0.0, |[lo, hi]| 0.5 * (hi - lo));
            let (centre, half) = centre_and_half_range(&log);
            assert_eq!(centre.to_bits(), want_centre.to_bits(), "case {k}");
            assert_eq!(half.to_bits(), want_half.to_bits(), "case {k}");
        }
    }
}
