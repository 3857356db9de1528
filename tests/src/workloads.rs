//! The benchmark workloads: what a legged robot asks of the actuator. Each is a driver and
//! control-mode setup plus input signals sampled at the communication points (held over
//! the step, as a co-simulation master does).

use std::f64::consts::PI;

use ehsv_actuator::variables::vr;

/// Driver enumeration values (the `driver` variable).
const OPAMP_PI: i64 = 2;
pub const HBRIDGE_PID: i64 = 4;
/// `control_mode` values.
pub const CURRENT: i64 = 0;
const FLOW: i64 = 1;
const POSITION: i64 = 2;

/// The inputs a workload drives, in this order, every communication step.
pub const INPUTS: [usize; 4] = [vr::I_REF, vr::Q_REF, vr::X_REF, vr::F_EXT];
/// The outputs recorded after every step and compared with the reference.
pub const OUTPUTS: [usize; 12] = [
    vr::I_COIL,
    vr::U_DRIVER,
    vr::X_FLAPPER,
    vr::X_SPOOL,
    vr::Q_VALVE,
    vr::Q_A,
    vr::Q_B,
    vr::P_A,
    vr::P_B,
    vr::X_PISTON,
    vr::V_PISTON,
    vr::F_HYDRAULIC,
];
/// The column of u_driver in [`OUTPUTS`].
pub const U_DRIVER_COLUMN: usize = 1;
const _: () = assert!(OUTPUTS[U_DRIVER_COLUMN] == vr::U_DRIVER);
pub const OUTPUT_NAMES: [&str; 12] = [
    "i_coil",
    "u_driver",
    "x_flapper",
    "x_spool",
    "Q_valve",
    "Q_A",
    "Q_B",
    "p_A",
    "p_B",
    "x_piston",
    "v_piston",
    "F_hydr",
];

/// Current command amplitude of the current-mode waves (A).
pub const I_AMPLITUDE: f64 = 5e-3;
/// Gait: period (stance + swing) (s), position amplitude (m) at 1/period, second harmonic (m).
const GAIT_PERIOD: f64 = 0.5;
const GAIT_AMPLITUDE: f64 = 15e-3;
const GAIT_HARMONIC: f64 = 3e-3;
/// Touchdown load during stance: half-sine peak (N) (pushing the rod in) and stance time (s).
const TOUCHDOWN_PEAK: f64 = 1500.0;
const STANCE: f64 = 0.25;
/// Standing: the position the leg holds (m) and its share of the body's weight (N, pushing
/// the rod in), both from t = 0.
const STAND_POSITION: f64 = 5e-3;
const STAND_LOAD: f64 = 750.0;
/// Flow loop square wave: amplitude (m3/s) and frequency (Hz).
const Q_AMPLITUDE: f64 = 2e-5;
const Q_FREQUENCY: f64 = 20.0;
/// Legs of the quadruped.
pub const LEGS: usize = 12;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Signal {
    /// Every input 0 from the equilibrium at rest: nothing moves, every step changes nothing.
    Idle,
    /// Current command 0 -> 5 mA at t = 0, then held: the piston runs to its end stop and rests.
    StepToRest,
    /// +-5 mA square wave (starts positive) at this frequency (Hz).
    Square(f64),
    /// 5 mA sine at this frequency (Hz).
    Sine(f64),
    /// Position loop on the gait reference with touchdown loads, this time shift (s).
    Gait(f64),
    /// Flow loop on a Q_ref square wave.
    FlowSquare,
    /// Position loop holding a leg's standing position under its share of the weight.
    Stand,
}

#[derive(Clone, Debug)]
pub struct Workload {
    pub name: String,
    pub driver: i64,
    pub control_mode: i64,
    pub v_supply: f64,
    /// One signal per instance stepped in lock-step (one entry: a single actuator).
    pub legs: Vec<Signal>,
    /// `solver.rtol` of every instance (None: the FMU's default).
    pub solver_rtol: Option<f64>,
    /// `solver.h_internal` of every instance (None: the FMU's default; fixed_cost reads it).
    pub h_internal: Option<f64>,
    /// `solver.method` of every instance ([`EXACT`] or [`FIXED_COST`]).
    pub solver_method: i64,
}

/// `solver.method`'s codes.
pub const EXACT: i64 = 0;
pub const FIXED_COST: i64 = 1;

/// Square wave of unit amplitude, +1 over the first half period.
fn square(f: f64, t: f64) -> f64 {
    if (2.0 * f * t).floor() as i64 % 2 == 0 {
        1.0
    } else {
        -1.0
    }
}

impl Signal {
    /// `[i_ref, Q_ref, x_ref, F_ext]` held over the step that starts at `t`.
    pub fn inputs(self, t: f64) -> [f64; 4] {
        match self {
            Signal::Idle => [0.0; 4],
            Signal::StepToRest => [I_AMPLITUDE, 0.0, 0.0, 0.0],
            Signal::Square(f) => [I_AMPLITUDE * square(f, t), 0.0, 0.0, 0.0],
            Signal::Sine(f) => [I_AMPLITUDE * (2.0 * PI * f * t).sin(), 0.0, 0.0, 0.0],
            Signal::FlowSquare => [0.0, Q_AMPLITUDE * square(Q_FREQUENCY, t), 0.0, 0.0],
            Signal::Stand => [0.0, 0.0, STAND_POSITION, -STAND_LOAD],
            Signal::Gait(shift) => {
                let t = t + shift;
                let w = 2.0 * PI / GAIT_PERIOD;
                let x_ref =
                    GAIT_AMPLITUDE * (w * t).sin() + GAIT_HARMONIC * (2.0 * w * t + 0.5).sin();
                let phase = t.rem_euclid(GAIT_PERIOD);
                let load = if phase < STANCE {
                    -TOUCHDOWN_PEAK * (PI * phase / STANCE).sin()
                } else {
                    0.0
                };
                [0.0, 0.0, x_ref, load]
            }
        }
    }
}

impl Workload {
    fn single(name: &str, driver: i64, control_mode: i64, v_supply: f64, s: Signal) -> Workload {
        Workload {
            name: name.into(),
            driver,
            control_mode,
            v_supply,
            legs: vec![s],
            solver_rtol: None,
            h_internal: None,
            solver_method: EXACT,
        }
    }

    /// Enumerations to set before initialisation.
    pub fn enums(&self) -> [(usize, i64); 3] {
        [
            (vr::DRIVER, self.driver),
            (vr::CONTROL_MODE, self.control_mode),
            (vr::SOLVER_METHOD, self.solver_method),
        ]
    }

    /// The same workload through `method`, named after it unless exact.
    pub fn with_method(&self, method: i64) -> Workload {
        let name =
            if method == FIXED_COST { format!("{}/fc", self.name) } else { self.name.clone() };
        Workload { name, solver_method: method, ..self.clone() }
    }

    /// Reals to set before initialisation (the inputs start at 0: every signal starts as a
    /// step at t = 0 from the equilibrium at rest).
    pub fn reals(&self) -> Vec<(usize, f64)> {
        let mut reals = vec![(vr::V_SUPPLY, self.v_supply)];
        reals.extend(self.solver_rtol.map(|rtol| (vr::SOLVER_RTOL, rtol)));
        reals.extend(self.h_internal.map(|h| (vr::SOLVER_H_INTERNAL, h)));
        reals
    }

    pub fn is_quadruped(&self) -> bool {
        self.legs.len() > 1
    }
}

/// Every workload of the benchmark, in table order.
pub fn all() -> Vec<Workload> {
    let mut w = vec![
        Workload::single("idle", OPAMP_PI, CURRENT, 72.0, Signal::Idle),
        Workload::single("step_to_rest", OPAMP_PI, CURRENT, 72.0, Signal::StepToRest),
    ];
    for f in [2.0, 20.0, 100.0] {
        w.push(Workload::single(
            &format!("square_{f}Hz"),
            OPAMP_PI,
            CURRENT,
            72.0,
            Signal::Square(f),
        ));
    }
    for f in [2.0, 20.0, 100.0] {
        w.push(Workload::single(&format!("sine_{f}Hz"), OPAMP_PI, CURRENT, 72.0, Signal::Sine(f)));
    }
    w.push(Workload::single("gait_position", OPAMP_PI, POSITION, 72.0, Signal::Gait(0.0)));
    w.push(Workload::single("stand_position", OPAMP_PI, POSITION, 72.0, Signal::Stand));
    w.push(Workload::single("flow_square", OPAMP_PI, FLOW, 72.0, Signal::FlowSquare));
    w.push(Workload::single(
        "hbridge_square_100Hz",
        HBRIDGE_PID,
        CURRENT,
        12.0,
        Signal::Square(100.0),
    ));
    w.push(Workload {
        name: format!("quadruped_{LEGS}x_gait"),
        driver: OPAMP_PI,
        control_mode: POSITION,
        v_supply: 72.0,
        legs: (0..LEGS).map(|l| Signal::Gait(l as f64 * GAIT_PERIOD / LEGS as f64)).collect(),
        solver_rtol: None,
        h_internal: None,
        solver_method: EXACT,
    });
    w
}

/// A short description of every workload for the report.
pub const DESCRIPTION: &str = "\
idle: opamp_pi 72 V, current mode, every input 0 (at rest throughout: the cost of the FMI calls alone)
step_to_rest: opamp_pi 72 V, i_ref 0 -> 5 mA at t = 0 (piston to its end stop, then at rest)
square_*/sine_*: opamp_pi 72 V, current mode, i_ref +-5 mA square / 5 mA sine
gait_position: opamp_pi 72 V, position loop, x_ref = 15 mm sin(2 pi 2 t) + 3 mm sin(2 pi 4 t + 0.5),
  F_ext = -1.5 kN half-sine during each 0.25 s stance, 0 during the 0.25 s swing
stand_position: opamp_pi 72 V, position loop, x_ref = 5 mm and F_ext = -750 N from t = 0 (a leg
  standing: to its position, then holding it under the load)
flow_square: opamp_pi 72 V, flow loop, Q_ref +-2e-5 m3/s square at 20 Hz
hbridge_square_100Hz: hbridge_pid 12 V, i_ref +-5 mA square at 100 Hz (PWM edges while moving)
quadruped_12x_gait: 12 instances on the gait, leg l shifted by l/12 of the period, lock-step";
