//! `step:COL[:T]`: a threshold in a covariate column — the bias
//! changes by a fitted height where the column exceeds a fitted threshold,
//!
//! `b = A · [v > T]`,
//!
//! v the column's value on the row (the column's unit), `T` the threshold in the same unit and
//! `A` (bias unit, counts) the linear parameter: positive where the bias steps up above `T`,
//! negative where it steps down. The level below `T` is the model's intercept. A `bins:COL`
//! term follows the same step only with hinges packed around `T` (sixteen knots spread over
//! the whole column to place a few near it); the step fits it with two parameters.
//!
//! **Why a sharp edge and not a smooth one** (a logistic edge with a fitted width): the
//! physical thresholds this term is for switch sharply compared with the spread of the logged
//! column — a load beyond which a preload spring or a second contact engages, a fan or a
//! servo mode that changes speed at a set point, stiction letting go at a breakaway force.
//! Where the edge is spread over a good part of the column's range (saturation, a gradual
//! engagement) the bias is a smooth curve in the column, which `bins:COL`'s hinges already
//! follow with a few knots; a width parameter adds a search whose RSS is flat wherever the
//! width is below the spacing of the logged values (it then ends at its bound, a warning with
//! no meaning). So the one term is the sharp edge, and diagnose verifies it beside `bins:COL`
//! by refit: the out-of-sample error decides which shape the log has. A controller switching
//! with hysteresis (on at one value, off at another) depends on the column's history, not its
//! value: neither term is that.
//!
//! **The threshold is searched** by the term itself ([`Term::search`]), because the least-
//! squares RSS is piecewise constant in `T` (it only changes when `T` crosses a logged value),
//! so a golden-section search on it has nothing to follow:
//! 1. a scan of every split between two neighbouring distinct values of the column, on the
//!    residual of the rest of the model ([`SearchContext::residual`]): each scored by the RSS
//!    reduction the step alone (beside a constant) would bring, `(S₁ − n₁·S/n)² / (n₁·(1 − n₁/n))`
//!    with `S₁`, `n₁` the residual's sum and rows above the split (one pass over the sorted
//!    values: the cost of a sort);
//! 2. the [`CANDIDATES`] best splits at least [`SEPARATION`] of the rows apart rescored by the
//!    exact RSS of the whole model (variable projection: every linear parameter refitted);
//! 3. around the best of those, the [`NEIGHBOURS`] best-scanned splits within [`SEPARATION`]
//!    of the rows rescored the same way; the exact best is kept.
//!
//! `T` is the midpoint of the two neighbouring values of its split, so the same log in another
//! unit of the column (any positive factor) gives the same split, the same predictions and `T`
//! in the new unit. Each side must hold at least [`MIN_SIDE_ROWS`] measured rows and
//! [`MIN_SIDE_FRACTION`] of them (a step on a handful of rows is an outlier, not a threshold).
//! With `step:COL:T` (the column's unit) the search is restricted to thresholds within an
//! eighth of the column's measured range of `T`; a `T` that leaves too few rows on one side is
//! refused when fitting.
//!
//! Reported: `A` (standard error from the least squares) and `threshold` (column unit), whose
//! standard error is half the width of the thresholds whose scanned RSS lies within `s²` of the
//! minimum (`s² = RSS/dof`: the Δχ² = 1 profile interval, from the scan, extended to the
//! neighbouring logged values; it assumes independent errors, so serially correlated noise
//! makes it too narrow). Exportable to C (`export c`); in single precision a logged value
//! within float rounding of `T` may fall on the other side.

use super::common::covariate_position;
use crate::codegen::{CContext, CTerm};
use crate::model::data::{FitData, FitError};
use crate::model::term::{
    Nonlinear, Param, SearchContext, Searched, Seek, Term, TermCaps, TermSpec, TermState,
    se_from_cov,
};
use crate::model::term_text::TermText;
use crate::model::{ModelError, SpecError};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Fewest measured rows on either side of the threshold.
pub const MIN_SIDE_ROWS: usize = 10;
/// Smallest fraction of the measured rows on either side of the threshold.
pub const MIN_SIDE_FRACTION: f64 = 0.02;
/// Separated scan candidates rescored by the exact RSS.
pub const CANDIDATES: usize = 3;
/// Scan candidates must be at least this fraction of the measured rows apart (in rank), and
/// the refinement looks this far either side of the best.
pub const SEPARATION: f64 = 0.05;
/// Best-scanned splits near the best candidate rescored by the exact RSS.
pub const NEIGHBOURS: usize = 6;
/// With a starting threshold: thresholds searched within this fraction of the measured range.
const START_SPAN: f64 = 0.125;

/// Spec of the `step` term.
#[derive(Debug, Clone)]
pub struct StepSpec {
    /// The covariate column.
    pub column: String,
    /// Starting threshold in the column's unit; `None`: searched over every split.
    pub start: Option<f64>,
}

impl TermSpec for StepSpec {
    fn name(&self) -> String {
        match self.start {
            // Shortest text that reads back to the same value.
            Some(t) => format!("step:{}:{t}", self.column),
            None => format!("step:{}", self.column),
        }
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let name = self.name();
        let bad = |why: String| FitError::BadSetting {
            term: name.clone(),
            why,
        };
        let idx = data.covariate(&self.column, &name)?;
        let v: Vec<f64> = data
            .measured_positional(|s| Some(s.covariates[idx]))
            .into_iter()
            .filter(|x| x.is_finite())
            .collect();
        let splits = Splits::of(&v);
        let m = min_side(v.len());
        let Some((t_lo, t_hi)) = splits.allowed(m) else {
            return Err(bad(format!(
                "the column `{}` cannot place a step with at least {m} of its {} measured rows \
                 on each side (too few rows or distinct values)",
                self.column,
                v.len()
            )));
        };
        let (mut lo, mut hi) = (t_lo, t_hi);
        let threshold = match self.start {
            None => 0.5 * (t_lo + t_hi),
            Some(t) => {
                if !(t_lo..=t_hi).contains(&t) {
                    return Err(bad(format!(
                        "the threshold {t} leaves fewer than {m} measured rows on one side \
                         (thresholds this log allows: [{t_lo}, {t_hi}], the column's unit)"
                    )));
                }
                let span = START_SPAN * (splits.hi - splits.lo);
                lo = lo.max(t - span);
                hi = hi.min(t + span);
                t
            }
        };
        Ok(Arc::new(StepTerm {
            name,
            column: self.column.clone(),
            threshold,
            t_lo: lo,
            t_hi: hi,
            threshold_se: None,
        }))
    }
}

/// Fewest rows on either side of a step among `n` measured rows.
pub(crate) fn min_side(n: usize) -> usize {
    MIN_SIDE_ROWS.max((MIN_SIDE_FRACTION * n as f64).ceil() as usize)
}

/// The distinct values of a column, sorted, with the rows at each.
#[derive(Debug, Clone, Default)]
struct Splits {
    /// `(value, rows)`, increasing.
    groups: Vec<(f64, usize)>,
    /// Smallest value (0 when empty).
    lo: f64,
    /// Largest value (0 when empty).
    hi: f64,
}

impl Splits {
    fn of(v: &[f64]) -> Splits {
        let s = crate::numeric::stats::sorted(v);
        let mut groups: Vec<(f64, usize)> = Vec::new();
        for x in s {
            match groups.last_mut() {
                Some(g) if g.0.to_bits() == x.to_bits() => g.1 += 1,
                _ => groups.push((x, 1)),
            }
        }
        let lo = groups.first().map_or(0.0, |g| g.0);
        let hi = groups.last().map_or(0.0, |g| g.0);
        Splits { groups, lo, hi }
    }

    /// The lowest and highest threshold (midpoints between neighbouring values) with at least
    /// `m` rows on each side.
    fn allowed(&self, m: usize) -> Option<(f64, f64)> {
        let n: usize = self.groups.iter().map(|g| g.1).sum();
        let mut below = 0;
        let mut first = None;
        let mut last = None;
        for w in self.groups.windows(2) {
            below += w[0].1;
            if below >= m && n - below >= m {
                let t = midpoint(w[0].0, w[1].0);
                first.get_or_insert(t);
                last = Some(t);
            }
        }
        Some((first?, last?))
    }
}

/// The threshold between neighbouring values `a < b`.
#[inline]
fn midpoint(a: f64, b: f64) -> f64 {
    a + 0.5 * (b - a)
}

/// One split of the scan: the threshold, its RSS reduction and its rank.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct StepHit {
    /// `(S₁ − n₁·S/n)² / (n₁·(1 − n₁/n))` (bias unit squared): the RSS reduction of the step
    /// beside a constant on the scanned residual.
    pub score: f64,
    /// Threshold (column unit): the midpoint between the split's two values.
    pub threshold: f64,
    /// Rows at or below the threshold.
    pub below: usize,
}

/// The scan of the module docs, step 1: `v` and `r` are the column and the residual of the
/// same rows (non-finite pairs skipped). Every split between neighbouring distinct values
/// whose threshold lies in `[t_lo, t_hi]` and leaves at least `min_side` rows on each side is
/// scored. Returns the scored splits in increasing threshold order.
pub(crate) fn scan(
    v: &[f64],
    r: &[f64],
    (t_lo, t_hi): (f64, f64),
    min_side: usize,
) -> Vec<StepHit> {
    let mut rows: Vec<(f64, f64)> = v
        .iter()
        .zip(r)
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .map(|(&a, &b)| (a, b))
        .collect();
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    // (value, Σ r, rows) per distinct value.
    let mut groups: Vec<(f64, f64, usize)> = Vec::new();
    for (x, y) in rows {
        match groups.last_mut() {
            Some(g) if g.0.to_bits() == x.to_bits() => {
                g.1 += y;
                g.2 += 1;
            }
            _ => groups.push((x, y, 1)),
        }
    }
    let n: usize = groups.iter().map(|g| g.2).sum();
    let total: f64 = groups.iter().map(|g| g.1).sum();
    let nf = n as f64;
    let mut out = Vec::new();
    let (mut below_sum, mut below) = (0.0, 0usize);
    for w in groups.windows(2) {
        below_sum += w[0].1;
        below += w[0].2;
        let above = n - below;
        let t = midpoint(w[0].0, w[1].0);
        if below < min_side || above < min_side || t < t_lo || t > t_hi {
            continue;
        }
        let n1 = above as f64;
        let s1 = total - below_sum;
        // Centred: the step beside a constant (the model's intercept).
        let c = s1 - n1 * total / nf;
        let gg = n1 * (1.0 - n1 / nf);
        if gg > 0.0 {
            out.push(StepHit {
                score: c * c / gg,
                threshold: t,
                below,
            });
        }
    }
    out
}

/// The indices of up to `keep` hits with the largest scores, best first, each at least `apart`
/// rows (in rank) from every better one.
fn best_separated(hits: &[StepHit], keep: usize, apart: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..hits.len()).collect();
    order.sort_by(|&a, &b| hits[b].score.total_cmp(&hits[a].score).then(a.cmp(&b)));
    let mut out: Vec<usize> = Vec::new();
    for i in order {
        if out.len() >= keep {
            break;
        }
        if out
            .iter()
            .all(|&o| hits[i].below.abs_diff(hits[o].below) >= apart)
        {
            out.push(i);
        }
    }
    out
}

/// The fitted `step` term.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StepTerm {
    /// Spec string (`step:COL`, `step:COL:T`).
    pub name: String,
    /// The covariate column.
    pub column: String,
    /// Threshold `T`, column unit: the basis is 1 where the column exceeds it, else 0.
    pub threshold: f64,
    /// Lower end of the threshold's search interval, column unit.
    pub t_lo: f64,
    /// Upper end of the threshold's search interval, column unit.
    pub t_hi: f64,
    /// Standard error of the threshold (the scan's profile interval, see the module docs),
    /// column unit; `None` before the search.
    #[serde(default)]
    pub threshold_se: Option<f64>,
}

impl StepTerm {
    /// The same term at threshold `t` (clamped to the search interval).
    fn at(&self, t: f64) -> StepTerm {
        StepTerm {
            threshold: t.clamp(self.t_lo, self.t_hi),
            threshold_se: None,
            ..self.clone()
        }
    }

    /// The basis value at column value `v`: 1 above the threshold, else 0 (also where `v` is
    /// not a number).
    #[inline]
    pub fn value(&self, v: f64) -> f64 {
        if v > self.threshold { 1.0 } else { 0.0 }
    }
}

impl Term for StepTerm {
    fn caps(&self) -> TermCaps {
        TermCaps {
            // Its state reads a covariate only.
            reads_history: false,
            // The exact RSS of two splits differs by what the rows between them change, far above
            // rounding; the projection is tested against the full solve (`fit::tests`).
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
    fn covariates(&self) -> Vec<String> {
        vec![self.column.clone()]
    }
    fn start(&self, covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        Ok(Box::new(StepState {
            idx: covariate_position(covariates, &self.column, &self.name)?,
            threshold: self.threshold,
        }))
    }
    /// The threshold (so the fit knows there is something to search); the fit hands the
    /// search to [`Term::search`].
    fn nonlinear(&self) -> Option<Nonlinear> {
        Some(Nonlinear {
            name: "threshold".into(),
            value: self.threshold,
            lo: self.t_lo,
            hi: self.t_hi,
        })
    }
    fn with_nonlinear(&self, value: f64) -> Option<Arc<dyn Term>> {
        value
            .is_finite()
            .then(|| Arc::new(self.at(value)) as Arc<dyn Term>)
    }
    fn search(&self, ctx: &SearchContext<'_>) -> Option<Searched> {
        Some(self.search_step(ctx))
    }
    /// `A` (bias unit) and `threshold` (column unit).
    fn report(&self, coef: &[f64], cov: &[f64], _nl_se: Option<f64>) -> Vec<Param> {
        let t = &self.name;
        vec![
            Param {
                name: format!("{t}.A"),
                value: coef[0],
                se: se_from_cov(cov, 1, 0),
            },
            Param {
                name: format!("{t}.threshold"),
                value: self.threshold,
                se: self.threshold_se,
            },
        ]
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn export_c(&self, ctx: &CContext) -> Option<CTerm> {
        Some(CTerm {
            basis: format!("b[0] = $X0 > {} ? 1 : 0;\n", ctx.real(self.threshold)),
            ..CTerm::default()
        })
    }
}

impl StepTerm {
    /// The search of the module docs.
    fn search_step(&self, ctx: &SearchContext<'_>) -> Searched {
        let data = ctx.data();
        let covs = &data.log().schema.covariates;
        let idx = covs.iter().position(|c| *c == self.column);
        let v: Vec<f64> = match idx {
            Some(i) => data.measured_positional(|s| Some(s.covariates[i])),
            None => Vec::new(),
        };
        let r = ctx.residual();
        let n = v.len();
        let hits = scan(&v, r, (self.t_lo, self.t_hi), min_side(n));
        let rss = |t: f64| ctx.rss(&(Arc::new(self.at(t)) as Arc<dyn Term>));
        let apart = ((SEPARATION * n as f64).ceil() as usize).max(1);
        let coarse = best_separated(&hits, CANDIDATES, apart);
        // The exact RSS at each separated candidate (at the current setting only when the
        // scan has none); the best starts the refinement.
        let mut best = (self.threshold, f64::INFINITY);
        let mut evaluations = 0;
        let starts: Vec<f64> = if coarse.is_empty() {
            vec![self.threshold]
        } else {
            coarse.iter().map(|&i| hits[i].threshold).collect()
        };
        for t in starts {
            let f = rss(t);
            evaluations += 1;
            if f < best.1 || evaluations == 1 {
                best = (t, f);
            }
        }
        // Refinement: the best-scanned splits near the exact best.
        if let Some(centre) = hits
            .iter()
            .find(|h| h.threshold.to_bits() == best.0.to_bits())
        {
            let near: Vec<StepHit> = hits
                .iter()
                .copied()
                .filter(|h| h.below.abs_diff(centre.below) < apart)
                .collect();
            let mut order: Vec<usize> = (0..near.len()).collect();
            order.sort_by(|&a, &b| near[b].score.total_cmp(&near[a].score).then(a.cmp(&b)));
            for &j in order.iter().take(NEIGHBOURS) {
                let t = near[j].threshold.to_bits();
                if coarse.iter().any(|&i| hits[i].threshold.to_bits() == t) {
                    continue;
                }
                let f = rss(near[j].threshold);
                evaluations += 1;
                if f < best.1 {
                    best = (near[j].threshold, f);
                }
            }
        }
        let mut found = self.at(best.0);
        found.threshold_se = profile_se(&hits, &v, best.0, best.1 / ctx.dof().max(1) as f64);
        let k = hits
            .iter()
            .position(|h| h.threshold.to_bits() == best.0.to_bits());
        Searched {
            // The best split is not the first or last one the interval allows.
            converged: hits.len() <= 1 || k.is_some_and(|k| k > 0 && k + 1 < hits.len()),
            term: Arc::new(found),
            evaluations,
        }
    }
}

/// Half the width of the Δχ² = 1 profile interval of the threshold from the scan (module
/// docs): the contiguous splits around `t` whose scanned score lies within `s2` of its score,
/// widened to the logged values beyond the outermost of them.
fn profile_se(hits: &[StepHit], v: &[f64], t: f64, s2: f64) -> Option<f64> {
    let k = hits
        .iter()
        .position(|h| h.threshold.to_bits() == t.to_bits())?;
    if !(s2.is_finite() && s2 > 0.0) {
        return None;
    }
    let floor = hits[k].score - s2;
    let mut a = k;
    while a > 0 && hits[a - 1].score >= floor {
        a -= 1;
    }
    let mut b = k;
    while b + 1 < hits.len() && hits[b + 1].score >= floor {
        b += 1;
    }
    let (t_a, t_b) = (hits[a].threshold, hits[b].threshold);
    // The logged values just below t_a and just above t_b.
    let below = v
        .iter()
        .copied()
        .filter(|&x| x < t_a)
        .fold(f64::NEG_INFINITY, f64::max);
    let above = v
        .iter()
        .copied()
        .filter(|&x| x > t_b)
        .fold(f64::INFINITY, f64::min);
    let se = 0.5 * (above - below);
    (se.is_finite() && se > 0.0).then_some(se)
}

/// The state of a [`StepTerm`] while a log is replayed (none: the basis depends on the row's
/// covariate only).
#[derive(Debug, Clone, Copy)]
struct StepState {
    idx: usize,
    threshold: f64,
}

impl TermState for StepState {
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        out[0] = if seek.covariates[self.idx] > self.threshold {
            1.0
        } else {
            0.0
        };
    }
    fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(*self)
    }
}

/// Parses `step:COL` or `step:COL:T` (T in the column's unit, finite); the registry's parser.
/// A column name holds no `:`: a last `:`-part that is not a finite number is refused as the threshold.
pub(crate) fn parse(t: &TermText<'_>) -> Result<Arc<dyn TermSpec>, SpecError> {
    let usage = "`step` needs a covariate column and optionally a starting threshold in the \
                 column's unit: `step:COL` or `step:COL:T` (e.g. `step:load:0.6`)";
    let Some(arg) = t.arg.filter(|a| !a.is_empty()) else {
        return Err(t.bad(usage.into()));
    };
    let (column, start) = match arg.rsplit_once(':') {
        // A column name holds no `:` (as in `by:A:B`): what follows one is the threshold.
        Some((c, v)) => match v.parse::<f64>() {
            Ok(x) if x.is_finite() => (c, Some(x)),
            _ => {
                return Err(t.bad(format!(
                    "the starting threshold T after `{c}:` must be a finite number in the \
                     column's unit, got `{v}` ({usage})"
                )));
            }
        },
        None => (arg, None),
    };
    if column.is_empty() {
        return Err(t.bad(format!("{usage}; got `{arg}`")));
    }
    Ok(Arc::new(StepSpec {
        column: column.to_string(),
        start,
    }))
}

/// The head of the term's spec text, for the diagnosis that suggests it.
pub(crate) const HEAD: &str = "step";

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{FitOptions, fit};
    use crate::log::{ColumnMap, Log};
    use crate::model::{FittedModel, ModelSpec};
    use crate::numeric::rng::SimRng;

    /// `n` seeks over tracks 0..=400 with a covariate `load` (uniform on [0, 1], three
    /// decimals) × `xs`; bias = a linear trend + `amp`·[load > 0.6] + N(0, 1) noise.
    fn log_text(seed: u64, n: usize, amp: f64, xs: f64) -> String {
        let mut rng = SimRng::new(seed);
        let mut text = String::from("time_s,track,bias,load\n");
        for k in 0..n {
            let x = (rng.uniform() * 400.0).round();
            let load = (rng.uniform() * 1000.0).round() / 1000.0;
            let step = if load > 0.6 { amp } else { 0.0 };
            let bias = 3.0 + 0.01 * x + step + rng.normal();
            text += &format!("{:?},{x:?},{bias:?},{:?}\n", 0.1 * k as f64, load * xs);
        }
        text
    }

    fn log(seed: u64, n: usize, amp: f64, xs: f64) -> Log {
        let text = log_text(seed, n, amp, xs);
        Log::from_reader("step.csv", text.as_bytes(), &ColumnMap::default()).unwrap()
    }

    fn fit_text(spec: &str, log: &Log) -> FittedModel {
        let opts = FitOptions::default().check().unwrap();
        fit(&ModelSpec::parse(spec).unwrap(), log, &opts).unwrap()
    }

    #[test]
    fn parses_its_syntax_and_refuses_bad_arguments() {
        for (ok, name) in [
            ("step:load", "step:load"),
            ("step:load:0.6", "step:load:0.6"),
            ("step:load:-3.50", "step:load:-3.5"),
            ("step:load:1e-6", "step:load:0.000001"),
        ] {
            let t = crate::model::terms::parse_term(ok).unwrap();
            assert_eq!(t.name(), name);
            assert_eq!(crate::model::terms::parse_term(name).unwrap().name(), name);
        }
        for bad in [
            "step",
            "step:",
            "step::0.5",
            "step:load:nan",
            "step:load:inf",
            "step:a:b",
        ] {
            let e = crate::model::terms::parse_term(bad)
                .unwrap_err()
                .to_string();
            assert!(e.contains("step:COL:T"), "{bad}: {e}");
        }
        // A last part that is no number is named as the threshold, not read into the column.
        let e = crate::model::terms::parse_term("step:col:abc")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("threshold T after `col:`") && e.contains("got `abc`"),
            "{e}"
        );
    }

    /// Reference: the truth of [`log_text`] (a step of 3 at load 0.6, logged to 0.001, so the
    /// threshold lies in [0.6, 0.601]) on 3000 seeks, from no start and from a start 0.1 off.
    #[test]
    fn recovers_threshold_and_height() {
        let l = log(5, 3000, 3.0, 1.0);
        for spec in ["poly2,step:load", "poly2,step:load:0.7"] {
            let m = fit_text(spec, &l);
            let name = spec.split(',').nth(1).unwrap();
            let p = |n: &str| m.param(&format!("{name}.{n}")).unwrap().clone();
            let (a, t) = (p("A"), p("threshold"));
            assert!((0.6..=0.601).contains(&t.value), "{spec}: {t:?}");
            assert!((a.value - 3.0).abs() < 2.5 * a.se.unwrap(), "{spec}: {a:?}");
            // The profile interval is a few logged values wide.
            let se = t.se.unwrap();
            assert!(se > 0.0 && se < 0.02, "{spec}: {t:?}");
            assert!(m.fit.converged, "{spec}: {:?}", m.warnings);
        }
    }

    /// A start the log cannot use, or a column the log lacks, is refused when fitting.
    #[test]
    fn refuses_a_start_outside_the_log() {
        let l = log(5, 800, 3.0, 1.0);
        let opts = FitOptions::default().check().unwrap();
        for (spec, why) in [
            ("poly2,step:load:2", "leaves fewer than 16 measured rows"),
            (
                "poly2,step:load:0.001",
                "leaves fewer than 16 measured rows",
            ),
            ("poly2,step:temp", "temp"),
        ] {
            let e = fit(&ModelSpec::parse(spec).unwrap(), &l, &opts)
                .unwrap_err()
                .to_string();
            assert!(e.contains("step:") && e.contains(why), "{spec}: {e}");
        }
    }

    /// Reference: the scores written out directly — for each split, the indicator column
    /// centred and the least-squares reduction `(Σ g·r)²/Σ g²` computed over every row, no
    /// sorting or running sums. The scan's scores must be the same up to rounding, and its
    /// best split the planted threshold.
    #[test]
    fn scan_equals_the_direct_sums() {
        let mut rng = SimRng::new(3);
        let v: Vec<f64> = (0..600).map(|_| (rng.uniform() * 100.0).round()).collect();
        let r: Vec<f64> = v
            .iter()
            .map(|&x| if x > 37.0 { 1.5 } else { 0.0 } + rng.normal())
            .collect();
        let hits = scan(&v, &r, (f64::NEG_INFINITY, f64::INFINITY), 10);
        assert!(hits.len() > 90, "{}", hits.len());
        let direct = |t: f64| {
            let g: Vec<f64> = v.iter().map(|&x| if x > t { 1.0 } else { 0.0 }).collect();
            let gm = g.iter().sum::<f64>() / g.len() as f64;
            let (mut gr, mut gg) = (0.0, 0.0);
            for (gi, ri) in g.iter().zip(&r) {
                gr += (gi - gm) * ri;
                gg += (gi - gm) * (gi - gm);
            }
            gr * gr / gg
        };
        for h in &hits {
            let d = direct(h.threshold);
            assert!(
                (d - h.score).abs() <= 1e-9 * d.max(1e-9),
                "{d} vs {}",
                h.score
            );
            let below = v.iter().filter(|&&x| x <= h.threshold).count();
            assert_eq!(below, h.below);
        }
        let best = hits
            .iter()
            .max_by(|a, b| a.score.total_cmp(&b.score))
            .unwrap();
        assert!((best.threshold - 37.5).abs() < 1e-12, "{best:?}");
    }

    /// Unit invariance (the module docs): the same log with the column × 1e-6 … 1e6 gives the
    /// same predictions (to 1e-9 of the bias spread) and the threshold × the factor, with and
    /// without a starting point (scaled with the column).
    #[test]
    fn predictions_do_not_depend_on_the_columns_unit() {
        let (train, test) = (log(8, 1500, 2.0, 1.0), log(9, 500, 2.0, 1.0));
        for (spec, start) in [("step:load", None), ("step:load:0.65", Some(0.65))] {
            let m0 = fit_text(&format!("poly2,{spec}"), &train);
            let p0 = m0.predict_log(&test).unwrap();
            let spread = p0.measured.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let t0 = m0.param(&format!("{spec}.threshold")).unwrap().value;
            for xs in [1e-6, 1e-3, 0.37, 1e3, 1e6] {
                let term = match start {
                    None => "step:load".to_string(),
                    Some(t) => format!("step:load:{}", t * xs),
                };
                let m = fit_text(&format!("poly2,{term}"), &log(8, 1500, 2.0, xs));
                let p = m.predict_log(&log(9, 500, 2.0, xs)).unwrap();
                for (a, b) in p0.predicted.iter().zip(&p.predicted) {
                    assert!((a - b).abs() <= 1e-9 * spread, "{term} ×{xs}: {a} vs {b}");
                }
                let t = m.param(&format!("{term}.threshold")).unwrap().value;
                assert!(
                    (t / xs - t0).abs() <= 1e-9 * t0,
                    "{term} ×{xs}: {t} vs {t0}"
                );
            }
        }
    }

    /// The model file round trip: settings, coefficients, parameters and predictions come back
    /// bit for bit; a misspelt setting or a missing threshold is refused at load.
    #[test]
    fn round_trips_bit_for_bit_and_refuses_bad_settings() {
        let l = log(5, 1500, 3.0, 1.0);
        let m = fit_text("poly2,step:load", &l);
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
        let t = m
            .terms
            .iter()
            .find(|t| t.term.name() == "step:load")
            .unwrap();
        let settings = t.term.settings();
        let again = crate::model::terms::restore_term("step:load", &settings).unwrap();
        assert_eq!(again.settings(), settings);
        let mut s = settings.clone();
        s["treshold"] = serde_json::json!(0.5);
        assert!(crate::model::terms::restore_term("step:load", &s).is_err());
        let mut s = settings.clone();
        s.as_object_mut().unwrap().remove("threshold");
        assert!(crate::model::terms::restore_term("step:load", &s).is_err());
    }
}
