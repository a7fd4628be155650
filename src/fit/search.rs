//! The searches of the terms' nonlinear parameters ([`search_nonlinear`]): a grid and golden
//! section on the least-squares RSS (by variable projection where the term allows it), or the
//! term's own search ([`Term::search`]) handed the residual of the other terms and the RSS of
//! any version of itself.

use super::design::design_pass;
use super::options::CheckedFitOptions;
use super::projection::Projection;
use super::solve::{slow_rss, slow_rss_of, solve};
use crate::model::data::FitData;
use crate::model::term::Term;
use crate::numeric::search::{golden_min, golden_min_batched, zoom_min_batched};
use std::sync::Arc;

/// How [`search_nonlinear`] searches, besides its schedule.
#[derive(Debug, Clone, Copy)]
pub(super) struct SearchMode {
    /// Whether each searched parameter's standard error is computed (three full solves).
    pub(super) se: bool,
    /// Whether a whole-interval search refines its grid's best cell by [`zoom_min_batched`]
    /// (to [`WARM_TOLERANCE`] of the interval) instead of golden section.
    pub(super) zoom: bool,
}

/// What the searches of the nonlinear parameters found besides the terms' values.
pub(super) struct NonlinearFit {
    /// Evaluations of the RSS, for the fit report.
    pub(super) evaluations: usize,
    /// Whether no searched parameter ended at the edge of its search interval.
    pub(super) converged: bool,
    /// Per term, the standard error of its searched parameter.
    pub(super) se: Vec<Option<f64>>,
}

/// Variable projection over the nonlinear parameters of `terms` (coordinate-wise if several:
/// two cycles), each term replaced by its version at the value found; `measured` rows, `p`
/// design columns. With `mode.se`, each searched parameter's standard error (three full
/// solves); without, `None` (and the edge of the interval alone says whether the search
/// converged). With `mode.zoom`, a whole-interval search refines its grid's best cell by
/// [`zoom_min_batched`] to [`WARM_TOLERANCE`] of the interval instead of by golden section.
///
/// `warm` holds values found before for terms of the same name (a verification's refits: the
/// values the refit of the model as it is found on the same fold). Where any term has one, the search is warm-started
/// ([`warm_schedule`]): the terms without one are searched as a cold search searches them,
/// once, the others held at their warm values; then every term is searched near its value
/// ([`local_search`], to [`WARM_TOLERANCE`] of its interval). With `warm` empty (every `fit`)
/// the search is the cold one, unchanged.
pub(super) fn search_nonlinear(
    terms: &mut [Arc<dyn Term>],
    data: &FitData<'_>,
    opts: &CheckedFitOptions,
    (measured, p): (usize, usize),
    mode: SearchMode,
    warm: &[(String, f64)],
) -> NonlinearFit {
    let nl_terms: Vec<usize> = (0..terms.len())
        .filter(|&k| terms[k].nonlinear().is_some())
        .collect();
    let mut evaluations = 0;
    let mut converged = true;
    let mut nl_se: Vec<Option<f64>> = vec![None; terms.len()];
    let schedule = match warm_schedule(terms, &nl_terms, warm) {
        Some(s) => s,
        None => {
            let cycles = if nl_terms.len() > 1 { 2 } else { 1 };
            (0..cycles)
                .flat_map(|_| nl_terms.iter().map(|&k| (k, Reach::Whole)))
                .collect()
        }
    };
    let mut moved = Moves::new(terms.len());
    for (k, reach) in schedule {
        let Some(nl) = terms[k].nonlinear() else {
            continue;
        };
        // A term that searches its own parameters (`Term::search`: `bump`'s centre and
        // width) does so here; its standard errors are its own.
        let dof = measured.saturating_sub(p + 1).max(1);
        if reach == Reach::Whole
            && let Some(found) = own_search(terms, k, data, opts, dof)
        {
            evaluations += found.evaluations;
            converged &= found.converged;
            terms[k] = found.term;
            moved.searched(k, f64::NAN);
            continue;
        }
        if reach == Reach::Near && moved.settled(k) {
            continue;
        }
        let (t, rss, ev) = search_term(terms, k, &nl, (reach, mode.zoom), data, opts);
        moved.searched(k, rss);
        evaluations += ev;
        let span = nl.hi - nl.lo;
        converged &= t > nl.lo + 1e-3 * span && t < nl.hi - 1e-3 * span;
        if mode.se {
            let rss_at = |t: f64| slow_rss(terms, k, t, data, opts);
            let ft = rss_at(t);
            // Standard error from the curvature of the RSS: var(t) ≈ 2 s² / RSS''(t).
            let h = 1e-3 * span;
            let (fm, fp) = (rss_at(t - h), rss_at(t + h));
            evaluations += 2;
            let curv = (fp - 2.0 * ft + fm) / (h * h);
            let s2 = ft / (measured.saturating_sub(p + 1).max(1)) as f64;
            nl_se[k] = (curv > 0.0 && ft.is_finite()).then(|| (2.0 * s2 / curv).sqrt());
        }
        if let Some(term) = terms[k].with_nonlinear(t) {
            terms[k] = term;
        }
    }
    NonlinearFit {
        evaluations,
        converged,
        se: nl_se,
    }
}

/// One search of term `k`'s nonlinear parameter `nl` over its interval, by golden section
/// (with `zoom`: [`zoom_min_batched`]) after the grid, or near its value ([`local_search`]), on
/// the variable projection's RSS where the term allows it, else on full solves. Returns the
/// value, its RSS and the count of evaluations.
fn search_term(
    terms: &[Arc<dyn Term>],
    k: usize,
    nl: &crate::model::term::Nonlinear,
    (reach, zoom_whole): (Reach, bool),
    data: &FitData<'_>,
    opts: &CheckedFitOptions,
) -> (f64, f64, usize) {
    // The search compares RSS values from the variable projection (the standard error
    // differentiates the RSS twice, so it takes three full solves: `search_nonlinear`).
    // Used where the term allows it (`TermCaps::search_by_projection`: the `dahl` rate,
    // `memsum`'s length and a lag's τ, each search tested to end where the full solves'
    // does or at an RSS equal to 1e-12);
    // `stribeck`'s search keeps the full solve per candidate: its velocity-scale search
    // compares RSS values that differ by rounding only, and ends elsewhere within that
    // noise with the projection (its unit-invariance test, 1e-9 of the prediction, then
    // fails by 1.5×).
    let proj = terms[k]
        .caps()
        .search_by_projection
        .then(|| Projection::new(terms, k, data, opts))
        .flatten();
    // The RSS at a batch of values: the projected RSS is cheaper per value in batches (one
    // replay for several); the full solves take the values one by one.
    let rss_many = |ts: &[f64]| -> Vec<f64> {
        match &proj {
            Some(p) => p.rss_many(terms, ts, opts),
            None => ts
                .iter()
                .map(|&t| slow_rss(terms, k, t, data, opts))
                .collect(),
        }
    };
    // A batch at a time, following the RSS's parabola.
    let zoom_over = |lo: f64, hi: f64, grid: usize, width: f64| {
        zoom_min_batched(&rss_many, lo, hi, grid, LOCAL_GRID, width)
    };
    let zoom = |lo: f64, hi: f64, width: f64| zoom_over(lo, hi, LOCAL_GRID, width);
    // The whole interval: `opts.grid` points, then zooming (`zoom_whole`) or golden section,
    // in batches where the projection makes them cheap (the same points, compared in the
    // same order), else one value at a time (no speculative full solves).
    let whole = |lo: f64, hi: f64, grid: usize, iters: usize| {
        if zoom_whole {
            zoom_over(lo, hi, grid, WARM_TOLERANCE * (nl.hi - nl.lo))
        } else if proj.is_some() {
            golden_min_batched(&rss_many, lo, hi, grid, iters)
        } else {
            golden_min(
                &|t: f64| slow_rss(terms, k, t, data, opts),
                lo,
                hi,
                grid,
                iters,
            )
        }
    };
    match reach {
        Reach::Whole => whole(nl.lo, nl.hi, opts.grid, opts.refine),
        Reach::Near => local_search(nl, (opts.grid, opts.refine), &zoom, &whole),
    }
}

/// A warm-started search's improvement of the RSS below which a coordinate's next near search
/// is skipped ([`Moves`]), relative to the RSS: a coordinate search's next gain is about its
/// last one times the cycle's rate of convergence (below 1), so what is left unsearched is of the
/// order of 10⁻⁹ of the training RSS: the out-of-sample residuals then move by far less than the
/// 10⁻⁶ of the gain to which a verdict is compared (`benches/verdicts.py`).
const SETTLED: f64 = 1e-9;

/// The coordinate searches' bookkeeping of a warm-started [`search_nonlinear`]: per term, whether
/// any other term's search since its own last search lowered the RSS by more than [`SETTLED`]
/// (else its next near search would start where it is optimal and is skipped).
struct Moves {
    /// The RSS after the last search (NaN: not known, as after a term's own search).
    rss: f64,
    /// Per term: searched at least once.
    searched: Vec<bool>,
    /// Per term: another term's search since its own last one lowered the RSS by more than
    /// [`SETTLED`] of it (or by an amount not known).
    stirred: Vec<bool>,
}

impl Moves {
    fn new(n: usize) -> Self {
        Self {
            rss: f64::NAN,
            searched: vec![false; n],
            stirred: vec![false; n],
        }
    }

    /// Whether term `k` was searched before and nothing moved the RSS since.
    fn settled(&self, k: usize) -> bool {
        self.searched[k] && !self.stirred[k]
    }

    /// Term `k` was searched and the RSS is now `rss` (NaN: not known).
    fn searched(&mut self, k: usize, rss: f64) {
        let gain = self.rss - rss;
        // A gain not known (NaN) counts as a move.
        let settled = gain <= SETTLED * rss.abs();
        let moved = gain.is_nan() || !settled;
        for (j, s) in self.stirred.iter_mut().enumerate() {
            if j == k {
                *s = false;
            } else if moved {
                *s = true;
            }
        }
        self.searched[k] = true;
        self.rss = rss;
    }
}

/// How far a search of one term reaches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Reach {
    /// The whole search interval: the grid, then golden-section steps (the cold search), or the
    /// term's own search.
    Whole,
    /// Near the term's current value ([`local_search`]).
    Near,
}

/// The width, as a share of a term's search interval, to which [`local_search`] narrows its
/// bracket: the warm-started refits' search tolerance. (The cold search's 40 golden-section
/// steps narrow its bracket to about 4·10⁻¹⁰ of the interval.)
pub(crate) const WARM_TOLERANCE: f64 = 1e-7;

/// Points of [`local_search`]'s grid: one batch of the projection's replay
/// (`projection::SEARCH_BATCH`).
const LOCAL_GRID: usize = 8;

/// The warm-started schedule of [`search_nonlinear`] where some searched term has a warm value
/// (`warm`, by term name; values outside a term's interval are not taken): each such term is
/// set to its value; the terms without one (and the terms that search themselves, which take
/// no warm value) are searched over their whole interval, in order; then every term searched by
/// golden section is searched near its value (once; twice in turn where there are several).
/// `None` where no term has a warm value.
fn warm_schedule(
    terms: &mut [Arc<dyn Term>],
    nl_terms: &[usize],
    warm: &[(String, f64)],
) -> Option<Vec<(usize, Reach)>> {
    if warm.is_empty() {
        return None;
    }
    let mut started = vec![false; terms.len()];
    for &k in nl_terms {
        if terms[k].caps().searches_itself {
            continue;
        }
        let name = terms[k].name();
        let Some(&(_, v)) = warm.iter().find(|(n, _)| *n == name) else {
            continue;
        };
        let nl = terms[k].nonlinear()?;
        if !(nl.lo..=nl.hi).contains(&v) {
            continue;
        }
        if let Some(t) = terms[k].with_nonlinear(v) {
            terms[k] = t;
            started[k] = true;
        }
    }
    if !started.iter().any(|&s| s) {
        return None;
    }
    let own = |t: &Arc<dyn Term>| t.caps().searches_itself;
    let cold = nl_terms
        .iter()
        .filter(|&&k| !started[k])
        .map(|&k| (k, Reach::Whole));
    let near: Vec<usize> = nl_terms
        .iter()
        .copied()
        .filter(|&k| !own(&terms[k]))
        .collect();
    // Coupled parameters move each other: two cycles where several are searched near, as the
    // cold search takes two over the whole intervals.
    let cycles = if near.len() > 1 { 2 } else { 1 };
    let near = (0..cycles).flat_map(|_| near.iter().map(|&k| (k, Reach::Near)));
    Some(cold.chain(near).collect())
}

/// A term's search near its current value `nl.value`: [`LOCAL_GRID`] points over the two cells
/// either side of it of the cold search's grid (`grid` points over the interval), then batches
/// of as many points that follow the RSS's parabola until the bracket about the best point is
/// [`WARM_TOLERANCE`] of the interval wide (`zoom(lo, hi, width)`: [`zoom_min_batched`]). Where
/// the best value is at the edge of the first grid's bracket (the minimum lies beyond it) the
/// whole interval is searched as a whole-interval search of the same fit searches it (`grid`
/// points, then `refine` golden-section steps or zooming: `min(lo, hi, grid, iters)`). Returns
/// the value, its RSS and the count of evaluations.
fn local_search(
    nl: &crate::model::term::Nonlinear,
    (grid, refine): (usize, usize),
    zoom: &dyn Fn(f64, f64, f64) -> (f64, f64, usize),
    min: &dyn Fn(f64, f64, usize, usize) -> (f64, f64, usize),
) -> (f64, f64, usize) {
    let span = nl.hi - nl.lo;
    let reach = 2.0 * span / (grid.max(3) - 1) as f64;
    let (lo, hi) = ((nl.value - reach).max(nl.lo), (nl.value + reach).min(nl.hi));
    let cell = (hi - lo) / (LOCAL_GRID - 1) as f64;
    let (t, f, ev) = zoom(lo, hi, WARM_TOLERANCE * span);
    let at_edge = (t - lo < cell && lo > nl.lo) || (hi - t < cell && hi < nl.hi);
    if !at_edge || span.is_nan() || span <= 0.0 {
        return (t, f, ev);
    }
    let (t, f, more) = min(nl.lo, nl.hi, grid, refine);
    (t, f, ev + more)
}

/// Term `k`'s own search ([`Term::search`]), if it has one: the residual of the other terms
/// and the projection are built only when the term asks for them.
fn own_search(
    terms: &[Arc<dyn Term>],
    k: usize,
    data: &FitData<'_>,
    opts: &CheckedFitOptions,
    dof: usize,
) -> Option<crate::model::term::Searched> {
    use std::cell::OnceCell;
    let proj: OnceCell<Option<Projection<'_, '_>>> = OnceCell::new();
    let projection = || {
        proj.get_or_init(|| {
            terms[k]
                .caps()
                .search_by_projection
                .then(|| Projection::new(terms, k, data, opts))
                .flatten()
        })
    };
    let rest: OnceCell<Vec<f64>> = OnceCell::new();
    let residual = || -> &[f64] {
        rest.get_or_init(|| match projection() {
            // The projection's response is already the residual on the other terms.
            Some(p) => p.y.clone(),
            None => rest_residual(terms, k, data, opts),
        })
    };
    let rss = |term: &Arc<dyn Term>| match projection() {
        Some(p) => p
            .fast_rss_of(term)
            .unwrap_or_else(|| slow_rss_of(terms, k, term, data, opts)),
        None => slow_rss_of(terms, k, term, data, opts),
    };
    let ctx = crate::model::term::SearchContext::new(data, &residual, &rss, dof);
    terms[k].search(&ctx)
}

/// Per measured row, the bias minus the least-squares fit of every term but `k` (the bias
/// itself where that fit fails).
fn rest_residual(
    terms: &[Arc<dyn Term>],
    k: usize,
    data: &FitData<'_>,
    opts: &CheckedFitOptions,
) -> Vec<f64> {
    let fixed: Vec<Arc<dyn Term>> = terms
        .iter()
        .enumerate()
        .filter(|&(j, _)| j != k)
        .map(|(_, t)| t.clone())
        .collect();
    let coef = solve(&fixed, data, opts).map(|s| s.coef).ok();
    let mut out = Vec::new();
    let pass = design_pass(&fixed, data, |x, y| {
        let fit = coef
            .as_ref()
            .map_or(0.0, |c| x.iter().zip(c).map(|(a, b)| a * b).sum::<f64>());
        out.push(y - fit);
    });
    if pass.is_err() {
        out.clear();
        // No terms: nothing can fail to start.
        let _ = design_pass(&[], data, |_, y| out.push(y));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::FitOptions;
    use crate::fit::design::offsets;
    use crate::log::Log;
    use crate::model::ModelSpec;
    use crate::numeric::rng::SimRng;

    /// `fit`'s search: golden section over whole intervals, no standard errors.
    const COLD: SearchMode = SearchMode {
        se: false,
        zoom: false,
    };
    /// A verification refit's: whole intervals refined by zooming.
    const ZOOMED: SearchMode = SearchMode {
        se: false,
        zoom: true,
    };

    /// Reference: the rule written out. A term is skipped only when it was searched before and
    /// every search since lowered the RSS by at most 10⁻⁹ of it; a search whose RSS is not
    /// known (a term's own search) counts as a move.
    #[test]
    fn a_coordinate_is_skipped_only_when_nothing_moved_since_its_search() {
        let mut m = Moves::new(3);
        assert!(!m.settled(0) && !m.settled(1), "never searched");
        m.searched(0, 10.0);
        assert!(!m.settled(1), "1 was never searched");
        assert!(m.settled(0), "nothing searched since 0");
        m.searched(1, 9.0);
        assert!(!m.settled(0), "1 lowered the RSS by 10 %");
        m.searched(0, 9.0 - 1e-9);
        assert!(m.settled(1), "0 lowered it by 1.1e-10 of it");
        m.searched(1, 9.0 - 1e-9 - 1e-7);
        assert!(!m.settled(0), "1 lowered it by 1.1e-8 of it");
        m.searched(0, 9.0 - 2e-7);
        m.searched(2, f64::NAN);
        assert!(
            !m.settled(0) && !m.settled(1),
            "a search of unknown RSS moves the others"
        );
        m.searched(0, 8.0);
        m.searched(1, 8.0);
        assert!(m.settled(0), "an RSS unchanged is no move");
    }

    /// Reference: the cold search (`warm` empty) of the same terms on the same rows. A refit's
    /// search (whole intervals refined by [`zoom_min_batched`]), cold or warm, and `fit`'s, warm,
    /// must end alike. Started
    /// near the values it found (both 1 % or 3 % of the interval away) or one of them far (40 %:
    /// beyond the local bracket, so that search falls back to the whole interval), the warm-started
    /// search of `dahl`'s rate and `memsum`'s length ends at an RSS no larger (to 1e-9
    /// relative: each search stops at its own tolerance, and the two coupled parameters' cycles
    /// end apart by a few 10⁻⁷ of the RSS, either side) and at values within 10⁻³ of each
    /// interval. A local search that did not fall back from the
    /// bracket's edge would stop 40 % away.
    #[test]
    fn a_warm_started_search_ends_where_the_cold_search_ends() {
        let log = crate::sim::random_log(4000, 13);
        let opts = FitOptions::default().check().unwrap();
        let spec = ModelSpec::parse("poly2,direction,dahl,memsum").unwrap();
        let data = FitData::new(&log);
        let prepared = || -> Vec<Arc<dyn Term>> {
            spec.terms
                .iter()
                .map(|t| t.prepare(&data))
                .collect::<Result<_, _>>()
                .unwrap()
        };
        let (_, p) = offsets(&prepared());
        let shape = (log.measured_count(), p);
        let searched = |ts: &[Arc<dyn Term>]| -> Vec<(String, crate::model::term::Nonlinear)> {
            ts.iter()
                .filter_map(|t| Some((t.name(), t.nonlinear()?)))
                .collect()
        };
        let rss = |ts: &[Arc<dyn Term>]| solve(ts, &data, &opts).unwrap().rss;
        let mut cold = prepared();
        search_nonlinear(&mut cold, &data, &opts, shape, COLD, &[]);
        let found = searched(&cold);
        assert_eq!(found.len(), 2, "{found:?}");
        let want = rss(&cold);
        let shifted = [[0.01, 0.01], [-0.03, -0.03], [0.0, 0.4], [0.4, 0.0]];
        let cases = std::iter::once((ZOOMED, None)).chain(
            shifted
                .iter()
                .flat_map(|s| [(COLD, Some(*s)), (ZOOMED, Some(*s))]),
        );
        for (mode, shifts) in cases {
            let warm: Vec<(String, f64)> = found
                .iter()
                .zip(shifts.into_iter().flatten())
                .map(|((n, nl), shift)| {
                    let v = nl.value + shift * (nl.hi - nl.lo);
                    // Beyond an end: the same distance inside from the other side.
                    let v = if v > nl.hi {
                        nl.value - shift * (nl.hi - nl.lo)
                    } else {
                        v
                    };
                    (n.clone(), v.clamp(nl.lo, nl.hi))
                })
                .collect();
            let mut terms = prepared();
            search_nonlinear(&mut terms, &data, &opts, shape, mode, &warm);
            let got = rss(&terms);
            assert!(
                got <= want * (1.0 + 1e-9),
                "{mode:?}, shifts {shifts:?}: RSS {got} vs cold {want}"
            );
            for ((name, a), (_, b)) in found.iter().zip(searched(&terms)) {
                assert!(
                    (a.value - b.value).abs() <= 1e-3 * (a.hi - a.lo),
                    "{mode:?}, shifts {shifts:?}, {name}: {} vs cold {}",
                    b.value,
                    a.value
                );
            }
        }
    }

    /// `bump` searches its own centre and width (`Term::search`) on the RSS by variable
    /// projection. Reference: [`slow_rss_of`], a full solve per version. On a simulated log
    /// with a planted defect, the projected RSS of versions across the range equals the full
    /// solve's to 1e-9, and the whole search run on full solves ends at the same centre and
    /// width (or at an RSS equal to 1e-12).
    #[test]
    fn bump_search_by_projection_equals_full_solves() {
        use crate::model::term::SearchContext;
        let mut log = crate::sim::random_log(3000, 5);
        let [lo, hi] = crate::numeric::stats::range(log.tracks()).unwrap();
        let (c0, w0) = (lo + 0.37 * (hi - lo), (hi - lo) / 300.0);
        for i in 0..log.len() {
            if let Some(b) = log.bias(i) {
                let x = log.tracks()[i];
                log.set_bias(i, Some(b + 40.0 * (-0.5 * ((x - c0) / w0).powi(2)).exp()));
            }
        }
        let opts = FitOptions::default().check().unwrap();
        let spec = ModelSpec::parse("poly2,direction,bump").unwrap();
        let data = FitData::new(&log);
        let mut terms = spec
            .terms
            .iter()
            .map(|t| t.prepare(&data))
            .collect::<Result<Vec<_>, _>>()
            .unwrap();
        let k = terms.iter().position(|t| t.name() == "bump").unwrap();
        let proj = Projection::new(&terms, k, &data, &opts).expect("fast path applies");
        let mut rng = SimRng::new(5);
        for i in 0..30 {
            let c = if i < 10 {
                c0 + w0 * (rng.uniform() - 0.5)
            } else {
                lo + (hi - lo) * rng.uniform()
            };
            let version = terms[k].with_nonlinear(c).unwrap();
            let slow = slow_rss_of(&terms, k, &version, &data, &opts);
            let fast = proj.fast_rss_of(&version).expect("closed form");
            assert!(
                (fast - slow).abs() <= 1e-9 * slow,
                "centre {c}: {fast} vs {slow}"
            );
        }
        drop(proj);
        let measured = log.measured_count();
        let (_, p) = offsets(&terms);
        let dof = measured - p - 1;
        let found = own_search(&terms, k, &data, &opts, dof).expect("bump searches itself");
        let residual = rest_residual(&terms, k, &data, &opts);
        let residual_fn = || -> &[f64] { &residual };
        let rss = |t: &Arc<dyn Term>| slow_rss_of(&terms, k, t, &data, &opts);
        let ctx = SearchContext::new(&data, &residual_fn, &rss, dof);
        let reference = terms[k].search(&ctx).unwrap();
        let params = |t: &Arc<dyn Term>| {
            t.report(&[0.0], &[0.0], None)
                .into_iter()
                .skip(1)
                .map(|p| p.value)
                .collect::<Vec<_>>()
        };
        let (a, b) = (params(&found.term), params(&reference.term));
        let (fa, fb) = (
            slow_rss_of(&terms, k, &found.term, &data, &opts),
            slow_rss_of(&terms, k, &reference.term, &data, &opts),
        );
        assert!(
            a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits())
                || (fa - fb).abs() <= 1e-12 * fb,
            "projected {a:?} (RSS {fa}) vs full solves {b:?} (RSS {fb})"
        );
        assert!((a[0] - c0).abs() < 0.2 * w0, "centre {} vs {c0}", a[0]);
        terms[k] = found.term;
        assert!(solve(&terms, &data, &opts).is_ok());
    }

    /// `step` searches its own threshold (`Term::search`) on the RSS by variable projection.
    /// Reference: [`slow_rss_of`], a full solve per version. On a simulated log with a logged
    /// covariate and a planted step in it, the projected RSS at thresholds across the column
    /// equals the full solve's to 1e-9, and the whole search run on full solves ends at the
    /// same threshold (or at an RSS equal to 1e-12), the planted one.
    #[test]
    fn step_search_by_projection_equals_full_solves() {
        use crate::model::term::SearchContext;
        let mut rng = SimRng::new(11);
        let mut text = String::from("time_s,track,bias,load\n");
        let (mut x, mut load) = (200.0f64, 0.0f64);
        for k in 0..3000 {
            x = (x + (rng.uniform() - 0.5) * 160.0)
                .round()
                .clamp(0.0, 400.0);
            load = 0.95 * load + 0.3 * rng.normal();
            let load = (load * 1000.0).round() / 1000.0;
            let d = if rng.uniform() < 0.5 { 1.0 } else { -1.0 };
            let bias = 5.0 + 0.02 * x + 1.5 * d + if load > 0.4 { 2.0 } else { 0.0 } + rng.normal();
            text += &format!("{:?},{x:?},{bias:?},{load:?}\n", 0.2 * k as f64);
        }
        let log = Log::from_reader("step.csv", text.as_bytes(), &Default::default()).unwrap();
        let opts = FitOptions::default().check().unwrap();
        let spec = ModelSpec::parse("poly2,direction,step:load").unwrap();
        let data = FitData::new(&log);
        let mut terms = spec
            .terms
            .iter()
            .map(|t| t.prepare(&data))
            .collect::<Result<Vec<_>, _>>()
            .unwrap();
        let k = terms.iter().position(|t| t.name() == "step:load").unwrap();
        let proj = Projection::new(&terms, k, &data, &opts).expect("fast path applies");
        let nl = terms[k].nonlinear().unwrap();
        for i in 0..30 {
            let t = nl.lo + (nl.hi - nl.lo) * (f64::from(i) + rng.uniform()) / 30.0;
            let version = terms[k].with_nonlinear(t).unwrap();
            let slow = slow_rss_of(&terms, k, &version, &data, &opts);
            let fast = proj.fast_rss_of(&version).expect("closed form");
            assert!(
                (fast - slow).abs() <= 1e-9 * slow,
                "threshold {t}: {fast} vs {slow}"
            );
        }
        drop(proj);
        let measured = log.measured_count();
        let (_, p) = offsets(&terms);
        let dof = measured - p - 1;
        let found = own_search(&terms, k, &data, &opts, dof).expect("step searches itself");
        let residual = rest_residual(&terms, k, &data, &opts);
        let residual_fn = || -> &[f64] { &residual };
        let rss = |t: &Arc<dyn Term>| slow_rss_of(&terms, k, t, &data, &opts);
        let ctx = SearchContext::new(&data, &residual_fn, &rss, dof);
        let reference = terms[k].search(&ctx).unwrap();
        let threshold = |t: &Arc<dyn Term>| t.nonlinear().unwrap().value;
        let (a, b) = (threshold(&found.term), threshold(&reference.term));
        let (fa, fb) = (
            slow_rss_of(&terms, k, &found.term, &data, &opts),
            slow_rss_of(&terms, k, &reference.term, &data, &opts),
        );
        assert!(
            a.to_bits() == b.to_bits() || (fa - fb).abs() <= 1e-12 * fb,
            "projected {a} (RSS {fa}) vs full solves {b} (RSS {fb})"
        );
        assert!((a - 0.4).abs() < 0.02, "threshold {a} vs 0.4");
        terms[k] = found.term;
        assert!(solve(&terms, &data, &opts).is_ok());
    }
}
