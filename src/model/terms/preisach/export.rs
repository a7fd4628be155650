//! `preisach:N` as C: the memory staircase in the state struct, its update as two small file-
//! scope functions, the relay states as the basis. The position arithmetic is in `double`
//! whatever the exported precision (the relays must switch where Rust's do).

use super::PreisachTerm;
use super::memory::MAX_LEVELS;
use crate::codegen::CTerm;

/// A `double` literal that reads back exactly.
fn dbl(x: f64) -> String {
    let t = format!("{x:e}");
    if t.starts_with('-') {
        format!("({t})")
    } else {
        t
    }
}

/// The C of a fitted `preisach:N` (see the module docs).
pub(super) fn c_term(t: &PreisachTerm) -> CTerm {
    let n = t.grid.levels;
    let cap = 2 * MAX_LEVELS + 2;
    let nc = t.cells.len();
    let list = |f: fn(&(u8, u8)) -> u8| {
        t.cells
            .iter()
            .map(|c| f(c).to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let (lo, hi, nf) = (dbl(t.grid.lo), dbl(t.grid.hi), dbl(n as f64));
    let constants = format!(
        r#"static const unsigned char $K_I[{nc}] = {{{i}}};
static const unsigned char $K_J[{nc}] = {{{j}}};
static void $K_up(unsigned char *o, int *len, int u) {{
    int l = *len;
    if (u == 0) return;
    if (l % 2 == 0) {{ if (o[l - 1] >= u) return; l -= 1; }}
    while (l >= 3 && o[l - 2] <= u) l -= 2;
    o[l] = (unsigned char)u; *len = l + 1;
}}
static void $K_down(unsigned char *o, int *len, int d) {{
    int l = *len;
    if (d >= {n}) return;
    if (l % 2 == 1) {{ if (o[l - 1] <= d) return; l -= 1; }}
    while (l >= 2 && o[l - 2] >= d) l -= 2;
    o[l] = (unsigned char)d; *len = l + 1;
}}
static void $K_step(unsigned char *o, int *len, int *started, double x) {{
    double u = (x - {lo}) * {nf} / ({hi} - {lo});
    if (!*started) {{
        int i, prev = 0;
        *started = 1;
        for (i = {n} - 1; i >= 0; i--) {{
            int b = (int)fmin(fmax(ceil(2.0 * u - (double)i - 1.0), 0.0), {nf});
            if (b > prev) {{ $K_up(o, len, i + 1); $K_down(o, len, b); prev = b; }}
        }}
    }}
    $K_up(o, len, (int)fmin(fmax(floor(u), 0.0), {nf}));
    $K_down(o, len, (int)fmin(fmax(ceil(u), 0.0), {nf}));
}}
static void $K_boundary(const unsigned char *o, int len, unsigned char *bd) {{
    int i, k;
    for (i = 0; i < {n}; i++) bd[i] = 0;
    for (k = 1; k < len; k += 2) {{
        int u = o[k], d = k + 1 < len ? o[k + 1] : {n}, below = k + 2 < len ? o[k + 2] : 0;
        for (i = below; i < u; i++) bd[i] = (unsigned char)(d < i + 1 ? d : i + 1);
    }}
}}
"#,
        i = list(|c| c.0),
        j = list(|c| c.1),
    );
    CTerm {
        state: format!("unsigned char ops[{cap}]; int len; int started;"),
        constants,
        init: "$S.ops[0] = 0; $S.len = 1; $S.started = 0;".into(),
        basis: format!(
            "{{ unsigned char o_[{cap}], bd_[{n}]; int l_ = $S.len, s_ = $S.started, k_;\n  for (k_ = 0; k_ < l_; k_++) o_[k_] = $S.ops[k_];\n  $K_step(o_, &l_, &s_, (double)f->target);\n  $K_boundary(o_, l_, bd_);\n  for (k_ = 0; k_ < {nc}; k_++) b[k_] = $K_J[k_] < bd_[$K_I[k_]] ? 1 : -1; }}\n"
        ),
        update: "$K_step($S.ops, &$S.len, &$S.started, (double)f->target);".into(),
        ..CTerm::default()
    }
}
