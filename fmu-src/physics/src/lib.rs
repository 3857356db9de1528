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

mod actuator;
mod advance;
mod augmented_exp;
mod augmented_state;
pub mod bytes;
mod coil;
mod cylinder;
mod cylinder_jacobian;
mod cylinder_terms;
mod driven_cylinder;
mod driver;
mod dyadic_ladder;
mod exact_integrator;
mod fixed_cost;
mod fixed_cost_cylinder;
mod hbridge;
mod integrator;
mod lu4;
mod metering_ports;
mod mode_systems;
mod outer_loop;
mod params;
mod retune;
#[cfg(feature = "whole-model")]
pub mod rhs;
mod rod_port;
mod root_finding;
mod rosenbrock;
mod slew_end;
mod state_bytes;
mod valve;

pub use params::{
    CoilParams, ControlMode, CylinderLoadParams, DriverKind, HBridgeParams, Inputs,
    OuterLoopParams, Outputs, Params, PiDriverParams, PidGains, RodPort, SolverMethod, ValveParams,
    VALVE_RATED_CURRENT,
};
pub use rod_port::RATE_PROBE;

use actuator::Actuator;
use augmented_state::{Mat, Vector, I, I_CMD, ONE, RAIL, U, UI, XF, XS};
use cylinder::{CylinderParams, CylinderState};
use driven_cylinder::DrivenCylinder;
use driver::{Mode, MODES};
use hbridge::HBridgeState;
use integrator::{ChosenIntegrator, Integrator};
use mode_systems::{locate_event, may_cross, GuardsAt, ModeSystem, Propagator, PropagatorCache};
use outer_loop::{LoopParams, OuterLoop};
use rosenbrock::RosenbrockMemory;
use valve::SpoolPath;

/// The parameters in the form the equations use (derived from [`Params`] once).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Coefficients {
    pub driver: DriverKind,
    /// Gains, output drop and slew rate of the continuous PI loop of the chosen driver.
    pub kp: f64,
    pub ki: f64,
    pub v_drop: f64,
    pub slew_rate: f64,
    pub hbridge: HBridgeParams,
    pub loops: LoopParams,
    pub cylinder: CylinderParams,
    pub inductance: f64,
    pub r_total: f64,
    pub k_backemf: f64,
    pub valve: ValveParams,
    /// Natural angular frequency of the first stage, 2 pi f_n.
    pub wn: f64,
}

impl Coefficients {
    /// Derives the coefficients and checks the rules between parameters.
    pub(crate) fn new(p: &Params) -> Result<Coefficients, String> {
        let pi = if p.driver == DriverKind::Industrial { p.industrial } else { p.opamp };
        let v = &p.valve;
        Ok(Coefficients {
            driver: p.driver,
            kp: pi.kp,
            ki: pi.ki,
            // The op-amp's output stage drop; the other drivers reach the supply.
            v_drop: if p.driver == DriverKind::OpampPi { p.opamp_v_drop } else { 0.0 },
            slew_rate: pi.slew_rate,
            hbridge: p.hbridge,
            loops: LoopParams::new(&p.outer_loop, p.control_mode, v.k3 * v.k1 / v.kw),
            cylinder: CylinderParams::new(&p.cylinder, v)?,
            inductance: p.coil.inductance,
            r_total: p.coil.resistance + p.coil.r_sense,
            k_backemf: p.coil.k_backemf,
            valve: *v,
            wn: 2.0 * std::f64::consts::PI * v.f_n,
        })
    }

    /// What the mode systems are built from, as bits: the driver's PI loop (gains, slew
    /// rate), the coil, and the valve (first stage, spool, stops). Equal keys give the same
    /// systems bit for bit.
    pub(crate) fn mode_system_key(&self) -> [u64; 19] {
        let v = &self.valve;
        [
            self.kp,
            self.ki,
            self.slew_rate,
            self.inductance,
            self.r_total,
            self.k_backemf,
            self.wn,
            v.k1,
            v.kf,
            v.kw,
            v.k2,
            v.k3,
            v.spool_area,
            v.zeta,
            v.f_n,
            v.x_flapper_max,
            v.x_spool_max,
            v.dp_rated,
            v.dp_laminar,
        ]
        .map(f64::to_bits)
    }
}

/// `z' = A z` for one driver mode, the valve free of its stops: coil, valve, then driver
/// rows (the linear PI mode's output row reads the coil row).
fn dynamics(c: &Coefficients, mode: Mode) -> Mat {
    let mut a = Mat::zeros();
    coil::coil_rows(c, mode, &mut a);
    valve::valve_rows(c, &mut a);
    driver::driver_rows(c, mode, &mut a);
    a
}

/// The system of a driver mode with its exit guards.
fn mode_system(c: &Coefficients, mode: Mode) -> ModeSystem {
    let a = dynamics(c, mode);
    ModeSystem::new(a, &driver::mode_guards(c, mode, &a))
}

/// Mode changes inside one step, for event logging.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepEvents {
    pub rail_entered: u32,
    pub rail_left: u32,
    /// Relief valves of chambers `[A, B]` open at the end of the step that were shut at its
    /// start (seen at communication points).
    pub relief_opened: [bool; 2],
}

/// Work the integrators have done since the instance was built or restored (cumulative
/// counters for benchmarks; not part of the state).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Work {
    /// Calls of the cylinder's Rosenbrock integrator (one per piece of spool path).
    pub cylinder_calls: u64,
    /// Its internal steps: accepted (Rodas3 ones included) and rejected.
    pub steps_accepted: u64,
    pub steps_rejected: u64,
    /// Analytic Jacobians, LU factorisations of the 4x4 iteration matrix, evaluations of
    /// the cylinder's right-hand side (a Jacobian counts as one).
    pub jacobians: u64,
    pub factorisations: u64,
    pub function_evaluations: u64,
    /// 9x9 matrix exponentials of the exact integrator (propagator cache misses).
    pub exponentials: u64,
    /// State-event searches (a guard may have crossed inside a sub-step).
    pub guard_locations: u64,
}

impl Work {
    /// The work done between `earlier` (a reading of the same instance) and `self`.
    pub fn since(&self, earlier: &Work) -> Work {
        Work {
            cylinder_calls: self.cylinder_calls - earlier.cylinder_calls,
            steps_accepted: self.steps_accepted - earlier.steps_accepted,
            steps_rejected: self.steps_rejected - earlier.steps_rejected,
            jacobians: self.jacobians - earlier.jacobians,
            factorisations: self.factorisations - earlier.factorisations,
            function_evaluations: self.function_evaluations - earlier.function_evaluations,
            exponentials: self.exponentials - earlier.exponentials,
            guard_locations: self.guard_locations - earlier.guard_locations,
        }
    }

    fn add(&mut self, stats: &rosenbrock::Stats) {
        self.cylinder_calls += 1;
        self.steps_accepted += stats.accepted as u64;
        self.steps_rejected += stats.rejected as u64;
        self.jacobians += stats.jacobian_evaluations as u64;
        self.factorisations += stats.factorisations as u64;
        self.function_evaluations += stats.function_evaluations as u64;
    }
}

/// The whole physical state and what is needed to advance it.
#[derive(Clone)]
pub struct Physics {
    /// Coefficients, mode systems and the state.
    actuator: Actuator,
    /// What advances the actuator between time events ([`Params::solver_method`]).
    integrator: ChosenIntegrator,
    /// Inputs and step size (bits) of the last step if it left the state as it was, bit
    /// for bit, with no clock running: the same step again changes nothing (a pure cache).
    resting: Option<RestKey>,
    /// The force on the rod averaged over the last step (an output, carried across a saved
    /// state by the value array, so not part of the state bytes).
    rod_force_mean: f64,
}

/// Inputs and step size as bits (see `Physics::resting`).
type RestKey = [u64; 10];

/// Inputs held over one step, as the equations use them.
#[derive(Clone, Copy)]
struct HeldInputs {
    i_ref: f64,
    rail: f64,
    p_supply: f64,
    /// The load on the rod: F_ext (N) with the force port, the host's acceleration of the
    /// rod (m/s2) with the motion port.
    load: f64,
    /// Reference of the outer loop (Q_ref or x_ref).
    reference: f64,
}

impl HeldInputs {
    fn new(c: &Coefficients, inputs: &Inputs) -> HeldInputs {
        let reference = match c.loops.mode {
            ControlMode::Flow => inputs.q_ref,
            ControlMode::Position => inputs.x_ref,
            ControlMode::Current => 0.0,
        };
        HeldInputs {
            i_ref: inputs.i_ref,
            rail: driver::rail(c, inputs.v_supply),
            p_supply: inputs.p_supply,
            load: match c.cylinder.port {
                RodPort::Force => inputs.f_ext,
                RodPort::Motion => inputs.a_rod,
            },
            reference,
        }
    }
}

impl Physics {
    /// Builds the mode systems and puts the model in equilibrium for `inputs` at
    /// `start_time` (the sampling clocks of the digital loops count from time 0).
    pub fn start(params: &Params, inputs: &Inputs, start_time: f64) -> Result<Physics, String> {
        let actuator = Actuator::start(params, inputs, start_time)?;
        let integrator = ChosenIntegrator::new(params, &actuator);
        let rod_force_mean = actuator.rod_force();
        Ok(Physics { actuator, integrator, resting: None, rod_force_mean })
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

    /// The outputs at the current state.
    pub fn outputs(&self) -> Outputs {
        let mut out = self.actuator.outputs();
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
    pub fn step(
        &mut self,
        inputs: &Inputs,
        t_start: f64,
        step: f64,
    ) -> Result<Option<StepEvents>, String> {
        if self.rests(inputs, step) {
            return Ok(None);
        }
        let c = &self.actuator.params.cylinder;
        c.check_supply(inputs.p_supply)?;
        let relief_before = cylinder::relief_open(c, &self.actuator.cylinder.state);
        let force_before = self.actuator.take_rod_motion(inputs)?;
        let mut events = self.advance(inputs, t_start, step)?;
        self.rod_force_mean = 0.5 * (force_before + self.actuator.rod_force());
        let a = &self.actuator;
        let relief_after = cylinder::relief_open(&a.params.cylinder, &a.cylinder.state);
        events.relief_opened = [0, 1].map(|k| relief_after[k] && !relief_before[k]);
        Ok(Some(events))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
