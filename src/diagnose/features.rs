//! The candidate features of every measured row: the seek history replayed over the whole log,
//! plus every covariate column, aligned with the rows that carry a measured bias.

use std::sync::Arc;

use crate::history::{Feature, replay};
use crate::log::{Log, Units};
use crate::model::terms::lag::FirstOrderLag;
use crate::model::terms::memsum::MemsumState;

use super::DiagnoseError;
use super::smoother::{Binned, Key, Unusable};
use super::values::{defined, short};

/// Where a candidate feature comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FeatureOrigin {
    /// A built-in feature of the seek history.
    BuiltIn(Feature),
    /// A covariate column of the log (or any column added with [`FeatureTable::push_column`]).
    Covariate,
    /// `memsum_L<L>`: the summed-kernel rest memory of the `memsum` term at one length scale
    /// L (the log's position unit): `Σ_p sgn(x − p)·exp(−|x − p|/L)` over every uncrossed rest
    /// position p ([`crate::model::terms::memsum`]).
    SummedMemory,
    /// `<COL>@lag<τ>s`: a covariate column through a first-order lag of time constant τ (s), as
    /// the `lag:COL` term computes it ([`crate::model::terms::lag`]).
    Lagged,
    /// [`DERIVED_VELOCITY`]: on a dense time series ([`crate::history::Sampling::dense`]) the
    /// velocity derived from position and time as the `viscous`/`stribeck` terms derive it
    /// without a column (`seek_length / dwell_s`, [`crate::model::terms::viscous::velocity`]),
    /// so velocity friction is found on a log with no velocity column.
    DerivedVelocity,
}

/// Name of the derived-velocity feature ([`FeatureOrigin::DerivedVelocity`]), position units
/// per second.
pub const DERIVED_VELOCITY: &str = "velocity_derived";

/// Length scales of the `memsum_L` features, as fractions of the log's travel (the range of
/// positions it visits): short, medium and long memory.
pub(super) const MEMSUM_FRACTIONS: [f64; 3] = [1.0 / 64.0, 1.0 / 16.0, 1.0 / 4.0];

/// Time constants of the lagged covariates, as points on a log scale of `[median Δt, span/16]`
/// (the log's sampling interval and a sixteenth of its duration): half-way and at the top. A
/// longer lag would be a proxy for time itself (on a random-walk drift a lag of 2/3 of the
/// span explained 38 % of it and smeared the drift onto the covariate).
pub(super) const LAG_POINTS: [f64; 2] = [0.5, 1.0];

/// Share of a column's variance a lagged copy must keep to become a feature (see [`LAG_POINTS`]):
/// a lag of a fast or noisy column keeps little of it and is only a slow random series.
pub(super) const LAG_MIN_VARIANCE: f64 = 0.5;

/// Fraction of the log's duration that is the longest lag of a lagged-covariate feature.
pub(super) const LAG_MAX_FRACTION: f64 = 1.0 / 16.0;

/// The covariate a lagged feature (`<COL>@lag<τ>s`) was made from.
pub(crate) fn lagged_column(name: &str) -> Option<&str> {
    name.rsplit_once("@lag").map(|(c, _)| c)
}

/// One candidate feature's values, one per measured row; undefined (missing) on some rows.
///
/// The values are `f64` with NaN marking an undefined row (a defined value is never NaN),
/// stored in the narrowest of `i8`, `i16`, `i32`, `f32` and `f64` that holds every one of
/// them exactly (bit for bit: a `-0.0` is not an integer), so a column of track numbers,
/// directions or seek counts costs 1–4 bytes a row instead of 8 and reads back the same
/// `f64`s. Read them with [`FeatureColumn::get`] or [`FeatureColumn::iter`], which give `None`
/// for an undefined row. The values are shared: a clone (as in [`FeatureTable::without`])
/// does not copy them.
#[derive(Debug, Clone)]
pub struct FeatureColumn {
    /// The feature's name: a built-in name (`seek_length`, …) or the covariate's header name.
    pub name: String,
    /// Built-in or covariate.
    pub origin: FeatureOrigin,
    /// One value per measured row, in log order; NaN = undefined (missing).
    values: Values,
}

/// A number type a column may be stored in: [`Narrow::encode`] gives `None` for an `f64` it
/// cannot hold exactly; [`Narrow::decode`] gives the `f64` back bit for bit (NaN for the
/// undefined mark).
trait Narrow: Copy {
    fn encode(x: f64) -> Option<Self>;
    fn decode(self) -> f64;
}

macro_rules! narrow_int {
    ($t:ty) => {
        impl Narrow for $t {
            /// `MIN` marks an undefined value; an integer in `(MIN, MAX]` is stored as itself.
            #[inline]
            fn encode(x: f64) -> Option<$t> {
                if x.is_nan() {
                    return Some(<$t>::MIN);
                }
                let v = x as $t; // saturating: out-of-range values fail the check below
                (v != <$t>::MIN && f64::from(v).to_bits() == x.to_bits()).then_some(v)
            }
            #[inline]
            fn decode(self) -> f64 {
                if self == <$t>::MIN {
                    f64::NAN
                } else {
                    f64::from(self)
                }
            }
        }
    };
}
narrow_int!(i8);
narrow_int!(i16);
narrow_int!(i32);

impl Narrow for f32 {
    #[inline]
    fn encode(x: f64) -> Option<f32> {
        if x.is_nan() {
            return Some(f32::NAN);
        }
        let v = x as f32;
        (f64::from(v).to_bits() == x.to_bits()).then_some(v)
    }
    #[inline]
    fn decode(self) -> f64 {
        f64::from(self)
    }
}

impl Narrow for f64 {
    #[inline]
    fn encode(x: f64) -> Option<f64> {
        Some(x)
    }
    #[inline]
    fn decode(self) -> f64 {
        self
    }
}

macro_rules! key_int {
    ($t:ty) => {
        impl Key for $t {
            #[inline]
            fn num(self) -> f64 {
                self.decode()
            }
            /// `MIN` (undefined, NaN) above every value, as `total_cmp` puts NaN; the
            /// integers in their own order (the order of their `f64`s).
            #[inline]
            fn order(&self, other: &Self) -> std::cmp::Ordering {
                (*self == <$t>::MIN, *self).cmp(&(*other == <$t>::MIN, *other))
            }
        }
    };
}
key_int!(i8);
key_int!(i16);
key_int!(i32);

macro_rules! key_float {
    ($t:ty) => {
        impl Key for $t {
            #[inline]
            fn num(self) -> f64 {
                self.decode()
            }
            /// `total_cmp` in the stored type: an `f32`'s order is its `f64`'s (the widening
            /// is exact and keeps sign and NaN ordering).
            #[inline]
            fn order(&self, other: &Self) -> std::cmp::Ordering {
                self.total_cmp(other)
            }
        }
    };
}
key_float!(f32);
key_float!(f64);

/// A column's stored values ([`FeatureColumn`]): the narrowest exact type, or a time
/// feature made from the measured rows' times on demand ([`Times`]).
#[derive(Debug, Clone)]
enum Values {
    I8(Arc<[i8]>),
    I16(Arc<[i16]>),
    I32(Arc<[i32]>),
    F32(Arc<[f32]>),
    F64(Arc<[f64]>),
    /// `elapsed_s` or `dwell_s` of the shared times.
    Time(Arc<Times>, TimeKind),
}

/// The times of the measured rows, shared by `elapsed_s` and `dwell_s` (8 B a row for both
/// instead of 8 each): `elapsed_s` of row `i` is `t[i] − start`, `dwell_s` is
/// `t[i] − t[i − 1]` (`first_dwell` for row 0, whose previous row may be an unmeasured one).
/// Used only where every row's value equals the replay's bit for bit (checked as the table
/// is built; a log with unmeasured rows between measured ones keeps `dwell_s` stored).
#[derive(Debug)]
struct Times {
    t: Vec<f64>,
    start: f64,
    first_dwell: f64,
}

/// Which time feature a [`Values::Time`] column is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum TimeKind {
    Elapsed,
    Dwell,
}

impl Times {
    #[inline]
    fn value(&self, kind: TimeKind, i: usize) -> Option<f64> {
        let t = *self.t.get(i)?;
        Some(match kind {
            TimeKind::Elapsed => t - self.start,
            TimeKind::Dwell => match i.checked_sub(1) {
                Some(p) => t - self.t[p],
                None => self.first_dwell,
            },
        })
    }
}

/// Dispatches `$body` on the stored slice `$v` of a [`Builder`].
macro_rules! each {
    ($e:expr, $ty:ident, $v:ident => $body:expr) => {
        match $e {
            $ty::I8($v) => $body,
            $ty::I16($v) => $body,
            $ty::I32($v) => $body,
            $ty::F32($v) => $body,
            $ty::F64($v) => $body,
        }
    };
}

/// [`each!`] for a [`Values`]: `$time` for a [`Values::Time`] column (`$t`: its times,
/// `$k`: its kind).
macro_rules! each_value {
    ($e:expr, $v:ident => $body:expr, ($t:ident, $k:ident) => $time:expr) => {
        match $e {
            Values::I8($v) => $body,
            Values::I16($v) => $body,
            Values::I32($v) => $body,
            Values::F32($v) => $body,
            Values::F64($v) => $body,
            Values::Time($t, $k) => $time,
        }
    };
}

impl Values {
    fn len(&self) -> usize {
        each_value!(self, v => v.len(), (t, _k) => t.t.len())
    }

    /// The value at row `i` (NaN = undefined); `None` out of range.
    #[inline]
    fn at(&self, i: usize) -> Option<f64> {
        each_value!(self, v => v.get(i).map(|x| x.decode()), (t, k) => t.value(*k, i))
    }

    /// Every value as `f64` (borrowed when stored as `f64`).
    fn to_f64(&self) -> std::borrow::Cow<'_, [f64]> {
        match self {
            Values::F64(v) => std::borrow::Cow::Borrowed(v),
            other => std::borrow::Cow::Owned(each_value!(
                other,
                v => v.iter().map(|x| x.decode()).collect(),
                (t, k) => (0..t.t.len()).filter_map(|i| t.value(*k, i)).collect()
            )),
        }
    }

    /// Bytes a row (a time column: half of the shared 8 B of times, 4).
    fn width(&self) -> usize {
        match self {
            Values::I8(_) => 1,
            Values::I16(_) => 2,
            Values::I32(_) | Values::F32(_) | Values::Time(..) => 4,
            Values::F64(_) => 8,
        }
    }
}

impl From<Vec<f64>> for Values {
    /// `values` in the narrowest exact type.
    fn from(values: Vec<f64>) -> Values {
        let mut b = Builder::with_capacity(values.len());
        for x in values {
            b.push(x);
        }
        b.finish()
    }
}

/// A [`Values`] built row by row: it starts as `i8` and widens (re-encoding what it holds)
/// to the narrowest type that holds every value pushed so far, so no `f64` copy of a narrow
/// column is ever made.
#[derive(Debug)]
enum Builder {
    I8(Vec<i8>),
    I16(Vec<i16>),
    I32(Vec<i32>),
    F32(Vec<f32>),
    F64(Vec<f64>),
}

/// `values` re-encoded as `T`, if every one of them fits, with room for `cap` values.
fn reencode<T: Narrow>(values: &[f64], cap: usize) -> Option<Vec<T>> {
    let mut out = Vec::with_capacity(cap.max(values.len()));
    for &x in values {
        out.push(T::encode(x)?);
    }
    Some(out)
}

impl Builder {
    fn with_capacity(n: usize) -> Builder {
        Builder::I8(Vec::with_capacity(n))
    }

    /// Appends `x` (NaN = undefined), widening the storage if `x` does not fit.
    #[inline]
    fn push(&mut self, x: f64) {
        let fits = match self {
            Builder::I8(v) => i8::encode(x).map(|e| v.push(e)),
            Builder::I16(v) => i16::encode(x).map(|e| v.push(e)),
            Builder::I32(v) => i32::encode(x).map(|e| v.push(e)),
            Builder::F32(v) => f32::encode(x).map(|e| v.push(e)),
            Builder::F64(v) => {
                v.push(x);
                Some(())
            }
        };
        if fits.is_none() {
            self.widen(x);
        }
    }

    /// Re-encodes the values held and `x` in the narrowest type wider than the current one
    /// that holds them all, then appends `x`.
    #[cold]
    fn widen(&mut self, x: f64) {
        let cap = each!(&*self, Builder, v => v.capacity());
        let mut all: Vec<f64> = Vec::with_capacity(cap.max(1));
        each!(&*self, Builder, v => all.extend(v.iter().map(|y| y.decode())));
        all.push(x);
        let rank = match self {
            Builder::I8(_) => 0,
            Builder::I16(_) => 1,
            Builder::I32(_) => 2,
            Builder::F32(_) => 3,
            Builder::F64(_) => 4,
        };
        // i32 and f32 are not nested (2²⁴ + 1 is an i32, 0.5 an f32): both are tried.
        let narrower = if rank < 1 {
            reencode(&all, cap).map(Builder::I16)
        } else {
            None
        }
        .or_else(|| {
            (rank < 2)
                .then(|| reencode(&all, cap).map(Builder::I32))
                .flatten()
        })
        .or_else(|| {
            (rank < 3)
                .then(|| reencode(&all, cap).map(Builder::F32))
                .flatten()
        });
        *self = narrower.unwrap_or(Builder::F64(all));
    }

    fn finish(self) -> Values {
        match self {
            Builder::I8(v) => Values::I8(v.into()),
            Builder::I16(v) => Values::I16(v.into()),
            Builder::I32(v) => Values::I32(v.into()),
            Builder::F32(v) => Values::F32(v.into()),
            Builder::F64(v) => Values::F64(v.into()),
        }
    }
}

/// The measured rows' times and whether `elapsed_s` and `dwell_s` can be made from them
/// ([`Times`]): each row's derived value is compared bit for bit with the replay's as the
/// table is built.
struct TimesBuilder {
    times: Times,
    elapsed: bool,
    dwell: bool,
}

impl TimesBuilder {
    /// For a log whose first row's time is `start` (`None`: no rows), with room for
    /// `measured` rows.
    fn new(start: Option<f64>, measured: usize) -> TimesBuilder {
        TimesBuilder {
            times: Times {
                t: Vec::with_capacity(measured),
                start: start.unwrap_or(0.0),
                first_dwell: 0.0,
            },
            elapsed: start.is_some(),
            dwell: true,
        }
    }

    /// The next measured row: its time and the replay's `elapsed_s` and `dwell_s` (NaN:
    /// undefined, which no derived value matches).
    #[inline]
    fn push(&mut self, time: f64, elapsed: f64, dwell: f64) {
        if !(self.elapsed || self.dwell) {
            return;
        }
        let t = &mut self.times;
        if t.t.is_empty() {
            t.first_dwell = dwell;
        }
        t.t.push(time);
        let i = t.t.len() - 1;
        let same = |kind, want: f64| {
            t.value(kind, i)
                .is_some_and(|v| v.to_bits() == want.to_bits() && !want.is_nan())
        };
        self.elapsed &= same(TimeKind::Elapsed, elapsed);
        self.dwell &= same(TimeKind::Dwell, dwell);
    }

    fn finish(self) -> FinishedTimes {
        let TimesBuilder {
            mut times,
            elapsed,
            dwell,
        } = self;
        if !(elapsed || dwell) {
            return FinishedTimes(None);
        }
        times.t.shrink_to_fit();
        FinishedTimes(Some((Arc::new(times), elapsed, dwell)))
    }
}

/// The shared times and which of `elapsed_s`, `dwell_s` they make ([`TimesBuilder::finish`]).
struct FinishedTimes(Option<(Arc<Times>, bool, bool)>);

impl FinishedTimes {
    /// The values of `feature` made from the times, if it is a time feature they make.
    fn values(&self, feature: Feature) -> Option<Values> {
        let (times, elapsed, dwell) = self.0.as_ref()?;
        match feature {
            Feature::ElapsedS if *elapsed => Some(Values::Time(times.clone(), TimeKind::Elapsed)),
            Feature::DwellS if *dwell => Some(Values::Time(times.clone(), TimeKind::Dwell)),
            _ => None,
        }
    }
}

/// Whether built-in `feature` is a length made by arithmetic on positions (a difference, a sum
/// of seek lengths), so [`PositionGrid::snap`] applies to it.
fn snaps(feature: Feature) -> bool {
    matches!(
        feature,
        Feature::SeekLength
            | Feature::SeekAbs
            | Feature::SinceReversal
            | Feature::RestDistanceOd
            | Feature::RestDistanceId
    )
}

/// Bits below the log's largest |position| that position-valued derived features keep
/// ([`PositionGrid`]).
const POSITION_GRID_BITS: i32 = 32;

/// Bits below the log's travel they keep at least ([`PositionGrid`]).
const TRAVEL_GRID_BITS: i32 = 24;

/// **The unit convention of derived position features.** Seek lengths, `since_reversal` and rest
/// distances ([`snaps`], and the seek length inside [`DERIVED_VELOCITY`]) are differences and
/// sums of positions; in a unit where positions are not exact binary numbers (tracks × 0.05,
/// µm → mm) two lengths equal in tracks (100 − 50, 200 − 150) come out unequal in the last bits,
/// and the quantile bins of the smoother broke those ties differently, so the diagnosis depended
/// on the unit. Every such value is therefore rounded to a grid of spacing
/// `q = 2^⌈log₂ min(2⁻³² P, 2⁻²⁴ T)⌉`, P the log's largest |position| and T its travel (a power
/// of two, so the rounding is exact). The rounding error of a difference or sum of positions is
/// some 2⁻⁵² P, about 2⁻²⁰ of q, so lengths equal in one unit meet on the same grid point in any
/// other (except with a chance of about 1e−6 per distinct value; more on a log whose positions
/// sit more than 256 travels from zero, where q is held at 2⁻²⁴ T so lengths keep their
/// resolution). Whole-track lengths (T < 2²⁴ tracks) lie on the grid already and are unchanged;
/// in other units a length moves by at most q/2 (about 1e−10 P). `None` (no snapping) for a log
/// that never moves.
#[derive(Debug, Clone, Copy)]
struct PositionGrid(Option<f64>);

impl PositionGrid {
    /// The grid of `log`'s positions.
    fn of(log: &Log) -> PositionGrid {
        let q = crate::numeric::stats::range(log.tracks())
            .map(|[a, b]| {
                let (p, t) = (a.abs().max(b.abs()), b - a);
                (p * 2f64.powi(-POSITION_GRID_BITS)).min(t * 2f64.powi(-TRAVEL_GRID_BITS))
            })
            .filter(|q| q.is_finite() && *q > 0.0)
            .map(|q| 2f64.powi(q.log2().ceil() as i32))
            .filter(|q| q.is_normal());
        PositionGrid(q)
    }

    /// `v` rounded to the nearest grid point (NaN, undefined, stays NaN; a zero is `+0.0`).
    #[inline]
    fn snap(self, v: f64) -> f64 {
        match self.0 {
            Some(q) if !v.is_nan() => (v / q).round() * q + 0.0,
            _ => v,
        }
    }
}

/// `v` as a stored value: NaN for `None`.
#[inline]
fn stored(v: Option<f64>) -> f64 {
    v.unwrap_or(f64::NAN)
}

impl PartialEq for FeatureColumn {
    /// Same name, origin and values, an undefined row equal to an undefined row (and a
    /// defined value equal only to the same value), however each side is stored.
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
            && self.origin == other.origin
            && self.len() == other.len()
            && self
                .iter()
                .zip(other.iter())
                .all(|(a, b)| a.map(f64::to_bits) == b.map(f64::to_bits))
    }
}

impl FeatureColumn {
    /// Number of measured rows (defined or not).
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Whether the column has no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The value at measured row `i` (0-based); `None` where it is undefined or `i` is out
    /// of range.
    pub fn get(&self, i: usize) -> Option<f64> {
        self.values.at(i).and_then(defined)
    }

    /// Every row's value in log order; `None` where it is undefined.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = Option<f64>> + Clone + '_ {
        (0..self.len()).map(move |i| self.get(i))
    }

    /// Number of rows with a defined value.
    pub fn defined_count(&self) -> usize {
        self.iter().filter(Option::is_some).count()
    }

    /// Bytes a row the values are stored in (1, 2, 4 or 8).
    pub fn bytes_per_row(&self) -> usize {
        self.values.width()
    }

    /// `v`'s pass over the column's values as `f64`s (NaN = undefined), decoded as they are
    /// read: one loop per stored type, no decoded copy of the column.
    pub(crate) fn visit<V: Visit>(&self, v: V) -> V::Out {
        each_value!(
            &self.values,
            s => v.rows(s.iter().map(|x| x.decode())),
            (t, k) => v.rows((0..t.t.len()).map(move |i| stored(t.value(*k, i))))
        )
    }

    /// [`Binned::new`] of the column's values, read in their stored type (no decoded `f64`
    /// copy per call: [`Binned::of_keys`]); a time column's values made row by row.
    pub(crate) fn binned(
        &self,
        max_bins: usize,
        min_bin_rows: usize,
        max_discrete: usize,
    ) -> Result<Binned, Unusable> {
        each_value!(
            &self.values,
            v => Binned::of_keys(|| v.iter().copied(), max_bins, min_bin_rows, max_discrete),
            (t, k) => Binned::of_keys(
                || (0..t.t.len()).map(|i| stored(t.value(*k, i))),
                max_bins,
                min_bin_rows,
                max_discrete,
            )
        )
    }

    /// The values as `f64`, NaN = undefined (never passed on to an output): borrowed when
    /// stored as `f64`, else decoded into a new vector that lives as long as the caller
    /// keeps it.
    pub(crate) fn raw(&self) -> std::borrow::Cow<'_, [f64]> {
        self.values.to_f64()
    }
}

/// A pass over a column's values ([`FeatureColumn::visit`]), compiled once per stored type.
pub(crate) trait Visit {
    /// What the pass gives.
    type Out;
    /// The pass over `x`, every row's value as `f64` in row order (NaN = undefined).
    fn rows<I: ExactSizeIterator<Item = f64> + Clone>(self, x: I) -> Self::Out;
}

/// Candidate features aligned with the measured rows of a log.
///
/// Built with [`FeatureTable::from_log`]: the [`History`](crate::history::History) is replayed over **all** rows (a move
/// that was not measured still changes direction, reversals and rest memory), and the values are
/// kept only for rows with a measured bias, so they line up with one residual per measured row.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FeatureTable {
    lines: Lines,
    columns: Vec<FeatureColumn>,
    units: Units,
}

/// The log line numbers of the measured rows, as runs of consecutive lines (a log without
/// comment lines or unmeasured rows between its rows is one run): a few bytes in all instead
/// of 8 a row.
#[derive(Debug, Clone, PartialEq, Default)]
struct Lines {
    /// `(first row, its line)` of each run, rows increasing; row `i` of the run starting at
    /// row `r` with line `l` is on line `l + (i − r)`. Maximal runs, so equal line lists have
    /// equal runs.
    runs: Arc<[(usize, u64)]>,
    len: usize,
}

impl Lines {
    fn new(lines: impl IntoIterator<Item = u64>) -> Lines {
        let mut b = LinesBuilder::default();
        lines.into_iter().for_each(|l| b.push(l));
        b.finish()
    }

    fn get(&self, i: usize) -> Option<u64> {
        if i >= self.len {
            return None;
        }
        let run = self.runs.partition_point(|&(r, _)| r <= i);
        let (r, l) = self.runs[run.checked_sub(1)?];
        Some(l + (i - r) as u64)
    }
}

/// [`Lines`] built line by line.
#[derive(Debug, Default)]
struct LinesBuilder {
    runs: Vec<(usize, u64)>,
    len: usize,
}

impl LinesBuilder {
    #[inline]
    fn push(&mut self, line: u64) {
        let continues = self
            .runs
            .last()
            .is_some_and(|&(r, l)| l.checked_add((self.len - r) as u64) == Some(line));
        if !continues {
            self.runs.push((self.len, line));
        }
        self.len += 1;
    }

    fn finish(self) -> Lines {
        Lines {
            runs: self.runs.into(),
            len: self.len,
        }
    }
}

/// The `memsum_L` features at [`MEMSUM_FRACTIONS`] of the log's travel (none if it never moves).
fn summed_memory(log: &Log) -> Vec<FeatureColumn> {
    let Some(travel) = crate::numeric::stats::range(log.tracks())
        .map(|[a, b]| b - a)
        .filter(|t| *t > 0.0)
    else {
        return Vec::new();
    };
    MEMSUM_FRACTIONS
        .iter()
        .map(|f| {
            let l = f * travel;
            let mut state = MemsumState::new(l);
            let mut source = None;
            let mut values = Builder::with_capacity(log.measured_count());
            for row in log.rows() {
                let from = source.unwrap_or(row.track);
                if row.bias.is_some() {
                    values.push(state.value_after_move(from, row.track));
                }
                state.apply_move(from, row.track);
                source = Some(row.track);
            }
            FeatureColumn {
                name: format!("memsum_L{}", short(l)),
                origin: FeatureOrigin::SummedMemory,
                values: values.finish(),
            }
        })
        .collect()
}

/// Every covariate through first-order lags at [`LAG_POINTS`] of `[median Δt, span/16]`
/// (none if that range is empty: a log too short or too coarse for a lag to show). `measured` holds each covariate's values at
/// the measured rows (for the skip of non-finite ones); the lag runs over every row.
fn lagged(log: &Log, measured: &[Vec<f64>]) -> Vec<FeatureColumn> {
    let times = log.times();
    let steps: Vec<f64> = times
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    let median =
        crate::numeric::stats::percentile_sorted(&crate::numeric::stats::sorted(&steps), 50.0);
    let span = times.last().map_or(0.0, |t| *t) - times.first().map_or(0.0, |t| *t);
    let hi = LAG_MAX_FRACTION * span;
    let Some(lo) = median.filter(|&m| m > 0.0 && hi > m) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (k, name) in log.schema.covariates.iter().enumerate() {
        if measured
            .get(k)
            .is_some_and(|v| v.iter().any(|x| x.is_nan()))
        {
            continue; // a gap in the column would stall the lag
        }
        let raw: &[f64] = &measured[k];
        let raw_var = crate::numeric::stats::std_dev(raw).map_or(0.0, |s| s * s);
        for p in LAG_POINTS {
            let tau = lo * (hi / lo).powf(p);
            let mut lag = FirstOrderLag::new(tau);
            let lagged: Vec<f64> = log
                .rows()
                .filter_map(|r| {
                    let z = lag.step(r.time_s, r.covariates.get(k).unwrap_or(0.0));
                    r.bias.is_some().then_some(z)
                })
                .collect();
            // A lag that keeps less than LAG_MIN_VARIANCE of the column's variance mostly
            // averages the column's own noise into a slow random series, which would match any
            // slow residual by chance: no feature then.
            let var = crate::numeric::stats::std_dev(&lagged).map_or(0.0, |s| s * s);
            if !(var >= LAG_MIN_VARIANCE * raw_var && var > 0.0) {
                continue;
            }
            out.push(FeatureColumn {
                name: format!("{name}@lag{}s", short(tau)),
                origin: FeatureOrigin::Lagged,
                values: Values::from(lagged),
            });
        }
    }
    out
}

impl FeatureTable {
    /// Replays the seek history over every row of `log` and collects, for every measured row,
    /// every built-in feature ([`Feature::ALL`]), the summed-memory features `memsum_L<L>` at
    /// `MEMSUM_FRACTIONS` of the log's travel, every covariate through lags at `LAG_POINTS`
    /// (`<COL>@lag<τ>s`), and every covariate column under its header name. Non-finite covariate values are kept as missing. The log's units
    /// ([`crate::log::LogSchema::units`]) come along and label the diagnosis.
    pub fn from_log(log: &Log) -> FeatureTable {
        Self::from_replay(log, replay(log))
    }

    /// [`FeatureTable::from_log`] with the seek history of `log` replayed by `history` (for
    /// direction read another way: `crate::history::replay_with`).
    pub fn from_replay(log: &Log, history: crate::history::Replay<'_>) -> FeatureTable {
        let measured = log.measured_count();
        let mut builtin: Vec<Builder> = Feature::ALL
            .iter()
            .map(|_| Builder::with_capacity(measured))
            .collect();
        let mut covariates: Vec<Vec<f64>> = log
            .schema
            .covariates
            .iter()
            .map(|_| Vec::with_capacity(measured))
            .collect();
        let mut lines = LinesBuilder::default();
        let dense = crate::history::sampling(log.times(), log.tracks()).dense;
        let mut velocity = Builder::with_capacity(if dense { measured } else { 0 });
        let mut times = TimesBuilder::new(log.times().first().copied(), measured);
        let grid = PositionGrid::of(log);
        let snapped: Vec<bool> = Feature::ALL.iter().map(|&f| snaps(f)).collect();
        for (_, row, f) in history {
            if row.bias.is_none() {
                continue;
            }
            lines.push(row.line);
            times.push(
                row.time_s,
                stored(f.value(Feature::ElapsedS)),
                stored(f.value(Feature::DwellS)),
            );
            if dense {
                // The rule of `viscous::velocity` without a column: 0 at a zero dwell or a
                // quotient that is not finite.
                let l = f.value(Feature::SeekLength).map(|l| grid.snap(l));
                let v = match (l, f.value(Feature::DwellS)) {
                    (Some(l), Some(d)) if d > 0.0 && (l / d).is_finite() => l / d,
                    _ => 0.0,
                };
                velocity.push(v);
            }
            for ((col, &feature), &snap) in builtin.iter_mut().zip(&Feature::ALL).zip(&snapped) {
                let v = stored(f.value(feature));
                col.push(if snap { grid.snap(v) } else { v });
            }
            for (k, col) in covariates.iter_mut().enumerate() {
                col.push(stored(row.covariates.get(k).filter(|v| v.is_finite())));
            }
        }
        let times = times.finish();
        let mut columns: Vec<FeatureColumn> = Feature::ALL
            .iter()
            .zip(builtin)
            .map(|(&feature, values)| FeatureColumn {
                name: feature.name().to_string(),
                origin: FeatureOrigin::BuiltIn(feature),
                values: times.values(feature).unwrap_or_else(|| values.finish()),
            })
            .collect();
        if dense {
            columns.push(FeatureColumn {
                name: DERIVED_VELOCITY.to_string(),
                origin: FeatureOrigin::DerivedVelocity,
                values: velocity.finish(),
            });
        }
        columns.extend(summed_memory(log));
        columns.extend(lagged(log, &covariates));
        columns.extend(
            log.schema
                .covariates
                .iter()
                .zip(covariates)
                .map(|(name, values)| FeatureColumn {
                    name: name.clone(),
                    origin: FeatureOrigin::Covariate,
                    values: values.into(),
                }),
        );
        FeatureTable {
            lines: lines.finish(),
            columns,
            units: log.schema.units.clone(),
        }
    }

    /// A table without features for measured rows whose log lines are `lines` (one per row,
    /// used in messages); add features with [`FeatureTable::push_column`]. Its units are counts
    /// and tracks until [`FeatureTable::with_units`] says otherwise.
    pub fn with_lines(lines: Vec<u64>) -> FeatureTable {
        FeatureTable {
            lines: Lines::new(lines),
            columns: Vec::new(),
            units: Units::default(),
        }
    }

    /// The table with the residual's and position's units set to `units`.
    pub fn with_units(mut self, units: Units) -> FeatureTable {
        self.units = units;
        self
    }

    /// The units of the residual (bias) and of the position-like features.
    pub fn units(&self) -> &Units {
        &self.units
    }

    /// Adds a covariate-like feature column. Errors if its length differs from the number of
    /// measured rows or its name is already taken. Non-finite values are kept as missing.
    pub fn push_column(
        &mut self,
        name: &str,
        values: Vec<Option<f64>>,
    ) -> Result<(), DiagnoseError> {
        if values.len() != self.len() {
            return Err(DiagnoseError::ColumnLength {
                name: name.to_string(),
                values: values.len(),
                rows: self.len(),
            });
        }
        if self.column(name).is_some() {
            return Err(DiagnoseError::DuplicateColumn {
                name: name.to_string(),
            });
        }
        let mut stored_values = Builder::with_capacity(values.len());
        for v in values {
            stored_values.push(stored(v.filter(|x| x.is_finite())));
        }
        let values = stored_values.finish();
        self.columns.push(FeatureColumn {
            name: name.to_string(),
            origin: FeatureOrigin::Covariate,
            values,
        });
        Ok(())
    }

    /// Number of measured rows.
    pub fn len(&self) -> usize {
        self.lines.len
    }

    /// Whether the table has no measured rows.
    pub fn is_empty(&self) -> bool {
        self.lines.len == 0
    }

    /// The log line of each measured row (made from the table's runs of consecutive lines).
    pub fn lines(&self) -> Vec<u64> {
        (0..self.len()).filter_map(|i| self.line(i)).collect()
    }

    /// The log line of measured row `i` (0-based); `None` out of range.
    pub fn line(&self, i: usize) -> Option<u64> {
        self.lines.get(i)
    }

    /// All feature columns: built-in features in [`Feature::ALL`] order, then covariates.
    pub fn columns(&self) -> &[FeatureColumn] {
        &self.columns
    }

    /// The column called `name`, if any.
    pub fn column(&self, name: &str) -> Option<&FeatureColumn> {
        self.columns.iter().find(|c| c.name == name)
    }

    /// This table without the columns for which `drop` is true (rows, units and origins kept).
    pub fn without(&self, drop: impl Fn(&FeatureColumn) -> bool) -> FeatureTable {
        FeatureTable {
            lines: self.lines.clone(),
            columns: self.columns.iter().filter(|c| !drop(c)).cloned().collect(),
            units: self.units.clone(),
        }
    }
}

#[cfg(test)]
mod storage_tests {
    //! The narrow column storage and the line runs against the plain vectors they replace:
    //! every value read back bit for bit, and the width the narrowest type by a direct check.
    use super::*;
    use crate::numeric::rng::SimRng;

    /// The reference width: the first of i8, i16, i32, f32, f64 (in that order) in which every
    /// value converts to and back bit for bit, the integers' MIN kept for the undefined mark.
    fn narrowest(values: &[f64]) -> usize {
        let int = |lo: f64, hi: f64| {
            values.iter().all(|&x| {
                x.is_nan()
                    || (x.fract() == 0.0 && x > lo && x <= hi && x.to_bits() != (-0.0f64).to_bits())
            })
        };
        let f32_exact = values
            .iter()
            .all(|&x| x.is_nan() || f64::from(x as f32).to_bits() == x.to_bits());
        if int(-128.0, 127.0) {
            1
        } else if int(-32768.0, 32767.0) {
            2
        } else if int(-2147483648.0, 2147483647.0) || f32_exact {
            4
        } else {
            8
        }
    }

    fn check(values: &[f64]) {
        let stored = Values::from(values.to_vec());
        let col = FeatureColumn {
            name: "x".into(),
            origin: FeatureOrigin::Covariate,
            values: stored,
        };
        assert_eq!(col.len(), values.len());
        assert_eq!(col.bytes_per_row(), narrowest(values), "{values:?}");
        let raw = col.raw();
        for (i, &x) in values.iter().enumerate() {
            let want = defined(x).map(f64::to_bits);
            assert_eq!(col.get(i).map(f64::to_bits), want, "row {i} of {values:?}");
            assert_eq!(
                defined(raw[i]).map(f64::to_bits),
                want,
                "row {i} of {values:?}"
            );
        }
        assert_eq!(col.get(values.len()), None);
        let listed: Vec<Option<u64>> = col.iter().map(|v| v.map(f64::to_bits)).collect();
        let want: Vec<Option<u64>> = values
            .iter()
            .map(|&x| defined(x).map(f64::to_bits))
            .collect();
        assert_eq!(listed, want);
        assert_eq!(
            col.defined_count(),
            values.iter().filter(|x| !x.is_nan()).count()
        );
    }

    /// A pass that collects what it reads ([`FeatureColumn::visit`]).
    struct Collect;

    impl Visit for Collect {
        type Out = Vec<u64>;
        fn rows<I: ExactSizeIterator<Item = f64> + Clone>(self, x: I) -> Vec<u64> {
            let n = x.len();
            let v: Vec<u64> = x.map(f64::to_bits).collect();
            assert_eq!(v.len(), n);
            v
        }
    }

    /// Reference: the decoded column (`raw`) — the values `visit` reads, bit for bit, and
    /// `Binned::new` of them, which `binned` (the column read in its stored type, compared
    /// in that type) must equal: the same fine slots, bins and levels, or the same reason
    /// for none. Every stored type, with and without undefined rows, discrete and quantile
    /// bins, pooled and unpooled undefined rows, −0 beside +0.
    #[test]
    fn binning_and_passes_in_the_stored_type_equal_the_decoded_columns() {
        let nan = f64::NAN;
        let mut rng = SimRng::new(11);
        let mut lists: Vec<Vec<f64>> = vec![
            vec![nan; 40],
            vec![3.0; 40],
            [1.0, -0.0, 0.0, -0.0, 2.0, 0.0, nan, 1.0].repeat(10),
            [vec![7.0; 38], vec![nan, 2.0]].concat(),
        ];
        for scale in [1.0, 100.0, 1e4, 1e9] {
            for holes in [0usize, 3, 200] {
                let mut ints: Vec<f64> = (0..2000)
                    .map(|_| (rng.range(-1.0, 1.0) * scale).round())
                    .collect();
                let mut reals: Vec<f64> = (0..2000).map(|_| rng.range(-1.0, 1.0) * scale).collect();
                let mut halves: Vec<f64> = (0..2000)
                    .map(|_| f64::from((rng.range(-1.0, 1.0) * scale) as f32))
                    .collect();
                for _ in 0..holes {
                    let i = rng.below(2000) as usize;
                    ints[i] = nan;
                    reals[i] = nan;
                    halves[i] = nan;
                }
                lists.extend([ints, reals, halves]);
            }
        }
        let mut widths = std::collections::BTreeSet::new();
        for values in &lists {
            let col = FeatureColumn {
                name: "x".into(),
                origin: FeatureOrigin::Covariate,
                values: Values::from(values.clone()),
            };
            widths.insert(col.bytes_per_row());
            let raw = col.raw();
            let want: Vec<u64> = raw.iter().map(|x| x.to_bits()).collect();
            assert_eq!(col.visit(Collect), want);
            for (max_bins, min_rows, max_discrete) in [(64, 30, 10), (512, 1, 10), (8, 5, 300)] {
                let slow = Binned::new(&raw, max_bins, min_rows, max_discrete);
                let fast = col.binned(max_bins, min_rows, max_discrete);
                match (slow, fast) {
                    (Ok(a), Ok(b)) => {
                        assert_eq!(a.fine, b.fine);
                        assert_eq!((a.n_fine, a.kind, &a.levels), (b.n_fine, b.kind, &b.levels));
                    }
                    (Err(a), Err(b)) => assert_eq!(format!("{a:?}"), format!("{b:?}")),
                    (a, b) => panic!("{a:?} against {b:?}"),
                }
            }
        }
        assert_eq!(widths.into_iter().collect::<Vec<_>>(), [1, 2, 4, 8]);
        // The time columns, made row by row.
        let table = FeatureTable::from_log(&crate::sim::random_log(3000, 5));
        for name in ["elapsed_s", "dwell_s"] {
            let col = table.column(name).expect("a time feature");
            let raw = col.raw();
            let want: Vec<u64> = raw.iter().map(|x| x.to_bits()).collect();
            assert_eq!(col.visit(Collect), want);
            let slow = Binned::new(&raw, 64, 30, 10).expect("usable");
            let fast = col.binned(64, 30, 10).expect("usable");
            assert_eq!(slow.fine, fast.fine);
            assert_eq!(slow.levels, fast.levels);
        }
    }

    #[test]
    fn narrow_storage_reads_back_every_value_bit_for_bit() {
        let nan = f64::NAN;
        // Each list widens at its end (the re-encoding of what was held is exercised).
        for values in [
            vec![],
            vec![nan, nan],
            vec![0.0, 1.0, -1.0, nan, 127.0, -127.0],
            vec![1.0, 2.0, -128.0],
            vec![1.0, nan, 300.0, -32767.0],
            vec![1.0, 2.0, -32768.0],
            vec![1.0, 70000.0, -2147483647.0, nan],
            vec![1.0, 2.0, 16777217.0],
            vec![1.0, 2.0, 0.5, -1.25e-3f32 as f64, nan],
            vec![1.0, -0.0],
            vec![5.0, 16777217.0, 0.5],
            vec![1.0, 0.1],
            vec![3.0, 1e300, 1e-310, nan],
            vec![1.0, 2147483648.0],
            vec![f64::INFINITY, 1.0],
        ] {
            check(&values);
        }
        let mut rng = SimRng::new(7);
        for scale in [1.0, 100.0, 1e4, 1e9] {
            let ints: Vec<f64> = (0..500)
                .map(|_| (rng.range(-1.0, 1.0) * scale).round())
                .collect();
            check(&ints);
            let reals: Vec<f64> = (0..500).map(|_| rng.range(-1.0, 1.0) * scale).collect();
            check(&reals);
        }
    }

    /// Reference: the seek-history replay's own `elapsed_s` and `dwell_s` at every measured
    /// row. The table makes them from the shared times where every row matches bit for bit
    /// (4 B a row each) and stores them otherwise: a log whose every row is measured makes
    /// both; one with unmeasured rows between measured ones (and an unmeasured first row)
    /// makes `elapsed_s` only.
    #[test]
    fn time_features_made_from_the_times_equal_the_replays() {
        let full = crate::sim::random_log(3000, 5);
        let mut gaps = full.clone();
        for i in (0..3000).step_by(7) {
            gaps.set_bias(i, None);
        }
        for (log, dwell_made) in [(&full, true), (&gaps, false)] {
            let table = FeatureTable::from_log(log);
            let want: Vec<(u64, u64)> = crate::history::replay(log)
                .filter(|(_, r, _)| r.bias.is_some())
                .map(|(_, _, f)| {
                    let v = |x: Feature| f.value(x).expect("always defined").to_bits();
                    (v(Feature::ElapsedS), v(Feature::DwellS))
                })
                .collect();
            assert_eq!(want.len(), table.len());
            let col = |name: &str| table.column(name).expect("a time feature");
            let (elapsed, dwell) = (col("elapsed_s"), col("dwell_s"));
            assert_eq!(elapsed.bytes_per_row(), 4);
            assert_eq!(dwell.bytes_per_row(), if dwell_made { 4 } else { 8 });
            let raw = (elapsed.raw(), dwell.raw());
            for (i, &(e, d)) in want.iter().enumerate() {
                assert_eq!(elapsed.get(i).map(f64::to_bits), Some(e), "row {i}");
                assert_eq!(dwell.get(i).map(f64::to_bits), Some(d), "row {i}");
                assert_eq!((raw.0[i].to_bits(), raw.1[i].to_bits()), (e, d), "row {i}");
            }
            assert_eq!(elapsed.get(want.len()), None);
        }
    }

    #[test]
    fn line_runs_give_back_every_line() {
        for lines in [
            vec![],
            vec![5],
            vec![2, 3, 4, 5],
            vec![2, 4, 5, 6, 9, 10, 11, 12, 40],
            vec![7, 7, 8, u64::MAX - 1, u64::MAX, 0, 1],
        ] {
            let t = FeatureTable::with_lines(lines.clone());
            assert_eq!(t.len(), lines.len());
            assert_eq!(t.lines(), lines);
            for (i, &l) in lines.iter().enumerate() {
                assert_eq!(t.line(i), Some(l));
            }
            assert_eq!(t.line(lines.len()), None);
        }
        // A run per gap, not per row.
        let t = FeatureTable::with_lines((10..1000).chain(2000..3000).collect());
        assert_eq!(t.lines.runs.len(), 2);
    }
}
