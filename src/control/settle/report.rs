//! `SettleReport`: everything `biasctl settle` reports, as text and as the CSV of the bounds
//! and the responses (the JSON is its `Serialize`).

use super::{Bounds, PaperRobust, Response, RobustChoice, WorstCase};
use serde::Serialize;

/// Everything `biasctl settle` reports. JSON keys as documented in the README.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SettleReport {
    /// LQR gain K over the loop state (u = −K x).
    pub gain: Vec<f64>,
    /// Closed-loop pole magnitudes, ascending.
    pub poles_abs: Vec<f64>,
    /// ∂z/∂d in µm·samples per count.
    pub dz_dbias: f64,
    /// Doubling steps of the DARE solve.
    pub dare_iterations: usize,
    /// Relative residual of the DARE solution.
    pub dare_residual: f64,
    /// Sample period in s.
    pub ts_s: f64,
    /// Horizon in samples.
    pub horizon: usize,
    /// Window half-width in µm.
    pub window_um: f64,
    /// Hold in samples.
    pub hold: usize,
    /// Step in µm.
    pub step_um: f64,
    /// Bias d in counts.
    pub bias: f64,
    /// The integrator's converged value ∂z/∂d·d (µm·samples); start values are relative to it.
    pub z_converged: f64,
    /// Minimum settle index k* (`None`: nothing settles in the horizon).
    pub k_star: Option<usize>,
    /// k*·Ts in ms.
    pub optimal_settle_ms: Option<f64>,
    /// [L*(k*), U*(k*)]: the optimal start values relative to the converged value.
    pub ff_interval: Option<[f64; 2]>,
    /// The start value chosen in the optimal interval
    /// ([`Interval::choice`](super::Interval::choice) with no margin): its midpoint when both
    /// ends are finite, otherwise the value closest to zero feedforward (0) inside it. Relative
    /// to the converged value, µm·samples.
    pub ff_midpoint: Option<f64>,
    /// Settle time of zero feedforward in ms.
    pub zero_ff_settle_ms: Option<f64>,
    /// Overshoot of the zero-feedforward response in % of the step.
    pub zero_ff_overshoot_pct: f64,
    /// The paper's robust choice (`None`: U_k has no local minimum).
    pub paper_robust: Option<PaperRobust>,
    /// Our robust choice for ±Δb.
    pub robust: Option<RobustChoice>,
    /// Worst case of robust choice and zero feedforward over ±Δb.
    pub worst_case: WorstCase,
    /// The bounds curves (Fig. 15).
    #[serde(skip)]
    pub bounds: Bounds,
    /// The responses of each choice (Fig. 16).
    #[serde(skip)]
    pub responses: Vec<Response>,
}

impl SettleReport {
    /// The absolute integrator start value (µm·samples) of a start value `relative` to the
    /// converged value: `z_converged + relative` (zero feedforward, relative 0, starts the
    /// integrator at its converged value for this bias).
    pub fn absolute(&self, relative: f64) -> f64 {
        self.z_converged + relative
    }

    /// The report as text, one fact a line (what `biasctl settle` prints): the LQR gain and
    /// DARE convergence, closed-loop poles, dz/dbias, the scenario, zero feedforward, the optimal
    /// start values (relative to the converged value, µm·samples), the paper's robust choice and
    /// the robust choice for ±Δb counts; settle times in ms.
    pub fn to_text(&self) -> String {
        let r = self;
        let mut out = String::new();
        let ms = settle_ms_text;
        let abs = |v: f64| format!("{v:.4} [{:.4}]", r.absolute(v));
        let gain: Vec<String> = r.gain.iter().map(|g| format!("{g:.6}")).collect();
        let poles: Vec<String> = r.poles_abs.iter().map(|p| format!("{p:.5}")).collect();
        push_line!(out, "LQR gain K = [{}]", gain.join(", "));
        push_line!(
            out,
            "  DARE: {} doubling steps, residual {:.1e}",
            r.dare_iterations,
            r.dare_residual
        );
        push_line!(out, "closed-loop |poles| = [{}]", poles.join(", "));
        push_line!(out, "dz/dbias = {:.5} (µm·samples per count)", r.dz_dbias);
        push_line!(
            out,
            "step {} µm, window ±{} µm, horizon {} samples, hold {}; start values (µm·samples) relative to the converged value {:.4}, absolute in brackets",
            r.step_um,
            r.window_um,
            r.horizon,
            r.hold,
            r.z_converged
        );
        push_line!(
            out,
            "zero feedforward: {} (overshoot {:.1} %), start value {}",
            r.zero_ff_settle_ms
                .map_or("does not settle within the horizon".to_string(), |m| {
                    format!("settles in {m:.2} ms")
                }),
            r.zero_ff_overshoot_pct,
            abs(0.0)
        );
        match (r.k_star, r.ff_interval) {
            (Some(k), Some([lo, hi])) => push_line!(
                out,
                "optimal: k* = {k}, {} for start values in [{lo:.4}, {hi:.4}] (choice {})",
                ms(r.optimal_settle_ms),
                r.ff_midpoint.map_or("none".to_string(), abs)
            ),
            _ => push_line!(out, "optimal: no start value settles within the horizon"),
        }
        match &r.paper_robust {
            Some(p) => push_line!(
                out,
                "paper's robust choice: {} (first local minimum of the upper bound at k = {}): {}",
                abs(p.ff),
                p.k_min,
                ms(p.settle_ms)
            ),
            None => push_line!(
                out,
                "paper's robust choice: the upper bound has no local minimum"
            ),
        }
        let w = &r.worst_case;
        match &r.robust {
            Some(c) => push_line!(
                out,
                "robust for ±{:.3} counts (shift ±{:.4}): {}, worst case {} (simulated {}); zero feedforward worst case {}",
                w.delta_b,
                w.shift,
                abs(c.ff),
                ms(Some(c.worst_settle_ms)),
                ms(c.simulated_worst_settle_ms),
                ms(w.zero_ff_worst_settle_ms)
            ),
            None => push_line!(
                out,
                "robust for ±{:.3} counts: no start value settles for every bias within the horizon",
                w.delta_b
            ),
        }
        out
    }

    /// `biasctl settle --json`: the report's keys, `absolute` (the absolute integrator start
    /// values, µm·samples: `z_converged` + each relative value) and, when given, `prediction`
    /// (what a caller adds about where the bias came from), through the one JSON writer (a
    /// non-finite number is refused naming its key).
    pub fn to_json_with<P: Serialize>(
        &self,
        prediction: Option<&P>,
    ) -> Result<String, crate::io::OutputError> {
        let abs = |v: Option<f64>| v.map(|v| self.absolute(v));
        let value = SettleJson {
            report: self,
            absolute: Absolute {
                zero_ff: self.absolute(0.0),
                ff_midpoint: abs(self.ff_midpoint),
                paper_robust: abs(self.paper_robust.as_ref().map(|p| p.ff)),
                robust: abs(self.robust.as_ref().map(|c| c.ff)),
            },
            prediction,
        };
        crate::io::json::to_string_pretty(&value)
    }

    /// [`SettleReport::to_json_with`] without a `prediction`.
    pub fn to_json(&self) -> Result<String, crate::io::OutputError> {
        self.to_json_with(None::<&()>)
    }

    /// The bounds of Fig. 15 as CSV: `k,time_s,upper,lower,upper_min,lower_max` (start values in
    /// µm·samples relative to the converged value; time in s). A bound that does not exist at a
    /// sample (at k = 0 no start value puts e(0) = −step in the window) is an empty cell.
    pub fn bounds_csv(&self) -> String {
        let b = &self.bounds;
        let header = ["k", "time_s", "upper", "lower", "upper_min", "lower_max"].map(String::from);
        let rows = (0..b.upper().len()).map(|k| {
            vec![
                k.to_string(),
                format!("{:.7}", k as f64 * self.ts_s),
                csv_cell(b.upper()[k]),
                csv_cell(b.lower()[k]),
                csv_cell(b.upper_min()[k]),
                csv_cell(b.lower_max()[k]),
            ]
        });
        csv_text(header.to_vec(), rows)
    }

    /// The responses of Fig. 16 as CSV: `k,time_s` and one `e_<choice>_um` column (µm) per
    /// start-value choice.
    pub fn responses_csv(&self) -> String {
        let mut header = vec!["k".to_string(), "time_s".to_string()];
        header.extend(self.responses.iter().map(|x| format!("e_{}_um", x.name)));
        let rows = (0..self.horizon).map(|k| {
            let mut row = vec![k.to_string(), format!("{:.7}", k as f64 * self.ts_s)];
            row.extend(
                self.responses
                    .iter()
                    .map(|x| x.e_um.get(k).map_or(String::new(), |e| csv_cell(*e))),
            );
            row
        });
        csv_text(header, rows)
    }
}

/// `settle --json`: the report's keys, `absolute` and, when given, `prediction`.
#[derive(Serialize)]
struct SettleJson<'a, P: Serialize> {
    #[serde(flatten)]
    report: &'a SettleReport,
    absolute: Absolute,
    #[serde(skip_serializing_if = "Option::is_none")]
    prediction: Option<&'a P>,
}

/// The absolute integrator start values (µm·samples): `z_converged` + each relative value.
#[derive(Serialize)]
struct Absolute {
    zero_ff: f64,
    ff_midpoint: Option<f64>,
    paper_robust: Option<f64>,
    robust: Option<f64>,
}

/// A header and rows as CSV text through [`crate::log::csv_writer`] (quoting where needed).
fn csv_text(header: Vec<String>, rows: impl Iterator<Item = Vec<String>>) -> String {
    let mut w = crate::log::csv_writer(Vec::new());
    // Writing to memory cannot fail.
    let _ = w.write_record(&header);
    for r in rows {
        let _ = w.write_record(&r);
    }
    w.into_inner()
        .ok()
        .and_then(|b| String::from_utf8(b).ok())
        .unwrap_or_default()
}

/// A CSV cell: the number, or an empty cell where it is not finite (no bound exists at that
/// sample, or the response overflowed), so the file never holds `inf` or `NaN`; a whole number
/// keeps `.0`, so that a reader guessing the column's type takes it as a float.
fn csv_cell(x: f64) -> String {
    if x.is_finite() {
        let mut s = x.to_string();
        if !s.contains('.') {
            s.push_str(".0");
        }
        s
    } else {
        String::new()
    }
}

/// `12.34 ms`, or `not settled` for `None`.
fn settle_ms_text(v: Option<f64>) -> String {
    v.map_or("not settled".to_string(), |m| format!("{m:.2} ms"))
}

/// Appends one formatted line to a `String`.
macro_rules! push_line {
    ($out:expr, $($t:tt)*) => {{
        $out.push_str(&format!($($t)*));
        $out.push('\n');
    }};
}
use push_line;
