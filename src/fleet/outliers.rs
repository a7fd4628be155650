//! The drives whose parameters stand out from the fleet: a robust z per drive and parameter,
//! its distance from the fleet's median over the larger of the fleet's robust spread
//! (1.4826·MAD) and the drive's own standard error of that parameter.

use super::DriveFit;
use crate::field::Field;
use crate::numeric::stats;

/// The default |z| above which a drive's parameter is an outlier.
pub const OUTLIER_THRESHOLD: f64 = 4.0;

/// At least this many fitted drives must have a parameter for the fleet to judge it.
pub const MIN_DRIVES: usize = 3;

/// 1.4826·MAD estimates the standard deviation of normal values.
const MAD_TO_SIGMA: f64 = 1.4826;

/// Which scale divided the distance from the fleet's median: the rule that decided.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutlierRule {
    /// The fleet's spread (1.4826·MAD over the drives) was the larger scale.
    FleetSpread,
    /// The drive's own standard error of the parameter was larger than the fleet's spread.
    OwnStandardError,
}

impl OutlierRule {
    /// The rule's name in tables and JSON.
    pub const fn name(self) -> &'static str {
        match self {
            OutlierRule::FleetSpread => "robust_z_fleet_mad",
            OutlierRule::OwnStandardError => "robust_z_own_se",
        }
    }
}

impl std::fmt::Display for OutlierRule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One drive's parameter that deviates from the fleet.
#[derive(Debug, Clone, PartialEq)]
pub struct Outlier {
    /// The drive (its row's source).
    pub source: String,
    /// The parameter (`poly2.c1`).
    pub parameter: String,
    /// The drive's value.
    pub value: f64,
    /// The fleet's median of the parameter.
    pub median: f64,
    /// The scale the distance was divided by: the larger of 1.4826·MAD and the drive's SE.
    pub sigma: f64,
    /// (value − median) / scale; |z| is above the threshold.
    pub z: f64,
    /// Which scale it was.
    pub rule: OutlierRule,
}

/// A threshold that is not a finite positive number.
#[derive(Debug, thiserror::Error)]
#[error("{field} {value}: the outlier threshold must be a finite number > 0 (default 4)")]
pub struct ThresholdError {
    /// The setting ([`Field::OutlierThreshold`]).
    pub field: Field,
    /// The value given.
    pub value: f64,
}

/// Every (drive, parameter) of the fleet whose robust z exceeds `threshold` in magnitude,
/// in the order of the drives, then of the parameters; the largest |z| of a drive is not
/// singled out, every deviating parameter is listed. Drives without a fit are left out of the
/// median (their rows name their error); a parameter fewer than [`MIN_DRIVES`] drives have,
/// or whose scale is 0 (every drive the same value, no standard error), is not judged.
pub fn outliers(rows: &[DriveFit], threshold: f64) -> Result<Vec<Outlier>, ThresholdError> {
    if !(threshold.is_finite() && threshold > 0.0) {
        return Err(ThresholdError {
            field: Field::OutlierThreshold,
            value: threshold,
        });
    }
    let names = super::param_names(rows);
    let fitted: Vec<&DriveFit> = rows.iter().filter(|r| r.error.is_none()).collect();
    let mut found: Vec<(usize, usize, Outlier)> = Vec::new();
    for (k, name) in names.iter().enumerate() {
        let values: Vec<(usize, f64, Option<f64>)> = fitted
            .iter()
            .enumerate()
            .filter_map(|(i, r)| r.param(name).map(|p| (i, p.value, p.se)))
            .collect();
        if values.len() < MIN_DRIVES {
            continue;
        }
        let mut v: Vec<f64> = values.iter().map(|&(_, x, _)| x).collect();
        let Some(median) = stats::percentile_select(&mut v, 50.0) else {
            continue;
        };
        for (d, x) in v.iter_mut().zip(&values) {
            *d = (x.1 - median).abs();
        }
        let spread = MAD_TO_SIGMA * stats::percentile_select(&mut v, 50.0).unwrap_or(0.0);
        for &(i, x, se) in &values {
            let se = se.filter(|s| s.is_finite()).unwrap_or(0.0);
            let (scale, rule) = if se > spread {
                (se, OutlierRule::OwnStandardError)
            } else {
                (spread, OutlierRule::FleetSpread)
            };
            if scale.is_nan() || scale <= 0.0 {
                continue;
            }
            let z = (x - median) / scale;
            if z.abs() > threshold {
                let o = Outlier {
                    source: fitted[i].source.clone(),
                    parameter: name.clone(),
                    value: x,
                    median,
                    sigma: scale,
                    z,
                    rule,
                };
                found.push((i, k, o));
            }
        }
    }
    found.sort_by_key(|&(i, k, _)| (i, k));
    Ok(found.into_iter().map(|(_, _, o)| o).collect())
}

/// The outliers as CSV: `source,parameter,value,median,scale,z,rule`.
pub fn outliers_csv(found: &[Outlier]) -> String {
    let mut out = String::new();
    let header = [
        "source",
        "parameter",
        "value",
        "median",
        "sigma",
        "z",
        "rule",
    ];
    super::table::push_record(&mut out, &header.map(String::from));
    for o in found {
        let mut cells = vec![o.source.clone(), o.parameter.clone()];
        cells.extend([o.value, o.median, o.sigma, o.z].map(super::table::number));
        cells.push(o.rule.name().to_string());
        super::table::push_record(&mut out, &cells);
    }
    out
}
