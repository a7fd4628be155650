//! The design of a fit: per measured row, every term's basis values (its design row), from
//! one replay of the log ([`design_pass`]) or a block of rows at a time ([`FixedRows`], which
//! can say where its replay stands: [`ChunkStart`]); and which term a design column belongs to.

use crate::model::data::{FitData, FitError};
use crate::model::term::{Seek, Term};
use std::sync::Arc;

pub(super) fn offsets(terms: &[Arc<dyn Term>]) -> (Vec<usize>, usize) {
    let mut off = Vec::with_capacity(terms.len());
    let mut p = 0;
    for t in terms {
        off.push(p);
        p += t.param_count();
    }
    (off, p)
}

/// Replays the log and calls `visit(basis_row, y)` for each measured row.
pub(super) fn design_pass(
    terms: &[Arc<dyn Term>],
    data: &FitData<'_>,
    mut visit: impl FnMut(&[f64], f64),
) -> Result<(), FitError> {
    let covs = &data.log().schema.covariates;
    let mut states = terms
        .iter()
        .map(|t| t.start(covs))
        .collect::<Result<Vec<_>, _>>()?;
    let (off, p) = offsets(terms);
    let widths: Vec<usize> = terms.iter().map(|t| t.param_count()).collect();
    let mut buf = vec![0.0; p];
    let mut cov = Vec::new();
    for (_, row, f) in data.replay_for(terms) {
        let seek = Seek {
            features: &f,
            covariates: row.covariates.gather(&mut cov),
        };
        if let Some(y) = row.bias {
            for (k, s) in states.iter().enumerate() {
                s.basis(&seek, &mut buf[off[k]..off[k] + widths[k]]);
            }
            visit(&buf, y);
        }
        for s in &mut states {
            s.update(&seek, None);
        }
    }
    Ok(())
}

pub(super) fn param_label(terms: &[Arc<dyn Term>], col: usize) -> (String, bool) {
    let mut start = 0;
    for t in terms {
        let names = t.param_names();
        if col < start + names.len() {
            return (
                format!("{}.{}", t.name(), names[col - start]),
                t.caps().droppable,
            );
        }
        start += names.len();
    }
    (format!("column {col}"), false)
}

/// Per design column, in order: whether its term's columns may be dropped
/// ([`crate::model::term::TermCaps::droppable`]) and its term's ridge penalty ([`Term::ridge`]);
/// [`param_label`]'s flag for every column, in one pass over the terms.
pub(super) fn column_flags(terms: &[Arc<dyn Term>]) -> Vec<(bool, f64)> {
    let mut out = Vec::new();
    for t in terms {
        let flags = (t.caps().droppable, t.ridge());
        out.extend(std::iter::repeat_n(flags, t.param_names().len()));
    }
    out
}

/// Where one of [`solve`](super::solve::solve)'s chunks of measured rows begins in its replay: the
/// history and every term's state just before the chunk's first measured row (after the previous
/// chunk's last row was learnt from), so that the chunk's rows can be replayed on their own, in
/// parallel with the others
/// ([`static_predictions_chunked`](super::statistics::static_predictions_chunked)).
pub(super) struct ChunkStart<'a> {
    pub(super) replay: crate::history::Replay<'a>,
    pub(super) states: Vec<Box<dyn crate::model::term::TermState>>,
}

/// The measured rows of a design of `terms`, replayed a block at a time: the rows
/// [`design_pass`] visits, in the same order and with the same bits.
pub(super) struct FixedRows<'a> {
    replay: crate::history::Replay<'a>,
    states: Vec<Box<dyn crate::model::term::TermState>>,
    /// The states that are not [`TermState::constant`](crate::model::term::TermState::constant)
    /// (the only ones a row updates).
    moving: Vec<usize>,
    off: Vec<usize>,
    widths: Vec<usize>,
    /// Per state, whether its term is [`TermCaps::piecewise_constant`](crate::model::term::TermCaps::piecewise_constant):
    /// its basis is kept where [`TermState::same_basis`](crate::model::term::TermState::same_basis) says it holds.
    piecewise: Vec<bool>,
    buf: Vec<f64>,
    /// Whether `buf` holds the design row of the previous row replayed (it was measured).
    primed: bool,
    cov: Vec<f64>,
}

impl<'a> FixedRows<'a> {
    /// Starts the replay; fails where a term fails to start.
    pub(super) fn new(terms: &[Arc<dyn Term>], data: &FitData<'a>) -> Result<Self, FitError> {
        let covs = &data.log().schema.covariates;
        let states = terms
            .iter()
            .map(|t| t.start(covs))
            .collect::<Result<Vec<_>, _>>()?;
        let (off, p) = offsets(terms);
        Ok(Self {
            replay: data.replay_for(terms),
            moving: (0..states.len())
                .filter(|&k| !states[k].constant())
                .collect(),
            states,
            off,
            widths: terms.iter().map(|t| t.param_count()).collect(),
            piecewise: terms.iter().map(|t| t.caps().piecewise_constant).collect(),
            buf: vec![0.0; p],
            primed: false,
            cov: Vec::new(),
        })
    }

    /// Where the replay stands: the history and every term's state before the next row.
    pub(super) fn start(&self) -> ChunkStart<'a> {
        ChunkStart {
            replay: self.replay.clone(),
            states: self.states.iter().map(|s| s.clone_box()).collect(),
        }
    }

    /// Replays the next `rows` measured rows (fewer where the log ends), handing each one's
    /// design row (every column, in design order), its response and whether the columns of
    /// the piecewise-constant terms are those of the previous row handed on (bit for bit;
    /// `false` where not known) to `each`; every row, measured or not, updates the term
    /// states. Returns how many measured rows it handed on. The one replay loop behind
    /// [`FixedRows::each_ordered`] and [`FixedRows::fill`].
    ///
    /// A piecewise-constant term whose state says the basis holds
    /// ([`TermState::same_basis`](crate::model::term::TermState::same_basis)) after a measured
    /// row keeps that row's values in the design row instead of writing them again.
    pub(super) fn measured_rows(
        &mut self,
        rows: usize,
        mut each: impl FnMut(&[f64], f64, bool),
    ) -> usize {
        let mut n = 0;
        while n < rows {
            let Some((_, row, f)) = self.replay.next() else {
                break;
            };
            let seek = Seek {
                features: &f,
                covariates: row.covariates.gather(&mut self.cov),
            };
            if let Some(y) = row.bias {
                let mut same = self.primed;
                for (k, s) in self.states.iter().enumerate() {
                    if self.piecewise[k] {
                        if self.primed && s.same_basis(&seek) {
                            continue;
                        }
                        same = false;
                    }
                    s.basis(
                        &seek,
                        &mut self.buf[self.off[k]..self.off[k] + self.widths[k]],
                    );
                }
                each(&self.buf, y, same);
                self.primed = true;
                n += 1;
            } else {
                self.primed = false;
            }
            for &k in &self.moving {
                self.states[k].update(&seek, None);
            }
        }
        n
    }

    /// Replays the next `rows` measured rows (fewer where the log ends), handing each one's
    /// design columns in the order `order` (in the scratch `xp`), its response and the flag of
    /// [`FixedRows::measured_rows`] (the piecewise-constant terms' columns unchanged) to `each`;
    /// adds each column value to `sums` and its square (and the response's) to `colsq`, by
    /// position in `order`, row by row. Returns how many rows it
    /// handed on.
    pub(super) fn each_ordered(
        &mut self,
        rows: usize,
        order: &[usize],
        sums: &mut [f64],
        colsq: &mut [f64],
        xp: &mut [f64],
        mut each: impl FnMut(&[f64], f64, bool),
    ) -> usize {
        let p = order.len();
        // In the terms' own order (no droppable column moved last): the rows as they are.
        let identity = order.iter().enumerate().all(|(q, &c)| q == c);
        self.measured_rows(rows, |buf, y, same| {
            let x: &[f64] = if identity {
                &buf[..p]
            } else {
                for (x, &c) in xp.iter_mut().zip(order) {
                    *x = buf[c];
                }
                xp
            };
            // By position: one pass the compiler vectorises.
            for ((&v, s), sq) in x.iter().zip(sums.iter_mut()).zip(colsq.iter_mut()) {
                *s += v;
                *sq += v * v;
            }
            colsq[p] += y * y;
            each(x, y, same);
        })
    }

    /// Appends the next `rows` measured rows (fewer where the log ends) to `out`, row-major;
    /// returns how many it appended.
    pub(super) fn fill(&mut self, out: &mut Vec<f64>, rows: usize) -> usize {
        self.measured_rows(rows, |buf, _, _| out.extend_from_slice(buf))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ModelSpec;
    use crate::model::terms::intercept::InterceptTerm;

    /// Reference: the full replay (the features every term saw before). A term that says it
    /// does not read the history ([`TermCaps::reads_history`]) must give the same basis, bit for
    /// bit, over the light replay; and the flag matters: `direction` and `memory` do read it.
    #[test]
    fn terms_without_history_give_the_same_basis_from_a_light_replay() {
        let mut log = crate::sim::random_log(3000, 5);
        for x in log.tracks_mut() {
            *x *= 0.37;
        }
        let data = FitData::new(&log);
        let spec =
            ModelSpec::parse("poly2,table,dahl,dahl:4,play:8,bump,direction,memory").unwrap();
        let mut terms: Vec<Arc<dyn Term>> = spec
            .terms
            .iter()
            .map(|t| t.prepare(&data).unwrap())
            .collect();
        terms.push(Arc::new(InterceptTerm));
        let reads: Vec<bool> = terms.iter().map(|t| t.caps().reads_history).collect();
        assert_eq!(
            reads,
            [false, false, false, false, false, false, true, true, false]
        );
        for t in terms.iter().filter(|t| !t.caps().reads_history) {
            let one = std::slice::from_ref(t);
            let basis = |light: bool| {
                let mut out = Vec::new();
                let replay = if light {
                    data.replay_for(one)
                } else {
                    data.replay()
                };
                let mut st = t.start(&[]).unwrap();
                let mut b = vec![0.0; t.param_count()];
                for (_, _, f) in replay {
                    let seek = Seek {
                        features: &f,
                        covariates: &[],
                    };
                    st.basis(&seek, &mut b);
                    out.extend(b.iter().map(|v| v.to_bits()));
                    st.update(&seek, None);
                }
                out
            };
            assert_eq!(basis(true), basis(false), "{}", t.name());
        }
    }
}
