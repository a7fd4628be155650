//! Generating a family run ([`generate`]): seeks, covariates, base physics, the hidden effects
//! switched on, and the log they make.

use super::physics::{PivotState, Rests, innovation, ou_step};
use super::{COVARIATES, FamilyDrive, HiddenEffect};
use crate::log::{ColumnMap, Log, LogError, LogWriter, fmt_trimmed};
use crate::numeric::rng::SimRng;

/// What to generate: a drive, up to two hidden effects, a seed and a number of seeks.
#[derive(Debug, Clone, PartialEq)]
pub struct FamilyConfig {
    /// The drive.
    pub drive: FamilyDrive,
    /// Hidden effects switched on (at most two, no repeats).
    pub effects: Vec<HiddenEffect>,
    /// Seed of every random process.
    pub seed: u64,
    /// Number of seeks (rows); every row is measured.
    pub n: usize,
}

impl FamilyConfig {
    /// A configuration (checked by [`generate`]).
    pub fn new(drive: FamilyDrive, effects: &[HiddenEffect], seed: u64, n: usize) -> Self {
        Self {
            drive,
            effects: effects.to_vec(),
            seed,
            n,
        }
    }
}

/// A generated run: the log and the true contribution of each part of the bias per row.
#[derive(Debug, Clone, PartialEq)]
pub struct FamilyRun {
    /// The log (`time_s,track,bias,` then [`COVARIATES`]); metadata names the generator, the
    /// member, the seed and the hidden effects.
    pub log: Log,
    /// `(name, one value per row)`, counts: `trend`, `pivot`, `noise`, then one column per
    /// hidden effect that is on (its [`HiddenEffect::name`]); the bias is their sum (before
    /// the log's 4-decimal rounding).
    pub truth: Vec<(String, Vec<f64>)>,
}

impl FamilyRun {
    /// The truth column called `name`.
    pub fn truth(&self, name: &str) -> Option<&[f64]> {
        self.truth
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }
}

/// An error of the family generator.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FamilyError {
    /// A drive parameter is out of range.
    #[error("family drive `{drive}`: {what}")]
    BadParameter {
        /// The drive's name.
        drive: String,
        /// What is wrong.
        what: String,
    },
    /// More than two effects, or one twice.
    #[error("hidden effects {effects:?}: switch on at most two, each once")]
    BadEffects {
        /// The effects asked for.
        effects: Vec<String>,
    },
    /// Too few seeks.
    #[error("{n} seeks: the family generator needs at least 2")]
    TooFewSeeks {
        /// Seeks asked for.
        n: usize,
    },
    /// The generated text did not read back as a log (a bug).
    #[error(transparent)]
    Log(#[from] LogError),
}

/// Time constant of the hidden lag effect, s.
const LAG_S: f64 = 10.0;

/// Substreams of the seed, one per random process.
mod stream {
    pub(super) const SEEKS: u64 = 1;
    pub(super) const NOISE: u64 = 2;
    pub(super) const COVARIATE: u64 = 10; // + index in COVARIATES
    pub(super) const DEFECT: u64 = 30;
}
/// Generates a run: random whole-track seeks in the drive's range with uniform dwell, every row
/// measured. Fails on bad parameters, more than two effects, or fewer than 2 seeks.
pub fn generate(config: &FamilyConfig) -> Result<FamilyRun, FamilyError> {
    check(config)?;
    let d = &config.drive;
    let (n, seed) = (config.n, config.seed);
    let half = d.span / 2.0;
    let seeks = Seeks::draw(d, seed, n);
    let (covs, lagged) = covariates(seed, &seeks);
    let base = BasePhysics::run(d, seed, &seeks.tracks);
    let defect_at = {
        let mut r = SimRng::substream(seed, stream::DEFECT);
        (d.centre + r.range(-0.35, 0.35) * d.span).round()
    };
    let hidden = Hidden {
        drive: d,
        a: d.effect_scale * d.noise.std,
        half,
        tracks: &seeks.tracks,
        dirs: &base.dirs,
        covs: &covs,
        lagged: &lagged,
        defect_at,
    };
    let mut truth = vec![
        ("trend".to_string(), base.trend),
        ("pivot".to_string(), base.pivot),
        ("noise".to_string(), base.noise),
    ];
    for &effect in &config.effects {
        truth.push((effect.name().to_string(), hidden.values(effect)));
    }
    let log = write_log(config, defect_at, &seeks, &covs, &truth)?;
    Ok(FamilyRun { log, truth })
}

/// Checks a configuration: the drive's parameters, at most two effects and none twice, at
/// least 2 seeks.
fn check(config: &FamilyConfig) -> Result<(), FamilyError> {
    config.drive.validate()?;
    let mut seen = Vec::new();
    for e in &config.effects {
        if seen.contains(e) {
            seen.clear();
            break;
        }
        seen.push(*e);
    }
    if config.effects.len() > 2 || seen.len() != config.effects.len() {
        return Err(FamilyError::BadEffects {
            effects: config
                .effects
                .iter()
                .map(|e| e.name().to_string())
                .collect(),
        });
    }
    if config.n < 2 {
        return Err(FamilyError::TooFewSeeks { n: config.n });
    }
    Ok(())
}

/// The seeks of a run: every row's time (s) and track, and the run's duration (s).
struct Seeks {
    times: Vec<f64>,
    tracks: Vec<f64>,
    duration: f64,
}

impl Seeks {
    /// `n` random whole-track seeks in `d`'s range with uniform dwell, from the seed's seek
    /// substream.
    fn draw(d: &FamilyDrive, seed: u64, n: usize) -> Self {
        let half = d.span / 2.0;
        let (lo_track, width) = ((d.centre - half).round(), d.span.round() as u64 + 1);
        let mut rng = SimRng::substream(seed, stream::SEEKS);
        let mut tracks = Vec::with_capacity(n);
        let mut times = Vec::with_capacity(n);
        let mut t = 0.0;
        for k in 0..n {
            if k > 0 {
                t += rng.range(d.dwell_s[0], d.dwell_s[1]);
            }
            times.push(t);
            tracks.push(lo_track + rng.below(width) as f64);
        }
        let duration = t.max(d.dwell_s[1]);
        Self {
            times,
            tracks,
            duration,
        }
    }
}

/// Every covariate column ([`COVARIATES`], one process each on its own substream) at the
/// seeks' times, and the hidden lag effect's lagged state of `temp_lag` per row.
fn covariates(seed: u64, seeks: &Seeks) -> (Vec<Vec<f64>>, Vec<f64>) {
    let n = seeks.times.len();
    let mut covs = vec![vec![0.0; n]; COVARIATES.len()];
    let mut lagged = vec![0.0; n];
    for (c, col) in covs.iter_mut().enumerate() {
        covariate(seed, c, seeks, col, &mut lagged);
    }
    (covs, lagged)
}

/// Fills `col` with covariate `c` of [`COVARIATES`] at the seeks' times; for `temp_lag`, also
/// `lagged` with the lag effect's state.
fn covariate(seed: u64, c: usize, seeks: &Seeks, col: &mut [f64], lagged: &mut [f64]) {
    let (times, duration) = (&seeks.times, seeks.duration);
    let mut r = SimRng::substream(seed, stream::COVARIATE + c as u64);
    let phase = r.range(0.0, std::f64::consts::TAU);
    let mut x: f64 = 0.0;
    let mut prev_t = 0.0;
    // temp_lag: set points held 10–40 s, and the effect's lagged state.
    let mut set = 45.0 + 3.0 * r.normal();
    let mut next_change = r.range(10.0, 40.0);
    let mut lag_state = set;
    for k in 0..times.len() {
        let dt = times[k] - prev_t;
        prev_t = times[k];
        let noise = r.normal();
        col[k] = match COVARIATES[c] {
            "white" => noise,
            "walk" => {
                x += 0.02 * dt.sqrt() * noise;
                x
            }
            "warmup" => 30.0 + 10.0 * (1.0 - (-times[k] / (duration / 5.0)).exp()) + 0.05 * noise,
            "temp_fast" => {
                40.0 + 1.5 * (std::f64::consts::TAU * times[k] / 12.0 + phase).sin() + 0.05 * noise
            }
            "temp_slow" => {
                40.0 + 2.0 * (std::f64::consts::TAU * 1.5 * times[k] / duration + phase).sin()
                    + 0.05 * noise
            }
            "load" => {
                x = if k == 0 {
                    0.5 + 0.2 * noise
                } else {
                    ou_step(x, 0.5, 0.2, 20.0, dt, &mut r)
                };
                x
            }
            "temp_lag" => {
                // Integrate the lag exactly over the piecewise-constant set point.
                let mut at = times[k] - dt;
                while next_change <= times[k] {
                    lag_state = set + (lag_state - set) * (-(next_change - at) / LAG_S).exp();
                    at = next_change;
                    set = 45.0 + 3.0 * r.normal();
                    next_change += r.range(10.0, 40.0);
                }
                lag_state = set + (lag_state - set) * (-(times[k] - at) / LAG_S).exp();
                lagged[k] = lag_state;
                set + 0.05 * noise
            }
            "humid" => {
                x = if k == 0 {
                    50.0 + 5.0 * noise
                } else {
                    ou_step(x, 50.0, 5.0, 5.0, dt, &mut r)
                };
                x
            }
            "supply" => {
                x = if k == 0 {
                    12.0 + 0.3 * noise
                } else {
                    ou_step(x, 12.0, 0.3, 10.0, dt, &mut r)
                };
                x
            }
            _ => 0.0,
        };
    }
}

/// The base physics of a run per row: position trend, pivot force, noise, and the direction
/// of the last move (±1, 0 before any).
struct BasePhysics {
    trend: Vec<f64>,
    pivot: Vec<f64>,
    noise: Vec<f64>,
    dirs: Vec<f64>,
}

impl BasePhysics {
    /// Runs `d`'s trend, pivot and noise (from the seed's noise substream) over `tracks`.
    fn run(d: &FamilyDrive, seed: u64, tracks: &[f64]) -> Self {
        let n = tracks.len();
        let half = d.span / 2.0;
        let mut trend = Vec::with_capacity(n);
        let mut pivot = Vec::with_capacity(n);
        let mut noise = Vec::with_capacity(n);
        let mut dirs = Vec::with_capacity(n);
        let mut state = PivotState::new(&d.pivot);
        let mut nr = SimRng::substream(seed, stream::NOISE);
        let mut e = 0.0;
        let mut dir = 0.0;
        for k in 0..n {
            let dx = if k == 0 {
                0.0
            } else {
                tracks[k] - tracks[k - 1]
            };
            if dx != 0.0 {
                dir = dx.signum();
            }
            dirs.push(dir);
            trend.push(d.trend((tracks[k] - d.centre) / half));
            pivot.push(state.step(dx));
            let w = innovation(d.noise.nu, &mut nr);
            e = if k == 0 {
                d.noise.std * w
            } else {
                d.noise.rho * e + (1.0 - d.noise.rho * d.noise.rho).sqrt() * d.noise.std * w
            };
            noise.push(e);
        }
        Self {
            trend,
            pivot,
            noise,
            dirs,
        }
    }
}

/// What the hidden effects read: the drive, the effect scale `a` (counts), the half span, and
/// the run's tracks, directions, covariates, lagged state and defect track.
struct Hidden<'a> {
    drive: &'a FamilyDrive,
    a: f64,
    half: f64,
    tracks: &'a [f64],
    dirs: &'a [f64],
    covs: &'a [Vec<f64>],
    lagged: &'a [f64],
    defect_at: f64,
}

impl Hidden<'_> {
    /// The covariate column called `name`.
    fn cov(&self, name: &str) -> &[f64] {
        let i = COVARIATES.iter().position(|c| *c == name).unwrap_or(0);
        &self.covs[i]
    }

    /// `effect`'s contribution to the bias per row, counts.
    fn values(&self, effect: HiddenEffect) -> Vec<f64> {
        let (d, a, half, tracks, dirs) = (self.drive, self.a, self.half, self.tracks, self.dirs);
        let n = tracks.len();
        let u = |k: usize| (tracks[k] - d.centre) / half;
        match effect {
            HiddenEffect::FastCovariate => self
                .cov("temp_fast")
                .iter()
                .map(|v| 1.5 * a * (v - 40.0) / 1.5)
                .collect(),
            HiddenEffect::SlowCovariate => self
                .cov("temp_slow")
                .iter()
                .map(|v| 1.5 * a * (v - 40.0) / 2.0)
                .collect(),
            HiddenEffect::Threshold => self
                .cov("load")
                .iter()
                .map(|&v| if v > 0.6 { 2.0 * a } else { 0.0 })
                .collect(),
            HiddenEffect::Lag => self
                .lagged
                .iter()
                .map(|v| 1.2 * a * (v - 45.0) / 3.0)
                .collect(),
            HiddenEffect::CovariateDirection => self
                .cov("humid")
                .iter()
                .zip(dirs)
                .map(|(v, dir)| 1.2 * a * dir * (v - 50.0) / 5.0)
                .collect(),
            HiddenEffect::PositionDirection => (0..n).map(|k| 1.5 * a * dirs[k] * u(k)).collect(),
            HiddenEffect::Defect => tracks
                .iter()
                .map(|x| 5.0 * a * (-0.5 * ((x - self.defect_at) / 1.5).powi(2)).exp())
                .collect(),
            HiddenEffect::SummedMemory => {
                let l = d.span / 12.0;
                let mut rests = Rests::default();
                let mut out = Vec::with_capacity(n);
                for k in 0..n {
                    let source = if k == 0 { tracks[0] } else { tracks[k - 1] };
                    out.push(1.2 * a * rests.sum_after_move(source, tracks[k], l));
                    rests.apply_move(source, tracks[k]);
                }
                out
            }
            HiddenEffect::Interaction => self
                .cov("supply")
                .iter()
                .enumerate()
                .map(|(k, v)| 1.5 * a * (v - 12.0) / 0.3 * u(k))
                .collect(),
            HiddenEffect::Windage => self
                .cov("temp_slow")
                .iter()
                .enumerate()
                .map(|(k, v)| 1.5 * a * (40.0 - v) / 2.0 * u(k))
                .collect(),
            HiddenEffect::SlowThreshold => self
                .cov("temp_slow")
                .iter()
                .map(|v| 3.0 * a * (v - 41.0).max(0.0))
                .collect(),
            HiddenEffect::Preisach => super::physics::preisach(tracks, d.centre, half)
                .into_iter()
                .map(|v| 4.0 * a * v)
                .collect(),
        }
    }
}

/// Writes the run as log text and reads it back, so the run is exactly what a file would
/// hold: metadata naming the generator, member, seed, effects and defect track; every row's
/// bias the sum of the `truth` columns.
fn write_log(
    config: &FamilyConfig,
    defect_at: f64,
    seeks: &Seeks,
    covs: &[Vec<f64>],
    truth: &[(String, Vec<f64>)],
) -> Result<Log, FamilyError> {
    let (d, seed) = (&config.drive, config.seed);
    let effects: Vec<&str> = config.effects.iter().map(|e| e.name()).collect();
    let metadata = vec![
        "generator = biasctl sim::family".to_string(),
        format!("member = {}", d.name),
        format!("seed = {seed}"),
        format!(
            "hidden_effects = {}",
            if effects.is_empty() {
                "none".to_string()
            } else {
                effects.join(" ")
            }
        ),
        format!("defect_track = {}", fmt_trimmed(defect_at, 0)),
        "bias_unit = counts".to_string(),
        "position_unit = tracks".to_string(),
    ];
    let names: Vec<String> = COVARIATES.iter().map(|c| c.to_string()).collect();
    let file = format!("family {} seed {seed}", d.name);
    let io = |source| LogError::Io {
        file: file.clone(),
        source,
    };
    let mut buf = Vec::new();
    {
        let mut w = LogWriter::new(&mut buf, &metadata, &names).map_err(io)?;
        let mut row = vec![0.0; COVARIATES.len()];
        for k in 0..config.n {
            let bias: f64 = truth.iter().map(|(_, v)| v[k]).sum();
            for (slot, col) in row.iter_mut().zip(covs) {
                *slot = col[k];
            }
            w.write_row(seeks.times[k], seeks.tracks[k], Some(bias), &row)
                .map_err(io)?;
        }
    }
    Ok(Log::from_reader(
        &file,
        buf.as_slice(),
        &ColumnMap::default(),
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::history::RestMemory;

    fn log_text(run: &FamilyRun) -> String {
        format!("{:?}", run.log.rows().collect::<Vec<_>>())
    }

    /// Same seed, same log, byte for byte (the rows as written and read back); another seed,
    /// another log; switching an effect on changes only the bias column.
    #[test]
    fn seeded_and_switchable() {
        for drive in FamilyDrive::members() {
            let a = generate(&FamilyConfig::new(drive.clone(), &[], 5, 300)).unwrap();
            let b = generate(&FamilyConfig::new(drive.clone(), &[], 5, 300)).unwrap();
            let c = generate(&FamilyConfig::new(drive.clone(), &[], 6, 300)).unwrap();
            assert_eq!(log_text(&a), log_text(&b));
            assert_ne!(log_text(&a), log_text(&c));
            for e in HiddenEffect::ALL.into_iter().chain(HiddenEffect::APART) {
                let on = generate(&FamilyConfig::new(drive.clone(), &[e], 5, 300)).unwrap();
                let mut differs = 0;
                for (r0, r1) in a.log.rows().zip(on.log.rows()) {
                    assert_eq!((r0.time_s, r0.track), (r1.time_s, r1.track));
                    assert_eq!(r0.covariates, r1.covariates);
                    differs += usize::from(r0.bias != r1.bias);
                }
                assert!(differs > 0, "{} {} changes nothing", drive.name, e.name());
            }
        }
    }

    /// Reference: the truth columns add up to the logged bias (to its 4-decimal rounding), every
    /// covariate (the three no-effect ones included) is logged, and nothing is NaN.
    #[test]
    fn truth_adds_up_and_columns_are_logged() {
        let drive = FamilyDrive::members()[1].clone();
        let effects = [HiddenEffect::SummedMemory, HiddenEffect::Lag];
        let run = generate(&FamilyConfig::new(drive, &effects, 9, 400)).unwrap();
        assert_eq!(run.log.schema.covariates, COVARIATES.to_vec());
        for (k, row) in run.log.rows().enumerate() {
            let sum: f64 = run.truth.iter().map(|(_, v)| v[k]).sum();
            let bias = row.bias.unwrap();
            assert!((bias - sum).abs() <= 5.1e-5, "row {k}: {bias} vs {sum}");
            assert!(row.covariates.iter().all(|v| v.is_finite()));
        }
        assert!(run.truth("summed_memory").is_some() && run.truth("lag").is_some());
        assert!(run.truth("defect").is_none());
    }

    /// Reference: two independent implementations of the uncrossed rest positions — the
    /// generator's full list scan and the seek history's O(1)-amortised stacks
    /// ([`RestMemory`]) — give the same summed memory on every row.
    #[test]
    #[allow(clippy::float_cmp)] // tracks are whole numbers; equality is meant
    fn summed_memory_matches_the_rest_memory() {
        let drive = FamilyDrive::members()[0].clone();
        let l = drive.span / 12.0;
        let scale = 1.2 * drive.effect_scale * drive.noise.std;
        let run = generate(&FamilyConfig::new(
            drive,
            &[HiddenEffect::SummedMemory],
            4,
            800,
        ))
        .unwrap();
        let truth = run.truth("summed_memory").unwrap();
        let mut memory = RestMemory::new();
        let mut source = run.log.row(0).track;
        for (k, row) in run.log.rows().enumerate() {
            let x = row.track;
            // After the move every remembered position but the source is an uncrossed rest.
            memory.apply_move(source, x);
            let sum: f64 = memory
                .positions()
                .filter(|&p| p != source)
                .map(|p| (x - p).signum() * (-(x - p).abs() / l).exp())
                .sum();
            let v = scale * sum;
            assert!((v - truth[k]).abs() < 1e-9, "row {k}: {v} vs {}", truth[k]);
            source = x;
        }
    }

    /// Reference: the closed forms of the two covariate effects checked apart from the
    /// studies, row by row from the logged column (4-decimal rounding): the slow threshold is
    /// 0 at or below 41 °C and `3·a·(T − 41)` above (a = effect scale × noise std), and the
    /// windage `1.5·a·(40 − T)/2·u`.
    #[test]
    fn slow_threshold_and_windage_follow_their_closed_forms() {
        let d = FamilyDrive::members()[2].clone();
        let a = d.effect_scale * d.noise.std;
        let effects = [HiddenEffect::SlowThreshold, HiddenEffect::Windage];
        let run = generate(&FamilyConfig::new(d.clone(), &effects, 12, 600)).unwrap();
        let k_t = run.log.schema.covariate_index("temp_slow").unwrap();
        let (thr, wind) = (
            run.truth("slow_threshold").unwrap(),
            run.truth("windage").unwrap(),
        );
        let (mut below, mut above) = (0, 0);
        for (k, row) in run.log.rows().enumerate() {
            let t = row.covariates.get(k_t).unwrap();
            let u = (row.track - d.centre) / (d.span / 2.0);
            let want = if t > 41.0 { 3.0 * a * (t - 41.0) } else { 0.0 };
            assert!(
                (thr[k] - want).abs() < 2e-3 * a,
                "row {k}: {} vs {want}",
                thr[k]
            );
            assert!(
                (wind[k] - 1.5 * a * (40.0 - t) / 2.0 * u).abs() < 1e-3 * a,
                "row {k}"
            );
            if t > 41.05 {
                above += 1;
            } else if t < 40.95 {
                below += 1;
            }
        }
        assert!(
            below > 100 && above > 100,
            "{below} below, {above} above the set point"
        );
    }

    /// Bad input is a typed error, never a panic.
    #[test]
    fn bad_configurations_are_errors() {
        let d = FamilyDrive::members()[0].clone();
        let two = [HiddenEffect::Lag, HiddenEffect::Lag];
        assert!(matches!(
            generate(&FamilyConfig::new(d.clone(), &two, 1, 100)),
            Err(FamilyError::BadEffects { .. })
        ));
        assert!(matches!(
            generate(&FamilyConfig::new(d.clone(), &[], 1, 1)),
            Err(FamilyError::TooFewSeeks { .. })
        ));
        let mut bad = d;
        bad.noise.nu = Some(2);
        assert!(matches!(
            generate(&FamilyConfig::new(bad, &[], 1, 100)),
            Err(FamilyError::BadParameter { .. })
        ));
    }
}
