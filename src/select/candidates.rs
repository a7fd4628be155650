//! What the verification refits: the candidates drawn from a diagnosis (flagged features, the
//! strongest unflagged ones, what adaptive terms absorbed, pairs) and each one's term variants.

use crate::diagnose::{Diagnosis, FeatureReport};
use crate::model::registry::head;
use crate::model::terms::{bins, covariate, drift, lag, parse_term, poly, preisach, table};
use crate::model::{ModelEdit, ModelSpec, SpecError};

/// A candidate for verification: the feature it comes from and the terms to try, best first
/// (the first that applies and fits is scored; for a covariate every one is scored and the
/// best kept, so a lagged term wins when the lag fits better).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Candidate {
    /// The feature (or description) the suggestion comes from.
    pub feature: String,
    /// Terms to try, best first.
    pub terms: Vec<String>,
    /// Score every term and keep the best, instead of stopping at the first that fits.
    pub try_all: bool,
    /// Knot spacing for a `table` (from the position smoother's cross-validated bins).
    pub table_spacing: Option<f64>,
    /// An unflagged feature verified on its refit alone ([`unflagged_candidates`]): its edit
    /// counts as verified only at a z-score of [`VerifyConfig::min_z`] + [`STRICT_EXTRA_Z`].
    pub strict: bool,
}

/// Most raw permutation p-value of an unflagged feature for its edit to be verified
/// ([`unflagged_candidates`]).
pub(crate) const UNFLAGGED_P: f64 = 0.01;

/// Extra z-score an unflagged feature's edit needs beyond [`VerifyConfig::min_z`] (2 + 1 = 3 by
/// default, a one-sided 0.13 % level): up to [`VerifyConfig::candidates`] such features, each
/// with a few term variants, are tried on the same log, and the model holding every effect
/// must still get no verified edit in 19 of 20 seeds (tests/it/family.rs). Such an edit must
/// also lower the loss in every fold (see `gains_in_every_fold` in the module source).
pub(crate) const STRICT_EXTRA_Z: f64 = 1.0;

/// The knot spacing a position smoother chose: the feature's range over its cross-validated
/// number of bins, rounded to two significant digits.
pub(crate) fn table_spacing(f: &FeatureReport) -> Option<f64> {
    let lo = f.curve.iter().filter_map(|c| c.lower).reduce(f64::min)?;
    let hi = f.curve.iter().filter_map(|c| c.upper).reduce(f64::max)?;
    let bins = f.bins.max(2) as f64;
    let h = (hi - lo) / bins;
    (h.is_finite() && h > 0.0).then(|| {
        let mag = 10f64.powf(h.log10().floor() - 1.0);
        (h / mag).round() * mag
    })
}

/// The candidates of a diagnosis: its leading flagged features with their suggested term and
/// the alternatives not in the model yet, the screened interactions (`by:A:B`) and what
/// adaptive terms absorbed.
pub(crate) fn candidates(d: &Diagnosis, max: usize) -> Vec<Candidate> {
    let mut c = feature_candidates(d, max);
    let room = max.saturating_sub(c.len());
    c.extend(unflagged_candidates(d, &c, room));
    c.extend(d.interactions.iter().map(|i| Candidate {
        feature: format!("{} × {}", i.a, i.b),
        terms: vec![i.suggested_term.clone()],
        try_all: false,
        table_spacing: None,
        strict: false,
    }));
    c.extend(d.absorbed.iter().filter_map(|a| {
        let mut terms: Vec<String> = a.suggested_term.iter().cloned().collect();
        terms.extend(a.alternatives.iter().cloned());
        (!terms.is_empty()).then(|| Candidate {
            feature: format!("{} → {}", a.term, a.feature),
            try_all: true,
            terms,
            table_spacing: None,
            strict: false,
        })
    }));
    c
}

pub(super) fn feature_candidates(d: &Diagnosis, max: usize) -> Vec<Candidate> {
    d.features
        .iter()
        .filter(|f| f.flagged)
        .filter(|f| f.suggested_term.is_some())
        .take(max)
        .map(|f| feature_candidate(f, false))
        .collect()
}

pub(super) fn feature_candidate(f: &FeatureReport, strict: bool) -> Candidate {
    let mut terms: Vec<String> = f.suggested_term.iter().cloned().collect();
    terms.extend(f.alternatives.iter().cloned());
    Candidate {
        feature: f.name.clone(),
        try_all: tries_every_term(&terms),
        terms,
        table_spacing: (f.name == "position").then(|| table_spacing(f)).flatten(),
        strict,
    }
}

/// Whether a feature's verification scores every one of its `terms` and keeps the best (a
/// covariate's or lag's terms, `play`), instead of stopping at the first that fits.
pub(crate) fn tries_every_term(terms: &[String]) -> bool {
    terms.iter().any(|t| {
        matches!(head(t), covariate::HEAD | lag::HEAD) || t == crate::diagnose::advice::PLAY_TERM
    })
}

/// The source a feature stands for: the column of a lagged covariate (`temp@lag4s` →
/// `temp`), `drift` for the time features, else its name. Candidates of one source are
/// verified once.
pub(super) fn source_of(f: &FeatureReport) -> String {
    match f.suggested_term.as_deref() {
        Some(drift::HEAD) => drift::HEAD.to_string(),
        _ => crate::diagnose::lagged_column(&f.name)
            .unwrap_or(&f.name)
            .to_string(),
    }
}

/// The source ([`source_of`]) of the feature named `name` in `d`; a name `d` holds no report
/// of (an edit's feature) is its own column, a lagged copy counting as its column.
pub(super) fn source_of_name(d: &Diagnosis, name: &str) -> String {
    d.feature(name).map_or_else(
        || {
            crate::diagnose::lagged_column(name)
                .unwrap_or(name)
                .to_string()
        },
        source_of,
    )
}

/// Up to `room` features that are **not** flagged but whose raw permutation p-value is at
/// most [`UNFLAGGED_P`], one per source (a lagged copy counts as its column, the time features
/// as `drift`) not already in `taken`, the largest
/// marginal `explained` first (then the smallest p): the strongest unflagged features, whose
/// power comes from the refit rather than the one-dimensional smoother. The time features
/// are left out: unflagged under their row-permutation null, what `drift` would fit is the
/// residual's serial correlation, which its one-step replay scores as a gain. A slow covariate
/// whose effect comes through a lag, or a narrow defect a few knots of a finer table fit,
/// can be clear on the refit and lost in the smoother's serial-structure null. Their edits
/// are verified against the stricter z-score ([`STRICT_EXTRA_Z`]).
pub(crate) fn unflagged_candidates(
    d: &Diagnosis,
    taken: &[Candidate],
    room: usize,
) -> Vec<Candidate> {
    let mut sources: Vec<String> = d
        .features
        .iter()
        .filter(|f| taken.iter().any(|c| c.feature == f.name))
        .map(source_of)
        .collect();
    let mut pool: Vec<&FeatureReport> = d
        .features
        .iter()
        .filter(|f| !f.flagged && f.p_value_raw <= UNFLAGGED_P)
        .filter(|f| {
            f.suggested_term
                .as_deref()
                .is_some_and(|t| t != drift::HEAD)
        })
        .collect();
    pool.sort_by(|a, b| {
        b.explained
            .total_cmp(&a.explained)
            .then(a.p_value_raw.total_cmp(&b.p_value_raw))
    });
    let mut out = Vec::new();
    for f in pool {
        if out.len() >= room {
            break;
        }
        let src = source_of(f);
        if sources.contains(&src) {
            continue;
        }
        sources.push(src);
        out.push(feature_candidate(f, true));
    }
    out
}

/// The typed edit for suggested `term` on `spec`: a `table` replaces `poly2` (or a coarser
/// table) with the cross-validated spacing, since the two span the same position polynomial
/// and cannot be fitted together; everything else is added.
pub(crate) fn edit_for(
    term: &str,
    spec: &ModelSpec,
    table_spacing: Option<f64>,
) -> Result<ModelEdit, SpecError> {
    let has = |name: &str| spec.terms.iter().any(|t| t.name() == name);
    if head(term) == table::HEAD {
        let new = match table_spacing {
            Some(h) if term == table::HEAD => parse_term(&table::spec(h))?,
            _ => parse_term(term)?,
        };
        if has(poly::HEAD) {
            return Ok(ModelEdit::Replace {
                old: poly::HEAD.into(),
                new,
            });
        }
        if let Some(old) = spec
            .terms
            .iter()
            .map(|t| t.name())
            .find(|n| head(n) == table::HEAD)
        {
            return Ok(ModelEdit::Replace { old, new });
        }
        return Ok(ModelEdit::Add(new));
    }
    Ok(ModelEdit::Add(parse_term(term)?))
}

/// Knot counts the verification tries for a `bins:`/`dbins:` suggestion given without one
/// (the term's default of 4 first): a threshold or a sharp bend needs more hinges than a
/// smooth curve, and the out-of-sample refit, not the 1-D smoother, decides how many pay.
pub(super) const KNOT_CHOICES: [usize; 2] = [8, 16];

/// Relay counts N the verification tries for a `preisach` suggestion given without one: the
/// term's default first, then these. A finer grid follows a narrower weight density, at
/// N(N+1)/2 weights; the out-of-sample refit decides how many pay.
pub(super) const PREISACH_CHOICES: [usize; 2] = [12, 16];

/// The terms the verification scores for suggestion `term`: the term itself, then for a
/// `bins:F` or `dbins:F` without a knot count the same term with each of [`KNOT_CHOICES`],
/// for `preisach` without a relay count the same with each of [`PREISACH_CHOICES`] (the best
/// verified gain among them is kept).
pub(super) fn knot_variants(term: &str) -> Vec<String> {
    let mut out = vec![term.to_string()];
    let parts: Vec<&str> = term.split(':').collect();
    if parts.len() == 2 && (parts[0] == bins::HEAD || parts[0] == bins::DBINS_HEAD) {
        out.extend(KNOT_CHOICES.iter().map(|k| format!("{term}:{k}")));
    }
    if term == preisach::HEAD {
        out.extend(PREISACH_CHOICES.iter().map(|k| format!("{term}:{k}")));
    }
    out
}

/// Finer tables the verification tries for a `table` suggestion on a model that already has
/// `table:H`: H / 2 and H / 4 (a localized defect a few tracks wide needs knots that close;
/// the out-of-sample refit decides whether they pay).
pub(crate) const TABLE_REFINEMENTS: [f64; 2] = [2.0, 4.0];

/// [`knot_variants`], and for `table` the cross-validated spacing (`spacing`, when finer than
/// the model's table) then the model's table spacing over each of [`TABLE_REFINEMENTS`]; for
/// `table` and `bins:position` also `bump` (a narrow localized defect, see
/// [`crate::diagnose::advice::BUMP_TERM`]), unless the model has one; for `bins:COL` on a covariate
/// also `step:COL` (a threshold, see [`crate::diagnose::advice::STEP_HEAD`]), unless the model has one.
pub(super) fn variants(term: &str, spec: &ModelSpec, spacing: Option<f64>) -> Vec<String> {
    if term != table::HEAD {
        let mut out = knot_variants(term);
        if crate::diagnose::advice::tries_bump(term) {
            out.extend(crate::diagnose::advice::bump_variant(spec));
        }
        out.extend(crate::diagnose::advice::step_variant(term, spec));
        return out;
    }
    let current = spec.terms.iter().find_map(|t| {
        t.name()
            .strip_prefix(table::HEAD)
            .and_then(|h| h.strip_prefix(':'))
            .and_then(|h| h.parse::<f64>().ok())
    });
    let mut out = Vec::new();
    match (spacing, current) {
        (Some(h), Some(c)) if h < c => out.push(table::spec(h)),
        (Some(_), None) => out.push(term.to_string()),
        _ => {}
    }
    if let Some(c) = current {
        out.extend(
            TABLE_REFINEMENTS
                .iter()
                .map(|k| format!("{}:{}", table::HEAD, c / k)),
        );
    }
    if out.is_empty() {
        out.push(term.to_string());
    }
    out.extend(crate::diagnose::advice::bump_variant(spec));
    out
}

/// A strict candidate `bump` for `position` when no candidate tries one yet (position was
/// neither flagged nor among the strongest unflagged features: the smoother's bins cannot
/// resolve a defect a few tracks wide) and the narrow-defect screen
/// ([`crate::diagnose::advice::defect_screen`], on the model's out-of-sample residual) found one
/// (`screened`). Each fold's refit still places the bump from its own training rows.
pub(super) fn defect_candidate(
    spec: &ModelSpec,
    screened: bool,
    cands: &[Candidate],
) -> Option<Candidate> {
    let bump = crate::diagnose::advice::bump_variant(spec)?;
    if !screened
        || cands.iter().any(|c| {
            c.terms
                .iter()
                .any(|t| crate::diagnose::advice::tries_bump(t))
        })
    {
        return None;
    }
    Some(Candidate {
        feature: "position".into(),
        terms: vec![bump],
        try_all: false,
        table_spacing: None,
        strict: true,
    })
}
