//! `discover`: the whole loop run by the tool — fit, diagnose, apply the best verified edit,
//! repeat — until nothing is flagged or the verified gain is below what noise allows.
//!
//! Each step fits the current spec on the training log, diagnoses its causal residual there
//! ([`crate::diagnose::diagnose_model`], adaptive terms' absorption included), verifies the leading
//! suggestions by refitting on folds of consecutive seeks ([`super::verify()`]) and applies the
//! edit with the largest verified gain. The error reported before and after each step is the
//! test log's causal error std when a test log is given, else the out-of-sample (fold) std of
//! the verification.
//!
//! **Honest scores with adaptive terms**: a model with an adaptive term (`drift`)
//! re-learns its offset from the measured bias, so its one-step error flatters it on a dense log.
//! For every rung where the model before or after has an adaptive term, discover also measures
//! the **free-run** error std (the adaptive terms never see the measured bias) on the test log,
//! or in sample on the training log without one, reports it beside the one-step figure
//! (`free_run_std_before`/`free_run_std_after`, labelled by `figure` and `free_run_basis`), and
//! applies an edit only if it does not make the free-run error worse: a verified edit whose gain
//! is one-step only is passed over (named in the step's reason) for the next verified one, and
//! when none is left the loop stops saying so. Why it stopped always quotes the final model's
//! free-run figure beside its one-step one when the model is adaptive.

use std::fmt;

use serde::{Deserialize, Serialize};

use super::{CheckedVerifyConfig, candidates, verify};
use crate::diagnose::{
    CheckedDiagnoseConfig, Diagnosis, ModelDiagnosisError, Reason, Verification, VerifiedEdit,
    diagnose_model, replay_model,
};
use crate::fit::{CheckedFitOptions, FitError, fit};
use crate::log::Log;
use crate::model::{Feedback, FittedModel, ModelSpec};

/// Settings of [`discover`].
#[derive(Debug, Clone, PartialEq)]
pub struct DiscoverConfig {
    /// The diagnosis at each step (checked by [`crate::diagnose::DiagnoseConfig::check`]).
    pub diagnose: CheckedDiagnoseConfig,
    /// The verification refits at each step (checked by [`super::VerifyConfig::check`]; their fit
    /// options fit every model).
    pub verify: CheckedVerifyConfig,
    /// Most edits applied, 1..=30 (default 8).
    pub max_steps: usize,
}

impl Default for DiscoverConfig {
    fn default() -> Self {
        Self {
            diagnose: CheckedDiagnoseConfig::default(),
            verify: CheckedVerifyConfig::default(),
            max_steps: 8,
        }
    }
}

impl DiscoverConfig {
    /// Checks `max_steps` (its diagnosis and verification settings are checked types already)
    /// into the checked type [`discover`] accepts.
    pub fn check(self) -> Result<CheckedDiscoverConfig, DiscoverError> {
        if !(1..=30).contains(&self.max_steps) {
            return Err(DiscoverError::InvalidConfig {
                field: crate::field::Field::MaxSteps,
                message: format!("{} is not in 1..=30", self.max_steps),
            });
        }
        Ok(CheckedDiscoverConfig(self))
    }
}

checked_settings! {
    /// Settings that passed [`DiscoverConfig::check`]; read them through `Deref`. `Default` is the
    /// checked default.
    #[derive(Debug, Clone, PartialEq, Default)]
    pub struct CheckedDiscoverConfig(DiscoverConfig);
}

/// An error of [`discover`].
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DiscoverError {
    /// A setting is out of range.
    #[error("invalid discover setting {field}: {message}")]
    InvalidConfig {
        /// The setting.
        field: crate::field::Field,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// The starting model could not be fitted on the training log.
    #[error("fitting the starting model `{terms}` on {file}")]
    Start {
        /// The starting terms.
        terms: String,
        /// The training log.
        file: String,
        /// The fit error.
        #[source]
        source: Box<FitError>,
    },
    /// A diagnosis, verification or refit failed.
    #[error(transparent)]
    Diagnosis(#[from] ModelDiagnosisError),
}

/// One rung of the ladder `discover` climbed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DiscoverStep {
    /// The edit applied (`add col:temp_c`, `replace poly2 by table:25`).
    pub edit: String,
    /// The feature that led to it (or `drift → temp_c` for an absorbed effect).
    pub feature: String,
    /// Why: the feature's shape and share, and the verified gain.
    pub reason: String,
    /// Error std before the edit (test log if given, else out-of-sample folds; bias unit).
    pub std_before: f64,
    /// Error std after the edit (same basis).
    pub std_after: f64,
    /// The model's terms after the edit.
    pub terms: String,
    /// Free-run error std before the edit (bias unit; on [`Discovery::free_run_basis`]), when
    /// the model before or after it has an adaptive term; left out of the JSON otherwise (then
    /// the one-step figures are the free-run ones).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub free_run_std_before: Option<f64>,
    /// Free-run error std after the edit (same basis), with `free_run_std_before`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub free_run_std_after: Option<f64>,
}

/// What [`discover`] did: the ladder, the final terms and why it stopped. Serialises to
/// `{"steps": [{"edit", "feature", "reason", "std_before", "std_after", "terms",
/// "free_run_std_before"?, "free_run_std_after"?}, …], "final_terms": […], "stopped_because":
/// "…", "basis": "…", "unit": "…", "start_std", "figure": "one-step", "free_run_basis"?,
/// "start_free_run_std"?, "final_std"?, "final_free_run_std"?}` (`?`: only where an adaptive
/// term makes the free run differ from the one-step figure; never `null`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Discovery {
    /// The edits applied, in order.
    pub steps: Vec<DiscoverStep>,
    /// The final model's terms.
    pub final_terms: Vec<String>,
    /// Why the loop stopped, in words (beginning with the rule's, [`Reason::words`]).
    pub stopped_because: String,
    /// The rule that stopped it ([`Reason`]): nothing is flagged, the best scored edit's own
    /// (below the practical minimum, only re-levels the folds, not significant, not a lower
    /// loss in every fold), the fit failed, the step limit, or a free-run error that grows.
    pub reason: Reason,
    /// What `std_before`/`std_after` are measured on (`test log …` or `out-of-sample folds …`).
    pub basis: String,
    /// The bias unit of every std.
    pub unit: String,
    /// Error std of the starting model (same basis).
    pub start_std: f64,
    /// Which figure `start_std`, `std_before` and `std_after` are: always `one-step` (adaptive
    /// terms see every measured bias).
    pub figure: String,
    /// What the free-run figures are measured on (`test log …`, or `training log …, in
    /// sample`), when any rung has an adaptive term.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub free_run_basis: Option<String>,
    /// Free-run error std of the starting model, when it has an adaptive term.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_free_run_std: Option<f64>,
    /// One-step error std of the final model on `free_run_basis`, when it has an adaptive term.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub final_std: Option<f64>,
    /// Free-run error std of the final model on `free_run_basis`, when it has an adaptive term.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub final_free_run_std: Option<f64>,
}

impl Discovery {
    /// The discovery as pretty JSON.
    /// Through the one JSON writer: a non-finite number is refused naming its key path.
    pub fn to_json(&self) -> Result<String, crate::io::OutputError> {
        crate::io::json::to_string_pretty(self)
    }
}

impl fmt::Display for Discovery {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "discover: {} error std on {} ({}), starting at {:.4}",
            self.figure, self.basis, self.unit, self.start_std
        )?;
        if let (Some(b), Some(v)) = (&self.free_run_basis, self.start_free_run_std) {
            writeln!(f, "  free-run error std on {b}: starting at {v:.4}")?;
        }
        for (i, s) in self.steps.iter().enumerate() {
            write!(
                f,
                "  {}. {} ({}): {} {:.4} → {:.4} {}",
                i + 1,
                s.edit,
                s.feature,
                self.figure,
                s.std_before,
                s.std_after,
                self.unit
            )?;
            if let (Some(a), Some(b)) = (s.free_run_std_before, s.free_run_std_after) {
                write!(f, "; free run {a:.4} → {b:.4} {}", self.unit)?;
            }
            writeln!(f)?;
            writeln!(f, "     why: {}", s.reason)?;
        }
        writeln!(f, "final terms: {}", self.final_terms.join(","))?;
        writeln!(f, "stopped because {}", self.stopped_because)
    }
}

/// The one-step and free-run error std of `m` on `log` (`None` for the free run of a model with
/// no adaptive term: both figures are the same then).
fn honest_stds(m: &FittedModel, log: &Log) -> Result<(f64, Option<f64>), ModelDiagnosisError> {
    let replay = |feedback| {
        m.predict_log_with(log, feedback)
            .map_err(|source| ModelDiagnosisError::Replay {
                file: log.schema.file.clone(),
                source,
            })
            .map(|p| crate::numeric::stats::std_dev(&p.residual).unwrap_or(0.0))
    };
    let one = replay(Feedback::EveryRow)?;
    Ok((
        one,
        if m.adaptive() {
            Some(replay(Feedback::Never)?)
        } else {
            None
        },
    ))
}

/// The free-run std of a model whose [`honest_stds`] are `s` (its one-step std if it has no
/// adaptive term).
fn free_or_one(s: (f64, Option<f64>)) -> f64 {
    s.1.unwrap_or(s.0)
}

/// Whether an edit from a model with one-step/free-run stds `before` to one with `after` gains on
/// the one-step figure only: a model on either side has an adaptive term (`adaptive`) and the
/// free-run error (the one-step one for a model with no adaptive term) grows.
fn one_step_only(adaptive: bool, before: (f64, Option<f64>), after: (f64, Option<f64>)) -> bool {
    adaptive && free_or_one(after) > free_or_one(before)
}

/// Runs the loop on `train` from `start` (see the module docs); `test`, if given, scores every
/// rung. Returns the ladder and the final model fitted on `train`.
pub fn discover(
    start: &ModelSpec,
    train: &Log,
    test: Option<&Log>,
    config: &CheckedDiscoverConfig,
) -> Result<(Discovery, FittedModel), DiscoverError> {
    let opts = &config.verify.fit;
    let mut spec = start.clone();
    let mut model = fit(&spec, train, opts).map_err(|source| DiscoverError::Start {
        terms: spec.to_string(),
        file: train.schema.file.clone(),
        source: Box::new(source),
    })?;
    let test_std = |m: &FittedModel| -> Result<Option<f64>, ModelDiagnosisError> {
        match test {
            Some(t) => Ok(crate::numeric::stats::std_dev(
                &replay_model(m, t)?.residual,
            )),
            None => Ok(None),
        }
    };
    // Where the free-run figures are measured: the test log, else the training log in sample.
    let honest_log = test.unwrap_or(train);
    let free_run_basis = match test {
        Some(t) => format!("test log {}", t.schema.file),
        None => format!("training log {}, in sample", train.schema.file),
    };
    let mut out = empty_discovery(train, test, config);
    let mut current_test = test_std(&model)?;
    let mut current_honest = honest_stds(&model, honest_log)?;
    out.start_free_run_std = current_honest.1;
    let mut first = true;
    for step in 0..=config.max_steps {
        let d = diagnose_model(&model, train, &config.diagnose)?;
        let cands = candidates(&d, config.verify.candidates);
        if cands.is_empty() {
            if first {
                out.start_std = current_test.unwrap_or(d.residual_std);
            }
            out.reason = Reason::NothingFlagged;
            out.stopped_because = format!(
                "{}: no candidate feature explains a practical share of the residual beyond \
                 noise",
                out.reason
            );
            break;
        }
        let v = verify(
            &spec,
            train,
            &cands,
            d.null_block_len,
            config.diagnose.min_effect,
            &config.verify,
        )?;
        if first {
            out.start_std = current_test.unwrap_or(v.std_before);
            first = false;
        }
        let Some(best) = v.best().cloned() else {
            (out.reason, out.stopped_because) = not_verified(&v);
            break;
        };
        if step == config.max_steps {
            out.reason = Reason::StepLimit;
            out.stopped_because = format!(
                "{} ({}); `{}` would still gain {:.1} %",
                out.reason,
                config.max_steps,
                best.edit,
                100.0 * best.gain
            );
            break;
        }
        // The verified edits in order of gain; with an adaptive term on either side, the first
        // whose free-run error is no worse than the current model's is taken.
        let (chosen, passed_over) = choose_edit(
            &v,
            &spec,
            &model,
            train,
            honest_log,
            opts,
            step,
            current_honest,
            &out.unit,
        )?;
        let passed = if passed_over.is_empty() {
            String::new()
        } else {
            format!(
                "; passed over, their gain being one-step only (on {free_run_basis}): {}",
                passed_over.join(", ")
            )
        };
        let Some((best, next_spec, next, next_honest, adaptive)) = chosen else {
            (out.reason, out.stopped_because) = none_applied(passed_over.is_empty(), &passed);
            break;
        };
        let next_test = test_std(&next)?;
        let shape = shape_words(&d, &best.feature);
        if adaptive {
            out.free_run_basis = Some(free_run_basis.clone());
        }
        out.steps.push(DiscoverStep {
            edit: best.edit.clone(),
            feature: best.feature.clone(),
            reason: format!(
                "{}: {shape}refitted, the edit gains {:.1} % of the error variance on held-out \
                 seeks (z = {:.1}, bar {:.1}){passed}",
                Reason::Verified,
                100.0 * best.gain,
                best.z,
                best.z_bar
            ),
            std_before: current_test.unwrap_or(best.std_before),
            std_after: next_test.unwrap_or(best.std_after),
            terms: next_spec.to_string(),
            free_run_std_before: adaptive.then(|| free_or_one(current_honest)),
            free_run_std_after: adaptive.then(|| free_or_one(next_honest)),
        });
        spec = next_spec;
        model = next;
        current_test = next_test;
        current_honest = next_honest;
    }
    note_free_run(&mut out, current_honest, free_run_basis);
    out.final_terms = spec.terms.iter().map(|t| t.name()).collect();
    Ok((out, model))
}

/// Why discover stopped when verified edits existed but none was taken: none could be applied
/// (`none_passed_over`), or every one gains on the one-step figure only (`passed` lists them).
fn none_applied(none_passed_over: bool, passed: &str) -> (Reason, String) {
    if none_passed_over {
        (
            Reason::NotApplicable,
            format!(
                "{}: no verified edit could be applied",
                Reason::NotApplicable
            ),
        )
    } else {
        (
            Reason::FreeRunWorse,
            format!(
                "{}: every verified edit gains on the one-step figure only: in free run it \
                 makes the error worse{passed}",
                Reason::FreeRunWorse
            ),
        )
    }
}

/// Records the final model's free-run figures in `out` when it has an adaptive term
/// (`honest.1`), and says so after the stop reason; names where they were measured.
fn note_free_run(out: &mut Discovery, honest: (f64, Option<f64>), free_run_basis: String) {
    if let Some(free) = honest.1 {
        out.final_std = Some(honest.0);
        out.final_free_run_std = Some(free);
        let (one, run) = (
            crate::log::fmt_trimmed(honest.0, 4),
            crate::log::fmt_trimmed(free, 4),
        );
        let but = if one == run { "and" } else { "but" };
        out.stopped_because = format!(
            "{}; the final model has an adaptive term: on {free_run_basis} its error std is \
             {one} {} one-step {but} {run} {} in free run (from the positions alone)",
            out.stopped_because, out.unit, out.unit
        );
        out.free_run_basis = Some(free_run_basis);
    } else if out.start_free_run_std.is_some() {
        out.free_run_basis = Some(free_run_basis);
    }
}

/// The residual's shape against `feature` in `d`, in words, as a step's reason begins
/// (empty when `d` has no such feature).
fn shape_words(d: &Diagnosis, feature: &str) -> String {
    d.feature(feature)
        .map(|f| {
            format!(
                "the residual{} {} ({:.1} % explained out of sample); ",
                if f.by_direction { " × direction" } else { "" },
                f.shape.describe(&f.name, f.shape_at),
                100.0 * f.explained
            )
        })
        .unwrap_or_default()
}

/// The discovery before its first step: what its figures are measured on, nothing found yet.
fn empty_discovery(train: &Log, test: Option<&Log>, config: &CheckedDiscoverConfig) -> Discovery {
    let basis = match test {
        Some(t) => format!("test log {}", t.schema.file),
        None => format!(
            "out-of-sample folds of {} ({} folds of consecutive seeks)",
            train.schema.file, config.verify.folds
        ),
    };
    Discovery {
        steps: Vec::new(),
        final_terms: Vec::new(),
        stopped_because: String::new(),
        reason: Reason::NothingFlagged,
        basis,
        unit: train.schema.units.bias.clone(),
        start_std: 0.0,
        figure: Feedback::EveryRow.label(),
        free_run_basis: None,
        start_free_run_std: None,
        final_std: None,
        final_free_run_std: None,
    }
}

/// Why a step found no verified edit, and its rule: the best scored edit's rule and figures,
/// or why nothing was scored (the model or every suggestion failed to fit, or no suggestion
/// applies).
pub(super) fn not_verified(v: &Verification) -> (Reason, String) {
    match v.edits.first() {
        Some(e) => (
            e.reason,
            format!(
                "the best scored edit, `{}` ({}), gains {:.1} % of the error variance out of \
                 sample (z = {:.1}): {}",
                e.edit,
                e.feature,
                100.0 * e.gain,
                e.z,
                v.why_not_verified(e)
            ),
        ),
        None => {
            let failed = v.not_run.is_some()
                || (!v.rejected.is_empty()
                    && v.rejected.iter().all(|r| r.reason == Reason::FitFailed));
            let reason = if failed {
                Reason::FitFailed
            } else {
                Reason::NotApplicable
            };
            let why = v.not_run.clone().unwrap_or_else(|| {
                let each: Vec<String> = v
                    .rejected
                    .iter()
                    .map(|r| format!("`{}` ({}): {}", r.term, r.reason, r.why))
                    .collect();
                format!("no suggested edit could be scored: {}", each.join("; "))
            });
            (reason, format!("{reason}: {why}"))
        }
    }
}

/// One of [`choose_edit`]'s picks: the edit, the spec and model with it, its honest error
/// stds, and whether an adaptive term is on either side.
type Chosen = (
    VerifiedEdit,
    ModelSpec,
    FittedModel,
    (f64, Option<f64>),
    bool,
);

/// The verified edits of `v` in order of gain, each refitted on `train`; with an adaptive term
/// on either side, the first whose free-run error is no worse than the current model's is
/// taken. Also the edits passed over, in words.
#[allow(clippy::too_many_arguments)]
fn choose_edit(
    v: &Verification,
    spec: &ModelSpec,
    model: &FittedModel,
    train: &Log,
    honest_log: &Log,
    opts: &CheckedFitOptions,
    step: usize,
    current_honest: (f64, Option<f64>),
    unit: &str,
) -> Result<(Option<Chosen>, Vec<String>), ModelDiagnosisError> {
    let mut passed_over: Vec<String> = Vec::new();
    let mut chosen = None;
    for e in v.edits.iter().filter(|e| e.verified) {
        let Some(edit) = e.model_edit.clone() else {
            continue;
        };
        let next_spec = spec
            .apply(&edit)
            .map_err(|source| ModelDiagnosisError::Spec {
                step: step + 1,
                terms: e.terms.clone(),
                source,
            })?;
        let next = fit(&next_spec, train, opts).map_err(|source| ModelDiagnosisError::Fit {
            step: step + 1,
            terms: e.terms.clone(),
            file: train.schema.file.clone(),
            source: Box::new(source),
        })?;
        let next_honest = honest_stds(&next, honest_log)?;
        let adaptive = model.adaptive() || next.adaptive();
        let (before, after) = (free_or_one(current_honest), free_or_one(next_honest));
        if one_step_only(adaptive, current_honest, next_honest) {
            passed_over.push(format!(
                "`{}` ({} {} → {} {} one-step, but free run {} → {} {})",
                e.edit,
                crate::log::fmt_trimmed(current_honest.0, 4),
                unit,
                crate::log::fmt_trimmed(next_honest.0, 4),
                unit,
                crate::log::fmt_trimmed(before, 4),
                crate::log::fmt_trimmed(after, 4),
                unit
            ));
            continue;
        }
        chosen = Some((e.clone(), next_spec, next, next_honest, adaptive));
        break;
    }
    Ok((chosen, passed_over))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_edit_that_only_helps_one_step_is_passed_over() {
        // Reference: the rule in words (module docs). Adaptive: the free run decides, never the
        // one-step figure; no adaptive term: both figures are one and the edit is not judged.
        // drift added: one-step 3 → 1, but free run 5 → 6: one-step only.
        assert!(one_step_only(true, (5.0, None), (1.0, Some(6.0))));
        // drift kept: one-step worse but free run better: taken.
        assert!(!one_step_only(true, (1.0, Some(6.0)), (2.0, Some(4.0))));
        // equal free run: not worse, taken.
        assert!(!one_step_only(true, (1.0, Some(4.0)), (0.5, Some(4.0))));
        // drift removed: free run 6 → one-step 5 of the new model (its free run): taken.
        assert!(!one_step_only(true, (1.0, Some(6.0)), (5.0, None)));
        assert!(one_step_only(true, (1.0, Some(4.0)), (5.0, None)));
        // No adaptive term: never passed over here (verification already judged it).
        assert!(!one_step_only(false, (1.0, None), (2.0, None)));
    }

    /// A seek log whose bias = 20 + 0.8·(temp − 40) + a slow random walk (steps of `walk` sd)
    /// + noise.
    fn walk_log(seed: u64, walk_sd: f64) -> Log {
        let mut rng = crate::numeric::rng::SimRng::new(seed);
        let mut text = String::from("time_s,track,bias,temp_c\n");
        let mut walk = 0.0;
        for i in 0..1500 {
            let pos = rng.below(300) as f64;
            let temp = 40.0 + 5.0 * rng.normal();
            walk += walk_sd * rng.normal();
            let bias = 20.0 + 0.8 * (temp - 40.0) + walk + rng.normal();
            text.push_str(&format!("{},{pos},{bias:.4},{temp:.4}\n", 0.3 * i as f64));
        }
        Log::from_reader(
            "walk.csv",
            text.as_bytes(),
            &crate::log::ColumnMap::default(),
        )
        .unwrap()
    }

    #[test]
    fn discover_reports_the_free_run_beside_the_one_step_figure() {
        // Reference: a direct replay of the final model on the test log, one-step and free run
        // (`predict_log_with`), and each step's free-run figures chained (after of one = before
        // of the next). The verification's keys stay; the free-run keys appear because `drift` is in.
        let (train, test) = (walk_log(41, 0.05), walk_log(42, 0.05));
        let (d, model) = discover(
            &ModelSpec::parse("poly2,drift").unwrap(),
            &train,
            Some(&test),
            &CheckedDiscoverConfig::default(),
        )
        .unwrap();
        let text = d.to_string();
        assert!(model.adaptive(), "{text}");
        let std_of = |f| {
            crate::numeric::stats::std_dev(&model.predict_log_with(&test, f).unwrap().residual)
                .unwrap()
        };
        let (one, free) = (std_of(Feedback::EveryRow), std_of(Feedback::Never));
        assert_eq!(d.final_std.map(f64::to_bits), Some(one.to_bits()), "{text}");
        assert_eq!(
            d.final_free_run_std.map(f64::to_bits),
            Some(free.to_bits()),
            "{text}"
        );
        assert_eq!(d.figure, "one-step");
        assert!(
            d.free_run_basis
                .as_deref()
                .is_some_and(|b| b.contains("walk.csv"))
        );
        assert!(d.stopped_because.contains("free run"), "{text}");
        assert!(d.start_free_run_std.is_some());
        let mut prev = d.start_free_run_std;
        for s in &d.steps {
            assert_eq!(
                s.free_run_std_before.map(f64::to_bits),
                prev.map(f64::to_bits),
                "{text}"
            );
            // Never an edit that makes the free run worse.
            assert!(s.free_run_std_after <= s.free_run_std_before, "{text}");
            prev = s.free_run_std_after;
        }
        let v: serde_json::Value = serde_json::from_str(&d.to_json().unwrap()).unwrap();
        for key in [
            "steps",
            "final_terms",
            "stopped_because",
            "figure",
            "free_run_basis",
            "start_free_run_std",
            "final_std",
            "final_free_run_std",
        ] {
            assert!(v.get(key).is_some(), "{key}");
        }
        assert!(
            !d.steps.is_empty(),
            "the temperature effect must be found: {text}"
        );
        for key in [
            "edit",
            "feature",
            "reason",
            "std_before",
            "std_after",
            "free_run_std_before",
            "free_run_std_after",
        ] {
            assert!(v["steps"][0].get(key).is_some(), "{key}");
        }
        assert!(text.contains("free run"), "{text}");
    }

    #[test]
    fn without_an_adaptive_term_no_free_run_keys_are_written() {
        // Reference: with no adaptive term the free run is the one-step replay, so the JSON
        // leaves the free-run keys out (never null) and the text does not mention a free run.
        let (train, test) = (walk_log(43, 0.0), walk_log(44, 0.0));
        let config = DiscoverConfig {
            max_steps: 1,
            ..DiscoverConfig::default()
        }
        .check()
        .unwrap();
        let (d, _) = discover(
            &ModelSpec::parse("poly2").unwrap(),
            &train,
            Some(&test),
            &config,
        )
        .unwrap();
        let v: serde_json::Value = serde_json::from_str(&d.to_json().unwrap()).unwrap();
        for key in ["free_run_basis", "start_free_run_std", "final_free_run_std"] {
            assert!(v.get(key).is_none(), "{key}");
        }
        for s in v["steps"].as_array().unwrap() {
            assert!(s.get("free_run_std_after").is_none());
        }
    }
}
