//! A simulation's settings: the switchable effects, the sequence options and their validation
//! into a [`SimConfig`].

use super::state::STREAM_SEQUENCE;
use super::{Drive, ScriptError, Step, sequence};
use crate::field::Field;
use crate::numeric::rng::SimRng;
use std::path::PathBuf;

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
                        "unknown effect{}; expected one of {}",
                        crate::io::words::did_you_mean(name.trim(), Effect::ALL.map(Effect::name)),
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
                                "unknown sequence{}; expected one of {}",
                                crate::io::words::did_you_mean(name, SEQUENCE_NAMES),
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

    pub(super) fn steps(&self) -> Box<dyn Iterator<Item = Step> + '_> {
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
