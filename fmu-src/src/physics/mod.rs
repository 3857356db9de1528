//! The physics of the actuator: coil driver, torque-motor coil, Moog 30 two-stage valve,
//! cylinder and load, and the outer flow/position loops. [`Physics`] ties the components
//! together and advances them; it sees only the typed [`Params`], [`Inputs`] and
//! [`Outputs`] (no value references, no variable names).
//!
//! Driver, coil and valve form a piecewise-linear system, integrated exactly
//! (`exact_integrator`); the cylinder is nonlinear and stiff, integrated by a Rosenbrock
//! method (`rosenbrock`) along the exact spool path. No FFI, no `unsafe`.

mod coil;
mod cylinder;
mod driver;
mod exact_integrator;
mod hbridge;
mod outer_loop;
mod params;
mod rosenbrock;
mod state;
mod state_bytes;
mod valve;

pub use params::{
    CoilParams, ControlMode, CylinderTableParams, DriverKind, HBridgeParams, Inputs,
    OuterLoopParams, Outputs, Params, PiDriverParams, PidGains, ValveParams,
};

use cylinder::{CylinderParams, CylinderState};
use driver::{Mode, MODES};
use exact_integrator::{
    locate_event, may_cross, taylor_propagate, ModeSystem, Propagator, PropagatorCache,
};
use hbridge::Digital;
use outer_loop::{LoopParams, OuterLoop};
use rosenbrock::{IntegratorMemory, SpoolPath};
use state::{Mat, Vector, I, IREF, ONE, U, UI, VMAX, XF, XS};

/// A step that switches mode more often than this is chattering: refuse it.
const MAX_EVENTS_PER_STEP: u32 = 1000;
/// Pieces this short (events right at a piece start) take an Euler step in the cylinder, s.
const TINY_PIECE: f64 = 1e-10;
/// A cylinder counts as at rest when it would drift less than 1e-10 of its scale in this time, s.
const REST_HORIZON: f64 = 1.0;
/// Bounds the work of one doStep with the PWM driver (each instant costs ~0.3 us).
const MAX_TIME_EVENTS_PER_STEP: u64 = 10_000_000;

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
    pub k1: f64,
    pub kf: f64,
    pub kw: f64,
    pub k2: f64,
    pub k3: f64,
    pub spool_area: f64,
    pub zeta: f64,
    pub wn: f64,
    /// Flapper and spool travel limits (0: none).
    pub x_flapper_max: f64,
    pub x_spool_max: f64,
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
            k1: v.k1,
            kf: v.kf,
            kw: v.kw,
            k2: v.k2,
            k3: v.k3,
            spool_area: v.spool_area,
            zeta: v.zeta,
            wn: 2.0 * std::f64::consts::PI * v.f_n,
            x_flapper_max: v.x_flapper_max,
            x_spool_max: v.x_spool_max,
        })
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
}

/// The whole physical state and what is needed to advance it.
#[derive(Clone)]
pub struct Physics {
    params: Coefficients,
    systems: [ModeSystem; MODES.len()],
    z: Vector,
    mode: Mode,
    stops: valve::Stops,
    /// The system of (mode, stops).
    active: ModeSystem,
    /// Discrete state of the H-bridge's digital loop and PWM.
    digital: Digital,
    outer: OuterLoop,
    cylinder: CylinderState,
    cylinder_memory: IntegratorMemory,
    /// Where the cylinder was last found at rest (see `drive_cylinder`); not part of the state.
    cylinder_rest: Option<[u64; 3]>,
    /// A state the propagator of (system, sub-step bits) maps onto itself bit for bit: the
    /// valve and driver have settled, so the product and the guard checks can be skipped
    /// with identical results (a pure cache, not part of the state).
    fixed_point: Option<(usize, u64, Vector)>,
    /// Supply pressure of the last step (the port flows depend on it).
    p_supply: f64,
    cache: PropagatorCache,
}

/// Inputs held over one step, as the equations use them.
#[derive(Clone, Copy)]
struct Held {
    i_ref: f64,
    rail: f64,
    p_supply: f64,
    f_ext: f64,
    /// Reference of the outer loop (Q_ref or x_ref).
    reference: f64,
}

impl Held {
    fn new(c: &Coefficients, inputs: &Inputs) -> Held {
        let reference = match c.loops.mode {
            ControlMode::Flow => inputs.q_ref,
            ControlMode::Position => inputs.x_ref,
            ControlMode::Current => 0.0,
        };
        Held {
            i_ref: inputs.i_ref,
            rail: driver::rail(c, inputs.v_supply),
            p_supply: inputs.p_supply,
            f_ext: inputs.f_ext,
            reference,
        }
    }
}

impl Physics {
    /// Builds the mode systems and puts the model in equilibrium for `inputs` at
    /// `start_time` (the sampling clocks of the digital loops count from time 0).
    pub(crate) fn start(
        params: &Params,
        inputs: &Inputs,
        start_time: f64,
    ) -> Result<Physics, String> {
        let params = Coefficients::new(params)?;
        let systems = MODES.map(|m| mode_system(&params, m));
        if !systems.iter().all(|s| s.a.iter().all(|x| x.is_finite()) && s.radius.is_finite()) {
            return Err(format!(
                "the parameters give a model too stiff to represent (coefficients like (coil.R + coil.R_sense)/coil.L = {:e} 1/s, \
                 valve.f_n, coil.K_b/coil.L overflow); use physically sized values",
                params.r_total / params.inductance
            ));
        }
        let mut physics = Physics {
            params,
            systems,
            z: Vector::zeros(),
            mode: Mode::Linear,
            stops: valve::Stops::default(),
            active: systems[Mode::Linear.index()],
            digital: Digital::default(),
            outer: OuterLoop::default(),
            cylinder: CylinderState::default(),
            cylinder_memory: IntegratorMemory::default(),
            cylinder_rest: None,
            fixed_point: None,
            p_supply: inputs.p_supply,
            cache: PropagatorCache::new(),
        };
        let held = Held::new(&params, inputs);
        physics.outer = OuterLoop::at_start(&params.loops, held.reference, start_time);
        physics.cylinder = cylinder::equilibrium(&params.cylinder, held.p_supply, held.f_ext);
        let i_cmd = physics.current_command(&held);
        physics.equilibrium(i_cmd, held.rail, start_time);
        Ok(physics)
    }

    /// The coil current command: the input, or the outer loop's output.
    fn current_command(&self, inputs: &Held) -> f64 {
        if self.params.loops.mode == ControlMode::Current {
            inputs.i_ref
        } else {
            self.outer.command
        }
    }

    fn equilibrium(&mut self, i_ref: f64, vmax: f64, start_time: f64) {
        let p = self.params;
        let mut z = Vector::zeros();
        z[IREF] = i_ref;
        z[VMAX] = vmax;
        z[ONE] = 1.0;
        let u = (p.r_total * i_ref).clamp(-vmax, vmax);
        z[U] = u;
        z[I] =
            if p.driver == DriverKind::IdealCurrent { i_ref } else { coil::steady_current(&p, u) };
        // An unsaturated PI holds e = 0 with ui = u; a saturated one sits at the rail with
        // its integrator stopped at the rail value.
        z[UI] = u;
        (z[XF], z[XS]) = valve::equilibrium(&p, z[I]);
        if p.driver == DriverKind::HBridge {
            // The average bridge voltage holds the current; the PWM starts at the next period.
            self.digital =
                Digital::at_equilibrium(&p.hbridge, u, p.r_total * i_ref, vmax, start_time);
            z[U] = self.digital.output(vmax);
        }
        self.settle(&mut z);
        self.z = z;
    }

    /// Chooses the stops and driver mode consistent with `z`, puts `z` on them and makes
    /// their system the active one. Returns whether anything changed.
    fn settle(&mut self, z: &mut Vector) -> bool {
        let stops = valve::settle_stops(&self.params, &self.systems[0].a, z);
        let systems = &self.systems;
        let mode = driver::consistent_mode(&self.params, z, |m| &systems[m.index()].a);
        driver::project_onto(&self.params, &self.digital, z, mode);
        let changed = (mode, stops) != (self.mode, self.stops);
        if changed {
            (self.mode, self.stops) = (mode, stops);
            self.active = self.systems[mode.index()].with_stops(&self.params, stops);
        }
        changed
    }

    /// The outputs at the current state.
    pub(crate) fn outputs(&self) -> Outputs {
        let z = &self.z;
        let c = cylinder::outputs(&self.params.cylinder, &self.cylinder, z[XS], self.p_supply);
        Outputs {
            i_coil: z[I],
            u_driver: z[U],
            driver_saturated: driver::saturated(&self.params, self.mode, &self.digital, z),
            x_flapper: z[XF],
            x_spool: z[XS],
            q_valve: valve::no_load_flow(&self.params, z[XS]),
            q_a: c.q_a,
            q_b: c.q_b,
            p_a: c.p_a,
            p_b: c.p_b,
            x_piston: c.x_piston,
            v_piston: c.v_piston,
            f_hydraulic: c.f_hydraulic,
        }
    }

    /// Advances from `t_start` by `step` seconds with `inputs` held constant.
    /// On error the state is left as it was.
    pub(crate) fn advance(
        &mut self,
        inputs: &Inputs,
        t_start: f64,
        step: f64,
    ) -> Result<StepEvents, String> {
        let saved = (
            self.z,
            self.mode,
            self.stops,
            self.digital,
            self.outer,
            self.cylinder,
            self.cylinder_memory,
            self.p_supply,
        );
        let result = self.advance_inner(inputs, t_start, step);
        if result.is_err() {
            (
                self.z,
                self.mode,
                self.stops,
                self.digital,
                self.outer,
                self.cylinder,
                self.cylinder_memory,
                self.p_supply,
            ) = saved;
            self.active = self.systems[self.mode.index()].with_stops(&self.params, self.stops);
            self.cylinder_rest = None;
        }
        result
    }

    fn advance_inner(
        &mut self,
        inputs: &Inputs,
        t_start: f64,
        step: f64,
    ) -> Result<StepEvents, String> {
        let mut events = StepEvents::default();
        let inputs = Held::new(&self.params, inputs);
        self.p_supply = inputs.p_supply;
        self.follow_command(&inputs, &mut events);
        let t_end = t_start + step;
        let p = self.params;
        let time_events =
            self.digital.events_until(&p.hbridge, t_end) + self.outer.events_until(&p.loops, t_end);
        if time_events > MAX_TIME_EVENTS_PER_STEP {
            return Err(format!(
                "a step of {step} s holds more than {MAX_TIME_EVENTS_PER_STEP} PWM/sampling instants; use shorter communication steps"
            ));
        }
        // Time events a hair past the step end (rounding of t_start + step) belong to it.
        let slack = 1e-9 * step.min(p.hbridge.period()).min(1.0 / p.loops.f_sample);
        let mut t = t_start;
        loop {
            let t_bridge = self.digital.next_event(&p.hbridge);
            let t_loop = self.outer.next_event(&p.loops);
            let t_event = t_bridge.min(t_loop);
            let fire = t_event <= t_end + slack;
            let segment_end = if fire { t_event.min(t_end) } else { t_end };
            if segment_end > t {
                self.evolve(segment_end - t, &inputs, &mut events)?;
                t = segment_end;
            }
            if !fire {
                break;
            }
            if t_loop <= t_bridge {
                // The outer loop samples first, so a bridge sample at the same instant sees its command.
                let measured = match p.loops.mode {
                    ControlMode::Flow => valve::no_load_flow(&p, self.z[XS]),
                    _ => self.cylinder.x,
                };
                self.outer.sample(&p.loops, inputs.reference, measured);
                self.follow_command(&inputs, &mut events);
            } else {
                self.digital.fire(&p.hbridge, self.z[I], self.z[IREF], p.r_total, self.z[VMAX]);
                self.z[U] = self.digital.output(self.z[VMAX]);
            }
        }
        if !self.z.iter().all(|x| x.is_finite()) {
            return Err("the state became non-finite; step refused".into());
        }
        Ok(events)
    }

    /// Takes a new current command or rail into the state. A state that ended the last step
    /// is consistent with its mode; only a new command or rail (or a restored state) needs
    /// the mode chosen again.
    fn follow_command(&mut self, inputs: &Held, events: &mut StepEvents) {
        let i_cmd = self.current_command(inputs);
        if self.z[IREF] != i_cmd || self.z[VMAX] != inputs.rail {
            let mut z = self.z;
            driver::apply_inputs(&self.params, &mut z, i_cmd, inputs.rail);
            let before = self.mode;
            self.settle(&mut z);
            driver::count_switch(events, before, self.mode);
            self.z = z;
        }
    }

    /// Advances the cylinder over a piece of `h` seconds in which the valve went from `z0`
    /// to `z1`: the spool path is the quintic Hermite interpolant of its exact position,
    /// velocity and acceleration at both ends. A cylinder at rest behind a still spool is
    /// left as it is; `rest` remembers
    /// the (spool, supply, load) bits at which that was last verified, a pure cache.
    #[allow(clippy::too_many_arguments)]
    fn drive_cylinder(
        sys: &ModeSystem,
        params: &CylinderParams,
        cylinder: &mut CylinderState,
        memory: &mut IntegratorMemory,
        rest: &mut Option<[u64; 3]>,
        (z0, z1, h): (&Vector, &Vector, f64),
        inputs: &Held,
    ) -> Result<(), String> {
        if (z1[XS] - z0[XS]).abs() <= 1e-13 * z0[XS].abs().max(1e-9) {
            let key = [z0[XS].to_bits(), inputs.p_supply.to_bits(), inputs.f_ext.to_bits()];
            if *rest == Some(key) {
                return Ok(());
            }
            // At rest means an equilibrium, whatever the piece length: drifting less than
            // 1e-10 of its scale in a second (a short piece must not make motion look still).
            let f = cylinder::derivatives(params, cylinder, z0[XS], inputs.p_supply, inputs.f_ext);
            if f.iter()
                .zip(rosenbrock::STATE_SCALE.iter())
                .all(|(d, scale)| d.abs() * REST_HORIZON <= 1e-10 * scale)
            {
                *rest = Some(key);
                return Ok(());
            }
        }
        *rest = None;
        if h <= TINY_PIECE {
            // Far below every cylinder time constant (|lambda| h < 2e-5): one Euler step.
            let f = cylinder::derivatives(
                params,
                cylinder,
                0.5 * (z0[XS] + z1[XS]),
                inputs.p_supply,
                inputs.f_ext,
            );
            let mut y = cylinder.to_array();
            for (y, d) in y.iter_mut().zip(f) {
                *y += h * d;
            }
            *cylinder = CylinderState::from_array(&y);
            return Ok(());
        }
        let a = &sys.a;
        let (az0, az1) = (a * z0, a * z1);
        let path = SpoolPath {
            h,
            start: [z0[XS], az0[XS], a.row(XS).dot(&az0.transpose())],
            end: [z1[XS], az1[XS], a.row(XS).dot(&az1.transpose())],
        };
        let spool = |tau: f64| (path.position(tau), path.rate(tau));
        rosenbrock::advance_with_rate(
            params,
            cylinder,
            h,
            inputs.p_supply,
            inputs.f_ext,
            spool,
            memory,
        )?;
        Ok(())
    }

    /// Continuous evolution over `span` seconds with state events (driver mode changes).
    fn evolve(
        &mut self,
        span_total: f64,
        inputs: &Held,
        events: &mut StepEvents,
    ) -> Result<(), String> {
        let mut z = self.z;
        let mut done = 0.0;
        let mut switches = 0;
        // Guards that fired without changing the mode: passed, ignored for this segment.
        let mut passed: u8 = 0;
        'modes: while done < span_total {
            let span = span_total - done;
            let sys = &self.active;
            // Between PWM edges the spans are short and irregular: a Taylor series beats
            // exp() there. Otherwise equal sub-steps with a cached propagator.
            let key = self.mode.index() + MODES.len() * self.stops.code();
            let (substeps, h, matrix) = if self.mode == Mode::Switched {
                (1, span, None)
            } else {
                let Propagator { substeps, h, ref matrix } = *self.cache.get(key, sys, span)?;
                (substeps, h, Some(matrix))
            };
            for k in 0..substeps {
                let settled = (key, h.to_bits(), z);
                let mut next = match matrix {
                    Some(_) if self.fixed_point == Some(settled) => z,
                    Some(matrix) => matrix * z,
                    None => taylor_propagate(sys, &z, h),
                };
                driver::project_onto(&self.params, &self.digital, &mut next, self.mode);
                // A stable system that returns to its state bit for bit is at rest: no guard
                // can have crossed on the way.
                if next == z {
                    if matrix.is_some() {
                        self.fixed_point = Some(settled);
                    }
                } else if may_cross(sys, &z, &next, h, passed) {
                    if let Some((tau, guard, at)) = locate_event(sys, &z, h, passed) {
                        Self::drive_cylinder(
                            sys,
                            &self.params.cylinder,
                            &mut self.cylinder,
                            &mut self.cylinder_memory,
                            &mut self.cylinder_rest,
                            (&z, &at, tau),
                            inputs,
                        )?;
                        z = at;
                        done += k as f64 * h + tau;
                        let before = self.mode;
                        let changed = self.settle(&mut z);
                        driver::count_switch(events, before, self.mode);
                        passed = if changed { 0 } else { passed | 1 << guard };
                        switches += 1;
                        if switches > MAX_EVENTS_PER_STEP {
                            return Err(format!(
                                "driver switched mode more than {MAX_EVENTS_PER_STEP} times in one step (chattering); step refused"
                            ));
                        }
                        continue 'modes;
                    }
                }
                Self::drive_cylinder(
                    sys,
                    &self.params.cylinder,
                    &mut self.cylinder,
                    &mut self.cylinder_memory,
                    &mut self.cylinder_rest,
                    (&z, &next, h),
                    inputs,
                )?;
                z = next;
            }
            break;
        }
        self.z = z;
        Ok(())
    }
}
