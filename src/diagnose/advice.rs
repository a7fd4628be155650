//! From a binned curve to plain words: the curve's shape and the model term that addresses it.

use serde::{Deserialize, Serialize};

use crate::history::Feature;
use crate::model::registry::{self, Cue, Law};

use super::features::FeatureOrigin;
use super::values::short;

/// The term suggested for the state-space (Dahl) model
/// ([`crate::model::terms::dahl`]'s suggestion: four elements).
pub(super) const DAHL_TERM: &str = crate::model::terms::dahl::SUGGESTED;

/// The term suggested for hysteresis that spans the reversal amplitudes: `play`, Prandtl–
/// Ishlinskii play elements with thresholds spread over the log's reversal amplitudes
/// ([`crate::model::terms::play`]). Suggested after [`DAHL_TERM`], so it leads when the model
/// already has a Dahl term with at least as many elements (or `seek`, which `dahl:N` does
/// not fit beside) and the residual still follows the distance since the last reversal:
/// a loop whose shape changes with the reversal amplitude, which a few Dahl rates and a
/// direction offset cannot express. The verification scores it beside `dahl:4` and keeps
/// the better.
pub(crate) const PLAY_TERM: &str = crate::model::terms::play::HEAD;

/// Shape of the residual's binned curve against a feature.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shape {
    /// No structure the cross-validation endorses (one bin).
    Flat,
    /// Rises roughly linearly.
    Increasing,
    /// Falls roughly linearly.
    Decreasing,
    /// Rises to an interior maximum and falls again.
    Peaked,
    /// Falls to an interior minimum and rises again.
    Dip,
    /// A jump up at one place, level on either side.
    StepUp,
    /// A jump down at one place, level on either side.
    StepDown,
    /// Rises quickly at small values, then levels off.
    SaturatingRise,
    /// Falls quickly at small values, then levels off.
    SaturatingFall,
    /// None of the above.
    Irregular,
}

impl Shape {
    /// The shape in plain words, with its location `at` where it has one.
    pub fn describe(self, feature: &str, at: Option<f64>) -> String {
        let at = at
            .map(|x| format!(" near {feature} ≈ {}", short(x)))
            .unwrap_or_default();
        match self {
            Shape::Flat => "is flat".to_string(),
            Shape::Increasing => format!("increases with {feature}"),
            Shape::Decreasing => format!("decreases with {feature}"),
            Shape::Peaked => format!("peaks{at}"),
            Shape::Dip => format!("dips{at}"),
            Shape::StepUp if at.is_empty() => format!("steps up with {feature}"),
            Shape::StepDown if at.is_empty() => format!("steps down with {feature}"),
            Shape::StepUp => format!("steps up{at}"),
            Shape::StepDown => format!("steps down{at}"),
            Shape::SaturatingRise => format!("rises at small {feature}, then levels off"),
            Shape::SaturatingFall => format!("falls at small {feature}, then levels off"),
            Shape::Irregular => "varies irregularly".to_string(),
        }
    }
}

/// One defined bin of a curve, in increasing feature order.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Point {
    /// Centre (mean feature value) of the bin.
    pub x: f64,
    /// Mean residual.
    pub y: f64,
}

/// Classifies a curve of bin means (defined bins, increasing x). `linear` says a straight line
/// explains nearly as much as the bins do.
pub(crate) fn classify(points: &[Point], linear: bool) -> (Shape, Option<f64>) {
    let k = points.len();
    if k < 2 {
        return (Shape::Flat, None);
    }
    let ys: Vec<f64> = points.iter().map(|p| p.y).collect();
    let (imin, ymin) = extreme(&ys, |a, b| a < b);
    let (imax, ymax) = extreme(&ys, |a, b| a > b);
    let range = ymax - ymin;
    if range.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return (Shape::Flat, None);
    }
    let (first, last) = (ys[0], ys[k - 1]);
    let net = last - first;
    // Between two bin centres; a midpoint that is zero but for rounding (centres ±a) is zero,
    // so a message never reads "steps up near x ≈ -1.55e-10".
    let mid = |i: usize| {
        let (a, b) = (points[i].x, points[i + 1].x);
        let m = 0.5 * (a + b);
        if m.abs() <= 1e-9 * (a.abs() + b.abs()) {
            0.0
        } else {
            m
        }
    };
    if k == 2 {
        let shape = if net > 0.0 {
            Shape::StepUp
        } else {
            Shape::StepDown
        };
        return (shape, Some(mid(0)));
    }
    if linear {
        let shape = if net > 0.0 {
            Shape::Increasing
        } else {
            Shape::Decreasing
        };
        return (shape, None);
    }
    if imax > 0 && imax < k - 1 && ymax - first.max(last) > 0.5 * range {
        return (Shape::Peaked, Some(points[imax].x));
    }
    if imin > 0 && imin < k - 1 && first.min(last) - ymin > 0.5 * range {
        return (Shape::Dip, Some(points[imin].x));
    }
    // A step: one jump, spread over at most two bins (the bin straddling it has a mean in
    // between), with the curve level elsewhere.
    let variation: f64 = ys.windows(2).map(|w| (w[1] - w[0]).abs()).sum();
    let mut step: Option<(f64, usize, usize)> = None;
    for width in 1..=2usize.min(k - 1) {
        for i in 0..k - width {
            let jump = ys[i + width] - ys[i];
            if step.is_none_or(|(best, _, _)| jump.abs() > best.abs()) {
                step = Some((jump, i, width));
            }
        }
    }
    if let Some((jump, i, width)) = step
        && jump.abs() > 0.6 * range
        && variation - jump.abs() < 0.3 * range
    {
        let shape = if jump > 0.0 {
            Shape::StepUp
        } else {
            Shape::StepDown
        };
        return (shape, Some(0.5 * (points[i].x + points[i + width].x)));
    }
    if net.abs() > 0.6 * range {
        let q = (k / 4).max(1);
        let early = (ys[q] - first) / net;
        let rising = net > 0.0;
        let shape = match (early > 0.55, rising) {
            (true, true) => Shape::SaturatingRise,
            (true, false) => Shape::SaturatingFall,
            (false, true) => Shape::Increasing,
            (false, false) => Shape::Decreasing,
        };
        return (shape, None);
    }
    (Shape::Irregular, None)
}

/// Index and value of the first element that is `better` than all others.
fn extreme(v: &[f64], better: impl Fn(f64, f64) -> bool) -> (usize, f64) {
    let mut best = (0, v[0]);
    for (i, &x) in v.iter().enumerate().skip(1) {
        if better(x, best.1) {
            best = (i, x);
        }
    }
    best
}

/// The terms that address a feature, best first.
/// `by_direction`: the residual follows the feature times the direction of the last move.
/// `odd_linear`: the feature's sign is the direction's and residual ≈ a·direction + b·feature,
/// a line in the signed feature (a velocity) that `viscous:` fits with one parameter (named as
/// the viscous friction it is; `col:` is the same line and is verified beside it). `velocity_sign`: the feature's sign is the
/// direction's but the law is not that line: a velocity whose friction falls off from a
/// breakaway level at low speed (`stribeck:`).
pub(crate) fn candidate_terms(
    name: &str,
    origin: FeatureOrigin,
    linear: bool,
    by_direction: bool,
    odd_linear: bool,
    velocity_sign: bool,
) -> Vec<String> {
    // Hysteresis-like (`by_direction`): the effect flips sign with the approach direction. An
    // even curve would miss it, so only the terms that flip with the direction answer it.
    let cue = match origin {
        FeatureOrigin::BuiltIn(f) => Cue::Feature(f, by_direction),
        FeatureOrigin::Covariate => {
            let law = if odd_linear {
                Law::OddLinear
            } else if velocity_sign && (by_direction || !linear) {
                Law::Velocity
            } else if linear && !by_direction {
                Law::Linear
            } else {
                Law::Other
            };
            Cue::Covariate(law, by_direction)
        }
        FeatureOrigin::SummedMemory => Cue::SummedMemory(by_direction),
        FeatureOrigin::Lagged => {
            let col = super::features::lagged_column(name).unwrap_or(name);
            return registry::candidates(Cue::Lagged, col);
        }
        FeatureOrigin::DerivedVelocity => {
            // The law whose curve the residual follows first: a line unless the friction falls
            // off from a breakaway level at low speed.
            let law = if odd_linear || !velocity_sign || linear {
                Law::OddLinear
            } else {
                Law::Velocity
            };
            Cue::DerivedVelocity(law)
        }
    };
    registry::candidates(cue, name)
}

/// `scale:COL:TERM` for a covariate column whose effect flips with the direction of the last
/// move (`by_direction`) while the model already has a direction-signed state term TERM
/// (`direction`, `dahl`, `dahl:N`, `play`, `play:N`): the column likely scales that term's force
/// (a supply voltage scaling the friction), which `dbins:COL` only approximates piecewise and
/// without the term's state. One per such term, in model order, none already in the model;
/// verified by refit like every other edit. Not for a velocity-like column (`velocity_sign`:
/// its sign is the direction's): that is velocity friction (`viscous:`, `stribeck:`).
pub(crate) fn scale_terms(
    name: &str,
    origin: FeatureOrigin,
    by_direction: bool,
    velocity_sign: bool,
    existing: &[String],
) -> Vec<String> {
    if origin != FeatureOrigin::Covariate || !by_direction || velocity_sign {
        return Vec::new();
    }
    existing
        .iter()
        .map(|t| t.trim())
        .filter(|t| registry::is_signed_state(t))
        .map(|t| format!("{}:{name}:{t}", crate::model::terms::scale::HEAD))
        .filter(|s| !existing.iter().any(|e| e.trim() == s))
        .collect()
}

/// Whether the model's term list `existing` already holds `term` (any `dahl:N` counts as a Dahl
/// term).
fn has_term(existing: &[String], term: &str) -> bool {
    // `dahl` is one element; `dahl:N` has N. A Dahl term is covered by one with at least as
    // many elements (one element cannot make the overshoot that `dahl:4` can); any `play:N`
    // holds the play family (the suggestion is `play`, the default count).
    existing.iter().any(|e| registry::covers(e.trim(), term))
}

/// The note for a residual that still steps with the direction although the model has the
/// `direction` term. That term fits a constant inbound/outbound offset exactly on the log it was
/// fitted on (least squares leaves no mean difference), so a step left on another log means the
/// offset there is not the training log's: the classic case is the 1997 practice of calibrating
/// on far seeks (Table I) and predicting short ones, which stop inside the far curves.
pub(crate) fn offset_note(origin: FeatureOrigin, existing: &[String]) -> Option<String> {
    // The term that answers a step with the direction (`direction`).
    let offset = registry::candidates(Cue::Feature(Feature::Direction, true), "");
    let offset = offset.first()?;
    (origin == FeatureOrigin::BuiltIn(Feature::Direction) && has_term(existing, offset)).then(
        || {
            format!(
                "the model already has `{offset}`, which leaves no inbound/outbound step on the \
                 log it was fitted on: a step here means this log's offset differs from that log's \
                 (e.g. calibrated on far seeks, applied to short ones). Refit on data like this, or \
                 add the effect that moves the offset with the seek history (the seek-length, \
                 reversal and rest-distance features ranked here); `{DAHL_TERM}` is the state-space way"
            )
        },
    )
}

/// The first candidate term the model does not have yet, and a note when a better one was
/// skipped because it is already there.
pub(crate) fn suggest(
    candidates: &[String],
    existing: &[String],
) -> (Option<String>, Option<String>) {
    let present: Vec<&String> = candidates
        .iter()
        .take_while(|t| has_term(existing, t))
        .collect();
    let chosen = candidates
        .iter()
        .skip(present.len())
        .find(|t| !conflicts(existing, t))
        .cloned();
    let note = match (&chosen, present.is_empty()) {
        (None, true) => Some(
            "no built-in term follows this feature (times the direction where the effect flips \
             with it): write one through the public `Term` trait, see examples/new_effect.rs"
                .to_string(),
        ),
        (_, true) => None,
        (Some(c), false) => Some(format!(
            "the model already has {}; suggesting `{c}` instead",
            list(&present)
        )),
        (None, false) => Some(format!(
            "the model already has every term for this feature ({}); the residual left is what \
             they cannot fit: give them more flexibility",
            list(&present)
        )),
    };
    (chosen, note)
}

/// Whether `term` belongs to another model family than one the model already has: a model
/// with the eq. 1 seek curves (`seek`) is not given the state-space `dahl:N` (a seek-length
/// effect left there gets `bins:seek_length`, which fits beside `seek`), and a state-space model
/// is not given `seek`.
fn conflicts(existing: &[String], term: &str) -> bool {
    existing.iter().any(|e| registry::conflicts(e, term))
}

/// The candidates after `chosen` that the model does not have and that do not conflict with
/// it: the alternatives the verification tries when the first does not fit.
pub(crate) fn alternatives(
    candidates: &[String],
    existing: &[String],
    chosen: Option<&str>,
) -> Vec<String> {
    candidates
        .iter()
        .filter(|t| Some(t.as_str()) != chosen)
        .filter(|t| !has_term(existing, t) && !conflicts(existing, t))
        .cloned()
        .collect()
}

fn list(terms: &[&String]) -> String {
    terms
        .iter()
        .map(|t| format!("`{t}`"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The term for a narrow localized position defect: `bump`, a Gaussian bump whose centre and
/// width the fit searches ([`crate::model::terms::bump`]). Verified beside the finer tables
/// a `table` suggestion is scored with (and beside `bins:position`'s knot counts) when the
/// narrow-defect screen ([`defect_screen`]) finds a bump narrower than the cross-validated
/// table spacing can follow ([`worth_a_bump`]): a defect a few tracks wide needs table knots
/// that close over the whole span, or three parameters of a bump; the out-of-sample refit
/// decides which resolves it better. Every fold's refit searches the centre and width on its
/// own training rows (bare `bump`), so the held-out rows never choose where the bump goes.
pub(crate) const BUMP_TERM: &str = crate::model::terms::bump::HEAD;

/// The position terms whose verification also scores [`BUMP_TERM`]: `table` and
/// `bins:position`.
pub(crate) fn tries_bump(term: &str) -> bool {
    // The terms that answer an even curve in position.
    let position = Feature::Position;
    registry::candidates(Cue::Feature(position, false), position.name())
        .iter()
        .any(|t| t == term)
}

/// [`BUMP_TERM`], unless the model `spec` already has a term of that name.
pub(crate) fn bump_variant(spec: &crate::model::ModelSpec) -> Option<String> {
    (!spec.terms.iter().any(|t| t.name() == BUMP_TERM)).then(|| BUMP_TERM.to_string())
}

/// `bump:CENTRE:WIDTH` at a fitted centre and width (position unit), both to the hundredth of
/// the width's leading digit (`bump:1506.89:1.44` for a width of 1.436 tracks): what the
/// suggestion shows and applies. The term searches again from there (centres within four
/// widths, widths within a factor three), so refitting it on the log it was found on ends
/// where the bare `bump` did.
pub(crate) fn bump_at(centre: f64, width: f64) -> String {
    let decimals = (2 - width.log10().floor() as i64).clamp(0, 300) as usize;
    let text = |v: f64| {
        let s = format!("{v:.decimals$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    };
    format!("{BUMP_TERM}:{}:{}", text(centre), text(width))
}

/// `step:COL:T` at a fitted threshold `t` (column unit) to the hundredth of its standard
/// error's leading digit (`se`; without one, 6 significant digits): what the suggestion shows
/// and applies. The term searches again from there (thresholds within an eighth of the
/// column's range), so refitting it on the log it was found on ends where the bare
/// `step:COL` did.
pub(crate) fn step_at(column: &str, t: f64, se: Option<f64>) -> String {
    let scale = se
        .filter(|s| *s > 0.0)
        .unwrap_or(1e-3 * t.abs().max(f64::MIN_POSITIVE));
    let decimals = (2 - scale.log10().floor() as i64).clamp(0, 300) as usize;
    let s = format!("{t:.decimals$}");
    let s = if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    };
    format!("{STEP_HEAD}:{column}:{s}")
}

/// For a verified `add bump` or `add step:COL` edit on `spec`: the same edit with what the
/// bare term finds when fitted on the whole `log` — the bump's centre and width
/// (`add bump:1506.89:1.44`), the step's threshold (`add step:load:0.599469`) — and the spec
/// after it; `None` for any other edit or where that fit fails (the edit then stays as it is).
pub(crate) fn name_searched(
    spec: &crate::model::ModelSpec,
    edit: &crate::model::ModelEdit,
    log: &crate::log::Log,
    opts: &crate::fit::CheckedFitOptions,
) -> Option<(crate::model::ModelEdit, crate::model::ModelSpec)> {
    use crate::model::ModelEdit;
    let ModelEdit::Add(t) = edit else { return None };
    let name = t.name();
    let column = name
        .strip_prefix(STEP_HEAD)
        .and_then(|r| r.strip_prefix(':'))
        .filter(|c| !c.is_empty() && !c.contains(':'));
    if name != BUMP_TERM && column.is_none() {
        return None;
    }
    let model = crate::fit::fit(&spec.apply(edit).ok()?, log, opts).ok()?;
    let p = |n: &str| model.param(&format!("{name}.{n}"));
    let text = match column {
        Some(c) => {
            let t = p("threshold")?;
            step_at(c, t.value, t.se)
        }
        None => bump_at(p("centre")?.value, p("width")?.value),
    };
    let edit = ModelEdit::Add(crate::model::terms::parse_term(&text).ok()?);
    let next = spec.apply(&edit).ok()?;
    Some((edit, next))
}

/// Margin of the narrow-defect screen ([`defect_screen`]) above `2·ln M` (M candidates
/// scanned), in units of the residual's variance. For M independent χ²₁ scores the chance
/// that the largest exceeds `2·ln M + 10` is about `e⁻⁵·√(2/(π·x))` ≈ 0.1 %; the scan's
/// candidates overlap, so fewer are independent and the chance is smaller still.
pub(crate) const DEFECT_MARGIN: f64 = 10.0;

/// Residuals beyond this many robust standard deviations are clipped before the screen, so
/// that one heavy-tailed outlier cannot look like a narrow defect.
pub(crate) const DEFECT_CLIP: f64 = 3.0;

/// The narrow-defect screen: whether the residual `r` (one per measured row, in the order of
/// the positions `x`) has a localized bump in position that the one-dimensional smoother's
/// bins cannot resolve. The bump term's own coarse scan
/// ([`crate::model::terms::bump`]: Gaussians of every width the log resolves, centres half a
/// width apart) runs on the residual centred and clipped at [`DEFECT_CLIP`] robust standard
/// deviations; the best candidate passes when the RSS reduction it alone would bring exceeds
/// the clipped residual's variance × (`2·ln M` + [`DEFECT_MARGIN`]). Returns that candidate.
/// The screen only decides whether `bump` is verified by refit when position is not already
/// a candidate; the refit decides whether it is suggested.
pub(crate) fn defect_screen(x: &[f64], r: &[f64]) -> Option<crate::model::terms::bump::ScanHit> {
    use crate::model::terms::bump;
    let (centred, var) = clipped_residual(r)?;
    let finite: Vec<f64> = x.iter().copied().filter(|v| v.is_finite()).collect();
    let [lo, hi] = crate::numeric::stats::range(&finite)?;
    let (w_lo, w_hi) = bump::width_limits(&finite, hi - lo);
    if !(hi > lo && w_lo < w_hi && var > 0.0) {
        return None;
    }
    let (hits, tried) = bump::scan(x, &centred, (lo, hi), (w_lo.ln(), w_hi.ln()), 1);
    let best = hits.into_iter().next()?;
    let threshold = var * (2.0 * (tried.max(1) as f64).ln() + DEFECT_MARGIN);
    (best.score > threshold).then_some(best)
}

/// The residual `r` less its median, clipped at [`DEFECT_CLIP`] robust standard deviations
/// (1.4826·MAD), centred on its mean; and its variance. `None` when the robust scale is 0.
/// What the screens ([`defect_screen`], [`step_screen`]) scan, so that one heavy-tailed
/// outlier cannot look like a defect or a step.
pub(crate) fn clipped_residual(r: &[f64]) -> Option<(Vec<f64>, f64)> {
    use crate::numeric::stats::percentile_select;
    // The medians by selection (O(n), the same bits as sorting: `percentile_select`).
    let med = percentile_select(&mut r.to_vec(), 50.0)?;
    let mut dev: Vec<f64> = r.iter().map(|v| (v - med).abs()).collect();
    let s = 1.4826 * percentile_select(&mut dev, 50.0)?;
    if !(s > 0.0 && s.is_finite()) {
        return None;
    }
    let clipped: Vec<f64> = r
        .iter()
        .map(|v| (v - med).clamp(-DEFECT_CLIP * s, DEFECT_CLIP * s))
        .collect();
    let mean = crate::numeric::stats::mean(&clipped)?;
    let centred: Vec<f64> = clipped.iter().map(|v| v - mean).collect();
    let var = centred.iter().map(|v| v * v).sum::<f64>() / centred.len() as f64;
    Some((centred, var))
}

/// The head of the threshold term, `step:COL` ([`crate::model::terms::step`]): a step of
/// fitted height where a covariate exceeds a fitted threshold. Scored beside a `bins:COL`
/// suggestion (and its knot counts) when the step screen ([`step_screen`]) finds that one
/// step in the column explains the model's out-of-sample residual better than a straight line
/// and beyond what the search over every split finds in noise: a sharp threshold needs hinges
/// packed around it (16 knots spread over the column to place a few there), or two
/// parameters of a step. The out-of-sample refit decides which pays, and each fold's refit
/// searches the threshold on its own training rows (bare `step:COL`).
pub(crate) const STEP_HEAD: &str = crate::model::terms::step::HEAD;

/// Whether `term` is a `step:` term.
pub(crate) fn is_step(term: &str) -> bool {
    term.split(':').next() == Some(STEP_HEAD)
}

/// `step:COL` for a `bins:COL` suggestion without a knot count on a covariate column (not a
/// built-in feature), unless the model `spec` already has a step in that column.
pub(crate) fn step_variant(term: &str, spec: &crate::model::ModelSpec) -> Option<String> {
    let col = term
        .strip_prefix(crate::model::terms::bins::HEAD)
        .and_then(|r| r.strip_prefix(':'))
        .filter(|c| !c.contains(':'))?;
    if Feature::from_name(col).is_some() {
        return None;
    }
    let step = format!("{STEP_HEAD}:{col}");
    let has = spec.terms.iter().any(|t| {
        let n = t.name();
        n == step || n.strip_prefix(&step).is_some_and(|r| r.starts_with(':'))
    });
    (!has).then_some(step)
}

/// Margin of the step screen ([`step_screen`]) above `2·ln M` (M splits scanned), in units of
/// the residual's variance: the same as [`DEFECT_MARGIN`] (the largest of M χ²₁ scores exceeds
/// `2·ln M + 10` with a chance of about 0.1 %; neighbouring splits overlap, so fewer are
/// independent and the chance is smaller still).
pub(crate) const STEP_MARGIN: f64 = DEFECT_MARGIN;

/// The step screen: whether a residual (one per measured row) steps at one value of the
/// covariate `v` (the same rows). The step term's own scan ([`crate::model::terms::step`]:
/// every split leaving enough rows on each side) runs on the residual clipped and centred as
/// for [`defect_screen`], given with its variance (`clipped`, [`clipped_residual`]: computed
/// once per residual, whatever the number of columns screened); the best split passes when the RSS
/// reduction it alone would bring exceeds the clipped residual's variance × (`2·ln M` +
/// [`STEP_MARGIN`]) **and** what a straight line in `v` brings (a linear effect is a line; the
/// best split of a line explains about ¾ of it). Returns that split. The screen only decides
/// whether `step:COL` is verified by refit; the refit decides whether it is suggested.
pub(crate) fn step_screen(
    v: &[f64],
    clipped: &(Vec<f64>, f64),
) -> Option<crate::model::terms::step::StepHit> {
    use crate::model::terms::step;
    let (centred, var) = (&clipped.0, clipped.1);
    let rows: Vec<(f64, f64)> = v
        .iter()
        .zip(centred)
        .filter(|(a, _)| a.is_finite())
        .map(|(&a, &b)| (a, b))
        .collect();
    let hits = step::scan(
        v,
        centred,
        (f64::NEG_INFINITY, f64::INFINITY),
        step::min_side(rows.len()),
    );
    let best = hits
        .iter()
        .copied()
        .max_by(|a, b| a.score.total_cmp(&b.score))?;
    let n = rows.len() as f64;
    let vm = rows.iter().map(|p| p.0).sum::<f64>() / n;
    let (mut vr, mut vv) = (0.0, 0.0);
    for &(a, b) in &rows {
        vr += (a - vm) * b;
        vv += (a - vm) * (a - vm);
    }
    let line = if vv > 0.0 { vr * vr / vv } else { 0.0 };
    let threshold = var * (2.0 * (hits.len().max(1) as f64).ln() + STEP_MARGIN);
    (var > 0.0 && best.score > threshold && best.score > line).then_some(best)
}

/// Full width at half maximum of a Gaussian, in σ: `2·√(2·ln 2)`.
pub(crate) const FWHM_PER_SIGMA: f64 = 2.354_820_045_030_949;

/// Whether `bump` gets a verification refit for a position candidate whose cross-validated
/// table spacing is `table_spacing`: the narrow-defect screen found a bump (`defect`) whose
/// full width at half maximum is below that spacing, so a table at the cross-validated spacing
/// cannot resolve it (a candidate without a spacing: whenever the screen found one). A broad
/// bump is left to the tables, and no refit is spent on a bump where the screen sees none.
pub(crate) fn worth_a_bump(
    defect: Option<&crate::model::terms::bump::ScanHit>,
    table_spacing: Option<f64>,
) -> bool {
    defect.is_some_and(|h| table_spacing.is_none_or(|s| FWHM_PER_SIGMA * h.ln_width.exp() < s))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::rng::SimRng;

    /// `n` rows on integer tracks 0..=300 with residual noise (Gaussian, or Student-t ν = 3
    /// scaled to unit variance: heavy tails) plus `amp`·a Gaussian bump of σ = 1.5 tracks at
    /// track 120.
    fn rows(seed: u64, n: usize, amp: f64, heavy: bool) -> (Vec<f64>, Vec<f64>) {
        let mut rng = SimRng::new(seed);
        let x: Vec<f64> = (0..n).map(|_| (rng.uniform() * 300.0).round()).collect();
        let r = x
            .iter()
            .map(|&v| {
                let e = if heavy {
                    let chi2: f64 = (0..3).map(|_| rng.normal().powi(2)).sum();
                    rng.normal() / (chi2 / 3.0).sqrt() / 3f64.sqrt()
                } else {
                    rng.normal()
                };
                amp * (-0.5 * ((v - 120.0) / 1.5f64).powi(2)).exp() + e
            })
            .collect();
        (x, r)
    }

    /// Bin centres symmetric about zero place a step at zero, not at the rounding of their sum
    /// (−0.3 and 0.1 + 0.2 sum to 5.6e-17): the message says "≈ 0".
    #[test]
    fn a_step_between_symmetric_centres_is_at_zero() {
        let points = [
            Point { x: -0.3, y: -1.0 },
            Point {
                x: 0.1 + 0.2,
                y: 1.0,
            },
        ];
        let (shape, at) = classify(&points, false);
        assert_eq!(shape, Shape::StepUp);
        assert_eq!(at, Some(0.0));
        assert_eq!(shape.describe("x", at), "steps up near x ≈ 0");
        let off = [Point { x: -0.3, y: -1.0 }, Point { x: 0.5, y: 1.0 }];
        assert_eq!(classify(&off, false).1, Some(0.1));
    }

    /// Reference: the planted truth. A bump of 3 noise std (σ = 1.5 tracks, 1500 rows) is
    /// found at its track; pure noise — Gaussian and heavy-tailed — passes the screen in none
    /// of 40 seeds (its nominal rate is about 0.1 % per log).
    #[test]
    fn defect_screen_finds_a_narrow_bump_and_passes_noise_by() {
        for heavy in [false, true] {
            let (x, r) = rows(1, 1500, 3.0, heavy);
            let hit = defect_screen(&x, &r).expect("the planted bump");
            assert!((hit.centre - 120.0).abs() < 1.5, "{hit:?}");
            let alarms = (0..40)
                .filter(|&s| {
                    let (x, r) = rows(100 + s, 1500, 0.0, heavy);
                    defect_screen(&x, &r).is_some()
                })
                .count();
            assert_eq!(alarms, 0, "heavy tails {heavy}");
        }
    }

    /// `n` rows of a covariate (an AR(1) process in row order, ρ = 0.98, unit variance: slow
    /// like a logged load) and residual noise (Student-t ν = 3, unit variance: heavy tails)
    /// plus `step`·[v > 0.8] and `slope`·v.
    fn step_rows(seed: u64, n: usize, step: f64, slope: f64) -> (Vec<f64>, Vec<f64>) {
        let mut rng = SimRng::new(seed);
        let mut v = Vec::with_capacity(n);
        let mut x = 0.0f64;
        for _ in 0..n {
            x = 0.98 * x + (1.0 - 0.98f64 * 0.98).sqrt() * rng.normal();
            v.push(x);
        }
        let r = v
            .iter()
            .map(|&x| {
                let chi2: f64 = (0..3).map(|_| rng.normal().powi(2)).sum();
                let e = rng.normal() / (chi2 / 3.0).sqrt() / 3f64.sqrt();
                (if x > 0.8 { step } else { 0.0 }) + slope * x + e
            })
            .collect();
        (v, r)
    }

    /// Reference: the planted truth. A step of 1 noise std where the covariate exceeds 0.8
    /// (about a fifth of 1500 rows) is found there; pure noise passes the screen in none of 40
    /// seeds (nominal rate about 0.1 % per log), and a linear effect of the same size (a line
    /// explains it better than any one step) in none of 20.
    #[test]
    fn step_screen_finds_a_threshold_and_passes_noise_and_lines_by() {
        let screen = |v: &[f64], r: &[f64]| step_screen(v, &clipped_residual(r).unwrap());
        let (v, r) = step_rows(1, 1500, 1.0, 0.0);
        let hit = screen(&v, &r).expect("the planted step");
        assert!((hit.threshold - 0.8).abs() < 0.1, "{hit:?}");
        let noise = (0..40)
            .filter(|&s| {
                let (v, r) = step_rows(100 + s, 1500, 0.0, 0.0);
                screen(&v, &r).is_some()
            })
            .count();
        assert_eq!(noise, 0);
        let lines = (0..20)
            .filter(|&s| {
                let (v, r) = step_rows(200 + s, 1500, 0.0, 1.0);
                screen(&v, &r).is_some()
            })
            .count();
        assert_eq!(lines, 0);
    }

    /// `step:COL` is a variant of a covariate's `bins:COL` only: not of a built-in feature's
    /// `bins`, nor of one with a knot count, nor when the model has a step in that column.
    #[test]
    fn step_variant_is_for_covariate_bins_only() {
        use crate::model::ModelSpec;
        let spec = ModelSpec::parse("poly2,step:walk").unwrap();
        assert_eq!(
            step_variant("bins:load", &spec).as_deref(),
            Some("step:load")
        );
        assert_eq!(step_variant("bins:dwell_s", &spec), None);
        assert_eq!(step_variant("bins:load:8", &spec), None);
        assert_eq!(step_variant("col:load", &spec), None);
        assert_eq!(step_variant("bins:walk", &spec), None);
        let spec = ModelSpec::parse("poly2,step:load:0.6").unwrap();
        assert_eq!(step_variant("bins:load", &spec), None);
        assert!(is_step("step:load") && !is_step("stepper") && !is_step("bins:step"));
    }

    #[test]
    fn step_text_rounds_to_the_standard_error_and_reads_back() {
        assert_eq!(
            step_at("load", 0.5994695, Some(0.00089)),
            "step:load:0.599469"
        );
        assert_eq!(step_at("load", 599469.5, Some(890.0)), "step:load:599470");
        assert_eq!(step_at("load", 0.25, None), "step:load:0.25");
        assert_eq!(step_at("load", 1.0 / 3.0, None), "step:load:0.333333");
        for t in ["step:load:0.599469", "step:load:599470"] {
            assert_eq!(crate::model::terms::parse_term(t).unwrap().name(), t);
        }
    }

    #[test]
    fn bump_text_rounds_to_the_width_and_reads_back() {
        assert_eq!(bump_at(1506.8912, 1.4361), "bump:1506.89:1.44");
        assert_eq!(bump_at(0.00150689, 1.4361e-6), "bump:0.00150689:0.00000144");
        assert_eq!(bump_at(150.0, 250.0), "bump:150:250");
        for t in ["bump:1506.89:1.44", "bump:0.00150689:0.00000144"] {
            assert_eq!(crate::model::terms::parse_term(t).unwrap().name(), t);
        }
    }
}
