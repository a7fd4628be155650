//! The computation of a report, with no HTML in it: [`DemoRun`] (the built-in drive) and
//! [`DataRun`] (a user's log) hold every log, fitted model, score, diagnosis, ladder, discovery
//! and settle analysis a report shows. The sections ([`super::sections`]) turn a run into HTML;
//! [`super::story`] computes a run, writes its files and assembles the sections.
//!
//! Steps a run cannot take on the data at hand (too few rows, a model that does not fit) are
//! kept as `Err(message)` in the run, so the page can say why; errors that make the whole run
//! meaningless (a simulation that fails, the built-in drive's models that do not fit) are
//! [`StoryError`]s.

use std::path::{Path, PathBuf};

use crate::control::settle::{
    AnalyseError, HandoffTable, SettleError, SettleReport, SettleSpec, WorstCase, analyse,
    worst_case_settle,
};
use crate::control::{Controller, ServoError};
use crate::diagnose::{
    CheckedDiagnoseConfig, DiagnoseConfig, Diagnosis, FeatureTable, ModelDiagnosisError,
    diagnose_residual, replay_model,
};
use crate::field::Field;
use crate::fit::{CheckedFitOptions, FitError, fit};
use crate::log::{Log, LogError};
use crate::model::preset;
use crate::model::{FittedModel, ModelError, ModelSpec, Prediction, SpecError};
use crate::render::OutputError;
use crate::score::{Score, ScoreError, score_with_units};
use crate::select::{
    CheckedVerifyConfig, DiscoverConfig, Discovery, Ladder, discover, ladder_fit, ladder_terms,
};
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

/// Largest [`StoryOptions::random_seeks`]: keeps the in-memory logs (and the files beside the
/// report) to a few hundred MB.
pub const MAX_SEEKS: u64 = 1_000_000;

impl StoryOptions {
    /// Checks every setting once, before anything runs: `random_seeks` from the diagnosis' minimum
    /// of measured rows ([`DiagnoseConfig::min_rows`]) to [`MAX_SEEKS`], `permutations` as
    /// the diagnosis accepts them (with the default `alpha`), and `settle_preset` a known preset
    /// ([`SettleSpec::preset`]). Any `seed` is valid.
    pub fn check(self) -> Result<CheckedStoryOptions, StoryError> {
        // The diagnosis of the test run needs its cross-validation's minimum of measured rows.
        let min = DiagnoseConfig::default().min_rows() as u64;
        if !(min..=MAX_SEEKS).contains(&self.random_seeks) {
            return Err(StoryError::InvalidConfig {
                field: Field::RandomSeeks,
                message: format!(
                    "{}: give {min} to {MAX_SEEKS} random seeks (the diagnosis of the test run \
                     needs at least {min} measured rows)",
                    self.random_seeks
                ),
            });
        }
        if let Err(e) = diagnose_config(&self) {
            return Err(StoryError::InvalidConfig {
                field: Field::StoryPermutations,
                message: format!("{}: {}", self.permutations, crate::render::message(&e)),
            });
        }
        if let Err(e) = SettleSpec::preset(&self.settle_preset) {
            return Err(StoryError::InvalidConfig {
                field: Field::SettlePreset,
                message: crate::render::message(&e),
            });
        }
        Ok(CheckedStoryOptions(self))
    }

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

checked_settings! {
    /// Settings that passed [`StoryOptions::check`]; read them through `Deref`. `Default` is the
    /// checked default. The story's entry points ([`crate::demo_report`], [`crate::data_report`],
    /// [`compute_demo`], [`compute_data`]) accept only these.
    #[derive(Debug, Clone, PartialEq, Default)]
    pub struct CheckedStoryOptions(StoryOptions);
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
    /// A story setting is out of range ([`StoryOptions::check`]).
    #[error("{field} {message}")]
    InvalidConfig {
        /// The setting.
        field: Field,
        /// The value, what is wrong and what is allowed.
        message: String,
    },
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

/// The four predictors of the demo: (label, term list, training run). position-direction is
/// calibrated as the paper (and 1997 practice) calibrates it, on the two far curves of Table I;
/// the others on the whole calibration run.
pub(crate) const STORY_MODELS: [(&str, &str, &str); 4] = [
    (
        preset::PRESET_LIST[0].0,
        preset::POSITION_DIRECTION,
        "table1",
    ),
    (preset::PRESET_LIST[1].0, preset::CALIBRATION, "calibration"),
    (preset::PRESET_LIST[2].0, preset::DAHL, "calibration"),
    (preset::RICH_DAHL, preset::RICH_DAHL, "calibration"),
];

/// The presets fitted on a user's log: (label, term list).
pub(crate) const DATA_MODELS: [(&str, &str); 4] = [
    (preset::PRESET_LIST[0].0, preset::POSITION_DIRECTION),
    (preset::PRESET_LIST[2].0, preset::DAHL),
    (preset::PRESET_LIST[1].0, preset::CALIBRATION),
    (preset::RICH_DAHL, preset::RICH_DAHL),
];

/// The ladder's terms, added one at a time.
pub(crate) const LADDER_TERMS: [&str; 5] = preset::CALIBRATION_TERMS;

/// The model [`discover`] starts from in a report: position-direction, the industry practice
/// the report's diagnosis also starts from.
pub(crate) const DISCOVER_START: &str = preset::POSITION_DIRECTION;

/// Steps of a demo run as [`Progress`] counts them (the computation's steps and "assembling the
/// report").
pub(crate) const DEMO_STEPS: usize = 12 + STORY_MODELS.len();

/// Steps of a data run as [`Progress`] counts them.
pub(crate) const DATA_STEPS: usize = 5 + DATA_MODELS.len();

/// One fitted and scored predictor.
///
/// `score` is the causal replay's score (each prediction from the rows before it, adaptive
/// terms following the measurements as firmware would). A free-run score beside it (adaptive
/// terms frozen) is the seam for a model scorer that computes both: add it here and to
/// `super::sections::score_table`.
#[derive(Debug, Clone)]
pub struct ScoredModel {
    /// The label shown in tables and figures (a preset name, or "your model (whole log)").
    pub label: String,
    /// What the model was fitted on (a file name, or "the first half").
    pub trained_on: String,
    /// What it was scored on.
    pub scored_on: String,
    /// The fitted model.
    pub model: FittedModel,
    /// Its causal replay over the scored rows.
    pub prediction: Prediction,
    /// The score of that replay's error, in the scored log's bias unit.
    pub score: Score,
}

/// A diagnosis with the feature table and residual it was computed from (the figure draws the
/// raw residuals behind the binned means).
#[derive(Debug, Clone)]
pub struct DiagnosedRun {
    /// What was diagnosed, in words ("`position-direction` on the second half").
    pub name: String,
    /// The diagnosis.
    pub diagnosis: Diagnosis,
    /// The feature table of the diagnosed log.
    pub table: FeatureTable,
    /// The residual diagnosed (measured − predicted, bias unit).
    pub residual: Vec<f64>,
}

/// A computed step, or why it could not be computed on this data (one line, with causes).
pub(crate) type Step<T> = Result<T, String>;

/// Why the paper's robust start value settles when it does, from the numbers of one settle
/// analysis (start values relative to the converged value, µm·samples; times in ms after
/// handoff). A start value ζ settles at the first sample k with L*(k) ≤ ζ ≤ U*(k)
/// ([`crate::control::settle::Bounds::settle_index_of`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaperRobustWhy {
    /// The sample of the first local minimum of U_k, where the paper takes its choice.
    pub k_min: usize,
    /// That sample's time, ms.
    pub k_min_ms: f64,
    /// [L(k_min), U(k_min)]: the per-sample bounds whose middle the paper takes.
    pub bounds_at_k_min: [f64; 2],
    /// The paper's robust start value.
    pub ff: f64,
    /// The optimal start values [L*(k*), U*(k*)], if anything settles.
    pub optimal_interval: Option<[f64; 2]>,
    /// Time of k*, ms.
    pub optimal_ms: Option<f64>,
    /// When the paper's start value enters the running bounds (its settle time), ms.
    pub paper_entry_ms: Option<f64>,
    /// When zero feedforward (ζ = 0) enters the running bounds, ms.
    pub zero_entry_ms: Option<f64>,
}

impl PaperRobustWhy {
    /// The numbers of `r`'s paper robust choice; `None` when U_k has no local minimum.
    pub fn of(r: &SettleReport) -> Option<PaperRobustWhy> {
        let p = r.paper_robust.as_ref()?;
        let b = &r.bounds;
        let ms = |k: usize| crate::control::settle::settle_ms(k, r.ts_s);
        Some(PaperRobustWhy {
            k_min: p.k_min,
            k_min_ms: ms(p.k_min),
            bounds_at_k_min: [
                b.lower().get(p.k_min).copied().unwrap_or(f64::NAN),
                b.upper().get(p.k_min).copied().unwrap_or(f64::NAN),
            ],
            ff: p.ff,
            optimal_interval: r.ff_interval,
            optimal_ms: r.optimal_settle_ms,
            paper_entry_ms: b.settle_index_of(p.ff).map(ms),
            zero_entry_ms: b.settle_index_of(0.0).map(ms),
        })
    }
}

/// The settle part of the demo: the analysis of the preset and, for each predictor, the
/// worst-case settle when the bias is known only to ± its test error std.
#[derive(Debug, Clone)]
pub struct SettleRun {
    /// The settle preset's name.
    pub preset: String,
    /// The analysis (Figs. 15 and 16).
    pub report: SettleReport,
    /// Why the paper's robust choice settles when it does.
    pub paper_why: Option<PaperRobustWhy>,
    /// (model label, its test error std Δb in counts, the worst case with that Δb).
    pub link: Vec<(String, f64, WorstCase)>,
}

/// Everything the demo report shows, computed on the built-in drive.
#[derive(Debug, Clone)]
pub struct DemoRun {
    /// The options it ran with.
    pub opts: StoryOptions,
    /// The simulated Tables I–VII, in order.
    pub tables: Vec<Log>,
    /// The 10 s dwell run (Fig. 4).
    pub dwell: Log,
    /// The calibration run (Tables I–VII then random seeks).
    pub calibration: Log,
    /// The random test run.
    pub random: Log,
    /// The simulator's true decomposition of each measured bias of the random run.
    pub truth: Vec<Truth>,
    /// The four predictors of `STORY_MODELS`, in order, scored on the random run.
    pub scored: Vec<ScoredModel>,
    /// The Dahl model's replay of Table II (Figs. 13/14).
    pub dahl_loop: Step<Prediction>,
    /// The diagnosis of position-direction's residual on the random run.
    pub diagnosis: DiagnosedRun,
    /// The ladder of `LADDER_TERMS`: calibration run → random run.
    pub ladder: Ladder,
    /// [`discover`] from `DISCOVER_START`: calibration run → random run.
    pub discovery: Step<Discovery>,
    /// The settle analysis and the link from prediction error to settle time.
    pub settle: SettleRun,
    /// Files written into the logs folder, `(name, what it holds)`, in the order written.
    pub files: Vec<(String, String)>,
}

/// Everything the report on a user's log shows.
#[derive(Debug, Clone)]
pub struct DataRun {
    /// The options it ran with.
    pub opts: StoryOptions,
    /// The log, its file named relative to the current directory (`relative_to_cwd`).
    pub log: Log,
    /// That name.
    pub file: String,
    /// The first half of the measured rows (training).
    pub train: Log,
    /// The second half (test).
    pub test: Log,
    /// Whether the positions are seeks to tracks (`positions_are_tracks`).
    pub tracks_like: bool,
    /// The presets of `DATA_MODELS` that could be fitted and scored, in order.
    pub scored: Vec<ScoredModel>,
    /// `label: why` of each preset that could not.
    pub failures: Vec<String>,
    /// The user's model scored on the whole log (`None`: no model given).
    pub user: Option<Step<ScoredModel>>,
    /// The diagnosis of the user's model on the whole log, else of the first scored preset on
    /// the second half (`Err`: none possible).
    pub diagnosis: Step<DiagnosedRun>,
    /// The ladder of `LADDER_TERMS`: first half → second half.
    pub ladder: Step<Ladder>,
    /// [`discover`] from `DISCOVER_START`: first half → second half.
    pub discovery: Step<Discovery>,
}

/// Counts [`Progress`] steps for a progress callback.
pub(crate) struct Steps<'a> {
    done: usize,
    total: usize,
    cb: &'a mut dyn FnMut(Progress<'_>),
}

impl<'a> Steps<'a> {
    /// A counter of `total` steps reporting to `cb`.
    pub(crate) fn new(total: usize, cb: &'a mut dyn FnMut(Progress<'_>)) -> Self {
        Steps { done: 0, total, cb }
    }
    /// Reports that `step` starts.
    pub(crate) fn start(&mut self, step: &str) {
        (self.cb)(Progress {
            step,
            done: self.done,
            total: self.total,
        });
        self.done += 1;
    }
    /// Reports that every step is done.
    pub(crate) fn finish(&mut self) {
        (self.cb)(Progress {
            step: "done",
            done: self.total,
            total: self.total,
        });
    }
}

fn fit_named(spec: &str, label: &str, log: &Log) -> Result<FittedModel, StoryError> {
    let spec = ModelSpec::parse(spec)?;
    fit(&spec, log, &CheckedFitOptions::default()).map_err(|e| StoryError::Fit {
        model: label.to_string(),
        file: log.schema.file.clone(),
        source: Box::new(e),
    })
}

/// Fits `terms` on `train`, replays it over `test` and scores the replay in `test`'s units.
fn fit_and_score(
    label: &str,
    terms: &str,
    train: &Log,
    test: &Log,
) -> Result<ScoredModel, StoryError> {
    let model = fit_named(terms, label, train)?;
    let prediction = model.predict_log(test)?;
    let score = score_with_units(
        &prediction.residual,
        &prediction.positions,
        &test.schema.units,
    )?;
    Ok(ScoredModel {
        label: label.to_string(),
        trained_on: train.schema.file.clone(),
        scored_on: test.schema.file.clone(),
        model,
        prediction,
        score,
    })
}

fn diagnose_config(opts: &StoryOptions) -> Result<CheckedDiagnoseConfig, ModelDiagnosisError> {
    let config = DiagnoseConfig {
        permutations: opts.permutations,
        seed: opts.seed,
        ..DiagnoseConfig::default()
    };
    Ok(config.check()?)
}

/// [`discover`] from [`DISCOVER_START`] on `train`, scored on `test`, with the report's
/// diagnosis settings.
fn discover_run(train: &Log, test: &Log, opts: &StoryOptions) -> Step<Discovery> {
    let config = DiscoverConfig {
        diagnose: diagnose_config(opts).map_err(|e| error_chain(&e))?,
        verify: CheckedVerifyConfig::default(),
        max_steps: DiscoverConfig::default().max_steps,
    }
    .check()
    .map_err(|e| error_chain(&e))?;
    let start = ModelSpec::parse(DISCOVER_START).map_err(|e| error_chain(&e))?;
    discover(&start, train, Some(test), &config)
        .map(|(d, _)| d)
        .map_err(|e| error_chain(&e))
}

/// Computes the whole demo on the built-in drive, writing the simulated logs (each with its
/// `_truth.csv`) into `logs_dir` (which must exist). `progress` is called before each step.
pub fn compute_demo(
    logs_dir: &Path,
    opts: &CheckedStoryOptions,
    progress: &mut dyn FnMut(Progress<'_>),
) -> Result<DemoRun, StoryError> {
    let mut steps = Steps::new(DEMO_STEPS - 1, progress);
    let run = demo_run(logs_dir, opts, &mut steps)?;
    steps.finish();
    Ok(run)
}

pub(crate) fn demo_run(
    logs_dir: &Path,
    opts: &StoryOptions,
    steps: &mut Steps<'_>,
) -> Result<DemoRun, StoryError> {
    let seq_opts = SequenceOptions {
        n: Some(opts.random_seeks),
        ..Default::default()
    };
    let mut files = Vec::new();
    let mut simulate_named = |name: &str| -> Result<Log, StoryError> {
        let cfg = SimConfig::new(Drive::paper1997(), name, &seq_opts, opts.seed, &[])?;
        let log_path = logs_dir.join(format!("{name}.csv"));
        let truth_path = logs_dir.join(format!("{name}_truth.csv"));
        simulate_to_files(&cfg, &log_path, Some(&truth_path))?;
        files.push((
            format!("{name}.csv"),
            "simulated measurement log".to_string(),
        ));
        files.push((
            format!("{name}_truth.csv"),
            "each effect's true contribution per row".to_string(),
        ));
        let mut log = Log::read(&log_path, &crate::log::ColumnMap::default())?;
        // Figure titles name the file, not the folder it was written to.
        log.schema.file = format!("{name}.csv");
        Ok(log)
    };

    steps.start("simulating Tables I–VII and the dwell run");
    let mut tables = Vec::new();
    for n in 1..=7 {
        tables.push(simulate_named(&format!("table{n}"))?);
    }
    let dwell = simulate_named("dwell")?;
    steps.start("simulating the calibration run");
    let calibration = simulate_named("calibration")?;
    steps.start("simulating the random test run");
    let random = simulate_named("random")?;
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
        let train_log = if train == "table1" {
            &tables[0]
        } else {
            &calibration
        };
        scored.push(fit_and_score(label, terms, train_log, &random)?);
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
    let diagnosis = DiagnosedRun {
        name: "the position-direction model on random.csv".into(),
        diagnosis,
        table,
        residual: scored[0].prediction.residual.clone(),
    };

    steps.start("building the ladder");
    let terms = ladder_terms(&LADDER_TERMS.join(","))?;
    let ladder = ladder_fit(&calibration, &random, &terms, &CheckedFitOptions::default())?;

    steps.start("discovering terms");
    let discovery = discover_run(&calibration, &random, opts);

    steps.start("settle analysis");
    let spec = SettleSpec::preset(&opts.settle_preset)?;
    let cfg = spec.check()?;
    let report = analyse(&cfg)?;

    steps.start("worst-case settle for each model's error");
    let ctl = Controller::design(&cfg.plant, &cfg.weights)?;
    let handoff_table = HandoffTable::new(&ctl, cfg.scenario.horizon)?;
    let handoff = cfg.scenario.handoff();
    let mut link = Vec::new();
    for s in &scored {
        let wc = worst_case_settle(&handoff_table, &handoff, &cfg.scenario.window, s.score.std)?;
        link.push((s.label.clone(), s.score.std, wc));
    }
    let settle = SettleRun {
        preset: opts.settle_preset.clone(),
        paper_why: PaperRobustWhy::of(&report),
        report,
        link,
    };

    steps.start("replaying Table II with the Dahl model");
    let dahl_loop = scored[2]
        .model
        .predict_log(&tables[1])
        .map_err(|e| e.to_string());

    Ok(DemoRun {
        opts: opts.clone(),
        tables,
        dwell,
        calibration,
        random,
        truth,
        scored,
        dahl_loop,
        diagnosis,
        ladder,
        discovery,
        settle,
        files,
    })
}

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

/// The error and its causes on one line.
pub(crate) fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cur = e.source();
    while let Some(c) = cur {
        s.push_str(": ");
        s.push_str(&c.to_string());
        cur = c.source();
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The computation alone, no HTML: the demo run on 300 seeks holds what the report shows,
    /// and its numbers agree with independent recomputations.
    #[test]
    fn demo_run_computes_every_part_without_html() {
        let dir = tempfile::tempdir().unwrap();
        let run = compute_demo(
            dir.path(),
            &StoryOptions::quick(5).check().unwrap(),
            &mut |_| {},
        )
        .unwrap();
        assert_eq!(run.tables.len(), 7);
        assert_eq!(run.scored.len(), STORY_MODELS.len());
        // Reference: every score is the std of measured − predicted of a fresh replay of the
        // saved model over random.csv (the batch path, recomputed here).
        for s in &run.scored {
            let p = s.model.predict_log(&run.random).unwrap();
            let std = crate::numeric::stats::std_dev(&p.residual).unwrap();
            assert!(
                (s.score.std - std).abs() <= 1e-12 * std.max(1.0),
                "{}",
                s.label
            );
            assert_eq!(s.scored_on, "random.csv");
        }
        assert_eq!(run.scored[0].trained_on, "table1.csv");
        // The ladder's last rung is the calibration model: same terms, same test error std as
        // its own fit and score above (reference: the scored calibration model).
        let last = run.ladder.steps.last().unwrap();
        assert_eq!(last.terms.join(","), preset::CALIBRATION);
        assert!((last.std - run.scored[1].score.std).abs() < 1e-9 * last.std.max(1.0));
        // Discover ran on the demo's data, starting at position-direction.
        let d = run.discovery.as_ref().unwrap();
        assert!(d.start_std.is_finite() && !d.stopped_because.is_empty());
        // Every file listed exists in the logs folder.
        for (f, _) in &run.files {
            assert!(dir.path().join(f).is_file(), "{f}");
        }
        // The link's Δb is each model's test error std.
        for ((l, db, _), s) in run.settle.link.iter().zip(&run.scored) {
            assert_eq!(l, &s.label);
            assert!((db - s.score.std).abs() < 1e-15 * db.max(1.0));
        }
    }

    /// Reference: the simulated responses of the settle analysis. The entry sample of a start
    /// value into the running bounds is its settle time, so the paper's choice and zero
    /// feedforward enter where their simulated responses settle.
    #[test]
    fn paper_robust_why_matches_the_simulated_settle_times() {
        let cfg = SettleSpec::preset("paper1997").unwrap().check().unwrap();
        let r = analyse(&cfg).unwrap();
        let why = PaperRobustWhy::of(&r).unwrap();
        let p = r.paper_robust.as_ref().unwrap();
        assert_eq!(why.paper_entry_ms, p.settle_ms);
        assert_eq!(why.zero_entry_ms, r.zero_ff_settle_ms);
        let [lo, hi] = why.bounds_at_k_min;
        assert!((why.ff - 0.5 * (lo + hi)).abs() < 1e-9 * (hi - lo).abs().max(1.0));
        assert!(why.k_min_ms > 0.0);
    }
}
