//! The story the report tells, in order: what bias is (the built-in drive's phenomena P1–P8 and
//! the Table I–VII figures), three predictors fitted on a calibration run and scored on a
//! separate random run, what diagnose finds in the position-direction residual, the ladder, the
//! settle optimisation, and the link from prediction error to worst-case settle time.
//! [`demo_report`] runs it on the built-in drive; [`data_report`] on a user's own log (and
//! optionally their fitted model). Both write `report.html` and every CSV/JSON behind it into
//! one folder and are deterministic for a given [`StoryOptions::seed`].

use std::path::{Path, PathBuf};

use super::{Cell, Report, Table};
use crate::control::settle::{
    AnalyseError, HandoffTable, SettleError, SettleSpec, analyse, worst_case_settle,
};
use crate::control::{Controller, ServoError};
use crate::diagnose::{
    CheckedDiagnoseConfig, DiagnoseConfig, Diagnosis, FeatureTable, Ladder, ModelDiagnosisError,
    diagnose_residual, ladder_fit, replay_model,
};
use crate::fit::{CheckedFitOptions, FitError, fit};
use crate::log::{Log, LogError, Units};
use crate::model::preset;
use crate::model::{FittedModel, ModelError, ModelSpec, Prediction, SpecError};
use crate::plot::figures::{Sweep, SweepFigure, SweepSeries, calibration_sweep};
use crate::plot::svg::fmt_num;
use crate::plot::{from_log, views};
use crate::render::{OutputError, StagedDir, write_string_atomic};
use crate::score::{Score, ScoreError, score_with_units};
use crate::sim::{Drive, SequenceOptions, SimConfig, SimError, Truth, simulate, simulate_to_files};

/// Settings of a story run.
#[derive(Debug, Clone, PartialEq)]
pub struct StoryOptions {
    /// Seed of every simulation and of the diagnosis (printed in the report).
    pub seed: u64,
    /// Random seeks of the test run and of the calibration run's random tail (default 2000).
    pub random_seeks: u64,
    /// Permutations of the diagnosis' significance test (default 199).
    pub permutations: usize,
    /// Settle preset (default `paper1997`).
    pub settle_preset: String,
}

impl Default for StoryOptions {
    fn default() -> Self {
        StoryOptions {
            seed: 1,
            random_seeks: crate::sim::DEFAULT_N,
            permutations: 199,
            settle_preset: "paper1997".into(),
        }
    }
}

impl StoryOptions {
    /// A smaller, faster run (300 random seeks, 99 permutations) for tests and quick looks.
    pub fn quick(seed: u64) -> Self {
        StoryOptions {
            seed,
            random_seeks: 300,
            permutations: 99,
            ..Default::default()
        }
    }
}

/// One progress report: step `done` of `total` is starting, described by `step`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress<'a> {
    /// What is being done now.
    pub step: &'a str,
    /// Steps finished so far.
    pub done: usize,
    /// Steps in all.
    pub total: usize,
}

/// Why a story could not be told.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StoryError {
    /// A simulation setting was rejected.
    #[error("simulation setting")]
    SimConfig(#[from] crate::sim::ConfigError),
    /// A simulation failed.
    #[error("simulation")]
    Sim(#[from] SimError),
    /// A log could not be read back.
    #[error("reading a log")]
    Log(#[from] LogError),
    /// A model spec was rejected.
    #[error("model spec")]
    Spec(#[from] SpecError),
    /// A model could not be fitted.
    #[error("fitting `{model}` on {file}")]
    Fit {
        /// The model.
        model: String,
        /// The training log.
        file: String,
        /// Why.
        #[source]
        source: Box<FitError>,
    },
    /// A model could not be replayed.
    #[error("replaying a model")]
    Model(#[from] ModelError),
    /// A score could not be computed.
    #[error("scoring")]
    Score(#[from] ScoreError),
    /// The diagnosis or the ladder failed.
    #[error("diagnosis")]
    Diagnose(#[from] ModelDiagnosisError),
    /// The settle preset is not valid.
    #[error("settle preset")]
    SettleConfig(#[from] crate::control::settle::ConfigError),
    /// The settle analysis failed.
    #[error("settle analysis")]
    Analyse(#[from] AnalyseError),
    /// The worst-case settle computation failed.
    #[error("worst-case settle")]
    Settle(#[from] SettleError),
    /// The controller could not be designed.
    #[error("controller design")]
    Servo(#[from] ServoError),
    /// A file could not be written.
    #[error("writing the report")]
    Output(#[from] OutputError),
}

/// What a story run wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct StoryOutcome {
    /// The report.
    pub report: PathBuf,
    /// Every other file written, in the order written.
    pub files: Vec<PathBuf>,
    /// The headline numbers in five lines of plain text.
    pub summary: Vec<String>,
}

/// The four predictors of the story: (label, term list, training run). position-direction is
/// calibrated as the paper (and 1997 practice) calibrates it, on the two far curves of Table I;
/// the others on the whole calibration run.
pub const STORY_MODELS: [(&str, &str, &str); 4] = [
    ("position-direction", preset::POSITION_DIRECTION, "table1"),
    ("calibration", preset::CALIBRATION, "calibration"),
    ("dahl", preset::DAHL, "calibration"),
    (preset::RICH_DAHL, preset::RICH_DAHL, "calibration"),
];

/// The ladder's terms, added one at a time.
pub const LADDER_TERMS: [&str; 5] = preset::CALIBRATION_TERMS;

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

impl Out<'_> {
    /// Where a file of the run is written now (inside the staging folder).
    fn path(&self, name: &str) -> PathBuf {
        match &self.staged {
            Some(s) => s.path(name),
            None => self.dir.join(name),
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
    /// Moves every staged file into `dir` ([`StagedDir::commit`]).
    fn commit(&mut self) -> Result<(), StoryError> {
        if let Some(s) = self.staged.take() {
            s.commit()?;
        }
        Ok(())
    }
}

struct Steps<'a> {
    done: usize,
    total: usize,
    cb: &'a mut dyn FnMut(Progress<'_>),
}

impl Steps<'_> {
    fn start(&mut self, step: &str) {
        (self.cb)(Progress {
            step,
            done: self.done,
            total: self.total,
        });
        self.done += 1;
    }
    fn finish(&mut self) {
        (self.cb)(Progress {
            step: "done",
            done: self.total,
            total: self.total,
        });
    }
}

/// Creates the staging folder beside `dir` and the step counter and file list of a run.
fn start<'a>(
    dir: &'a Path,
    total: usize,
    cb: &'a mut dyn FnMut(Progress<'_>),
) -> Result<(Steps<'a>, Out<'a>), StoryError> {
    let staged = StagedDir::create(dir)?;
    Ok((
        Steps { done: 0, total, cb },
        Out {
            dir,
            staged: Some(staged),
            files: Vec::new(),
        },
    ))
}

fn fit_named(spec: &str, label: &str, log: &Log) -> Result<FittedModel, StoryError> {
    let spec = ModelSpec::parse(spec)?;
    fit(&spec, log, &CheckedFitOptions::default()).map_err(|e| StoryError::Fit {
        model: label.to_string(),
        file: log.schema.file.clone(),
        source: Box::new(e),
    })
}

/// A model label as part of a file name: the term-list separators `,` and `:` become `_`.
fn file_stem(label: &str) -> String {
    label.replace([',', ':'], "_")
}

fn pretty<T: serde::Serialize>(v: &T) -> String {
    serde_json::to_string_pretty(v).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
}

fn ms(v: Option<f64>) -> String {
    v.map_or("not settled".into(), |m| format!("{} ms", fmt_num(m)))
}

fn pct(from: f64, to: f64) -> String {
    if from > 0.0 && from.is_finite() && to.is_finite() {
        format!("{:.0} %", 100.0 * (from - to) / from)
    } else {
        "n/a".into()
    }
}

/// `(x, bias)` of the measured rows of a table log with their history features, and the
/// previous rows' tracks (for the rest offset of Table VI).
fn measured_rows(log: &Log) -> Vec<(crate::history::SeekFeatures, f64, Option<f64>)> {
    let mut out = Vec::new();
    for (i, r, f) in crate::history::replay(log) {
        let two_back = i.checked_sub(2).map(|j| log.rows[j].track);
        if let Some(b) = r.bias {
            out.push((f, b, two_back));
        }
    }
    out
}

/// The Figs. 5–9 and 12 sweeps of the simulated Tables II–VII (see
/// [`crate::sim::sequence::table`] for the sequences).
fn table_sweeps(tables: &[Log]) -> Vec<(String, String)> {
    let rows: Vec<_> = tables.iter().map(measured_rows).collect();
    let series = |name: &str, points: Vec<(f64, f64)>, joined: bool| SweepSeries {
        name: name.into(),
        points,
        joined,
    };
    let refs = |t: &[(crate::history::SeekFeatures, f64, Option<f64>)], n: usize| {
        t.iter()
            .take(n)
            .map(|(f, b, _)| {
                let label = if f.direction > 0 {
                    "inbound curve at target"
                } else {
                    "outbound curve at target"
                };
                (label.to_string(), *b)
            })
            .collect::<Vec<_>>()
    };
    let mut out = Vec::new();
    // Fig. 5: the Table II loop.
    let t2 = &rows[1];
    let branch = |dir: i8| -> Vec<(f64, f64)> {
        t2.iter()
            .skip(1)
            .filter(|(f, _, _)| f.direction == dir)
            .map(|(f, b, _)| (f.target, *b))
            .collect()
    };
    let mut loop_sweep = Sweep {
        figure: SweepFigure::Fig5SeekLength,
        series: vec![
            series("outbound one-track steps", branch(-1), true),
            series("inbound one-track steps back", branch(1), true),
        ],
        levels: refs(t2, 1),
    };
    let svg5 = calibration_sweep(&loop_sweep)
        .replace("tracks moved since reversal (tracks)", "position (tracks)")
        .replace(
            "bias vs tracks moved since reversal",
            "the Table II loop, bias vs position",
        );
    out.push((
        svg5,
        "Fig. 5 (Table II, P4): after a long inbound seek the head steps outbound one track at a \
         time, then back. The bias does not jump to the outbound curve: it walks along a \
         hysteresis loop between the two curves — the pivot's friction needs tens of tracks of \
         travel to reverse."
            .into(),
    ));
    loop_sweep.levels.clear();
    // Fig. 6: Table III.
    let t3 = &rows[2];
    let pts3: Vec<(f64, f64)> = t3
        .iter()
        .skip(2)
        .map(|(f, b, _)| (-f.seek_length, *b))
        .collect();
    out.push((
        calibration_sweep(&Sweep {
            figure: SweepFigure::Fig6SourceOffset,
            series: vec![series("direction change at source", pts3, true)],
            levels: refs(t3, 2),
        }),
        "Fig. 6 (Table III, P4): bias at one target after a seek from a source at the given \
         offset, always reversing at the source. Short seeks stay between the curves, seeks of \
         ~50–100 tracks overshoot the far curve, ~100–200 undershoot it, longer ones land on it."
            .into(),
    ));
    // Figs. 7 and 8: Tables IV and V.
    for (k, fig, caption) in [
        (
            3usize,
            SweepFigure::Fig7NoDirectionChange,
            "Fig. 7 (Table IV, P5): the same sweep without a direction change at the source: \
             the overshoot is weaker.",
        ),
        (
            4usize,
            SweepFigure::Fig8DirectionChange,
            "Fig. 8 (Table V, P5): with a direction change at the source (the head crossed the \
             source first): the overshoot is stronger.",
        ),
    ] {
        let t = &rows[k];
        let side = |inbound: bool| -> Vec<(f64, f64)> {
            t.iter()
                .skip(2)
                .filter(|(f, _, _)| (f.seek_length > 0.0) == inbound)
                .map(|(f, b, _)| (-f.seek_length, *b))
                .collect()
        };
        out.push((
            calibration_sweep(&Sweep {
                figure: fig,
                series: vec![
                    series("inbound seeks (source on OD side)", side(true), true),
                    series("outbound seeks (source on ID side)", side(false), true),
                ],
                levels: refs(t, 2),
            }),
            caption.into(),
        ));
    }
    // Fig. 9: Table VI.
    let t6 = &rows[5];
    let pts6: Vec<(f64, f64)> = t6
        .iter()
        .skip(1)
        .filter_map(|(f, b, p)| p.map(|p| (p - f.target, *b)))
        .collect();
    out.push((
        calibration_sweep(&Sweep {
            figure: SweepFigure::Fig9RestOffset,
            series: vec![series("rest at offset, far OD, then target", pts6, true)],
            levels: vec![(
                "no rest nearby".into(),
                t6.first().map_or(f64::NAN, |r| r.1),
            )],
        }),
        "Fig. 9 (Table VI, P6): the head rested at an intermediate position, went far OD, then \
         came to the target. A rest position close to the target on one side, not crossed since, \
         changes the bias there: the pivot remembers where it rested."
            .into(),
    ));
    // Fig. 12: Table VII vs the Table II branch.
    let t7 = &rows[6];
    let one: Vec<(f64, f64)> = t7
        .iter()
        .map(|(f, b, _)| (f.seek_length.abs(), *b))
        .collect();
    let start = t2.first().map_or(0.0, |r| r.0.target);
    let many: Vec<(f64, f64)> = t2
        .iter()
        .skip(1)
        .filter(|(f, _, _)| f.direction < 0)
        .map(|(f, b, _)| (start - f.target, *b))
        .collect();
    out.push((
        calibration_sweep(&Sweep {
            figure: SweepFigure::Fig12SeekCount,
            series: vec![
                series("one N-track seek (Table VII)", one, true),
                series("N one-track seeks (Table II)", many, true),
            ],
            levels: Vec::new(),
        }),
        "Fig. 12 (Table VII): after a direction change, one seek of N tracks against N one-track \
         seeks. They differ: seek length matters, not only the distance travelled — which is \
         why the Dahl model, which treats an N-track seek as N one-track seeks, misses the \
         overshoot."
            .into(),
    ));
    out
}

/// Std of each true effect over the measured rows.
fn truth_table(truth: &[Truth]) -> Table {
    type Get = fn(&Truth) -> f64;
    let effects: [(&str, &str, Get); 9] = [
        ("P1 position", "flex cable, windage, gravity", |t| {
            t.position
        }),
        ("P2 direction", "pivot friction, main element", |t| {
            t.direction
        }),
        ("P4/P5 seek length", "pivot friction, extra elements", |t| {
            t.overshoot
        }),
        ("P3 time at track", "lubricant flow", |t| t.time),
        ("P6 rest memory", "pivot rest positions", |t| t.memory),
        ("P7 drift", "driver electronics", |t| t.drift),
        ("temperature", "ambient covariate", |t| t.temperature),
        ("P8 scatter", "turbulence, head/disk contact", |t| t.scatter),
        ("runout residue", "one-revolution average", |t| t.runout),
    ];
    let mut table = Table::new(&["effect", "source", "std (counts)", "range (counts)"]).caption(
        "Table A. The simulator's true decomposition of the bias over the random test run",
    );
    for (name, source, get) in effects {
        let v: Vec<f64> = truth.iter().map(get).collect();
        let spread = crate::numeric::stats::range(&v).map_or(f64::NAN, |[lo, hi]| hi - lo);
        table = table.row(vec![
            name.into(),
            source.into(),
            Cell::Fixed(crate::numeric::stats::std_dev(&v).unwrap_or(f64::NAN), 2),
            Cell::Fixed(spread, 2),
        ]);
    }
    table
}

/// One fitted and scored predictor.
struct Scored {
    label: String,
    model: FittedModel,
    prediction: Prediction,
    score: Score,
}

/// A p-value in a table cell: `p < 0.0001` below 1e-4 (never `p = 0`), else `p = …`.
fn p_cell(p: f64) -> String {
    if p < 1e-4 {
        "p < 0.0001".into()
    } else {
        format!("p = {}", fmt_num(p))
    }
}

fn score_table<'a>(
    scored: impl IntoIterator<Item = &'a Scored>,
    caption: &str,
    units: &Units,
) -> Table {
    let fit_std = format!("fit residual std ({})", units.bias);
    let test_std = format!("test error std ({})", units.bias);
    let test_mean = format!("test mean ({})", units.bias);
    let mut t = Table::new(&[
        "model",
        "terms",
        "parameters",
        &fit_std,
        &test_std,
        &test_mean,
        "bimodality",
        "two humps (dip test, p < 0.05)",
        "trend vs position (p < 0.01)",
    ])
    .caption(caption);
    for s in scored {
        let trend = s
            .score
            .trend
            .as_ref()
            .map(|t| {
                let verdict = if t.p_value < 0.01 { "yes" } else { "no" };
                format!("{verdict} ({})", p_cell(t.p_value))
            })
            .unwrap_or_else(|| "n/a".into());
        let humps = s
            .score
            .dip
            .as_ref()
            .map(|d| {
                let verdict = if s.score.bimodal { "yes" } else { "no" };
                format!("{verdict} ({})", p_cell(d.p_value))
            })
            .unwrap_or_else(|| "n/a".into());
        t = t.row(vec![
            s.label.clone().into(),
            s.model.spec.to_string().into(),
            s.model.fit.parameters.into(),
            Cell::Fixed(s.model.fit.residual_std, 2),
            Cell::Fixed(s.score.std, 2),
            Cell::Fixed(s.score.mean, 2),
            s.score
                .bimodality
                .map_or(Cell::Text("n/a".into()), |b| Cell::Fixed(b, 2)),
            humps.into(),
            trend.into(),
        ]);
    }
    t
}

fn diagnosis_table(d: &Diagnosis, top: usize) -> Table {
    let std_once = format!("std once added ({})", d.units.bias);
    let mut t = Table::new(&[
        "feature",
        "explains (out of sample)",
        "p (family-wise)",
        "shape",
        "suggested term",
        &std_once,
    ])
    .caption("Candidate features of the residual, strongest first");
    for f in d.features.iter().take(top) {
        t = t.row(vec![
            f.name.clone().into(),
            format!("{:.1} %", 100.0 * f.explained).into(),
            Cell::Number(f.p_value),
            f.shape.describe(&f.name, f.shape_at).into(),
            f.suggested_term
                .clone()
                .unwrap_or_else(|| "—".into())
                .into(),
            Cell::Fixed(f.expected_std, 2),
        ]);
    }
    t
}

fn ladder_table(l: &Ladder, units: &Units) -> Table {
    let test_std = format!("test error std ({})", units.bias);
    let mut t = Table::new(&["step", "terms", &test_std, "reduction vs step 0"])
        .caption("The ladder: fitted on the training run, scored on the test run");
    for (i, s) in l.steps.iter().enumerate() {
        t = t.row(vec![
            i.into(),
            s.terms.join(", ").into(),
            Cell::Fixed(s.std, 2),
            format!("{:.1} %", 100.0 * s.reduction).into(),
        ]);
    }
    t
}

fn diagnose_config(opts: &StoryOptions) -> Result<CheckedDiagnoseConfig, StoryError> {
    let config = DiagnoseConfig {
        permutations: opts.permutations,
        seed: opts.seed,
        ..DiagnoseConfig::default()
    };
    Ok(config.check().map_err(ModelDiagnosisError::from)?)
}

fn files_section(report: &mut Report, out: &Out<'_>) {
    let mut t = Table::new(&["file", "what it holds"]).caption("Files next to this report");
    for (p, what) in &out.files {
        let name = p
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        t = t.row(vec![name.into(), what.clone().into()]);
    }
    report
        .section("Files behind this report")
        .paragraph(
            "Every number and figure above comes from these files; each can be re-read by \
             biasctl (logs by every command, models by predict and score).",
        )
        .table(t);
}

/// The whole story on the built-in drive (`paper1997`), written into `dir` (created if
/// missing): the logs (with `_truth.csv`), the fitted models, their scores, the diagnosis, the
/// ladder, the settle analysis and `report.html`. `progress` is called before each step.
pub fn demo_report(
    dir: &Path,
    opts: &StoryOptions,
    progress: &mut dyn FnMut(Progress<'_>),
) -> Result<StoryOutcome, StoryError> {
    let (mut steps, mut out) = start(dir, 11 + STORY_MODELS.len(), progress)?;
    let seq_opts = SequenceOptions {
        n: Some(opts.random_seeks),
        ..Default::default()
    };
    let simulate_named = |name: &str, out: &mut Out<'_>| -> Result<Log, StoryError> {
        let cfg = SimConfig::new(Drive::paper1997(), name, &seq_opts, opts.seed, &[])?;
        let log_path = out.path(&format!("{name}.csv"));
        let truth_path = out.path(&format!("{name}_truth.csv"));
        simulate_to_files(&cfg, &log_path, Some(&truth_path))?;
        out.note(&format!("{name}.csv"), "simulated measurement log");
        out.note(
            &format!("{name}_truth.csv"),
            "each effect's true contribution per row",
        );
        let mut log = Log::read(&log_path, &crate::log::ColumnMap::default())?;
        // Figure titles name the file, not the folder it was written to.
        log.schema.file = format!("{name}.csv");
        Ok(log)
    };

    steps.start("simulating Tables I–VII and the dwell run");
    let mut tables = Vec::new();
    for n in 1..=7 {
        tables.push(simulate_named(&format!("table{n}"), &mut out)?);
    }
    let dwell = simulate_named("dwell", &mut out)?;
    steps.start("simulating the calibration run");
    let calibration = simulate_named("calibration", &mut out)?;
    steps.start("simulating the random test run");
    let random = simulate_named("random", &mut out)?;
    let random_cfg = SimConfig::new(Drive::paper1997(), "random", &seq_opts, opts.seed, &[])?;
    let mut truth = Vec::new();
    simulate(&random_cfg, |row| -> Result<(), StoryError> {
        if row.bias.is_some() {
            truth.push(row.truth);
        }
        Ok(())
    })?;

    let mut scored = Vec::new();
    for (label, terms, train) in STORY_MODELS {
        steps.start(&format!("fitting {label}"));
        let stem = file_stem(label);
        let train_log = if train == "table1" {
            &tables[0]
        } else {
            &calibration
        };
        let model = fit_named(terms, label, train_log)?;
        out.text(
            &format!("model_{stem}.json"),
            &model.to_json(),
            &format!("{label} model fitted on {train}.csv"),
        )?;
        let prediction = model.predict_log(&random)?;
        let sc = score_with_units(
            &prediction.residual,
            &prediction.positions,
            &random.schema.units,
        )?;
        out.text(
            &format!("score_{stem}.json"),
            &pretty(&sc),
            &format!("{label} scored on random.csv"),
        )?;
        scored.push(Scored {
            label: label.to_string(),
            model,
            prediction,
            score: sc,
        });
    }

    steps.start("diagnosing the position-direction residual");
    let dcfg = diagnose_config(opts)?;
    let table = FeatureTable::from_log(&random);
    let diagnosis = diagnose_residual(
        &scored[0].model,
        &table,
        &scored[0].prediction.residual,
        &dcfg,
    )?;
    out.text(
        "diagnosis.json",
        &diagnosis.to_json(),
        "diagnosis of the position-direction model on random.csv",
    )?;

    steps.start("building the ladder");
    let terms: Vec<String> = LADDER_TERMS.iter().map(|s| s.to_string()).collect();
    let ladder = ladder_fit(&calibration, &random, &terms, &CheckedFitOptions::default())?;
    out.text(
        "ladder.json",
        &ladder.to_json(),
        "test error std after each added term",
    )?;

    steps.start("settle analysis");
    let spec = SettleSpec::preset(&opts.settle_preset)?;
    let cfg = spec.validate()?;
    let settle = analyse(&cfg)?;
    out.text(
        "settle.json",
        &pretty(&settle),
        "settle analysis (paper1997)",
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

    steps.start("worst-case settle for each model's error");
    let ctl = Controller::design(&cfg.plant, &cfg.weights)?;
    let handoff_table = HandoffTable::new(&ctl, cfg.scenario.horizon)?;
    let handoff = cfg.scenario.handoff();
    let mut link = Vec::new();
    for s in &scored {
        let wc = worst_case_settle(&handoff_table, &handoff, &cfg.scenario.window, s.score.std)?;
        link.push((s.label.clone(), s.score.std, wc));
    }
    out.text(
        "worst_case.json",
        &pretty(
            &link
                .iter()
                .map(|(l, _, w)| (l.clone(), *w))
                .collect::<Vec<_>>(),
        ),
        "worst-case settle with each model's test error std as Δb",
    )?;

    steps.start("table figures");
    let sweeps = table_sweeps(&tables);

    steps.start("assembling the report");
    let pd = &scored[0];
    let cal = &scored[1];
    let dahl = &scored[2];
    let dahl4 = &scored[3];
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
    {
        let s = r.section("What bias is, and what this drive shows");
        s.paragraph(
            "Bias is the average current the voice-coil driver must supply to hold the head on \
             a track, measured as the tracking controller's integrator averaged over one disk \
             revolution once the head has settled. Units are counts (DAC counts of the driver). \
             Tracks are numbered from the outer diameter (OD, track 0) inwards; a positive seek \
             moves inbound, towards the inner diameter (ID). If the firmware knew the bias \
             before the head arrives it could start the integrator there and settle faster.",
        )
        .table(
            Table::new(&["#", "effect", "what the data show"])
                .caption("The bias phenomena of the paper (Section II)")
                .row(vec!["P1".into(), "position".into(), "a smooth trend over the stroke, a 2nd-order polynomial (Fig. 3)".into()])
                .row(vec!["P2".into(), "direction".into(), "inbound and outbound curves offset by a constant — pivot hysteresis (Fig. 3)".into()])
                .row(vec!["P3".into(), "time at track".into(), "at one track the bias creeps to a constant over seconds (Fig. 4)".into()])
                .row(vec!["P4".into(), "seek length".into(), "after a reversal short seeks trace a loop; ~50–100 tracks overshoot, ~100–200 undershoot (Figs. 5, 6)".into()])
                .row(vec!["P5".into(), "direction change at source".into(), "the overshoot is weaker without a reversal at the source (Figs. 7, 8)".into()])
                .row(vec!["P6".into(), "rest-position memory".into(), "an earlier rest close to the target, not crossed since, changes the bias (Fig. 9)".into()])
                .row(vec!["P7".into(), "drift".into(), "the constant term wanders over minutes (driver offset)".into()])
                .row(vec!["P8".into(), "scatter".into(), "measurement noise: turbulence, head/disk contact".into()]),
        )
        .figure(
            from_log::bias_vs_position(&tables[0]),
            "Fig. 3 (Table I, P1+P2): each target approached from far OD (inbound) and from far \
             ID (outbound). Two curves of the same shape; the gap between them is twice the \
             pivot's friction level.",
        )
        .figure(
            from_log::bias_vs_time(&dwell, None),
            "Fig. 4 (P3): the head stays on one track for 10 s; the bias approaches a constant.",
        );
        for (svg, caption) in sweeps {
            s.figure(svg, caption);
        }
        s.table(truth_table(&truth)).paragraph(
            "Table A is only possible on a simulator: it splits each measured bias of the random \
             test run into its causes. Position and direction are most of the variation; the \
             seek-length and memory effects are what the simple model below leaves behind.",
        );
    }

    // 2. Predictors.
    {
        let s = r.section("Three predictors, scored on fresh data");
        s.paragraph(format!(
            "Each model is fitted (least squares) and then replayed causally over a separate \
             run of random seeks in a 250-track range (random.csv), as firmware would use it. \
             position-direction is the industry practice of 1997 (a 2nd-order polynomial plus \
             an inbound/outbound offset), calibrated as the paper calibrates it: on the two far \
             curves of Table I (table1.csv). The others are fitted on calibration.csv (Tables \
             I–VII followed by {} random seeks): calibration adds the seek-length, rest-memory \
             and drift curves of the paper's Section III-A; dahl is the paper's two-parameter \
             state-space friction model (Section III-B); poly2,dahl:4 is a richer friction \
             model with four Dahl elements.",
            opts.random_seeks
        ))
        .headline(&[
            (
                "position-direction error std",
                format!("{} counts", fmt_num(pd.score.std)),
            ),
            (
                "calibration error std",
                format!("{} counts", fmt_num(cal.score.std)),
            ),
            ("reduction", pct(pd.score.std, cal.score.std)),
            (
                "dahl error std",
                format!("{} counts", fmt_num(dahl.score.std)),
            ),
            (
                "poly2,dahl:4 error std",
                format!("{} counts", fmt_num(dahl4.score.std)),
            ),
        ])
        .table(score_table(
            &scored,
            "position-direction fitted on table1.csv, the others on calibration.csv; scored \
             on random.csv; a bimodality \
             coefficient above 0.555 suggests two modes, the dip test (Hartigans' test of \
             unimodality) finds two humps when p < 0.05",
            &random.schema.units,
        ))
        .figure(
            views::errors(
                &[
                    (pd.label.as_str(), &pd.prediction),
                    (cal.label.as_str(), &cal.prediction),
                ],
                &random.schema.units,
            ),
            "Figs. 10/11: prediction error on the random run vs position (top) and its \
             histogram (bottom). The position-direction model calibrated on the far curves \
             misses random seeks by roughly ±Fc's shortfall with the sign of the seek \
             direction — random seeks stop short of uncrossed rest positions and rarely reach \
             the far curves — so its error has two humps (the table's dip test says whether \
             they are separate on this run); the calibration model's error is narrower and \
             centred.",
        )
        .figure(
            views::errors(
                &[
                    (dahl.label.as_str(), &dahl.prediction),
                    (dahl4.label.as_str(), &dahl4.prediction),
                ],
                &random.schema.units,
            ),
            "The two friction-state models on the same random run, on the same axes as above.",
        );
        match views::position(&random, Some(&cal.model)) {
            Ok(svg) => {
                s.figure(
                    svg,
                    "The random run's measurements by approach direction with the calibration \
                     model's asymptotic inbound and outbound curves.",
                );
            }
            Err(e) => {
                s.paragraph(format!(
                    "The calibration model's curves could not be drawn: {}.",
                    error_chain(&e)
                ));
            }
        }
        match dahl.model.predict_log(&tables[1]) {
            Ok(p) => {
                s.figure(
                    views::dahl_loop(&p, &tables[1].schema.units, "dahl"),
                    "Figs. 13/14: the Table II hysteresis loop, measured and as the fitted Dahl \
                     model replays it. The model captures the loop's shape from two parameters \
                     (its friction level and initial slope).",
                );
            }
            Err(e) => {
                s.paragraph(format!("The Dahl loop could not be drawn: {e}."));
            }
        }
    }

    // 3. Diagnose.
    {
        let s = r.section("What diagnose finds in the simple model's error");
        s.paragraph(
            "diagnose asks, for every candidate feature of the seek history (position, signed \
             and absolute seek length, direction change, tracks since reversal, distance to \
             uncrossed rest positions, dwell, elapsed time), how much of the position-direction \
             model's test error a flexible curve of that feature predicts out of sample, with a \
             permutation test that accounts for trying many features.",
        )
        .paragraph(diagnosis.summary.clone())
        .table(diagnosis_table(&diagnosis, 6))
        .figure(
            views::diagnose_panel(&diagnosis, &table, &pd.prediction.residual, 6),
            "The residual (measured − predicted) against each top feature: binned mean ± \
             standard error, marker size by the number of seeks, raw residuals faint behind.",
        );
    }

    // 4. Ladder.
    r.section("The ladder: adding one effect at a time")
        .paragraph(
            "Starting from the position polynomial alone, each rung adds one term, refits on \
             the calibration run and scores on the random run. The drop at each rung is what \
             that physical effect is worth for prediction.",
        )
        .table(ladder_table(&ladder, &random.schema.units))
        .figure(
            views::ladder(&ladder, &random.schema.units),
            "Test error std after each added term, with the reduction from the previous rung.",
        );

    // 5. Settle.
    let paper_ms = settle.paper_robust.as_ref().and_then(|p| p.settle_ms);
    r.section("Settling faster: the integrator start value at handoff")
        .paragraph(format!(
            "When the seek controller hands over to track following, the integrator's start \
             value decides how fast the head settles into the ±{} µm window after a {} µm \
             step. Zero feedforward starts it at its converged value (the bias); the optimum \
             (eqs. 14–16) is any value between the running bounds at the first sample where \
             they cross. The paper's robust choice takes the middle of the bounds at the first \
             local minimum of the upper bound; the worst-case robust choice settles fastest for \
             every bias within ±{} counts.",
            fmt_num(settle.window_um),
            fmt_num(settle.step_um),
            fmt_num(settle.worst_case.delta_b)
        ))
        .headline(&[
            ("zero feedforward", ms(settle.zero_ff_settle_ms)),
            ("optimal", ms(settle.optimal_settle_ms)),
            ("paper's robust", ms(paper_ms)),
            (
                "worst-case robust",
                ms(settle.robust.as_ref().map(|c| c.worst_settle_ms)),
            ),
            (
                "reduction (optimal)",
                pct(
                    settle.zero_ff_settle_ms.unwrap_or(f64::NAN),
                    settle.optimal_settle_ms.unwrap_or(f64::NAN),
                ),
            ),
        ])
        .figure(
            views::settle_bounds(&settle),
            "Fig. 15: the bounds U, L on the start value at each sample (thin) and their running \
             min/max from the end U*, L* (dashed). Where they cross is the fastest possible \
             settle; horizontal lines are the chosen start values.",
        )
        .figure(
            views::settle_responses(&settle),
            "Fig. 16: the position error after handoff for each choice, whole and zoomed on the \
             window.",
        );

    // 6. Link.
    {
        let mut t = Table::new(&[
            "model",
            "test error std = Δb (counts)",
            "worst-case settle, robust start (ms)",
            "worst-case settle, zero feedforward (ms)",
        ])
        .caption("If the bias is only known to ± the model's error std");
        for (label, std, wc) in &link {
            t = t.row(vec![
                label.clone().into(),
                Cell::Fixed(*std, 2),
                wc.robust_worst_settle_ms
                    .map_or(Cell::Text("not settled".into()), |v| Cell::Fixed(v, 1)),
                wc.zero_ff_worst_settle_ms
                    .map_or(Cell::Text("not settled".into()), |v| Cell::Fixed(v, 1)),
            ]);
        }
        r.section("From prediction error to settle time")
            .paragraph(
                "A start value is computed from a predicted bias. If the prediction may be off \
                 by Δb counts, the start value may be off by ∂z/∂d·Δb, and the head must settle \
                 for every bias in the range. Taking each model's test error std as Δb gives the \
                 worst-case settle time that model buys: better prediction, faster settling.",
            )
            .table(t);
    }

    files_section(&mut r, &out);
    r.write(&out.path("report.html"))?;
    out.commit()?;
    let report = dir.join("report.html");
    steps.finish();

    let lead = diagnosis.features.first();
    let rob = link
        .iter()
        .find(|(l, _, _)| l == "calibration")
        .map(|(_, std, w)| (*std, *w));
    let summary = vec![
        format!(
            "prediction error std on {} random seeks: position-direction {} → calibration {} counts ({} lower)",
            random.measured_count(),
            fmt_num(pd.score.std),
            fmt_num(cal.score.std),
            pct(pd.score.std, cal.score.std)
        ),
        format!(
            "state-space models: dahl {} counts, poly2,dahl:4 {} counts",
            fmt_num(dahl.score.std),
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
    ];
    Ok(StoryOutcome {
        report,
        files: std::mem::take(&mut out.files)
            .into_iter()
            .map(|f| f.0)
            .collect(),
        summary,
    })
}

/// The presets fitted on a user's log: (label, term list).
pub const DATA_MODELS: [(&str, &str); 4] = [
    ("position-direction", preset::POSITION_DIRECTION),
    ("dahl", preset::DAHL),
    ("calibration", preset::CALIBRATION),
    (preset::RICH_DAHL, preset::RICH_DAHL),
];

/// A log holding rows `range` of `log` (its seek history starts afresh at the first row).
/// `file` as seen from the current directory: relative to it (with `..` where needed) when the
/// path is absolute, unchanged when it is already relative (titles and captions then name the
/// file as the user typed it from where the command ran, never a machine's absolute path).
pub fn relative_to_cwd(file: &str) -> String {
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
pub fn positions_are_tracks(log: &Log) -> bool {
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

fn sub_log(log: &Log, range: std::ops::Range<usize>, part: &str) -> Log {
    let mut schema = log.schema.clone();
    schema.file = format!("{} ({part})", log.schema.file);
    Log {
        schema,
        rows: log.rows[range].to_vec(),
    }
}

/// The story of a user's log: its bias plots; the presets (and `model`, if given) fitted on the
/// first half of the measured rows and scored on the second; the diagnosis of `model` on the
/// whole log, or else of position-direction on the second half; the ladder. Steps that the
/// data cannot support (too few rows, a model that does not fit) are reported in the page, not
/// as errors. Writes `report.html`, the model, score, diagnosis and ladder files into `dir`.
/// Every number, table and axis is labelled with the log's units
/// ([`crate::log::LogSchema::units`]).
pub fn data_report(
    dir: &Path,
    log: &Log,
    model: Option<&FittedModel>,
    opts: &StoryOptions,
    progress: &mut dyn FnMut(Progress<'_>),
) -> Result<StoryOutcome, StoryError> {
    let (mut steps, mut out) = start(dir, 4 + DATA_MODELS.len(), progress)?;
    let file = relative_to_cwd(&log.schema.file);
    let mut named = log.clone();
    named.schema.file = file.clone();
    let log = &named;
    let units = &log.schema.units;
    let tracks_like = positions_are_tracks(log);
    let measured_idx: Vec<usize> = log
        .rows
        .iter()
        .enumerate()
        .filter(|(_, r)| r.bias.is_some())
        .map(|(i, _)| i)
        .collect();
    let split = measured_idx
        .get(measured_idx.len() / 2)
        .copied()
        .unwrap_or(log.rows.len());
    let train = sub_log(log, 0..split, "first half");
    let test = sub_log(log, split..log.rows.len(), "second half");

    let mut r = Report::new(format!("biasctl report — {file}"));
    r.intro(format!(
        "Measurement log {file}: {} rows, {} with a measured bias. Seed {} (diagnosis \
         permutations). Generated by biasctl {}.",
        log.rows.len(),
        log.measured_count(),
        opts.seed,
        env!("CARGO_PKG_VERSION")
    ));
    steps.start("bias plots");
    let tracks: Vec<f64> = log.rows.iter().map(|x| x.track).collect();
    let [lo, hi] = crate::numeric::stats::range(&tracks).unwrap_or([f64::NAN; 2]);
    let sec = r.section("Your data");
    sec.table(
        Table::new(&["quantity", "value"])
            .row(vec!["rows".into(), log.rows.len().into()])
            .row(vec!["measured rows".into(), log.measured_count().into()])
            .row(vec![
                "columns (time, position, bias)".into(),
                format!(
                    "{}, {}, {}",
                    log.schema.map.time, log.schema.map.track, log.schema.map.bias
                )
                .into(),
            ])
            .row(vec![
                "units (bias, position)".into(),
                format!("{}, {}", units.bias, units.position).into(),
            ])
            .row(vec![
                "covariates".into(),
                log.schema.covariates.join(", ").into(),
            ])
            .row(vec![
                "position range".into(),
                format!("{} … {} {}", fmt_num(lo), fmt_num(hi), units.position).into(),
            ])
            .row(vec![
                "time span (s)".into(),
                Cell::Number(
                    log.rows.last().map_or(0.0, |x| x.time_s)
                        - log.rows.first().map_or(0.0, |x| x.time_s),
                ),
            ]),
    )
    .figure(
        from_log::bias_vs_position(log),
        "Bias vs position, split by the direction of the move into each row (Fig. 3 view).",
    );
    if tracks_like {
        sec.figure(
            from_log::bias_vs_time(log, None),
            "Bias vs time at the position measured most often (Fig. 4 view).",
        )
        .figure(
            from_log::bias_vs_seek_length(log),
            "Bias vs signed seek length, split by whether the seek reversed direction \
                 (Figs. 5–9 view).",
        );
    } else {
        sec.paragraph(
            "The views of one track over time (Fig. 4) and of bias against seek length \
             (Figs. 5–9) are left out: this log's positions form a continuous trajectory, not \
             repeated visits to a set of tracks.",
        );
    }

    let mut scored = Vec::new();
    let mut failures = Vec::new();
    for (label, terms) in DATA_MODELS {
        steps.start(&format!("fitting {label}"));
        let attempt = || -> Result<Scored, StoryError> {
            let m = fit_named(terms, label, &train)?;
            let p = m.predict_log(&test)?;
            let sc = score_with_units(&p.residual, &p.positions, units)?;
            Ok(Scored {
                label: label.to_string(),
                model: m,
                prediction: p,
                score: sc,
            })
        };
        match attempt() {
            Ok(s) => {
                let stem = file_stem(label);
                out.text(
                    &format!("model_{stem}.json"),
                    &s.model.to_json(),
                    &format!("{label} fitted on the first half"),
                )?;
                out.text(
                    &format!("score_{stem}.json"),
                    &pretty(&s.score),
                    &format!("{label} scored on the second half"),
                )?;
                scored.push(s);
            }
            Err(e) => failures.push(format!("{label}: {}", error_chain(&e))),
        }
    }
    let mut user = None;
    let mut user_failure = None;
    if let Some(m) = model {
        match m.predict_log(log).map_err(StoryError::from).and_then(|p| {
            let sc = score_with_units(&p.residual, &p.positions, units)?;
            Ok((p, sc))
        }) {
            Ok((p, sc)) => {
                out.text(
                    "score_your_model.json",
                    &pretty(&sc),
                    "your model scored on the whole log",
                )?;
                user = Some(Scored {
                    label: "your model (whole log)".into(),
                    model: m.clone(),
                    prediction: p,
                    score: sc,
                });
            }
            Err(e) => user_failure = Some(error_chain(&e)),
        }
    }
    {
        let s = r.section("Models fitted on the first half, scored on the second");
        s.paragraph(
            "Out of sample: each preset is fitted on the first half of the measured rows and \
             replayed causally over the second half. Your own model, if given, is scored on the \
             whole log in a separate table: in sample if it was fitted on this log, so its \
             numbers are not comparable with the presets'.",
        );
        if let Some(w) = user
            .as_ref()
            .and_then(|u| u.model.outside_range(&u.prediction.positions))
        {
            s.paragraph(format!("Warning about your model: {w}."));
        }
        if scored.is_empty() {
            s.paragraph("No preset could be fitted and scored on this log.");
        } else {
            s.table(score_table(
                scored.iter(),
                "Out of sample: presets fitted on the first half, scored on the second half",
                units,
            ));
            let preds: Vec<(&str, &Prediction)> = scored
                .iter()
                .take(4)
                .map(|x| (x.label.as_str(), &x.prediction))
                .collect();
            s.figure(
                views::errors(&preds, units),
                "Out-of-sample prediction error vs position and its histogram (Figs. 10/11 \
                 view).",
            );
        }
        for f in &failures {
            s.paragraph(format!("Not fitted — {f}."));
        }
        if let Some(u) = &user {
            s.table(score_table(
                [u],
                "Your model on the whole log (in sample if it was fitted on this log)",
                units,
            ));
        }
        if let Some(f) = &user_failure {
            s.paragraph(format!("Your model could not be scored — {f}."));
        }
        let curves = user.as_ref().or(scored.first());
        if let Some(c) = curves {
            match views::position(log, Some(&c.model)) {
                Ok(svg) => {
                    s.figure(
                        svg,
                        format!("Bias vs position with the {} model's curves.", c.label),
                    );
                }
                Err(e) => {
                    s.paragraph(format!(
                        "The {} model's curves could not be drawn: {}.",
                        c.label,
                        error_chain(&e)
                    ));
                }
            }
        }
    }

    steps.start("diagnosing");
    let dcfg = diagnose_config(opts)?;
    // The replay scored above, when there is one, is the one the diagnosis needs.
    let first_scored_name = scored
        .first()
        .map(|s| format!("`{}` on the second half", s.label))
        .unwrap_or_default();
    let (dmodel, dpred, dlog, dname): (Option<&FittedModel>, Option<&Prediction>, &Log, &str) =
        match (model, scored.first()) {
            (Some(m), _) => (
                Some(m),
                user.as_ref().map(|u| &u.prediction),
                log,
                "your model on the whole log",
            ),
            // The first scored model: position-direction unless its fit failed on this log.
            (None, Some(s)) => (
                Some(&s.model),
                Some(&s.prediction),
                &test,
                first_scored_name.as_str(),
            ),
            (None, None) => (None, None, log, ""),
        };
    {
        let s = r.section("What diagnose finds");
        let diagnosed = dmodel.map(|m| {
            let residual = match dpred {
                Some(p) => p.residual.clone(),
                None => replay_model(m, dlog)?.residual,
            };
            let table = FeatureTable::from_log(dlog);
            let d = diagnose_residual(m, &table, &residual, &dcfg)?;
            Ok::<_, ModelDiagnosisError>((d, table, residual))
        });
        match diagnosed {
            Some(Ok((d, table, residual))) => {
                out.text(
                    "diagnosis.json",
                    &d.to_json(),
                    &format!("diagnosis of {dname}"),
                )?;
                s.paragraph(format!("The residual of {dname}."))
                    .paragraph(d.summary.clone())
                    .table(diagnosis_table(&d, 6))
                    .figure(
                        views::diagnose_panel(&d, &table, &residual, 6),
                        "The residual against each top feature: binned mean ± standard error.",
                    );
            }
            Some(Err(e)) => {
                s.paragraph(format!("No diagnosis: {}.", error_chain(&e)));
            }
            None => {
                s.paragraph("No diagnosis: no model could be fitted.");
            }
        }
    }

    steps.start("building the ladder");
    let terms: Vec<String> = LADDER_TERMS.iter().map(|s| s.to_string()).collect();
    {
        let s = r.section("The ladder: adding one effect at a time");
        match ladder_fit(&train, &test, &terms, &CheckedFitOptions::default()) {
            Ok(l) => {
                out.text(
                    "ladder.json",
                    &l.to_json(),
                    "test error std after each added term",
                )?;
                s.table(ladder_table(&l, units)).figure(
                    views::ladder(&l, units),
                    "Test error std after each added term (first half fit, second half test).",
                );
            }
            Err(e) => {
                s.paragraph(format!("No ladder: {}.", error_chain(&e)));
            }
        }
    }
    steps.start("assembling the report");
    files_section(&mut r, &out);
    r.write(&out.path("report.html"))?;
    out.commit()?;
    let report = dir.join("report.html");
    steps.finish();
    let best = scored
        .iter()
        .min_by(|a, b| a.score.std.total_cmp(&b.score.std));
    let summary = vec![
        format!("{file}: {} measured rows", log.measured_count()),
        format!(
            "presets fitted: {} of {} (out of sample: first half → second half)",
            scored.len(),
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
        match (&user, model) {
            (Some(u), _) => format!(
                "your model: error std {} {} on the whole log (in sample if fitted on it)",
                fmt_num(u.score.std),
                units.bias
            ),
            (None, Some(_)) => {
                "your model (--model) could not be scored on this log; see the report".into()
            }
            (None, None) => "no model of yours given (--model)".into(),
        },
        if failures.is_empty() {
            "every preset could be fitted".into()
        } else {
            format!(
                "{} preset(s) could not be fitted on this log (see the report)",
                failures.len()
            )
        },
    ];
    Ok(StoryOutcome {
        report,
        files: std::mem::take(&mut out.files)
            .into_iter()
            .map(|f| f.0)
            .collect(),
        summary,
    })
}

/// The error and its causes on one line.
fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cur = e.source();
    while let Some(c) = cur {
        s.push_str(": ");
        s.push_str(&c.to_string());
        cur = c.source();
    }
    s
}
