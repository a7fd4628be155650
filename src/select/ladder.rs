//! The ladder: how the test-set error falls as terms are added one at a time. The table
//! ([`ladder`]) takes each step's term list and error std; [`ladder_fit`] fits and replays the
//! steps.

use serde::{Deserialize, Serialize};

use crate::diagnose::{DiagnoseError, ModelDiagnosisError, replay_model, short};
use crate::field::Field;
use crate::fit::{CheckedFitOptions, fit};
use crate::log::{Log, Units};
use crate::model::ModelSpec;

/// One rung as measured by the caller: the model's terms and its test-set error std.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LadderInput {
    /// The model's terms at this step.
    pub terms: Vec<String>,
    /// Test-set error std, in the test log's bias unit.
    pub std: f64,
    /// Free-run test-set error std (adaptive terms such as `drift` see no measured bias),
    /// for a model with an adaptive term; `None` otherwise.
    pub free_run_std: Option<f64>,
    /// The step's warnings: its fit's self-check and a test mean error large against the std.
    pub warnings: Vec<String>,
}

/// One rung of the ladder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LadderStep {
    /// The model's terms at this step.
    pub terms: Vec<String>,
    /// Test-set error std, in the test log's bias unit (one-step: adaptive terms see every
    /// earlier measured bias).
    pub std: f64,
    /// Free-run test-set error std of a model with an adaptive term (`drift`), which then sees
    /// no measured bias; absent from the JSON when the model has none (both figures agree).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub free_run_std: Option<f64>,
    /// The step's warnings (fit self-check, test mean error large against the std); absent
    /// from the JSON when there are none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// Reduction of the std relative to the first step, as a fraction (0.36 = 36 % lower;
    /// negative if worse; 0 when the first std is 0).
    pub reduction: f64,
}

/// The whole ladder; JSON `{"steps": [{"terms", "std", "reduction"}, ...]}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Ladder {
    /// The rungs in the order given.
    pub steps: Vec<LadderStep>,
}

/// Builds the ladder: each step's reduction relative to the first step. Errors on a std that is
/// negative or not finite (it would put NaN or infinity in the JSON).
pub(crate) fn ladder(steps: &[LadderInput]) -> Result<Ladder, DiagnoseError> {
    if let Some((step, s)) = steps.iter().enumerate().find(|(_, s)| {
        !(s.std.is_finite() && s.std >= 0.0)
            || s.free_run_std.is_some_and(|f| !(f.is_finite() && f >= 0.0))
    }) {
        return Err(DiagnoseError::BadLadderStd {
            step,
            terms: s.terms.join(", "),
            std: s.std,
        });
    }
    let first = steps.first().map(|s| s.std).unwrap_or(0.0);
    let steps = steps
        .iter()
        .map(|s| LadderStep {
            terms: s.terms.clone(),
            std: s.std,
            free_run_std: s.free_run_std,
            warnings: s.warnings.clone(),
            reduction: if first > 0.0 {
                1.0 - s.std / first
            } else {
                0.0
            },
        })
        .collect();
    Ok(Ladder { steps })
}

impl LadderStep {
    /// This step's terms that `previous` lacks, in this step's order (the `+ term` of a rung;
    /// `previous.added_since(self)` gives the terms dropped).
    pub fn added_since<'a>(&'a self, previous: &LadderStep) -> Vec<&'a str> {
        self.terms
            .iter()
            .filter(|t| !previous.terms.contains(t))
            .map(String::as_str)
            .collect()
    }
}

impl Ladder {
    /// A text table: step, the terms (as `+ added` after the first step), std (in
    /// `units.bias`, the test log's) and reduction.
    pub fn to_text(&self, units: &Units) -> String {
        let std_header = format!("std ({})", units.bias);
        let w = std_header.chars().count().max(10);
        let free = self.steps.iter().any(|s| s.free_run_std.is_some());
        let mut out = format!(
            "{:<4} {:<40} {:>w$} {:>10}",
            "step", "terms", std_header, "reduction"
        );
        out.push_str(if free { "   free-run std\n" } else { "\n" });
        let mut previous: Option<&LadderStep> = None;
        for (i, s) in self.steps.iter().enumerate() {
            let terms = match previous {
                None => s.terms.join(", "),
                Some(prev) => {
                    let added = s.added_since(prev);
                    let removed = prev.added_since(s);
                    let mut parts: Vec<String> = added.iter().map(|t| format!("+ {t}")).collect();
                    parts.extend(removed.iter().map(|t| format!("- {t}")));
                    if parts.is_empty() {
                        "(same terms)".to_string()
                    } else {
                        parts.join(", ")
                    }
                }
            };
            out.push_str(&format!(
                "{:<4} {:<40} {:>w$} {:>9.1}%",
                i,
                terms,
                short(s.std),
                100.0 * s.reduction
            ));
            if free {
                out.push_str(&format!(
                    " {:>14}",
                    s.free_run_std.map_or("=".to_string(), short)
                ));
            }
            out.push('\n');
            previous = Some(s);
        }
        for (i, s) in self.steps.iter().enumerate() {
            for w in &s.warnings {
                out.push_str(&format!("warning: step {i}: {w}\n"));
            }
        }
        if free {
            out.push_str(
                "std is one-step: adaptive terms (drift) see every earlier measured bias; the \
                 free-run std is the error from the positions alone (= where both agree). Judge \
                 a model with an adaptive term by its free-run std.\n",
            );
        }
        out
    }

    /// The JSON of the contract (pretty-printed).
    /// Through the one JSON writer: a non-finite number is refused naming its key path.
    pub fn to_json(&self) -> Result<String, crate::io::OutputError> {
        crate::io::json::to_string_pretty(self)
    }
}

/// Checks a ladder's comma-separated term list (`poly2,direction,seek`) into the
/// [`LadderTerms`] that [`ladder_fit`] requires: trimmed, in order. An empty entry, or an empty
/// list, is an error naming [`Field::LadderTerms`] and the entry's position.
pub fn ladder_terms(list: &str) -> Result<LadderTerms, ModelDiagnosisError> {
    let terms: Vec<String> = list.split(',').map(|t| t.trim().to_string()).collect();
    match terms.iter().position(String::is_empty) {
        Some(i) => Err(ModelDiagnosisError::EmptyTerm {
            field: Field::LadderTerms,
            list: list.to_string(),
            index: i + 1,
        }),
        None => Ok(LadderTerms(terms)),
    }
}

/// A ladder's term list that passed [`ladder_terms`] (no empty entry), in the order the terms are
/// added; read it through `Deref`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LadderTerms(Vec<String>);

impl std::ops::Deref for LadderTerms {
    type Target = [String];
    fn deref(&self) -> &[String] {
        &self.0
    }
}

/// The ladder: for k = 1..=terms.len(), fits the first k terms on `train`, replays on `test`
/// and records the test error std (counts); reductions are relative to the first step. The
/// steps run in parallel (`crate::numeric::parallel`); the result does not depend on the
/// thread count.
pub fn ladder_fit(
    train: &Log,
    test: &Log,
    terms: &LadderTerms,
    opts: &CheckedFitOptions,
) -> Result<Ladder, ModelDiagnosisError> {
    use rayon::prelude::*;
    // Each step is fitted and scored on its own (nothing shared but the logs): in parallel on
    // the process's pool, collected in step order, so the ladder and the error of the first
    // failing step are the same for any thread count.
    let steps: Vec<Result<LadderInput, ModelDiagnosisError>> = (1..=terms.len())
        .into_par_iter()
        .map(|k| -> Result<LadderInput, ModelDiagnosisError> {
            let list = terms[..k].join(",");
            let step = k - 1; // numbered as in the ladder table: step 0 is the first term alone
            let spec = ModelSpec::parse(&list).map_err(|source| ModelDiagnosisError::Spec {
                step,
                terms: list.clone(),
                source,
            })?;
            let model = fit(&spec, train, opts).map_err(|source| ModelDiagnosisError::Fit {
                step,
                terms: list.clone(),
                file: train.schema.file.clone(),
                source: Box::new(source),
            })?;
            let prediction = replay_model(&model, test)?;
            let std = crate::numeric::stats::std_dev(&prediction.residual).ok_or_else(|| {
                ModelDiagnosisError::TooFewTestRows {
                    step,
                    file: test.schema.file.clone(),
                }
            })?;
            let free_run_std = if model.adaptive() {
                model
                    .predict_log_with(test, crate::model::Feedback::Never)
                    .ok()
                    .and_then(|p| crate::numeric::stats::std_dev(&p.residual))
            } else {
                None
            };
            let mut warnings: Vec<String> =
                model.warnings.iter().map(|w| format!("fit: {w}")).collect();
            let mean = crate::numeric::stats::mean(&prediction.residual).unwrap_or(0.0);
            if mean.abs() > crate::score::MEAN_WARNING_RATIO * std {
                warnings.push(format!(
                    "test mean error {mean:.4e} is {:.2}× the error std {std:.4e}, above the \
                     {}× that is warned about: the model is offset on the test log",
                    mean.abs() / std.max(f64::MIN_POSITIVE),
                    crate::score::MEAN_WARNING_RATIO
                ));
            }
            Ok(LadderInput {
                terms: terms[..k].to_vec(),
                std,
                free_run_std,
                warnings,
            })
        })
        .collect();
    let inputs = steps.into_iter().collect::<Result<Vec<_>, _>>()?;
    Ok(ladder(&inputs)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn step(terms: &[&str], std: f64) -> LadderInput {
        LadderInput {
            terms: terms.iter().map(|t| t.to_string()).collect(),
            std,
            free_run_std: None,
            warnings: Vec::new(),
        }
    }

    #[test]
    fn ladder_reductions_are_relative_to_the_first_step() {
        // Reference: the paper's headline, 19 → just under 8 is a reduction of more than 50 %;
        // (19 − 7.6)/19 = 0.6 exactly.
        let l = ladder(&[
            step(&["poly", "direction"], 19.0),
            step(&["poly", "direction", "seek"], 11.4),
            step(&["poly", "direction", "seek", "memory"], 7.6),
        ])
        .unwrap();
        assert!(l.steps[0].reduction.abs() < 1e-15);
        assert!((l.steps[1].reduction - 0.4).abs() < 1e-12);
        assert!((l.steps[2].reduction - 0.6).abs() < 1e-12);
        let text = l.to_text(&Units::default());
        assert!(
            text.contains("+ seek") && text.contains("+ memory"),
            "{text}"
        );
        assert!(
            text.starts_with("step") && text.contains(" std (counts) "),
            "{text}"
        );
        let newtons = Units {
            bias: "N".into(),
            position: "m".into(),
        };
        let text = l.to_text(&newtons);
        assert!(
            text.contains(" std (N) ") && !text.contains("counts"),
            "{text}"
        );
        assert!(text.contains("60.0%"), "{text}");
        assert_eq!(l.steps[2].added_since(&l.steps[1]), ["memory"]);
        assert!(l.steps[1].added_since(&l.steps[2]).is_empty());
        let v: serde_json::Value = serde_json::from_str(&l.to_json().unwrap()).unwrap();
        let keys: Vec<&String> = v["steps"][0].as_object().unwrap().keys().collect();
        assert_eq!(keys, ["reduction", "std", "terms"]);
        assert_eq!(v.as_object().unwrap().len(), 1);
    }

    #[test]
    fn free_run_std_is_shown_only_when_a_step_has_one() {
        let mut with = step(&["poly2"], 2.0);
        let mut drift = step(&["poly2", "drift"], 1.0);
        drift.free_run_std = Some(1.9);
        let l = ladder(&[with.clone(), drift]).unwrap();
        let text = l.to_text(&Units::default());
        assert!(
            text.contains("free-run std") && text.contains("1.9"),
            "{text}"
        );
        let v: serde_json::Value = serde_json::from_str(&l.to_json().unwrap()).unwrap();
        assert!(v["steps"][0].get("free_run_std").is_none());
        assert!((v["steps"][1]["free_run_std"].as_f64().unwrap() - 1.9).abs() < 1e-12);
        with.free_run_std = Some(f64::NAN);
        assert!(ladder(&[with]).is_err());
    }

    #[test]
    fn ladder_rejects_nan_std_and_handles_zero_first_std() {
        let e = ladder(&[step(&["a"], 1.0), step(&["a", "b"], f64::NAN)]).unwrap_err();
        assert!(e.to_string().contains("step 1 (a, b)"), "{e}");
        let l = ladder(&[step(&["a"], 0.0), step(&["b"], 0.0)]).unwrap();
        assert!(l.steps.iter().all(|s| s.reduction.abs() < 1e-15));
        assert!(ladder(&[]).unwrap().steps.is_empty());
    }

    /// A rung whose test error is offset is warned about, naming the rule's bar. Reference:
    /// the test log is the training log with 50 added to every bias, the noise std is 1, so
    /// the test mean error is about 50 times the std, far above the 0.5× bar.
    #[test]
    fn an_offset_rung_is_warned_about_naming_the_bar() {
        let log = |shift: f64| {
            let mut rng = crate::numeric::rng::SimRng::new(3);
            let mut text = String::from("time_s,track,bias\n");
            for i in 0..300 {
                let pos = rng.below(1000) as f64;
                let bias = 1e-3 * pos + rng.normal() + shift;
                text.push_str(&format!("{i}.0,{pos},{bias}\n"));
            }
            Log::from_reader("l.csv", text.as_bytes(), &Default::default()).unwrap()
        };
        let terms = ladder_terms(crate::model::preset::POSITION_DIRECTION).unwrap();
        let l = ladder_fit(&log(0.0), &log(50.0), &terms, &CheckedFitOptions::default()).unwrap();
        let w = &l.steps[0].warnings;
        assert!(
            w.iter()
                .any(|w| w.contains("above the 0.5× that is warned about")),
            "{w:?}"
        );
        let l = ladder_fit(&log(0.0), &log(0.0), &terms, &CheckedFitOptions::default()).unwrap();
        assert!(
            l.steps
                .iter()
                .all(|s| s.warnings.iter().all(|w| !w.contains("offset")))
        );
    }
}
