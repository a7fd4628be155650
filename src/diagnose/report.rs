//! The diagnosis as data (serde, JSON contract), as text, and as per-feature CSV curves.

use serde::{Deserialize, Serialize};

use crate::log::Units;
use crate::numeric::stats;

use super::DiagnoseConfig;
use super::advice::{self, Point, Shape};
use super::column::{FeatureColumn, FeatureOrigin, Visit};
use super::smoother::{BinAcc, BinKind, Binned, Unusable, accumulate};
use super::values::{defined, short};

/// The result of [`super::diagnose`]. Serialises to the JSON contract
/// `{"residual_std", "features": [...], "whiteness", "bimodality", "dip", "summary", "units"}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Diagnosis {
    /// Sample standard deviation of the residuals, in the bias unit of [`Diagnosis::units`].
    pub residual_std: f64,
    /// Every candidate feature, strongest first; skipped features last.
    pub features: Vec<FeatureReport>,
    /// Serial-correlation check of the residuals in seek order.
    pub whiteness: Whiteness,
    /// Sarle's bimodality coefficient of the residuals (> 5/9 suggests two modes); `null` when
    /// undefined (zero spread).
    pub bimodality: Option<f64>,
    /// Hartigans' dip test of unimodality of the residuals ([`stats::dip_test`]); the summary
    /// calls the histogram two-humped when it rejects unimodality at 5 %. `null` for fewer than
    /// 4 residuals or zero spread.
    pub dip: Option<stats::DipTest>,
    /// The diagnosis in a few plain sentences.
    pub summary: String,
    /// The units of the residual and of the position-like features, from the log:
    /// `{"bias": "N", "position": "m"}` (counts and tracks when absent).
    #[serde(default)]
    pub units: Units,
    /// Block length (seeks) of the block-permutation null behind every `p_value`: blocks of
    /// consecutive residuals are permuted, so serial correlation shorter than this is kept by
    /// the null (1: plain row permutation).
    #[serde(default)]
    pub null_block_len: usize,
    /// Effects adaptive terms (`drift`) absorbed: candidates that explain residual + the
    /// term's contribution (filled by [`super::diagnose_model`]).
    #[serde(default)]
    pub absorbed: Vec<super::Absorption>,
    /// Warnings about the model (a forgetting factor much faster than a slow offset needs).
    #[serde(default)]
    pub warnings: Vec<String>,
    /// The leading suggestions refitted and scored out of sample, best verified gain first
    /// (filled by [`crate::select::diagnose_verified`]; `null` when not run).
    #[serde(default)]
    pub verification: Option<super::Verification>,
    /// Measured rows diagnosed.
    #[serde(default)]
    pub rows: usize,
    /// The family-wise significance level used.
    #[serde(default)]
    pub alpha: f64,
    /// Pairs of candidates whose joint cells explain clearly more of what the single features
    /// left than either does alone (an interaction without a one-dimensional marginal), best
    /// first, with the interaction term to verify.
    #[serde(default)]
    pub interactions: Vec<super::Interaction>,
    /// The global check: the leading candidates' joint cells against the best single one.
    #[serde(default)]
    pub global: Option<super::GlobalCheck>,
}

/// What one candidate feature says about the residual.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FeatureReport {
    /// Feature name (built-in name or covariate header).
    pub name: String,
    /// Fraction of the residual variance the binned smoother explains out of sample
    /// (1 − CV-MSE / variance, clamped to [0, 1]).
    pub explained: f64,
    /// Family-wise (Westfall–Young min-p) permutation p-value over all features.
    pub p_value: f64,
    /// Fraction of the residual variance the feature explains out of sample **beyond** the
    /// features ranked before it by the forward pass (for features the pass did not take:
    /// beyond all it took); `null` for a skipped feature. See the module docs of
    /// `crate::diagnose`.
    pub explained_beyond_previous: Option<f64>,
    /// The model term that addresses this feature and is not in the model yet; `null` if there
    /// is none (or the feature was skipped).
    pub suggested_term: Option<String>,
    /// Other terms that address the feature and are not in the model, tried in this order
    /// when the suggested one does not fit (verification).
    #[serde(default)]
    pub alternatives: Vec<String>,
    /// Per-feature permutation p-value, not corrected for the number of features.
    pub p_value_raw: f64,
    /// Whether the feature is significant: `p_value` ≤ alpha (family-wise, block null).
    #[serde(default)]
    pub significant: bool,
    /// Whether the feature is flagged: significant, and both `explained` and
    /// `explained_beyond_previous` reach the practical minimum
    /// ([`super::DiagnoseConfig::min_effect`]).
    pub flagged: bool,
    /// The rule that decided `flagged` ([`super::Reason`]): flagged, flagged by its verified
    /// refit, below the practical minimum (significant, but too small alone or beyond the
    /// features ranked before it), not significant, or not analysed.
    pub reason: super::Reason,
    /// Shape of the residual against the feature at the chosen binning.
    pub shape: Shape,
    /// Where the peak, dip or step is (feature units), if the shape has a location.
    pub shape_at: Option<f64>,
    /// Residual std expected once the suggested term is added: residual_std·√(1 − explained).
    pub expected_std: f64,
    /// Rows where the feature is defined.
    pub n: usize,
    /// Rows where it is undefined (kept as their own bin).
    pub missing: usize,
    /// Number of bins the cross-validation chose (the missing bin included).
    pub bins: usize,
    /// Least-squares slope of the residual against the feature (defined rows).
    pub slope: Option<f64>,
    /// Two-sided p-value of that slope.
    pub slope_p: Option<f64>,
    /// Whether the residual follows the feature **times the direction of the last move**
    /// (+1 inbound, −1 outbound): an effect that flips sign with the approach direction, as
    /// hysteresis does. Then `curve`, `shape`, `slope` describe residual × direction.
    pub by_direction: bool,
    /// Whether a straight line explains nearly as much as the bins (≥ 85 % of their R²).
    pub linear: bool,
    /// Why the feature was skipped, or which better term the model already has.
    pub note: Option<String>,
    /// The residual's binned curve against the feature, for plotting (at least 8 bins where the
    /// feature has that many).
    pub curve: Vec<CurveBin>,
}

/// One bin of a residual-vs-feature curve.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CurveBin {
    /// Smallest feature value in the bin; `null` for the bin of undefined values.
    pub lower: Option<f64>,
    /// Largest feature value in the bin; `null` for the bin of undefined values.
    pub upper: Option<f64>,
    /// Mean feature value in the bin; `null` for the bin of undefined values.
    pub centre: Option<f64>,
    /// Mean residual, bias unit.
    pub mean: f64,
    /// Sample std of the residuals in the bin (0 for a single row).
    pub std: f64,
    /// Rows in the bin.
    pub count: usize,
}

/// Whiteness of the residuals in seek order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Whiteness {
    /// Lag-1 autocorrelation.
    pub lag1: f64,
    /// Ljung–Box Q over `lags` lags; `null` with too few rows.
    pub ljung_box_q: Option<f64>,
    /// Its p-value (χ² with `lags` degrees of freedom).
    pub ljung_box_p: Option<f64>,
    /// Lags tested.
    pub lags: usize,
    /// Whether the residuals pass as white at the diagnosis' alpha.
    pub white: bool,
}

impl Whiteness {
    /// Lag-1 autocorrelation and Ljung–Box test of `r` over `lags` lags; white when p > `alpha`.
    pub fn of(r: &[f64], lags: usize, alpha: f64) -> Whiteness {
        let lb = stats::ljung_box(r, lags).filter(|(q, p)| q.is_finite() && p.is_finite());
        Whiteness {
            lag1: finite_or(stats::autocorrelation(r, 1), 0.0),
            ljung_box_q: lb.map(|x| x.0),
            ljung_box_p: lb.map(|x| x.1),
            lags,
            white: lb.is_none_or(|(_, p)| p > alpha),
        }
    }
}

fn finite_or(x: f64, default: f64) -> f64 {
    if x.is_finite() { x } else { default }
}

fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// The bins' sums of a curve ([`accumulate`]), the column read in place.
struct CurveSums<'a> {
    b: &'a Binned,
    shift: u32,
    y: &'a [f64],
}

impl Visit for CurveSums<'_> {
    type Out = Vec<BinAcc>;
    fn rows<I: ExactSizeIterator<Item = f64> + Clone>(self, x: I) -> Vec<BinAcc> {
        accumulate(self.b, self.shift, x, self.y)
    }
}

/// [`stats::linear_trend_of`] of the defined rows' (value, residual) pairs, the column read
/// in place.
struct TrendOf<'a>(&'a [f64]);

impl Visit for TrendOf<'_> {
    type Out = Option<stats::Trend>;
    fn rows<I: ExactSizeIterator<Item = f64> + Clone>(self, x: I) -> Option<stats::Trend> {
        stats::linear_trend_of(
            x.zip(self.0.iter().copied())
                .filter_map(|(x, y)| defined(x).map(|x| (x, y))),
        )
    }
}

/// Curve of the residual `y` against `col` at level `shift`.
fn curve(b: &Binned, shift: u32, col: &FeatureColumn, y: &[f64]) -> Vec<CurveBin> {
    let acc = col.visit(CurveSums { b, shift, y });
    let defined = b.defined_bins(shift);
    acc.iter()
        .enumerate()
        .filter(|(_, a)| a.count > 0)
        .map(|(s, a)| {
            let c = a.count as f64;
            let mean = a.y_sum / c;
            let var = if a.count > 1 {
                ((a.y_sq - a.y_sum * mean) / (c - 1.0)).max(0.0)
            } else {
                0.0
            };
            let is_missing = s == defined;
            CurveBin {
                lower: (!is_missing).then(|| finite(a.x_min)).flatten(),
                upper: (!is_missing).then(|| finite(a.x_max)).flatten(),
                centre: (!is_missing).then(|| finite(a.x_sum / c)).flatten(),
                mean: finite_or(mean, 0.0),
                std: finite_or(var.sqrt(), 0.0),
                count: a.count,
            }
        })
        .collect()
}

/// Whether a covariate's sign is the direction's on at least 90 % of the rows where both are
/// non-zero (a velocity).
/// `direction` is −1, 0 or +1 per row (bytes: a nonzero one is its own sign).
fn sign_follows_direction(x: &[f64], direction: &[i8]) -> bool {
    let (mut agree, mut both) = (0usize, 0usize);
    for (&x, &d) in x.iter().zip(direction) {
        if let Some(x) = defined(x)
            && x != 0.0
            && d != 0
        {
            both += 1;
            // x is neither 0 nor NaN, d is ±1: the signs agree when both are positive or
            // both negative.
            agree += usize::from((x > 0.0) == (d > 0));
        }
    }
    both > 0 && (agree as f64) >= 0.9 * both as f64
}

/// Whether a covariate whose sign follows the direction ([`sign_follows_direction`]) acts like
/// a velocity: the residual is close to a line in the signed value
/// plus a direction step, r ≈ c + a·sign(x) + b·x. Checked on the analysed residual `y` against
/// the analysis's own binned curve (`r2_bins`, in-sample): for the plain analysis `y = r` and the
/// line is in (sign x, x); for the direction-signed one `y = r·d` and, with sign x = d, the same
/// law is a line in |x|. A line with at least 0.85 of the curve's R² means `col:x` (with the
/// model's `direction` carrying a·sign) fits it with one parameter.
fn velocity_like(x: &[f64], y: &[f64], by_direction: bool, r2_bins: f64) -> bool {
    let mut rows: Vec<[f64; 3]> = Vec::new();
    let mut ys = Vec::new();
    for (&x, &y) in x.iter().zip(y) {
        let Some(x) = defined(x) else { continue };
        let sign = if x == 0.0 { 0.0 } else { x.signum() };
        rows.push(if by_direction {
            [1.0, x.abs(), 0.0]
        } else {
            [1.0, sign, x]
        });
        ys.push(y);
    }
    if r2_bins <= 0.0 || ys.len() < 4 {
        return false;
    }
    let k = if by_direction { 2 } else { 3 };
    let n = ys.len();
    let xm = nalgebra::DMatrix::from_fn(n, k, |i, j| rows[i][j]);
    let yv = nalgebra::DVector::from_vec(ys);
    let Ok(coef) = xm.clone().svd(true, true).solve(&yv, 1e-12) else {
        return false;
    };
    let sse = (&yv - &xm * coef).norm_squared();
    let sst = stats::sum_sq_about_mean(yv.as_slice());
    sst > 0.0 && 1.0 - sse / sst >= 0.85 * r2_bins
}

/// In-sample R² of the binned means over the defined rows of a curve.
fn binned_r2(curve: &[CurveBin]) -> f64 {
    let defined: Vec<&CurveBin> = curve.iter().filter(|c| c.centre.is_some()).collect();
    let n: f64 = defined.iter().map(|c| c.count as f64).sum();
    if n < 2.0 {
        return 0.0;
    }
    let total: f64 = defined.iter().map(|c| c.mean * c.count as f64).sum();
    let grand = total / n;
    let ssb: f64 = defined
        .iter()
        .map(|c| c.count as f64 * (c.mean - grand).powi(2))
        .sum();
    let ssw: f64 = defined
        .iter()
        .map(|c| c.std * c.std * (c.count as f64 - 1.0).max(0.0))
        .sum();
    if ssb + ssw > 0.0 {
        ssb / (ssb + ssw)
    } else {
        0.0
    }
}

/// The report of a usable feature.
#[allow(clippy::too_many_arguments)]
pub(crate) fn feature_report(
    col: &FeatureColumn,
    shift: u32,
    b: &Binned,
    explained: f64,
    p_raw: f64,
    p_adj: f64,
    residuals: &[f64],
    by_direction: bool,
    direction: Option<&[i8]>,
    residual_std: f64,
    config: &DiagnoseConfig,
) -> FeatureReport {
    let chosen = curve(b, shift, col, residuals);
    // The defined rows' (value, residual) pairs, read in place from the stored column (no
    // decoded copy, no copy of the pairs; `linear_trend_of` runs over them several times).
    let trend = col.visit(TrendOf(residuals));
    let r2_bins = binned_r2(&chosen);
    let linear = trend.is_some_and(|t| r2_bins > 0.0 && t.r2 >= 0.85 * r2_bins);
    let (shape, shape_at) = if explained > 0.0 {
        let points: Vec<Point> = chosen
            .iter()
            .filter_map(|c| c.centre.map(|x| Point { x, y: c.mean }))
            .collect();
        advice::classify(&points, linear)
    } else {
        (Shape::Flat, None)
    };
    // Plot at least 8 bins where the feature has them.
    let display_shift = match b.kind {
        BinKind::Discrete => 0,
        BinKind::Quantile => {
            let want = b.n_fine.min(8);
            if b.defined_bins(shift) >= want {
                shift
            } else {
                (b.n_fine / want).trailing_zeros()
            }
        }
    };
    let display = if display_shift == shift {
        chosen.clone()
    } else {
        curve(b, display_shift, col, residuals)
    };
    let velocity_sign = matches!(
        col.origin,
        FeatureOrigin::Covariate | FeatureOrigin::DerivedVelocity
    ) && direction.is_some_and(|d| sign_follows_direction(&col.raw(), d));
    let odd_linear = velocity_sign && velocity_like(&col.raw(), residuals, by_direction, r2_bins);
    // A covariate scaling a direction-signed term of the model is tried first (`scale:COL:TERM`).
    let mut candidates = advice::scale_terms(
        &col.name,
        col.origin,
        by_direction,
        velocity_sign,
        &config.existing_terms,
    );
    candidates.extend(advice::candidate_terms(
        &col.name,
        col.origin,
        linear,
        by_direction,
        odd_linear,
        velocity_sign,
    ));
    let (suggested_term, note) = advice::suggest(&candidates, &config.existing_terms);
    let alternatives = advice::alternatives(
        &candidates,
        &config.existing_terms,
        suggested_term.as_deref(),
    );
    let note = advice::offset_note(col.origin, &config.existing_terms).or(note);
    FeatureReport {
        name: col.name.clone(),
        explained,
        p_value: p_adj,
        explained_beyond_previous: None,
        suggested_term,
        alternatives,
        p_value_raw: p_raw,
        significant: p_adj <= config.alpha && explained > 0.0,
        flagged: p_adj <= config.alpha && explained > 0.0,
        reason: if p_adj <= config.alpha && explained > 0.0 {
            super::Reason::Flagged
        } else {
            super::Reason::NotSignificant
        },
        shape,
        // A discrete feature's step is between its values; a location adds nothing.
        shape_at: shape_at
            .filter(|_| b.kind == BinKind::Quantile)
            .and_then(finite),
        expected_std: residual_std * (1.0 - explained).max(0.0).sqrt(),
        n: col.defined_count(),
        missing: col.len() - col.defined_count(),
        bins: chosen.len(),
        slope: trend.and_then(|t| finite(t.slope)),
        slope_p: trend.and_then(|t| finite(t.p_value)),
        by_direction,
        linear,
        note,
        curve: display,
    }
}

/// The report of a feature that cannot be smoothed.
pub(crate) fn skipped_report(
    col: &FeatureColumn,
    why: &Unusable,
    residual_std: f64,
) -> FeatureReport {
    let note = match why {
        Unusable::Constant(v) => format!("skipped: constant (every value is {})", short(*v)),
        Unusable::NearlyConstant { value, others } => format!(
            "skipped: nearly constant (all rows but {others} are {}, too few to compare)",
            short(*value)
        ),
        Unusable::AllMissing => "skipped: undefined on every measured row".to_string(),
        Unusable::PairOnly => "not a single candidate: read jointly with `position` by the \
                                pair screen (alone it stands in for the direction of the next \
                                move, which turns back away from where the last one reversed)"
            .to_string(),
    };
    let defined = col.defined_count();
    FeatureReport {
        name: col.name.clone(),
        explained: 0.0,
        p_value: 1.0,
        explained_beyond_previous: None,
        suggested_term: None,
        alternatives: Vec::new(),
        p_value_raw: 1.0,
        significant: false,
        flagged: false,
        reason: super::Reason::NotAnalysed,
        shape: Shape::Flat,
        shape_at: None,
        expected_std: residual_std,
        n: defined,
        missing: col.len() - defined,
        bins: 0,
        slope: None,
        slope_p: None,
        by_direction: false,
        linear: false,
        note: Some(note),
        curve: Vec::new(),
    }
}

pub(super) fn is_skipped(f: &FeatureReport) -> bool {
    f.bins == 0
}

/// Whether `f` is the report of a feature only the pair screen reads
/// ([`super::pairs::pair_only`]): skipped by the single screen, but not constant or undefined.
pub(super) fn is_pair_only(f: &FeatureReport) -> bool {
    crate::history::Feature::from_name(&f.name)
        .is_some_and(|b| super::pairs::pair_only(FeatureOrigin::BuiltIn(b)))
}

/// Marginal strength order: explained (on the grid of [`EXPLAINED_TIE`]), then family-wise p,
/// then raw p, then name; skipped last (a feature only the pair screen reads before the
/// constant or undefined ones).
///
/// The permutation p-values are multiples of 1/(permutations + 1), so unflagged features often
/// share one (p = 0.005), and features that bin alike (`elapsed_s` and `seek_index`, a lagged
/// copy whose lag spans the whole log) explain the same share up to rounding. Compared exactly,
/// such ties were ordered by the last bits of the fit, and a change of the fit at rounding level
/// (the pattern-grouped QR) flipped the lower ranks. On the grid the order of a tie is decided
/// by p, then by name: the same for any rounding of the fit (unless a share straddles a grid
/// step, about one tie in 10⁴ per 1e-13 of change).
pub(crate) fn compare(a: &FeatureReport, b: &FeatureReport) -> std::cmp::Ordering {
    let rank = |f: &FeatureReport| match (is_skipped(f), is_pair_only(f)) {
        (false, _) => 0u8,
        (true, true) => 1,
        (true, false) => 2,
    };
    rank(a)
        .cmp(&rank(b))
        .then(explained_key(b).total_cmp(&explained_key(a)))
        .then(a.p_value.total_cmp(&b.p_value))
        .then(a.p_value_raw.total_cmp(&b.p_value_raw))
        .then(a.name.cmp(&b.name))
}

/// Grid on which [`compare`] reads a feature's explained share: shares closer than this are a
/// tie (rounding-level changes of a fit move a share by ~1e-13).
pub(crate) const EXPLAINED_TIE: f64 = 1e-9;

/// `f.explained` rounded to the grid of [`EXPLAINED_TIE`] (a total order: no tolerance
/// comparison, which would not be transitive).
fn explained_key(f: &FeatureReport) -> f64 {
    (f.explained / EXPLAINED_TIE).round()
}
