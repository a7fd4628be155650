//! The run on a user's log: the log split in halves, the presets and the user's model fitted
//! and scored, diagnosis, ladder and discovery.

use super::error::error_chain;
use super::options::diagnose_config;
use super::options::{CheckedStoryOptions, Progress, StoryOptions};
use super::runs::{DataRun, DiagnosedRun, ScoredModel, Step};
use super::steps::{LADDER_TERMS, Steps, discover_run, fit_and_score};
use crate::diagnose::{FeatureTable, ModelDiagnosisError, diagnose_residual, replay_model};
use crate::fit::CheckedFitOptions;
use crate::log::Log;
use crate::model::{FittedModel, preset};
use crate::score::score_with_units;
use crate::select::{ladder_fit, ladder_terms};
use std::path::{Path, PathBuf};

/// The presets fitted on a user's log: (label, term list).
pub(crate) const DATA_MODELS: [(&str, &str); 4] = [
    (preset::PRESET_LIST[0].0, preset::POSITION_DIRECTION),
    (preset::PRESET_LIST[2].0, preset::DAHL),
    (preset::PRESET_LIST[1].0, preset::CALIBRATION),
    (preset::RICH_DAHL, preset::RICH_DAHL),
];

/// Steps of a data run as [`Progress`] counts them.
pub(crate) const DATA_STEPS: usize = 5 + DATA_MODELS.len();

/// Computes the report on a user's log (and optionally their fitted model): the presets fitted
/// on the first half of the measured rows and scored on the second; the user's model on the
/// whole log; the diagnosis of the user's model on the whole log, or else of the first scored
/// preset on the second half; the ladder; discover. `progress` is called before each step.
pub fn compute_data(
    log: &Log,
    model: Option<&FittedModel>,
    opts: &CheckedStoryOptions,
    progress: &mut dyn FnMut(Progress<'_>),
) -> DataRun {
    let mut steps = Steps::new(DATA_STEPS - 1, progress);
    let run = data_run(log, model, opts, &mut steps);
    steps.finish();
    run
}

pub(crate) fn data_run(
    log: &Log,
    model: Option<&FittedModel>,
    opts: &StoryOptions,
    steps: &mut Steps<'_>,
) -> DataRun {
    let file = relative_to_cwd(&log.schema.file);
    let mut log = log.clone();
    log.schema.file = file.clone();
    let tracks_like = positions_are_tracks(&log);
    let measured_idx: Vec<usize> = log
        .rows()
        .enumerate()
        .filter(|(_, r)| r.bias.is_some())
        .map(|(i, _)| i)
        .collect();
    let split = measured_idx
        .get(measured_idx.len() / 2)
        .copied()
        .unwrap_or(log.len());
    let train = sub_log(&log, 0..split, "first half");
    let test = sub_log(&log, split..log.len(), "second half");
    steps.start("bias plots");

    let mut scored = Vec::new();
    let mut failures = Vec::new();
    for (label, terms) in DATA_MODELS {
        steps.start(&format!("fitting {label}"));
        match fit_and_score(label, terms, &train, &test) {
            Ok(s) => scored.push(s),
            Err(e) => failures.push(format!("{label}: {}", error_chain(&e))),
        }
    }
    let units = &log.schema.units;
    let user = model.map(|m| {
        let p = m.predict_log(&log).map_err(|e| error_chain(&e))?;
        let sc = score_with_units(&p.residual, &p.positions, units).map_err(|e| error_chain(&e))?;
        Ok(ScoredModel {
            label: "your model (whole log)".into(),
            trained_on: "your own fit".into(),
            scored_on: file.clone(),
            model: m.clone(),
            prediction: p,
            score: sc,
        })
    });

    steps.start("diagnosing");
    let diagnosis = data_diagnosis(&log, &test, model, user.as_ref(), &scored, opts);

    steps.start("building the ladder");
    let ladder = ladder_terms(&LADDER_TERMS.join(","))
        .and_then(|terms| ladder_fit(&train, &test, &terms, &CheckedFitOptions::default()))
        .map_err(|e| error_chain(&e));

    steps.start("discovering terms");
    let discovery = discover_run(&train, &test, opts);

    DataRun {
        opts: opts.clone(),
        log,
        file,
        train,
        test,
        tracks_like,
        scored,
        failures,
        user,
        diagnosis,
        ladder,
        discovery,
    }
}

/// The data report's diagnosis: the user's model on the whole log (its replay scored above, if
/// any, is the one the diagnosis needs), or else the first scored preset on the second half.
fn data_diagnosis(
    log: &Log,
    test: &Log,
    model: Option<&FittedModel>,
    user: Option<&Step<ScoredModel>>,
    scored: &[ScoredModel],
    opts: &StoryOptions,
) -> Step<DiagnosedRun> {
    let (m, pred, dlog, name) = match (model, scored.first()) {
        (Some(m), _) => (
            m,
            user.and_then(|u| u.as_ref().ok()).map(|u| &u.prediction),
            log,
            "your model on the whole log".to_string(),
        ),
        // The first scored model: position-direction unless its fit failed on this log.
        (None, Some(s)) => (
            &s.model,
            Some(&s.prediction),
            test,
            format!("`{}` on the second half", s.label),
        ),
        (None, None) => return Err("no model could be fitted".into()),
    };
    let go = || -> Result<DiagnosedRun, ModelDiagnosisError> {
        let dcfg = diagnose_config(opts)?;
        let residual = match pred {
            Some(p) => p.residual.clone(),
            None => replay_model(m, dlog)?.residual,
        };
        let table = FeatureTable::from_log(dlog);
        let diagnosis = diagnose_residual(m, &table, &residual, &dcfg)?;
        Ok(DiagnosedRun {
            name,
            diagnosis,
            table,
            residual,
        })
    };
    go().map_err(|e| error_chain(&e))
}

/// A log holding rows `range` of `log` (its seek history starts afresh at the first row).
fn sub_log(log: &Log, range: std::ops::Range<usize>, part: &str) -> Log {
    let mut schema = log.schema.clone();
    schema.file = format!("{} ({part})", log.schema.file);
    let mut part = log.slice(range);
    part.schema = schema;
    part
}

/// `file` as seen from the current directory: relative to it (with `..` where needed) when the
/// path is absolute, unchanged when it is already relative (titles and captions then name the
/// file as the user typed it from where the command ran, never a machine's absolute path).
pub(crate) fn relative_to_cwd(file: &str) -> String {
    let p = Path::new(file);
    let Ok(cwd) = std::env::current_dir() else {
        return file.to_string();
    };
    if !p.is_absolute() {
        return file.to_string();
    }
    let (a, b): (Vec<_>, Vec<_>) = (p.components().collect(), cwd.components().collect());
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    if common == 0 {
        return file.to_string();
    }
    let mut rel = PathBuf::new();
    for _ in common..b.len() {
        rel.push("..");
    }
    for c in &a[common..] {
        rel.push(c);
    }
    rel.display().to_string()
}

/// Whether a log's positions are seeks to tracks, as a disk drive's are: repeated visits to a
/// set of positions (at most one distinct measured position per four measured rows), or moves
/// whose median length is at least 1 % of the position range. A continuous trajectory (a
/// positioning axis sampled at 1 kHz moves a tiny step per row, each position new) is neither,
/// and the views of one track over time and of bias against seek length (Figs. 4–9) mean
/// nothing for it.
pub(crate) fn positions_are_tracks(log: &Log) -> bool {
    let p = log.measured_positions();
    let n = p.len();
    if n < 2 {
        return n > 0;
    }
    let mut moves: Vec<f64> = p.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    let Some([lo, hi]) = crate::numeric::stats::range(&p) else {
        return false;
    };
    let mut distinct = p.clone();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup_by(|a, b| a.total_cmp(b).is_eq());
    moves.sort_by(f64::total_cmp);
    let median = moves[moves.len() / 2];
    4 * distinct.len() <= n || median >= 0.01 * (hi - lo)
}
