//! `bump[:CENTRE:WIDTH]`: a localized position defect — a narrow Gaussian bump in the bias around one position,
//!
//! `b = A · exp(−½·((x − c)/w)²)`,
//!
//! x the target position (the log's position unit, tracks on a disk drive), `c` the centre and
//! `w` the width (the Gaussian's σ), both in the position unit. `A` (bias unit, counts) is the
//! linear parameter: positive where the bias rises at the defect, negative where it dips. A
//! `table` fits the same defect only with knots a fraction of `w` apart over the whole span;
//! the bump fits it with three parameters.
//!
//! **Centre and width are searched**, not given: both are nonlinear parameters, searched by
//! the term itself ([`Term::search`]) because the least-squares RSS only moves within a few
//! widths of the defect (a grid of a few dozen centres would step over it):
//! 1. a coarse scan on the residual of the rest of the model ([`SearchContext::residual`]):
//!    widths spaced by a factor [`WIDTH_RATIO`], centres half a width apart, each scored by the
//!    RSS reduction a bump alone would bring, `(Σ g·r)²/Σ g²` over the rows within
//!    [`SCAN_WINDOW`] widths (sorted positions, so a candidate costs only its window's rows);
//! 2. the [`CANDIDATES`] best separated candidates rescored by the exact RSS of the whole model
//!    (variable projection: every linear parameter refitted), the best kept;
//! 3. coordinate-wise golden-section refinement of the centre (± one width) and of `ln w`
//!    (× or ÷ 1.5) on that exact RSS, [`REFINE_CYCLES`] times.
//!
//! The intervals come from the training log, never from an absolute unit, so the same log in
//! another position unit gives the same predictions: centres over the measured positions'
//! range; widths from `max(½·median gap between distinct positions, 4·range / measured rows)`
//! (a bump must span more than one position and about eight rows) to `range / 8` (wider is a
//! trend, for `table` or `poly2`). With `bump:CENTRE:WIDTH` (position unit) the search starts
//! there: centres within 4 widths of CENTRE and widths within a factor 3 of WIDTH (clipped to
//! the intervals above; a CENTRE outside the measured positions, or a WIDTH the log cannot
//! resolve, is refused when fitting).
//!
//! Reported: `A` (standard error from the least squares), `centre` and `width` (standard errors
//! from the curvature of the RSS along each, the other parameters at their fitted values).
//! Exportable to C (`export c`).

use crate::codegen::{CContext, CTerm};
use crate::model::ModelError;
use crate::model::SpecError;
use crate::model::data::{FitData, FitError};
use crate::model::term::{
    Nonlinear, Param, SearchContext, Searched, Seek, Term, TermCaps, TermSpec, TermState,
    se_from_cov,
};
use crate::model::term_text::TermText;
use crate::model::terms::common::positive_finite;
use crate::numeric::search::golden_min;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Ratio between neighbouring widths of the coarse scan.
pub const WIDTH_RATIO: f64 = 1.4;
/// Centre step of the coarse scan, in widths.
pub const CENTRE_STEP: f64 = 0.5;
/// Half-window of the coarse scan's score, in widths (the basis is below `exp(−8) = 3.4e-4`
/// beyond it).
pub const SCAN_WINDOW: f64 = 4.0;
/// Separated coarse candidates rescored by the exact RSS.
pub const CANDIDATES: usize = 3;
/// Coordinate-wise refinement cycles (centre, then width).
pub const REFINE_CYCLES: usize = 2;
/// Grid points and golden-section steps of each refinement. Few on purpose: the last step
/// still compares RSS values that differ far beyond rounding, so the search ends at the same
/// place for the same log in any position unit.
const REFINE_GRID: usize = 5;
/// See [`REFINE_GRID`].
const REFINE_STEPS: usize = 20;
/// Half-width of the centre refinement, in widths.
const CENTRE_BRACKET: f64 = 1.0;
/// Factor of the width refinement (the bracket is `w / 1.5 … 1.5·w`).
const WIDTH_BRACKET: f64 = 1.5;
/// With a starting point: centres searched within this many widths of it.
const START_CENTRE_SPAN: f64 = 4.0;
/// With a starting point: widths searched within this factor of it.
const START_WIDTH_FACTOR: f64 = 3.0;

/// Spec of the `bump` term.
#[derive(Debug, Clone, Copy)]
pub struct BumpSpec {
    /// Starting point `(centre, width)` in the position unit; `None`: searched over the whole
    /// measured range.
    pub start: Option<(f64, f64)>,
}

impl TermSpec for BumpSpec {
    fn name(&self) -> String {
        match self.start {
            // Shortest text that reads back to the same value (any position unit).
            Some((c, w)) => format!("bump:{c}:{w}"),
            None => "bump".into(),
        }
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let name = self.name();
        let bad = |why: String| FitError::BadSetting {
            term: name.clone(),
            why,
        };
        let x = data.measured_values(|s| Some(s.features.target).filter(|v| v.is_finite()));
        let [lo, hi] = crate::numeric::stats::range(&x).unwrap_or([0.0, 0.0]);
        let range = hi - lo;
        if range.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Err(bad(
                "the measured rows never change position, so no position defect can be placed"
                    .into(),
            ));
        }
        let (w_lo, w_hi) = width_limits(&x, range);
        if w_lo.partial_cmp(&w_hi) != Some(std::cmp::Ordering::Less) {
            return Err(bad(format!(
                "{} measured rows over a position range of {range} cannot resolve a bump \
                 narrower than a trend (narrowest {w_lo}, widest {w_hi})",
                x.len()
            )));
        }
        let (mut c_lo, mut c_hi, mut lw_lo, mut lw_hi) = (lo, hi, w_lo.ln(), w_hi.ln());
        let (centre, width) = match self.start {
            None => (0.5 * (lo + hi), (lw_lo + 0.5 * (lw_hi - lw_lo)).exp()),
            Some((c, w)) => {
                if !(lo..=hi).contains(&c) {
                    return Err(bad(format!(
                        "the centre {c} lies outside the measured positions [{lo}, {hi}]"
                    )));
                }
                if !(w >= w_lo && w <= w_hi) {
                    return Err(bad(format!(
                        "the width {w} is outside what this log resolves, [{w_lo}, {w_hi}] \
                         (position unit)"
                    )));
                }
                c_lo = c_lo.max(c - START_CENTRE_SPAN * w);
                c_hi = c_hi.min(c + START_CENTRE_SPAN * w);
                lw_lo = lw_lo.max((w / START_WIDTH_FACTOR).ln());
                lw_hi = lw_hi.min((w * START_WIDTH_FACTOR).ln());
                (c, w)
            }
        };
        Ok(Arc::new(BumpTerm {
            name,
            centre,
            width,
            c_lo,
            c_hi,
            lw_lo,
            lw_hi,
            centre_se: None,
            width_se: None,
        }))
    }
}

/// The narrowest and widest width a log resolves (see the module docs): the narrowest is
/// half the median gap between distinct measured positions or four times the range per
/// measured row, whichever is larger; the widest an eighth of the range.
pub(crate) fn width_limits(x: &[f64], range: f64) -> (f64, f64) {
    let mut s = crate::numeric::stats::sorted(x);
    s.dedup_by(|a, b| a.to_bits() == b.to_bits());
    let mut gaps: Vec<f64> = s.windows(2).map(|w| w[1] - w[0]).collect();
    let gap = crate::numeric::stats::percentile_select(&mut gaps, 50.0).unwrap_or(range);
    let w_lo = (0.5 * gap).max(4.0 * range / x.len().max(1) as f64);
    (w_lo, range / 8.0)
}

/// The fitted `bump` term.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BumpTerm {
    /// Spec string (`bump`, `bump:CENTRE:WIDTH`).
    pub name: String,
    /// Centre `c`, position unit.
    pub centre: f64,
    /// Width `w` (the Gaussian's σ), position unit, > 0.
    #[serde(deserialize_with = "positive_finite")]
    pub width: f64,
    /// Lower end of the centre's search interval, position unit.
    pub c_lo: f64,
    /// Upper end of the centre's search interval, position unit.
    pub c_hi: f64,
    /// Lower end of the `ln w` search interval.
    pub lw_lo: f64,
    /// Upper end of the `ln w` search interval.
    pub lw_hi: f64,
    /// Standard error of the centre (RSS curvature), position unit; `None` before the search.
    #[serde(default)]
    pub centre_se: Option<f64>,
    /// Standard error of the width (RSS curvature, delta method from `ln w`), position unit.
    #[serde(default)]
    pub width_se: Option<f64>,
}

impl BumpTerm {
    /// The same term at centre `c` and width `exp(lw)` (clamped to the search intervals).
    fn at(&self, c: f64, lw: f64) -> BumpTerm {
        BumpTerm {
            centre: c.clamp(self.c_lo, self.c_hi),
            width: lw.clamp(self.lw_lo, self.lw_hi).exp(),
            centre_se: None,
            width_se: None,
            ..self.clone()
        }
    }

    /// The basis value at position `x`.
    #[inline]
    pub fn value(&self, x: f64) -> f64 {
        let z = (x - self.centre) / self.width;
        (-0.5 * z * z).exp()
    }
}

impl Term for BumpTerm {
    fn caps(&self) -> TermCaps {
        TermCaps {
            // Its state reads `target` only.
            reads_history: false,
            // The RSS curve near its minimum stands clear of rounding (a narrow basin; the
            // refinement stops where RSS differences are still far above rounding), and the
            // projection is tested against the full solve (`fit::tests`).
            search_by_projection: true,
            searches_itself: true,
            ..TermCaps::DEFAULT
        }
    }
    fn name(&self) -> String {
        self.name.clone()
    }
    fn param_names(&self) -> Vec<String> {
        vec!["A".into()]
    }
    fn start(&self, _covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        Ok(Box::new(BumpState {
            centre: self.centre,
            width: self.width,
        }))
    }
    /// The centre (so the fit knows there is something to search, and `scale:COL:bump`
    /// searches it); the fit hands the search to [`Term::search`], which searches the width too.
    fn nonlinear(&self) -> Option<Nonlinear> {
        Some(Nonlinear {
            name: "centre".into(),
            value: self.centre,
            lo: self.c_lo,
            hi: self.c_hi,
        })
    }
    fn with_nonlinear(&self, value: f64) -> Option<Arc<dyn Term>> {
        value
            .is_finite()
            .then(|| Arc::new(self.at(value, self.width.ln())) as Arc<dyn Term>)
    }
    fn search(&self, ctx: &SearchContext<'_>) -> Option<Searched> {
        Some(self.search_bump(ctx))
    }
    /// `A` (bias unit), `centre` and `width` (position unit).
    fn report(&self, coef: &[f64], cov: &[f64], _nl_se: Option<f64>) -> Vec<Param> {
        let t = &self.name;
        vec![
            Param {
                name: format!("{t}.A"),
                value: coef[0],
                se: se_from_cov(cov, 1, 0),
            },
            Param {
                name: format!("{t}.centre"),
                value: self.centre,
                se: self.centre_se,
            },
            Param {
                name: format!("{t}.width"),
                value: self.width,
                se: self.width_se,
            },
        ]
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn export_c(&self, ctx: &CContext) -> Option<CTerm> {
        Some(CTerm {
            basis: format!(
                "{{ bias_real z_ = (f->target - {}) / {}; b[0] = exp(-0.5 * z_ * z_); }}\n",
                ctx.real(self.centre),
                ctx.real(self.width)
            ),
            ..CTerm::default()
        })
    }
}

/// One coarse-scan candidate: the RSS reduction a bump alone would bring, centre, `ln w`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ScanHit {
    /// `(Σ g·r)² / Σ g²` (bias unit squared).
    pub score: f64,
    /// Centre, position unit.
    pub centre: f64,
    /// `ln` of the width.
    pub ln_width: f64,
    /// Least-squares amplitude of the bump alone on the residual, `Σ g·r / Σ g²` (bias unit).
    pub amplitude: f64,
}

/// The coarse scan (module docs, step 1): `x` and `r` are positions and residuals of the same
/// rows (non-finite pairs are skipped); centres over `[c_lo, c_hi]` half a width apart, `ln w`
/// over `[lw_lo, lw_hi]` a factor [`WIDTH_RATIO`] apart. Rows at the same position are summed
/// first (a log of integer tracks scans its distinct tracks, not its rows). Returns up to
/// `keep` candidates, best first, each centre more than two widths (the larger) from every
/// better one, and the number of candidates scored.
pub(crate) fn scan(
    x: &[f64],
    r: &[f64],
    (c_lo, c_hi): (f64, f64),
    (lw_lo, lw_hi): (f64, f64),
    keep: usize,
) -> (Vec<ScanHit>, usize) {
    let mut rows: Vec<(f64, f64)> = x
        .iter()
        .zip(r)
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .map(|(&a, &b)| (a, b))
        .collect();
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    // (position, Σ r, rows) per distinct position.
    let mut groups: Vec<(f64, f64, f64)> = Vec::new();
    for (xi, ri) in rows {
        match groups.last_mut() {
            Some(g) if g.0.to_bits() == xi.to_bits() => {
                g.1 += ri;
                g.2 += 1.0;
            }
            _ => groups.push((xi, ri, 1.0)),
        }
    }
    let widths = if lw_hi > lw_lo {
        ((lw_hi - lw_lo) / WIDTH_RATIO.ln()).ceil() as usize + 1
    } else {
        1
    };
    let mut hits: Vec<ScanHit> = Vec::new();
    let mut tried = 0;
    for j in 0..widths {
        let lw = if widths == 1 {
            lw_lo
        } else {
            lw_lo + (lw_hi - lw_lo) * j as f64 / (widths - 1) as f64
        };
        let w = lw.exp();
        let steps = ((c_hi - c_lo) / (CENTRE_STEP * w)).ceil().max(1.0) as usize;
        for i in 0..=steps {
            let c = c_lo + (c_hi - c_lo) * i as f64 / steps as f64;
            let a = groups.partition_point(|p| p.0 < c - SCAN_WINDOW * w);
            let b = groups.partition_point(|p| p.0 <= c + SCAN_WINDOW * w);
            let (mut gr, mut gg) = (0.0, 0.0);
            for &(xi, ri, ni) in &groups[a..b] {
                let z = (xi - c) / w;
                let g = (-0.5 * z * z).exp();
                gr += g * ri;
                gg += g * g * ni;
            }
            tried += 1;
            if gg > 0.0 {
                hits.push(ScanHit {
                    score: gr * gr / gg,
                    centre: c,
                    ln_width: lw,
                    amplitude: gr / gg,
                });
            }
        }
    }
    hits.sort_by(|a, b| b.score.total_cmp(&a.score));
    let mut out: Vec<ScanHit> = Vec::new();
    for h in hits {
        if out.len() >= keep {
            break;
        }
        let apart =
            |o: &ScanHit| (h.centre - o.centre).abs() > 2.0 * h.ln_width.max(o.ln_width).exp();
        if out.iter().all(apart) {
            out.push(h);
        }
    }
    (out, tried)
}

impl BumpTerm {
    /// The search of the module docs.
    fn search_bump(&self, ctx: &SearchContext<'_>) -> Searched {
        let data = ctx.data();
        let x: Vec<f64> = data
            .measured_map(|s| Some(s.features.target))
            .into_iter()
            .map(|v| v.unwrap_or(f64::NAN))
            .collect();
        let r = ctx.residual();
        let rss = |t: &BumpTerm| ctx.rss(&(Arc::new(t.clone()) as Arc<dyn Term>));
        let mut evaluations = 0;
        let (hits, _) = scan(
            &x,
            r,
            (self.c_lo, self.c_hi),
            (self.lw_lo, self.lw_hi),
            CANDIDATES,
        );
        // The exact RSS at the current setting and at each coarse candidate; the best starts
        // the refinement.
        let mut best = (self.centre, self.width.ln());
        let mut best_rss = rss(self);
        evaluations += 1;
        for h in &hits {
            let f = rss(&self.at(h.centre, h.ln_width));
            evaluations += 1;
            if f < best_rss {
                best_rss = f;
                best = (h.centre, h.ln_width);
            }
        }
        let (mut c, mut lw) = best;
        for _ in 0..REFINE_CYCLES {
            let w = lw.exp();
            let (a, b) = (
                (c - CENTRE_BRACKET * w).max(self.c_lo),
                (c + CENTRE_BRACKET * w).min(self.c_hi),
            );
            if b > a {
                let f = |t: f64| rss(&self.at(t, lw));
                let (t, _, ev) = golden_min(&f, a, b, REFINE_GRID, REFINE_STEPS);
                evaluations += ev;
                c = t;
            }
            let (a, b) = (
                (lw - WIDTH_BRACKET.ln()).max(self.lw_lo),
                (lw + WIDTH_BRACKET.ln()).min(self.lw_hi),
            );
            if b > a {
                let f = |t: f64| rss(&self.at(c, t));
                let (t, _, ev) = golden_min(&f, a, b, REFINE_GRID, REFINE_STEPS);
                evaluations += ev;
                lw = t;
            }
        }
        let mut found = self.at(c, lw);
        // Standard errors from the curvature along each parameter: var ≈ 2·s²/RSS''.
        let f0 = rss(&found);
        let s2 = f0 / ctx.dof().max(1) as f64;
        let curvature_se = |f: &dyn Fn(f64) -> f64, t: f64, h: f64| {
            let curv = (f(t + h) - 2.0 * f0 + f(t - h)) / (h * h);
            (curv > 0.0 && f0.is_finite())
                .then(|| (2.0 * s2 / curv).sqrt())
                .filter(|v| v.is_finite())
        };
        let h_c = 1e-2 * found.width;
        found.centre_se = curvature_se(&|t| rss(&self.at(t, lw)), c, h_c);
        found.width_se = curvature_se(&|t| rss(&self.at(c, t)), lw, 1e-2).map(|s| s * found.width);
        evaluations += 5;
        let inside = |v: f64, lo: f64, hi: f64| {
            let m = 1e-3 * (hi - lo);
            hi <= lo || (v > lo + m && v < hi - m)
        };
        Searched {
            converged: inside(c, self.c_lo, self.c_hi) && inside(lw, self.lw_lo, self.lw_hi),
            term: Arc::new(found),
            evaluations,
        }
    }
}

/// The state of a [`BumpTerm`] while a log is replayed (none: the basis depends on the
/// target only).
#[derive(Debug, Clone, Copy)]
struct BumpState {
    centre: f64,
    width: f64,
}

impl TermState for BumpState {
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        let z = (seek.features.target - self.centre) / self.width;
        out[0] = (-0.5 * z * z).exp();
    }
    fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(*self)
    }
}

/// Parses `bump` or `bump:CENTRE:WIDTH` (position unit; WIDTH > 0); the registry's parser.
pub(crate) fn parse(t: &TermText<'_>) -> Result<Arc<dyn TermSpec>, SpecError> {
    let Some(arg) = t.arg else {
        return Ok(Arc::new(BumpSpec { start: None }));
    };
    let usage = "`bump` takes no argument or a starting centre and width in the log's position \
                 unit: `bump:CENTRE:WIDTH` (e.g. `bump:2412:1.5`), WIDTH > 0";
    let Some((c, w)) = arg.split_once(':') else {
        return Err(t.bad(format!("{usage}; got `{arg}`")));
    };
    match (c.parse::<f64>(), w.parse::<f64>()) {
        (Ok(c), Ok(w)) if c.is_finite() && w.is_finite() && w > 0.0 => Ok(Arc::new(BumpSpec {
            start: Some((c, w)),
        })),
        _ => Err(t.bad(format!("{usage}; got `{arg}`"))),
    }
}

/// The head of the term's spec text, for the diagnosis that suggests it.
pub(crate) const HEAD: &str = "bump";

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{FitOptions, fit};
    use crate::log::{ColumnMap, Log};
    use crate::model::{FittedModel, ModelSpec};
    use crate::numeric::rng::SimRng;

    /// `n` seeks over integer tracks 0..=400 (random moves of mixed length), bias = a linear
    /// trend + `amp·exp(−½((x − 150)/2)²)` + N(0, 1) noise; positions × `xs`.
    fn log_text(seed: u64, n: usize, amp: f64, xs: f64) -> String {
        let mut rng = SimRng::new(seed);
        let mut text = String::from("time_s,track,bias\n");
        let mut x = 200.0f64;
        for k in 0..n {
            let step = if rng.uniform() < 0.5 { 15.0 } else { 200.0 };
            x = (x + (rng.uniform() - 0.5) * 2.0 * step)
                .round()
                .clamp(0.0, 400.0);
            let bias =
                3.0 + 0.01 * x + amp * (-0.5 * ((x - 150.0) / 2.0).powi(2)).exp() + rng.normal();
            text += &format!("{:?},{:?},{bias:?}\n", 0.1 * k as f64, x * xs);
        }
        text
    }

    fn log(seed: u64, n: usize, amp: f64, xs: f64) -> Log {
        let text = log_text(seed, n, amp, xs);
        Log::from_reader("bump.csv", text.as_bytes(), &ColumnMap::default()).unwrap()
    }

    fn fit_text(spec: &str, log: &Log) -> FittedModel {
        let opts = FitOptions::default().check().unwrap();
        fit(&ModelSpec::parse(spec).unwrap(), log, &opts).unwrap()
    }

    #[test]
    fn parses_its_syntax_and_refuses_bad_arguments() {
        // The name is the shortest text of each value, so it reads back to itself.
        for (ok, name) in [
            ("bump", "bump"),
            ("bump:150:2", "bump:150:2"),
            ("bump:-3.5:1e-6", "bump:-3.5:0.000001"),
        ] {
            let t = crate::model::terms::parse_term(ok).unwrap();
            assert_eq!(t.name(), name);
            assert_eq!(crate::model::terms::parse_term(name).unwrap().name(), name);
        }
        for bad in [
            "bump:150",
            "bump:x:2",
            "bump:150:0",
            "bump:150:-1",
            "bump:nan:1",
            "bump:1:inf",
        ] {
            let e = crate::model::terms::parse_term(bad)
                .unwrap_err()
                .to_string();
            assert!(e.contains("bump:CENTRE:WIDTH"), "{bad}: {e}");
        }
    }

    /// Reference: the truth of [`log_text`] (centre 150, width 2, amplitude 6) on 4000 seeks:
    /// `poly2,bump` from no starting point, and from a start 5 tracks and a factor 1.6 off.
    #[test]
    fn recovers_centre_width_and_amplitude() {
        let l = log(5, 4000, 6.0, 1.0);
        for spec in ["poly2,bump", "poly2,bump:155:3.2"] {
            let m = fit_text(spec, &l);
            let name = spec.split(',').nth(1).unwrap();
            let p = |n: &str| m.param(&format!("{name}.{n}")).unwrap().clone();
            let (a, c, w) = (p("A"), p("centre"), p("width"));
            assert!((c.value - 150.0).abs() < 0.25, "{spec}: {c:?}");
            assert!((w.value - 2.0).abs() < 0.2 * 2.0, "{spec}: {w:?}");
            assert!((a.value - 6.0).abs() < 2.5 * a.se.unwrap(), "{spec}: {a:?}");
            // The curvature standard errors are there and of a plausible size.
            assert!(c.se.unwrap() > 0.0 && c.se.unwrap() < 0.3, "{spec}: {c:?}");
            assert!(w.se.unwrap() > 0.0 && w.se.unwrap() < 0.4, "{spec}: {w:?}");
            assert!(m.fit.converged, "{spec}: {:?}", m.warnings);
        }
    }

    /// A start the log cannot use is refused when fitting, naming the term.
    #[test]
    fn refuses_a_start_outside_the_log() {
        let l = log(5, 800, 6.0, 1.0);
        let opts = FitOptions::default().check().unwrap();
        for (spec, why) in [
            ("poly2,bump:900:2", "outside the measured positions"),
            ("poly2,bump:150:0.01", "outside what this log resolves"),
            ("poly2,bump:150:300", "outside what this log resolves"),
        ] {
            let e = fit(&ModelSpec::parse(spec).unwrap(), &l, &opts)
                .unwrap_err()
                .to_string();
            assert!(e.contains("bump:") && e.contains(why), "{spec}: {e}");
        }
    }

    /// Reference: the windowed sums written out directly — every row's distance tested, no
    /// grouping, sorting or binary search. The scan's scores must be the same up to rounding,
    /// and its best candidates the largest of those scores, separated.
    #[test]
    fn scan_equals_the_direct_windowed_sums() {
        let mut rng = SimRng::new(3);
        let x: Vec<f64> = (0..700).map(|_| (rng.uniform() * 300.0).round()).collect();
        let r: Vec<f64> = x
            .iter()
            .map(|&v| 4.0 * (-0.5 * ((v - 77.0) / 3.0f64).powi(2)).exp() + rng.normal())
            .collect();
        let (cr, wr) = ((0.0, 300.0), (0.5f64.ln(), 30.0f64.ln()));
        let (hits, tried) = scan(&x, &r, cr, wr, 3);
        assert_eq!(hits.len(), 3);
        assert!(tried > 600, "{tried}");
        let mut sorted: Vec<(f64, f64)> = x.iter().copied().zip(r.iter().copied()).collect();
        sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
        let direct = |c: f64, lw: f64| {
            let w = lw.exp();
            let (mut gr, mut gg) = (0.0, 0.0);
            for &(xi, ri) in &sorted {
                if xi >= c - SCAN_WINDOW * w && xi <= c + SCAN_WINDOW * w {
                    let z = (xi - c) / w;
                    let g = (-0.5 * z * z).exp();
                    gr += g * ri;
                    gg += g * g;
                }
            }
            gr * gr / gg
        };
        // Rows of one track are summed before the scan: the same sums up to rounding.
        for h in &hits {
            let d = direct(h.centre, h.ln_width);
            assert!((d - h.score).abs() <= 1e-12 * d, "{d} vs {}", h.score);
        }
        // The best is the defect, and nothing in a dense direct grid beats it by much.
        assert!((hits[0].centre - 77.0).abs() < 2.0, "{:?}", hits[0]);
        let mut best = 0.0f64;
        for i in 0..=600 {
            for lw in [0.5f64, 1.0, 2.0, 3.0, 5.0, 8.0] {
                best = best.max(direct(i as f64 * 0.5, lw.ln()));
            }
        }
        assert!(hits[0].score >= 0.9 * best, "{} vs {best}", hits[0].score);
    }

    /// Unit invariance (the module docs): the same log with positions × 1e-6 … 1e6 gives the
    /// same predictions (to 1e-9 of the bias spread) and the same centre and width in the new
    /// unit, with and without a starting point (scaled with the positions).
    #[test]
    fn predictions_do_not_depend_on_the_position_unit() {
        let (train, test) = (log(8, 1500, 5.0, 1.0), log(9, 500, 5.0, 1.0));
        for (spec, start) in [("bump", None), ("bump:152:3", Some((152.0, 3.0)))] {
            let m0 = fit_text(&format!("poly2,{spec}"), &train);
            let p0 = m0.predict_log(&test).unwrap();
            let spread = p0.measured.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let c0 = m0
                .params()
                .find(|p| p.name.ends_with(".centre"))
                .unwrap()
                .value;
            for xs in [1e-6, 1e-3, 0.37, 1e3, 1e6] {
                let term = match start {
                    None => "bump".to_string(),
                    Some((c, w)) => format!("bump:{}:{}", c * xs, w * xs),
                };
                let m = fit_text(&format!("poly2,{term}"), &log(8, 1500, 5.0, xs));
                let p = m.predict_log(&log(9, 500, 5.0, xs)).unwrap();
                for (a, b) in p0.predicted.iter().zip(&p.predicted) {
                    assert!((a - b).abs() <= 1e-9 * spread, "{term} ×{xs}: {a} vs {b}");
                }
                let c = m
                    .params()
                    .find(|p| p.name.ends_with(".centre"))
                    .unwrap()
                    .value;
                assert!(
                    (c / xs - c0).abs() <= 1e-9 * c0,
                    "{term} ×{xs}: {c} vs {c0}"
                );
            }
        }
    }

    /// The model file round trip: settings, coefficients, parameters and predictions come back
    /// bit for bit; a width ≤ 0 or a misspelt setting is refused at load.
    #[test]
    fn round_trips_bit_for_bit_and_refuses_bad_settings() {
        let l = log(5, 1500, 6.0, 1.0);
        let m = fit_text("poly2,bump", &l);
        let json = m.to_json().unwrap();
        let back =
            FittedModel::from_json(&json, std::path::Path::new("m.json"), &|_, _| None).unwrap();
        assert_eq!(back.to_json().unwrap(), json);
        let (a, b) = (m.predict_log(&l).unwrap(), back.predict_log(&l).unwrap());
        assert!(
            a.predicted
                .iter()
                .zip(&b.predicted)
                .all(|(x, y)| x.to_bits() == y.to_bits())
        );
        let t = m.terms.iter().find(|t| t.term.name() == "bump").unwrap();
        let settings = t.term.settings();
        let again = crate::model::terms::restore_term("bump", &settings).unwrap();
        assert_eq!(again.settings(), settings);
        for (key, value) in [
            ("width", serde_json::json!(0.0)),
            ("widht", serde_json::json!(1.0)),
        ] {
            let mut s = settings.clone();
            s[key] = value;
            assert!(
                crate::model::terms::restore_term("bump", &s).is_err(),
                "{key}"
            );
        }
    }
}
