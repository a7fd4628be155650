//! The [`Term`] trait: one physical effect's contribution to the predicted bias.
//!
//! A model is a sum of terms. Each term is split in two types, linfa style:
//! - a [`TermSpec`]: the unfitted setting parsed from a string such as `seek` or `bins:dwell_s`;
//!   [`TermSpec::prepare`] looks at the training data once (to place knots, centre a column) and
//!   returns a
//! - [`Term`]: a term whose data-dependent settings are fixed. It has `n` **linear** parameters
//!   (fitted by the one least-squares solve of [`crate::fit`](mod@crate::fit)) and at most one
//!   **nonlinear** parameter (searched by variable projection). [`Term::start`] gives its per-log
//!   [`TermState`], which turns each seek into `n` basis values; the contribution is the dot
//!   product of the basis with the fitted coefficients, plus an optional causal offset.
//!
//! A term with a nonlinear parameter (a rate, a time constant) implements [`Term::nonlinear`]
//! (the current value and the search interval) and [`Term::with_nonlinear`] (the same term at
//! another value); [`crate::fit::fit`] searches it and the default [`Term::report`] reports it.
//! `examples/new_effect.rs` adds the time-at-track effect (P3) that way.
//!
//! Everything is object safe, so a user can add a physical effect outside the crate:
//!
//! ```
//! use std::sync::Arc;
//! use biasctl::{ModelError, ModelSpec, model::Seek, Term, TermSpec, model::TermState};
//! use biasctl::{FitData, FitError, FitOptions, fit};
//!
//! /// Bias proportional to the square of the seek length (a made-up effect), per track².
//! #[derive(Debug)]
//! struct SeekSquared;
//! impl TermSpec for SeekSquared {
//!     fn name(&self) -> String { "seek_squared".into() }
//!     fn prepare(&self, _data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> { Ok(Arc::new(SeekSquared)) }
//! }
//! impl Term for SeekSquared {
//!     fn name(&self) -> String { "seek_squared".into() }
//!     fn param_names(&self) -> Vec<String> { vec!["k".into()] }
//!     fn start(&self, _covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
//!         Ok(Box::new(SeekSquaredState))
//!     }
//! }
//! #[derive(Debug, Clone)]
//! struct SeekSquaredState;
//! impl TermState for SeekSquaredState {
//!     fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) { out[0] = seek.features.seek_length.powi(2); }
//!     fn update(&mut self, _seek: &Seek<'_>, _residual: Option<f64>) {}
//!     fn clone_box(&self) -> Box<dyn TermState> { Box::new(self.clone()) }
//! }
//!
//! // Fit `poly2` plus the user term on a small synthetic log: bias = 3 + 0.01·s².
//! let mut text = String::from("time_s,track,bias\n");
//! let tracks = [100.0, 130.0, 90.0, 150.0, 120.0, 80.0, 110.0, 140.0, 95.0, 125.0];
//! let mut prev = tracks[0];
//! for (i, t) in tracks.iter().enumerate() {
//!     let s: f64 = t - prev;
//!     text += &format!("{i},{t},{}\n", 3.0 + 0.01 * s * s);
//!     prev = *t;
//! }
//! let log = biasctl::Log::from_reader("x.csv", text.as_bytes(), &Default::default()).unwrap();
//! let spec = ModelSpec::parse("").unwrap().with_term(Arc::new(SeekSquared));
//! let model = fit(&spec, &log, &FitOptions::default().check().unwrap()).unwrap();
//! let k = model.param("seek_squared.k").unwrap();
//! assert!((k.value - 0.01).abs() < 1e-9);
//! ```

use crate::codegen::{CContext, CTerm};
use crate::history::Replay;
use crate::model::ModelError;
pub use crate::model::data::Seek;
use crate::model::data::{FitData, FitError};
use serde::{Deserialize, Serialize};
use std::fmt::Debug;
use std::sync::Arc;

/// A fitted parameter as reported in the model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Param {
    /// Full name, `term.param` (for example `poly2.c1`, `dahl.Fc`).
    pub name: String,
    /// Value, in the units the term documents (counts, counts per track, …).
    pub value: f64,
    /// Standard error; `None` where none is available (a setting chosen by search).
    pub se: Option<f64>,
}

/// A term's nonlinear parameter, searched by variable projection (1-D search, the linear
/// parameters refitted by least squares at every candidate).
#[derive(Debug, Clone, PartialEq)]
pub struct Nonlinear {
    /// Name (for messages and the search report).
    pub name: String,
    /// Current value, in the search coordinate.
    pub value: f64,
    /// Lower end of the search interval (search coordinate).
    pub lo: f64,
    /// Upper end of the search interval (search coordinate).
    pub hi: f64,
}

/// The unfitted setting of a term: what the user asked for, before any data was seen.
pub trait TermSpec: Debug + Send + Sync {
    /// The spec string (`poly2`, `bins:dwell_s`, …).
    fn name(&self) -> String;
    /// Fixes the data-dependent settings (knots, centring) from the training data.
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError>;
}

/// What a term can do, as the fit, the replay and the diagnosis read it: one value per term
/// ([`Term::caps`]) instead of a method per flag. A new term states only the flags it changes
/// from [`TermCaps::DEFAULT`] (`TermCaps { droppable: true, ..TermCaps::DEFAULT }`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TermCaps {
    /// Whether the basis spans a constant (then the model adds no separate intercept).
    pub provides_intercept: bool,
    /// Whether basis columns the data cannot determine may be fixed at 0 with a warning
    /// (hinge knots) instead of failing the fit.
    pub droppable: bool,
    /// Whether the term's contribution adapts to the measured bias while a log is replayed
    /// (its state uses the `residual` of [`TermState::update`], like `drift`): then its
    /// one-step error and its free-run error differ and both are reported.
    pub adaptive: bool,
    /// Whether the term's state reads nothing but the residuals: an [`TermCaps::adaptive`] term
    /// with no linear parameters whose [`TermState::offset`] and [`TermState::update`] read
    /// neither the seek features nor the covariates (`drift`). The fit then replays it over the
    /// rest of the model's stored predictions for its statistics instead of replaying the whole
    /// model over the log once more (the same arithmetic, tested).
    pub reads_only_residuals: bool,
    /// Whether the basis carries a constant inbound/outbound offset (a direction × constant
    /// column, as `direction` and `dahl` do); terms that need such a companion ask the other
    /// terms of the model through this in [`Term::fit_warnings`].
    pub spans_direction_offset: bool,
    /// Whether the solver may search this term's nonlinear parameter by variable projection:
    /// the rest of the model factored once, each candidate's RSS from sums over this term's own
    /// columns, instead of a full solve per candidate. Only for a search whose RSS curve stands
    /// clear of rounding near its minimum, tested to end where the full solves' search ends
    /// (`dahl`'s rate). Otherwise a full solve per candidate, as `stribeck`'s velocity scale
    /// keeps: its RSS values near the minimum differ by rounding only.
    pub search_by_projection: bool,
    /// Whether the term's state reads the seek history: any feature beyond those a log's times
    /// and positions give row by row (`seek_index`, `time_s`, `elapsed_s`, `dwell_s`, `source`,
    /// `target`, `seek_length`). A fit whose terms all answer `false` replays the log without
    /// the direction tracker and the rest memory (their features are then 0 / `None`, see
    /// [`crate::history::History`]), as the `dahl` rate search does once per candidate.
    pub reads_history: bool,
    /// Whether the term's basis holds its values over runs of consecutive rows (a relay's state
    /// changes only where the position crosses a threshold): the solve folds each run of rows
    /// equal in these columns into one mean row and contrast rows zero in them (an orthogonal
    /// transformation, `crate::numeric::runs`: the same least squares, factorised on fewer
    /// columns).
    pub piecewise_constant: bool,
    /// Whether the term searches its own nonlinear parameters ([`Term::search`]: `bump`'s
    /// centre and width, `step`'s threshold, `preisach`'s smoothing) instead of the fit's
    /// golden-section search of [`Term::nonlinear`]. A warm-started refit
    /// (`crate::fit::fit_sharing`'s `warm`) searches such a term as a cold fit does.
    pub searches_itself: bool,
}

impl TermCaps {
    /// The capabilities of a plain term: no intercept, no dropped columns, not adaptive, reads
    /// the seek history (the safe answer), searched by full solves.
    pub const DEFAULT: TermCaps = TermCaps {
        provides_intercept: false,
        droppable: false,
        adaptive: false,
        reads_only_residuals: false,
        spans_direction_offset: false,
        search_by_projection: false,
        reads_history: true,
        piecewise_constant: false,
        searches_itself: false,
    };
}

impl Default for TermCaps {
    fn default() -> Self {
        TermCaps::DEFAULT
    }
}

/// A term with its data-dependent settings fixed (see the module docs).
pub trait Term: Debug + Send + Sync {
    /// The spec string this term came from; also the name of its contribution column.
    fn name(&self) -> String;
    /// Names of the linear parameters (without the `term.` prefix); one per basis value.
    fn param_names(&self) -> Vec<String>;
    /// What the term can do (see [`TermCaps`]). Default: [`TermCaps::DEFAULT`].
    fn caps(&self) -> TermCaps {
        TermCaps::DEFAULT
    }
    /// Relative ridge penalty on this term's coefficients (default 0: plain least squares):
    /// each of its columns `j` adds `λ·‖x_j‖²·β_j²` to the least-squares objective, pulling
    /// the coefficient towards 0. Scale free (the same for any bias or position unit); for
    /// families of strongly collinear elements such as `play`.
    fn ridge(&self) -> f64 {
        0.0
    }
    /// Penalty rows on this term's own coefficients beyond [`Term::ridge`] (default none): each
    /// row `[(column, coefficient), …]` (the term's columns, from 0) adds
    /// `s·(Σ coefficient·β_column)²` to the least-squares objective, where `s` is the mean sum
    /// of squares of the term's columns over the data rows (scale free, as the ridge). For a
    /// surface of weights that must be smooth (`preisach:N`: differences of neighbouring cells,
    /// the strength folded into the coefficients).
    fn penalty(&self) -> Vec<Vec<(usize, f64)>> {
        Vec::new()
    }
    /// For a [`TermCaps::reads_only_residuals`] term that is exponential forgetting of the
    /// residuals (`drift`): its factor `alpha`, where its state's offset is a running `m`
    /// starting at 0 and its update with residual `e` is `m += alpha · e`. The fit then
    /// replays it in one plain loop ([`crate::fit`](mod@crate::fit)'s tail statistics; tested equal to the
    /// replay of its state). Default `None`.
    fn forgetting_factor(&self) -> Option<f64> {
        None
    }
    /// Number of linear parameters (basis values); the solver sizes the design by it.
    /// Default: the length of [`Term::param_names`].
    fn param_count(&self) -> usize {
        self.param_names().len()
    }
    /// Warnings about this term once fitted, given every term of the model (itself included):
    /// for example a hinge term left with no knots, or a missing companion term. The fit adds
    /// them to [`crate::model::FittedModel::warnings`] (each distinct text once). Default: none.
    fn fit_warnings(&self, _model: &[Arc<dyn Term>]) -> Vec<String> {
        Vec::new()
    }
    /// Covariate columns this term reads.
    fn covariates(&self) -> Vec<String> {
        Vec::new()
    }
    /// The per-log state; `covariates` are the names of the columns [`Seek::covariates`] will
    /// hold. Fails if a covariate the term needs is missing.
    fn start(&self, covariates: &[String]) -> Result<Box<dyn TermState>, ModelError>;
    /// The nonlinear parameter, if any.
    fn nonlinear(&self) -> Option<Nonlinear> {
        None
    }
    /// The same term with its nonlinear parameter set to `value` (search coordinate).
    fn with_nonlinear(&self, _value: f64) -> Option<Arc<dyn Term>> {
        None
    }
    /// The replay the search of the nonlinear parameter runs for every batch of candidate
    /// values ([`SearchBasis`]): this term's basis over `data`'s rows at several values at once,
    /// a block of rows at a time. Called once per search; the returned object may keep what it
    /// needs from `data` in a compact form. Default: `PerRowSearch`, the term at each value
    /// through [`Term::with_nonlinear`], [`Term::start`] and [`TermState::basis`]/`update` row
    /// by row (what a term needs to do nothing for). A term overrides it to produce its
    /// columns faster (`dahl`: its rate's candidates side by side, the sign and table index of
    /// each seek computed once per block for all of them); it must give the same values bit
    /// for bit.
    fn search_basis<'d>(&'d self, data: &'d FitData<'_>) -> Box<dyn SearchBasis + 'd> {
        Box::new(PerRowSearch { term: self, data })
    }
    /// A term that searches its own nonlinear parameters — more than one, or a landscape a
    /// grid of [`crate::FitOptions::grid`] points cannot cover (`bump`'s centre and width: the
    /// RSS only moves within a few widths of the defect) — returns the term at its best
    /// setting here, given the residual of the rest of the model and the exact RSS of the
    /// whole model at any version of the term ([`SearchContext`]). Called by the fit in place of
    /// its own 1-D search of [`Term::nonlinear`] (which such a term still reports, so the fit
    /// knows it has something to search); `None` (the default): the fit searches
    /// [`Term::nonlinear`] itself. The RSS comes by variable projection where
    /// [`TermCaps::search_by_projection`] allows it, else by a full solve per version.
    fn search(&self, _ctx: &SearchContext<'_>) -> Option<Searched> {
        None
    }
    /// For a term whose contribution is a causal function of past residuals (an offset, like
    /// `drift`): choose its setting from the residual series of the rest of the model
    /// (measured rows in log order). Returns the tuned term, or `None` if it has nothing to tune.
    fn tune_on_residuals(&self, _residuals: &[f64]) -> Option<Arc<dyn Term>> {
        None
    }
    /// The parameters to report, given the fitted coefficients, their covariance (row-major,
    /// `n × n`) and the standard error of the nonlinear parameter (search coordinate).
    /// Default: one parameter per coefficient, named by [`Term::param_names`], then the
    /// nonlinear parameter (if any) at its searched value, in the search coordinate, named
    /// `term.NAME` after [`Nonlinear::name`] (which may already carry the `term.` prefix).
    fn report(&self, coef: &[f64], cov: &[f64], nonlinear_se: Option<f64>) -> Vec<Param> {
        let n = coef.len();
        let term = self.name();
        let mut params: Vec<Param> = self
            .param_names()
            .into_iter()
            .zip(coef)
            .enumerate()
            .map(|(i, (name, &value))| Param {
                name: format!("{term}.{name}"),
                value,
                se: se_from_cov(cov, n, i),
            })
            .collect();
        if let Some(nl) = self.nonlinear() {
            let prefixed = nl
                .name
                .strip_prefix(term.as_str())
                .is_some_and(|r| r.starts_with('.'));
            params.push(Param {
                name: if prefixed {
                    nl.name
                } else {
                    format!("{term}.{}", nl.name)
                },
                value: nl.value,
                se: nonlinear_se,
            });
        }
        params
    }
    /// The data-dependent settings to save in the model file (knots, centre, rates).
    fn settings(&self) -> serde_json::Value {
        serde_json::Value::Null
    }
    /// The term as C code for the firmware export (`biasctl export c`, `crate::export`),
    /// written with the helpers of `crate::codegen` ([`CContext`](crate::export::CContext), [`CTerm`](crate::export::CTerm)); `None` (the
    /// default): not exportable (the export then refuses, naming the term). Each built-in term
    /// that can be exported implements it in its own file from its fitted settings.
    fn export_c(&self, _ctx: &CContext) -> Option<CTerm> {
        None
    }
}

/// A term's basis at several values of its nonlinear parameter over a log, for the search
/// ([`Term::search_basis`]).
pub trait SearchBasis {
    /// Replays the log once with the term at each of `values` (search coordinate, each one
    /// [`Term::with_nonlinear`] accepts) and hands `sink` the basis of every measured row, in
    /// log order, a block of consecutive measured rows at a time: `sink(block, rows)`, where
    /// `block[(j · values.len() + c) · w + b]` is basis value `b` (of `w`, the term's
    /// [`Term::param_count`]) at value `c` on the block's `j`-th measured row (`j < rows`). The
    /// values are what [`TermState::basis`] gives on that row after [`TermState::update`] on
    /// every row before it (bit for bit). `None` where the term refuses a value or cannot start.
    fn replay(&self, values: &[f64], sink: &mut dyn FnMut(&[f64], usize)) -> Option<()>;
    /// The value the term is actually set to at search coordinate `value`: two values with the
    /// same bits here give the same term, so the search evaluates only one of them (for
    /// example a coordinate the term rounds). Default: `value` itself.
    fn effective_value(&self, value: f64) -> f64 {
        value
    }
}

/// Measured rows per block [`PerRowSearch`] hands its sink.
const PER_ROW_BLOCK: usize = 256;

/// The default [`SearchBasis`]: the term at each value started once and replayed through
/// [`TermState::basis`] and [`TermState::update`], row by row (two dynamic calls per row and
/// value).
#[derive(Debug)]
pub(crate) struct PerRowSearch<'d, T: ?Sized> {
    /// The term whose nonlinear parameter is searched.
    pub(crate) term: &'d T,
    /// The training data.
    pub(crate) data: &'d FitData<'d>,
}

impl<T: Term + ?Sized> SearchBasis for PerRowSearch<'_, T> {
    fn replay(&self, values: &[f64], sink: &mut dyn FnMut(&[f64], usize)) -> Option<()> {
        let log = self.data.log();
        let mut states = Vec::with_capacity(values.len());
        for &v in values {
            states.push(
                self.term
                    .with_nonlinear(v)?
                    .start(&log.schema.covariates)
                    .ok()?,
            );
        }
        let w = self.term.param_count();
        let stride = values.len() * w;
        let mut block = vec![0.0; PER_ROW_BLOCK * stride];
        let mut rows = 0;
        let mut cov = Vec::new();
        for (_, row, f) in self.data.replay_reading(self.term.caps().reads_history) {
            let seek = Seek {
                features: &f,
                covariates: row.covariates.gather(&mut cov),
            };
            if row.bias.is_some() {
                let out = &mut block[rows * stride..(rows + 1) * stride];
                for (s, o) in states.iter().zip(out.chunks_exact_mut(w.max(1))) {
                    s.basis(&seek, o);
                }
                rows += 1;
                if rows == PER_ROW_BLOCK {
                    sink(&block, rows);
                    rows = 0;
                }
            }
            for s in &mut states {
                s.update(&seek, None);
            }
        }
        if rows > 0 {
            sink(&block[..rows * stride], rows);
        }
        Some(())
    }
}

/// What the fit gives a term that searches its own nonlinear parameters ([`Term::search`]).
/// Everything is computed on first use.
pub struct SearchContext<'a> {
    data: &'a FitData<'a>,
    residual: &'a dyn Fn() -> &'a [f64],
    rss: &'a dyn Fn(&Arc<dyn Term>) -> f64,
    dof: usize,
}

impl Debug for SearchContext<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SearchContext")
            .field("dof", &self.dof)
            .finish_non_exhaustive()
    }
}

impl<'a> SearchContext<'a> {
    /// The context of one search (built by the fit).
    pub(crate) fn new(
        data: &'a FitData<'a>,
        residual: &'a dyn Fn() -> &'a [f64],
        rss: &'a dyn Fn(&Arc<dyn Term>) -> f64,
        dof: usize,
    ) -> Self {
        Self {
            data,
            residual,
            rss,
            dof,
        }
    }

    /// The training data (log, seek features, measured rows).
    pub fn data(&self) -> &FitData<'a> {
        self.data
    }

    /// Per measured row, in log order: the measured bias minus the least-squares fit of the
    /// model's **other** terms (bias unit) — what this term may still explain. Its columns are
    /// not refitted beside this term's, so it is for locating a setting, not for the final RSS.
    pub fn residual(&self) -> &'a [f64] {
        (self.residual)()
    }

    /// The least-squares RSS of the whole model with this term replaced by `term` (every
    /// linear parameter refitted; bias unit squared); `∞` where it cannot be fitted.
    pub fn rss(&self, term: &Arc<dyn Term>) -> f64 {
        (self.rss)(term)
    }

    /// Degrees of freedom of the residual variance `s² = RSS / dof` (measured rows minus the
    /// linear parameters minus one, at least 1), for standard errors from the RSS curvature:
    /// `var(t) ≈ 2·s² / RSS''(t)`.
    pub fn dof(&self) -> usize {
        self.dof
    }
}

/// What [`Term::search`] found.
#[derive(Debug, Clone)]
pub struct Searched {
    /// The term at its best setting.
    pub term: Arc<dyn Term>,
    /// RSS evaluations spent (added to the fit report's count).
    pub evaluations: usize,
    /// Whether every searched parameter ended inside its interval (else the fit warns).
    pub converged: bool,
}

/// A term's state while a log is replayed.
pub trait TermState: Debug + Send {
    /// Writes the basis values of `seek` into `out` (length = number of linear parameters)
    /// WITHOUT changing the state; the seek is the next one after every seek passed to `update`.
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]);
    /// A contribution not scaled by any coefficient (a causal offset such as `drift`), counts.
    fn offset(&self, _seek: &Seek<'_>) -> f64 {
        0.0
    }
    /// Whether the state never changes and adds nothing: [`TermState::update`] leaves it as it
    /// is and [`TermState::offset`] is always 0, so the basis is a function of the seek alone
    /// (`poly2`, `direction`, `seek`, `memory`). The fit's hot replays then make neither call
    /// (the same values; the fit's bit-for-bit tests against `Predictor` hold them to it).
    /// Default `false`.
    fn constant(&self) -> bool {
        false
    }
    /// Whether [`TermState::basis`] at `seek` gives, bit for bit, the basis of the seek the state
    /// was last updated with (the previous row): then a replay that holds that row's basis may
    /// keep it instead of writing it again. `false` where it cannot tell (the default; and
    /// before the first update). Like `basis`, it does not change the state. Answered cheaply
    /// by `preisach` (its relay states change only where the position crosses a level of its
    /// grid), which the fit's replays ask.
    fn same_basis(&self, _seek: &Seek<'_>) -> bool {
        false
    }
    /// Advances the state past `seek`; `residual` is measured − predicted bias of the whole model
    /// for this row, `None` when the row was not measured (and always `None` during the
    /// least-squares passes, so the basis must not depend on residuals).
    fn update(&mut self, seek: &Seek<'_>, residual: Option<f64>);
    /// A boxed copy (so predictors can be cloned).
    fn clone_box(&self) -> Box<dyn TermState>;
}

impl Clone for Box<dyn TermState> {
    fn clone(&self) -> Self {
        self.clone_box()
    }
}

/// Standard error of coefficient `i` from a row-major `n × n` covariance; `None` if not finite.
pub(crate) fn se_from_cov(cov: &[f64], n: usize, i: usize) -> Option<f64> {
    cov.get(i * n + i)
        .map(|v| v.max(0.0).sqrt())
        .filter(|v| v.is_finite())
}

impl<'a> FitData<'a> {
    /// A replay for `terms`: without the direction tracker and rest memory
    /// ([`crate::history::History::step_light`]) when no term reads the history
    /// ([`TermCaps::reads_history`]).
    pub(crate) fn replay_for(&self, terms: &[Arc<dyn Term>]) -> Replay<'a> {
        self.replay_reading(terms.iter().any(|t| t.caps().reads_history))
    }
}
