//! The H-bridge driver through the physics crate's public API, against an independent
//! event-by-event simulation of what its documentation states: centre-aligned PWM at
//! `f_pwm` (+V for (1 + d)/2 of each period, d = applied / V), a digital PI current loop
//! sampled at `f_sample` with conditional integration and the optional (R + R_sense) i_cmd
//! feed-forward, its command in force from the next sample and latched at the next period
//! start; between the instants the coil is the RL circuit (no back-EMF in the paper's
//! device). Also its saturation flag, its state record (save, restore, refuse a corrupted
//! one) and the bound on the PWM instants of one step.

mod common;

use common::{refusal_of_step, restore, save, within};
use ehsv_physics::{DriverKind, HBridgeParams, Inputs, Params, Physics};

fn bridge_params(feedforward: bool) -> Params {
    let mut p = Params::PAPER;
    p.driver = DriverKind::HBridge;
    p.hbridge.feedforward = feedforward;
    p
}

fn inputs(i_ref: f64, v_supply: f64) -> Inputs {
    Inputs { i_ref, v_supply, ..Inputs::PAPER }
}

/// The digital loop, the PWM and the coil current, simulated instant by instant.
struct Reference {
    p: HBridgeParams,
    r: f64,
    l: f64,
    i: f64,
    t: f64,
    integral: f64,
    pending: f64,
    applied: f64,
    next_sample: i64,
    next_period: i64,
    edges: [f64; 2],
    next_edge: usize,
    high: bool,
}

impl Reference {
    /// At rest with no current at t = 0: nothing applied, in the first period's low part.
    fn at_rest(params: &Params, rail: f64) -> Reference {
        let mut r = Reference {
            p: params.hbridge,
            r: params.coil.resistance + params.coil.r_sense,
            l: params.coil.inductance,
            i: 0.0,
            t: 0.0,
            integral: 0.0,
            pending: 0.0,
            applied: 0.0,
            next_sample: 0,
            next_period: 0,
            edges: [0.0; 2],
            next_edge: 2,
            high: false,
        };
        r.start_period(rail);
        r
    }

    fn voltage(&self, rail: f64) -> f64 {
        if self.high {
            rail
        } else {
            -rail
        }
    }

    fn next_instant(&self) -> f64 {
        let edge = if self.next_edge < 2 { self.edges[self.next_edge] } else { f64::INFINITY };
        let sample = self.next_sample as f64 / self.p.f_sample;
        let period = self.next_period as f64 / self.p.f_pwm;
        edge.min(sample).min(period)
    }

    fn start_period(&mut self, rail: f64) {
        let t0 = self.next_period as f64 / self.p.f_pwm;
        let period = 1.0 / self.p.f_pwm;
        let duty = if rail > 0.0 { (self.applied / rail).clamp(-1.0, 1.0) } else { 0.0 };
        let on = 0.5 * (1.0 + duty) * period;
        self.edges = [t0 + 0.5 * (period - on), t0 + 0.5 * (period + on)];
        self.next_edge = 0;
        self.high = false;
        self.next_period += 1;
    }

    fn sample(&mut self, i_cmd: f64, rail: f64) {
        let p = self.p;
        let e = i_cmd - self.i;
        let feedforward = if p.feedforward { self.r * i_cmd } else { 0.0 };
        let integral = self.integral + p.ki * e / p.f_sample;
        let wanted = p.kp * e + integral + feedforward;
        // Conditional integration: hold while beyond a rail with the error pushing further.
        let pushing_on = (wanted > rail && e > 0.0) || (wanted < -rail && e < 0.0);
        if !pushing_on {
            self.integral = integral;
        }
        self.applied = self.pending;
        self.pending = (p.kp * e + self.integral + feedforward).clamp(-rail, rail);
        self.next_sample += 1;
    }

    /// The RL coil under the present bridge voltage up to `t`.
    fn coast_to(&mut self, t: f64, rail: f64) {
        let steady = self.voltage(rail) / self.r;
        self.i = steady + (self.i - steady) * (-(self.r / self.l) * (t - self.t)).exp();
        self.t = t;
    }

    /// Runs to `t_end` with the command and supply held (instants at the same time: the
    /// ending period's edges, then the sample, then the new period).
    fn run_to(&mut self, t_end: f64, i_cmd: f64, rail: f64) {
        loop {
            let t = self.next_instant();
            if t > t_end * (1.0 + 1e-12) {
                break;
            }
            self.coast_to(t.max(self.t), rail);
            if self.next_edge < 2 && self.edges[self.next_edge] <= t {
                self.high = self.next_edge == 0;
                self.next_edge += 1;
            } else if self.next_sample as f64 / self.p.f_sample <= t {
                self.sample(i_cmd, rail);
            } else {
                self.start_period(rail);
            }
        }
        self.coast_to(t_end, rail);
    }

    fn saturated(&self, rail: f64) -> bool {
        self.applied.abs() >= rail
    }
}

/// A current schedule through both signs and beyond what the 24 V supply can drive through
/// the 1 kOhm coil (24 mA): (until, i_ref).
const SCHEDULE: [(f64, f64); 5] =
    [(2e-3, 5e-3), (4e-3, -8e-3), (6e-3, 30e-3), (8e-3, -30e-3), (10e-3, 3e-3)];

fn command_at(t: f64) -> f64 {
    SCHEDULE.iter().find(|(until, _)| t < *until - 1e-12).map_or(SCHEDULE[4].1, |s| s.1)
}

/// The coil current, the bridge voltage and the saturation flag follow the reference at
/// every communication point, with and without the feed-forward (without it the
/// integrator carries the whole voltage), at steps that are whole PWM periods and steps
/// that end inside them.
#[test]
fn current_loop_and_pwm_follow_the_documented_digital_pi() {
    let rail = 24.0;
    for feedforward in [true, false] {
        for h in [1e-4_f64, 3.7e-5] {
            let p = bridge_params(feedforward);
            let mut physics = Physics::start(&p, &inputs(0.0, rail), 0.0).unwrap();
            let mut reference = Reference::at_rest(&p, rail);
            let n = (10e-3_f64 / h).round() as usize;
            let (mut seen_high, mut seen_saturated, mut seen_free) = (false, false, false);
            for k in 0..n {
                let t = k as f64 * h;
                let i_ref = command_at(t);
                physics.step(&inputs(i_ref, rail), t, h).unwrap();
                reference.run_to(t + h, i_ref, rail);
                let out = physics.outputs();
                let label = format!("feedforward {feedforward}, h {h}, t {:.6}", t + h);
                assert!(
                    (out.i_coil - reference.i).abs() <= 1e-9 * 30e-3,
                    "{label}: i_coil {} vs {}",
                    out.i_coil,
                    reference.i
                );
                assert_eq!(out.u_driver, reference.voltage(rail), "{label}: u_driver");
                assert_eq!(out.driver_saturated, reference.saturated(rail), "{label}");
                seen_high |= reference.high;
                seen_saturated |= reference.saturated(rail);
                seen_free |= !reference.saturated(rail);
            }
            assert!(seen_high && seen_saturated && seen_free, "feedforward {feedforward}, h {h}");
        }
    }
}

/// Offset of the H-bridge record's flag byte in [`Physics::write_bytes`]: driver mode and
/// valve stops (a byte each), then the 9 values of the augmented state.
const HBRIDGE_FLAGS: usize = 2 + 9 * 8;

/// A state saved at any point of a PWM run (bridge high or low, commands in force or
/// pending, at a rail) is restored to the same bytes and continues bit for bit; also with
/// the supply at 0 V, where the duty cycle is 0.
#[test]
fn saved_bridge_states_restore_exactly() {
    let p = bridge_params(true);
    let h = 3.7e-5;
    let mut physics = Physics::start(&p, &inputs(0.0, 24.0), 0.0).unwrap();
    let (mut high, mut low) = (0, 0);
    for k in 0..160 {
        let t = k as f64 * h;
        let i = inputs(command_at(t * 10e-3 / (160.0 * h)), if k < 120 { 24.0 } else { 0.0 });
        physics.step(&i, t, h).unwrap();
        let bytes = save(&physics);
        if physics.outputs().u_driver > 0.0 {
            high += 1;
        } else {
            low += 1;
        }
        let mut restored = restore(&p, &i, &bytes)
            .unwrap_or_else(|e| panic!("step {k} (u_driver {}): {e}", physics.outputs().u_driver));
        assert_eq!(save(&restored), bytes, "step {k}: the restored state saves the same bytes");
        let mut ahead = physics.clone();
        for j in 1..4 {
            let t = (k + j) as f64 * h;
            ahead.step(&i, t, h).unwrap();
            restored.step(&i, t, h).unwrap();
            assert_eq!(ahead.outputs(), restored.outputs(), "step {k} + {j}");
        }
    }
    assert!(high > 10 && low > 10, "{high} states saved high, {low} low");
}

/// A record whose flags, edge index or clock counters are out of range is refused, each on
/// its own.
#[test]
fn corrupted_bridge_records_are_refused() {
    let p = bridge_params(true);
    let i = inputs(5e-3, 24.0);
    let mut physics = Physics::start(&p, &i, 0.0).unwrap();
    physics.step(&i, 0.0, 1e-4).unwrap();
    let bytes = save(&physics);
    assert!((1..=3).contains(&bytes[HBRIDGE_FLAGS]), "flags {}", bytes[HBRIDGE_FLAGS]);
    assert!(bytes[HBRIDGE_FLAGS + 1] <= 2, "edge index {}", bytes[HBRIDGE_FLAGS + 1]);
    for (offset, value) in
        [(HBRIDGE_FLAGS, 4), (HBRIDGE_FLAGS, 255), (HBRIDGE_FLAGS + 1, 3), (HBRIDGE_FLAGS + 1, 200)]
    {
        let mut corrupted = bytes.clone();
        corrupted[offset] = value;
        let result = restore(&p, &i, &corrupted);
        assert!(result.is_err(), "byte {offset} = {value} was accepted");
    }
    // After the two bytes: integral, pending, applied, then the sample and period counters,
    // whole numbers below 9e15.
    for counter in [3, 4] {
        for value in [0.5, 1e16, -2.25] {
            let at = HBRIDGE_FLAGS + 2 + 8 * counter;
            let mut corrupted = bytes.clone();
            corrupted[at..at + 8].copy_from_slice(&f64::to_le_bytes(value));
            let result = restore(&p, &i, &corrupted);
            assert!(result.is_err(), "counter {counter} = {value} was accepted");
        }
    }
}

/// A step that would hold more than 10^7 PWM and sampling instants (at 20 kHz: three
/// instants per period and one per sample, 8e4 per second, so from 125 s on) is refused
/// at once, however long it is; a step below the bound is taken.
#[test]
fn steps_with_too_many_pwm_instants_are_refused_at_once() {
    let p = bridge_params(true);
    let i = inputs(1e-3, 24.0);
    for step in [126.0, 1e6, 1e15, 1e300] {
        let error = refusal_of_step(&p, &i, step);
        assert!(error.contains("PWM/sampling instants"), "{step} s: {error}");
    }
}

/// A step below the bound is taken: at 1 kHz PWM and sampling, 4e3 instants per second,
/// so up to 2500 s; 650 s here (2.6e6 instants; with the supply off and no command,
/// nothing moves and each instant is cheap).
#[test]
fn a_step_below_the_pwm_instant_bound_is_taken() {
    let mut p = bridge_params(true);
    p.hbridge.f_pwm = 1e3;
    p.hbridge.f_sample = 1e3;
    let i = inputs(0.0, 0.0);
    let mut physics = Physics::start(&p, &inputs(0.0, 24.0), 0.0).unwrap();
    let result = within(60.0, move || physics.step(&i, 0.0, 650.0).map(|_| physics.outputs()));
    let out = result.unwrap_or_else(|e| panic!("refused: {e}"));
    assert_eq!(out.i_coil, 0.0);
}
