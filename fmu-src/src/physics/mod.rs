//! Physics core: coil driver, torque-motor coil and Moog 30 two-stage valve.
//!
//! # Why an exact piecewise-linear integrator
//! Between communication points the inputs are constant and, within one driver *mode*
//! (linear, at a rail, slewing, ...), the whole system is linear and time-invariant:
//! `z' = A_mode z` on an augmented state `z` that carries the constant inputs too. Its
//! exact solution is `z(t) = exp(A t) z(0)`, so we propagate with matrix exponentials:
//! no stability limit (the driver loop's 20 us pole costs nothing), no truncation error,
//! the same result at any communication step. Mode changes happen where a linear *guard*
//! `c . z` crosses zero (the output reaches a rail, leaves it, the error changes sign,
//! the slew limit binds); they are located to machine precision on the exact trajectory
//! (a Taylor polynomial of the guard inside a short window, then bisection).
//! The cost of a step without events is one 9x9 matrix-vector product per sub-step, with
//! propagators cached per (mode, sub-step); no heap allocation anywhere in `advance`.
//!
//! The H-bridge driver adds *time events* on an absolute clock (PWM edges, samples of its
//! digital PI loop, see [`hbridge`]); the step is cut at each, so switching instants are
//! exact and do not depend on the communication step.

mod events;
pub mod hbridge;
pub mod outer;

use crate::hydraulics::{self, CylinderParams, CylinderState, IntegratorMemory, SpoolPath};
use events::{locate_event, may_cross};
use hbridge::Digital;
use outer::{ControlMode, LoopParams, OuterLoop};

use crate::model::Reader;
use crate::variables::{vr, N_VARIABLES};
use nalgebra::{SMatrix, SVector};

/// Augmented state size: 6 physical states + 3 constants.
const N: usize = 9;
type Mat = SMatrix<f64, N, N>;
type Vector = SVector<f64, N>;

// Augmented state layout.
const I: usize = 0; // coil current [A]
const UI: usize = 1; // PI integrator output Ki*integral(e) [V]
const U: usize = 2; // driver output voltage [V]
const XF: usize = 3; // flapper displacement [m]
const VF: usize = 4; // flapper velocity [m/s]
const XS: usize = 5; // spool displacement [m]
const IREF: usize = 6; // current command (constant over a step) [A]
const VMAX: usize = 7; // rail voltage V_supply - V_drop (constant over a step) [V]
const ONE: usize = 8; // the constant 1, for affine terms

/// Coarse sub-steps keep |lambda|*h below this; guards are checked at their ends.
const THETA_COARSE: f64 = 6.0;
/// A step that switches mode more often than this is chattering: refuse it.
const MAX_EVENTS_PER_STEP: u32 = 1000;
/// Pieces this short (events right at a piece start) take an Euler step in the cylinder [s].
const TINY_PIECE: f64 = 1e-10;
/// A cylinder counts as at rest when it would drift less than 1e-10 of its scale in this time [s].
const REST_HORIZON: f64 = 1.0;
/// Largest |A h|_1 handed to exp() (see `PropagatorCache::get`).
const MAX_SCALED_NORM: f64 = 1e25;
/// Sub-steps per propagation at most (a 1e6 s step stays well under a second).
const MAX_SUBSTEPS: usize = 1 << 14;
/// Bounds the work of one doStep with the PWM driver (each instant costs ~0.3 us).
const MAX_TIME_EVENTS_PER_STEP: u64 = 10_000_000;
/// Driver guards (4) + flapper stop guards (2) + spool stop guards (2).
const MAX_GUARDS: usize = 8;
const CACHE_SLOTS: usize = 8;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriverKind {
    IdealCurrent,
    Voltage,
    OpampPi,
    Industrial,
    HBridge,
}

/// Driver modes. The op-amp driver moves between the last seven.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    Ideal,
    Voltage,
    Linear,
    /// At the + rail, error pushing further up: integrator stopped (anti-windup).
    HighFrozen,
    /// At the + rail, error pulling back: integrator running.
    HighIntegrating,
    LowFrozen,
    LowIntegrating,
    SlewUp,
    SlewDown,
    /// H-bridge: output held at +V or -V between switching instants.
    Switched,
}

const MODES: [Mode; 10] = [
    Mode::Ideal,
    Mode::Voltage,
    Mode::Linear,
    Mode::HighFrozen,
    Mode::HighIntegrating,
    Mode::LowFrozen,
    Mode::LowIntegrating,
    Mode::SlewUp,
    Mode::SlewDown,
    Mode::Switched,
];

impl Mode {
    fn index(self) -> usize {
        self as usize
    }
    fn at_rail(self) -> bool {
        matches!(
            self,
            Mode::HighFrozen | Mode::HighIntegrating | Mode::LowFrozen | Mode::LowIntegrating
        )
    }
}

/// Parameters in SI, read from the variable table's values.
#[derive(Clone, Copy, Debug)]
pub struct Params {
    pub driver: DriverKind,
    /// Gains, output drop and slew rate of the continuous PI loop of the chosen driver.
    pub kp: f64,
    pub ki: f64,
    pub v_drop: f64,
    pub slew_rate: f64,
    pub hbridge: hbridge::HBridgeParams,
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

impl Params {
    pub fn from_values(v: &[f64; N_VARIABLES]) -> Result<Params, String> {
        let driver = match v[vr::DRIVER] as i64 {
            0 => DriverKind::IdealCurrent,
            1 => DriverKind::Voltage,
            2 => DriverKind::OpampPi,
            3 => DriverKind::Industrial,
            4 => DriverKind::HBridge,
            other => return Err(format!("driver = {other} is not available (0 to 4)")),
        };
        // Single values were range-checked when set; these are the values as a whole.
        for (i, var) in crate::variables::VARIABLES.iter().enumerate() {
            if var.causality == crate::variables::Causality::Parameter {
                var.check(v[i])?;
            }
        }
        let industrial = driver == DriverKind::Industrial;
        let pick = |opamp: usize, ind: usize| if industrial { v[ind] } else { v[opamp] };
        Ok(Params {
            driver,
            kp: pick(vr::DRIVER_KP, vr::INDUSTRIAL_KP),
            ki: pick(vr::DRIVER_KI, vr::INDUSTRIAL_KI),
            // The op-amp's output stage drop; the other drivers reach the supply.
            v_drop: if driver == DriverKind::OpampPi { v[vr::DRIVER_V_DROP] } else { 0.0 },
            slew_rate: pick(vr::DRIVER_SLEW_RATE, vr::INDUSTRIAL_SLEW_RATE),
            hbridge: hbridge::HBridgeParams::from_values(v),
            loops: LoopParams::from_values(v, v[vr::VALVE_K3] * v[vr::VALVE_K1] / v[vr::VALVE_KW])?,
            cylinder: CylinderParams::from_lookup(
                |name| {
                    v[crate::variables::index_of(name)
                        .expect("cylinder parameter in the variable table")]
                },
                v[vr::VALVE_K3],
            )?,
            inductance: v[vr::COIL_L],
            r_total: v[vr::COIL_R] + v[vr::COIL_R_SENSE],
            k_backemf: v[vr::COIL_K_B],
            k1: v[vr::VALVE_K1],
            kf: v[vr::VALVE_KF],
            kw: v[vr::VALVE_KW],
            k2: v[vr::VALVE_K2],
            k3: v[vr::VALVE_K3],
            spool_area: v[vr::VALVE_A_S],
            zeta: v[vr::VALVE_ZETA],
            wn: 2.0 * std::f64::consts::PI * v[vr::VALVE_F_N],
            x_flapper_max: v[vr::VALVE_X_FLAPPER_MAX],
            x_spool_max: v[vr::VALVE_X_SPOOL_MAX],
        })
    }

    /// Rail voltage for a supply voltage (never negative).
    fn rail(&self, v_supply: f64) -> f64 {
        (v_supply - self.v_drop).max(0.0)
    }

    /// Row vector of u_lin = Kp*(i_ref - i) + ui.
    fn u_lin_row(&self) -> Vector {
        let mut r = Vector::zeros();
        r[IREF] = self.kp;
        r[I] = -self.kp;
        r[UI] = 1.0;
        r
    }
}

/// Row vector e_k.
fn unit(k: usize) -> Vector {
    let mut r = Vector::zeros();
    r[k] = 1.0;
    r
}

/// Row vector of the current error i_ref - i.
fn error_row() -> Vector {
    unit(IREF) - unit(I)
}

/// The linear system of one mode: dynamics, exit guards (leave when `guard . z > 0`),
/// and the sub-step lengths that keep |lambda|*h bounded.
#[derive(Clone, Copy)]
struct ModeSystem {
    a: Mat,
    guards: [Vector; MAX_GUARDS],
    /// d(guard)/dt = (A^T guard) . z
    guard_rates: [Vector; MAX_GUARDS],
    n_guards: usize,
    /// Spectral radius of `a` (1/s).
    radius: f64,
}

impl ModeSystem {
    /// A driver mode with the valve free of its travel stops.
    fn new(p: &Params, mode: Mode) -> ModeSystem {
        let a = dynamics(p, mode);
        let radius = spectral_radius(&a);
        let mut sys = ModeSystem {
            a,
            guards: [Vector::zeros(); MAX_GUARDS],
            guard_rates: [Vector::zeros(); MAX_GUARDS],
            n_guards: 0,
            radius,
        };
        for g in mode_guards(p, mode, &a) {
            sys.push_guard(g);
        }
        sys
    }

    fn push_guard(&mut self, guard: Vector) {
        self.guards[self.n_guards] = guard;
        self.guard_rates[self.n_guards] = self.a.transpose() * guard;
        self.n_guards += 1;
    }

    /// This driver mode with the valve's travel stops: a part at a stop is held there
    /// (inelastic), a free part gets guards for reaching its stops. No allocation.
    fn with_stops(&self, p: &Params, stops: Stops) -> ModeSystem {
        if p.x_flapper_max <= 0.0 && p.x_spool_max <= 0.0 {
            return *self;
        }
        let mut sys = *self;
        let flapper_accel = self.a.row(VF).transpose();
        if stops.flapper != 0 {
            sys.a.row_mut(XF).fill(0.0);
            sys.a.row_mut(VF).fill(0.0);
        }
        if stops.spool != 0 {
            sys.a.row_mut(XS).fill(0.0);
        }
        // The free system's spectral radius bounds the held one's well enough for sub-steps.
        sys.n_guards = 0;
        for k in 0..self.n_guards {
            sys.push_guard(self.guards[k]);
        }
        let one = unit(ONE);
        if p.x_flapper_max > 0.0 {
            match stops.flapper {
                0 => {
                    sys.push_guard(unit(XF) - p.x_flapper_max * one);
                    sys.push_guard(-unit(XF) - p.x_flapper_max * one);
                }
                // Leaves the stop when the torque pulls it back.
                side => sys.push_guard(-(side as f64) * flapper_accel),
            }
        }
        if p.x_spool_max > 0.0 {
            match stops.spool {
                0 => {
                    sys.push_guard(unit(XS) - p.x_spool_max * one);
                    sys.push_guard(-unit(XS) - p.x_spool_max * one);
                }
                // Leaves the stop when the flapper drives it back.
                side => sys.push_guard(-(side as f64) * unit(XF)),
            }
        }
        sys
    }

    /// Sub-steps keeping |lambda|*h below `theta`; capped so that a huge step stays bounded
    /// in time (the propagation itself is exact at any length, only event search coarsens).
    fn substeps(&self, span: f64, theta: f64) -> usize {
        ((span * self.radius / theta).ceil() as usize).clamp(1, MAX_SUBSTEPS)
    }
}

/// `z' = A z` for one mode.
fn dynamics(p: &Params, mode: Mode) -> Mat {
    let mut a = Mat::zeros();
    // Coil: L di/dt = u - R_total i - K_b dx_f/dt (the ideal source holds i at i_ref).
    if mode != Mode::Ideal {
        a[(I, I)] = -p.r_total / p.inductance;
        a[(I, U)] = 1.0 / p.inductance;
        a[(I, VF)] = -p.k_backemf / p.inductance;
    }
    // First stage: x_f'' + 2 zeta wn x_f' + wn^2 x_f = wn^2 (K1 i - Kw x_s) / Kf.
    let wn2 = p.wn * p.wn;
    a[(XF, VF)] = 1.0;
    a[(VF, XF)] = -wn2;
    a[(VF, VF)] = -2.0 * p.zeta * p.wn;
    a[(VF, I)] = wn2 * p.k1 / p.kf;
    a[(VF, XS)] = -wn2 * p.kw / p.kf;
    // Spool: x_s' = (K2 / A_s) x_f.
    a[(XS, XF)] = p.k2 / p.spool_area;
    // Driver.
    let integrate = p.ki * error_row();
    match mode {
        Mode::Linear => {
            a.set_row(UI, &integrate.transpose());
            // u = Kp e + ui  =>  u' = -Kp i' + Ki e
            let i_row = a.row(I).into_owned();
            a.set_row(U, &(-p.kp * i_row + integrate.transpose()));
        }
        Mode::HighIntegrating | Mode::LowIntegrating => a.set_row(UI, &integrate.transpose()),
        Mode::Switched => {}
        Mode::SlewUp | Mode::SlewDown => {
            a.set_row(UI, &integrate.transpose());
            a[(U, ONE)] = if mode == Mode::SlewUp { p.slew_rate } else { -p.slew_rate };
        }
        Mode::Ideal | Mode::Voltage | Mode::HighFrozen | Mode::LowFrozen => {}
    }
    a
}

/// Exit guards of a mode: the mode ends where any of them turns from <= 0 to > 0 (edge
/// triggered: a guard already positive when the mode starts is a condition that has been
/// passed, e.g. the + rail while slewing down from above it after a supply drop).
fn mode_guards(p: &Params, mode: Mode, a: &Mat) -> Vec<Vector> {
    let u = unit(U);
    let vmax = unit(VMAX);
    let u_lin = p.u_lin_row();
    let e = error_row();
    let slew = p.slew_rate * unit(ONE);
    match mode {
        Mode::Ideal | Mode::Voltage | Mode::Switched => vec![],
        Mode::Linear => {
            let du = a.row(U).transpose();
            vec![u - vmax, -u - vmax, du - slew, -du - slew]
        }
        Mode::HighFrozen => vec![vmax - u_lin, -e],
        Mode::HighIntegrating => vec![vmax - u_lin, e],
        Mode::LowFrozen => vec![u_lin + vmax, e],
        Mode::LowIntegrating => vec![u_lin + vmax, -e],
        // Slewing ends where u meets clamp(u_lin, -vmax, vmax).
        Mode::SlewUp => vec![u - vmax, u - u_lin, u + vmax],
        Mode::SlewDown => vec![-u - vmax, u_lin - u, vmax - u],
    }
}

/// Flapper and spool at a travel stop: -1 lower, 0 free, +1 upper.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stops {
    pub flapper: i8,
    pub spool: i8,
}

impl Stops {
    fn code(self) -> usize {
        ((self.flapper + 1) * 3 + self.spool + 1) as usize
    }
}

/// How a span is cut into equal sub-steps, with the sub-step propagator exp(A h).
#[derive(Clone, Copy)]
struct Propagator {
    substeps: usize,
    h: f64,
    matrix: Mat,
}

/// A few recently used propagators, keyed by system and span.
#[derive(Clone, Copy)]
struct PropagatorCache {
    keys: [(usize, u64); CACHE_SLOTS],
    values: [Propagator; CACHE_SLOTS],
    next: usize,
}

impl PropagatorCache {
    fn new() -> Self {
        let empty = Propagator { substeps: 0, h: 0.0, matrix: Mat::zeros() };
        PropagatorCache {
            keys: [(usize::MAX, 0); CACHE_SLOTS],
            values: [empty; CACHE_SLOTS],
            next: 0,
        }
    }

    /// `system` names the (mode, stops) pair; keys hold the bits of the span, so equal
    /// communication steps (the common case) hit exactly.
    fn get(&mut self, system: usize, sys: &ModeSystem, span: f64) -> Result<&Propagator, String> {
        let key = (system, span.to_bits());
        let slot = match self.keys.iter().position(|&k| k == key) {
            Some(slot) => slot,
            None => {
                let substeps = sys.substeps(span, THETA_COARSE);
                let h = span / substeps as f64;
                let scaled = sys.a * h;
                // exp() estimates norms of powers up to (A h)^10 and squares log2 of them
                // times: past ~1e30 they overflow and the squaring never ends. Physical
                // cases stay decades below MAX_SCALED_NORM (a 1e20 s step gives ~3e23).
                let norm = scaled
                    .column_iter()
                    .map(|c| c.iter().map(|x| x.abs()).sum::<f64>())
                    .fold(0.0, f64::max);
                if norm.is_nan() || norm > MAX_SCALED_NORM {
                    return Err(format!(
                        "a sub-step of {h} s with these parameters is beyond exact propagation (|A h| = {norm:e}); step refused"
                    ));
                }
                let slot = self.next;
                self.keys[slot] = key;
                self.values[slot] = Propagator { substeps, h, matrix: scaled.exp() };
                self.next = (slot + 1) % CACHE_SLOTS;
                slot
            }
        };
        Ok(&self.values[slot])
    }
}

/// Mode changes inside one step, for event logging.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepEvents {
    pub rail_entered: u32,
    pub rail_left: u32,
}

#[derive(Clone)]
pub struct Physics {
    params: Params,
    systems: [ModeSystem; MODES.len()],
    z: Vector,
    mode: Mode,
    stops: Stops,
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

/// Inputs held over one step.
#[derive(Clone, Copy)]
struct Inputs {
    i_ref: f64,
    rail: f64,
    p_supply: f64,
    f_ext: f64,
    /// Reference of the outer loop (Q_ref or x_ref).
    reference: f64,
}

impl Inputs {
    fn new(p: &Params, v: &[f64; N_VARIABLES]) -> Inputs {
        let reference = match p.loops.mode {
            ControlMode::Flow => v[vr::Q_REF],
            ControlMode::Position => v[vr::X_REF],
            ControlMode::Current => 0.0,
        };
        Inputs {
            i_ref: v[vr::I_REF],
            rail: p.rail(v[vr::V_SUPPLY]),
            p_supply: v[vr::P_SUPPLY],
            f_ext: v[vr::F_EXT],
            reference,
        }
    }
}

impl Default for Physics {
    fn default() -> Self {
        Physics::start(&crate::variables::start_values(), 0.0).expect("start values are valid")
    }
}

impl Physics {
    /// Builds the mode systems and puts the model in equilibrium for the current inputs at
    /// `start_time` (the sampling clock of a digital driver counts from time 0).
    pub fn start(values: &[f64; N_VARIABLES], start_time: f64) -> Result<Physics, String> {
        let params = Params::from_values(values)?;
        let systems = MODES.map(|m| ModeSystem::new(&params, m));
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
            stops: Stops::default(),
            active: systems[Mode::Linear.index()],
            digital: Digital::default(),
            outer: OuterLoop::default(),
            cylinder: CylinderState::default(),
            cylinder_memory: IntegratorMemory::default(),
            cylinder_rest: None,
            fixed_point: None,
            p_supply: values[vr::P_SUPPLY],
            cache: PropagatorCache::new(),
        };
        let inputs = Inputs::new(&params, values);
        physics.outer = OuterLoop::at_start(&params.loops, inputs.reference, start_time);
        physics.cylinder = hydraulics::equilibrium(&params.cylinder, inputs.p_supply, inputs.f_ext);
        let i_cmd = physics.current_command(&inputs);
        physics.equilibrium(i_cmd, inputs.rail, start_time);
        Ok(physics)
    }

    /// The coil current command: the input, or the outer loop's output.
    fn current_command(&self, inputs: &Inputs) -> f64 {
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
        z[I] = if p.driver == DriverKind::IdealCurrent { i_ref } else { u / p.r_total };
        // An unsaturated PI holds e = 0 with ui = u; a saturated one sits at the rail with
        // its integrator stopped at the rail value.
        z[UI] = u;
        // Torque balance K1 i = Kw x_s + Kf x_f with the flapper centred, unless the spool
        // sits at its stop and the flapper carries the rest.
        let free_spool = p.k1 * z[I] / p.kw;
        z[XS] = if p.x_spool_max > 0.0 {
            free_spool.clamp(-p.x_spool_max, p.x_spool_max)
        } else {
            free_spool
        };
        let flapper = (p.k1 * z[I] - p.kw * z[XS]) / p.kf;
        z[XF] = if p.x_flapper_max > 0.0 {
            flapper.clamp(-p.x_flapper_max, p.x_flapper_max)
        } else {
            flapper
        };
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
        let p = &self.params;
        // An inelastic impact: at its limit the flapper loses any outward velocity.
        let reach = p.x_flapper_max * (1.0 - 1e-12);
        if p.x_flapper_max > 0.0
            && (z[XF] >= reach && z[VF] > 0.0 || z[XF] <= -reach && z[VF] < 0.0)
        {
            z[XF] = z[XF].clamp(-p.x_flapper_max, p.x_flapper_max);
            z[VF] = 0.0;
        }
        let stops = self.consistent_stops(z);
        if stops.flapper != 0 {
            z[XF] = stops.flapper as f64 * p.x_flapper_max;
            z[VF] = 0.0;
        }
        if stops.spool != 0 {
            z[XS] = stops.spool as f64 * p.x_spool_max;
        }
        let mode = self.consistent_mode(z);
        self.project(z, mode);
        let changed = (mode, stops) != (self.mode, self.stops);
        if changed {
            (self.mode, self.stops) = (mode, stops);
            self.active = self.systems[mode.index()].with_stops(&self.params, stops);
        }
        changed
    }

    /// Which travel stops hold the valve at `z`: a part at its limit stays there while it is
    /// driven outwards (flapper: its free acceleration; spool: the flapper's sign).
    fn consistent_stops(&self, z: &Vector) -> Stops {
        let p = &self.params;
        let mut at_rest = *z;
        at_rest[VF] = 0.0;
        let flapper_accel = self.systems[0].a.row(VF).transpose().dot(&at_rest);
        let side = |x: f64, limit: f64, drive: f64| -> i8 {
            let reach = limit * (1.0 - 1e-12);
            if limit <= 0.0 {
                0
            } else if x >= reach && drive > 0.0 {
                1
            } else if x <= -reach && drive < 0.0 {
                -1
            } else {
                0
            }
        };
        Stops {
            flapper: side(z[XF], p.x_flapper_max, flapper_accel),
            spool: side(z[XS], p.x_spool_max, z[XF]),
        }
    }

    pub fn write_outputs(&self, values: &mut [f64; N_VARIABLES]) {
        let z = &self.z;
        values[vr::I_COIL] = z[I];
        values[vr::U_DRIVER] = z[U];
        values[vr::DRIVER_SATURATED] = self.saturated() as u8 as f64;
        values[vr::X_FLAPPER] = z[XF];
        values[vr::X_SPOOL] = z[XS];
        values[vr::Q_VALVE] = self.params.k3 * z[XS];
        let c = hydraulics::outputs(&self.params.cylinder, &self.cylinder, z[XS], self.p_supply);
        values[vr::Q_A] = c.q_a;
        values[vr::Q_B] = c.q_b;
        values[vr::P_A] = c.p_a;
        values[vr::P_B] = c.p_b;
        values[vr::X_PISTON] = c.x_piston;
        values[vr::V_PISTON] = c.v_piston;
        values[vr::F_HYDRAULIC] = c.f_hydraulic;
    }

    fn saturated(&self) -> bool {
        match self.mode {
            Mode::Voltage => (self.params.r_total * self.z[IREF]).abs() > self.z[VMAX],
            Mode::Switched => self.digital.saturated(self.z[VMAX]),
            m => m.at_rail(),
        }
    }

    /// Applies the inputs held over the coming step: the algebraic drivers follow them at once.
    fn apply_inputs(&self, z: &mut Vector, i_ref: f64, rail: f64) {
        let p = &self.params;
        z[IREF] = i_ref;
        z[VMAX] = rail;
        match p.driver {
            // The ideal source's voltage is what holds the current (its L di/dt impulse aside).
            DriverKind::IdealCurrent => z[U] = p.r_total * i_ref,
            DriverKind::Voltage
            | DriverKind::HBridge
            | DriverKind::OpampPi
            | DriverKind::Industrial => {}
        }
    }

    /// The mode the op-amp driver is in at state `z`; on a boundary the direction of
    /// motion decides, so a mode is never entered only to be left at once.
    fn consistent_mode(&self, z: &Vector) -> Mode {
        let p = &self.params;
        match p.driver {
            DriverKind::IdealCurrent => return Mode::Ideal,
            DriverKind::Voltage => return Mode::Voltage,
            DriverKind::HBridge => return Mode::Switched,
            DriverKind::OpampPi | DriverKind::Industrial => {}
        }
        let vmax = z[VMAX];
        let e = z[IREF] - z[I];
        let u_lin = p.u_lin_row().dot(z);
        let target = u_lin.clamp(-vmax, vmax);
        let tol = 1e-9 * (1.0 + vmax);
        if z[U] < target - tol {
            return Mode::SlewUp;
        }
        if z[U] > target + tol {
            return Mode::SlewDown;
        }
        let high = if e > 0.0 { Mode::HighFrozen } else { Mode::HighIntegrating };
        let low = if e < 0.0 { Mode::LowFrozen } else { Mode::LowIntegrating };
        let rate_in = |mode: Mode| {
            let mut at = *z;
            at[U] = target;
            p.u_lin_row().dot(&(self.systems[mode.index()].a * at))
        };
        if u_lin > vmax + tol || (u_lin >= vmax - tol && rate_in(high) > 0.0) {
            return high;
        }
        if u_lin < -vmax - tol || (u_lin <= -vmax + tol && rate_in(low) < 0.0) {
            return low;
        }
        let mut at = *z;
        at[U] = u_lin;
        let du = self.systems[Mode::Linear.index()].a.row(U).transpose().dot(&at);
        if du > p.slew_rate {
            Mode::SlewUp
        } else if du < -p.slew_rate {
            Mode::SlewDown
        } else {
            Mode::Linear
        }
    }

    fn project(&self, z: &mut Vector, mode: Mode) {
        project_onto(&self.params, &self.digital, z, mode);
    }

    /// Advances from `t_start` by `step` seconds with the inputs in `values` held constant.
    /// On error the state is left as it was.
    pub fn advance(
        &mut self,
        values: &[f64; N_VARIABLES],
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
        let result = self.advance_inner(values, t_start, step);
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
        values: &[f64; N_VARIABLES],
        t_start: f64,
        step: f64,
    ) -> Result<StepEvents, String> {
        let mut events = StepEvents::default();
        let inputs = Inputs::new(&self.params, values);
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
                self.flow(segment_end - t, &inputs, &mut events)?;
                t = segment_end;
            }
            if !fire {
                break;
            }
            if t_loop <= t_bridge {
                // The outer loop samples first, so a bridge sample at the same instant sees its command.
                let measured = match p.loops.mode {
                    ControlMode::Flow => p.k3 * self.z[XS],
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
    fn follow_command(&mut self, inputs: &Inputs, events: &mut StepEvents) {
        let i_cmd = self.current_command(inputs);
        if self.z[IREF] != i_cmd || self.z[VMAX] != inputs.rail {
            let mut z = self.z;
            self.apply_inputs(&mut z, i_cmd, inputs.rail);
            let before = self.mode;
            self.settle(&mut z);
            count_switch(events, before, self.mode);
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
        inputs: &Inputs,
    ) -> Result<(), String> {
        if (z1[XS] - z0[XS]).abs() <= 1e-13 * z0[XS].abs().max(1e-9) {
            let key = [z0[XS].to_bits(), inputs.p_supply.to_bits(), inputs.f_ext.to_bits()];
            if *rest == Some(key) {
                return Ok(());
            }
            // At rest means an equilibrium, whatever the piece length: drifting less than
            // 1e-10 of its scale in a second (a short piece must not make motion look still).
            let f =
                hydraulics::derivatives(params, cylinder, z0[XS], inputs.p_supply, inputs.f_ext);
            if f.iter()
                .zip(hydraulics::STATE_SCALE.iter())
                .all(|(d, scale)| d.abs() * REST_HORIZON <= 1e-10 * scale)
            {
                *rest = Some(key);
                return Ok(());
            }
        }
        *rest = None;
        if h <= TINY_PIECE {
            // Far below every cylinder time constant (|lambda| h < 2e-5): one Euler step.
            let f = hydraulics::derivatives(
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
        hydraulics::advance_with_rate(
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
    fn flow(
        &mut self,
        span_total: f64,
        inputs: &Inputs,
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
                project_onto(&self.params, &self.digital, &mut next, self.mode);
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
                        count_switch(events, before, self.mode);
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

    pub fn write_bytes(&self, out: &mut Vec<u8>) {
        out.push(self.mode.index() as u8);
        out.push(self.stops.code() as u8);
        for x in self.z.iter() {
            out.extend_from_slice(&x.to_le_bytes());
        }
        self.digital.write_bytes(out);
        self.outer.write_bytes(out);
        for x in self.cylinder.to_array().iter().chain(self.cylinder_memory.to_array().iter()) {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }

    pub fn read_bytes(values: &[f64; N_VARIABLES], r: &mut Reader) -> Result<Physics, String> {
        let mode_index = r.u8()? as usize;
        let mode = *MODES
            .get(mode_index)
            .ok_or_else(|| format!("state has unknown driver mode {mode_index}"))?;
        let code = r.u8()? as i8;
        if code > 8 {
            return Err(format!("state has unknown valve stop code {code}"));
        }
        let stops = Stops { flapper: code / 3 - 1, spool: code % 3 - 1 };
        let mut physics = Physics::start(values, 0.0)
            .map_err(|e| format!("state holds invalid parameters: {e}"))?;
        for k in 0..N {
            physics.z[k] = r.f64()?;
        }
        physics.digital = Digital::read_bytes(r)?;
        physics.outer = OuterLoop::read_bytes(r)?;
        let mut cylinder = [0.0; hydraulics::N_STATES];
        for x in cylinder.iter_mut() {
            *x = r.f64()?;
        }
        let mut memory = [0.0; 4];
        for x in memory.iter_mut() {
            *x = r.f64()?;
        }
        if !cylinder.iter().chain(memory.iter()).all(|x| x.is_finite()) {
            return Err("state holds non-finite cylinder values".into());
        }
        physics.cylinder = CylinderState::from_array(&cylinder);
        physics.cylinder_memory = IntegratorMemory::from_array(&memory);
        if !physics.z.iter().all(|x| x.is_finite()) {
            return Err("state holds non-finite values".into());
        }
        (physics.mode, physics.stops) = (mode, stops);
        physics.active = physics.systems[mode.index()].with_stops(&physics.params, stops);
        Ok(physics)
    }
}

fn count_switch(events: &mut StepEvents, from: Mode, to: Mode) {
    if !from.at_rail() && to.at_rail() {
        events.rail_entered += 1;
    }
    if from.at_rail() && !to.at_rail() {
        events.rail_left += 1;
    }
}

/// exp(A t) z by its Taylor series, in pieces with |lambda| h <= 1, each summed until
/// (|lambda| h)^k / k! is below rounding.
fn taylor_propagate(sys: &ModeSystem, z0: &Vector, span: f64) -> Vector {
    let pieces = sys.substeps(span, 1.0);
    let h = span / pieces as f64;
    let scale = sys.radius * h;
    let mut terms = 1;
    let mut bound = 1.0;
    while terms < events::TAYLOR_TERMS && bound > 1e-18 {
        bound *= scale / terms as f64;
        terms += 1;
    }
    let mut z = *z0;
    for _ in 0..pieces {
        let mut term = z;
        let mut sum = z;
        for k in 1..terms {
            term = sys.a * term * (h / k as f64);
            sum += term;
        }
        z = sum;
    }
    z
}

/// Largest |eigenvalue| of `a`, from a Schur decomposition with bounded iterations; a
/// matrix it cannot decompose (absurdly scaled parameters) gets its infinity norm, an
/// upper bound. Never loops unbounded.
fn spectral_radius(a: &Mat) -> f64 {
    if !a.iter().all(|x| x.is_finite()) {
        return f64::INFINITY;
    }
    match nalgebra::linalg::Schur::try_new(*a, f64::EPSILON, 500) {
        Some(schur) => schur.complex_eigenvalues().iter().map(|l| l.norm()).fold(0.0, f64::max),
        None => a.row_iter().map(|r| r.iter().map(|x| x.abs()).sum::<f64>()).fold(0.0, f64::max),
    }
}

/// Puts the algebraic part of the state on the mode's manifold (after every propagation
/// too, so held values stay exact rather than within rounding of exp()).
fn project_onto(p: &Params, digital: &Digital, z: &mut Vector, mode: Mode) {
    match mode {
        Mode::Ideal => z[I] = z[IREF],
        Mode::Voltage => z[U] = (p.r_total * z[IREF]).clamp(-z[VMAX], z[VMAX]),
        Mode::Switched => z[U] = digital.output(z[VMAX]),
        Mode::Linear => z[U] = p.u_lin_row().dot(z),
        Mode::HighFrozen | Mode::HighIntegrating => z[U] = z[VMAX],
        Mode::LowFrozen | Mode::LowIntegrating => z[U] = -z[VMAX],
        Mode::SlewUp | Mode::SlewDown => {}
    }
}
