//! The C descriptions of the built-in terms, from a term's name and saved settings (what the
//! model file keeps): the default of [`crate::model::term::Term::export_c`]. Each follows the
//! term's `TermState::basis`/`offset`/`update` operation by operation, so the C prediction
//! agrees with Rust to rounding.

use super::{CContext, CTerm};
use crate::model::terms::{bins, covariate, dahl, drift, memory, poly, seek, table};
use serde::de::DeserializeOwned;

fn de<T: DeserializeOwned>(settings: &serde_json::Value) -> Option<T> {
    serde_json::from_value(settings.clone()).ok()
}

/// `b[0 .. n) = 0`.
fn zero(n: usize) -> String {
    format!("{{ int i_; for (i_ = 0; i_ < {n}; i_++) b[i_] = 0; }}\n")
}

/// Hinge curves of `seek` and `memory` (`knots::curve_hinges`): all zero, then for the curve
/// `curve_expr` (C int, < 0 for none) `max(k_j − a, 0)/k_last` with `a = a_expr`.
fn curve_hinges(
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

/// The side of a direction (`knots::direction_side`): inbound 1, outbound 0, none −1.
const SIDE: &str = "(f->direction == 1 ? 1 : (f->direction == -1 ? 0 : -1))";

/// The C description of the built-in term `name` with saved `settings`; `None` for a name
/// that is not a built-in term (or settings that do not parse).
pub(crate) fn builtin_term(
    name: &str,
    settings: &serde_json::Value,
    ctx: &CContext,
) -> Option<CTerm> {
    let head = name.split(':').next().unwrap_or("");
    let mut t = CTerm::default();
    match head {
        "intercept" => t.basis = "b[0] = 1;\n".into(),
        "direction" => t.basis = "b[0] = (bias_real)f->direction;\n".into(),
        "poly2" => {
            let p: poly::Poly2Term = de(settings)?;
            t.basis = format!(
                "{{ bias_real u_ = (f->target - {}) / {}; b[0] = 1; b[1] = u_; b[2] = u_ * u_; }}\n",
                ctx.real(p.centre),
                ctx.real(p.scale)
            );
        }
        "table" => {
            let p: table::TableTerm = de(settings)?;
            if p.knots == 1 {
                t.basis = "b[0] = 1;\n".into();
            } else {
                let top = (p.knots - 1) as f64;
                t.basis = zero(p.knots);
                t.basis += &format!(
                    "{{ bias_real u_ = (f->target - {x0}) / {h}; int i_; bias_real fr_;\n  u_ = u_ < 0 ? 0 : (u_ > {top} ? {top} : u_);\n  i_ = (int)floor(u_); if (i_ > {last}) i_ = {last};\n  fr_ = u_ - (bias_real)i_; b[i_] = 1 - fr_; b[i_ + 1] = fr_; }}\n",
                    x0 = ctx.real(p.x0),
                    h = ctx.real(p.spacing),
                    top = ctx.real(top),
                    last = p.knots - 2
                );
            }
        }
        "seek" => {
            let p: seek::SeekTerm = de(settings)?;
            let curve = format!("({SIDE} < 0 ? -1 : 2 * f->direction_change + {SIDE})");
            t = curve_hinges(
                ctx,
                &p.knots,
                seek::CURVES.len(),
                &curve,
                "fabs(f->seek_length)",
            );
        }
        "memory" => {
            let p: memory::MemoryTerm = de(settings)?;
            let curve = format!(
                "((f->direction == 1 && f->has_rest_id) || (f->direction == -1 && f->has_rest_od) ? {SIDE} : -1)"
            );
            t = curve_hinges(
                ctx,
                &p.knots,
                2,
                &curve,
                "(f->direction == 1 ? f->rest_id : f->rest_od)",
            );
        }
        "drift" => {
            let p: drift::DriftTerm = de(settings)?;
            t.state = "bias_real m;".into();
            t.offset = "$S.m".into();
            t.update = format!("if (measured) $S.m += {} * resid;", ctx.real(p.alpha));
        }
        "dahl" => {
            let p: dahl::DahlTerm = de(settings)?;
            let n = p.rates.len();
            let ln_r: Vec<f64> = p.rates.iter().map(|r| r.ln()).collect();
            t.state = format!("bias_real g[{n}];");
            t.constants = format!(
                "static const bias_real $K_LNR[{n}] = {};\n",
                ctx.array(&ln_r)
            );
            // G = s + (G − s)·r^|dx| (eq. 8 / Fc), unchanged for dx = 0.
            let peek = "bias_real dx_ = f->seek_length, d_ = exp($K_LNR[j_] * fabs(dx_)), g_ = $S.g[j_];\n      g_ = dx_ > 0 ? 1 + (g_ - 1) * d_ : (dx_ < 0 ? -1 + (g_ + 1) * d_ : g_);";
            t.basis =
                format!("{{ int j_; for (j_ = 0; j_ < {n}; j_++) {{ {peek} b[j_] = g_; }} }}\n");
            t.update = format!("int j_; for (j_ = 0; j_ < {n}; j_++) {{ {peek} $S.g[j_] = g_; }}");
        }
        "col" => {
            let p: covariate::ColTerm = de(settings)?;
            t.basis = format!(
                "b[0] = ($X0 - {}) / {};\n",
                ctx.real(p.centre),
                ctx.real(p.scale)
            );
        }
        "bins" | "dbins" => {
            let p: bins::BinsTerm = de(settings)?;
            let by_direction = head == "dbins";
            let (defined, value) = if p.covariate {
                ("1", "$X0")
            } else {
                ctx.feature(&p.source)?
            };
            let k = p.knots.len();
            let n = 1 + k + usize::from(p.indicator);
            if k > 0 {
                t.constants = format!(
                    "static const bias_real $K_KNOTS[{k}] = {};\n",
                    ctx.array(&p.knots)
                );
            }
            t.basis = zero(n);
            t.basis += &format!(
                "if ({defined}) {{ bias_real v_ = {value}; b[0] = (v_ - {c}) / {s};",
                c = ctx.real(p.centre),
                s = ctx.real(p.scale)
            );
            if k > 0 {
                t.basis += &format!(
                    " {{ int j_; for (j_ = 0; j_ < {k}; j_++) {{ bias_real h_ = v_ - $K_KNOTS[j_]; b[1 + j_] = (h_ > 0 ? h_ : 0) / {s}; }} }}",
                    s = ctx.real(p.scale)
                );
            }
            t.basis += " }";
            if p.indicator {
                t.basis += &format!(" else {{ b[{}] = 1; }}", k + 1);
            }
            t.basis.push('\n');
            if by_direction {
                t.basis += &format!(
                    "{{ int i_; for (i_ = 0; i_ < {n}; i_++) b[i_] *= (bias_real)f->direction; }}\n"
                );
            }
        }
        _ => return None,
    }
    Some(t)
}
