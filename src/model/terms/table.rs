//! `table[:SPACING]`: a lookup table over position with linear interpolation between knots
//! `spacing` tracks apart (default: a tenth of the measured range), constant beyond the end
//! knots. Its values (counts) are the parameters; the hat basis sums to 1, so it spans the
//! intercept.

use crate::codegen::{CContext, CTerm, zero};
use crate::model::ModelError;
use crate::model::cue::{Answer, Cue};
use crate::model::data::{FitData, FitError};
use crate::model::term::{Seek, Term, TermCaps, TermSpec, TermState};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The head of the term's spec text (`table`).
pub(crate) const HEAD: &str = "table";

/// The spec text of a table with knot spacing `h` (`table:2.5`, six significant digits at
/// most), as model-structure selection proposes it.
pub(crate) fn spec(h: f64) -> String {
    format!("{HEAD}:{}", crate::log::fmt_trimmed(h, 6))
}

/// Spec of the `table` term.
#[derive(Debug, Clone, Copy)]
pub struct TableSpec {
    /// Knot spacing in tracks; `None` = a tenth of the measured position range.
    pub spacing: Option<f64>,
}

impl TermSpec for TableSpec {
    fn name(&self) -> String {
        match self.spacing {
            Some(h) => format!("table:{}", crate::log::fmt_trimmed(h, 6)),
            None => HEAD.into(),
        }
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let x = data.log().measured_positions();
        let lo = x.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let range = hi - lo;
        let spacing = self
            .spacing
            .unwrap_or(if range > 0.0 { range / 10.0 } else { 1.0 });
        let knots = ((range / spacing).ceil() as usize + 1).max(1);
        if knots > 100_000 {
            return Err(FitError::BadSetting {
                term: self.name(),
                why: format!(
                    "{knots} knots over a position range of {range} (the log's position unit); \
                     use a larger spacing"
                ),
            });
        }
        Ok(Arc::new(TableTerm {
            name: self.name(),
            x0: lo,
            spacing,
            knots,
        }))
    }
}

/// The fitted `table` term.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TableTerm {
    /// Spec string.
    pub name: String,
    /// Position of the first knot, tracks.
    pub x0: f64,
    /// Knot spacing, tracks.
    pub spacing: f64,
    /// Number of knots.
    pub knots: usize,
}

impl Term for TableTerm {
    fn caps(&self) -> TermCaps {
        TermCaps {
            // Its state reads `target` / `seek_length` only.
            reads_history: false,
            provides_intercept: true,
            ..TermCaps::DEFAULT
        }
    }
    fn name(&self) -> String {
        self.name.clone()
    }
    fn param_names(&self) -> Vec<String> {
        (0..self.knots)
            .map(|i| {
                format!(
                    "x={}",
                    crate::log::fmt_trimmed(self.x0 + self.spacing * i as f64, 3)
                )
            })
            .collect()
    }
    fn start(&self, _covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        Ok(Box::new(self.clone()))
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn export_c(&self, ctx: &CContext) -> Option<CTerm> {
        let mut t = CTerm::default();
        if self.knots == 1 {
            t.basis = "b[0] = 1;\n".into();
        } else {
            let top = (self.knots - 1) as f64;
            t.basis = zero(self.knots);
            t.basis += &format!(
                "{{ bias_real u_ = (f->target - {x0}) / {h}; int i_; bias_real fr_;\n  u_ = u_ < 0 ? 0 : (u_ > {top} ? {top} : u_);\n  i_ = (int)floor(u_); if (i_ > {last}) i_ = {last};\n  fr_ = u_ - (bias_real)i_; b[i_] = 1 - fr_; b[i_ + 1] = fr_; }}\n",
                x0 = ctx.real(self.x0),
                h = ctx.real(self.spacing),
                top = ctx.real(top),
                last = self.knots - 2
            );
        }
        Some(t)
    }
}

impl TermState for TableTerm {
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        out.fill(0.0);
        if self.knots == 1 {
            out[0] = 1.0;
            return;
        }
        let u =
            ((seek.features.target - self.x0) / self.spacing).clamp(0.0, (self.knots - 1) as f64);
        let i = (u.floor() as usize).min(self.knots - 2);
        let frac = u - i as f64;
        out[i] = 1.0 - frac;
        out[i + 1] = frac;
    }
    fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(self.clone())
    }
}

/// Parses `table[:SPACING]` (knot spacing in the log's position unit); the registry's parser.
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    let spacing = match t.arg {
        None => None,
        Some(a) => match a.parse::<f64>() {
            Ok(h) if h.is_finite() && h > 0.0 => Some(h),
            _ => {
                return Err(t.bad(format!(
                    "knot spacing must be a positive number (in the log's position unit), got `{a}`"
                )));
            }
        },
    };
    Ok(Arc::new(TableSpec { spacing }))
}

/// The pattern `table` answers: an even curve in position.
pub(crate) fn answers(cue: Cue) -> Option<Answer> {
    match cue {
        Cue::Feature(crate::history::Feature::Position, false) => Answer::fixed(0),
        _ => None,
    }
}
