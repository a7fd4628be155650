//! The simulated drive: a physical model of every bias effect of the paper (P1–P8), measured the
//! way the paper measures (one-revolution average of a track-following servo's control effort),
//! driven by the paper's calibration sequences.
//!
//! - [`drive`]: the drive description (TOML) and the physics of each effect; see its docs for
//!   the pivot model (Dahl + Maxwell-slip elements with deceleration back-drive).
//! - [`measure`]: the closed-loop servo and the one-revolution average (slow reference loop and
//!   the fast superposition path).
//! - [`sequence`]: Tables I–VII, random, dwell, script.
//!
//! ## Log semantics
//! A row's `time_s` is when its bias is measured. The seek to the row's track starts right after
//! the previous row's measurement, so `dwell_s` (time since the previous row) is the time the head
//! has spent at the target when it is measured (for a zero-length seek the head stays, and its
//! time at the track keeps growing). Unmeasured rows (`bias` empty) are positioning moves.
//!
//! ## Effects and switches
//! Every effect can be switched off by name ([`Effect`]): `position` (P1), `direction` (P2),
//! `overshoot` (P4/P5), `time` (P3), `memory` (P6), `drift` (P7), `scatter` (P8: force scatter
//! and sensor noise), `runout`, `temperature` (the `temp_c` covariate; only in drives that enable
//! it). Each random effect draws from its own [`SimRng::substream`] of the seed, so switching one
//! off leaves the others' draws unchanged.
//!
//! ```
//! use biasctl::{Drive, SequenceOptions, SimConfig, simulate_log};
//! let opts = SequenceOptions { n: Some(500), ..SequenceOptions::default() };
//! let cfg = SimConfig::new(Drive::paper1997(), "random", &opts, 7, &[]).unwrap();
//! let log = simulate_log(&cfg).unwrap();
//! assert_eq!(log.len(), 500);
//! assert_eq!(log.schema.metadata_value("seed"), Some("7"));
//! ```

pub(crate) mod drive;
pub mod family;
pub(crate) mod measure;
pub(crate) mod sequence;

pub use drive::Drive;
pub(crate) use measure::{Handoff, Servo};
pub(crate) use sequence::{ScriptError, Step};

use crate::field::Field;
use crate::history::{History, sign};
use crate::log::{Log, LogError, LogWriter, fmt_fixed};
use crate::numeric::rng::SimRng;
use crate::render::{OutputError, write_atomic};
use std::io::Write;
use std::path::{Path, PathBuf};

/// A switchable effect of the simulated drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Effect {
    /// P1: the smooth position trend.
    Position,
    /// P2: the pivot's main hysteresis element (two curves 2·Fc apart).
    Direction,
    /// P4/P5: the extra pivot elements and the deceleration back-drive.
    Overshoot,
    /// P3: relaxation with time at track.
    Time,
    /// P6: the lubricant ridge at uncrossed rest positions.
    Memory,
    /// P7: slow offset drift.
    Drift,
    /// P8: force scatter per measurement and position-sensor noise.
    Scatter,
    /// Repeatable runout at spindle harmonics.
    Runout,
    /// The ambient-temperature covariate (`temp_c`).
    Temperature,
}

impl Effect {
    /// Every effect, in a fixed order.
    pub const ALL: [Effect; 9] = [
        Effect::Position,
        Effect::Direction,
        Effect::Overshoot,
        Effect::Time,
        Effect::Memory,
        Effect::Drift,
        Effect::Scatter,
        Effect::Runout,
        Effect::Temperature,
    ];

    /// The effect's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Effect::Position => "position",
            Effect::Direction => "direction",
            Effect::Overshoot => "overshoot",
            Effect::Time => "time",
            Effect::Memory => "memory",
            Effect::Drift => "drift",
            Effect::Scatter => "scatter",
            Effect::Runout => "runout",
            Effect::Temperature => "temperature",
        }
    }

    /// The effect called `name`.
    pub fn from_name(name: &str) -> Option<Effect> {
        Effect::ALL.into_iter().find(|e| e.name() == name)
    }

    fn bit(self) -> u16 {
        1 << (self as u16)
    }
}

/// How each measurement is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MeasureMode {
    /// Superposition with precomputed responses (default; same law as `Slow`).
    #[default]
    Fast,
    /// The sample-by-sample reference loop.
    Slow,
}

/// The sequence names `SimConfig::new` accepts.
pub(crate) const SEQUENCE_NAMES: [&str; 11] = [
    "table1",
    "table2",
    "table3",
    "table4",
    "table5",
    "table6",
    "table7",
    "random",
    "dwell",
    "script",
    "calibration",
];

/// The unvalidated sequence options (the CLI's flags); `None` takes the default.
#[derive(Debug, Clone, Default)]
pub struct SequenceOptions {
    /// Random seeks (`random`, and the random tail of `calibration`); default 2000.
    pub n: Option<u64>,
    /// Width of the random range, tracks; default 250.
    pub span: Option<f64>,
    /// Centre of the random range, the tables and the dwell run; default mid-stroke.
    pub center: Option<f64>,
    /// Script file for `script`.
    pub script: Option<PathBuf>,
    /// Shortest random dwell, s; default 0.05.
    pub dwell_min_s: Option<f64>,
    /// Longest random dwell, s; default 0.5.
    pub dwell_max_s: Option<f64>,
    /// Measurement mode; default fast.
    pub measure: MeasureMode,
}

/// Default number of random seeks.
pub const DEFAULT_N: u64 = 2000;
/// Default random span, tracks (the paper's headline range).
pub(crate) const DEFAULT_SPAN: f64 = 250.0;
/// Default random dwell range, s.
pub(crate) const DEFAULT_DWELL_S: (f64, f64) = (0.05, 0.5);

/// The validated random-seek part of a sequence.
#[derive(Debug, Clone, PartialEq)]
pub struct RandomSpec {
    /// Number of seeks (≥ 1).
    pub n: u64,
    /// Centre, track.
    pub center: f64,
    /// Width, tracks (> 0).
    pub span: f64,
    /// Dwell range, s.
    pub dwell_s: (f64, f64),
}

/// A validated sequence.
#[derive(Debug, Clone, PartialEq)]
pub enum Sequence {
    /// Table I..VII (1..=7), centred on `center`.
    Table {
        /// Table number 1..=7.
        number: u8,
        /// Centre track.
        center: f64,
    },
    /// Uniform random seeks.
    Random(RandomSpec),
    /// Time at one track (Fig. 4): 10 s of measurements every 0.1 s.
    Dwell {
        /// The track.
        track: f64,
    },
    /// A user's script.
    Script {
        /// The script's file name.
        file: String,
        /// Its steps.
        steps: Vec<Step>,
    },
    /// Tables I–VII then random seeks: the predictor's training run.
    Calibration(RandomSpec),
}

impl Sequence {
    /// The sequence's name (`table3`, `random`, …).
    pub fn name(&self) -> String {
        match self {
            Sequence::Table { number, .. } => format!("table{number}"),
            Sequence::Random(_) => "random".into(),
            Sequence::Dwell { .. } => "dwell".into(),
            Sequence::Script { .. } => "script".into(),
            Sequence::Calibration(_) => "calibration".into(),
        }
    }
}

/// A bad simulation setting; names the setting.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// A setting's value is not allowed.
    #[error("{field} {value}: {reason}")]
    Invalid {
        /// The setting, e.g. [`Field::Span`].
        field: Field,
        /// Its value.
        value: String,
        /// What it must be.
        reason: String,
    },
    /// The script could not be used.
    #[error("{field}: {0}", field = Field::Script)]
    Script(#[from] ScriptError),
}

/// A complete, validated simulation: drive, sequence, seed, switched-off effects.
#[derive(Debug, Clone)]
pub struct SimConfig {
    /// The drive.
    pub drive: Drive,
    /// The sequence.
    pub sequence: Sequence,
    /// The seed; the whole output is a function of it.
    pub seed: u64,
    /// Measurement mode.
    pub measure: MeasureMode,
    disabled: u16,
}

/// Dwell-run interval and duration, s.
pub(crate) const DWELL_RUN_S: (f64, f64) = (0.1, 10.0);

impl SimConfig {
    /// Validates `sequence` (one of `SEQUENCE_NAMES`) with `opts` against `drive`.
    /// `disabled` lists effect names to switch off. Errors name the setting ([`Field::Sequence`],
    /// [`Field::Disabled`] or a field of [`SequenceOptions`]).
    pub fn new(
        drive: Drive,
        sequence: &str,
        opts: &SequenceOptions,
        seed: u64,
        disabled: &[&str],
    ) -> Result<SimConfig, ConfigError> {
        let bad = |field, value: String, reason: String| ConfigError::Invalid {
            field,
            value,
            reason,
        };
        let mut mask = 0u16;
        for name in disabled {
            let e = Effect::from_name(name.trim()).ok_or_else(|| {
                bad(
                    Field::Disabled,
                    (*name).to_string(),
                    format!(
                        "unknown effect; expected one of {}",
                        Effect::ALL.map(Effect::name).join(", ")
                    ),
                )
            })?;
            mask |= e.bit();
        }
        let max = drive.max_track();
        let center = opts.center.unwrap_or_else(|| drive.mid_track());
        if !center.is_finite() || !(0.0..=max).contains(&center) {
            return Err(bad(
                Field::Center,
                center.to_string(),
                format!("must lie in the stroke 0..={max}"),
            ));
        }
        let random = || -> Result<RandomSpec, ConfigError> {
            let n = opts.n.unwrap_or(DEFAULT_N);
            if n == 0 {
                return Err(bad(Field::SeekCount, "0".into(), "must be ≥ 1".into()));
            }
            let span = opts.span.unwrap_or(DEFAULT_SPAN);
            if !span.is_finite() || span <= 0.0 {
                return Err(bad(Field::Span, span.to_string(), "must be > 0".into()));
            }
            if center - span / 2.0 < 0.0 || center + span / 2.0 > max {
                return Err(bad(
                    Field::Span,
                    span.to_string(),
                    format!(
                        "{} {center} ± span/2 leaves the stroke 0..={max}",
                        Field::Center
                    ),
                ));
            }
            let lo = opts.dwell_min_s.unwrap_or(DEFAULT_DWELL_S.0);
            let hi = opts.dwell_max_s.unwrap_or(DEFAULT_DWELL_S.1);
            if !lo.is_finite() || lo < 0.0 {
                return Err(bad(Field::DwellMin, lo.to_string(), "must be ≥ 0 s".into()));
            }
            if !hi.is_finite() || hi < lo {
                return Err(bad(
                    Field::DwellMax,
                    hi.to_string(),
                    format!("must be ≥ {}", Field::DwellMin),
                ));
            }
            Ok(RandomSpec {
                n,
                center,
                span,
                dwell_s: (lo, hi),
            })
        };
        let far = f64::from(drive.far_tracks);
        let check_tables = |numbers: &[u8]| -> Result<(), ConfigError> {
            for &t in numbers {
                let steps = sequence::table(t, center, far, max).unwrap_or_default();
                if steps.iter().any(|s| !(0.0..=max).contains(&s.target)) {
                    return Err(bad(
                        Field::Center,
                        center.to_string(),
                        format!("table{t} would seek outside the stroke 0..={max}"),
                    ));
                }
            }
            Ok(())
        };
        let seq = match sequence {
            "random" => Sequence::Random(random()?),
            "calibration" => {
                check_tables(&[1, 2, 3, 4, 5, 6, 7])?;
                Sequence::Calibration(random()?)
            }
            "dwell" => Sequence::Dwell { track: center },
            "script" => {
                let path = opts.script.as_ref().ok_or_else(|| {
                    bad(
                        Field::Script,
                        "(missing)".into(),
                        format!("the script sequence needs {} FILE.csv", Field::Script),
                    )
                })?;
                Sequence::Script {
                    file: path.display().to_string(),
                    steps: sequence::read_script(path, max)?,
                }
            }
            name => {
                let number = name
                    .strip_prefix("table")
                    .and_then(|d| d.parse::<u8>().ok())
                    .filter(|n| (1..=7).contains(n))
                    .ok_or_else(|| {
                        bad(
                            Field::Sequence,
                            name.to_string(),
                            format!(
                                "unknown sequence; expected one of {}",
                                SEQUENCE_NAMES.join(", ")
                            ),
                        )
                    })?;
                check_tables(&[number])?;
                Sequence::Table { number, center }
            }
        };
        Ok(SimConfig {
            drive,
            sequence: seq,
            seed,
            measure: opts.measure,
            disabled: mask,
        })
    }

    /// Whether `effect` is simulated (not switched off, and present in the drive).
    pub fn is_on(&self, effect: Effect) -> bool {
        self.disabled & effect.bit() == 0
            && (effect != Effect::Temperature || self.drive.temperature.enabled)
    }

    /// The switched-off effects, in [`Effect::ALL`] order.
    pub fn disabled(&self) -> Vec<Effect> {
        Effect::ALL
            .into_iter()
            .filter(|e| self.disabled & e.bit() != 0)
            .collect()
    }

    /// Switches `effect` off (for tests and library callers).
    pub fn disable(mut self, effect: Effect) -> Self {
        self.disabled |= effect.bit();
        self
    }

    /// The covariate columns the log will have (`temp_c` when the temperature effect is on).
    pub fn covariates(&self) -> Vec<String> {
        if self.is_on(Effect::Temperature) {
            vec!["temp_c".into()]
        } else {
            Vec::new()
        }
    }

    /// The log's metadata lines (`key = value`), among them `bias_unit = counts` and
    /// `position_unit = tracks`.
    pub fn metadata(&self) -> Vec<String> {
        let disabled = self.disabled();
        let mut m = vec![
            format!("generator = biasctl simulate {}", env!("CARGO_PKG_VERSION")),
            format!("seed = {}", self.seed),
            format!("drive = {}", self.drive.name),
            format!("sequence = {}", self.sequence.name()),
            format!(
                "disabled = {}",
                if disabled.is_empty() {
                    "none".to_string()
                } else {
                    disabled
                        .iter()
                        .map(|e| e.name())
                        .collect::<Vec<_>>()
                        .join(",")
                }
            ),
            format!(
                "measure = {}",
                match self.measure {
                    MeasureMode::Fast => "fast",
                    MeasureMode::Slow => "slow",
                }
            ),
            "bias_unit = counts".to_string(),
            "position_unit = tracks".to_string(),
        ];
        match &self.sequence {
            Sequence::Random(r) | Sequence::Calibration(r) => {
                m.push(format!("n = {}", r.n));
                m.push(format!("span = {}", r.span));
                m.push(format!("center = {}", r.center));
                m.push(format!("dwell_s = {} .. {}", r.dwell_s.0, r.dwell_s.1));
            }
            Sequence::Table { center, .. } => m.push(format!("center = {center}")),
            Sequence::Dwell { track } => m.push(format!("center = {track}")),
            Sequence::Script { file, .. } => m.push(format!("script = {file}")),
        }
        m
    }

    fn steps(&self) -> Box<dyn Iterator<Item = Step> + '_> {
        let far = f64::from(self.drive.far_tracks);
        let max = self.drive.max_track();
        let random = |r: &RandomSpec| {
            sequence::RandomSeeks::new(
                r.n,
                r.center,
                r.span,
                r.dwell_s.0,
                r.dwell_s.1,
                SimRng::substream(self.seed, STREAM_SEQUENCE),
            )
        };
        match &self.sequence {
            Sequence::Table { number, center } => Box::new(
                sequence::table(*number, *center, far, max)
                    .unwrap_or_default()
                    .into_iter(),
            ),
            Sequence::Random(r) => Box::new(random(r)),
            Sequence::Dwell { track } => {
                Box::new(sequence::dwell_run(*track, far, DWELL_RUN_S.1, DWELL_RUN_S.0).into_iter())
            }
            Sequence::Script { steps, .. } => Box::new(steps.iter().copied()),
            Sequence::Calibration(r) => Box::new(
                (1..=7)
                    .flat_map(move |t| sequence::table(t, r.center, far, max).unwrap_or_default())
                    .chain(random(r)),
            ),
        }
    }
}

const STREAM_SEQUENCE: u64 = 0;
const STREAM_HANDOFF: u64 = 1;
const STREAM_NOISE: u64 = 2;
const STREAM_SCATTER: u64 = 3;
const STREAM_DRIFT: u64 = 4;
const STREAM_TEMPERATURE: u64 = 5;

/// Each effect's true contribution to one row's bias, counts.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Truth {
    /// P1.
    pub position: f64,
    /// P2: the main pivot element.
    pub direction: f64,
    /// P4/P5: the extra pivot elements.
    pub overshoot: f64,
    /// P3.
    pub time: f64,
    /// P6.
    pub memory: f64,
    /// P7.
    pub drift: f64,
    /// Temperature covariate effect.
    pub temperature: f64,
    /// P8 force scatter of this measurement (0 on unmeasured rows).
    pub scatter: f64,
    /// What the repeatable runout left in the one-revolution average (0 on unmeasured rows).
    pub runout: f64,
    /// The noiseless true bias: position + direction + overshoot + time + memory + drift +
    /// temperature.
    pub total: f64,
}

/// The truth CSV's header.
pub const TRUTH_COLUMNS: &str = "time_s,track,measured,position,direction,overshoot,time,memory,drift,temperature,scatter,runout,bias_true";

/// One simulated row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimRow {
    /// Time of the measurement, s.
    pub time_s: f64,
    /// Target track.
    pub track: f64,
    /// Measured bias, counts (`None` for a positioning move).
    pub bias: Option<f64>,
    /// Logged ambient temperature, °C (when the temperature effect is on).
    pub temp_c: Option<f64>,
    /// The true contributions.
    pub truth: Truth,
}

/// What a simulation produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimSummary {
    /// Rows.
    pub rows: u64,
    /// Measured rows.
    pub measured: u64,
    /// Simulated time at the last row, s.
    pub end_time_s: f64,
}

/// The drive's evolving physical state.
struct DriveState<'a> {
    cfg: &'a SimConfig,
    servo: Servo,
    history: History,
    main: f64,
    extra: Vec<f64>,
    last_dir: i8,
    time: f64,
    arrival: f64,
    drift: f64,
    wander: f64,
    z: Option<f64>,
    rng_handoff: SimRng,
    rng_noise: SimRng,
    rng_scatter: SimRng,
    rng_drift: SimRng,
    rng_temp: SimRng,
}

impl<'a> DriveState<'a> {
    fn new(cfg: &'a SimConfig) -> Self {
        let d = &cfg.drive;
        let harmonics = if cfg.is_on(Effect::Runout) {
            d.runout.harmonics.clone()
        } else {
            Vec::new()
        };
        let mut rng_drift = SimRng::substream(cfg.seed, STREAM_DRIFT);
        let mut rng_temp = SimRng::substream(cfg.seed, STREAM_TEMPERATURE);
        let drift = d.drift.sigma * rng_drift.normal();
        let wander = d.temperature.wander_c * rng_temp.normal();
        DriveState {
            cfg,
            servo: Servo::new(&d.servo, &harmonics),
            history: History::new(),
            main: 1.0,
            extra: vec![1.0; d.overshoot.elements.len()],
            last_dir: 1,
            time: 0.0,
            arrival: 0.0,
            drift,
            wander,
            z: None,
            rng_handoff: SimRng::substream(cfg.seed, STREAM_HANDOFF),
            rng_noise: SimRng::substream(cfg.seed, STREAM_NOISE),
            rng_scatter: SimRng::substream(cfg.seed, STREAM_SCATTER),
            rng_drift,
            rng_temp,
        }
    }

    fn step(&mut self, step: Step) -> SimRow {
        let cfg = self.cfg;
        let d = &cfg.drive;
        let prev_time = self.time;
        self.time += step.dwell_s;
        let f = self.history.step(self.time, step.target);
        let dx = f.seek_length;
        if dx != 0.0 {
            let main_el = drive::Element {
                kind: drive::ElementKind::Dahl,
                fc: d.direction.fc,
                length: d.direction.length,
            };
            self.main = main_el.step(self.main, dx);
            for (w, el) in self.extra.iter_mut().zip(&d.overshoot.elements) {
                *w = el.step(*w, dx);
            }
            if cfg.is_on(Effect::Overshoot) {
                let beta = d.overshoot.backdrive_fraction(dx);
                let s = dx.signum();
                self.main -= beta * (self.main + s);
                for w in &mut self.extra {
                    *w -= beta * (*w + s);
                }
            }
            self.last_dir = sign(dx);
            self.arrival = prev_time;
        }
        // P7 and the temperature wander: exact OU steps over the row's time step.
        let ou = |x: f64, sigma: f64, tau: f64, dt: f64, rng: &mut SimRng| {
            let a = (-dt / tau).exp();
            x * a + sigma * (1.0 - a * a).max(0.0).sqrt() * rng.normal()
        };
        self.drift = ou(
            self.drift,
            d.drift.sigma,
            d.drift.tau_s,
            step.dwell_s,
            &mut self.rng_drift,
        );
        let tp = &d.temperature;
        self.wander = ou(
            self.wander,
            tp.wander_c,
            tp.wander_tau_s,
            step.dwell_s,
            &mut self.rng_temp,
        );
        let on = |e| cfg.is_on(e);
        let gate = |e, v: f64| if on(e) { v } else { 0.0 };
        let temp_c = on(Effect::Temperature).then(|| tp.cycle(self.time) + self.wander);
        let mut t = Truth {
            position: gate(Effect::Position, d.position.at(step.target)),
            direction: gate(Effect::Direction, d.direction.fc * self.main),
            overshoot: gate(
                Effect::Overshoot,
                self.extra
                    .iter()
                    .zip(&d.overshoot.elements)
                    .map(|(w, e)| e.fc * w)
                    .sum(),
            ),
            time: gate(
                Effect::Time,
                d.time.at(self.last_dir, self.time - self.arrival),
            ),
            memory: gate(
                Effect::Memory,
                d.memory.at(f.direction, f.rest_distance_ahead()),
            ),
            drift: gate(Effect::Drift, self.drift),
            temperature: temp_c.map_or(0.0, |tc| tp.coefficient * (tc - tp.t0_c)),
            ..Truth::default()
        };
        t.total =
            t.position + t.direction + t.overshoot + t.time + t.memory + t.drift + t.temperature;
        let bias = if step.measure {
            let scatter_on = on(Effect::Scatter);
            t.scatter = if scatter_on {
                d.scatter.sigma * self.rng_scatter.normal()
            } else {
                0.0
            };
            let pes = if scatter_on { d.scatter.pes_noise } else { 0.0 };
            let h = Handoff {
                e0: d.servo.handoff_std * self.rng_handoff.normal(),
                v0: 0.0,
                z0: self.z.unwrap_or(t.total),
            };
            let theta0 = self.servo.start_angle(self.time, d.servo.spindle_rpm);
            let b = t.total + t.scatter;
            let m = match cfg.measure {
                MeasureMode::Fast => {
                    self.servo
                        .measure_fast(&h, b, theta0, pes, &mut self.rng_noise)
                }
                MeasureMode::Slow => {
                    self.servo
                        .measure_slow(&h, b, theta0, pes, &mut self.rng_noise)
                }
            };
            t.runout = self.servo.runout_parts(theta0).0;
            self.z = Some(m.z_end);
            Some(m.average)
        } else {
            // A positioning move: the loop converges to the true bias while the head waits.
            self.z = Some(t.total);
            None
        };
        SimRow {
            time_s: self.time,
            track: step.target,
            bias,
            temp_c,
            truth: t,
        }
    }
}

/// Runs the simulation, handing each row to `sink` as it is made (memory independent of the
/// number of rows). A sink error stops the run and is returned.
pub fn simulate<E>(
    config: &SimConfig,
    mut sink: impl FnMut(&SimRow) -> Result<(), E>,
) -> Result<SimSummary, E> {
    let mut state = DriveState::new(config);
    let mut summary = SimSummary {
        rows: 0,
        measured: 0,
        end_time_s: 0.0,
    };
    for step in config.steps() {
        let row = state.step(step);
        summary.rows += 1;
        summary.measured += u64::from(row.bias.is_some());
        summary.end_time_s = row.time_s;
        sink(&row)?;
    }
    Ok(summary)
}

/// An error of a simulation run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// An output file could not be written (nothing was left half-written).
    #[error(transparent)]
    Output(#[from] OutputError),
    /// The in-memory log could not be read back (a defect).
    #[error("reading the simulated log back: {0}")]
    Log(#[from] LogError),
    /// Writing to memory failed.
    #[error("writing the simulated log: {0}")]
    Io(#[from] std::io::Error),
}

fn write_log_row<W: Write>(w: &mut LogWriter<W>, row: &SimRow) -> std::io::Result<()> {
    match row.temp_c {
        Some(t) => w.write_row(row.time_s, row.track, row.bias, &[(t * 1e4).round() / 1e4]),
        None => w.write_row(row.time_s, row.track, row.bias, &[]),
    }
}

fn write_truth_row<W: Write>(w: &mut csv::Writer<W>, row: &SimRow) -> std::io::Result<()> {
    let t = &row.truth;
    w.write_record([
        fmt_fixed(row.time_s, 6),
        crate::log::fmt_trimmed(row.track, 6),
        u8::from(row.bias.is_some()).to_string(),
        fmt_fixed(t.position, 4),
        fmt_fixed(t.direction, 4),
        fmt_fixed(t.overshoot, 4),
        fmt_fixed(t.time, 4),
        fmt_fixed(t.memory, 4),
        fmt_fixed(t.drift, 4),
        fmt_fixed(t.temperature, 4),
        fmt_fixed(t.scatter, 4),
        fmt_fixed(t.runout, 4),
        fmt_fixed(t.total, 4),
    ])?;
    Ok(())
}

/// Simulates into an in-memory [`Log`] (quick for a few thousand seeks: for other modules' tests).
pub fn simulate_log(config: &SimConfig) -> Result<Log, SimError> {
    let mut buf = Vec::new();
    {
        let mut w = LogWriter::new(&mut buf, &config.metadata(), &config.covariates())?;
        simulate(config, |row| write_log_row(&mut w, row))?;
        w.into_inner()?;
    }
    Ok(Log::from_reader(
        &format!("simulated {}", config.sequence.name()),
        buf.as_slice(),
        &crate::log::ColumnMap::default(),
    )?)
}

/// Simulates and writes the log to `out` and, if given, each effect's true contribution per row
/// to `truth` (columns [`TRUTH_COLUMNS`]). Both files are written atomically.
pub fn simulate_to_files(
    config: &SimConfig,
    out: &Path,
    truth: Option<&Path>,
) -> Result<SimSummary, SimError> {
    let mut summary = None;
    write_atomic(out, |w| -> Result<(), String> {
        let mut log = LogWriter::new(w, &config.metadata(), &config.covariates())
            .map_err(|e| e.to_string())?;
        let s = match truth {
            None => {
                simulate(config, |row| write_log_row(&mut log, row)).map_err(|e| e.to_string())?
            }
            Some(tp) => {
                let mut inner = None;
                write_atomic(tp, |tw| -> Result<(), std::io::Error> {
                    for m in config.metadata() {
                        writeln!(tw, "# {m}")?;
                    }
                    let mut tw = crate::log::csv_writer(tw);
                    tw.write_record(TRUTH_COLUMNS.split(','))?;
                    inner = Some(simulate(config, |row| {
                        write_log_row(&mut log, row)?;
                        write_truth_row(&mut tw, row)
                    })?);
                    tw.flush()?;
                    Ok(())
                })
                .map_err(|e| e.to_string())?;
                inner.ok_or("no summary")?
            }
        };
        log.into_inner().map_err(|e| e.to_string())?;
        summary = Some(s);
        Ok(())
    })?;
    Ok(summary.unwrap_or(SimSummary {
        rows: 0,
        measured: 0,
        end_time_s: 0.0,
    }))
}
/// Test support: the log of `n` random seeks on the built-in `paper1997` drive with every
/// effect on, simulated with `seed` (the setup unit tests share).
#[cfg(test)]
pub(crate) fn random_log(n: u64, seed: u64) -> crate::log::Log {
    let opts = SequenceOptions {
        n: Some(n),
        ..SequenceOptions::default()
    };
    let cfg = SimConfig::new(Drive::paper1997(), "random", &opts, seed, &[])
        .expect("the built-in drive and the random sequence are valid");
    simulate_log(&cfg).expect("a simulated log")
}

#[cfg(test)]
mod tests;
