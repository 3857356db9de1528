//! The typed boundary of the physics: parameters, inputs and outputs in SI, each a plain
//! field (whoever embeds the physics fills and reads them).

/// The Moog 30's rated coil current (A): the valve's flow gain is specified up to it, the
/// outer loops limit their command to it by default, and a current command beyond it is
/// reported with a warning.
pub const VALVE_RATED_CURRENT: f64 = 0.01;

/// Coil driver topology.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriverKind {
    IdealCurrent,
    Voltage,
    OpampPi,
    Industrial,
    HBridge,
}

impl DriverKind {
    /// Every topology, in the order of their codes.
    pub const ALL: [DriverKind; 5] = [
        DriverKind::IdealCurrent,
        DriverKind::Voltage,
        DriverKind::OpampPi,
        DriverKind::Industrial,
        DriverKind::HBridge,
    ];
}

/// How the rod meets its load.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RodPort {
    /// The model moves the load mass under an external force.
    Force,
    /// The host (a multibody simulator) owns the moving mass and prescribes the rod's
    /// motion; the model returns the force on the rod.
    Motion,
}

impl RodPort {
    /// Every port, in the order of their codes.
    pub const ALL: [RodPort; 2] = [RodPort::Force, RodPort::Motion];
}

/// Which command drives the coil current.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControlMode {
    Current,
    Flow,
    Position,
}

impl ControlMode {
    /// Every command source, in the order of their codes.
    pub const ALL: [ControlMode; 3] =
        [ControlMode::Current, ControlMode::Flow, ControlMode::Position];
}

/// The integrator the physics steps through between time events (the seam of
/// `integrator.rs`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolverMethod {
    /// Driver, coil and valve exactly (matrix exponentials, state events located to
    /// rounding), the cylinder by an adaptive Rosenbrock method along the exact spool path:
    /// results that do not depend on the communication step; work that follows what
    /// happens in it.
    Exact,
    /// Work fixed by the step size for real-time rigs: driver, coil and valve by
    /// precomputed propagators over internal steps of at most `solver_h_internal`, a mode
    /// change placed by one interpolation, the cylinder by one linearly implicit trapezoidal
    /// step per internal step, cut at end-stop contact and cavitation (docs/solvers.md).
    FixedCost,
}

impl SolverMethod {
    /// Every method, in the order of their codes.
    pub const ALL: [SolverMethod; 2] = [SolverMethod::Exact, SolverMethod::FixedCost];
}

/// A continuous PI current loop with a slew-rate limited output (op-amp or industrial).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PiDriverParams {
    /// Proportional gain, V/A.
    pub kp: f64,
    /// Integral gain, V/(A s).
    pub ki: f64,
    /// Output slew-rate limit, V/s.
    pub slew_rate: f64,
}

/// H-bridge with PWM and a digital PI current loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HBridgeParams {
    pub f_pwm: f64,
    pub f_sample: f64,
    pub kp: f64,
    pub ki: f64,
    /// Adds (R + R_sense) i_cmd to the PI output.
    pub feedforward: bool,
    /// Takes each PWM period by its mean voltage (`duty * V`) instead of its two switchings:
    /// what `solver.method = fixed_cost` does (no variable of its own: the coefficients set
    /// it from the method, whatever it holds here). The coil current's ripple at the PWM
    /// frequency is then not resolved.
    pub pwm_mean: bool,
}

/// Torque-motor coil.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoilParams {
    /// Apparent inductance, H.
    pub inductance: f64,
    /// Coil resistance, Ohm.
    pub resistance: f64,
    /// Current-sense resistor in series, Ohm.
    pub r_sense: f64,
    /// Back-EMF constant on the flapper velocity, V s/m.
    pub k_backemf: f64,
}

/// How the valve's figures are given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValveParameterization {
    /// The internal gains of the Moog 30 model (K1, Kf, Kw, K2, K3, A_s, zeta, f_n).
    Gains,
    /// A datasheet's figures: rated flow and current, the -90 degree and -3 dB
    /// frequencies, null leakage and pressure gain; the gains follow from them
    /// (`components::valve_datasheet`).
    Datasheet,
}

impl ValveParameterization {
    /// Every form, in the order of their codes.
    pub const ALL: [ValveParameterization; 2] =
        [ValveParameterization::Gains, ValveParameterization::Datasheet];
}

/// A valve as its datasheet states it (read when the valve's parameterization is
/// [`ValveParameterization::Datasheet`]; the null leakage, its reference supply and the
/// pressure gain also describe the lap in either form).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValveDatasheet {
    /// No-load flow at the rated current and the rated total drop (m3/s).
    pub q_rated: f64,
    /// Rated current (A).
    pub i_rated: f64,
    /// Where the flow lags the current by 90 degrees (Hz).
    pub f_90: f64,
    /// Where the flow's amplitude is 3 dB down (Hz); 0: not given.
    pub f_3db: f64,
    /// Null leakage, supply to tank, spool centred and ports blocked, at `p_leak_ref`
    /// (m3/s); 0: not given.
    pub q_leak_null: f64,
    /// Supply pressure above tank at which the leakage and pressure gain are stated (Pa).
    pub p_leak_ref: f64,
    /// Blocked-port pressure gain d(p_A - p_B)/di at null, at `p_leak_ref` (Pa/A); 0: what
    /// the leakage gives.
    pub pressure_gain: f64,
}

/// Moog 30 two-stage valve: first stage, spool, travel stops and metering ports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ValveParams {
    /// How the valve is given: its gains, or its datasheet (then the gains below are
    /// derived at the start, `components::valve_datasheet`).
    pub parameterization: ValveParameterization,
    pub k1: f64,
    pub kf: f64,
    pub kw: f64,
    pub k2: f64,
    pub k3: f64,
    pub spool_area: f64,
    pub zeta: f64,
    /// Natural frequency of the first stage, Hz.
    pub f_n: f64,
    /// Travel limits, m (0: none).
    pub x_flapper_max: f64,
    pub x_spool_max: f64,
    /// Total rated pressure drop at which the no-load flow is K3 x_s, Pa.
    pub dp_rated: f64,
    /// Port drop below which the orifice law is regularised, Pa.
    pub dp_laminar: f64,
    /// The spool's lap at null (m): > 0 underlap (null leakage, a finite pressure gain),
    /// < 0 overlap (a dead band), 0 critically centred.
    pub lap: f64,
    /// The datasheet's figures.
    pub datasheet: ValveDatasheet,
    /// The first stage's pilot flow, supply to tank, at `datasheet.p_leak_ref` (m3/s): not
    /// a parameter of its own, derived from the datasheet's null leakage (0 in gains form).
    pub q_pilot: f64,
}

/// Cylinder, load, leakage and fluid, in SI (pressures gauge).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CylinderLoadParams {
    /// Piston (bore) diameter (m).
    pub bore: f64,
    /// Rod diameter (m); the rod is on the B side.
    pub rod: f64,
    /// Full stroke (m); x runs from -stroke/2 to +stroke/2.
    pub stroke: f64,
    /// How the rod meets its load.
    pub port: RodPort,
    /// Moving mass: piston, rod and load (kg); with the motion port the host's.
    pub mass: f64,
    /// Effective bulk modulus of oil, hoses and walls (Pa).
    pub beta: f64,
    /// Dead volume per chamber at its end of stroke (m3).
    pub v_dead: f64,
    pub b_viscous: f64,
    pub f_coulomb: f64,
    /// Breakaway force (peak of the Stribeck curve) (N).
    pub f_static: f64,
    pub v_stribeck: f64,
    /// Velocity scale of the tanh that replaces sign(v) in the Coulomb/Stribeck term (m/s).
    pub v_friction_smooth: f64,
    pub k_endstop: f64,
    pub c_endstop: f64,
    /// Internal (cross-piston) leakage A -> B per pressure difference (m3/(s.Pa)).
    pub c_leak: f64,
    /// External leakage from each chamber to the drain (at p_tank) (m3/(s.Pa)).
    pub c_leak_external: f64,
    pub p_tank: f64,
    /// Lowest chamber pressure (gauge) (Pa).
    pub p_cavitation: f64,
    /// Band above the floor over which an emptying chamber's bulk modulus fades out (Pa).
    pub dp_cavitation_band: f64,
    /// Relief valves (chamber to tank): cracking pressure above tank, 0 = none (Pa).
    pub relief_p_crack: f64,
    /// Rise above cracking at which a relief valve passes `relief_q_rated` (Pa).
    pub relief_dp_override: f64,
    /// Rated flow of a relief valve (m3/s).
    pub relief_q_rated: f64,
}

/// Gains (Kp, Ki, Kd) of a PID.
pub type PidGains = [f64; 3];

/// Outer flow and position loops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OuterLoopParams {
    pub f_sample: f64,
    /// Limit of the current command, A.
    pub i_max: f64,
    pub flow: PidGains,
    pub position: PidGains,
}

/// Every parameter of the model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    pub driver: DriverKind,
    pub control_mode: ControlMode,
    pub opamp: PiDriverParams,
    /// Op-amp output stage drop: its output saturates at +-(V_supply - V_drop), V.
    pub opamp_v_drop: f64,
    pub industrial: PiDriverParams,
    pub hbridge: HBridgeParams,
    pub coil: CoilParams,
    pub valve: ValveParams,
    pub cylinder: CylinderLoadParams,
    pub outer_loop: OuterLoopParams,
    /// Relative tolerance of the cylinder's integrator.
    pub solver_rtol: f64,
    /// The integrator the physics steps through.
    pub solver_method: SolverMethod,
    /// The longest internal step of [`SolverMethod::FixedCost`] (s).
    pub solver_h_internal: f64,
}

/// Inputs, held constant over a communication step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Inputs {
    pub i_ref: f64,
    pub v_supply: f64,
    pub p_supply: f64,
    pub f_ext: f64,
    pub q_ref: f64,
    pub x_ref: f64,
    /// With the motion port: the rod's position (m, 0 = mid-stroke), velocity (m/s) and
    /// acceleration (m/s2, the host's input derivative of `v_rod`; 0 if it gives none) at
    /// the communication point.
    pub x_rod: f64,
    pub v_rod: f64,
    pub a_rod: f64,
}

/// Outputs at the current state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Outputs {
    pub i_coil: f64,
    pub u_driver: f64,
    pub driver_saturated: bool,
    pub x_flapper: f64,
    pub x_spool: f64,
    pub q_valve: f64,
    pub q_a: f64,
    pub q_b: f64,
    pub p_a: f64,
    pub p_b: f64,
    pub x_piston: f64,
    pub v_piston: f64,
    pub f_hydraulic: f64,
    /// The flow drawn from the supply: the metering edges' and the pilot's (m3/s).
    pub q_supply: f64,
    /// The force of the actuator on the rod in +x (hydraulic force, friction and end stops):
    /// its mean over the last step (N).
    pub f_rod: f64,
    /// Its local stiffness and damping at the step's end (N/m, N s/m).
    pub df_rod_dx: f64,
    pub df_rod_dv: f64,
}

impl Params {
    /// The device of the paper: the op-amp PI driver on the Moog 30 valve and a 16 mm
    /// cylinder with a 5 kg load, driven by the current command: the values a run starts
    /// from unless it is told otherwise.
    pub const PAPER: Params = Params {
        driver: DriverKind::OpampPi,
        control_mode: ControlMode::Current,
        opamp: PiDriverParams { kp: 1.6e5, ki: 5.0e7, slew_rate: 2.0e7 },
        opamp_v_drop: 0.0,
        industrial: PiDriverParams { kp: 2500.0, ki: 781250.0, slew_rate: 1.0e6 },
        hbridge: HBridgeParams {
            f_pwm: 20000.0,
            f_sample: 20000.0,
            kp: 9000.0,
            ki: 2812500.0,
            feedforward: true,
            pwm_mean: false,
        },
        coil: CoilParams { inductance: 3.2, resistance: 1000.0, r_sense: 0.0, k_backemf: 0.0 },
        valve: ValveParams {
            parameterization: ValveParameterization::Gains,
            k1: 2.82462,
            kf: 511.545,
            kw: 74.2853,
            k2: 0.0967740,
            k3: 0.664515,
            spool_area: 1.67742e-5,
            zeta: 0.4,
            f_n: 814.0,
            x_flapper_max: 0.0,
            x_spool_max: 0.0,
            dp_rated: 6.8948e6,
            dp_laminar: 1.0e5,
            lap: 0.0,
            // The same valve's figures (its small-signal response, worked out from the
            // gains above to rounding): in datasheet form it is the paper's valve.
            datasheet: ValveDatasheet {
                q_rated: 2.5267480366909735e-4,
                i_rated: VALVE_RATED_CURRENT,
                f_90: 368.3369021874452,
                f_3db: 160.95738161940366,
                q_leak_null: 0.0,
                p_leak_ref: 2.1e7,
                pressure_gain: 0.0,
            },
            q_pilot: 0.0,
        },
        cylinder: CylinderLoadParams {
            bore: 0.016,
            rod: 0.010,
            stroke: 0.080,
            port: RodPort::Force,
            mass: 5.0,
            beta: 1.0e9,
            v_dead: 2.0e-6,
            b_viscous: 200.0,
            f_coulomb: 20.0,
            f_static: 30.0,
            v_stribeck: 0.01,
            v_friction_smooth: 1.0e-4,
            k_endstop: 1.0e8,
            c_endstop: 1.0e4,
            c_leak: 0.0,
            c_leak_external: 0.0,
            p_tank: 0.0,
            p_cavitation: -0.9e5,
            dp_cavitation_band: 5.0e4,
            relief_p_crack: 8.0e6,
            relief_dp_override: 1.0e6,
            relief_q_rated: 4.0e-4,
        },
        outer_loop: OuterLoopParams {
            f_sample: 20000.0,
            i_max: VALVE_RATED_CURRENT,
            flow: [2.0, 0.0, 0.0],
            position: [1.0, 0.0, 0.0],
        },
        solver_rtol: 1.0e-7,
        solver_method: SolverMethod::Exact,
        solver_h_internal: 5e-5,
    };
}

impl Inputs {
    /// The inputs a run starts with: the paper's 72 V driver supply and 1000 psi hydraulic
    /// supply, no command, no load.
    pub const PAPER: Inputs = Inputs {
        i_ref: 0.0,
        v_supply: 72.0,
        p_supply: 6.8948e6,
        f_ext: 0.0,
        q_ref: 0.0,
        x_ref: 0.0,
        x_rod: 0.0,
        v_rod: 0.0,
        a_rod: 0.0,
    };
}
