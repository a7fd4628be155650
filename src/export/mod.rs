//! Firmware export: a fitted model as C99 source that predicts exactly what
//! [`crate::model::Predictor`] predicts (`biasctl export c`).
//!
//! [`c_source`] writes three files:
//! - `bias_model.h`: `bias_real` (`double`, or `float` with [`CPrecision::Float32`]), the state
//!   struct `bias_model_state` (history, each term's state; no allocation, no globals) and the
//!   functions `bias_model_init`, `bias_model_step` and `bias_model_peek`, with the meaning of
//!   [`crate::model::Predictor::new`], [`crate::model::Predictor::step`] and
//!   [`crate::model::Predictor::peek`]; with a handoff plant, also
//!   `bias_model_integrator_start` ([`crate::control::StartValues::integrator_start`]);
//! - `bias_model.c`: the coefficients, scalings and the handoff table as `static const` data,
//!   and the functions;
//! - `replay.c`: a program that reads a log in biasctl's format on stdin (`#` metadata lines,
//!   a header naming the model's columns, then rows; an empty or missing bias column means not
//!   measured) and prints one predicted value per row (and `,integrator_start` when the model
//!   was exported with a handoff plant; an empty cell where no start value settles).
//!
//! `cc -std=c99 -O2 DIR/*.c -lm` builds the replay program.
//!
//! ## How a term describes itself
//! Every term is written by [`crate::model::term::Term::export_c`], implemented in the term's
//! own file, which returns a [`CTerm`]: C text with placeholders the generator fills in (see
//! [`crate::codegen`](mod@crate::codegen)). A term that does not describe itself is refused
//! with [`ExportError::NotExportable`] naming it.

pub use crate::codegen::{CContext, CPrecision, CTerm};
use crate::model::FittedModel;
use crate::model::predictor::REST_CAPACITY;
use crate::render::{OutputError, StagedDir, write_string_atomic};
use std::fmt::Write as _;
use std::path::Path;

/// The handoff table to export with the model ([`crate::control::StartValues`]).
#[derive(Debug, Clone, Copy)]
pub struct CHandoff<'a> {
    /// The plant's start values for the model's Δb.
    pub start: &'a crate::control::StartValues,
}

/// Options of [`c_source`].
#[derive(Debug, Clone, Copy, Default)]
pub struct COptions<'a> {
    /// Precision of the generated code.
    pub precision: CPrecision,
    /// Emit the handoff table and `bias_model_integrator_start`.
    pub handoff: Option<CHandoff<'a>>,
}

/// Why a model cannot be exported or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportError {
    /// A term does not describe itself in C.
    #[error(
        "term `{term}` cannot be exported to C: it does not describe itself (implement Term::export_c)"
    )]
    NotExportable {
        /// The term's name.
        term: String,
    },
    /// A term's C description is inconsistent (for example a covariate it names is not among
    /// the model's columns).
    #[error("term `{term}`: {why}")]
    BadTerm {
        /// The term's name.
        term: String,
        /// What is wrong.
        why: String,
    },
    /// The output folder cannot be used.
    #[error("{path}: {why}")]
    Folder {
        /// The folder.
        path: String,
        /// What is wrong.
        why: String,
    },
    /// Writing a file failed.
    #[error(transparent)]
    Output(#[from] OutputError),
}

/// The three generated files.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CSource {
    /// `bias_model.h`.
    pub header: String,
    /// `bias_model.c`.
    pub source: String,
    /// `replay.c`.
    pub replay: String,
}

/// The files [`CSource::write`] puts into its folder, in order: header, source, replay.
pub const C_FILES: [&str; 3] = ["bias_model.h", "bias_model.c", "replay.c"];

impl CSource {
    /// Writes `bias_model.h`, `bias_model.c` and `replay.c` into `dir` (created if missing):
    /// staged in one temporary folder and moved into place together ([`StagedDir`]), so a
    /// failure leaves `dir` as it was.
    pub fn write(&self, dir: &Path) -> Result<(), ExportError> {
        if dir.exists() && !dir.is_dir() {
            return Err(ExportError::Folder {
                path: dir.display().to_string(),
                why: "exists and is not a folder (the C files are written into a folder)".into(),
            });
        }
        // Staged beside `dir` and moved in whole: all three files or none.
        let staged = StagedDir::create(dir)?;
        for (name, text) in [
            (C_FILES[0], &self.header),
            (C_FILES[1], &self.source),
            (C_FILES[2], &self.replay),
        ] {
            write_string_atomic(&staged.path(name), text)?;
        }
        Ok(staged.commit()?)
    }
}

/// Replaces `$S`, `$K` and `$X<i>` in a term's text.
fn fill(text: &str, state: &str, prefix: &str, covariates: &[usize]) -> Result<String, String> {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(i) = rest.find('$') {
        out.push_str(&rest[..i]);
        let after = &rest[i + 1..];
        if let Some(r) = after.strip_prefix('S') {
            out.push_str(state);
            rest = r;
        } else if let Some(r) = after.strip_prefix('K') {
            out.push_str(prefix);
            rest = r;
        } else if let Some(r) = after.strip_prefix('X') {
            let digits = r.bytes().take_while(u8::is_ascii_digit).count();
            let k: usize = r[..digits]
                .parse()
                .map_err(|_| "`$X` without a covariate number".to_string())?;
            let idx = covariates.get(k).ok_or_else(|| {
                format!(
                    "`$X{k}`: the term reads only {} covariates",
                    covariates.len()
                )
            })?;
            let _ = write!(out, "x[{idx}]");
            rest = &r[digits..];
        } else {
            return Err(format!(
                "unknown placeholder `${}`",
                after.chars().next().unwrap_or(' ')
            ));
        }
    }
    out.push_str(rest);
    Ok(out)
}

/// C string literal of `s` (escaping `\` and `"`).
fn c_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '"' => out.push_str("\\\""),
            c if c.is_control() => out.push(' '),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// Generates the C export of `model` (see the module docs). Fails naming the first term that
/// does not describe itself.
pub fn c_source(model: &FittedModel, opts: &COptions<'_>) -> Result<CSource, ExportError> {
    let ctx = CContext::new(opts.precision);
    let covariates = &model.columns.covariates;
    struct Written {
        name: String,
        n: usize,
        term: CTerm,
        prefix: String,
    }
    let mut terms = Vec::new();
    for (k, t) in model.terms.iter().enumerate() {
        let name = t.term.name();
        let c = t
            .term
            .export_c(&ctx)
            .ok_or_else(|| ExportError::NotExportable { term: name.clone() })?;
        let idx = t
            .term
            .covariates()
            .iter()
            .map(|c| {
                covariates
                    .iter()
                    .position(|n| n == c)
                    .ok_or_else(|| ExportError::BadTerm {
                        term: name.clone(),
                        why: format!("covariate `{c}` is not among the model's columns"),
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let member = format!("s->t{k}");
        let prefix = format!("BM{k}");
        let bad = |why: String| ExportError::BadTerm {
            term: name.clone(),
            why,
        };
        let term = CTerm {
            state: c.state.clone(),
            constants: fill(&c.constants, &member, &prefix, &idx).map_err(bad)?,
            init: fill(&c.init, &member, &prefix, &idx).map_err(bad)?,
            basis: fill(&c.basis, &member, &prefix, &idx).map_err(bad)?,
            offset: fill(&c.offset, &member, &prefix, &idx).map_err(bad)?,
            update: fill(&c.update, &member, &prefix, &idx).map_err(bad)?,
        };
        terms.push(Written {
            name,
            n: t.coefficients.len(),
            term,
            prefix,
        });
    }
    let real_type = match opts.precision {
        CPrecision::Float64 => "double",
        CPrecision::Float32 => "float",
    };
    let nmax = terms.iter().map(|t| t.n).max().unwrap_or(0).max(1);
    let comment = |s: &str| s.replace("*/", "* /");

    // ---------------------------------------------------------------- header
    let mut h = String::new();
    let _ = writeln!(
        h,
        "/* bias_model.h: generated by biasctl export c from a model `{}` (C99, no allocation,\n * no globals). Positions in the log's position unit (tracks: 0 at the outer diameter,\n * positive seeks inbound), time in s, bias in the log's bias unit. */",
        comment(&model.spec.to_string())
    );
    h.push_str("#ifndef BIAS_MODEL_H\n#define BIAS_MODEL_H\n\n");
    let _ = writeln!(
        h,
        "/** The floating-point type of every value. */\ntypedef {real_type} bias_real;\n"
    );
    let _ = writeln!(
        h,
        "/** Number of covariate values `cov` holds (see bias_model_covariate_name). */\n#define BIAS_MODEL_N_COVARIATES {}",
        covariates.len()
    );
    let _ = writeln!(
        h,
        "/** Uncrossed rest positions kept per side of the head (the farthest is dropped beyond). */\n#define BIAS_MODEL_REST_CAP {REST_CAPACITY}"
    );
    let _ = writeln!(
        h,
        "/** 1 when bias_model_integrator_start is available. */\n#define BIAS_MODEL_HAS_HANDOFF {}\n",
        u8::from(opts.handoff.is_some())
    );
    h.push_str(
        "/** The history features of one seek (crate::history::SeekFeatures). */
typedef struct {
    bias_real seek_index, time_s, elapsed_s, dwell_s, source, target, seek_length;
    bias_real since_reversal, rest_od, rest_id;
    int direction, direction_change, has_rest_od, has_rest_id;
} bias_model_features;

/** The seek history: head position, direction, time and the uncrossed rest positions. */
typedef struct {
    int started, direction, n_below, n_above;
    bias_real position, start_time, last_time, seeks, since_reversal;
    bias_real below[BIAS_MODEL_REST_CAP];
    bias_real above[BIAS_MODEL_REST_CAP];
} bias_model_history;

/** The predictor's whole state: initialise with bias_model_init. */
typedef struct {
    bias_model_history h;
",
    );
    for (k, t) in terms.iter().enumerate() {
        if !t.term.state.trim().is_empty() {
            let _ = writeln!(
                h,
                "    struct {{ {} }} t{k}; /* {} */",
                t.term.state.trim(),
                comment(&t.name)
            );
        }
    }
    h.push_str("} bias_model_state;\n\n");
    h.push_str(
        "/** Name of covariate column i (0 <= i < BIAS_MODEL_N_COVARIATES), or 0. */
const char *bias_model_covariate_name(int i);
/** Name of the model's time (0), position (1) and bias (2) column, or 0. */
const char *bias_model_column(int which);
/** Sets the state to the start of a log. */
void bias_model_init(bias_model_state *s);
/** The predicted bias if the next seek went to `target` at `time_s` with covariates `cov`
 * (BIAS_MODEL_N_COVARIATES values); the state is unchanged. */
bias_real bias_model_peek(const bias_model_state *s, bias_real time_s, bias_real target,
                          const bias_real *cov);
/** Records a seek to `target` at `time_s` and, when `measured` is non-zero, its measured `bias`;
 * returns the prediction made before the measurement was seen. */
bias_real bias_model_step(bias_model_state *s, bias_real time_s, bias_real target,
                          const bias_real *cov, int measured, bias_real bias);
",
    );
    if opts.handoff.is_some() {
        h.push_str(
            "/** The settle-optimal (robust) integrator start value, µm·samples, for a seek whose
 * predicted bias is `bias` (counts): the converged value dz/dd·bias plus the robust start
 * relative to it. Returns 1 and sets *start, or 0 when no start value settles. */
int bias_model_integrator_start(bias_real bias, bias_real *start);
",
        );
    }
    h.push_str("\n#endif\n");

    // ---------------------------------------------------------------- source
    let mut c = String::new();
    let _ = writeln!(
        c,
        "/* bias_model.c: generated by biasctl export c from a model `{}`. */",
        comment(&model.spec.to_string())
    );
    c.push_str("#include \"bias_model.h\"\n#include <string.h>\n#include <tgmath.h>\n\n");
    let names: Vec<String> = covariates.iter().map(|n| c_string(n)).collect();
    let _ = writeln!(
        c,
        "const char *bias_model_covariate_name(int i)\n{{\n    static const char *const names[] = {{{}}};\n    return (i >= 0 && i < BIAS_MODEL_N_COVARIATES) ? names[i] : 0;\n}}\n",
        if names.is_empty() {
            "0".to_string()
        } else {
            names.join(", ")
        }
    );
    let _ = writeln!(
        c,
        "const char *bias_model_column(int which)\n{{\n    static const char *const names[] = {{{}, {}, {}}};\n    return (which >= 0 && which < 3) ? names[which] : 0;\n}}\n",
        c_string(&model.columns.time),
        c_string(&model.columns.track),
        c_string(&model.columns.bias)
    );
    for (k, t) in terms.iter().enumerate() {
        let coefficients = &model.terms[k].coefficients;
        let _ = writeln!(c, "/* term {k}: {} */", comment(&t.name));
        if !coefficients.is_empty() {
            let _ = writeln!(
                c,
                "static const bias_real {}_C[{}] = {};",
                t.prefix,
                coefficients.len(),
                ctx.array(coefficients)
            );
        }
        c.push_str(&t.term.constants);
        if !t.term.constants.ends_with('\n') && !t.term.constants.is_empty() {
            c.push('\n');
        }
    }
    c.push_str(HISTORY_C);
    c.push_str("\nvoid bias_model_init(bias_model_state *s)\n{\n    memset(s, 0, sizeof *s);\n");
    for t in &terms {
        if !t.term.init.trim().is_empty() {
            let _ = writeln!(c, "    {{ {} }}", t.term.init.trim());
        }
    }
    c.push_str("}\n\n");
    let _ = writeln!(
        c,
        "static bias_real evaluate(const bias_model_state *s, const bias_model_features *f,\n                          const bias_real *x)\n{{\n    bias_real b[{nmax}];\n    bias_real total = 0, acc;\n    int j;\n    (void)s; (void)x; (void)b; (void)j;"
    );
    for t in &terms {
        let _ = writeln!(c, "    /* {} */", comment(&t.name));
        c.push_str("    {\n");
        for line in t.term.basis.lines() {
            let _ = writeln!(c, "        {line}");
        }
        c.push_str("        acc = 0;\n");
        if t.n > 0 {
            let _ = writeln!(
                c,
                "        for (j = 0; j < {}; j++) acc += b[j] * {}_C[j];",
                t.n, t.prefix
            );
        }
        if !t.term.offset.trim().is_empty() {
            let _ = writeln!(c, "        acc += {};", t.term.offset.trim());
        }
        c.push_str("        total += acc;\n    }\n");
    }
    c.push_str("    return total;\n}\n\n");
    c.push_str(
        "bias_real bias_model_peek(const bias_model_state *s, bias_real time_s, bias_real target,
                          const bias_real *cov)
{
    bias_model_features f;
    history_peek(&s->h, time_s, target, &f);
    return evaluate(s, &f, cov);
}

bias_real bias_model_step(bias_model_state *s, bias_real time_s, bias_real target,
                          const bias_real *cov, int measured, bias_real bias)
{
    bias_model_features fs;
    const bias_model_features *f = &fs;
    const bias_real *x = cov;
    bias_real pred, resid;
    history_peek(&s->h, time_s, target, &fs);
    history_apply(&s->h, &fs);
    pred = evaluate(s, f, cov);
    resid = measured ? bias - pred : 0;
    (void)f; (void)x; (void)resid;
",
    );
    for t in &terms {
        if !t.term.update.trim().is_empty() {
            let _ = writeln!(c, "    {{ {} }}", t.term.update.trim());
        }
    }
    c.push_str("    return pred;\n}\n");
    if let Some(hand) = &opts.handoff {
        c.push_str(&handoff_c(&ctx, hand.start));
    }

    // ---------------------------------------------------------------- replay
    let out_fmt = match opts.precision {
        CPrecision::Float64 => "%.17g",
        CPrecision::Float32 => "%.9g",
    };
    let replay = REPLAY_C
        .replace("@FMT@", out_fmt)
        .replace("@HANDOFF@", if opts.handoff.is_some() { "1" } else { "0" });
    Ok(CSource {
        header: h,
        source: c,
        replay,
    })
}

/// The handoff table and `bias_model_integrator_start` (a port of
/// [`crate::control::settle::HandoffTable::solve`]'s robust choice for a step from rest).
fn handoff_c(ctx: &CContext, start: &crate::control::StartValues) -> String {
    let table = start.table();
    let (rows, zeros) = table.export_rows();
    let col = |i: usize| -> Vec<f64> { rows.iter().map(|r| r[i]).collect() };
    let mut c = String::new();
    let n = rows.len();
    let _ = writeln!(
        c,
        "\n/* The handoff table (eq. 14-16): per sample k the bounds' coefficients. */"
    );
    let _ = writeln!(c, "#define BM_H_N {n}");
    let _ = writeln!(c, "#define BM_H_HOLD {}", start.window().hold());
    for (i, name) in ["PE", "PV", "PU", "W"].iter().enumerate() {
        let _ = writeln!(
            c,
            "static const bias_real BM_H_{name}[{n}] = {};",
            ctx.array(&col(i))
        );
    }
    let nz = zeros.len();
    let _ = writeln!(c, "#define BM_H_NZ {nz}");
    let zk: Vec<String> = zeros.iter().map(|z| z.0.to_string()).collect();
    let _ = writeln!(
        c,
        "static const int BM_H_ZK[{}] = {{{}}};",
        nz.max(1),
        if zk.is_empty() {
            "0".into()
        } else {
            zk.join(", ")
        }
    );
    for (i, name) in ["ZCE", "ZCV", "ZCU"].iter().enumerate() {
        let v: Vec<f64> = zeros.iter().map(|z| z.1[i]).collect();
        let _ = writeln!(
            c,
            "static const bias_real BM_H_{name}[{}] = {};",
            nz.max(1),
            ctx.array(&v)
        );
    }
    let _ = writeln!(
        c,
        "static const bias_real BM_H_DZ_DBIAS = {};\nstatic const bias_real BM_H_DELTA = {};\nstatic const bias_real BM_H_DELTA_B = {};\nstatic const bias_real BM_H_STEP = {};",
        ctx.real(table.dz_dbias()),
        ctx.real(start.window().half_width_um()),
        ctx.real(start.delta_b()),
        ctx.real(start.step_um())
    );
    c.push_str(HANDOFF_C);
    c
}

/// History: a port of `crate::history::History::peek` / `step` with fixed-size rest stacks.
const HISTORY_C: &str = r#"
static int sign_of(bias_real x) { return x > 0 ? 1 : (x < 0 ? -1 : 0); }

static void history_peek(const bias_model_history *h, bias_real time_s, bias_real target,
                         bias_model_features *f)
{
    bias_real source = h->started ? h->position : target;
    bias_real len = target - source;
    int move = sign_of(len);
    int change = move != 0 && h->direction != 0 && move != h->direction;
    int i;
    int has_od = 0, has_id = 0;
    bias_real od = 0, id = 0;
    f->seek_index = h->seeks;
    f->time_s = time_s;
    f->elapsed_s = h->started ? time_s - h->start_time : 0;
    f->dwell_s = h->started ? time_s - h->last_time : 0;
    f->source = source;
    f->target = target;
    f->seek_length = len;
    f->direction = move == 0 ? h->direction : move;
    f->direction_change = change;
    f->since_reversal = (change || h->direction == 0) ? fabs(len) : h->since_reversal + fabs(len);
    if (target > source) {
        if (h->n_below > 0) { has_od = 1; od = h->below[h->n_below - 1]; }
        for (i = h->n_above - 1; i >= 0; i--) {
            if (h->above[i] > target) { has_id = 1; id = h->above[i]; break; }
        }
    } else if (target < source) {
        for (i = h->n_below - 1; i >= 0; i--) {
            if (h->below[i] < target) { has_od = 1; od = h->below[i]; break; }
        }
        if (h->n_above > 0) { has_id = 1; id = h->above[h->n_above - 1]; }
    } else {
        if (h->n_below > 0) { has_od = 1; od = h->below[h->n_below - 1]; }
        if (h->n_above > 0) { has_id = 1; id = h->above[h->n_above - 1]; }
    }
    f->has_rest_od = has_od;
    f->rest_od = has_od ? target - od : 0;
    f->has_rest_id = has_id;
    f->rest_id = has_id ? id - target : 0;
}

/* Pushes p onto a stack of BIAS_MODEL_REST_CAP; when full, the bottom (farthest) is dropped. */
static void rest_push(bias_real *stack, int *n, bias_real p)
{
    if (*n == BIAS_MODEL_REST_CAP) {
        memmove(stack, stack + 1, (BIAS_MODEL_REST_CAP - 1) * sizeof *stack);
        *n -= 1;
    }
    stack[(*n)++] = p;
}

static void history_apply(bias_model_history *h, const bias_model_features *f)
{
    bias_real source = f->source, target = f->target;
    if (!h->started) {
        h->start_time = f->time_s;
    }
    if (target > source) {
        while (h->n_above > 0 && h->above[h->n_above - 1] <= target) h->n_above--;
        rest_push(h->below, &h->n_below, source);
    } else if (target < source) {
        while (h->n_below > 0 && h->below[h->n_below - 1] >= target) h->n_below--;
        rest_push(h->above, &h->n_above, source);
    }
    h->started = 1;
    h->position = target;
    h->last_time = f->time_s;
    h->seeks += 1;
    h->direction = f->direction;
    h->since_reversal = f->since_reversal;
}
"#;

/// The robust start value: the backward scan of `HandoffTable::solve` (phases 1 and 2).
const HANDOFF_C: &str = r#"
static bias_real h_min(bias_real a, bias_real b) { return b < a ? b : a; }
static bias_real h_max(bias_real a, bias_real b) { return b > a ? b : a; }

int bias_model_integrator_start(bias_real bias, bias_real *start)
{
    const bias_real e0 = -BM_H_STEP, v0 = 0, du = bias - bias;
    const bias_real shift = fabs(BM_H_DZ_DBIAS * BM_H_DELTA_B), two_shift = 2 * shift;
    bias_real umin = INFINITY, lmax = -INFINITY, lo, hi, zeta;
    int k, top, floor_k = 0, phase, z;
    if (!(bias == bias) || BM_H_HOLD > BM_H_N) return 0;
    top = BM_H_N - BM_H_HOLD;
    for (z = BM_H_NZ - 1; z >= 0 && BM_H_NZ > 0; z--) {
        bias_real c = BM_H_ZCE[z] * e0 + BM_H_ZCV[z] * v0 + BM_H_ZCU[z] * du;
        if (c != c || fabs(c) > BM_H_DELTA) { floor_k = BM_H_ZK[z] + 1; break; }
    }
    if (floor_k > top) return 0;
    for (k = top + 1; k < BM_H_N; k++) {
        bias_real mid = BM_H_PE[k] * e0 + BM_H_PV[k] * v0 + BM_H_PU[k] * du;
        bias_real half = BM_H_W[k] * BM_H_DELTA;
        umin = h_min(umin, mid + half);
        lmax = h_max(lmax, mid - half);
    }
    k = top + 1;
    for (phase = 0; phase < 2; phase++) {
        while (k > floor_k) {
            bias_real mid = BM_H_PE[k - 1] * e0 + BM_H_PV[k - 1] * v0 + BM_H_PU[k - 1] * du;
            bias_real half = BM_H_W[k - 1] * BM_H_DELTA;
            bias_real nu = h_min(umin, mid + half), nl = h_max(lmax, mid - half);
            int keep = phase == 0 ? (nl <= -shift && nu >= shift) : (nu - nl >= two_shift);
            if (!keep) break;
            umin = nu;
            lmax = nl;
            k--;
        }
    }
    if (k > top) return 0;
    lo = lmax;
    hi = umin;
    if (isfinite(lo) && isfinite(hi)) {
        zeta = 0.5f * (lo + hi);
    } else {
        bias_real a = lo + shift, b = hi - shift;
        zeta = a > b ? 0.5f * (a + b) : (0 < a ? a : (0 > b ? b : 0));
    }
    *start = BM_H_DZ_DBIAS * bias + zeta;
    return isfinite(*start) ? 1 : 0;
}
"#;

/// The replay program.
const REPLAY_C: &str = r#"/* replay.c: generated by biasctl export c. Reads a log in biasctl's format on stdin
 * (`#` metadata lines, a header naming the model's columns, rows; an empty bias cell or no bias
 * column means not measured) and prints the predicted bias of every row, one per line
 * (followed by `,integrator_start` when the model was exported with a handoff plant). */
#include "bias_model.h"
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_LINE 65536
#define MAX_COLS 256
#define HAS_HANDOFF @HANDOFF@

static int split(char *line, char **cells)
{
    int n = 0;
    char *p = line, *end;
    end = p + strcspn(p, "\r\n");
    *end = 0;
    for (;;) {
        char *comma = strchr(p, ',');
        if (n == MAX_COLS) return -1;
        cells[n++] = p;
        if (!comma) break;
        *comma = 0;
        p = comma + 1;
    }
    return n;
}

static int blank(const char *s)
{
    while (*s == ' ' || *s == '\t') s++;
    return *s == 0;
}

static int find(char **cells, int n, const char *name)
{
    int i;
    for (i = 0; i < n; i++) {
        const char *c = cells[i];
        size_t len;
        while (*c == ' ' || *c == '\t') c++;
        len = strlen(name);
        if (strncmp(c, name, len) == 0 && blank(c + len)) return i;
    }
    return -1;
}

static int number(const char *cell, double *out)
{
    char *end;
    if (blank(cell)) return 0;
    *out = strtod(cell, &end);
    return blank(end) ? 1 : -1;
}

int main(void)
{
    static char line[MAX_LINE];
    static bias_model_state state;
    char *cells[MAX_COLS];
    int n, col_time, col_track, col_bias, col_cov[BIAS_MODEL_N_COVARIATES + 1], i;
    long line_no = 0;
    bias_real cov[BIAS_MODEL_N_COVARIATES + 1];
    for (;;) {
        if (!fgets(line, sizeof line, stdin)) {
            fprintf(stderr, "replay: no header\n");
            return 2;
        }
        line_no++;
        if (line[0] != '#' && !blank(line) && line[0] != '\n' && line[0] != '\r') break;
    }
    n = split(line, cells);
    col_time = find(cells, n, bias_model_column(0));
    col_track = find(cells, n, bias_model_column(1));
    col_bias = find(cells, n, bias_model_column(2));
    if (col_time < 0 || col_track < 0) {
        fprintf(stderr, "replay: line %ld: the header lacks `%s` or `%s`\n", line_no,
                bias_model_column(0), bias_model_column(1));
        return 2;
    }
    for (i = 0; i < BIAS_MODEL_N_COVARIATES; i++) {
        col_cov[i] = find(cells, n, bias_model_covariate_name(i));
        if (col_cov[i] < 0) {
            fprintf(stderr, "replay: line %ld: the header lacks covariate `%s`\n", line_no,
                    bias_model_covariate_name(i));
            return 2;
        }
    }
    bias_model_init(&state);
    while (fgets(line, sizeof line, stdin)) {
        double t, x, y = 0, v;
        int measured;
        bias_real pred;
        line_no++;
        if (blank(line) || line[0] == '\n' || line[0] == '\r') continue;
        n = split(line, cells);
        if (n <= col_time || n <= col_track || number(cells[col_time], &t) != 1
            || number(cells[col_track], &x) != 1) {
            fprintf(stderr, "replay: line %ld: bad time or position\n", line_no);
            return 2;
        }
        measured = col_bias >= 0 && col_bias < n ? number(cells[col_bias], &y) : 0;
        if (measured < 0) {
            fprintf(stderr, "replay: line %ld: bad bias\n", line_no);
            return 2;
        }
        for (i = 0; i < BIAS_MODEL_N_COVARIATES; i++) {
            if (col_cov[i] >= n || number(cells[col_cov[i]], &v) != 1) {
                fprintf(stderr, "replay: line %ld: bad covariate `%s`\n", line_no,
                        bias_model_covariate_name(i));
                return 2;
            }
            cov[i] = (bias_real)v;
        }
        pred = bias_model_step(&state, (bias_real)t, (bias_real)x, cov, measured,
                               (bias_real)y);
#if HAS_HANDOFF
        {
            bias_real z;
            if (bias_model_integrator_start(pred, &z)) {
                printf("@FMT@,@FMT@\n", (double)pred, (double)z);
            } else {
                printf("@FMT@,\n", (double)pred);
            }
        }
#else
        printf("@FMT@\n", (double)pred);
#endif
    }
    return 0;
}
"#;
