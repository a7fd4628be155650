//! The fleet's verdict on the pooled suggestion: the drives' refits
//! ([`super::verify_drive`]) pooled per candidate into the fleet's gain and z, the candidate
//! chosen and judged by the rule of [`super::verify`]'s module docs; and the whole verified
//! fleet diagnosis of a list of files on one machine ([`diagnose_paths`]).

use std::path::PathBuf;

use rayon::prelude::*;

use super::ReadSettings;
use super::pooled::{DriveScreen, FleetDiagnosis, PoolError, pool, screen_path, summary};
use super::verify::{DriveEdit, DriveVerification, TriedEdit, verify_path};
use crate::diagnose::CheckedDiagnoseConfig;
use crate::fit::CheckedFitOptions;
use crate::model::ModelSpec;
use crate::select::CheckedVerifyConfig;

/// Screens every path's drive on rayon's pool and pools them ([`pool`]); with `verify`, then
/// refits every drive with the pooled suggestion and pools the refits
/// ([`pool_verifications`], the refits' settings and fit options `verify`'s).
pub fn diagnose_paths(
    paths: &[PathBuf],
    read: &ReadSettings,
    spec: &ModelSpec,
    opts: &CheckedFitOptions,
    config: &CheckedDiagnoseConfig,
    verify: Option<&CheckedVerifyConfig>,
) -> Result<FleetDiagnosis, PoolError> {
    let screens: Vec<DriveScreen> = paths
        .par_iter()
        .map(|p| screen_path(p, read, spec, opts, config))
        .collect();
    let default = CheckedVerifyConfig::default();
    let mut d = pool(&screens, config, verify.unwrap_or(&default))?;
    if let (Some(v), false) = (verify, d.verification.candidates.is_empty()) {
        // The drives the pool screened, each read again (no log is held through the screens).
        let screened: Vec<&PathBuf> = paths
            .iter()
            .zip(&screens)
            .filter(|(_, s)| s.screen.is_ok())
            .map(|(p, _)| p)
            .collect();
        let terms = d.verification.candidates.clone();
        let drives: Vec<DriveVerification> = screened
            .par_iter()
            .flat_map_iter(|p| verify_path(p, read, spec, &terms, config.min_effect, v))
            .collect();
        pool_verifications(&mut d, &drives);
    }
    Ok(d)
}

/// The fleet's gain and z of the drives' figures (see the module docs): none without a drive.
fn pooled(per: &[DriveEdit]) -> Option<(f64, f64)> {
    if per.is_empty() {
        return None;
    }
    let sum = |f: fn(&DriveEdit) -> f64| per.iter().map(f).sum::<f64>();
    let (before, after) = (sum(|e| e.sse_before), sum(|e| e.sse_after));
    let gain = if before > 0.0 {
        (before - after) / before
    } else {
        0.0
    };
    let se = sum(|e| e.loss_se * e.loss_se).sqrt();
    let z = if se > 0.0 {
        sum(|e| e.loss_gain) / se
    } else {
        0.0
    };
    Some((gain, z))
}

/// Pools the drives' refits with the candidates
/// ([`FleetVerification::candidates`](super::FleetVerification::candidates)) into the fleet's
/// verdict (per candidate the gain Σ (SSE_before − SSE_after) / Σ SSE_before and the z
/// Σ Tᵢ / √(Σ sᵢ²); the candidate chosen as `diagnose` chooses among a feature's terms;
/// verified iff z reaches [`FleetVerification::z_bar`](super::FleetVerification::z_bar) and
/// the gain is positive), sets [`FleetDiagnosis::best_edit`] and the summary. The drives'
/// order does not change it. Does nothing when the pooled screen has no edit to verify;
/// refits of other terms are ignored.
pub fn pool_verifications(d: &mut FleetDiagnosis, drives: &[DriveVerification]) {
    let v = &mut d.verification;
    if v.candidates.is_empty() {
        return;
    }
    let mut order: Vec<&DriveVerification> = drives.iter().collect();
    order.sort_by(|a, b| a.source.cmp(&b.source));
    let of = |term: &str| -> (Vec<DriveEdit>, Vec<(String, String)>) {
        let mine = order.iter().filter(|r| r.term == term);
        let ok = mine.clone().filter_map(|r| r.result.as_ref().ok().cloned());
        let failed = mine.filter_map(|r| {
            r.result
                .as_ref()
                .err()
                .map(|e| (r.source.clone(), e.clone()))
        });
        (ok.collect(), failed.collect())
    };
    v.tried = v
        .candidates
        .iter()
        .map(|t| {
            let (per, _) = of(t);
            let p = pooled(&per);
            TriedEdit {
                term: t.clone(),
                drives: per.len(),
                gain: p.map(|p| p.0),
                z: p.map(|p| p.1),
            }
        })
        .collect();
    // As `diagnose` chooses among a feature's terms: the largest gain of all, or the first
    // that fitted.
    let refitted = v.tried.iter().filter(|t| t.drives > 0);
    let chosen = if v.try_all {
        refitted
            .reduce(|a, b| if b.gain > a.gain { b } else { a })
            .map(|t| t.term.clone())
    } else {
        refitted.map(|t| t.term.clone()).next()
    };
    let term = chosen.unwrap_or_else(|| v.candidates[0].clone());
    let (per, failed) = of(&term);
    v.term = Some(term.clone());
    v.per_drive = per;
    v.failed = failed;
    v.drives = v.per_drive.len();
    v.drives_verified_alone = v.per_drive.iter().filter(|e| e.verified_alone).count();
    let Some((gain, z)) = pooled(&v.per_drive) else {
        v.reason = "no_drive_refitted";
        v.why = format!(
            "no_drive_refitted: no drive could be refitted with `{}` (the failed list names \
             each one's error)",
            v.candidates.join("`, `")
        );
        d.best_edit = None;
        d.summary = summary(d);
        return;
    };
    (v.gain, v.z) = (Some(gain), Some(z));
    v.edit = v.per_drive.first().map(|e| e.edit.clone());
    v.terms = v.per_drive.first().map(|e| e.terms.clone());
    v.reason = if z.partial_cmp(&v.z_bar).is_none_or(|o| o.is_lt()) {
        "not_significant_pooled_z"
    } else if gain.partial_cmp(&0.0).is_none_or(|o| o.is_le()) {
        "no_pooled_gain"
    } else {
        "verified_pooled_z"
    };
    v.verified = v.reason == "verified_pooled_z";
    let figures = format!(
        "over {} drives it gains {:.2} % of the held-out squared error at z = {:.2} (bar \
         {}); {} of {} drives verify it alone",
        v.drives,
        100.0 * gain,
        z,
        v.z_bar,
        v.drives_verified_alone,
        v.drives
    );
    v.why = match v.reason {
        "verified_pooled_z" => format!("verified_pooled_z: `{term}` {figures}"),
        "no_pooled_gain" => {
            format!("no_pooled_gain: `{term}` {figures}, but the squared error does not fall")
        }
        _ => format!("not_significant_pooled_z: `{term}` {figures}: below the bar"),
    };
    d.best_edit = v.verified.then_some(term);
    d.summary = summary(d);
}
