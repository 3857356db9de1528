//! The whole model as one explicit right-hand side `dy = f(y, held inputs)`, built from the
//! component functions that [`crate::Physics`] itself integrates: the coil and valve rows of
//! the mode matrices (`coil::coil_rows`, `valve::valve_rows`), the PI coefficients of the
//! driver and `cylinder::derivatives`. It is there for an independent integration of the same
//! equations by a general ODE solver (the benchmark's CVODE peer, reference runs), so
//! that the model is transcribed once.
//!
//! Where the exact integrator switches between driver modes, a smooth ODE cannot: here the PI
//! driver's output is a state that tracks its clamped target `clamp(Kp e + ui, +-rail)` at
//! the rate [`TRACKING`] (10 ps behind), limited to +-slew rate, and the integrator stops
//! while the output rests on a rail with the error pushing further (anti-windup). The
//! valve travel stops are not represented ([`WholeModel::new`] refuses them), nor the
//! ideal current source (an algebraic current).
//!
//! The digital parts (H-bridge PWM and PI, outer PID) are the physics' own, behind
//! [`Sampled`]: they change the held inputs at their time events.

use crate::components::coefficients::Coefficients;
use crate::components::cylinder::{self, CylinderState};
use crate::components::driver::Mode;
use crate::components::hbridge::HBridgeState;
use crate::components::metering_ports::AnyLap;
use crate::components::outer_loop::OuterLoop;
use crate::components::{coil, valve};
use crate::numerics::augmented_state::{self, Mat, Vector};
use crate::numerics::rosenbrock::STATE_SCALE;
use crate::params::{ControlMode, DriverKind, Outputs, Params};

/// State size: coil current, PI integrator output, driver output, flapper position and
/// velocity, spool, chamber pressures A and B, piston position and velocity.
pub const NY: usize = 10;
pub const I: usize = 0;
pub const UI: usize = 1;
pub const U: usize = 2;
pub const XF: usize = 3;
pub const VF: usize = 4;
pub const XS: usize = 5;
pub const PA: usize = 6;
pub const PB: usize = 7;
pub const X: usize = 8;
pub const V: usize = 9;

/// Rate at which the PI driver's output follows its clamped target (1/s). Its lag is a
/// model error no solver tolerance removes, so it is fast enough to put that error below
/// the tolerances the peer runs at, and no faster: a stiffer tracking makes a solver's
/// Newton iteration fail at tight tolerances.
pub const TRACKING: f64 = 1e11;

/// Inputs and discrete outputs held between time events.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RhsInputs {
    /// Coil current command (i_ref, or the outer loop's output) (A).
    pub i_cmd: f64,
    /// Driver rail V_supply - V_drop (V).
    pub rail: f64,
    /// H-bridge output between switching instants (V) (other drivers: unused).
    pub u_bridge: f64,
    pub p_supply: f64,
    pub f_ext: f64,
}

/// The model's coefficients in the form the right-hand side uses (derived once).
#[derive(Clone, Copy, Debug)]
pub struct WholeModel {
    c: Coefficients,
    /// Coil and valve rows of `z' = A z` (augmented state of [`augmented_state`]); driver rows zero.
    coil_valve: Mat,
}

impl WholeModel {
    /// For `params`; refuses what the smooth form does not represent.
    pub fn new(params: &Params) -> Result<WholeModel, String> {
        let mut c = Coefficients::new(params)?;
        // The equations themselves, whatever the method: the H-bridge's every switching (the
        // fixed-cost method's periods' means are its own approximation).
        c.hbridge.pwm_mean = false;
        if valve::has_stops(&c) {
            return Err("the whole-model right-hand side has no valve travel stops".into());
        }
        if c.driver == DriverKind::IdealCurrent {
            return Err("the whole-model right-hand side has no ideal current source".into());
        }
        let mut coil_valve = Mat::zeros();
        coil::coil_rows(&c, Mode::Linear, &mut coil_valve);
        valve::valve_rows(&c, &mut coil_valve);
        Ok(WholeModel { c, coil_valve })
    }

    pub fn driver(&self) -> DriverKind {
        self.c.driver
    }

    pub fn control_mode(&self) -> ControlMode {
        self.c.loops.mode
    }

    /// The driver rail for a supply voltage (V).
    pub fn rail(&self, v_supply: f64) -> f64 {
        crate::components::driver::rail(&self.c, v_supply)
    }

    /// Coil resistance plus sense resistor (Ohm).
    pub fn r_total(&self) -> f64 {
        self.c.r_total
    }

    /// The driver's output voltage at `y`.
    pub fn driver_voltage(&self, held: &RhsInputs, y: &[f64; NY]) -> f64 {
        match self.c.driver {
            DriverKind::HBridge => held.u_bridge,
            DriverKind::Voltage => (self.c.r_total * held.i_cmd).clamp(-held.rail, held.rail),
            _ => y[U],
        }
    }

    /// `dy = f(y)` for the held inputs.
    pub fn rhs(&self, held: &RhsInputs, y: &[f64; NY], dy: &mut [f64; NY]) {
        let c = &self.c;
        let u = self.driver_voltage(held, y);
        let mut z = Vector::zeros();
        z[augmented_state::I] = y[I];
        z[augmented_state::UI] = y[UI];
        z[augmented_state::U] = u;
        z[augmented_state::XF] = y[XF];
        z[augmented_state::VF] = y[VF];
        z[augmented_state::XS] = y[XS];
        z[augmented_state::I_CMD] = held.i_cmd;
        z[augmented_state::RAIL] = held.rail;
        z[augmented_state::ONE] = 1.0;
        let dz = self.coil_valve * z;
        dy[I] = dz[augmented_state::I];
        dy[XF] = dz[augmented_state::XF];
        dy[VF] = dz[augmented_state::VF];
        dy[XS] = dz[augmented_state::XS];
        if matches!(c.driver, DriverKind::OpampPi | DriverKind::Industrial) {
            let e = held.i_cmd - y[I];
            let u_lin = c.kp * e + y[UI];
            let pull = TRACKING * (u_lin.clamp(-held.rail, held.rail) - y[U]);
            let slewing = pull.abs() > c.slew_rate;
            let frozen =
                !slewing && ((u_lin >= held.rail && e > 0.0) || (u_lin <= -held.rail && e < 0.0));
            dy[UI] = if frozen { 0.0 } else { c.ki * e };
            dy[U] = pull.clamp(-c.slew_rate, c.slew_rate);
        } else {
            dy[UI] = 0.0;
            dy[U] = 0.0;
        }
        let cyl = CylinderState { p_a: y[PA], p_b: y[PB], x: y[X], v: y[V] };
        let d =
            cylinder::derivatives::<AnyLap>(&c.cylinder, &cyl, y[XS], held.p_supply, held.f_ext);
        dy[PA..].copy_from_slice(&d);
    }

    /// Absolute error scales of the states (a solver's atol is `rtol` times these): the
    /// cylinder's are the physics' own Rosenbrock weights; the valve's follow 10 mA of current.
    pub fn error_scales(&self) -> [f64; NY] {
        let c = &self.c;
        let i = 1e-2;
        let xf = c.valve.k1 * i / c.valve.kf;
        let [pa, pb, x, v] = STATE_SCALE;
        [i, 100.0, 100.0, xf, xf * c.wn, c.valve.k1 * i / c.valve.kw, pa, pb, x, v]
    }

    /// The outputs at `y`.
    pub fn outputs(&self, held: &RhsInputs, y: &[f64; NY]) -> Outputs {
        let c = &self.c;
        let cyl = CylinderState { p_a: y[PA], p_b: y[PB], x: y[X], v: y[V] };
        let u = self.driver_voltage(held, y);
        let mut out = Outputs {
            i_coil: y[I],
            u_driver: u,
            driver_saturated: u.abs() >= held.rail,
            x_flapper: y[XF],
            x_spool: y[XS],
            q_valve: valve::no_load_flow(c, y[XS]),
            ..Outputs::default()
        };
        cylinder::write_outputs(&c.cylinder, &cyl, y[XS], held.p_supply, &mut out);
        out
    }
}

/// The digital parts (H-bridge PWM and digital PI, outer flow/position PID): the physics' own.
#[derive(Clone, Copy, Debug)]
pub struct Sampled {
    hbridge: HBridgeState,
    outer: OuterLoop,
}

impl Sampled {
    /// Settled at `start_time` on the outer loop's `reference`, the bridge holding the
    /// equilibrium voltage `R i_coil` on average.
    pub fn at_start(
        model: &WholeModel,
        i_coil: f64,
        rail: f64,
        reference: f64,
        start: f64,
    ) -> Self {
        let c = &model.c;
        let hbridge = if c.driver == DriverKind::HBridge {
            let u = (c.r_total * i_coil).clamp(-rail, rail);
            HBridgeState::at_equilibrium(&c.hbridge, u, u, rail, start)
        } else {
            HBridgeState::default()
        };
        Sampled { hbridge, outer: OuterLoop::at_start(&c.loops, reference, start) }
    }

    /// Time of the next sampling or switching instant (infinite without digital parts).
    pub fn next_event(&self, model: &WholeModel) -> f64 {
        let c = &model.c;
        self.hbridge.next_event(&c.hbridge).min(self.outer.next_event(&c.loops))
    }

    /// The coil current command for the input `i_ref`.
    pub fn command(&self, model: &WholeModel, i_ref: f64) -> f64 {
        if model.c.loops.mode == ControlMode::Current {
            i_ref
        } else {
            self.outer.command
        }
    }

    /// The bridge output for `rail` (V).
    pub fn bridge_output(&self, model: &WholeModel, rail: f64) -> f64 {
        self.hbridge.output(&model.c.hbridge, rail)
    }

    /// Handles the next instant at state `y` (the outer loop first at equal times, as
    /// [`crate::Physics`] does) and updates `held`; `reference` is Q_ref or x_ref, `i_ref`
    /// the input.
    pub fn fire(
        &mut self,
        model: &WholeModel,
        y: &[f64; NY],
        reference: f64,
        i_ref: f64,
        held: &mut RhsInputs,
    ) {
        let c = &model.c;
        if self.outer.next_event(&c.loops) <= self.hbridge.next_event(&c.hbridge) {
            let measured = match c.loops.mode {
                ControlMode::Flow => valve::no_load_flow(c, y[XS]),
                _ => y[X],
            };
            self.outer.sample(&c.loops, reference, measured);
            held.i_cmd = self.command(model, i_ref);
        } else {
            self.hbridge.fire(&c.hbridge, y[I], held.i_cmd, c.r_total, held.rail);
            held.u_bridge = self.hbridge.output(&c.hbridge, held.rail);
        }
    }
}
