//! The actuator as every integrator sees it: its coefficients, the mode systems of driver,
//! coil and valve, and its state (driver mode, valve stops, the augmented state `z`, the
//! digital loops, the cylinder), with the rules that keep the state consistent with its
//! mode ([`Actuator::settle`]) and take new commands into it.

use crate::components::coefficients::Coefficients;
use crate::components::coil;
use crate::components::cylinder;
use crate::components::cylinder::check_inside;
use crate::components::cylinder::CylinderState;
use crate::components::cylinder_terms::net_force;
use crate::components::driver;
use crate::components::driver::Mode;
use crate::components::driver::MODES;
use crate::components::hbridge::HBridgeState;
use crate::components::metering_ports::AnyLap;
use crate::components::outer_loop::OuterLoop;
use crate::components::rod_port;
use crate::components::valve;
use crate::events::StepEvents;
use crate::events::Work;
use crate::held_inputs::HeldInputs;
use crate::integrators::exact::driven_cylinder::DrivenCylinder;
use crate::numerics::augmented_state::Mat;
use crate::numerics::augmented_state::Vector;
use crate::numerics::augmented_state::I;
use crate::numerics::augmented_state::I_CMD;
use crate::numerics::augmented_state::ONE;
use crate::numerics::augmented_state::RAIL;
use crate::numerics::augmented_state::U;
use crate::numerics::augmented_state::UI;
use crate::numerics::augmented_state::XF;
use crate::numerics::augmented_state::XS;
use crate::numerics::mode_systems::ModeSystem;
use crate::numerics::rosenbrock::RosenbrockMemory;
use crate::params::ControlMode;
use crate::params::DriverKind;
use crate::params::Inputs;
use crate::params::Outputs;
use crate::params::Params;
use crate::params::RodPort;

/// The model and its state; the integrator that advances it is [`Physics`]'s other half.
#[derive(Clone)]
pub(crate) struct Actuator {
    pub(crate) params: Coefficients,
    /// Each driver mode's system, the valve free of its stops, in [`MODES`] order.
    pub(crate) systems: [ModeSystem; MODES.len()],
    pub(crate) z: Vector,
    pub(crate) mode: Mode,
    pub(crate) stops: valve::Stops,
    /// The system of (mode, stops) when the valve has travel stops (without, the mode's
    /// own system in `systems` serves: [`current_system`]).
    pub(crate) active: ModeSystem,
    /// Discrete state of the H-bridge's digital loop and PWM.
    pub(crate) hbridge: HBridgeState,
    pub(crate) outer: OuterLoop,
    pub(crate) cylinder: DrivenCylinder,
    /// Supply pressure of the last step (the port flows depend on it).
    pub(crate) p_supply: f64,
    /// The work counted so far (the integrator's own counters aside: [`Physics::work`]).
    pub(crate) work: Work,
}

/// `z' = A z` for one driver mode, the valve free of its stops: coil, valve, then driver
/// rows (the linear PI mode's output row reads the coil row).
pub(crate) fn dynamics(c: &Coefficients, mode: Mode) -> Mat {
    let mut a = Mat::zeros();
    coil::coil_rows(c, mode, &mut a);
    valve::valve_rows(c, &mut a);
    driver::driver_rows(c, mode, &mut a);
    a
}

/// The system of a driver mode with its exit guards.
pub(crate) fn mode_system(c: &Coefficients, mode: Mode) -> ModeSystem {
    let a = dynamics(c, mode);
    ModeSystem::new(a, &driver::mode_guards(c, mode, &a))
}

/// The propagator caches' name for a (mode, stops) pair: each pair has a system of its own.
pub(crate) fn system_key(mode: Mode, stops: valve::Stops) -> usize {
    mode.index() + MODES.len() * stops.code()
}

/// The system of each driver mode for the coefficients `c`; refused where the parameters
/// overflow them.
pub(crate) fn mode_systems(c: &Coefficients) -> Result<[ModeSystem; MODES.len()], String> {
    let systems = MODES.map(|m| mode_system(c, m));
    if !systems.iter().all(|s| s.a.iter().all(|x| x.is_finite()) && s.radius.is_finite()) {
        return Err(format!(
            "the parameters give a model too stiff to represent (coefficients like (coil.R + coil.R_sense)/coil.L = {} 1/s, \
             valve.f_n, coil.K_b/coil.L overflow); use physically sized values",
            crate::readable::readable(c.r_total / c.inductance)
        ));
    }
    Ok(systems)
}

impl Actuator {
    /// The propagator caches' name for the actuator's (mode, stops) pair ([`system_key`]).
    pub(crate) fn system_key(&self) -> usize {
        system_key(self.mode, self.stops)
    }

    /// Builds the mode systems and puts the model in equilibrium for `inputs` at
    /// `start_time` (the sampling clocks of the digital loops count from time 0).
    pub(crate) fn start(
        params: &Params,
        inputs: &Inputs,
        start_time: f64,
    ) -> Result<Actuator, String> {
        let rtol = params.solver_rtol;
        let params = Coefficients::new(params)?;
        let systems = mode_systems(&params)?;
        let mut actuator = Actuator {
            params,
            systems,
            z: Vector::zeros(),
            mode: Mode::Linear,
            stops: valve::Stops::default(),
            active: systems[Mode::Linear.index()],
            hbridge: HBridgeState::default(),
            outer: OuterLoop::default(),
            cylinder: DrivenCylinder::new(CylinderState::default(), RosenbrockMemory::new(rtol)),
            p_supply: inputs.p_supply,
            work: Work::default(),
        };
        let held = HeldInputs::new(&params, inputs);
        params.cylinder.check_supply(held.p_supply)?;
        actuator.outer = OuterLoop::at_start(&params.loops, held.reference, start_time);
        actuator.start_cylinder(&held, inputs);
        let i_cmd = actuator.current_command(&held);
        actuator.equilibrium(i_cmd, held.rail, start_time);
        Ok(actuator)
    }

    /// The coil current command: the input, or the outer loop's output.
    pub(crate) fn current_command(&self, inputs: &HeldInputs) -> f64 {
        if self.params.loops.mode == ControlMode::Current {
            inputs.i_ref
        } else {
            self.outer.command
        }
    }

    fn equilibrium(&mut self, i_ref: f64, vmax: f64, start_time: f64) {
        let (mut z, hbridge) = rest_state(&self.params, i_ref, vmax, start_time);
        if let Some(hbridge) = hbridge {
            self.hbridge = hbridge;
        }
        self.settle(&mut z);
        self.z = z;
    }

    /// Chooses the stops and driver mode consistent with `z`, puts `z` on them and makes
    /// their system the active one. Returns whether anything changed.
    pub(crate) fn settle(&mut self, z: &mut Vector) -> bool {
        let (mode, stops) = consistent_state(&self.params, &self.systems, &self.hbridge, z);
        let changed = (mode, stops) != (self.mode, self.stops);
        if changed {
            (self.mode, self.stops) = (mode, stops);
            // Without stops the mode's own system serves (see `current_system`): no 1.8 kB copy.
            if valve::has_stops(&self.params) {
                self.active = self.systems[mode.index()].with_stops(&self.params, stops);
            }
        }
        changed
    }

    /// Takes a new current command or rail into the state. A state that ended the last step
    /// is consistent with its mode; only a new command or rail (or a restored state) needs
    /// the mode chosen again.
    /// Inline: most calls find nothing new or start a slew; the rest go out of line, so
    /// that their stack frame is not every call's.
    #[inline(always)]
    pub(crate) fn follow_command(&mut self, inputs: &HeldInputs, events: &mut StepEvents) {
        let i_cmd = self.current_command(inputs);
        let same_rail = self.z[RAIL] == inputs.rail;
        if same_rail && (self.z[I_CMD] == i_cmd || self.starts_a_slew(i_cmd)) {
            return;
        }
        self.settle_on_command(i_cmd, inputs.rail, events);
    }

    /// [`Actuator::follow_command`] of a new command or rail the long way: the mode chosen
    /// again.
    #[inline(never)]
    fn settle_on_command(&mut self, i_cmd: f64, rail: f64, events: &mut StepEvents) {
        let mut z = self.z;
        driver::apply_inputs(&self.params, &mut z, i_cmd, rail);
        let before = self.mode;
        self.settle(&mut z);
        driver::count_switch(events, before, self.mode);
        self.z = z;
    }

    /// The most common new command, a loop's sample or a command's next value to a PI
    /// driver in its linear mode free of valve stops: where it puts the PI law's value
    /// beyond the output by more than the tolerance, the driver slews towards it (the
    /// outcome of [`driver::consistent_mode`]'s first tests, which [`Actuator::settle`]
    /// would reach the long way), and the new command is taken with no more work.
    /// `false`, nothing changed, for any other case.
    #[inline]
    fn starts_a_slew(&mut self, i_cmd: f64) -> bool {
        let c = &self.params;
        if self.mode != Mode::Linear || !pi_driver_free_of_stops(c) {
            return false;
        }
        let mut z = self.z;
        z[I_CMD] = i_cmd;
        let Some(slew) = driver::slew_towards_law(c, &z) else {
            return false;
        };
        (self.mode, self.z) = (slew, z);
        true
    }

    /// The outputs at the current state (F_rod: the force at the state).
    pub(crate) fn outputs(&self) -> Outputs {
        self.outputs_at(&self.z, &self.cylinder.state)
    }

    /// The outputs at augmented state `z` and cylinder state `cylinder` (F_rod: the force
    /// there).
    pub(crate) fn outputs_at(&self, z: &Vector, cylinder: &CylinderState) -> Outputs {
        let mut out = self.state_outputs_at(z, cylinder);
        let c = &self.params.cylinder;
        cylinder::write_outputs(c, cylinder, z[XS], self.p_supply, &mut out);
        out.f_rod = net_force(c, cylinder, 0.0)[0];
        (out.df_rod_dx, out.df_rod_dv) = rod_port::rod_stiffness(c, cylinder, z[XS], self.p_supply);
        out
    }

    /// The outputs read off the state without evaluating a law of the cylinder: the others
    /// (port flows, the rod's force and its slopes) are left at 0.
    pub(crate) fn state_outputs_at(&self, z: &Vector, cylinder: &CylinderState) -> Outputs {
        let mut out = Outputs {
            i_coil: z[I],
            u_driver: z[U],
            driver_saturated: driver::saturated(&self.params, self.mode, &self.hbridge, z),
            x_flapper: z[XF],
            x_spool: z[XS],
            q_valve: valve::no_load_flow(&self.params, z[XS]),
            ..Outputs::default()
        };
        cylinder::write_state_outputs(&self.params.cylinder, cylinder, &mut out);
        out
    }
}

/// Driver, coil and valve at rest under the current command `i_cmd` and the rail `vmax`, not
/// yet put on a mode; for the H-bridge also the digital state that holds the current on
/// average from `start_time` (its PWM starts at the next period).
pub(crate) fn rest_state(
    p: &Coefficients,
    i_cmd: f64,
    vmax: f64,
    start_time: f64,
) -> (Vector, Option<HBridgeState>) {
    let mut z = Vector::zeros();
    z[I_CMD] = i_cmd;
    z[RAIL] = vmax;
    z[ONE] = 1.0;
    let u = (p.r_total * i_cmd).clamp(-vmax, vmax);
    z[U] = u;
    z[I] = if p.driver == DriverKind::IdealCurrent { i_cmd } else { coil::steady_current(p, u) };
    // An unsaturated PI holds e = 0 with ui = u; a saturated one sits at the rail with
    // its integrator stopped at the rail value.
    z[UI] = u;
    (z[XF], z[XS]) = valve::equilibrium(p, z[I]);
    if p.driver != DriverKind::HBridge {
        return (z, None);
    }
    let hbridge = HBridgeState::at_equilibrium(&p.hbridge, u, p.r_total * i_cmd, vmax, start_time);
    z[U] = hbridge.output(&p.hbridge, vmax);
    (z, Some(hbridge))
}

/// The valve stops and the driver mode consistent with `z`, and `z` put on them: an impact
/// takes the flapper's outward velocity at its limit, the held parts sit at their limits,
/// the algebraic part of the driver follows the mode. None of it depends on the mode before.
pub(crate) fn consistent_state(
    c: &Coefficients,
    systems: &[ModeSystem; MODES.len()],
    hbridge: &HBridgeState,
    z: &mut Vector,
) -> (Mode, valve::Stops) {
    let stops = valve::settle_stops(c, &systems[0].a, z);
    let mode = driver::consistent_mode(c, z, |m| &systems[m.index()].a);
    driver::project_onto(c, hbridge, z, mode);
    (mode, stops)
}

/// A PI driver (op-amp or industrial) on a valve without travel stops: where the shortcuts
/// of the common step (a new command's slew, fixed_cost's linear lane) hold.
pub(crate) fn pi_driver_free_of_stops(c: &Coefficients) -> bool {
    matches!(c.driver, DriverKind::OpampPi | DriverKind::Industrial) && !valve::has_stops(c)
}

/// The system `mode` runs on: its own without travel stops, else the one with the stops
/// that hold now ([`Actuator::settle`] keeps it as `active`). Over the fields, so that the
/// caller may still borrow the cylinder and its own caches.
pub(crate) fn current_system<'a>(
    params: &Coefficients,
    active: &'a ModeSystem,
    systems: &'a [ModeSystem; MODES.len()],
    mode: Mode,
) -> &'a ModeSystem {
    if valve::has_stops(params) {
        active
    } else {
        &systems[mode.index()]
    }
}

// The rod's port as the actuator meets it (its equations are `components::rod_port`'s).
impl Actuator {
    /// Puts the cylinder at rest in equilibrium for the held inputs; with the motion port
    /// the rod where the host says.
    pub(crate) fn start_cylinder(&mut self, held: &HeldInputs, inputs: &Inputs) {
        let c = &self.params.cylinder;
        let force = if c.port == RodPort::Force { held.load } else { 0.0 };
        self.cylinder.state = cylinder::equilibrium(c, held.p_supply, force);
        if c.port == RodPort::Motion {
            (self.cylinder.state.x, self.cylinder.state.v) = (inputs.x_rod, inputs.v_rod);
        }
    }

    /// With the motion port, moves the rod to the host's position and velocity at the
    /// start of a step (refused, nothing changed, if that puts the piston through the end
    /// of the cylinder); returns the force on the rod there.
    pub(crate) fn take_rod_motion(&mut self, inputs: &Inputs) -> Result<f64, String> {
        if self.params.cylinder.port == RodPort::Motion {
            let moved = CylinderState { x: inputs.x_rod, v: inputs.v_rod, ..self.cylinder.state };
            check_inside(&self.params.cylinder, &moved)?;
            self.cylinder.state = moved;
        }
        Ok(self.rod_force())
    }

    /// The force of the actuator on the rod at the current state (N, + = extension).
    pub(crate) fn rod_force(&self) -> f64 {
        net_force(&self.params.cylinder, &self.cylinder.state, 0.0)[0]
    }

    /// See [`Physics::outputs_along`].
    pub(crate) fn outputs_along(&self, inputs: &Inputs, span: f64) -> Outputs {
        let system = current_system(&self.params, &self.active, &self.systems, self.mode);
        let dz = system.a * self.z;
        let held = HeldInputs::new(&self.params, inputs);
        let state = &self.cylinder.state;
        let c = &self.params.cylinder;
        let dy = cylinder::derivatives::<AnyLap>(c, state, self.z[XS], held.p_supply, held.load);
        let z = self.z + dz * span;
        let mut y = state.to_array();
        for (y, d) in y.iter_mut().zip(dy) {
            *y += d * span;
        }
        let moved = CylinderState::from_array(&y);
        self.outputs_at(&z, &moved)
    }
}
