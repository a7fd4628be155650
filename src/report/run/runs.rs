//! What a run holds: the scored models, the diagnosis, the settle analysis, and the demo's and a
//! user's log's runs built from them.

use super::options::StoryOptions;
use crate::control::settle::{SettleReport, WorstCase};
use crate::diagnose::{Diagnosis, FeatureTable};
use crate::log::Log;
use crate::model::{FittedModel, Prediction};
use crate::score::Score;
use crate::select::{Discovery, Ladder};
use crate::sim::Truth;

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
    /// [`discover`](crate::select::discover) from `DISCOVER_START`: a second random run
    /// (`DISCOVER_TRAIN`, the seed after the demo's) → the random run.
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
    /// [`discover`](crate::select::discover) from `DISCOVER_START`: first half → second half.
    pub discovery: Step<Discovery>,
}
