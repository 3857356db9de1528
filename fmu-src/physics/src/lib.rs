//! The physics of the actuator: coil driver, torque-motor coil, Moog 30 two-stage valve,
//! cylinder and load, and the outer flow/position loops. [`Physics`] ties the components
//! together and advances them; it sees only the typed [`Params`], [`Inputs`] and
//! [`Outputs`].
//!
//! [`Physics`] holds the actuator (`actuator`: coefficients, mode systems, state) and the
//! integrator that [`Params::solver_method`] chose (`integrator`: the seam). It cuts each
//! step at the time events of the digital loops (`advance`) and has the integrator evolve
//! the continuous part between them. The exact integrator (`exact_integrator`): driver,
//! coil and valve form a piecewise-linear system, integrated exactly (`mode_systems`);
//! the cylinder is nonlinear and stiff, integrated by a Rosenbrock method (`rosenbrock`)
//! along the exact spool path. No FFI, no `unsafe`.

//!
//! The folders show the parts: `components` (the equations of driver, H-bridge, coil,
//! valve, metering ports, cylinder and its terms, outer loops, rod port), `numerics` (what
//! both integrators use: the augmented state and its exponentials, the mode systems, the slew
//! ends, the Rosenbrock steps, LU and root finding), `integrators` (the seam, and each
//! integrator in a folder of its own), `state` (byte framing and the state as bytes). No
//! file imports from a file that imports it (`scripts/import-cycles.py`).

mod actuator;
mod advance;
mod components;
mod events;
mod held_inputs;
mod integrators;
mod numerics;
mod params;
mod physics;
mod readable;
mod retune;
#[cfg(feature = "whole-model")]
pub mod rhs;
mod state;

pub use components::rod_port::RATE_PROBE;
pub use components::valve_datasheet::{
    ValveFigures, DATASHEET_HZ, MAX_AMPLIFIER_GAIN, MAX_FIRST_STAGE_HZ, MAX_LAP,
};
pub use events::{StepEvents, Work};
pub use params::{
    CoilParams, ControlMode, CylinderLoadParams, DriverKind, HBridgeParams, Inputs,
    OuterLoopParams, Outputs, Params, PiDriverParams, PidGains, RodPort, SolverMethod,
    ValveDatasheet, ValveParameterization, ValveParams, VALVE_RATED_CURRENT,
};
pub use physics::Physics;
use physics::StepEnd;
pub use readable::readable;
pub use state::bytes;

use actuator::Actuator;
use components::cylinder;
use integrators::chosen::ChosenIntegrator;
use integrators::seam::Integrator;

impl Physics {
    /// Builds the mode systems and puts the model in equilibrium for `inputs` at
    /// `start_time` (the sampling clocks of the digital loops count from time 0).
    pub fn start(params: &Params, inputs: &Inputs, start_time: f64) -> Result<Physics, String> {
        let actuator = Actuator::start(params, inputs, start_time)?;
        let integrator = ChosenIntegrator::new(params, &actuator);
        let rod_force_mean = actuator.rod_force();
        Ok(Physics { actuator, integrator, resting: None, rod_force_mean, step_end: None })
    }

    /// Builds ahead the propagators that a first step of `step` seconds with these inputs
    /// needs, and the whole segments' that the steps after a command change use, so that the
    /// first steps cost what the others do (a real-time host budgets every step alike). Only
    /// the integrator's caches change: a probe takes the step and hands what it built back;
    /// a probe that fails leaves nothing.
    pub fn prepare_first_step(&mut self, inputs: &Inputs, t_start: f64, step: f64) {
        // On the heap: two instances' worth of stack is more than some host threads have.
        let mut probe = Box::new(self.clone());
        if probe.advance(inputs, t_start, step).is_ok() {
            let Physics { actuator, integrator, .. } = &mut *probe;
            integrator.prepare(actuator, step);
            self.integrator.adopt_prepared(probe.integrator);
        }
    }

    /// The work done so far.
    pub fn work(&self) -> Work {
        let mut work = self.actuator.work;
        self.integrator.count_work(&mut work);
        work
    }

    /// The force on the rod averaged over the last step (the output F_rod), without
    /// computing the other outputs.
    pub fn rod_force_mean(&self) -> f64 {
        self.rod_force_mean
    }

    /// What the valve's gains in use amount to, in a datasheet's terms (its gains as
    /// resolved when the physics was built).
    pub fn valve_figures(&self) -> ValveFigures {
        components::valve_datasheet::figures(&self.actuator.params.valve)
    }

    /// The outputs at the current state.
    pub fn outputs(&self) -> Outputs {
        let mut out = self.actuator.outputs();
        out.f_rod = self.rod_force_mean;
        out
    }

    /// The outputs that are read off the state, F_rod (the mean over the last step) among
    /// them; the port flows `q_a`, `q_b` and the rod's slopes `df_rod_dx`, `df_rod_dv`, which
    /// evaluate the cylinder's laws, are left at 0 ([`Physics::outputs`] has them all).
    pub fn state_outputs(&self) -> Outputs {
        let a = &self.actuator;
        let mut out = a.state_outputs_at(&a.z, &a.cylinder.state);
        out.f_rod = self.rod_force_mean;
        out
    }
}

impl Physics {
    /// One communication step: `Physics::advance` (which refuses, leaving the state as it
    /// was, a step that ends with the piston through the end of the cylinder) after refusing a
    /// supply at or above the relief valves' setting; reports relief valves that opened.
    /// `None` for a step that changes nothing (`Physics::rests`; its supply passed with the
    /// step before): the state, and so the outputs, stay as they are.
    #[inline]
    pub fn step(
        &mut self,
        inputs: &Inputs,
        t_start: f64,
        step: f64,
    ) -> Result<Option<StepEvents>, String> {
        if self.rests(inputs, step) {
            return Ok(None);
        }
        self.step_moving(inputs, t_start, step).map(Some)
    }

    /// [`Physics::step`] of a step that does not rest. Out of line, so that a resting step
    /// is a comparison in the caller.
    #[inline(never)]
    fn step_moving(
        &mut self,
        inputs: &Inputs,
        t_start: f64,
        step: f64,
    ) -> Result<StepEvents, String> {
        let c = &self.actuator.params.cylinder;
        c.check_supply(inputs.p_supply)?;
        let relief_before = match self.step_end {
            Some(end) => end.relief_open,
            None => cylinder::relief_open(c, &self.actuator.cylinder.state),
        };
        let force_before = match self.step_end {
            Some(end) if c.port == RodPort::Force => end.rod_force,
            _ => self.actuator.take_rod_motion(inputs)?,
        };
        let mut events = self.advance(inputs, t_start, step)?;
        let force_after = self.actuator.rod_force();
        self.rod_force_mean = 0.5 * (force_before + force_after);
        let a = &self.actuator;
        let relief_after = cylinder::relief_open(&a.params.cylinder, &a.cylinder.state);
        self.step_end = Some(StepEnd { rod_force: force_after, relief_open: relief_after });
        events.relief_opened = [0, 1].map(|k| relief_after[k] && !relief_before[k]);
        Ok(events)
    }
}

impl Physics {
    /// The outputs with the state moved `span` seconds along its current rates (the valve
    /// and driver by their mode's matrix, the cylinder by its equations under `inputs`):
    /// differences of these give the outputs' time derivatives. F_rod is the force at that
    /// state, not a step's mean.
    pub fn outputs_along(&self, inputs: &Inputs, span: f64) -> Outputs {
        self.actuator.outputs_along(inputs, span)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::actuator::dynamics;
    use crate::components::coefficients::Coefficients;
    use crate::components::driver::MODES;
    use crate::numerics::augmented_state::{self, Vector, I};

    /// `augmented_state::rate` and `augmented_state::propagate` compute only the evolving rows: no mode may give
    /// the held constants dynamics, and over a step they must come out as they went in.
    #[test]
    fn no_mode_moves_the_held_constants() {
        let c = Coefficients::new(&Params::PAPER).unwrap();
        let z = Vector::from_fn(|k, _| 0.3 + k as f64);
        for mode in MODES {
            let a = dynamics(&c, mode);
            for row in augmented_state::EVOLVING..augmented_state::N {
                assert!(a.row(row).iter().all(|&x| x == 0.0), "{mode:?} moves constant {row}");
            }
            let full = a * z;
            assert!(
                (augmented_state::rate(&a, &z) - full).norm() <= 1e-12 * full.norm(),
                "{mode:?}"
            );
            let p = (a * 1e-4).exp();
            let stepped = augmented_state::propagate(&p, &z);
            assert!((stepped - p * z).norm() <= 1e-12 * z.norm(), "{mode:?}");
            assert_eq!(
                stepped.rows(augmented_state::EVOLVING, 3),
                z.rows(augmented_state::EVOLVING, 3)
            );
        }
    }

    /// A command step's slew ends within a microsecond, found by the event search before
    /// any propagation: no propagator of the step's span is built for the slewing mode, only
    /// the linear mode's for the rest of the step.
    #[test]
    fn a_brief_slew_builds_no_propagator_of_its_own() {
        let p = Params::PAPER;
        assert_eq!(p.driver, DriverKind::OpampPi);
        let inputs = |i_ref| Inputs { i_ref, ..Inputs::PAPER };
        let mut physics = Physics::start(&p, &inputs(0.0), 0.0).unwrap();
        physics.step(&inputs(0.0), 0.0, 1e-4).unwrap();
        let before = physics.work();
        // 0.1 mA: Kp di = 16 V, 0.8 us at the slew rate.
        physics.step(&inputs(1e-4), 1e-4, 1e-4).unwrap();
        let work = physics.work().since(&before);
        assert_eq!(work.guard_locations, 1, "the slew's end searched once");
        // The linear mode runs from the step's start pulled back (`slew_end`): through the
        // whole step's propagator, which the step before built.
        assert_eq!(work.exponentials, 0, "no propagator for the rest of the step");
        assert!(physics.actuator.z[I] > 0.5e-4, "the current follows: {} A", physics.actuator.z[I]);
    }

    /// The sampling instants `k / f_sample` are rounded, so the sample periods between them
    /// differ in their last bits, more once `t` passes 0.5 s (its rounding doubles). Each
    /// period is propagated as the nominal one: a position loop that follows a moving
    /// reference across 0.5 s builds no propagator after its first steps.
    #[test]
    fn sample_periods_share_their_propagator_across_the_clock() {
        let mut p = Params::PAPER;
        p.control_mode = ControlMode::Position;
        let inputs = |t: f64| Inputs {
            x_ref: 5e-3 * (2.0 * std::f64::consts::PI * 2.0 * t).sin(),
            ..Inputs::PAPER
        };
        let (t0, h) = (0.45, 1e-4);
        let mut physics = Physics::start(&p, &inputs(t0), t0).unwrap();
        let mut after_warm_up = 0;
        for k in 0..1000 {
            let t = t0 + k as f64 * h;
            if k == 20 {
                after_warm_up = physics.work().exponentials;
            }
            physics.step(&inputs(t), t, h).unwrap();
        }
        assert!(physics.actuator.cylinder.state.v.abs() > 1e-3, "the piston moves");
        assert_eq!(physics.work().exponentials, after_warm_up, "exponentials after the warm-up");
    }

    /// A position loop started at rest whose reference then jumps (a gait's first sample,
    /// 1.44 mm) rides the rail and comes off it inside its first sample period: one-off spans,
    /// taken by Taylor series. The period's whole-segment propagator, which the slews of the
    /// samples after it use, is built with the first step's. So neither of the first two
    /// steps builds an exponential.
    #[test]
    fn a_position_loop_builds_no_exponential_in_its_first_steps() {
        let mut p = Params::PAPER;
        p.control_mode = ControlMode::Position;
        let at_rest = Inputs::PAPER;
        let mut physics = Physics::start(&p, &at_rest, 0.0).unwrap();
        physics.prepare_first_step(&at_rest, 0.0, 1e-4);
        let prepared = physics.work().exponentials;
        let gait = |t: f64| Inputs {
            x_ref: 15e-3 * (4.0 * std::f64::consts::PI * t).sin()
                + 3e-3 * (8.0 * std::f64::consts::PI * t + 0.5).sin(),
            ..at_rest
        };
        for k in 0..2 {
            let t = k as f64 * 1e-4;
            physics.step(&gait(t), t, 1e-4).unwrap();
            assert_eq!(physics.work().exponentials, prepared, "exponentials in step {k}");
        }
        // The loop drives the coil toward its command, and the spool opens toward x_ref > 0.
        assert!(physics.actuator.z[I] > 1e-3, "i_coil {} A", physics.actuator.z[I]);
        assert!(
            physics.actuator.z[augmented_state::XS] > 0.5e-6,
            "x_spool {} m",
            physics.actuator.z[augmented_state::XS]
        );
    }

    /// fixed_cost builds every exponential it needs when the first step is prepared: none in
    /// a doStep, through a position loop's gait (a slew at every sample, parts of internal
    /// steps either side) and 20 Hz current squares (the op-amp to its rails and back, the
    /// piston from stop to stop).
    #[test]
    fn fixed_cost_builds_no_exponential_in_a_step() {
        let gait = |t: f64| Inputs {
            x_ref: 15e-3 * (4.0 * std::f64::consts::PI * t).sin(),
            ..Inputs::PAPER
        };
        let square = |t: f64| Inputs {
            i_ref: if (40.0 * t).fract() < 0.5 { 5e-3 } else { -5e-3 },
            ..Inputs::PAPER
        };
        let runs: [(ControlMode, &dyn Fn(f64) -> Inputs); 2] =
            [(ControlMode::Position, &gait), (ControlMode::Current, &square)];
        for (mode, inputs) in runs {
            let mut p = Params::PAPER;
            (p.control_mode, p.solver_method) = (mode, SolverMethod::FixedCost);
            let mut physics = Physics::start(&p, &inputs(0.0), 0.0).unwrap();
            physics.prepare_first_step(&inputs(0.0), 0.0, 1e-4);
            let prepared = physics.work().exponentials;
            for k in 0..1000 {
                let t = k as f64 * 1e-4;
                physics.step(&inputs(t), t, 1e-4).unwrap();
            }
            assert_eq!(physics.work().exponentials, prepared, "{mode:?}");
            assert!(physics.actuator.cylinder.state.x.abs() > 1e-3, "{mode:?}: the piston moves");
        }
    }

    /// A 100 Hz current sine at 1e-4 s steps: each step's command change ends its slew
    /// microseconds in, and the linear mode's output then rises towards its new value, fast
    /// enough that its slope alone predicts the rail within the step. Its curvature says it
    /// bends away: the step goes the usual way, no event search for it (the slope alone
    /// would have most steps search a window that holds no event).
    #[test]
    fn a_guard_bending_away_from_its_threshold_is_not_searched() {
        let p = Params::PAPER;
        let sine = |t: f64| Inputs {
            i_ref: 5e-3 * (2.0 * std::f64::consts::PI * 100.0 * t).sin(),
            ..Inputs::PAPER
        };
        let mut physics = Physics::start(&p, &sine(0.0), 0.0).unwrap();
        let h = 1e-4;
        for k in 0..400 {
            let t = k as f64 * h;
            physics.step(&sine(t), t, h).unwrap();
        }
        // One search per step remains: the slew's end, in closed form.
        let searches = physics.work().guard_locations;
        assert!(searches <= 420, "{searches} event searches in 400 steps");
        assert!(physics.actuator.cylinder.state.v.abs() > 1e-3, "the piston moves");
    }

    /// Piece and sub-step counts round up as `ceil` does, saturating at both ends.
    #[test]
    fn counts_round_up_like_ceil() {
        let cases = [0.0, -0.0, 0.3, 1.0, 1.0 + f64::EPSILON, 6.5, 2f64.powi(60), 1e30];
        for x in cases {
            assert_eq!(augmented_state::ceil_count(x), x.ceil() as usize, "{x}");
        }
        assert_eq!(augmented_state::ceil_count(f64::INFINITY), usize::MAX);
        assert_eq!(augmented_state::ceil_count(f64::NAN), 0);
        assert_eq!(augmented_state::ceil_count(-3.5), 0);
    }

    /// Preparing the first step computes its propagators ahead (that step then computes no
    /// matrix exponential) and changes nothing else: the run continues bit for bit as an
    /// unprepared one, through steps of other sizes too.
    #[test]
    fn prepared_first_step_computes_no_exponential_and_changes_no_result() {
        let mut p = Params::PAPER;
        p.control_mode = ControlMode::Position;
        let inputs = |k: usize| Inputs { x_ref: 5e-3 * (k as f64 * 0.01).sin(), ..Inputs::PAPER };
        let plain = Physics::start(&p, &inputs(0), 0.0).unwrap();
        let mut prepared = plain.clone();
        prepared.prepare_first_step(&inputs(0), 0.0, 1e-4);
        let mut runs = [plain, prepared];
        let ahead = runs.each_ref().map(|run| run.work().exponentials);
        assert_eq!(ahead[0], 0);
        assert!(ahead[1] > 0, "nothing prepared");
        for (n, run) in runs.iter_mut().enumerate() {
            let mut t = 0.0;
            for k in 0..40 {
                let h = if k < 20 { 1e-4 } else { 3e-5 };
                run.step(&inputs(k), t, h).unwrap();
                t += h;
                if k == 0 {
                    let in_first_step = run.work().exponentials - ahead[n];
                    assert_eq!(in_first_step == 0, n == 1, "run {n}: {in_first_step} exponentials");
                }
            }
        }
        let [plain, prepared] = &runs;
        assert!(plain.actuator.cylinder.state.x.abs() > 1e-5, "the piston moved");
        assert_eq!(plain.actuator.z.map(f64::to_bits), prepared.actuator.z.map(f64::to_bits));
        assert_eq!(
            plain.actuator.cylinder.state.to_array(),
            prepared.actuator.cylinder.state.to_array()
        );
        assert_eq!(plain.outputs(), prepared.outputs());
    }
}
