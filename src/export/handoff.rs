//! The handoff table and `bias_model_integrator_start` in C (with a handoff plant).

use crate::codegen::CContext;
use std::fmt::Write as _;

/// The handoff table and `bias_model_integrator_start` (a port of
/// [`crate::control::settle::HandoffTable::solve`]'s robust choice for a step from rest).
pub(super) fn handoff_c(ctx: &CContext, start: &crate::control::StartValues) -> String {
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
