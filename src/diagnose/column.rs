//! One feature's column: its values stored in the narrowest exact type (or made from the
//! measured rows' times on demand), read back as the same `f64`s, and its builders.

use std::sync::Arc;

use crate::history::Feature;
use crate::log::Log;

use super::smoother::{Binned, Key, Unusable};
use super::values::defined;

/// Where a candidate feature comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FeatureOrigin {
    /// A built-in feature of the seek history.
    BuiltIn(Feature),
    /// A covariate column of the log (or any column added with [`FeatureTable::push_column`](super::FeatureTable::push_column)).
    Covariate,
    /// `memsum_L<L>`: the summed-kernel rest memory of the `memsum` term at one length scale
    /// L (the log's position unit): `Σ_p sgn(x − p)·exp(−|x − p|/L)` over every uncrossed rest
    /// position p ([`crate::model::terms::memsum`]).
    SummedMemory,
    /// `<COL>@lag<τ>s`: a covariate column through a first-order lag of time constant τ (s), as
    /// the `lag:COL` term computes it ([`crate::model::terms::lag`]).
    Lagged,
    /// [`DERIVED_VELOCITY`](super::DERIVED_VELOCITY): on a dense time series ([`crate::history::Sampling::dense`]) the
    /// velocity derived from position and time as the `viscous`/`stribeck` terms derive it
    /// without a column (`seek_length / dwell_s`, [`crate::model::terms::viscous::velocity`]),
    /// so velocity friction is found on a log with no velocity column.
    DerivedVelocity,
}
/// One candidate feature's values, one per measured row; undefined (missing) on some rows.
///
/// The values are `f64` with NaN marking an undefined row (a defined value is never NaN),
/// stored in the narrowest of `i8`, `i16`, `i32`, `f32` and `f64` that holds every one of
/// them exactly (bit for bit: a `-0.0` is not an integer), so a column of track numbers,
/// directions or seek counts costs 1–4 bytes a row instead of 8 and reads back the same
/// `f64`s. Read them with [`FeatureColumn::get`] or [`FeatureColumn::iter`], which give `None`
/// for an undefined row. The values are shared: a clone (as in [`FeatureTable::without`](super::FeatureTable::without))
/// does not copy them.
#[derive(Debug, Clone)]
pub struct FeatureColumn {
    /// The feature's name: a built-in name (`seek_length`, …) or the covariate's header name.
    pub name: String,
    /// Built-in or covariate.
    pub origin: FeatureOrigin,
    /// One value per measured row, in log order; NaN = undefined (missing).
    pub(super) values: Values,
}

/// A number type a column may be stored in: [`Narrow::encode`] gives `None` for an `f64` it
/// cannot hold exactly; [`Narrow::decode`] gives the `f64` back bit for bit (NaN for the
/// undefined mark).
pub(super) trait Narrow: Copy {
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
pub(super) enum Values {
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
/// `t[i] − t[i − 1]` on the time grid (`first_dwell` for row 0, whose previous row may be an
/// unmeasured one). Used only where every row's value equals the replay's (on the time grid)
/// bit for bit (checked as the table is built; a log with unmeasured rows between measured
/// ones keeps `dwell_s` stored).
#[derive(Debug)]
pub(super) struct Times {
    t: Vec<f64>,
    start: f64,
    first_dwell: f64,
    grid: PositionGrid,
}

/// Which time feature a [`Values::Time`] column is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum TimeKind {
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
                Some(p) => self.grid.snap(t - self.t[p]),
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
pub(super) enum Builder {
    I8(Vec<i8>),
    I16(Vec<i16>),
    I32(Vec<i32>),
    F32(Vec<f32>),
    F64(Vec<f64>),
}

/// `values` re-encoded as `T`, if every one of them fits, with room for `cap` values.
pub(super) fn reencode<T: Narrow>(values: &[f64], cap: usize) -> Option<Vec<T>> {
    let mut out = Vec::with_capacity(cap.max(values.len()));
    for &x in values {
        out.push(T::encode(x)?);
    }
    Some(out)
}

impl Builder {
    pub(super) fn with_capacity(n: usize) -> Builder {
        Builder::I8(Vec::with_capacity(n))
    }

    /// Appends `x` (NaN = undefined), widening the storage if `x` does not fit.
    #[inline]
    pub(super) fn push(&mut self, x: f64) {
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
    pub(super) fn widen(&mut self, x: f64) {
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

    pub(super) fn finish(self) -> Values {
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
pub(super) struct TimesBuilder {
    times: Times,
    elapsed: bool,
    dwell: bool,
}

impl TimesBuilder {
    /// For a log whose first row's time is `start` (`None`: no rows), with room for
    /// `measured` rows, `dwell_s` read on `grid` (the log's time grid).
    pub(super) fn new(start: Option<f64>, measured: usize, grid: PositionGrid) -> TimesBuilder {
        TimesBuilder {
            times: Times {
                t: Vec::with_capacity(measured),
                start: start.unwrap_or(0.0),
                first_dwell: 0.0,
                grid,
            },
            elapsed: start.is_some(),
            dwell: true,
        }
    }

    /// The next measured row: its time and the replay's `elapsed_s` and `dwell_s` (the latter
    /// on the time grid; NaN: undefined, which no derived value matches).
    #[inline]
    pub(super) fn push(&mut self, time: f64, elapsed: f64, dwell: f64) {
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

    pub(super) fn finish(self) -> FinishedTimes {
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
pub(super) struct FinishedTimes(Option<(Arc<Times>, bool, bool)>);

impl FinishedTimes {
    /// The values of `feature` made from the times, if it is a time feature they make.
    pub(super) fn values(&self, feature: Feature) -> Option<Values> {
        let (times, elapsed, dwell) = self.0.as_ref()?;
        match feature {
            Feature::ElapsedS if *elapsed => Some(Values::Time(times.clone(), TimeKind::Elapsed)),
            Feature::DwellS if *dwell => Some(Values::Time(times.clone(), TimeKind::Dwell)),
            _ => None,
        }
    }
}

/// The grid built-in `feature` is read on: the position grid for a length made by arithmetic
/// on positions (a difference, a sum of seek lengths), the time grid for the time between rows
/// (`dwell_s`, a difference of times); `None` for the others.
pub(super) fn grid_of(
    feature: Feature,
    positions: PositionGrid,
    times: PositionGrid,
) -> Option<PositionGrid> {
    match feature {
        Feature::SeekLength
        | Feature::SeekAbs
        | Feature::SinceReversal
        | Feature::ReversalPosition
        | Feature::RestDistanceOd
        | Feature::RestDistanceId => Some(positions),
        Feature::DwellS => Some(times),
        _ => None,
    }
}

/// Bits below the log's largest |position| that position-valued derived features keep
/// ([`PositionGrid`]).
pub(super) const POSITION_GRID_BITS: i32 = 32;

/// Bits below the log's travel they keep at least ([`PositionGrid`]).
pub(super) const TRAVEL_GRID_BITS: i32 = 24;

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
///
/// **Times the same way.** The time between rows (`dwell_s`) is a difference of times, and a
/// regular clock written in decimal is not exact in binary either: `pandas` writes 201 × 0.02 s
/// as `4.0200000000000005`, and the differences of such times take a dozen rounding variants
/// of 0.02 s that change with the size of t (the last bits of a larger t are coarser). Read
/// as they are, those variants follow the elapsed time, and `dwell_s` stood in for a drift. So
/// `dwell_s` is read on the same grid made from the log's times ([`PositionGrid::of_times`]: P
/// the largest |time|, T the time span): a regular clock gives one value, and a time step
/// moves by at most q/2 (about 1e−10 of the largest time).
#[derive(Debug, Clone, Copy)]
pub(super) struct PositionGrid(Option<f64>);

impl PositionGrid {
    /// The grid of `log`'s positions.
    pub(super) fn of(log: &Log) -> PositionGrid {
        Self::of_values(log.tracks())
    }

    /// The grid of `log`'s times (see the type's docs).
    pub(super) fn of_times(log: &Log) -> PositionGrid {
        Self::of_values(log.times())
    }

    /// The grid of values `v`: `P` their largest |value|, `T` their range.
    fn of_values(v: &[f64]) -> PositionGrid {
        let q = crate::numeric::stats::range(v)
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
    pub(super) fn snap(self, v: f64) -> f64 {
        match self.0 {
            Some(q) if !v.is_nan() => (v / q).round() * q + 0.0,
            _ => v,
        }
    }
}

/// `v` as a stored value: NaN for `None`.
#[inline]
pub(super) fn stored(v: Option<f64>) -> f64 {
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

#[cfg(test)]
mod storage_tests {
    //! The narrow column storage and the line runs against the plain vectors they replace:
    //! every value read back bit for bit, and the width the narrowest type by a direct check.
    use super::*;
    use crate::diagnose::FeatureTable;
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
    /// row (`dwell_s` rounded to the log's time grid, and within 1e-9 of the largest time of
    /// the replay's). The table makes them from the shared times where every row matches bit
    /// for bit (4 B a row each) and stores them otherwise: a log whose every row is measured
    /// makes both; one with unmeasured rows between measured ones (and an unmeasured first
    /// row) makes `elapsed_s` only and stores `dwell_s` (in 4 B a row too: on the time grid a
    /// dwell of a few seconds is an exact f32).
    #[test]
    fn time_features_made_from_the_times_equal_the_replays() {
        let full = crate::sim::random_log(3000, 5);
        let mut gaps = full.clone();
        for i in (0..3000).step_by(7) {
            gaps.set_bias(i, None);
        }
        for (log, dwell_made) in [(&full, true), (&gaps, false)] {
            let table = FeatureTable::from_log(log);
            let grid = PositionGrid::of_times(log);
            let largest = log.times().iter().fold(0.0_f64, |m, t| m.max(t.abs()));
            let want: Vec<(u64, u64)> = crate::history::replay(log)
                .filter(|(_, r, _)| r.bias.is_some())
                .map(|(_, _, f)| {
                    let v = |x: Feature| f.value(x).expect("always defined");
                    let d = v(Feature::DwellS);
                    assert!((grid.snap(d) - d).abs() <= 1e-9 * largest, "{d}");
                    (v(Feature::ElapsedS).to_bits(), grid.snap(d).to_bits())
                })
                .collect();
            assert_eq!(want.len(), table.len());
            let col = |name: &str| table.column(name).expect("a time feature");
            let (elapsed, dwell) = (col("elapsed_s"), col("dwell_s"));
            assert_eq!(elapsed.bytes_per_row(), 4);
            assert_eq!(matches!(dwell.values, Values::Time(..)), dwell_made);
            // Stored on the time grid, a dwell fits an f32 exactly.
            assert_eq!(dwell.bytes_per_row(), 4);
            let raw = (elapsed.raw(), dwell.raw());
            for (i, &(e, d)) in want.iter().enumerate() {
                assert_eq!(elapsed.get(i).map(f64::to_bits), Some(e), "row {i}");
                assert_eq!(dwell.get(i).map(f64::to_bits), Some(d), "row {i}");
                assert_eq!((raw.0[i].to_bits(), raw.1[i].to_bits()), (e, d), "row {i}");
            }
            assert_eq!(elapsed.get(want.len()), None);
        }
    }
}
