//! New values of tunable parameters during a run: the state reached so far is kept, and of
//! what was derived from the parameters only what a changed parameter touches is rebuilt,
//! so the change takes effect from the next communication point. Called when the parameters
//! are set, never from `advance` (building the mode systems is not for a step's hot path).
//!
//! What each group touches:
//! * the driver's PI loop (gains, slew rate), the coil and the valve: the mode systems of
//!   driver, coil and valve (their matrices, guards and spectral radii), the active system
//!   and everything the integrator derived from them (for the exact one its propagators and
//!   slew exits). `V_drop` is not among them: it moves the rail, a held input that the next
//!   step takes in;
//! * the cylinder, load and fluid: the cylinder's coefficients, and its rest cache;
//! * the outer loops and the H-bridge's loop: their coefficients only (plain values; their
//!   states carry on).
//!
//! In every case the driver mode and valve stops are chosen again for the state reached
//! (new gains or limits can make a rail or a slew the consistent mode), the rest cache of
//! the step goes, and no equilibrium is computed but in the one case where a start's
//! equilibrium decides the result (see [`start_keeps_the_free_linear_system`]).

use crate::actuator::{consistent_state, mode_systems, rest_state, Actuator};
use crate::components::coefficients::Coefficients;
use crate::components::driver::Mode;
use crate::components::driver::MODES;
use crate::components::outer_loop::OuterLoop;
use crate::components::valve;
use crate::held_inputs::HeldInputs;
use crate::integrators::chosen::ChosenIntegrator;
use crate::integrators::exact::driven_cylinder::DrivenCylinder;
use crate::integrators::seam::Integrator;
use crate::numerics::mode_systems::ModeSystem;
use crate::params::ControlMode;
use crate::params::Inputs;
use crate::params::Params;
use crate::physics::Physics;

impl Physics {
    /// The same state under `params`, which differ from the current ones in tunable
    /// parameters only (gains, limits, friction, load, leakage): the structure (driver,
    /// control mode, sampling clocks) and the hardware are the caller's to keep. `inputs`
    /// and `time` are those of a start at this point: they decide nothing but which system
    /// is active in one case (`start_keeps_the_free_linear_system`). On error nothing
    /// changes.
    pub fn retune(&mut self, params: &Params, inputs: &Inputs, time: f64) -> Result<(), String> {
        let next = Coefficients::new(params)?;
        let a = &self.actuator;
        let systems_touched = next.mode_system_key() != a.params.mode_system_key();
        let systems = systems_touched.then(|| mode_systems(&next)).transpose()?;
        next.cylinder.check_supply(inputs.p_supply)?;
        // Nothing fails from here on.
        let cylinder_touched = next.cylinder != a.params.cylinder;
        let a = &mut self.actuator;
        a.params = next;
        if let Some(systems) = systems {
            a.systems = systems;
        }
        if cylinder_touched {
            // Its rest cache holds for the old coefficients.
            a.cylinder = DrivenCylinder::new(a.cylinder.state, a.cylinder.memory);
        }
        settle_after_retune(a, inputs, time);
        if self.integrator.method() == params.solver_method {
            self.integrator.retuned(a, systems_touched);
        } else {
            // Another integrator: the old one's work stays counted.
            self.integrator.count_work(&mut a.work);
            self.integrator = ChosenIntegrator::new(params, a);
        }
        // The same step again may no longer change nothing, nor the rod's force be the same.
        self.resting = None;
        self.step_end = None;
        Ok(())
    }
}

/// Chooses the driver mode and valve stops again for the state reached under the new
/// coefficients, and the active system for them.
fn settle_after_retune(a: &mut Actuator, inputs: &Inputs, time: f64) {
    let mut z = a.z;
    let (mode, stops) = consistent_state(&a.params, &a.systems, &a.hbridge, &mut z);
    let linear = a.systems[Mode::Linear.index()];
    a.active = if !valve::has_stops(&a.params) {
        // Not read without stops; what a start leaves.
        linear
    } else if (mode, stops) == (Mode::Linear, valve::Stops::default())
        && start_keeps_the_free_linear_system(&a.params, &a.systems, inputs, time)
    {
        linear
    } else {
        a.systems[mode.index()].with_stops(&a.params, stops)
    };
    (a.mode, a.stops, a.z) = (mode, stops, z);
}

/// Whether a start with these coefficients at `inputs` and `time` would leave the linear
/// mode's own system active with the valve free of its stops. A start begins in (linear
/// mode, no stop) with that system, and settling onto its equilibrium builds the system
/// with the stops' guards only if the mode or the stops change; so when its equilibrium is
/// (linear, free), the travel stops have no guards until the next change of mode or stops
/// (a restored state has them). A retune leaves the active system as that start, settled
/// onto the state reached, would leave it (the missing guards are a defect of the start,
/// kept so that results stay bit for bit until it is fixed knowingly), and computes that
/// start's equilibrium only here, where it decides.
fn start_keeps_the_free_linear_system(
    c: &Coefficients,
    systems: &[ModeSystem; MODES.len()],
    inputs: &Inputs,
    time: f64,
) -> bool {
    let held = HeldInputs::new(c, inputs);
    let i_cmd = if c.loops.mode == ControlMode::Current {
        held.i_ref
    } else {
        OuterLoop::at_start(&c.loops, held.reference, time).command
    };
    let (mut z, hbridge) = rest_state(c, i_cmd, held.rail, time);
    let hbridge = hbridge.unwrap_or_default();
    consistent_state(c, systems, &hbridge, &mut z) == (Mode::Linear, valve::Stops::default())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::actuator::dynamics;
    use crate::components::driver;
    use crate::params::{DriverKind, Outputs, SolverMethod};
    use std::f64::consts::PI;

    /// A named change of parameters.
    type Change = (&'static str, fn(&mut Params));
    /// A named input signal, its control mode and the steps taken before the retune.
    type Signal<'a> = (&'static str, &'a dyn Fn(f64) -> Inputs, ControlMode, usize);

    /// The reference a retune must match bit for bit: a whole start under the new
    /// parameters, with the state reached carried over and settled.
    fn restarted(old: &Physics, params: &Params, inputs: &Inputs, time: f64) -> Physics {
        let mut next = Physics::start(params, inputs, time).unwrap();
        let (a, o) = (&mut next.actuator, &old.actuator);
        a.hbridge = o.hbridge;
        a.outer = o.outer;
        a.cylinder = DrivenCylinder::new(o.cylinder.state, o.cylinder.memory);
        a.p_supply = o.p_supply;
        let mut z = o.z;
        a.settle(&mut z);
        a.z = z;
        next
    }

    fn bytes(physics: &Physics) -> Vec<u8> {
        let mut out = Vec::new();
        physics.write_bytes(&mut out);
        out
    }

    /// Steps `physics` through `inputs(t)` from `t0`, `steps` steps of 1e-4 s, and returns the
    /// state bytes and outputs after each.
    fn run(
        physics: &mut Physics,
        inputs: &dyn Fn(f64) -> Inputs,
        t0: f64,
        steps: usize,
    ) -> Vec<(Vec<u8>, Outputs)> {
        (0..steps)
            .map(|k| {
                let t = t0 + k as f64 * 1e-4;
                let _ = physics.step(&inputs(t), t, 1e-4);
                (bytes(physics), physics.outputs())
            })
            .collect()
    }

    /// A retune continues exactly as a start under the new parameters with the state carried
    /// over would, for a change of each group, with and without travel stops, from a state in
    /// the linear mode (a slow sine) and from one in a slew (a square wave), on both methods
    /// (their caches of propagators built for the old systems forgotten).
    #[test]
    fn a_retune_continues_as_a_restart_would() {
        let changes: [Change; 9] = [
            ("nothing", |_| {}),
            ("opamp.Kp", |p| p.opamp.kp *= 0.7),
            ("opamp.slew_rate", |p| p.opamp.slew_rate *= 0.3),
            ("V_drop", |p| p.opamp_v_drop = 5.0),
            ("cylinder", |p| {
                p.cylinder.mass = 20.0;
                p.cylinder.f_coulomb = 60.0;
            }),
            ("loop", |p| p.outer_loop.position = [2.0, 10.0, 0.0]),
            ("coil", |p| p.coil.r_sense = 20.0),
            ("valve stops", |p| p.valve.x_spool_max = 2.5e-4),
            ("valve K1", |p| p.valve.k1 = 3.2),
        ];
        let slow_sine =
            |t: f64| Inputs { i_ref: 0.012 * (2.0 * PI * 8.0 * t).sin(), ..Inputs::PAPER };
        let square = |amplitude: f64| {
            move |t: f64| Inputs {
                i_ref: amplitude * if (80.0 * t).floor() as i64 % 2 == 0 { 1.0 } else { -1.0 },
                ..Inputs::PAPER
            }
        };
        let square_8ma = square(0.008);
        let position =
            |t: f64| Inputs { x_ref: 0.01 * (2.0 * PI * 5.0 * t).sin(), ..Inputs::PAPER };
        let constant = |t: f64| Inputs { i_ref: 0.0046 + 0.0 * t, ..Inputs::PAPER };
        // (name, inputs, control mode, steps before the retune). At a constant 4.6 mA a
        // larger K1 moves the spool, in the linear mode, from 1.75e-4 m to 1.98e-4 m, the
        // flapper deflecting by 3.8e-6 m on the way: past a 2e-6 m stop, which the rule of
        // `start_keeps_the_free_linear_system` leaves without its guards.
        let signals: [Signal; 4] = [
            ("slow sine", &slow_sine, ControlMode::Current, 37),
            ("8 mA square", &square_8ma, ControlMode::Current, 37),
            ("4.6 mA", &constant, ControlMode::Current, 37),
            ("position", &position, ControlMode::Position, 37),
        ];
        // Both methods; travel stops of flapper and spool (m): none, loose, a tight flapper.
        for method in SolverMethod::ALL {
            for (flapper, spool) in [(0.0, 0.0), (2e-5, 2e-4), (2e-6, 2e-4)] {
                for (signal, inputs, mode, before) in signals {
                    let mut p =
                        Params { control_mode: mode, solver_method: method, ..Params::PAPER };
                    (p.valve.x_flapper_max, p.valve.x_spool_max) = (flapper, spool);
                    for (name, change) in changes {
                        let case = format!(
                            "{method:?}: {name} retuned, {signal}, stops {flapper:e} {spool:e}"
                        );
                        retune_matches_restart(&p, change, (inputs, before), &case);
                    }
                }
            }
        }
    }

    /// Runs `p` through `inputs` for `before` steps, retunes to `change`d parameters, and
    /// checks the state and 400 steps after it against [`restarted`]'s, bit for bit.
    fn retune_matches_restart(
        p: &Params,
        change: fn(&mut Params),
        (inputs, before): (&dyn Fn(f64) -> Inputs, usize),
        case: &str,
    ) {
        let mut physics = Physics::start(p, &inputs(0.0), 0.0).unwrap();
        run(&mut physics, inputs, 0.0, before);
        let mut q = *p;
        change(&mut q);
        let t = before as f64 * 1e-4;
        let mut reference = restarted(&physics, &q, &inputs(t), t);
        physics.retune(&q, &inputs(t), t).unwrap();
        assert_eq!(bytes(&physics), bytes(&reference), "{case}: at the retune");
        let after = run(&mut physics, inputs, t, 400);
        let expected = run(&mut reference, inputs, t, 400);
        for (k, (got, want)) in after.iter().zip(&expected).enumerate() {
            assert!(got == want, "{case}: step {k} after the retune differs");
        }
    }

    /// A retune of the cylinder, the load or the loops keeps the mode systems and the
    /// propagators built for them: the steps after it compute no matrix exponential; a new
    /// gain of the driver rebuilds them. The work counters carry on across retunes.
    #[test]
    fn only_a_change_the_mode_systems_read_rebuilds_them() {
        let sine = |t: f64| Inputs {
            i_ref: 5e-3 * (2.0 * PI * 100.0 * t).sin(),
            f_ext: 200.0,
            ..Inputs::PAPER
        };
        let mut p = Params::PAPER;
        let mut physics = Physics::start(&p, &sine(0.0), 0.0).unwrap();
        run(&mut physics, &sine, 0.0, 100);
        let changes: [(Change, bool); 5] = [
            (("mass", |p| p.cylinder.mass *= 2.0), false),
            (("friction", |p| p.cylinder.f_coulomb *= 2.0), false),
            (("position loop", |p| p.outer_loop.position[0] *= 2.0), false),
            (("V_drop", |p| p.opamp_v_drop = 2.0), false),
            (("opamp.Kp", |p| p.opamp.kp *= 0.8), true),
        ];
        let mut t = 100e-4;
        for ((name, change), rebuilds) in changes {
            let before = physics.work();
            change(&mut p);
            physics.retune(&p, &sine(t), t).unwrap();
            run(&mut physics, &sine, t, 50);
            t += 50e-4;
            let after = physics.work();
            assert!(after.cylinder_calls > before.cylinder_calls, "{name}: work counted on");
            let built = after.exponentials - before.exponentials;
            assert_eq!(built > 0, rebuilds, "{name}: {built} exponentials after the retune");
        }
    }

    /// Moves a parameter: scaled, or from zero to a small value.
    fn bump(x: &mut f64) {
        *x = if *x == 0.0 { 1e-3 } else { *x * 1.25 };
    }

    /// Every numeric parameter, each with a function that moves it.
    macro_rules! every_parameter {
        ($($($field:ident).+),* $(,)?) => {
            [$((stringify!($($field).+), (|p: &mut Params| bump(&mut p.$($field).+)) as fn(&mut Params))),*]
        };
    }

    /// A retune rebuilds the mode systems when, and only when, a parameter they read changed
    /// (the valve's are all in the key: its port data too, which no system reads; the valve
    /// is not tunable).
    #[test]
    fn the_mode_system_key_holds_what_the_systems_read() {
        let parameters = every_parameter![
            opamp.kp,
            opamp.ki,
            opamp.slew_rate,
            opamp_v_drop,
            industrial.kp,
            industrial.ki,
            industrial.slew_rate,
            hbridge.f_pwm,
            hbridge.f_sample,
            hbridge.kp,
            hbridge.ki,
            coil.inductance,
            coil.resistance,
            coil.r_sense,
            coil.k_backemf,
            valve.k1,
            valve.kf,
            valve.kw,
            valve.k2,
            valve.k3,
            valve.spool_area,
            valve.zeta,
            valve.f_n,
            valve.x_flapper_max,
            valve.x_spool_max,
            valve.dp_rated,
            valve.dp_laminar,
            cylinder.bore,
            cylinder.rod,
            cylinder.stroke,
            cylinder.mass,
            cylinder.beta,
            cylinder.v_dead,
            cylinder.b_viscous,
            cylinder.f_coulomb,
            cylinder.f_static,
            cylinder.v_stribeck,
            cylinder.v_friction_smooth,
            cylinder.k_endstop,
            cylinder.c_endstop,
            cylinder.c_leak,
            cylinder.c_leak_external,
            cylinder.p_tank,
            cylinder.p_cavitation,
            cylinder.dp_cavitation_band,
            cylinder.relief_p_crack,
            cylinder.relief_dp_override,
            cylinder.relief_q_rated,
            outer_loop.f_sample,
            outer_loop.i_max,
            solver_rtol,
            solver_h_internal,
        ];
        let gains: [Change; 6] = [
            ("outer_loop.flow[0]", |p| bump(&mut p.outer_loop.flow[0])),
            ("outer_loop.flow[1]", |p| bump(&mut p.outer_loop.flow[1])),
            ("outer_loop.flow[2]", |p| bump(&mut p.outer_loop.flow[2])),
            ("outer_loop.position[0]", |p| bump(&mut p.outer_loop.position[0])),
            ("outer_loop.position[1]", |p| bump(&mut p.outer_loop.position[1])),
            ("outer_loop.position[2]", |p| bump(&mut p.outer_loop.position[2])),
        ];
        let flags: [Change; 3] = [
            ("hbridge.feedforward", |p| p.hbridge.feedforward = !p.hbridge.feedforward),
            ("control_mode", |p| p.control_mode = ControlMode::Flow),
            ("driver", |p| p.driver = DriverKind::Voltage),
        ];
        for driver in [DriverKind::OpampPi, DriverKind::Industrial, DriverKind::HBridge] {
            let mut base = Params { driver, ..Params::PAPER };
            (base.valve.x_flapper_max, base.valve.x_spool_max) = (2e-5, 2e-4);
            let c0 = Coefficients::new(&base).unwrap();
            for (name, change) in parameters.iter().chain(&gains).chain(&flags) {
                let mut q = base;
                change(&mut q);
                let Ok(c1) = Coefficients::new(&q) else { continue };
                let systems_differ = MODES.iter().any(|&m| {
                    let (a0, a1) = (dynamics(&c0, m), dynamics(&c1, m));
                    a0 != a1 || driver::mode_guards(&c0, m, &a0) != driver::mode_guards(&c1, m, &a1)
                });
                let keys_differ = c0.mode_system_key() != c1.mode_system_key();
                if systems_differ {
                    assert!(keys_differ, "{driver:?}, {name}: the systems change, not their key");
                } else if !name.starts_with("valve.") {
                    assert!(!keys_differ, "{driver:?}, {name}: the key changes, not the systems");
                }
            }
        }
    }
}
