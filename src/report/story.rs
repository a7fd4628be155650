//! The story the report tells, in order: what bias is (the built-in drive's phenomena P1–P8 and
//! the Table I–VII figures), three predictors fitted on a calibration run and scored on a
//! separate random run, what diagnose finds in the position-direction residual, the ladder,
//! discover, the settle optimisation, and the link from prediction error to worst-case settle
//! time. [`demo_report`] runs it on the built-in drive; [`data_report`] on a user's own log (and
//! optionally their fitted model). Both write `report.html` and every CSV/JSON behind it into
//! one folder and are deterministic for a given [`StoryOptions::seed`].
//!
//! Each is three steps: compute the run ([`super::run`], no HTML), write its files, assemble
//! the page from the shared [`super::sections`].

use std::path::{Path, PathBuf};

use super::Report;
use super::run::{DATA_STEPS, DEMO_STEPS, DISCOVER_TRAIN, DataRun, DemoRun, ScoredModel, Steps};
use super::sections::{
    Notes, data, diagnosis, discover, files, ladder, ms, paper, pct, scores, settle,
};
use crate::io::{StagedDir, write_string_atomic};
use crate::plot::svg::fmt_num;
use crate::plot::views;

pub use super::run::{CheckedStoryOptions, Progress, StoryOptions};
pub(crate) use super::run::{DATA_MODELS, StoryError};

/// What a story run wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct StoryOutcome {
    /// The report.
    pub report: PathBuf,
    /// Every other file written, in the order written.
    pub files: Vec<PathBuf>,
    /// The headline numbers in five lines of plain text.
    pub summary: Vec<String>,
    /// What could not be drawn (a figure that failed, and why), one line each; the page says
    /// it in place too. The CLI prints these on stderr.
    pub warnings: Vec<String>,
}

/// Files written for a run, with a one-line description each. They are written into a staging
/// folder beside `dir` and moved into `dir` only when the whole run has succeeded
/// ([`Out::commit`]); a run that fails leaves `dir` as it was (the staging folder is removed
/// when `Out` is dropped uncommitted).
struct Out<'a> {
    dir: &'a Path,
    /// The staging folder; `None` once committed.
    staged: Option<StagedDir>,
    /// Final paths (in `dir`) and what each holds, in the order written.
    files: Vec<(PathBuf, String)>,
}

impl<'a> Out<'a> {
    /// Creates the staging folder beside `dir`.
    fn create(dir: &'a Path) -> Result<Self, StoryError> {
        Ok(Out {
            dir,
            staged: Some(StagedDir::create(dir)?),
            files: Vec::new(),
        })
    }
    /// Where a file of the run is written now (inside the staging folder).
    fn path(&self, name: &str) -> PathBuf {
        match &self.staged {
            Some(s) => s.path(name),
            None => self.dir.join(name),
        }
    }
    /// The folder files are written into now.
    fn staging_dir(&self) -> &Path {
        match &self.staged {
            Some(s) => s.stage(),
            None => self.dir,
        }
    }
    fn text(&mut self, name: &str, text: &str, what: &str) -> Result<(), StoryError> {
        write_string_atomic(&self.path(name), text)?;
        self.note(name, what);
        Ok(())
    }
    /// Records a file written at [`Out::path`] by someone else.
    fn note(&mut self, name: &str, what: &str) {
        self.files.push((self.dir.join(name), what.to_string()));
    }
    /// The last step of both reports: builds the page with `page` (which records its notes),
    /// adds the files section, writes the page, moves every staged file into `dir`
    /// ([`StagedDir::commit`]) and returns the outcome.
    fn finish(
        mut self,
        steps: &mut Steps<'_>,
        page: impl FnOnce(&mut Notes) -> Report,
        summary: Vec<String>,
    ) -> Result<StoryOutcome, StoryError> {
        steps.start("assembling the report");
        let mut notes = Notes::default();
        let mut r = page(&mut notes);
        files::files(&mut r, &self.files);
        r.write(&self.path("report.html"))?;
        if let Some(s) = self.staged.take() {
            s.commit()?;
        }
        steps.finish();
        Ok(StoryOutcome {
            report: self.dir.join("report.html"),
            files: self.files.into_iter().map(|f| f.0).collect(),
            summary,
            warnings: notes.0,
        })
    }
}

/// A model label as part of a file name: the term-list separators `,` and `:` become `_`.
fn file_stem(label: &str) -> String {
    label.replace([',', ':'], "_")
}

fn pretty<T: serde::Serialize>(v: &T) -> Result<String, crate::io::OutputError> {
    crate::io::json::to_string_pretty(v)
}

/// Writes a scored model's `model_*.json` and `score_*.json`.
fn write_scored(
    out: &mut Out<'_>,
    s: &ScoredModel,
    fitted: &str,
    scored: &str,
) -> Result<(), StoryError> {
    let stem = file_stem(&s.label);
    out.text(
        &format!("model_{stem}.json"),
        &s.model.to_json()?,
        &format!("{} {fitted}", s.label),
    )?;
    out.text(
        &format!("score_{stem}.json"),
        &pretty(&s.score)?,
        &format!("{} {scored}", s.label),
    )
}

/// The whole story on the built-in drive (`paper1997`), written into `dir` (created if
/// missing): the logs (with `_truth.csv`), the fitted models, their scores, the diagnosis, the
/// ladder, discover's steps, the settle analysis and `report.html`. `progress` is called
/// before each step.
pub fn demo_report(
    dir: &Path,
    opts: &CheckedStoryOptions,
    progress: &mut dyn FnMut(Progress<'_>),
) -> Result<StoryOutcome, StoryError> {
    let mut out = Out::create(dir)?;
    let mut steps = Steps::new(DEMO_STEPS, progress);
    let run = super::run::demo_run(out.staging_dir(), opts, &mut steps)?;
    for (name, what) in &run.files {
        out.note(name, what);
    }
    for (s, (_, _, train)) in run.scored.iter().zip(super::run::STORY_MODELS) {
        write_scored(
            &mut out,
            s,
            &format!("model fitted on {train}.csv"),
            "scored on random.csv",
        )?;
    }
    out.text(
        "diagnosis.json",
        &run.diagnosis.diagnosis.to_json()?,
        "diagnosis of the position-direction model on random.csv",
    )?;
    out.text(
        "ladder.json",
        &run.ladder.to_json()?,
        "test error std after each added term",
    )?;
    if let Ok(d) = &run.discovery {
        out.text(
            "discover.json",
            &d.to_json()?,
            &format!("discover's verified edits, {DISCOVER_TRAIN}.csv → random.csv"),
        )?;
    }
    let settle = &run.settle.report;
    out.text(
        "settle.json",
        &pretty(settle)?,
        &format!("settle analysis ({})", run.settle.preset),
    )?;
    out.text(
        "settle_bounds.csv",
        &settle.bounds_csv(),
        "Fig. 15 bounds per sample",
    )?;
    out.text(
        "settle_responses.csv",
        &settle.responses_csv(),
        "Fig. 16 position error per sample and choice",
    )?;
    out.text(
        "worst_case.json",
        &pretty(
            &run.settle
                .link
                .iter()
                .map(|(l, _, w)| (l.clone(), *w))
                .collect::<Vec<_>>(),
        )?,
        "worst-case settle with each model's test error std as Δb",
    )?;

    let summary = demo_summary(&run);
    out.finish(&mut steps, |notes| demo_page(&run, notes), summary)
}

/// The demo page's predictors section: the four models fitted and scored on fresh data, their
/// error figures, the calibration model's curves and the Dahl loop.
fn predictors(r: &mut Report, run: &DemoRun, notes: &mut Notes) {
    let opts = &run.opts;
    let random = &run.random;
    let [pd, cal, dahl, dahl4] = [0, 1, 2, 3].map(|i| &run.scored[i]);
    let units = &random.schema.units;
    let s = r.section("Three predictors, scored on fresh data");
    s.paragraph(format!(
        "Each model is fitted (least squares) and then replayed causally over a separate \
         run of random seeks in a 250-track range (random.csv), as firmware would use it. \
         position-direction is the industry practice of 1997 (a 2nd-order polynomial plus \
         an inbound/outbound offset), calibrated as the paper calibrates it: on the two far \
         curves of Table I (table1.csv). The others are fitted on calibration.csv (Tables \
         I–VII followed by {} random seeks): calibration adds the seek-length, rest-memory \
         and drift curves of the paper's Section III-A; dahl is the paper's two-parameter \
         state-space friction model (Section III-B); {} is a richer friction model with four \
         Dahl elements.",
        opts.random_seeks, dahl4.label
    ))
    .headline(&[
        (
            format!("{} error std", pd.label),
            format!("{} counts", fmt_num(pd.score.std)),
        ),
        (
            format!("{} error std", cal.label),
            format!("{} counts", fmt_num(cal.score.std)),
        ),
        ("reduction".into(), pct(pd.score.std, cal.score.std)),
        (
            format!("{} error std", dahl.label),
            format!("{} counts", fmt_num(dahl.score.std)),
        ),
        (
            format!("{} error std", dahl4.label),
            format!("{} counts", fmt_num(dahl4.score.std)),
        ),
    ])
    .table(scores::fit_summary_table(&run.scored, units))
    .table(scores::score_table(
        &run.scored,
        "Out of sample: position-direction fitted on table1.csv, the others on \
         calibration.csv; scored on random.csv; a bimodality coefficient above 0.555 \
         suggests two modes, the dip test (Hartigans' test of unimodality) finds two humps \
         when p < 0.05",
        units,
    ));
    scores::errors_figure(
        s,
        &[pd, cal],
        units,
        "Figs. 10/11: prediction error on the random run vs position (top) and its \
         histogram (bottom). The position-direction model calibrated on the far curves \
         misses random seeks by roughly ±Fc's shortfall with the sign of the seek \
         direction — random seeks stop short of uncrossed rest positions and rarely reach \
         the far curves — so its error has two humps (the table's dip test says whether \
         they are separate on this run); the calibration model's error is narrower and \
         centred.",
    );
    scores::errors_figure(
        s,
        &[dahl, dahl4],
        units,
        "The two friction-state models on the same random run. Their axes are scaled to their \
         own errors, not to the figure above: compare the numbers on the axes, not the heights.",
    );
    scores::curves_figure(
        s,
        random,
        cal,
        "The random run's measurements by approach direction with the calibration \
         model's asymptotic inbound and outbound curves.",
        notes,
    );
    match &run.dahl_loop {
        Ok(p) => {
            s.figure(
                views::dahl_loop(p, &run.tables[1].schema.units, &dahl.label),
                "Figs. 13/14: the Table II hysteresis loop, measured and as the fitted Dahl \
                 model replays it. The model captures the loop's shape from two parameters \
                 (its friction level and initial slope).",
            );
        }
        Err(e) => {
            let line = format!("The Dahl loop could not be drawn: {e}");
            s.paragraph(format!("{line}."));
            notes.0.push(line);
        }
    }
}

/// The demo's page (without the files section) from its run.
/// discover's first edit beside the ladder's largest step after position-direction (discover's
/// start), both on the random run, and whether the edit is a term of the seek history as the
/// ladder's `seek` is; `None` when discover applied no edit or the ladder has no such step.
pub(super) fn discovery_beside_ladder(run: &DemoRun) -> Option<String> {
    use crate::model::terms::{dahl, play, seek};
    let d = run.discovery.as_ref().ok()?;
    let first = d.steps.first()?;
    let rungs = &run.ladder.steps;
    let start = rungs
        .iter()
        .position(|r| r.terms.join(",") == crate::model::preset::POSITION_DIRECTION)?;
    let drop = |i: usize| rungs[i - 1].std - rungs[i].std;
    let big = (start + 1..rungs.len()).max_by(|&a, &b| drop(a).total_cmp(&drop(b)))?;
    let added = rungs[big].added_since(&rungs[big - 1]).join(", ");
    let num = crate::plot::svg::fmt_num;
    let head = first
        .edit
        .strip_prefix("add ")
        .and_then(|t| t.split(':').next())
        .unwrap_or("");
    let history = [seek::HEAD, play::HEAD, dahl::HEAD].contains(&head);
    Some(format!(
        "Beside the ladder: discover's first edit, `{}` (from `{}`), takes the error std on \
         random.csv from {} to {} {unit}; the ladder's largest step after {}, `+ {added}`, from \
         {} to {} {unit}.{}",
        first.edit,
        first.feature,
        num(first.std_before),
        num(first.std_after),
        crate::model::preset::POSITION_DIRECTION,
        num(rungs[big - 1].std),
        num(rungs[big].std),
        if history {
            " Both are terms of the seek history (the length of each seek and the reversals \
             before it); discover applies the one whose verified gain is the largest."
        } else {
            ""
        },
        unit = d.unit,
    ))
}

fn demo_page(run: &DemoRun, notes: &mut Notes) -> Report {
    let opts = &run.opts;
    let random = &run.random;
    let mut r = Report::new("biasctl report — bias of a disk-drive rotary actuator");
    r.intro(format!(
        "Built-in drive paper1997, seed {}, {} random test seeks. Generated by biasctl {}; \
         rerun with `biasctl report --seed {}` for the same numbers.",
        opts.seed,
        random.measured_count(),
        env!("CARGO_PKG_VERSION"),
        opts.seed
    ));
    r.intro(
        "This report follows K. Eddy, J. Steele, W. Messner, “Bias in disk drive rotary \
         actuators” (IEEE Trans. Magn., 1997) on a simulated drive: what bias is, how well three \
         predictors follow it, what is still missing, and what a good prediction buys in \
         settle time.",
    );

    // 1. What bias is.
    paper::what_bias_is(&mut r, run);

    // 2. Predictors.
    predictors(&mut r, run, notes);

    // 3. Diagnose.
    {
        let s = r.section("What diagnose finds in the simple model's error");
        s.paragraph(
            "diagnose asks, for every candidate feature of the seek history (position, signed \
             and absolute seek length, direction change, tracks since reversal, distance to \
             uncrossed rest positions, dwell, elapsed time), how much of the position-direction \
             model's test error a flexible curve of that feature predicts out of sample, with a \
             permutation test that accounts for trying many features.",
        );
        diagnosis::diagnosis(
            s,
            &run.diagnosis,
            "The residual (measured − predicted) against each top feature: binned mean ± \
             standard error, marker size by the number of seeks, raw residuals faint behind.",
        );
    }

    // 4. Ladder.
    {
        let s = r.section("The ladder: adding one effect at a time");
        s.paragraph(
            "Starting from the position polynomial alone, each rung adds one term, refits on \
             the calibration run and scores on the random run. The drop at each rung is what \
             that physical effect is worth for prediction.",
        );
        ladder::ladder(
            s,
            &run.ladder,
            &random.schema.units,
            "Test error std after each added term, with the reduction from the previous rung.",
        );
    }

    // 5. Discover.
    {
        let train = format!("{DISCOVER_TRAIN}.csv");
        let s = r.section("Discover: the terms the data ask for");
        s.paragraph(format!(
            "discover trains on {train}, a second random run (seed {}), not on the calibration \
             run the ladder fits: it verifies each edit by refitting on two of three contiguous \
             stretches of its training log and scoring on the third, and the calibration run's \
             first stretch is the paper's tables, whose tracks and seek lengths its random seeks \
             never visit. Refitted without them, both models extrapolate there; that \
             stretch's loss differences are not noise, yet they dominate the z-score's noise \
             estimate (over 80 % of its variance on this drive), and no edit reaches \
             significance.",
            run.opts.seed.wrapping_add(1)
        ));
        discover::discover(s, &run.discovery, &train, "random.csv");
        if let Some(text) = discovery_beside_ladder(run) {
            s.paragraph(text);
        }
    }

    // 6. Settle, 7. Link.
    settle::settle(&mut r, &run.settle);
    settle::link(&mut r, &run.settle);
    r
}

/// The demo's five summary lines.
fn demo_summary(run: &DemoRun) -> Vec<String> {
    let [pd, cal, dahl, dahl4] = [0, 1, 2, 3].map(|i| &run.scored[i]);
    let settle = &run.settle.report;
    let paper_ms = settle.paper_robust.as_ref().and_then(|p| p.settle_ms);
    let lead = run.diagnosis.diagnosis.features.first();
    let rob = run
        .settle
        .link
        .iter()
        .find(|(l, _, _)| l == "calibration")
        .map(|(_, std, w)| (*std, *w));
    vec![
        format!(
            "prediction error std on {} random seeks: position-direction {} → calibration {} counts ({} lower)",
            run.random.measured_count(),
            fmt_num(pd.score.std),
            fmt_num(cal.score.std),
            pct(pd.score.std, cal.score.std)
        ),
        format!(
            "state-space models: {} {} counts, {} {} counts",
            dahl.label,
            fmt_num(dahl.score.std),
            dahl4.label,
            fmt_num(dahl4.score.std)
        ),
        match lead {
            Some(f) => format!(
                "diagnose: `{}` explains {:.0} % of the position-direction error (suggests `{}`)",
                f.name,
                100.0 * f.explained,
                f.suggested_term.as_deref().unwrap_or("—")
            ),
            None => "diagnose: no feature".into(),
        },
        format!(
            "settle: zero feedforward {} → optimal start {} ({} faster; paper's robust choice {})",
            ms(settle.zero_ff_settle_ms),
            ms(settle.optimal_settle_ms),
            pct(
                settle.zero_ff_settle_ms.unwrap_or(f64::NAN),
                settle.optimal_settle_ms.unwrap_or(f64::NAN)
            ),
            ms(paper_ms)
        ),
        match rob {
            Some((std, w)) => format!(
                "worst case with calibration's error (Δb = {} counts): robust start {}, zero feedforward {}",
                fmt_num(std),
                ms(w.robust_worst_settle_ms),
                ms(w.zero_ff_worst_settle_ms)
            ),
            None => "worst case: n/a".into(),
        },
    ]
}

/// The story of a user's log: its bias plots; the presets (and `model`, if given) fitted on the
/// first half of the measured rows and scored on the second; the diagnosis of `model` on the
/// whole log, or else of position-direction on the second half; the ladder; discover. Steps
/// that the data cannot support (too few rows, a model that does not fit) are reported in the
/// page, not as errors. Writes `report.html`, the model, score, diagnosis, ladder and discover
/// files into `dir`. Every number, table and axis is labelled with the log's units
/// ([`crate::log::LogSchema::units`]).
pub fn data_report(
    dir: &Path,
    log: &crate::log::Log,
    model: Option<&crate::model::FittedModel>,
    opts: &CheckedStoryOptions,
    progress: &mut dyn FnMut(Progress<'_>),
) -> Result<StoryOutcome, StoryError> {
    let mut out = Out::create(dir)?;
    let mut steps = Steps::new(DATA_STEPS, progress);
    let run = super::run::data_run(log, model, opts, &mut steps);
    for s in &run.scored {
        write_scored(
            &mut out,
            s,
            "fitted on the first half",
            "scored on the second half",
        )?;
    }
    if let Some(Ok(u)) = &run.user {
        out.text(
            "score_your_model.json",
            &pretty(&u.score)?,
            "your model scored on the whole log",
        )?;
    }
    if let Ok(d) = &run.diagnosis {
        out.text(
            "diagnosis.json",
            &d.diagnosis.to_json()?,
            &format!("diagnosis of {}", d.name),
        )?;
    }
    if let Ok(l) = &run.ladder {
        out.text(
            "ladder.json",
            &l.to_json()?,
            "test error std after each added term",
        )?;
    }
    if let Ok(d) = &run.discovery {
        out.text(
            "discover.json",
            &d.to_json()?,
            "discover's verified edits, first half → second half",
        )?;
    }
    let summary = data_summary(&run);
    out.finish(&mut steps, |notes| data_page(&run, notes), summary)
}

/// The data report's page (without the files section) from its run.
fn data_page(run: &DataRun, notes: &mut Notes) -> Report {
    let file = &run.file;
    let log = &run.log;
    let units = &log.schema.units;
    let mut r = Report::new(format!("biasctl report — {file}"));
    r.intro(format!(
        "Measurement log {file}: {} rows, {} with a measured bias. Seed {} (diagnosis \
         permutations). Generated by biasctl {}.",
        log.len(),
        log.measured_count(),
        run.opts.seed,
        env!("CARGO_PKG_VERSION")
    ));
    data::your_data(&mut r, run);
    let user = run.user.as_ref().and_then(|u| u.as_ref().ok());
    {
        let s = r.section("Models fitted on the first half, scored on the second");
        s.paragraph(
            "Out of sample: each preset is fitted on the first half of the measured rows and \
             replayed causally over the second half. Your own model, if given, is scored on the \
             whole log in a separate table: in sample if it was fitted on this log, so its \
             numbers are not comparable with the presets'.",
        );
        if let Some(w) = user.and_then(|u| u.model.outside_range(&u.prediction.positions)) {
            s.paragraph(format!("Warning about your model: {w}."));
        }
        if run.scored.is_empty() && user.is_none() {
            s.paragraph("No preset could be fitted and scored on this log.");
        } else {
            s.table(scores::fit_summary_table(
                run.scored.iter().chain(user),
                units,
            ));
        }
        if !run.scored.is_empty() {
            s.table(scores::score_table(
                run.scored.iter(),
                "Out of sample: presets fitted on the first half, scored on the second half",
                units,
            ));
            let shown: Vec<&ScoredModel> = run.scored.iter().take(4).collect();
            scores::errors_figure(
                s,
                &shown,
                units,
                "Out-of-sample prediction error vs position and its histogram (Figs. 10/11 \
                 view).",
            );
        } else if user.is_some() {
            s.paragraph("No preset could be fitted and scored on this log.");
        }
        for f in &run.failures {
            s.paragraph(format!("Not fitted — {f}."));
        }
        if let Some(u) = user {
            s.table(scores::score_table(
                [u],
                "Your model on the whole log (in sample if it was fitted on this log)",
                units,
            ));
        }
        if let Some(Err(f)) = &run.user {
            s.paragraph(format!("Your model could not be scored — {f}."));
        }
        if let Some(c) = user.or(run.scored.first()) {
            scores::curves_figure(
                s,
                log,
                c,
                format!(
                    "Bias vs position with the curves of {}.",
                    scores::model_phrase(&c.label)
                ),
                notes,
            );
        }
    }
    {
        let s = r.section("What diagnose finds");
        match &run.diagnosis {
            Ok(d) => {
                s.paragraph(format!("The residual of {}.", d.name));
                diagnosis::diagnosis(
                    s,
                    d,
                    "The residual against each top feature: binned mean ± standard error.",
                );
            }
            Err(e) => {
                s.paragraph(format!("No diagnosis: {e}."));
            }
        }
    }
    {
        let s = r.section("The ladder: adding one effect at a time");
        match &run.ladder {
            Ok(l) => ladder::ladder(
                s,
                l,
                units,
                "Test error std after each added term (first half fit, second half test).",
            ),
            Err(e) => {
                s.paragraph(format!("No ladder: {e}."));
            }
        }
    }
    discover::discover(
        r.section("Discover: the terms the data ask for"),
        &run.discovery,
        "the first half of the log",
        "the second half",
    );
    r
}

/// The data report's five summary lines.
fn data_summary(run: &DataRun) -> Vec<String> {
    let units = &run.log.schema.units;
    let best = run
        .scored
        .iter()
        .min_by(|a, b| a.score.std.total_cmp(&b.score.std));
    vec![
        format!("{}: {} measured rows", run.file, run.log.measured_count()),
        format!(
            "presets fitted: {} of {} (out of sample: first half → second half)",
            run.scored.len(),
            DATA_MODELS.len()
        ),
        match best {
            Some(b) => format!(
                "lowest test error std: {} {} (`{}`, fitted on the first half, scored on the second)",
                fmt_num(b.score.std),
                units.bias,
                b.label
            ),
            None => "no model scored".into(),
        },
        match &run.user {
            Some(Ok(u)) => format!(
                "your model: error std {} {} on the whole log (in sample if fitted on it)",
                fmt_num(u.score.std),
                units.bias
            ),
            Some(Err(_)) => {
                "your model (--model) could not be scored on this log; see the report".into()
            }
            None => "no model of yours given (--model)".into(),
        },
        if run.failures.is_empty() {
            "every preset could be fitted".into()
        } else {
            format!(
                "{} preset(s) could not be fitted on this log (see the report)",
                run.failures.len()
            )
        },
    ]
}
