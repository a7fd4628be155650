//! `preisach:N`: the discrete Preisach model of rate-independent hysteresis with reversal
//! memory — N(N+1)/2 relay hysterons on a triangular grid over the travel the training log
//! visits, the bias a weighted sum of their states.
//!
//! Relay `(i, j)` (`j ≤ i < N`) is +1 after the position last reached `α_i` (from below) and −1
//! after it last reached `β_j ≤ α_i` (from above): the grid of thresholds, the memory
//! staircase that holds the states in O(reversals remembered) and the Everett-table predictor
//! are in [`memory`]. The term's basis is the state (±1) of every relay the log switches; its
//! weights are linear, fitted in the one least-squares solve with the other terms, under a
//! smoothness penalty on the weight density (neighbouring cells, [`cv::smoothness_rows`]) whose
//! strength λ is chosen by cross-validation on folds of consecutive rows ([`cv`], run as the
//! term's own search, reported as `log10_lambda` and stored). A relay the log never switches
//! (its cell of the (α, β) plane is never visited: the travel never reverses across it) has a
//! constant state, which the intercept cannot be told from: it gets no column, the fit warns
//! naming how many, and the model file lists the relays it kept.
//!
//! Special cases: a weight density on the diagonal band `α − β = 2r` is a play operator of
//! threshold r (`play:N` is Preisach with the weights on N bands, tested); `dahl:N` a smooth
//! version of the same.

pub mod cv;
pub mod memory;

use crate::codegen::{CContext, CTerm};
use crate::model::ModelError;
use crate::model::data::{FitData, FitError};
use crate::model::term::{
    Nonlinear, SearchContext, Searched, Seek, Term, TermCaps, TermSpec, TermState,
};
use memory::{MAX_LEVELS, PreisachGrid, PreisachMemory};
use serde::{Deserialize, Serialize};
use std::cell::Cell;
use std::sync::Arc;

/// Default N of `preisach`.
pub const DEFAULT_LEVELS: usize = 8;

/// log₁₀ λ before the cross-validation has chosen it (a term built by hand).
pub const DEFAULT_LOG10_LAMBDA: f64 = -2.0;

/// Spec of the `preisach:N` term.
#[derive(Debug, Clone, Copy)]
pub struct PreisachSpec {
    /// N: α-lines and β-columns of the grid.
    pub levels: usize,
}

impl TermSpec for PreisachSpec {
    fn name(&self) -> String {
        format!("{HEAD}:{}", self.levels)
    }
    fn prepare(&self, data: &FitData<'_>) -> Result<Arc<dyn Term>, FitError> {
        let bad = |why: String| FitError::BadSetting {
            term: self.name(),
            why,
        };
        let [lo, hi] = crate::numeric::stats::range(data.log().tracks())
            .ok_or_else(|| bad("the log has no finite position".into()))?;
        let grid = PreisachGrid {
            lo,
            hi,
            levels: self.levels,
        };
        if !grid.is_valid() {
            return Err(bad(format!(
                "the log's positions span [{lo}, {hi}]; the relay grid needs two distinct positions"
            )));
        }
        let keep = cv::identified(data, &grid);
        let cells: Vec<(u8, u8)> = grid
            .relays()
            .filter(|&(i, j)| keep[PreisachGrid::cell(i as usize, j as usize)])
            .collect();
        if cells.is_empty() {
            return Err(bad(
                "no relay of the grid switches on this log (it never reverses across a grid cell)"
                    .into(),
            ));
        }
        Ok(Arc::new(PreisachTerm {
            name: self.name(),
            grid,
            cells,
            log10_lambda: DEFAULT_LOG10_LAMBDA,
        }))
    }
}

/// The fitted `preisach:N` term.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PreisachTerm {
    /// Spec string.
    pub name: String,
    /// The relay grid (the training log's position range, N).
    pub grid: PreisachGrid,
    /// The relays `(i, j)` with a weight, in column order: those the training log switches.
    pub cells: Vec<(u8, u8)>,
    /// log₁₀ of the smoothness penalty's strength, chosen by cross-validation.
    pub log10_lambda: f64,
}

impl PreisachTerm {
    /// Relays of the grid the model leaves out (never switched on the training log).
    pub fn unidentified(&self) -> usize {
        self.grid.cells().saturating_sub(self.cells.len())
    }

    /// Every relay's weight (triangle order, [`PreisachGrid::cell`]) from the fitted
    /// coefficients (one per kept relay); 0 for the relays left out.
    pub fn weights(&self, coef: &[f64]) -> Vec<f64> {
        let mut mu = vec![0.0; self.grid.cells()];
        for (&(i, j), &c) in self.cells.iter().zip(coef) {
            mu[PreisachGrid::cell(i as usize, j as usize)] = c;
        }
        mu
    }

    fn check(&self) -> Result<(), ModelError> {
        let n = self.grid.levels;
        if !self.grid.is_valid() || self.cells.iter().any(|&(i, j)| j > i || i as usize >= n) {
            return Err(ModelError::BadTerm {
                term: self.name.clone(),
                why: format!(
                    "the grid needs finite lo < hi, N from 1 to {MAX_LEVELS} and relays (i, j) with j ≤ i < N"
                ),
            });
        }
        Ok(())
    }
}

impl Term for PreisachTerm {
    fn caps(&self) -> TermCaps {
        TermCaps {
            // Its state reads `target` only.
            reads_history: false,
            // Relay states change only where the position crosses a threshold.
            piecewise_constant: true,
            searches_itself: true,
            ..TermCaps::DEFAULT
        }
    }
    fn name(&self) -> String {
        self.name.clone()
    }
    /// `w_iI_jJ`: the weight of relay (I, J), thresholds α = `grid.alpha(I)`, β = `grid.beta(J)`.
    fn param_names(&self) -> Vec<String> {
        self.cells
            .iter()
            .map(|&(i, j)| format!("w_i{i}_j{j}"))
            .collect()
    }
    fn fit_warnings(&self, _model: &[Arc<dyn Term>]) -> Vec<String> {
        let left = self.unidentified();
        if left == 0 {
            return Vec::new();
        }
        vec![format!(
            "{}: {left} of {} relays never switch on this log (their cells of the (α, β) plane are never visited: the travel never reverses across them); their weights cannot be identified and are left out of the model, and a log that switches them is predicted without them",
            self.name,
            self.grid.cells()
        )]
    }
    fn start(&self, _covariates: &[String]) -> Result<Box<dyn TermState>, ModelError> {
        self.check()?;
        Ok(Box::new(PreisachState {
            grid: self.grid,
            memory: PreisachMemory::new(self.grid.levels),
            lines: line_runs(&self.cells).into(),
            peeked: Cell::new(None),
            switched: None,
        }))
    }
    fn nonlinear(&self) -> Option<Nonlinear> {
        Some(Nonlinear {
            name: "log10_lambda".into(),
            value: self.log10_lambda,
            lo: -6.0,
            hi: 2.0,
        })
    }
    fn with_nonlinear(&self, value: f64) -> Option<Arc<dyn Term>> {
        value.is_finite().then(|| {
            Arc::new(Self {
                log10_lambda: value,
                ..self.clone()
            }) as Arc<dyn Term>
        })
    }
    /// λ by cross-validation on the residual of the rest of the model ([`cv::cross_validate`]),
    /// not by the RSS (which always prefers the least penalty).
    fn search(&self, ctx: &SearchContext<'_>) -> Option<Searched> {
        let t = cv::cross_validate(ctx.data(), &self.grid, &self.cells, ctx.residual());
        Some(Searched {
            term: self.with_nonlinear(t)?,
            evaluations: 0,
            converged: true,
        })
    }
    fn penalty(&self) -> Vec<Vec<(usize, f64)>> {
        let s = 10f64.powf(self.log10_lambda).sqrt();
        cv::smoothness_rows(&self.cells)
            .into_iter()
            .map(|r| r.into_iter().map(|(c, v)| (c, s * v)).collect())
            .collect()
    }
    fn settings(&self) -> serde_json::Value {
        serde_json::to_value(self).unwrap_or_default()
    }
    fn export_c(&self, _ctx: &CContext) -> Option<CTerm> {
        Some(export::c_term(self))
    }
}

mod export;

/// What `basis` peeked at: the position's bits, the memory after it and its `(U, D)`.
type Peeked = (u64, PreisachMemory, (u8, u8));

#[derive(Debug, Clone)]
struct PreisachState {
    grid: PreisachGrid,
    memory: PreisachMemory,
    /// The model's relays as runs of consecutive columns on one α-line ([`line_runs`]).
    lines: Arc<[LineRun]>,
    /// The bits of the position `basis` last peeked at, the memory after it and its `(U, D)`:
    /// the fit calls `basis` then `update` with the same seek, and the update takes them.
    peeked: Cell<Option<Peeked>>,
    /// `(U, D)` of the input of the last update ([`PreisachGrid::switches`]; `None` before).
    switched: Option<(u8, u8)>,
}

impl TermState for PreisachState {
    fn basis(&self, seek: &Seek<'_>, out: &mut [f64]) {
        let x = seek.features.target;
        let mut m = self.memory;
        let switched = m.step_switching(&self.grid, x);
        let mut b = [0u8; MAX_LEVELS];
        m.boundary(&mut b[..self.grid.levels]);
        // Relay (i, j) is up (+1) iff j < B(i): on a run of relays j0, j0 + 1, … of line i,
        // the first B(i) − j0 are up.
        for r in self.lines.iter() {
            let (start, len) = (r.start as usize, r.len as usize);
            let up = (b[r.i as usize] as usize)
                .saturating_sub(r.j0 as usize)
                .min(len);
            out[start..start + up].fill(1.0);
            out[start + up..start + len].fill(-1.0);
        }
        self.peeked.set(Some((x.to_bits(), m, switched)));
    }
    /// The same basis where the input switches what the last one switched (the same `(U, D)`:
    /// it crossed no level of the grid since): a step is idempotent — the last one already
    /// switched every relay this one would, up the α-lines below `U`, then down the β-columns
    /// from `D` (tested against every relay updated every step).
    fn same_basis(&self, seek: &Seek<'_>) -> bool {
        self.switched == Some(self.grid.switches(seek.features.target))
    }
    fn update(&mut self, seek: &Seek<'_>, _residual: Option<f64>) {
        let x = seek.features.target;
        let switched = match self.peeked.take() {
            Some((bits, m, switched)) if bits == x.to_bits() => {
                self.memory = m;
                switched
            }
            _ => self.memory.step_switching(&self.grid, x),
        };
        self.switched = Some(switched);
    }
    fn clone_box(&self) -> Box<dyn TermState> {
        Box::new(self.clone())
    }
}

/// Relays `(i, j0)`, `(i, j0 + 1)`, … of one α-line in consecutive columns from `start`.
#[derive(Debug, Clone, Copy)]
struct LineRun {
    i: u8,
    j0: u8,
    start: u16,
    len: u16,
}

/// The columns `cells` (`(i, j)` of each) as maximal runs of one line and consecutive `j`.
fn line_runs(cells: &[(u8, u8)]) -> Vec<LineRun> {
    let mut runs: Vec<LineRun> = Vec::new();
    for (c, &(i, j)) in cells.iter().enumerate() {
        match runs.last_mut() {
            Some(r) if r.i == i && usize::from(r.j0) + usize::from(r.len) == usize::from(j) => {
                r.len += 1
            }
            _ => runs.push(LineRun {
                i,
                j0: j,
                start: c as u16,
                len: 1,
            }),
        }
    }
    runs
}

/// Parses `preisach` / `preisach:N` (N from 1 to [`MAX_LEVELS`]; default [`DEFAULT_LEVELS`]).
pub(crate) fn parse(
    t: &crate::model::term_text::TermText<'_>,
) -> Result<Arc<dyn TermSpec>, crate::model::SpecError> {
    Ok(Arc::new(PreisachSpec {
        levels: t
            .arg
            .map(|a| t.count(a, "the number of Preisach levels", MAX_LEVELS))
            .transpose()?
            .unwrap_or(DEFAULT_LEVELS),
    }))
}

/// The head of the term's spec text.
pub(crate) const HEAD: &str = "preisach";

#[cfg(test)]
mod tests;
