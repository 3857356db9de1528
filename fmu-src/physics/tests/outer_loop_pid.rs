//! The outer flow and position loops through the physics crate's public API, against an
//! independent implementation of what their documentation states: a digital PID sampled
//! at `f_sample` on an absolute clock, `i = clamp(ff r + Kp e + Ki sum(e)/f_s + Kd (e -
//! e_prev) f_s, +-i_max)` with conditional integration (the integrator holds while the
//! command is limited and the error pushes further), the flow loop's feed-forward
//! `1 / (K3 K1 / Kw)`. With the ideal current source the coil current is the command, so
//! every sample's command is seen at the communication point it falls on. Also the loop's
//! state record and the bound on the samples of one step.

mod common;

use common::{refusal_of_step, save};
use ehsv_physics::bytes::ByteReader;
use ehsv_physics::{ControlMode, DriverKind, Inputs, Params, Physics};

/// The PID of the documentation.
struct Pid {
    gains: [f64; 3],
    f_sample: f64,
    i_max: f64,
    feedforward: f64,
    integral: f64,
    previous_error: f64,
    command: f64,
}

impl Pid {
    fn new(p: &Params, reference: f64) -> Pid {
        let (gains, feedforward) = match p.control_mode {
            ControlMode::Flow => (p.outer_loop.flow, 1.0 / (p.valve.k3 * p.valve.k1 / p.valve.kw)),
            _ => (p.outer_loop.position, 0.0),
        };
        let i_max = p.outer_loop.i_max;
        Pid {
            gains,
            f_sample: p.outer_loop.f_sample,
            i_max,
            feedforward,
            integral: 0.0,
            previous_error: 0.0,
            command: (feedforward * reference).clamp(-i_max, i_max),
        }
    }

    fn sample(&mut self, reference: f64, measured: f64) {
        let [kp, ki, kd] = self.gains;
        let e = reference - measured;
        let proportional_and_derivative =
            self.feedforward * reference + kp * e + kd * (e - self.previous_error) * self.f_sample;
        let integral = self.integral + ki * e / self.f_sample;
        let wanted = proportional_and_derivative + integral;
        let held = (wanted > self.i_max && e > 0.0) || (wanted < -self.i_max && e < 0.0);
        if !held {
            self.integral = integral;
        }
        self.command = (proportional_and_derivative + self.integral).clamp(-self.i_max, self.i_max);
        self.previous_error = e;
    }
}

fn loop_params(mode: ControlMode) -> Params {
    let mut p = Params::PAPER;
    p.driver = DriverKind::IdealCurrent;
    p.control_mode = mode;
    // Gains that drive the command into its limit after each reference step, and an
    // integrator and a derivative that matter.
    p.outer_loop.position = [2.0, 40.0, 2e-4];
    p.outer_loop.flow = [60.0, 4e4, 2e-3];
    p
}

/// Runs a loop over a reference that steps both ways, one sample per communication step,
/// and compares the coil current (the command) with the reference PID at every sample;
/// returns how many commands were at the limit.
fn follow(mode: ControlMode, references: [f64; 4]) -> usize {
    let p = loop_params(mode);
    let f_s = p.outer_loop.f_sample;
    let inputs = |r: f64| match mode {
        ControlMode::Flow => Inputs { q_ref: r, ..Inputs::PAPER },
        _ => Inputs { x_ref: r, ..Inputs::PAPER },
    };
    let measured = |physics: &Physics| {
        let out = physics.outputs();
        match mode {
            ControlMode::Flow => out.q_valve,
            _ => out.x_piston,
        }
    };
    let mut physics = Physics::start(&p, &inputs(references[0]), 0.0).unwrap();
    let mut pid = Pid::new(&p, references[0]);
    assert_eq!(physics.outputs().i_coil, pid.command, "{mode:?} at the start");
    let per_reference = 300;
    let mut limited = 0;
    for k in 0..4 * per_reference {
        let reference = references[k / per_reference];
        let (t, t_next) = (k as f64 / f_s, (k + 1) as f64 / f_s);
        if k == 0 {
            // The first sample is at t = 0, on the start state.
            pid.sample(reference, measured(&physics));
        }
        physics.step(&inputs(reference), t, t_next - t).unwrap();
        pid.sample(reference, measured(&physics));
        let i_coil = physics.outputs().i_coil;
        assert!(
            (i_coil - pid.command).abs() <= 1e-12 * p.outer_loop.i_max,
            "{mode:?}, sample {}: command {i_coil} vs {}",
            k + 1,
            pid.command
        );
        limited += (pid.command.abs() == p.outer_loop.i_max) as usize;
    }
    limited
}

#[test]
fn position_loop_is_the_documented_pid() {
    let limited = follow(ControlMode::Position, [0.0, 8e-3, -6e-3, 1e-3]);
    assert!(limited > 20, "the command reached its limit {limited} times");
}

#[test]
fn flow_loop_is_the_documented_pid_with_its_feedforward() {
    let limited = follow(ControlMode::Flow, [0.0, 2e-4, -3e-4, 5e-5]);
    assert!(limited > 20, "the command reached its limit {limited} times");
}

/// Offset of the outer loop's record in [`Physics::write_bytes`]: driver mode and valve
/// stops (a byte each), the 9 values of the augmented state, the H-bridge record (two
/// bytes and 7 values).
const OUTER_ACTIVE: usize = 2 + 9 * 8 + 2 + 7 * 8;

/// A state saved while a loop runs restores to the same bytes and continues bit for bit;
/// a record whose activity flag is neither 0 nor 1 is refused.
#[test]
fn loop_states_restore_exactly_and_corrupted_ones_are_refused() {
    for mode in [ControlMode::Flow, ControlMode::Position] {
        let mut p = loop_params(mode);
        p.driver = DriverKind::OpampPi;
        let i = Inputs { q_ref: 1e-4, x_ref: 4e-3, ..Inputs::PAPER };
        let mut physics = Physics::start(&p, &Inputs::PAPER, 0.0).unwrap();
        let h = 1e-4;
        for k in 0..20 {
            physics.step(&i, k as f64 * h, h).unwrap();
        }
        let bytes = save(&physics);
        assert_eq!(bytes[OUTER_ACTIVE], 1, "{mode:?}: the loop's record is active");
        let mut restored = Physics::read_bytes(&p, &i, &mut ByteReader::new(&bytes))
            .unwrap_or_else(|e| panic!("{mode:?}: {e}"));
        assert_eq!(save(&restored), bytes, "{mode:?}");
        for k in 20..40 {
            physics.step(&i, k as f64 * h, h).unwrap();
            restored.step(&i, k as f64 * h, h).unwrap();
            assert_eq!(physics.outputs(), restored.outputs(), "{mode:?} step {k}");
        }
        for flag in [2, 3, 255] {
            let mut corrupted = bytes.clone();
            corrupted[OUTER_ACTIVE] = flag;
            let result = Physics::read_bytes(&p, &i, &mut ByteReader::new(&corrupted));
            assert!(result.is_err(), "{mode:?}: activity flag {flag} accepted");
        }
    }
}

/// A step holding more than 10^7 samples of the loop (20 kHz: from 500 s on) is refused at
/// once.
#[test]
fn steps_with_too_many_loop_samples_are_refused_at_once() {
    let p = loop_params(ControlMode::Position);
    let i = Inputs { x_ref: 1e-3, ..Inputs::PAPER };
    for step in [501.0, 1e9] {
        let error = refusal_of_step(&p, &i, step);
        assert!(error.contains("PWM/sampling instants"), "{step} s: {error}");
    }
}
