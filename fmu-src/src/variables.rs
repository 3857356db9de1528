//! The one table of model variables.
//!
//! Everything that names a variable reads it from here: both modelDescription.xml
//! files, get/set by value reference in the C API, parameter validation and the
//! README's variable list. The value reference of a variable is its index in
//! [`VARIABLES`]; new variables are appended so existing references never move.

/// FMI causality (the subset this FMU uses).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Causality {
    Independent,
    Parameter,
    Input,
    Output,
}

/// FMI variability (the subset this FMU uses).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variability {
    Fixed,
    Tunable,
    Discrete,
    Continuous,
}

/// Value type; enumerations name one of [`ENUMERATIONS`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VarType {
    Real,
    Boolean,
    Enumeration(&'static str),
}

/// `initial` attribute: start values are exact for inputs and parameters,
/// calculated for outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Initial {
    Exact,
    Calculated,
}

/// Why [`Variable::check`] refuses a value.
#[derive(Clone, Copy)]
enum ValueFault {
    NotFinite,
    NotBoolean,
    NotInteger,
    OutOfRange,
}

#[derive(Clone, Copy, Debug)]
pub struct Variable {
    pub name: &'static str,
    pub causality: Causality,
    pub variability: Variability,
    pub ty: VarType,
    /// Name of a unit in [`crate::units::UNITS`]; `None` for Booleans, enums and dimensionless ratios.
    pub unit: Option<&'static str>,
    pub display_unit: Option<&'static str>,
    pub start: f64,
    pub min: Option<f64>,
    pub max: Option<f64>,
    /// `min` itself is not allowed (a strictly positive quantity).
    pub min_exclusive: bool,
    pub description: &'static str,
}

impl Variable {
    pub const fn value_reference(&self, index: usize) -> u32 {
        index as u32
    }
    pub fn initial(&self) -> Option<Initial> {
        match self.causality {
            Causality::Independent | Causality::Input => None,
            Causality::Parameter => Some(Initial::Exact),
            Causality::Output => Some(Initial::Calculated),
        }
    }
    /// Outputs and the independent variable have no start value in the XML.
    pub fn has_start(&self) -> bool {
        matches!(self.causality, Causality::Parameter | Causality::Input)
    }
    /// Checks a value against type and range; the message names the variable and the allowed range.
    #[inline]
    pub fn check(&self, value: f64) -> Result<(), String> {
        match self.fault(value) {
            None => Ok(()),
            Some(fault) => Err(self.refusal(value, fault)),
        }
    }

    /// What is wrong with `value` for this variable, if anything.
    #[inline]
    fn fault(&self, value: f64) -> Option<ValueFault> {
        if !value.is_finite() {
            return Some(ValueFault::NotFinite);
        }
        match self.ty {
            VarType::Boolean if value != 0.0 && value != 1.0 => {
                return Some(ValueFault::NotBoolean)
            }
            VarType::Enumeration(_) if value.fract() != 0.0 => return Some(ValueFault::NotInteger),
            _ => {}
        }
        let below = match self.min {
            Some(min) if self.min_exclusive => value <= min,
            Some(min) => value < min,
            None => false,
        };
        let above = matches!(self.max, Some(max) if value > max);
        (below || above).then_some(ValueFault::OutOfRange)
    }

    /// The message for a value [`Variable::fault`] refuses. Out of line: setters call `check`
    /// on every value, and the formatting would weigh on each call.
    #[cold]
    #[inline(never)]
    fn refusal(&self, value: f64, fault: ValueFault) -> String {
        let why = match fault {
            ValueFault::NotFinite => "the value must be finite".to_string(),
            ValueFault::NotBoolean => "a Boolean is 0 or 1".to_string(),
            ValueFault::NotInteger => "an enumeration value is an integer".to_string(),
            ValueFault::OutOfRange => format!("allowed range is {}", self.range_text()),
        };
        format!("{} = {value} rejected: {why}", self.name)
    }
    pub fn range_text(&self) -> String {
        let lo = match self.min {
            Some(m) if self.min_exclusive => format!("({m}"),
            Some(m) => format!("[{m}"),
            None => "(-inf".to_string(),
        };
        let hi = match self.max {
            Some(m) => format!("{m}]"),
            None => "+inf)".to_string(),
        };
        format!("{lo}, {hi}")
    }
}

/// An FMI enumeration type: (integer value, item name, description).
pub struct Enumeration {
    pub name: &'static str,
    pub description: &'static str,
    pub items: &'static [(i64, &'static str, &'static str)],
}

pub const ENUMERATIONS: &[Enumeration] = &[
    Enumeration {
        name: "DriverType",
        description: "Coil driver topology",
        items: &[
            (0, "ideal_current", "coil current equals the command exactly (paper eq. 3)"),
            (1, "voltage", "open-loop voltage R_total*i_cmd clamped at the rails (paper eq. 4)"),
            (2, "opamp_pi", "high-voltage op-amp PI current driver (the paper's proposal)"),
            (3, "industrial", "off-the-shelf linear current amplifier (My-502 like)"),
            (4, "hbridge_pid", "H-bridge with PWM and a digital PI current loop"),
        ],
    },
    Enumeration {
        name: "ControlMode",
        description: "Which command drives the coil current",
        items: &[
            (0, "current", "i_ref is the current command"),
            (1, "flow", "flow PID on Q_valve follows Q_ref"),
            (2, "position", "position PID on the piston follows x_ref"),
        ],
    },
];

use Causality::*;
use Variability::*;

const fn real(
    name: &'static str,
    causality: Causality,
    variability: Variability,
    unit: Option<&'static str>,
    display_unit: Option<&'static str>,
    start: f64,
    description: &'static str,
) -> Variable {
    Variable {
        name,
        causality,
        variability,
        ty: VarType::Real,
        unit,
        display_unit,
        start,
        min: None,
        max: None,
        min_exclusive: false,
        description,
    }
}

const fn input(
    name: &'static str,
    unit: &'static str,
    display: Option<&'static str>,
    start: f64,
    description: &'static str,
) -> Variable {
    real(name, Input, Continuous, Some(unit), display, start, description)
}

const fn output(
    name: &'static str,
    unit: &'static str,
    display: Option<&'static str>,
    description: &'static str,
) -> Variable {
    real(name, Output, Continuous, Some(unit), display, 0.0, description)
}

/// A fixed parameter (changeable before initialisation only).
const fn param(
    name: &'static str,
    unit: Option<&'static str>,
    start: f64,
    description: &'static str,
) -> Variable {
    real(name, Parameter, Fixed, unit, None, start, description)
}

impl Variable {
    const fn range(mut self, min: Option<f64>, max: Option<f64>) -> Self {
        self.min = min;
        self.max = max;
        self
    }
    /// Strictly positive.
    const fn positive(mut self) -> Self {
        self.min = Some(0.0);
        self.min_exclusive = true;
        self
    }
    const fn non_negative(mut self) -> Self {
        self.min = Some(0.0);
        self
    }
    /// A parameter that may change during a run (Step Mode); it takes effect at the next
    /// communication point.
    const fn tunable(mut self) -> Self {
        self.variability = Tunable;
        self
    }
}

/// The Moog 30's rated coil current (A): the valve's flow gain is specified up to it, the
/// outer loops limit their command to it by default, and a current command beyond it is
/// reported with a warning (logStatusWarning).
pub const VALVE_RATED_CURRENT: f64 = 0.01;

/// Longest stroke (m) of a servo cylinder this model describes (`cylinder.stroke`'s maximum,
/// which bounds `x_ref`).
const MAX_STROKE: f64 = 1.0;

/// Declares the table and, from the same rows, one constant per variable in [`vr`]: the
/// value reference of a variable is its row, so no reference is ever numbered by hand.
macro_rules! variable_table {
    ($($constant:ident => $row:expr,)*) => {
        /// Row numbers, counted by the compiler.
        #[allow(non_camel_case_types, clippy::upper_case_acronyms)]
        #[repr(usize)]
        enum Row {
            $($constant,)*
        }

        /// Index (= value reference) of every variable, generated from the table, so code
        /// names variables, never numbers.
        pub mod vr {
            $(pub const $constant: usize = super::Row::$constant as usize;)*
        }

        /// Constant names in row order (the test checks each is derived from its variable's name).
        #[cfg(test)]
        const CONSTANT_NAMES: [&str; N_VARIABLES] = [$(stringify!($constant),)*];

        pub const N_VARIABLES: usize = [$(stringify!($constant),)*].len();

        pub static VARIABLES: [Variable; N_VARIABLES] = [$($row,)*];
    };
}

variable_table! {
    TIME => Variable {
        name: "time",
        causality: Independent,
        variability: Continuous,
        ty: VarType::Real,
        unit: Some("s"),
        display_unit: None,
        start: 0.0,
        min: None,
        max: None,
        min_exclusive: false,
        description: "Simulation time",
    },
    // Inputs
    // Every input has a physical range; a value beyond it is refused with Error. i_ref:
    // ten times the valve's rated current (10 mA; above it a warning): the torque motor
    // saturates magnetically long before, and a larger command is a unit mistake (5 mA
    // typed as 5 A), not a current this valve can carry.
    I_REF => input("i_ref", "A", Some("mA"), 0.0, "Coil current command (used when control_mode = current); rated current 10 mA")
        .range(Some(-10.0 * VALVE_RATED_CURRENT), Some(10.0 * VALVE_RATED_CURRENT)),
    // Up to 1 kV: far above any coil driver's supply (the paper's is 72 V).
    V_SUPPLY => input("V_supply", "V", None, 72.0, "Driver supply: the output rails are at +V_supply and -V_supply")
        .range(Some(0.0), Some(1000.0)),
    // Outputs
    I_COIL => output("i_coil", "A", Some("mA"), "Torque-motor coil current"),
    U_DRIVER => output("u_driver", "V", None, "Driver output voltage across coil and sense resistor"),
    DRIVER_SATURATED => Variable {
        name: "driver_saturated",
        causality: Output,
        variability: Discrete,
        ty: VarType::Boolean,
        unit: None,
        display_unit: None,
        start: 0.0,
        min: None,
        max: None,
        min_exclusive: false,
        description: "The driver output is at a supply rail",
    },
    X_FLAPPER => output("x_flapper", "m", Some("um"), "Armature/flapper displacement at the nozzles"),
    X_SPOOL => output("x_spool", "m", Some("mm"), "Main spool displacement"),
    Q_VALVE => output("Q_valve", "m3/s", Some("L/min"), "No-load valve flow K3*x_spool (the paper's hydraulic-amplifier load flow)"),
    // Parameters are fixed (set before initialisation ends) unless marked `.tunable()`:
    // tunable are what a user tunes or varies during a run (controller gains and limits,
    // friction, load mass, leakage): settable in Step Mode, they take effect at the next
    // communication point, from the state reached (the physics is rebuilt at the set).
    // Fixed stay the structure (driver, control_mode, H-bridge feed-forward), the sampling
    // clocks (they count instants from t = 0: a new rate would move the next instant), and
    // the hardware: coil and valve constants and travel stops, cylinder geometry, end
    // stops, fluid and circuit (a different value is a different device, and a travel or
    // geometry change could leave the state outside the new limits).
    // Structural parameters
    DRIVER => Variable {
        name: "driver",
        causality: Parameter,
        variability: Fixed,
        ty: VarType::Enumeration("DriverType"),
        unit: None,
        display_unit: None,
        start: 2.0,
        min: Some(0.0),
        max: Some(4.0),
        min_exclusive: false,
        description: "Coil driver: 0 ideal_current, 1 voltage, 2 opamp_pi, 3 industrial, 4 hbridge_pid",
    },
    CONTROL_MODE => Variable {
        name: "control_mode",
        causality: Parameter,
        variability: Fixed,
        ty: VarType::Enumeration("ControlMode"),
        unit: None,
        display_unit: None,
        start: 0.0,
        min: Some(0.0),
        max: Some(2.0),
        min_exclusive: false,
        description: "Command source: 0 current (i_ref), 1 flow loop (Q_ref), 2 position loop (x_ref)",
    },
    // Driver
    DRIVER_KP => param("driver.Kp", Some("V/A"), 1.6e5, "Op-amp PI proportional gain (= G*R_s; the paper's linear analysis writes R_s)")
        .non_negative()
        .tunable(),
    DRIVER_KI => param("driver.Ki", Some("V/(A.s)"), 5.0e7, "Op-amp PI integral gain (= G*R_s/(R_f*C_f)); default Ki/Kp = R/L cancels the coil pole")
        .non_negative()
        .tunable(),
    DRIVER_V_DROP => param("driver.V_drop", Some("V"), 0.0, "Output stage drop: the output saturates at +-(V_supply - V_drop)")
        .non_negative()
        .tunable(),
    DRIVER_SLEW_RATE => param("driver.slew_rate", Some("V/s"), 2.0e7, "Op-amp output slew-rate limit (20 V/us)").positive().tunable(),
    // Coil
    COIL_L => param("coil.L", Some("H"), 3.2, "Torque-motor coil (apparent) inductance").positive(),
    COIL_R => param("coil.R", Some("Ohm"), 1000.0, "Torque-motor coil resistance").positive(),
    COIL_R_SENSE => param("coil.R_sense", Some("Ohm"), 0.0, "Current-sense resistor in series with the coil").non_negative(),
    COIL_K_B => param("coil.K_b", Some("V.s/m"), 0.0, "Back-EMF constant on the flapper velocity (0: already in the apparent inductance)")
        .non_negative(),
    // Valve (Moog 30 linear model)
    VALVE_K1 => param("valve.K1", Some("N.m/A"), 2.82462, "Torque-motor gain (0.025 in-lb/mA)").positive(),
    VALVE_KF => param("valve.Kf", Some("N.m/m"), 511.545, "Net stiffness on flapper/armature (115 in-lb/in)").positive(),
    VALVE_KW => param("valve.Kw", Some("N.m/m"), 74.2853, "Feedback wire stiffness (16.7 in-lb/in)").positive(),
    VALVE_K2 => param("valve.K2", Some("m2/s"), 0.0967740, "Hydraulic amplifier flow gain (150 in3/s/in)").positive(),
    VALVE_K3 => param("valve.K3", Some("m2/s"), 0.664515, "Spool/bushing flow gain (1030 in3/s/in)").positive(),
    VALVE_A_S => param("valve.A_s", Some("m2"), 1.67742e-5, "Spool end area (0.026 in2)").positive(),
    VALVE_ZETA => param("valve.zeta", None, 0.4, "Damping ratio of the first stage").range(Some(0.0), Some(10.0)),
    VALVE_F_N => param("valve.f_n", Some("Hz"), 814.0, "Natural frequency of the first stage").positive(),
    // Industrial linear current amplifier (driver 3): a PI loop like the op-amp driver's
    // but with the slow gains of an off-the-shelf unit. L/Kp = 1.28 ms gives the My-502's
    // 5 ms (2 %) settling; Ki/Kp = R/L cancels the coil pole.
    INDUSTRIAL_KP => param("industrial.Kp", Some("V/A"), 2500.0, "Industrial amplifier proportional gain").non_negative().tunable(),
    INDUSTRIAL_KI => param("industrial.Ki", Some("V/(A.s)"), 781250.0, "Industrial amplifier integral gain").non_negative().tunable(),
    INDUSTRIAL_SLEW_RATE => param("industrial.slew_rate", Some("V/s"), 1.0e6, "Industrial amplifier output slew-rate limit (1 V/us)").positive().tunable(),
    // H-bridge with PWM and a digital PI current loop (driver 4).
    HBRIDGE_F_PWM => param("hbridge.f_pwm", Some("Hz"), 20000.0, "PWM switching frequency (bipolar, centre-aligned)")
        .positive()
        .range(Some(0.0), Some(1.0e6)),
    HBRIDGE_F_SAMPLE => param("hbridge.f_sample", Some("Hz"), 20000.0, "Sampling rate of the digital PI current loop (one-sample computation delay)")
        .positive()
        .range(Some(0.0), Some(1.0e6)),
    // With feed-forward and Ki/Kp = R/L, a 5 mA step at 12 V runs at 100 % duty to ~4.2 mA
    // (the supply limits the slope, as on the paper's bench), then the loop closes with
    // L/Kp = 0.36 ms: 1.9 ms settling of the period-averaged current.
    HBRIDGE_KP => param("hbridge.Kp", Some("V/A"), 9000.0, "Digital PI proportional gain").non_negative().tunable(),
    HBRIDGE_KI => param("hbridge.Ki", Some("V/(A.s)"), 2812500.0, "Digital PI integral gain").non_negative().tunable(),
    HBRIDGE_FEEDFORWARD => Variable {
        name: "hbridge.feedforward",
        causality: Parameter,
        variability: Fixed,
        ty: VarType::Boolean,
        unit: None,
        display_unit: None,
        start: 1.0,
        min: None,
        max: None,
        min_exclusive: false,
        description: "Add the feed-forward voltage (R + R_sense)*i_cmd to the digital PI output",
    },
    // Optional valve travel limits (the paper's linear model has none).
    VALVE_X_FLAPPER_MAX => param("valve.x_flapper_max", Some("m"), 0.0, "Flapper travel limit at the nozzles, inelastic stop (0: none)").non_negative(),
    VALVE_X_SPOOL_MAX => param("valve.x_spool_max", Some("m"), 0.0, "Spool travel limit, inelastic stop (0: none)").non_negative(),
    // Cylinder side: inputs and outputs.
    // Up to 1000 bar: beyond the pressure rating of industrial servo hydraulics (the
    // Moog 30 is rated for 3000 psi, 207 bar).
    P_SUPPLY => input("p_supply", "Pa", Some("bar"), 6.8948e6, "Hydraulic supply pressure, gauge (1000 psi: the valve's rated drop, so the no-load flow is K3*x_spool)")
        .range(Some(0.0), Some(1.0e8)),
    // +-100 kN: 72 times the default stall force p_S*A_A (1.39 kN) and 5 times the largest
    // stall force the ranges allow at this bore (1000 bar on 16 mm: 20 kN); a larger force
    // crushes the oil column of any actuator this model describes.
    F_EXT => input("F_ext", "N", None, 0.0, "External force on the rod, positive in the direction of +x (extension)")
        .range(Some(-1.0e5), Some(1.0e5)),
    // +-1e-3 m3/s (60 L/min): four times the valve's rated flow (2.53e-4 m3/s, 15 L/min at
    // 10 mA), which the outer loop cannot exceed with its default limit.
    Q_REF => input("Q_ref", "m3/s", Some("L/min"), 0.0, "Valve flow command (used when control_mode = flow)")
        .range(Some(-1.0e-3), Some(1.0e-3)),
    // Half the longest stroke the cylinder.stroke range allows; once the stroke is known
    // (at initialisation) x_ref is also checked against +-cylinder.stroke/2.
    X_REF => input("x_ref", "m", Some("mm"), 0.0, "Piston position command, 0 = mid-stroke, within +-cylinder.stroke/2 (used when control_mode = position)")
        .range(Some(-0.5 * MAX_STROKE), Some(0.5 * MAX_STROKE)),
    Q_A => output("Q_A", "m3/s", Some("L/min"), "Actual flow into chamber A"),
    Q_B => output("Q_B", "m3/s", Some("L/min"), "Actual flow out of chamber B"),
    P_A => output("p_A", "Pa", Some("bar"), "Chamber A (piston side) pressure, gauge"),
    P_B => output("p_B", "Pa", Some("bar"), "Chamber B (rod side) pressure, gauge"),
    X_PISTON => output("x_piston", "m", Some("mm"), "Piston position, 0 = mid-stroke, positive = extension"),
    V_PISTON => output("v_piston", "m/s", None, "Piston velocity"),
    F_HYDRAULIC => output("F_hydraulic", "N", None, "Hydraulic force p_A*A_A - p_B*A_B"),
    // Cylinder, load and hydraulic fluid.
    CYLINDER_BORE => param("cylinder.bore", Some("m"), 0.016, "Piston (bore) diameter").positive(),
    CYLINDER_ROD => param("cylinder.rod", Some("m"), 0.010, "Rod diameter (single rod on the B side; 0 gives equal areas)").non_negative(),
    CYLINDER_STROKE => param("cylinder.stroke", Some("m"), 0.080, "Full stroke; x_piston = 0 at mid-stroke, end stops at +-stroke/2")
        .positive()
        .range(Some(0.0), Some(MAX_STROKE)),
    CYLINDER_MASS => param("cylinder.mass", Some("kg"), 5.0, "Moving mass of piston, rod and load").positive().tunable(),
    CYLINDER_BETA => param("cylinder.beta", Some("Pa"), 1.0e9, "Effective bulk modulus of oil, hoses and walls").positive(),
    CYLINDER_V_DEAD => param("cylinder.V_dead", Some("m3"), 2.0e-6, "Dead volume of each chamber at its end of stroke (ports, hoses)").positive(),
    CYLINDER_B_VISCOUS => param("cylinder.b_viscous", Some("N.s/m"), 200.0, "Viscous friction coefficient").non_negative().tunable(),
    CYLINDER_F_COULOMB => param("cylinder.F_coulomb", Some("N"), 20.0, "Coulomb friction force").non_negative().tunable(),
    CYLINDER_F_STATIC => param("cylinder.F_static", Some("N"), 30.0, "Breakaway (static) friction force: peak of the Stribeck curve").non_negative().tunable(),
    CYLINDER_V_STRIBECK => param("cylinder.v_stribeck", Some("m/s"), 0.01, "Stribeck velocity: friction falls from F_static to F_coulomb over this speed").positive().tunable(),
    CYLINDER_V_FRICTION_SMOOTH => param("cylinder.v_friction_smooth", Some("m/s"), 1.0e-4, "Creep velocity scale of tanh(v/v) replacing sign(v) in the friction (no sticking singularity)").positive().tunable(),
    CYLINDER_K_ENDSTOP => param("cylinder.k_endstop", Some("N/m"), 1.0e8, "End-stop contact stiffness beyond +-stroke/2").positive(),
    CYLINDER_C_ENDSTOP => param("cylinder.c_endstop", Some("N.s/m"), 1.0e4, "End-stop contact damping (only while penetrating; the contact never pulls)").non_negative(),
    CYLINDER_C_LEAK => param("cylinder.C_leak", Some("m3/(s.Pa)"), 0.0, "Internal leakage coefficient across the piston, A to B").non_negative().tunable(),
    CYLINDER_C_LEAK_EXTERNAL => param("cylinder.C_leak_external", Some("m3/(s.Pa)"), 0.0, "External leakage coefficient from each chamber to the drain at p_tank").non_negative().tunable(),
    VALVE_DP_RATED => param("valve.dp_rated", Some("Pa"), 6.8948e6, "Total rated valve pressure drop (1000 psi): the no-load flow K3*x_s is specified at this drop").positive(),
    VALVE_DP_LAMINAR => param("valve.dp_laminar", Some("Pa"), 1.0e5, "Port pressure drop below which the orifice flow law is regularised (laminar, finite slope)").positive(),
    HYDRAULICS_P_TANK => param("hydraulics.p_tank", Some("Pa"), 0.0, "Tank (return) pressure, gauge").range(Some(-1.01325e5), None),
    HYDRAULICS_P_CAVITATION => param("hydraulics.p_cavitation", Some("Pa"), -0.9e5, "Cavitation floor (gauge; -0.9e5 = 0.1 bar absolute): chamber pressures never fall below it").range(Some(-1.01325e5), None),
    HYDRAULICS_DP_CAVITATION_BAND => param("hydraulics.dp_cavitation_band", Some("Pa"), 5.0e4, "Pressure band above the floor over which an emptying chamber's bulk modulus fades to zero").positive(),
    // Outer loops (control_mode 1 flow, 2 position): a digital PID producing the current command.
    LOOP_F_SAMPLE => param("loop.f_sample", Some("Hz"), 20000.0, "Sampling rate of the outer flow/position PID (the command is held between samples)")
        .positive()
        .range(Some(0.0), Some(1.0e6)),
    LOOP_I_MAX => param("loop.i_max", Some("A"), VALVE_RATED_CURRENT, "Limit of the current command from the outer loops (rated current)").positive().tunable(),
    // Flow defaults, a gentle P on top of the exact feed-forward like the paper's untuned
    // loop: a 2e-4 m3/s step settles in 3.37 ms at 72 V and 6.08 ms at 10 V (180 %; paper
    // 3.3 ms, 6 ms, 181 %). With the feed-forward exact, P alone leaves no steady-state
    // error; an integral adds a slow tail (the area it collects in the transient) and winds
    // up against the 10 V supply limit, where the coil current can only rise with L/R.
    FLOW_KP => param("flow.Kp", Some("A.s/m3"), 2.0, "Flow PID proportional gain (on Q_ref - Q_valve; feed-forward Q_ref/(K3*K1/Kw) added)").tunable(),
    FLOW_KI => param("flow.Ki", Some("A/m3"), 0.0, "Flow PID integral gain").tunable(),
    FLOW_KD => param("flow.Kd", Some("A.s2/m3"), 0.0, "Flow PID derivative gain").tunable(),
    // Position defaults: P only (1 mA per mm). The valve-controlled cylinder integrates flow,
    // and a critically centred valve holds a constant load with zero flow only at null spool,
    // so P alone has zero steady-state error; Ki is for leakage or a valve offset. Derivative
    // action excites the hydraulic resonance at these gains.
    POSITION_KP => param("position.Kp", Some("A/m"), 1.0, "Position PID proportional gain (on x_ref - x_piston)").tunable(),
    POSITION_KI => param("position.Ki", Some("A/(m.s)"), 0.0, "Position PID integral gain").tunable(),
    POSITION_KD => param("position.Kd", Some("A.s/m"), 0.0, "Position PID derivative gain").tunable(),
    // Relief valves of the cylinder (appended: references never move). One per chamber, to
    // tank; 80 bar is 16 % above the 1000 psi supply, so they stay shut in normal operation
    // (docs/model.md) and cap what braking a fast piston with the valve does to the chambers.
    RELIEF_P_CRACK => param("relief.p_crack", Some("Pa"), 8.0e6, "Cracking pressure of the chamber relief valves, above p_tank (0: no relief valves); must exceed p_supply - p_tank")
        .non_negative(),
    RELIEF_DP_OVERRIDE => param("relief.dp_override", Some("Pa"), 1.0e6, "Pressure override: rise above the cracking pressure at which a relief valve passes its rated flow").positive(),
    RELIEF_Q_RATED => param("relief.Q_rated", Some("m3/s"), 4.0e-4, "Rated flow of each relief valve, reached at relief.p_crack + relief.dp_override").positive(),
    // Accuracy against speed (appended). 1e-7 keeps every output within ~1e-6 of its range
    // of a tight reference (docs/benchmark.md); looser settings are for hardware-in-the-loop
    // budgets, tighter ones for references. Past 1e-3 the error control means nothing.
    SOLVER_RTOL => param("solver.rtol", None, 1.0e-7, "Relative tolerance of the cylinder's Rosenbrock integrator (errors weighed against rtol*max(|y|, 1 MPa / 10 mm / 0.1 m/s)); driver, coil and valve are exact at any setting")
        .range(Some(1.0e-12), Some(1.0e-3)),
}

/// Index of the variable with this name.
pub fn index_of(name: &str) -> Option<usize> {
    VARIABLES.iter().position(|v| v.name == name)
}

/// Start values of all variables, indexed by value reference.
pub fn start_values() -> [f64; N_VARIABLES] {
    let mut values = [0.0; N_VARIABLES];
    for (slot, var) in values.iter_mut().zip(VARIABLES.iter()) {
        *slot = var.start;
    }
    values
}

/// FNV-1a over every attribute that an importer binds to, formatted as a GUID:
/// the FMI 2 guid and FMI 3 instantiationToken change whenever the interface does.
pub fn interface_token() -> String {
    let mut hash: u128 = 0x6c62272e07bb014262b821756295c58d;
    let mut feed = |bytes: &[u8]| {
        for &b in bytes {
            hash ^= b as u128;
            hash = hash.wrapping_mul(0x0000000001000000000000000000013B);
        }
        hash ^= 0xff;
    };
    for (i, v) in VARIABLES.iter().enumerate() {
        feed(&(i as u64).to_le_bytes());
        feed(v.name.as_bytes());
        feed(format!("{:?}{:?}{:?}", v.causality, v.variability, v.ty).as_bytes());
        feed(v.unit.unwrap_or("").as_bytes());
        feed(&v.start.to_le_bytes());
        feed(&v.min.unwrap_or(f64::NAN).to_le_bytes());
        feed(&v.max.unwrap_or(f64::NAN).to_le_bytes());
    }
    for e in ENUMERATIONS {
        feed(e.name.as_bytes());
        for (value, name, _) in e.items {
            feed(&value.to_le_bytes());
            feed(name.as_bytes());
        }
    }
    let h = format!("{hash:032x}");
    format!("{{{}-{}-{}-{}-{}}}", &h[0..8], &h[8..12], &h[12..16], &h[16..20], &h[20..32])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_unique_and_every_constant_is_its_row() {
        for (i, a) in VARIABLES.iter().enumerate() {
            for b in &VARIABLES[i + 1..] {
                assert_ne!(a.name, b.name);
            }
        }
        // The constant of each row is the variable's name in upper case with '.' -> '_'
        // (so `vr::COIL_L` is "coil.L"), and its value is that row.
        for (row, (var, constant)) in VARIABLES.iter().zip(CONSTANT_NAMES).enumerate() {
            assert_eq!(var.name.to_uppercase().replace('.', "_"), constant, "row {row}");
            assert_eq!(index_of(var.name), Some(row));
        }
        assert_eq!(VARIABLES[vr::COIL_K_B].name, "coil.K_b");
        assert_eq!(VARIABLES[vr::POSITION_KD].name, "position.Kd");
        assert_eq!(N_VARIABLES, 80);
    }

    #[test]
    fn start_values_pass_their_own_checks() {
        for v in VARIABLES.iter().filter(|v| v.has_start()) {
            v.check(v.start).unwrap();
        }
    }

    #[test]
    fn check_names_variable_and_range() {
        let l = &VARIABLES[vr::COIL_L];
        let msg = l.check(-1.0).unwrap_err();
        assert!(msg.contains("coil.L") && msg.contains("(0, +inf)"), "{msg}");
        assert!(l.check(f64::NAN).unwrap_err().contains("finite"));
    }

    #[test]
    fn every_input_has_a_range_and_only_parameters_are_tunable() {
        for v in VARIABLES.iter() {
            if v.causality == Input {
                assert!(v.min.is_some() && v.max.is_some(), "{} has no range", v.name);
            }
            if v.variability == Tunable {
                assert_eq!(v.causality, Parameter, "{}", v.name);
            }
        }
        let i_ref = &VARIABLES[vr::I_REF];
        assert!(i_ref.check(5.0).unwrap_err().contains("[-0.1, 0.1]"), "5 mA typed in A");
        assert_eq!(VARIABLES[vr::LOOP_I_MAX].start, VALVE_RATED_CURRENT);
        for structural in [vr::DRIVER, vr::CONTROL_MODE, vr::CYLINDER_STROKE, vr::LOOP_F_SAMPLE] {
            assert_eq!(VARIABLES[structural].variability, Fixed, "{}", VARIABLES[structural].name);
        }
    }

    #[test]
    fn token_is_a_guid() {
        let t = interface_token();
        assert_eq!(t.len(), 38);
        assert!(t.starts_with('{') && t.ends_with('}'));
    }
}
