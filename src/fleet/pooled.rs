//! The pooled screen: an effect too weak for any one drive, named across the fleet. Every drive
//! is fitted and its residual screened as `diagnose` screens it
//! ([`crate::diagnose::screen_statistics`], kept as [`DriveStatistics`]: the same features, smoothers, seeds and block
//! permutations); per feature the drives' statistics (ln of the smallest F-test p-value) are
//! summed, and the sum's family-wise p-value is counted over the same permutations, each drive's
//! residual permuted within that drive (Westfall–Young single-step min-p over the features, as
//! for one drive). Under the null of no missing effect in any drive the family-wise false-alarm
//! rate stays at alpha however many drives are pooled.

use std::path::Path;

use serde::Serialize;

use super::verify::FleetVerification;
use super::{DriveError, ReadSettings};
use crate::diagnose::CheckedDiagnoseConfig;
use crate::fit::CheckedFitOptions;
use crate::log::Log;
use crate::model::ModelSpec;
use crate::select::CheckedVerifyConfig;

/// What the pooled screen reads of one drive's screen
/// ([`crate::diagnose::ScreenStatistics`]), per feature in the drive's order.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveStatistics {
    /// Feature names.
    pub names: Vec<String>,
    /// Whether the drive tested the feature.
    pub tested: Vec<bool>,
    /// Observed statistic (ln of the smallest F-test p-value; 0 if untested).
    pub observed: Vec<f64>,
    /// Out-of-sample explained share.
    pub explained: Vec<f64>,
    /// The drive's own family-wise p-value.
    pub p_value: Vec<f64>,
    /// Permutations (rows of `null`).
    pub permutations: usize,
    /// Row-major permutations × features.
    pub null: Vec<f64>,
    /// The term the drive alone would suggest for the feature.
    pub suggested: Vec<Option<String>>,
    /// The other terms for the feature the drive's verification would try (as `diagnose`'s
    /// `alternatives`).
    pub alternatives: Vec<Vec<String>>,
}

/// One drive's screen, or why it has none (the library's message).
#[derive(Debug, Clone, PartialEq)]
pub struct DriveScreen {
    /// The drive (its log's path or given name).
    pub source: String,
    /// Its statistics, or the message.
    pub screen: Result<DriveStatistics, String>,
}

/// A feature of the pooled screen.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PooledFeature {
    /// The feature (`seek_length`, a covariate's column name, …).
    pub name: String,
    /// The mean over the drives that tested it of the out-of-sample share of the residual
    /// variance it explains.
    pub explained: f64,
    /// The family-wise p-value of the pooled statistic (the drives' statistics summed).
    pub p_value: f64,
    /// The pooled statistic's own permutation p-value (not corrected for the family).
    pub p_value_raw: f64,
    /// `p_value` ≤ alpha and a positive mean explained share.
    pub flagged: bool,
    /// The rule that decided: `pooled_family_wise` (flagged), `not_significant_pooled`, or
    /// `untested` (no drive could test it).
    pub reason: &'static str,
    /// Drives whose own screen finds it significant (their own family-wise p ≤ alpha).
    pub drives_alone: usize,
    /// Drives that tested it.
    pub drives: usize,
    /// The term the drives suggest for it most often (ties: the first drive's).
    pub suggested_term: Option<String>,
    /// The other terms the drives would try for it, in the order they first appear (the
    /// fleet's verification tries them as `diagnose` tries a feature's alternatives).
    pub alternatives: Vec<String>,
}

/// The fleet's pooled diagnosis.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FleetDiagnosis {
    /// Drives screened.
    pub drives: usize,
    /// Drives that could not be read, fitted or screened: (source, message).
    pub failed: Vec<(String, String)>,
    /// Every feature, flagged first, then by pooled p-value and mean explained share.
    pub features: Vec<PooledFeature>,
    /// The verdict in words.
    pub summary: String,
    /// The family-wise level.
    pub alpha: f64,
    /// Permutations per drive.
    pub permutations: usize,
    /// The permutations' seed (every drive's, as `diagnose --seed`).
    pub seed: u64,
    /// The pooled suggestion's term when the fleet verifies it (see [`FleetVerification`]).
    pub best_edit: Option<String>,
    /// The pooled suggestion verified across the fleet, or why it was not.
    pub verification: FleetVerification,
}

/// Drive screens that cannot be pooled: another number of permutations, or lengths that
/// disagree.
#[derive(Debug, thiserror::Error)]
#[error(
    "{drive}: {got} permutations (or per-feature lists of unequal lengths), the fleet's \
     setting {want}: pool screens made with one setting"
)]
pub struct PoolError {
    /// The drive that differs.
    pub drive: String,
    /// Its permutations.
    pub got: usize,
    /// The first drive's.
    pub want: usize,
}

/// Fits `spec` to one drive's log and screens the fit's residual (`config`: the diagnosis
/// settings, its seed for every drive); per feature also the term the drive alone suggests.
pub fn screen_drive(
    source: &str,
    log: &Log,
    spec: &ModelSpec,
    opts: &CheckedFitOptions,
    config: &CheckedDiagnoseConfig,
) -> DriveScreen {
    let run = || -> Result<_, String> {
        let model = crate::fit::fit(spec, log, opts)
            .map_err(|e| crate::io::message(&DriveError::from(e)))?;
        let s = crate::diagnose::screen_model(&model, log, config)
            .map_err(|e| crate::io::message(&e))?;
        let existing: Vec<String> = model.terms.iter().map(|t| t.term.name()).collect();
        let (suggested, alternatives): (Vec<Option<String>>, Vec<Vec<String>>) = (0..s.names.len())
            .map(|j| {
                let c = crate::diagnose::advice::candidate_terms(
                    &s.names[j],
                    s.origins[j],
                    false,
                    s.by_direction[j],
                    false,
                    false,
                );
                let chosen = crate::diagnose::advice::suggest(&c, &existing).0;
                let others =
                    crate::diagnose::advice::alternatives(&c, &existing, chosen.as_deref());
                (chosen, others)
            })
            .unzip();
        Ok(DriveStatistics {
            names: s.names,
            tested: s.tested,
            observed: s.observed,
            explained: s.explained,
            p_value: s.p_value,
            permutations: s.permutations,
            null: s.null,
            suggested,
            alternatives,
        })
    };
    DriveScreen {
        source: source.to_string(),
        screen: run(),
    }
}

/// [`screen_drive`] of the log at `path` read with `read`.
pub fn screen_path(
    path: &Path,
    read: &ReadSettings,
    spec: &ModelSpec,
    opts: &CheckedFitOptions,
    config: &CheckedDiagnoseConfig,
) -> DriveScreen {
    let source = path.display().to_string();
    match read.read(path) {
        Ok(log) => screen_drive(&source, &log, spec, opts, config),
        Err(e) => DriveScreen {
            source,
            screen: Err(crate::io::message(&e)),
        },
    }
}

/// The pooled screen of the drives' screens (see the module docs); the drives' order does not
/// change it.
pub fn pool(
    screens: &[DriveScreen],
    config: &CheckedDiagnoseConfig,
    verify: &CheckedVerifyConfig,
) -> Result<FleetDiagnosis, PoolError> {
    // In the order of the sources, so that the sums (and so every figure) do not depend on
    // the order the drives came in.
    let mut order: Vec<&DriveScreen> = screens.iter().collect();
    order.sort_by(|a, b| a.source.cmp(&b.source));
    let ok: Vec<(&str, &DriveStatistics)> = order
        .iter()
        .filter_map(|d| d.screen.as_ref().ok().map(|s| (d.source.as_str(), s)))
        .collect();
    let failed: Vec<(String, String)> = order
        .iter()
        .filter_map(|d| {
            d.screen
                .as_ref()
                .err()
                .map(|e| (d.source.clone(), e.clone()))
        })
        .collect();
    let b = config.permutations;
    let m_of = |s: &DriveStatistics| s.names.len();
    check_shapes(&ok, b)?;
    // The features of every drive, in the order they first appear.
    let mut names: Vec<String> = Vec::new();
    for (_, s) in &ok {
        for n in &s.names {
            if !names.contains(n) {
                names.push(n.clone());
            }
        }
    }
    let m = names.len();
    let mut observed = vec![0.0; m];
    let mut null = vec![0.0; b * m];
    let mut explained = vec![0.0; m];
    let mut tested = vec![0usize; m];
    let mut alone = vec![0usize; m];
    let mut votes: Vec<Vec<(String, usize)>> = vec![Vec::new(); m];
    let mut others: Vec<Vec<String>> = vec![Vec::new(); m];
    for (_, s) in &ok {
        let w = m_of(s);
        for (j, name) in s.names.iter().enumerate() {
            if !s.tested[j] {
                continue;
            }
            let k = names.iter().position(|n| n == name).unwrap_or(0);
            observed[k] += s.observed[j];
            for i in 0..b {
                null[i * m + k] += s.null[i * w + j];
            }
            explained[k] += s.explained[j];
            tested[k] += 1;
            if s.p_value[j] <= config.alpha && s.explained[j] > 0.0 {
                alone[k] += 1;
            }
            if let Some(t) = &s.suggested[j] {
                match votes[k].iter_mut().find(|(v, _)| v == t) {
                    Some((_, c)) => *c += 1,
                    None => votes[k].push((t.clone(), 1)),
                }
            }
            for t in &s.alternatives[j] {
                if !others[k].contains(t) {
                    others[k].push(t.clone());
                }
            }
        }
    }
    let suggested: Vec<Option<String>> = votes
        .iter()
        .map(|v| {
            let best = v.iter().map(|(_, c)| *c).max().unwrap_or(0);
            v.iter().find(|(_, c)| *c == best).map(|(t, _)| t.clone())
        })
        .collect();
    let any: Vec<bool> = tested.iter().map(|&t| t > 0).collect();
    let (p_raw, p_adj) = crate::diagnose::family_wise_p_values(b, &observed, &null, &any);
    let mut features: Vec<PooledFeature> = (0..m)
        .map(|k| {
            let mean = if tested[k] > 0 {
                explained[k] / tested[k] as f64
            } else {
                0.0
            };
            let flagged = tested[k] > 0 && p_adj[k] <= config.alpha && mean > 0.0;

            PooledFeature {
                name: names[k].clone(),
                explained: mean,
                p_value: p_adj[k],
                p_value_raw: p_raw[k],
                flagged,
                reason: match (tested[k] > 0, flagged) {
                    (false, _) => "untested",
                    (true, true) => "pooled_family_wise",
                    (true, false) => "not_significant_pooled",
                },
                drives_alone: alone[k],
                drives: tested[k],
                suggested_term: suggested[k].clone(),
                // The drives' other suggestions first, then their alternatives.
                alternatives: votes[k]
                    .iter()
                    .map(|(t, _)| t)
                    .chain(&others[k])
                    .filter(|t| Some(*t) != suggested[k].as_ref())
                    .fold(Vec::new(), |mut a: Vec<String>, t| {
                        if !a.contains(t) {
                            a.push(t.clone());
                        }
                        a
                    }),
            }
        })
        .collect();
    features.sort_by(|a, b| {
        b.flagged
            .cmp(&a.flagged)
            .then(a.p_value.total_cmp(&b.p_value))
            .then(b.explained.total_cmp(&a.explained))
    });
    let verification = pending(&features, verify);
    let mut d = FleetDiagnosis {
        drives: ok.len(),
        failed,
        features,
        summary: String::new(),
        alpha: config.alpha,
        permutations: b,
        seed: config.seed,
        best_edit: None,
        verification,
    };
    d.summary = summary(&d);
    Ok(d)
}

/// Every drive's statistics of `b` permutations, one of each per feature: else the first
/// drive that differs.
fn check_shapes(ok: &[(&str, &DriveStatistics)], b: usize) -> Result<(), PoolError> {
    let bad = |s: &DriveStatistics| {
        let m = s.names.len();
        s.permutations != b
            || [
                s.tested.len(),
                s.observed.len(),
                s.explained.len(),
                s.p_value.len(),
                s.suggested.len(),
                s.alternatives.len(),
            ]
            .iter()
            .any(|&l| l != m)
            || s.null.len() != b * m
    };
    match ok.iter().find(|(_, s)| bad(s)) {
        Some((source, s)) => Err(PoolError {
            drive: source.to_string(),
            got: s.permutations,
            want: b,
        }),
        None => Ok(()),
    }
}

/// The verification the pooled screen asks for, before any refit: the first flagged feature
/// (in the features' order) that has a suggested term, its candidates that term and then the
/// alternatives the drives would try.
pub(super) fn pending(
    features: &[PooledFeature],
    verify: &CheckedVerifyConfig,
) -> FleetVerification {
    let mut flagged = features.iter().filter(|f| f.flagged).peekable();
    let any = flagged.peek().is_some();
    let suggestion = flagged.find_map(|f| {
        let term = f.suggested_term.as_ref()?;
        let candidates = std::iter::once(term)
            .chain(&f.alternatives)
            .cloned()
            .collect();
        Some((f.name.clone(), candidates))
    });
    FleetVerification::pending(suggestion, any, verify.min_z, verify.folds)
}

/// The verdict in words: the flagged features with their pooled p, mean share and how many
/// drives find them alone, or that none is flagged; then the verification's verdict.
pub(super) fn summary(d: &FleetDiagnosis) -> String {
    let flagged: Vec<&PooledFeature> = d.features.iter().filter(|f| f.flagged).collect();
    let mut s = format!("{} drives pooled", d.drives);
    if !d.failed.is_empty() {
        s.push_str(&format!(" ({} could not be screened)", d.failed.len()));
    }
    if flagged.is_empty() {
        s.push_str(&format!(
            ": not_significant_pooled: no feature's pooled statistic is significant at the \
             family-wise level {}",
            d.alpha
        ));
        return s;
    }
    s.push_str(": pooled_family_wise: ");
    let parts: Vec<String> = flagged
        .iter()
        .map(|f| {
            let term = f
                .suggested_term
                .as_deref()
                .map(|t| format!(", add `{t}`"))
                .unwrap_or_default();
            format!(
                "`{}` (pooled p = {:.3}, {:.2} % of the residual variance per drive, \
                 significant alone in {} of {} drives{term})",
                f.name,
                f.p_value,
                100.0 * f.explained,
                f.drives_alone,
                f.drives
            )
        })
        .collect();
    s.push_str(&parts.join("; "));
    s.push_str(&format!(". Across the fleet: {}", d.verification.why));
    s
}
