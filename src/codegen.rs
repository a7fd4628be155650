//! Code generation for the firmware export: the C text a term describes itself with
//! ([`CTerm`]), the numbers and history features it may use ([`CContext`]) and the small C
//! snippets several terms share. Knows nothing of models or terms; `crate::export` assembles
//! the pieces into files.
//!
//! ## Placeholders
//! In a [`CTerm`]'s text, `$S` is the term's state member (a struct with the fields of
//! [`CTerm::state`]), `$K` a prefix unique to the term for its constants, `$X0`, `$X1`, … the
//! term's covariates (in the order of the term's covariate list); `f` is
//! `const bias_model_features *` (the seek's history features), `b` the basis output
//! (`bias_real b[n]`); in [`CTerm::update`], `measured` (int) and `resid` (`bias_real`, the row's
//! measured − predicted bias when `measured`).

/// Floating-point type of the exported code.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[non_exhaustive]
pub enum CPrecision {
    /// `double` (IEEE binary64): agrees with the Rust predictor to rounding.
    #[default]
    Float64,
    /// `float` (IEEE binary32) for targets without double precision; every constant and every
    /// operation is single precision (see README for the measured error).
    Float32,
}

/// A term as C code (see the module docs for the placeholders).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct CTerm {
    /// Member declarations of the term's state, e.g. `bias_real g[4];` (empty: stateless).
    pub state: String,
    /// File-scope constant declarations (`static const …`), named with the prefix `$K`.
    pub constants: String,
    /// Statements that set the state `$S` at the start of a log.
    pub init: String,
    /// Statements that write the term's basis values into `b[0 ..n)` (every one of them) from
    /// `f`, the covariates `$X…` and the state `$S` (read only).
    pub basis: String,
    /// An expression for the causal offset (bias units) added to the term's contribution, or
    /// empty for none.
    pub offset: String,
    /// Statements that advance the state `$S` past the seek (`f`, `$X…`, `measured`, `resid`).
    pub update: String,
}

/// What the term's C code may use from the generator: number formatting in the exported
/// precision and the history features by name.
#[derive(Debug, Clone, Copy)]
pub struct CContext {
    precision: CPrecision,
}

impl CContext {
    /// A context for `precision`.
    pub fn new(precision: CPrecision) -> Self {
        Self { precision }
    }

    /// A C literal of `x` in the exported precision that reads back exactly (`(-1.5e0)`,
    /// `2.5e-1f`; `INFINITY` for +∞).
    pub fn real(&self, x: f64) -> String {
        if x.is_infinite() {
            return if x > 0.0 { "INFINITY" } else { "(-INFINITY)" }.into();
        }
        let text = match self.precision {
            CPrecision::Float64 => format!("{x:e}"),
            CPrecision::Float32 => format!("{:e}f", x as f32),
        };
        // Always a floating literal: `1e0`, never `1`.
        if text.starts_with('-') {
            format!("({text})")
        } else {
            text
        }
    }

    /// A brace-enclosed initialiser of `values` (`{1e0, 2e0}`); `{0}` when empty.
    pub fn array(&self, values: &[f64]) -> String {
        if values.is_empty() {
            return "{0}".into();
        }
        let items: Vec<String> = values.iter().map(|&v| self.real(v)).collect();
        format!("{{{}}}", items.join(", "))
    }

    /// The C expressions `(defined, value)` of the history feature called `name`
    /// ([`crate::history::Feature`]), for `f` of type `const bias_model_features *`.
    pub fn feature(&self, name: &str) -> Option<(&'static str, &'static str)> {
        use crate::history::Feature as F;
        Some(match F::from_name(name)? {
            F::Position => ("1", "f->target"),
            F::SeekLength => ("1", "f->seek_length"),
            F::SeekAbs => ("1", "fabs(f->seek_length)"),
            F::Direction => ("1", "(bias_real)f->direction"),
            F::DirectionChange => ("1", "(bias_real)f->direction_change"),
            F::SinceReversal => ("1", "f->since_reversal"),
            F::ReversalPosition => (
                "1",
                "(f->target - (bias_real)f->direction * f->since_reversal)",
            ),
            F::RestDistanceOd => ("f->has_rest_od", "f->rest_od"),
            F::RestDistanceId => ("f->has_rest_id", "f->rest_id"),
            F::DwellS => ("1", "f->dwell_s"),
            F::ElapsedS => ("1", "f->elapsed_s"),
            F::SeekIndex => ("1", "f->seek_index"),
        })
    }
}

/// `b[0 .. n) = 0`.
pub(crate) fn zero(n: usize) -> String {
    format!("{{ int i_; for (i_ = 0; i_ < {n}; i_++) b[i_] = 0; }}\n")
}

/// Hinge curves (one set of `knots` per curve): all zero, then for the curve `curve_expr` (C
/// int, < 0 for none) `max(k_j − a, 0)/k_last` with `a = a_expr`.
pub(crate) fn c_curve_hinges(
    ctx: &CContext,
    knots: &[f64],
    curves: usize,
    curve_expr: &str,
    a_expr: &str,
) -> CTerm {
    let k = knots.len();
    let scale = knots.last().copied().unwrap_or(1.0);
    let mut t = CTerm::default();
    if k > 0 {
        t.constants = format!(
            "static const bias_real $K_KNOTS[{k}] = {};\nstatic const bias_real $K_SCALE = {};\n",
            ctx.array(knots),
            ctx.real(scale)
        );
    }
    t.basis = zero(curves * k);
    if k > 0 {
        t.basis += &format!(
            "{{ int c_ = {curve_expr}; if (c_ >= 0) {{ bias_real a_ = {a_expr}; int j_; for (j_ = 0; j_ < {k}; j_++) {{ bias_real h_ = $K_KNOTS[j_] - a_; b[c_ * {k} + j_] = (h_ > 0 ? h_ : 0) / $K_SCALE; }} }} }}\n"
        );
    }
    t
}

/// The side of a direction: inbound 1, outbound 0, none −1.
pub(crate) const SIDE: &str = "(f->direction == 1 ? 1 : (f->direction == -1 ? 0 : -1))";
