//! The simulated drive's evolving physical state, stepped once per row, and the substreams of
//! the seed its random effects draw from.

use super::drive;
use super::{Effect, Handoff, MeasureMode, Servo, SimConfig, SimRow, Step, Truth};
use crate::history::{History, sign};
use crate::numeric::rng::SimRng;

pub(super) const STREAM_SEQUENCE: u64 = 0;
pub(super) const STREAM_HANDOFF: u64 = 1;
pub(super) const STREAM_NOISE: u64 = 2;
pub(super) const STREAM_SCATTER: u64 = 3;
pub(super) const STREAM_DRIFT: u64 = 4;
pub(super) const STREAM_TEMPERATURE: u64 = 5;

/// The drive's evolving physical state.
pub(super) struct DriveState<'a> {
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
    pub(super) fn new(cfg: &'a SimConfig) -> Self {
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

    pub(super) fn step(&mut self, step: Step) -> SimRow {
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
