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
    /// Worked out from the parameters at initialisation, read-only (FMI's
    /// `calculatedParameter`).
    CalculatedParameter,
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
            Causality::Output | Causality::CalculatedParameter => Some(Initial::Calculated),
        }
    }
    /// Whether the variable may be set, before initialisation ends or after: parameters
    /// and inputs may, fixed parameters only until initialisation ends. (The FMI layer's
    /// call sequence maps this onto its states.)
    pub const fn may_be_set(&self, initialized: bool) -> bool {
        match (self.causality, self.variability) {
            (Causality::Parameter, Variability::Fixed) => !initialized,
            (Causality::Parameter | Causality::Input, _) => true,
            _ => false,
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
        format!("{} = {} rejected: {why}", self.name, crate::units::readable(value))
    }
    pub fn range_text(&self) -> String {
        let lo = match self.min {
            Some(m) if self.min_exclusive => format!("({}", crate::units::readable(m)),
            Some(m) => format!("[{}", crate::units::readable(m)),
            None => "(-inf".to_string(),
        };
        let hi = match self.max {
            Some(m) => format!("{}]", crate::units::readable(m)),
            None => "+inf)".to_string(),
        };
        format!("{lo}, {hi}")
    }
}

/// An FMI enumeration type: its items (name, description); an item's value is its position.
pub struct Enumeration {
    pub name: &'static str,
    pub description: &'static str,
    pub items: &'static [(&'static str, &'static str)],
}

impl Enumeration {
    /// Items with their values (value, name, description).
    pub fn valued_items(&self) -> impl Iterator<Item = (i64, &'static str, &'static str)> + '_ {
        self.items
            .iter()
            .enumerate()
            .map(|(value, &(name, description))| (value as i64, name, description))
    }
}

/// The coil driver topologies: an item's value is the position of its
/// [`DriverKind`] in [`DriverKind::ALL`] (a test holds the two in step).
pub const DRIVER_TYPE: Enumeration = Enumeration {
    name: "DriverType",
    description: "Coil driver topology",
    items: &[
        ("ideal_current", "coil current equals the command exactly (paper eq. 3)"),
        ("voltage", "open-loop voltage R_total*i_cmd clamped at the rails (paper eq. 4)"),
        ("opamp_pi", "high-voltage op-amp PI current driver (the paper's proposal)"),
        ("industrial", "off-the-shelf linear current amplifier (My-502 like)"),
        ("hbridge_pid", "H-bridge with PWM and a digital PI current loop"),
    ],
};

/// The command sources, in the order of [`ControlMode::ALL`].
pub const CONTROL_MODE_TYPE: Enumeration = Enumeration {
    name: "ControlMode",
    description: "Which command drives the coil current",
    items: &[
        ("current", "i_ref is the current command"),
        ("flow", "flow PID on Q_valve follows Q_ref"),
        ("position", "position PID on the piston follows x_ref"),
    ],
};

/// How the rod meets its load, in the order of [`RodPort::ALL`].
pub const ROD_PORT_TYPE: Enumeration = Enumeration {
    name: "RodPort",
    description: "How the rod meets its load",
    items: &[
        ("force", "the FMU moves cylinder.mass under F_ext"),
        ("motion", "the host moves the rod (x_rod, v_rod) and takes the force F_rod"),
    ],
};

/// The integrators, in the order of [`SolverMethod::ALL`].
pub const SOLVER_METHOD_TYPE: Enumeration = Enumeration {
    name: "SolverMethod",
    description: "The integrator between time events",
    items: &[
        ("exact", "driver, coil and valve exact, the cylinder by adaptive Rosenbrock: results independent of the communication step"),
        ("fixed_cost", "work fixed by the step size for real-time rigs: internal steps of at most solver.h_internal, the cylinder by one linearly implicit trapezoidal step each, the H-bridge's PWM by each period's mean voltage (docs/solvers.md)"),
    ],
};

/// How the valve is given, in the order of [`ValveParameterization::ALL`].
pub const VALVE_PARAMETERIZATION_TYPE: Enumeration = Enumeration {
    name: "ValveParameterization",
    description: "How the valve's figures are given",
    items: &[
        ("gains", "the Moog 30 model's internal gains (valve.K1, Kf, Kw, K2, K3, A_s, zeta, f_n)"),
        ("datasheet", "a datasheet's figures (valve.Q_rated, i_rated, dp_rated, f_90, f_3dB, zeta; Q_leak_null, p_leak_ref, pressure_gain): the gains follow at initialisation (valve.derived.*)"),
    ],
};

pub const ENUMERATIONS: &[Enumeration] = &[
    DRIVER_TYPE,
    CONTROL_MODE_TYPE,
    ROD_PORT_TYPE,
    SOLVER_METHOD_TYPE,
    VALVE_PARAMETERIZATION_TYPE,
];

use Causality::*;
use Variability::*;

use crate::physics::{
    ControlMode, DriverKind, Inputs, Outputs, Params, RodPort, SolverMethod, ValveFigures,
    ValveParameterization, DATASHEET_HZ, MAX_AMPLIFIER_GAIN, MAX_FIRST_STAGE_HZ, MAX_LAP,
};

/// A Boolean or enumeration field, stored in the value array as its integer value.
pub trait Coded: Sized {
    fn from_code(value: f64) -> Result<Self, String>;
    fn code(self) -> f64;
}

impl Coded for bool {
    fn from_code(value: f64) -> Result<Self, String> {
        Ok(value != 0.0)
    }
    fn code(self) -> f64 {
        self as u8 as f64
    }
}

/// Enumerations are coded by their position in `ALL`.
macro_rules! coded_enumeration {
    ($($ty:ty => $variable:literal),*) => {$(
        impl Coded for $ty {
            fn from_code(value: f64) -> Result<Self, String> {
                <$ty>::ALL.get(value as usize).copied().filter(|_| value >= 0.0).ok_or_else(|| {
                    format!("{} = {} is not available (0 to {})", $variable, crate::units::readable(value), <$ty>::ALL.len() - 1)
                })
            }
            fn code(self) -> f64 {
                self as u8 as f64
            }
        }
    )*};
}

coded_enumeration!(
    DriverKind => "driver",
    ControlMode => "control_mode",
    RodPort => "cylinder.port",
    SolverMethod => "solver.method",
    ValveParameterization => "valve.parameterization"
);

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
    description: &'static str,
) -> Variable {
    real(name, Input, Continuous, Some(unit), display, 0.0, description)
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
    description: &'static str,
) -> Variable {
    real(name, Parameter, Fixed, unit, None, 0.0, description)
}

/// A fixed Boolean parameter.
const fn boolean_param(name: &'static str, description: &'static str) -> Variable {
    let mut v = param(name, None, description);
    v.ty = VarType::Boolean;
    v
}

/// A fixed parameter choosing one item of `enumeration` (its values 0 to n - 1).
const fn enumeration(
    name: &'static str,
    enumeration: &'static Enumeration,
    description: &'static str,
) -> Variable {
    let mut v = param(name, None, description);
    v.ty = VarType::Enumeration(enumeration.name);
    v.range(Some(0.0), Some((enumeration.items.len() - 1) as f64))
}

/// A calculated parameter: worked out from the parameters at initialisation, read-only.
const fn calculated(
    name: &'static str,
    unit: Option<&'static str>,
    description: &'static str,
) -> Variable {
    real(name, CalculatedParameter, Fixed, unit, None, 0.0, description)
}

/// A Boolean output that changes at events only.
const fn boolean_output(name: &'static str, description: &'static str) -> Variable {
    let mut v = real(name, Output, Discrete, None, None, 0.0, description);
    v.ty = VarType::Boolean;
    v
}

impl Variable {
    const fn with_start(mut self, start: f64) -> Self {
        self.start = start;
        self
    }
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

pub use crate::physics::VALVE_RATED_CURRENT;

/// The fastest rod motion a host may prescribe (m/s).
const MAX_ROD_SPEED: f64 = 10.0;

/// Where the physics of the parameters ends (issue 37; each row's comment says why).
/// A PI loop's proportional gain: 1e8 V/A puts the largest rail (1 kV) at 10 uA of error, a
/// thousandth of the rated current (more gain makes it an on-off switch); an op-amp's
/// open-loop gain (~1e6) on a 100 Ohm sense resistor gives no more.
const MAX_PI_KP: f64 = 1.0e8;
/// Its integral gain: MAX_PI_KP with an integral corner Ki/Kp of 1e6 1/s, the bandwidth of
/// the op-amps and converters that realise it.
const MAX_PI_KI: f64 = 1.0e14;
/// An op-amp's (or amplifier's) output slews at most ~1e4 V/us.
const MAX_SLEW_RATE: f64 = 1.0e10;
/// Forces on the rod: F_ext's range.
const MAX_FORCE: f64 = 1.0e5;
/// Leakage: the valve's rated flow (2.5e-4 m3/s) through a 0.25 bar drop.
const MAX_LEAK: f64 = 1.0e-8;
/// The outer loops' proportional gains: an error of 1 um (position) or 1e-9 m3/s (flow, a
/// millionth of Q_ref's range) commands the largest current (0.1 A).
const MAX_POSITION_KP: f64 = 1.0e5;
const MAX_FLOW_KP: f64 = 1.0e8;
/// Their integral and derivative times: from the fastest sample period (1 us, loop.f_sample's
/// maximum) to a second, beyond which the derivative action acts on nothing an actuator does.
const MIN_LOOP_TIME: f64 = 1.0e-6;
const MAX_LOOP_TIME: f64 = 1.0;

/// Longest stroke (m) of a servo cylinder this model describes (`cylinder.stroke`'s maximum,
/// which bounds `x_ref`).
const MAX_STROKE: f64 = 1.0;

/// What a setter needs of a variable, precomputed from its row ([`SET_RULES`]): setters
/// run on every communication step, and the common case, a real value within its range,
/// then costs a look-up and two compares instead of the walk through the row's options
/// that [`Variable::check`] and [`Variable::may_be_set`] take.
#[derive(Clone, Copy, Debug)]
pub struct SetRule {
    /// [`Variable::may_be_set`] before initialisation ends.
    pub before_initialisation: bool,
    /// [`Variable::may_be_set`] after initialisation.
    pub after_initialisation: bool,
    /// A parameter: a new value after initialisation rebuilds the physics.
    pub parameter: bool,
    /// The closed interval of values that [`Variable::check`] accepts for a real variable,
    /// with finite ends so that NaN and the infinities fall outside it; empty for Booleans
    /// and enumerations, whose values the full check decides.
    lo: f64,
    hi: f64,
}

impl SetRule {
    const fn of(v: &Variable) -> SetRule {
        let (lo, hi) = match v.ty {
            VarType::Real => (
                match v.min {
                    Some(min) if v.min_exclusive => min.next_up(),
                    Some(min) => min,
                    None => f64::MIN,
                }
                .max(f64::MIN),
                match v.max {
                    Some(max) => max,
                    None => f64::MAX,
                }
                .min(f64::MAX),
            ),
            VarType::Boolean | VarType::Enumeration(_) => (f64::INFINITY, f64::NEG_INFINITY),
        };
        SetRule {
            before_initialisation: v.may_be_set(false),
            after_initialisation: v.may_be_set(true),
            parameter: matches!(v.causality, Causality::Parameter),
            lo,
            hi,
        }
    }

    /// [`Variable::may_be_set`].
    #[inline]
    pub fn may_be_set(&self, initialized: bool) -> bool {
        if initialized {
            self.after_initialisation
        } else {
            self.before_initialisation
        }
    }

    /// Whether `value` surely passes [`Variable::check`]; `false` leaves it to the check.
    #[inline]
    pub fn surely_accepts(&self, value: f64) -> bool {
        self.lo <= value && value <= self.hi
    }
}

/// [`SetRule`] of every variable, indexed by value reference.
pub static SET_RULES: [SetRule; N_VARIABLES] = {
    let mut rules = [SetRule::of(&VARIABLES[0]); N_VARIABLES];
    let mut i = 1;
    while i < N_VARIABLES {
        rules[i] = SetRule::of(&VARIABLES[i]);
        i += 1;
    }
    rules
};

/// Declares the table and, from the same rows, one constant per variable in [`vr`] (the
/// value reference of a variable is its row, so no reference is ever numbered by hand) and
/// the binding of each row to its typed field: `param[coil.inductance] real` is the field
/// of [`Params`], `input[..]` of [`Inputs`], `output[..]` of [`Outputs`]; `coded` marks a
/// Boolean or an enumeration, stored as its integer value. A parameter's or input's start
/// value is its field's value in [`Params::PAPER`] or [`Inputs::PAPER`].
macro_rules! variable_table {
    ($($constant:ident => $group:ident [$($field:tt)*] $kind:ident : $row:expr,)*) => {
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

        pub static VARIABLES: [Variable; N_VARIABLES] =
            [$($row.with_start(start_value!($group [$($field)*] $kind)),)*];

        /// The typed parameters in a value array (its values were checked when they were set or restored).
        pub fn params(values: &[f64; N_VARIABLES]) -> Result<Params, String> {
            let mut params = Params::PAPER;
            $(read_field!(param, $group [$($field)*] $kind, params, values[vr::$constant]);)*
            Ok(params)
        }

        /// The typed inputs in a value array (all real: a coded input would need a `Result`).
        pub fn inputs(values: &[f64; N_VARIABLES]) -> Inputs {
            let mut inputs = Inputs::PAPER;
            $(read_field!(input, $group [$($field)*] $kind, inputs, values[vr::$constant]);)*
            inputs
        }

        /// Writes the physics' outputs into their value references.
        pub fn write_outputs(outputs: &Outputs, values: &mut [f64; N_VARIABLES]) {
            $(write_field!($group [$($field)*] $kind, outputs, values[vr::$constant]);)*
        }

        /// Writes the valve's figures into the calculated parameters' value references.
        pub fn write_calculated(figures: &ValveFigures, values: &mut [f64; N_VARIABLES]) {
            $(write_calculated_field!($group [$($field)*], figures, values[vr::$constant]);)*
        }
    };
}

/// A row's start value: its field in the paper's device, 0 for outputs and time.
macro_rules! start_value {
    (param [$($field:tt)*] real) => { Params::PAPER.$($field)* };
    (param [$($field:tt)*] coded) => { Params::PAPER.$($field)* as u8 as f64 };
    (input [$($field:tt)*] real) => { Inputs::PAPER.$($field)* };
    ($group:ident [$($field:tt)*] $kind:ident) => { 0.0 };
}

/// Reads a row of group `$want` into its typed field; rows of other groups are no-ops.
macro_rules! read_field {
    (param, param [$($field:tt)*] real, $to:ident, $value:expr) => { $to.$($field)* = $value; };
    (param, param [$($field:tt)*] coded, $to:ident, $value:expr) => { $to.$($field)* = Coded::from_code($value)?; };
    (input, input [$($field:tt)*] real, $to:ident, $value:expr) => { $to.$($field)* = $value; };
    ($want:ident, $group:ident [$($field:tt)*] $kind:ident, $to:ident, $value:expr) => {};
}

/// Writes a calculated parameter's row from its field of [`ValveFigures`]; other rows are
/// no-ops.
macro_rules! write_calculated_field {
    (calc [$($field:tt)*], $from:ident, $slot:expr) => { $slot = $from.$($field)*; };
    ($group:ident [$($field:tt)*], $from:ident, $slot:expr) => {};
}

/// Writes an output row from its typed field; other rows are no-ops.
macro_rules! write_field {
    (output [$($field:tt)*] real, $from:ident, $slot:expr) => { $slot = $from.$($field)*; };
    (output [$($field:tt)*] coded, $from:ident, $slot:expr) => { $slot = $from.$($field)*.code(); };
    ($group:ident [$($field:tt)*] $kind:ident, $from:ident, $slot:expr) => {};
}

variable_table! {
    TIME => clock[] real: Variable {
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
    I_REF => input[i_ref] real: input("i_ref", "A", Some("mA"), "Coil current command (used when control_mode = current); rated current 10 mA")
        .range(Some(-10.0 * VALVE_RATED_CURRENT), Some(10.0 * VALVE_RATED_CURRENT)),
    // Up to 1 kV: far above any coil driver's supply (the paper's is 72 V).
    V_SUPPLY => input[v_supply] real: input("V_supply", "V", None, "Driver supply: the output rails are at +V_supply and -V_supply")
        .range(Some(0.0), Some(1000.0)),
    // Outputs
    I_COIL => output[i_coil] real: output("i_coil", "A", Some("mA"), "Torque-motor coil current"),
    U_DRIVER => output[u_driver] real: output("u_driver", "V", None, "Driver output voltage across coil and sense resistor"),
    DRIVER_SATURATED => output[driver_saturated] coded: boolean_output("driver_saturated", "The driver output is at a supply rail"),
    X_FLAPPER => output[x_flapper] real: output("x_flapper", "m", Some("um"), "Armature/flapper displacement at the nozzles"),
    X_SPOOL => output[x_spool] real: output("x_spool", "m", Some("mm"), "Main spool displacement"),
    Q_VALVE => output[q_valve] real: output("Q_valve", "m3/s", Some("L/min"), "No-load valve flow K3*x_spool (the paper's hydraulic-amplifier load flow)"),
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
    DRIVER => param[driver] coded: enumeration("driver", &DRIVER_TYPE, "Coil driver topology"),
    CONTROL_MODE => param[control_mode] coded: enumeration("control_mode", &CONTROL_MODE_TYPE, "Which command drives the coil current"),
    // Driver
    // Ranges end where the physics does (issue 37: driver.slew_rate = 1e300 was accepted and
    // hung fixed_cost's initialisation). PI gains: MAX_PI_KP and MAX_PI_KI below.
    DRIVER_KP => param[opamp.kp] real: param("driver.Kp", Some("V/A"), "Op-amp PI proportional gain (= G*R_s; the paper's linear analysis writes R_s)")
        .non_negative()
        .range(Some(0.0), Some(MAX_PI_KP))
        .tunable(),
    DRIVER_KI => param[opamp.ki] real: param("driver.Ki", Some("V/(A.s)"), "Op-amp PI integral gain (= G*R_s/(R_f*C_f)); default Ki/Kp = R/L cancels the coil pole")
        .non_negative()
        .range(Some(0.0), Some(MAX_PI_KI))
        .tunable(),
    // At most the largest supply (V_supply up to 1 kV): a larger drop leaves no output swing.
    DRIVER_V_DROP => param[opamp_v_drop] real: param("driver.V_drop", Some("V"), "Output stage drop: the output saturates at +-(V_supply - V_drop)")
        .non_negative()
        .range(Some(0.0), Some(1000.0))
        .tunable(),
    DRIVER_SLEW_RATE => param[opamp.slew_rate] real: param("driver.slew_rate", Some("V/s"), "Op-amp output slew-rate limit (20 V/us)").positive().range(Some(0.0), Some(MAX_SLEW_RATE)).tunable(),
    // Coil
    // Torque-motor coils: 0.1 mH (a few turns) to 1 kH, beyond any coil a valve carries (the
    // paper's is 3.2 H); a smaller L makes L/R a time constant below a nanosecond.
    COIL_L => param[coil.inductance] real: param("coil.L", Some("H"), "Torque-motor coil (apparent) inductance").range(Some(1.0e-4), Some(1.0e3)),
    // Resistances up to 1 MOhm: at 1 kV such a coil carries 1 mA, a tenth of the rated current.
    COIL_R => param[coil.resistance] real: param("coil.R", Some("Ohm"), "Torque-motor coil resistance").positive().range(Some(0.0), Some(1.0e6)),
    COIL_R_SENSE => param[coil.r_sense] real: param("coil.R_sense", Some("Ohm"), "Current-sense resistor in series with the coil").non_negative().range(Some(0.0), Some(1.0e6)),
    // The motor's own force constant bounds its back-EMF: K1 (2.8 N.m/A) over a ~1 cm arm is
    // ~300 V.s/m; 1e5 is 300 times that.
    COIL_K_B => param[coil.k_backemf] real: param("coil.K_b", Some("V.s/m"), "Back-EMF constant on the flapper velocity (0: already in the apparent inductance)")
        .non_negative().range(Some(0.0), Some(1.0e5)),
    // Valve (Moog 30 linear model)
    // Valve constants: a factor of about 100 to 1000 either side of the Moog 30's (the paper's
    // values in the descriptions) spans every flapper-nozzle valve made; beyond, the first
    // stage's coefficients (K1/Kf, Kw/Kf, K2/A_s) leave every time scale a valve has.
    VALVE_K1 => param[valve.k1] real: param("valve.K1", Some("N.m/A"), "Torque-motor gain (0.025 in-lb/mA)").positive().range(Some(0.0), Some(1.0e3)),
    VALVE_KF => param[valve.kf] real: param("valve.Kf", Some("N.m/m"), "Net stiffness on flapper/armature (115 in-lb/in)").range(Some(1.0), Some(1.0e6)),
    VALVE_KW => param[valve.kw] real: param("valve.Kw", Some("N.m/m"), "Feedback wire stiffness (16.7 in-lb/in)").positive().range(Some(0.0), Some(1.0e5)),
    VALVE_K2 => param[valve.k2] real: param("valve.K2", Some("m2/s"), "Hydraulic amplifier flow gain (150 in3/s/in)").positive().range(Some(0.0), Some(MAX_AMPLIFIER_GAIN)),
    VALVE_K3 => param[valve.k3] real: param("valve.K3", Some("m2/s"), "Spool/bushing flow gain (1030 in3/s/in)").positive().range(Some(0.0), Some(100.0)),
    // Spool end areas: 0.4 mm to 110 mm diameter.
    VALVE_A_S => param[valve.spool_area] real: param("valve.A_s", Some("m2"), "Spool end area (0.026 in2)").range(Some(1.0e-7), Some(1.0e-2)),
    VALVE_ZETA => param[valve.zeta] real: param("valve.zeta", None, "Damping ratio of the first stage").range(Some(0.0), Some(10.0)),
    // A first stage is a small mechanical resonator: 100 kHz is 120 times the Moog 30's.
    VALVE_F_N => param[valve.f_n] real: param("valve.f_n", Some("Hz"), "Natural frequency of the first stage").positive().range(Some(0.0), Some(MAX_FIRST_STAGE_HZ)),
    // Industrial linear current amplifier (driver 3): a PI loop like the op-amp driver's
    // but with the slow gains of an off-the-shelf unit. L/Kp = 1.28 ms gives the My-502's
    // 5 ms (2 %) settling; Ki/Kp = R/L cancels the coil pole.
    INDUSTRIAL_KP => param[industrial.kp] real: param("industrial.Kp", Some("V/A"), "Industrial amplifier proportional gain").non_negative().range(Some(0.0), Some(MAX_PI_KP)).tunable(),
    INDUSTRIAL_KI => param[industrial.ki] real: param("industrial.Ki", Some("V/(A.s)"), "Industrial amplifier integral gain").non_negative().range(Some(0.0), Some(MAX_PI_KI)).tunable(),
    INDUSTRIAL_SLEW_RATE => param[industrial.slew_rate] real: param("industrial.slew_rate", Some("V/s"), "Industrial amplifier output slew-rate limit (1 V/us)").positive().range(Some(0.0), Some(MAX_SLEW_RATE)).tunable(),
    // H-bridge with PWM and a digital PI current loop (driver 4).
    HBRIDGE_F_PWM => param[hbridge.f_pwm] real: param("hbridge.f_pwm", Some("Hz"), "PWM switching frequency (bipolar, centre-aligned)")
        .positive()
        .range(Some(0.0), Some(1.0e6)),
    HBRIDGE_F_SAMPLE => param[hbridge.f_sample] real: param("hbridge.f_sample", Some("Hz"), "Sampling rate of the digital PI current loop (one-sample computation delay)")
        .positive()
        .range(Some(0.0), Some(1.0e6)),
    // With feed-forward and Ki/Kp = R/L, a 5 mA step at 12 V runs at 100 % duty to ~4.2 mA
    // (the supply limits the slope, as on the paper's bench), then the loop closes with
    // L/Kp = 0.36 ms: 1.9 ms settling of the period-averaged current.
    HBRIDGE_KP => param[hbridge.kp] real: param("hbridge.Kp", Some("V/A"), "Digital PI proportional gain").non_negative().range(Some(0.0), Some(MAX_PI_KP)).tunable(),
    HBRIDGE_KI => param[hbridge.ki] real: param("hbridge.Ki", Some("V/(A.s)"), "Digital PI integral gain").non_negative().range(Some(0.0), Some(MAX_PI_KI)).tunable(),
    HBRIDGE_FEEDFORWARD => param[hbridge.feedforward] coded: boolean_param("hbridge.feedforward", "Add the feed-forward voltage (R + R_sense)*i_cmd to the digital PI output"),
    // Optional valve travel limits (the paper's linear model has none).
    // Travel stops up to 1 cm (flapper) and 10 cm (spool): flapper gaps are tens of um and spool
    // strokes a few mm; a larger stop is never reached (0 still removes it).
    VALVE_X_FLAPPER_MAX => param[valve.x_flapper_max] real: param("valve.x_flapper_max", Some("m"), "Flapper travel limit at the nozzles, inelastic stop (0: none)").non_negative().range(Some(0.0), Some(1.0e-2)),
    VALVE_X_SPOOL_MAX => param[valve.x_spool_max] real: param("valve.x_spool_max", Some("m"), "Spool travel limit, inelastic stop (0: none)").non_negative().range(Some(0.0), Some(0.1)),
    // Cylinder side: inputs and outputs.
    // Up to 1000 bar: beyond the pressure rating of industrial servo hydraulics (the
    // Moog 30 is rated for 3000 psi, 207 bar).
    P_SUPPLY => input[p_supply] real: input("p_supply", "Pa", Some("bar"), "Hydraulic supply pressure, gauge (1000 psi: the valve's rated drop, so the no-load flow is K3*x_spool)")
        .range(Some(0.0), Some(1.0e8)),
    // +-100 kN: 72 times the default stall force p_S*A_A (1.39 kN) and 5 times the largest
    // stall force the ranges allow at this bore (1000 bar on 16 mm: 20 kN); a larger force
    // crushes the oil column of any actuator this model describes.
    F_EXT => input[f_ext] real: input("F_ext", "N", None, "External force on the rod, positive in the direction of +x (extension); unused when cylinder.port = motion")
        .range(Some(-1.0e5), Some(1.0e5)),
    // +-1e-3 m3/s (60 L/min): four times the valve's rated flow (2.53e-4 m3/s, 15 L/min at
    // 10 mA), which the outer loop cannot exceed with its default limit.
    Q_REF => input[q_ref] real: input("Q_ref", "m3/s", Some("L/min"), "Valve flow command (used when control_mode = flow)")
        .range(Some(-1.0e-3), Some(1.0e-3)),
    // Half the longest stroke the cylinder.stroke range allows; once the stroke is known
    // (at initialisation) x_ref is also checked against +-cylinder.stroke/2.
    X_REF => input[x_ref] real: input("x_ref", "m", Some("mm"), "Piston position command, 0 = mid-stroke, within +-cylinder.stroke/2 (used when control_mode = position)")
        .range(Some(-0.5 * MAX_STROKE), Some(0.5 * MAX_STROKE)),
    Q_A => output[q_a] real: output("Q_A", "m3/s", Some("L/min"), "Actual flow into chamber A"),
    Q_B => output[q_b] real: output("Q_B", "m3/s", Some("L/min"), "Actual flow out of chamber B"),
    P_A => output[p_a] real: output("p_A", "Pa", Some("bar"), "Chamber A (piston side) pressure, gauge"),
    P_B => output[p_b] real: output("p_B", "Pa", Some("bar"), "Chamber B (rod side) pressure, gauge"),
    X_PISTON => output[x_piston] real: output("x_piston", "m", Some("mm"), "Piston position, 0 = mid-stroke, positive = extension"),
    V_PISTON => output[v_piston] real: output("v_piston", "m/s", None, "Piston velocity"),
    F_HYDRAULIC => output[f_hydraulic] real: output("F_hydraulic", "N", None, "Hydraulic force p_A*A_A - p_B*A_B"),
    // Cylinder, load and hydraulic fluid.
    // Bores and rods up to 1 m (press cylinders).
    CYLINDER_BORE => param[cylinder.bore] real: param("cylinder.bore", Some("m"), "Piston (bore) diameter").positive().range(Some(0.0), Some(1.0)),
    CYLINDER_ROD => param[cylinder.rod] real: param("cylinder.rod", Some("m"), "Rod diameter (single rod on the B side; 0 gives equal areas)").non_negative().range(Some(0.0), Some(1.0)),
    CYLINDER_STROKE => param[cylinder.stroke] real: param("cylinder.stroke", Some("m"), "Full stroke; x_piston = 0 at mid-stroke, end stops at +-stroke/2")
        .positive()
        .range(Some(0.0), Some(MAX_STROKE)),
    // 1 g (a bare piston) to 1000 t: lighter, the oil column's resonance sqrt(beta A^2/(V m))
    // leaves the microsecond range.
    CYLINDER_MASS => param[cylinder.mass] real: param("cylinder.mass", Some("kg"), "Moving mass of piston, rod and load; unused when cylinder.port = motion (the host moves the mass)").range(Some(1.0e-3), Some(1.0e6)).tunable(),
    // Mineral oil's bulk modulus is 1.5-2 GPa, water's 2.2 GPa; 10 GPa is no fluid's.
    CYLINDER_BETA => param[cylinder.beta] real: param("cylinder.beta", Some("Pa"), "Effective bulk modulus of oil, hoses and walls").positive().range(Some(0.0), Some(1.0e10)),
    // Up to 1 m3 (1000 L of hose per chamber).
    CYLINDER_V_DEAD => param[cylinder.v_dead] real: param("cylinder.V_dead", Some("m3"), "Dead volume of each chamber at its end of stroke (ports, hoses)").positive().range(Some(0.0), Some(1.0)),
    // Friction: forces up to MAX_FORCE, F_ext's range (a larger one crushes the oil column of
    // any actuator this model describes); viscous 1e7 N.s/m is 100 kN at 1 cm/s; the Stribeck
    // and creep speeds between 1 um/s and the 10 m/s no servo cylinder reaches.
    CYLINDER_B_VISCOUS => param[cylinder.b_viscous] real: param("cylinder.b_viscous", Some("N.s/m"), "Viscous friction coefficient").non_negative().range(Some(0.0), Some(1.0e7)).tunable(),
    CYLINDER_F_COULOMB => param[cylinder.f_coulomb] real: param("cylinder.F_coulomb", Some("N"), "Coulomb friction force").non_negative().range(Some(0.0), Some(MAX_FORCE)).tunable(),
    CYLINDER_F_STATIC => param[cylinder.f_static] real: param("cylinder.F_static", Some("N"), "Breakaway (static) friction force: peak of the Stribeck curve").non_negative().range(Some(0.0), Some(MAX_FORCE)).tunable(),
    CYLINDER_V_STRIBECK => param[cylinder.v_stribeck] real: param("cylinder.v_stribeck", Some("m/s"), "Stribeck velocity: friction falls from F_static to F_coulomb over this speed").range(Some(1.0e-6), Some(MAX_ROD_SPEED)).tunable(),
    CYLINDER_V_FRICTION_SMOOTH => param[cylinder.v_friction_smooth] real: param("cylinder.v_friction_smooth", Some("m/s"), "Creep velocity scale of tanh(v/v) replacing sign(v) in the friction (no sticking singularity)").positive().range(Some(0.0), Some(MAX_ROD_SPEED)).tunable(),
    // End stops: steel on steel is ~1e10 N/m; 1e12 N/m and 1e8 N.s/m are beyond any contact.
    CYLINDER_K_ENDSTOP => param[cylinder.k_endstop] real: param("cylinder.k_endstop", Some("N/m"), "End-stop contact stiffness beyond +-stroke/2").positive().range(Some(0.0), Some(1.0e12)),
    CYLINDER_C_ENDSTOP => param[cylinder.c_endstop] real: param("cylinder.c_endstop", Some("N.s/m"), "End-stop contact damping (only while penetrating; the contact never pulls)").non_negative().range(Some(0.0), Some(1.0e8)),
    // Leakage up to MAX_LEAK: the valve's rated flow through a 0.25 bar drop, a piston with no seal.
    CYLINDER_C_LEAK => param[cylinder.c_leak] real: param("cylinder.C_leak", Some("m3/(s.Pa)"), "Internal leakage coefficient across the piston, A to B").non_negative().range(Some(0.0), Some(MAX_LEAK)).tunable(),
    CYLINDER_C_LEAK_EXTERNAL => param[cylinder.c_leak_external] real: param("cylinder.C_leak_external", Some("m3/(s.Pa)"), "External leakage coefficient from each chamber to the drain at p_tank").non_negative().range(Some(0.0), Some(MAX_LEAK)).tunable(),
    // Pressures (gauge) up to 1000 bar, p_supply's range; valves are rated at 1-1000 bar drops.
    VALVE_DP_RATED => param[valve.dp_rated] real: param("valve.dp_rated", Some("Pa"), "Total rated valve pressure drop (1000 psi): the no-load flow K3*x_s is specified at this drop").range(Some(1.0e5), Some(1.0e8)),
    VALVE_DP_LAMINAR => param[valve.dp_laminar] real: param("valve.dp_laminar", Some("Pa"), "Port pressure drop below which the orifice flow law is regularised (laminar, finite slope)").positive().range(Some(0.0), Some(1.0e8)),
    // Tank and cavitation pressures from vacuum to 100 bar of back pressure.
    HYDRAULICS_P_TANK => param[cylinder.p_tank] real: param("hydraulics.p_tank", Some("Pa"), "Tank (return) pressure, gauge").range(Some(-1.01325e5), Some(1.0e7)),
    HYDRAULICS_P_CAVITATION => param[cylinder.p_cavitation] real: param("hydraulics.p_cavitation", Some("Pa"), "Cavitation floor (gauge; -0.9e5 = 0.1 bar absolute): chamber pressures never fall below it").range(Some(-1.01325e5), Some(1.0e7)),
    HYDRAULICS_DP_CAVITATION_BAND => param[cylinder.dp_cavitation_band] real: param("hydraulics.dp_cavitation_band", Some("Pa"), "Pressure band above the floor over which an emptying chamber's bulk modulus fades to zero").positive().range(Some(0.0), Some(1.0e7)),
    // Outer loops (control_mode 1 flow, 2 position): a digital PID producing the current command.
    LOOP_F_SAMPLE => param[outer_loop.f_sample] real: param("loop.f_sample", Some("Hz"), "Sampling rate of the outer flow/position PID (the command is held between samples)")
        .positive()
        .range(Some(0.0), Some(1.0e6)),
    // The outer loops' command within i_ref's range: ten times the rated current.
    LOOP_I_MAX => param[outer_loop.i_max] real: param("loop.i_max", Some("A"), "Limit of the current command from the outer loops (rated current)").positive().range(Some(0.0), Some(10.0 * VALVE_RATED_CURRENT)).tunable(),
    // Flow defaults, a gentle P on top of the exact feed-forward like the paper's untuned
    // loop: a 2e-4 m3/s step settles in 3.37 ms at 72 V and 6.08 ms at 10 V (180 %; paper
    // 3.3 ms, 6 ms, 181 %). With the feed-forward exact, P alone leaves no steady-state
    // error; an integral adds a slow tail (the area it collects in the transient) and winds
    // up against the 10 V supply limit, where the coil current can only rise with L/R.
    // Outer-loop gains, either sign: MAX_POSITION_KP, MAX_FLOW_KP and the integral and
    // derivative gains they give (below).
    FLOW_KP => param[outer_loop.flow[0]] real: param("flow.Kp", Some("A.s/m3"), "Flow PID proportional gain (on Q_ref - Q_valve; feed-forward Q_ref/(K3*K1/Kw) added)").range(Some(-MAX_FLOW_KP), Some(MAX_FLOW_KP))
        .tunable(),
    FLOW_KI => param[outer_loop.flow[1]] real: param("flow.Ki", Some("A/m3"), "Flow PID integral gain").range(Some(-MAX_FLOW_KP / MIN_LOOP_TIME), Some(MAX_FLOW_KP / MIN_LOOP_TIME))
        .tunable(),
    FLOW_KD => param[outer_loop.flow[2]] real: param("flow.Kd", Some("A.s2/m3"), "Flow PID derivative gain").range(Some(-MAX_FLOW_KP * MAX_LOOP_TIME), Some(MAX_FLOW_KP * MAX_LOOP_TIME))
        .tunable(),
    // Position defaults: P only (1 mA per mm). The valve-controlled cylinder integrates flow,
    // and a critically centred valve holds a constant load with zero flow only at null spool,
    // so P alone has zero steady-state error; Ki is for leakage or a valve offset. Derivative
    // action excites the hydraulic resonance at these gains.
    POSITION_KP => param[outer_loop.position[0]] real: param("position.Kp", Some("A/m"), "Position PID proportional gain (on x_ref - x_piston)").range(Some(-MAX_POSITION_KP), Some(MAX_POSITION_KP))
        .tunable(),
    POSITION_KI => param[outer_loop.position[1]] real: param("position.Ki", Some("A/(m.s)"), "Position PID integral gain").range(Some(-MAX_POSITION_KP / MIN_LOOP_TIME), Some(MAX_POSITION_KP / MIN_LOOP_TIME))
        .tunable(),
    POSITION_KD => param[outer_loop.position[2]] real: param("position.Kd", Some("A.s/m"), "Position PID derivative gain").range(Some(-MAX_POSITION_KP * MAX_LOOP_TIME), Some(MAX_POSITION_KP * MAX_LOOP_TIME))
        .tunable(),
    // Relief valves of the cylinder (appended: references never move). One per chamber, to
    // tank; 80 bar is 16 % above the 1000 psi supply, so they stay shut in normal operation
    // (docs/model.md) and cap what braking a fast piston with the valve does to the chambers.
    RELIEF_P_CRACK => param[cylinder.relief_p_crack] real: param("relief.p_crack", Some("Pa"), "Cracking pressure of the chamber relief valves, above p_tank (0: no relief valves); must exceed p_supply - p_tank")
        .non_negative()
        .range(Some(0.0), Some(1.0e8)),
    RELIEF_DP_OVERRIDE => param[cylinder.relief_dp_override] real: param("relief.dp_override", Some("Pa"), "Pressure override: rise above the cracking pressure at which a relief valve passes its rated flow").positive().range(Some(0.0), Some(1.0e8)),
    // 1 m3/s (60,000 L/min) is beyond any relief valve.
    RELIEF_Q_RATED => param[cylinder.relief_q_rated] real: param("relief.Q_rated", Some("m3/s"), "Rated flow of each relief valve, reached at relief.p_crack + relief.dp_override").positive().range(Some(0.0), Some(1.0)),
    // Accuracy against speed (appended). 1e-7 keeps every output within ~1e-6 of its range
    // of a tight reference (docs/benchmark.md); looser settings are for hardware-in-the-loop
    // budgets, tighter ones for references. Past 1e-3 the error control means nothing.
    SOLVER_RTOL => param[solver_rtol] real: param("solver.rtol", None, "Relative tolerance of the cylinder's Rosenbrock integrator (errors weighed against rtol*max(|y|, 1 MPa / 10 mm / 0.1 m/s)); driver, coil and valve are exact at any setting")
        .range(Some(1.0e-12), Some(1.0e-3)),
    // The rod's port to a multibody host (appended; docs/coupling.md). x_rod's range is the
    // longest stroke's; once the geometry is known it is checked against the stroke and the
    // end stops' largest penetration (the chamber's dead volume). v_rod: 10 m/s is far
    // beyond any servo cylinder's speed (this one's valve moves the piston at ~1.3 m/s).
    CYLINDER_PORT => param[cylinder.port] coded: enumeration("cylinder.port", &ROD_PORT_TYPE, "How the rod meets its load: force (the FMU moves cylinder.mass under F_ext) or motion (the host moves the rod by x_rod, v_rod and takes F_rod)"),
    X_ROD => input[x_rod] real: input("x_rod", "m", Some("mm"), "Rod position from the host at the communication point, 0 = mid-stroke (cylinder.port = motion)")
        .range(Some(-MAX_STROKE), Some(MAX_STROKE)),
    V_ROD => input[v_rod] real: input("v_rod", "m/s", None, "Rod velocity from the host at the communication point; the rod moves as x_rod + v_rod (t - t_k) over the step (cylinder.port = motion)")
        .range(Some(-MAX_ROD_SPEED), Some(MAX_ROD_SPEED)),
    F_ROD => output[f_rod] real: output("F_rod", "N", None, "Force of the actuator on the rod in +x (hydraulic force, friction, end stops): its mean over the last step"),
    DF_ROD_DX => output[df_rod_dx] real: output("dF_rod_dx", "N/m", None, "Local stiffness of F_rod to the rod position at the step's end (oil columns and end stops)"),
    DF_ROD_DV => output[df_rod_dv] real: output("dF_rod_dv", "N.s/m", None, "Local damping of F_rod to the rod velocity at the step's end (friction and end stops)"),
    // The integrator (appended; docs/solvers.md): exact for design studies and the paper's
    // figures, fixed_cost for real-time rigs and long robot runs.
    SOLVER_METHOD => param[solver_method] coded: enumeration("solver.method", &SOLVER_METHOD_TYPE, "Integrator: exact (results independent of the communication step) or fixed_cost (work fixed by the step size, for real-time rigs)"),
    // fixed_cost's internal step (appended). The default 5e-5 s is the digital loops' period:
    // one internal step per loop sample, two per 1e-4 s communication step. The accuracy goes
    // with its square on smooth motion (the trapezoidal step), the cost with its inverse:
    // docs/solvers.md gives the curve to pick a point on.
    SOLVER_H_INTERNAL => param[solver_h_internal] real: param("solver.h_internal", Some("s"), "Longest internal step of solver.method = fixed_cost: each span between time events is cut into equal steps no longer than this; not read by exact")
        .range(Some(1.0e-6), Some(1.0e-3)),

    // A valve from its datasheet (issue 44; appended): docs/model.md, "The valve from its
    // datasheet". Rated flows up to 1e-2 m3/s (600 L/min, beyond any two-stage servo valve
    // this model describes); rated currents from 0.1 mA to i_ref's limit; the frequencies up
    // to 10 kHz, ten times the fastest servo valve's.
    VALVE_PARAMETERIZATION => param[valve.parameterization] coded: enumeration("valve.parameterization", &VALVE_PARAMETERIZATION_TYPE, "How the valve is given: gains (valve.K1 ... valve.f_n) or datasheet (valve.Q_rated, i_rated, dp_rated, f_90, f_3dB, zeta; the gains follow at initialisation)"),
    VALVE_Q_RATED => param[valve.datasheet.q_rated] real: param("valve.Q_rated", Some("m3/s"), "Datasheet: no-load flow at valve.i_rated and the total drop valve.dp_rated").positive().range(Some(0.0), Some(1.0e-2)),
    VALVE_I_RATED => param[valve.datasheet.i_rated] real: param("valve.i_rated", Some("A"), "Datasheet: rated current").range(Some(1.0e-4), Some(10.0 * VALVE_RATED_CURRENT)),
    VALVE_F_90 => param[valve.datasheet.f_90] real: param("valve.f_90", Some("Hz"), "Datasheet: frequency at which Q_valve/i_coil lags 90 degrees (small signal, ideal current)").range(Some(DATASHEET_HZ.0), Some(DATASHEET_HZ.1)),
    VALVE_F_3DB => param[valve.datasheet.f_3db] real: param("valve.f_3dB", Some("Hz"), "Datasheet: frequency at which |Q_valve/i_coil| is 3 dB down (0: not given, the first stage keeps the Moog 30's ratio of its natural frequency to the spool loop's bandwidth)").non_negative().range(Some(0.0), Some(DATASHEET_HZ.1)),
    // Laps up to MAX_LAP either way (a spool's stroke is a few mm).
    VALVE_LAP => param[valve.lap] real: param("valve.lap", Some("m"), "Spool lap at null: > 0 underlap (null leakage, finite pressure gain), < 0 overlap (dead band), 0 critically centred; in datasheet form valve.Q_leak_null may set it instead").range(Some(-MAX_LAP), Some(MAX_LAP)),
    // Null leakage up to 1e-3 m3/s (60 L/min): a valve's whole rated flow.
    VALVE_Q_LEAK_NULL => param[valve.datasheet.q_leak_null] real: param("valve.Q_leak_null", Some("m3/s"), "Datasheet: null leakage supply to tank, spool centred, ports blocked, at valve.p_leak_ref (0: not given, no leakage)").non_negative().range(Some(0.0), Some(1.0e-3)),
    VALVE_P_LEAK_REF => param[valve.datasheet.p_leak_ref] real: param("valve.p_leak_ref", Some("Pa"), "Supply pressure above tank at which valve.Q_leak_null and valve.pressure_gain are stated (and valve.derived.* reported)").range(Some(1.0e5), Some(1.0e8)),
    // Pressure gains up to 1e14 Pa/A: 1000 bar across the ports per 1 uA.
    VALVE_PRESSURE_GAIN => param[valve.datasheet.pressure_gain] real: param("valve.pressure_gain", Some("Pa/A"), "Datasheet: blocked-port pressure gain d(p_A - p_B)/di at null at valve.p_leak_ref (0: what the leakage gives); the rest of the leakage is pilot flow").non_negative().range(Some(0.0), Some(1.0e14)),
    Q_SUPPLY => output[q_supply] real: output("Q_supply", "m3/s", Some("L/min"), "Flow drawn from the supply: through the P->A and P->B metering edges and the first stage's pilot flow"),
    // What the valve's gains amount to (both parameterizations), read after initialisation.
    VALVE_DERIVED_K1 => calc[k1] real: calculated("valve.derived.K1", Some("N.m/A"), "Torque-motor gain in use (datasheet form: Kw x_r/i_rated, x_r the Moog 30's rated spool stroke)"),
    VALVE_DERIVED_KW => calc[kw] real: calculated("valve.derived.Kw", Some("N.m/m"), "Feedback-wire stiffness in use"),
    VALVE_DERIVED_K2 => calc[k2] real: calculated("valve.derived.K2", Some("m2/s"), "Hydraulic-amplifier flow gain in use (datasheet form: A_s Kf/(Kw tau))"),
    VALVE_DERIVED_K3 => calc[k3] real: calculated("valve.derived.K3", Some("m2/s"), "Spool flow gain in use (datasheet form: Q_rated/x_r)"),
    VALVE_DERIVED_F_N => calc[f_n] real: calculated("valve.derived.f_n", Some("Hz"), "First-stage natural frequency in use"),
    VALVE_DERIVED_TAU => calc[tau] real: calculated("valve.derived.tau", Some("s"), "Time constant of the spool loop, A_s Kf/(Kw K2)"),
    VALVE_DERIVED_F_90 => calc[f_90] real: calculated("valve.derived.f_90", Some("Hz"), "Frequency at which Q_valve/i_coil lags 90 degrees (small signal, ideal current; 0: never)"),
    VALVE_DERIVED_F_3DB => calc[f_3db] real: calculated("valve.derived.f_3dB", Some("Hz"), "Frequency at which |Q_valve/i_coil| is first 3 dB down"),
    VALVE_DERIVED_LAP => calc[lap] real: calculated("valve.derived.lap", Some("m"), "Spool lap in use"),
    VALVE_DERIVED_Q_LEAK_NULL => calc[q_leak_null] real: calculated("valve.derived.Q_leak_null", Some("m3/s"), "Null leakage at valve.p_leak_ref, ports blocked: the lap's and the pilot's"),
    VALVE_DERIVED_Q_PILOT => calc[q_pilot] real: calculated("valve.derived.Q_pilot", Some("m3/s"), "First-stage pilot flow, supply to tank, at valve.p_leak_ref"),
    VALVE_DERIVED_PRESSURE_GAIN => calc[pressure_gain] real: calculated("valve.derived.pressure_gain", Some("Pa/A"), "Blocked-port pressure gain at null at valve.p_leak_ref (0: unbounded, no underlap)"),
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
        for (value, name, _) in e.valued_items() {
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
        assert_eq!(N_VARIABLES, 110);
    }

    /// Users' scripts and saved states hold value references: every variable keeps its row.
    #[test]
    fn value_references_never_move() {
        let names: Vec<&str> = VARIABLES.iter().map(|v| v.name).collect();
        let pinned = [
            "time",
            "i_ref",
            "V_supply",
            "i_coil",
            "u_driver",
            "driver_saturated",
            "x_flapper",
            "x_spool",
            "Q_valve",
            "driver",
            "control_mode",
            "driver.Kp",
            "driver.Ki",
            "driver.V_drop",
            "driver.slew_rate",
            "coil.L",
            "coil.R",
            "coil.R_sense",
            "coil.K_b",
            "valve.K1",
            "valve.Kf",
            "valve.Kw",
            "valve.K2",
            "valve.K3",
            "valve.A_s",
            "valve.zeta",
            "valve.f_n",
            "industrial.Kp",
            "industrial.Ki",
            "industrial.slew_rate",
            "hbridge.f_pwm",
            "hbridge.f_sample",
            "hbridge.Kp",
            "hbridge.Ki",
            "hbridge.feedforward",
            "valve.x_flapper_max",
            "valve.x_spool_max",
            "p_supply",
            "F_ext",
            "Q_ref",
            "x_ref",
            "Q_A",
            "Q_B",
            "p_A",
            "p_B",
            "x_piston",
            "v_piston",
            "F_hydraulic",
            "cylinder.bore",
            "cylinder.rod",
            "cylinder.stroke",
            "cylinder.mass",
            "cylinder.beta",
            "cylinder.V_dead",
            "cylinder.b_viscous",
            "cylinder.F_coulomb",
            "cylinder.F_static",
            "cylinder.v_stribeck",
            "cylinder.v_friction_smooth",
            "cylinder.k_endstop",
            "cylinder.c_endstop",
            "cylinder.C_leak",
            "cylinder.C_leak_external",
            "valve.dp_rated",
            "valve.dp_laminar",
            "hydraulics.p_tank",
            "hydraulics.p_cavitation",
            "hydraulics.dp_cavitation_band",
            "loop.f_sample",
            "loop.i_max",
            "flow.Kp",
            "flow.Ki",
            "flow.Kd",
            "position.Kp",
            "position.Ki",
            "position.Kd",
            "relief.p_crack",
            "relief.dp_override",
            "relief.Q_rated",
            "solver.rtol",
            "cylinder.port",
            "x_rod",
            "v_rod",
            "F_rod",
            "dF_rod_dx",
            "dF_rod_dv",
            "solver.method",
            "solver.h_internal",
            "valve.parameterization",
            "valve.Q_rated",
            "valve.i_rated",
            "valve.f_90",
            "valve.f_3dB",
            "valve.lap",
            "valve.Q_leak_null",
            "valve.p_leak_ref",
            "valve.pressure_gain",
            "Q_supply",
            "valve.derived.K1",
            "valve.derived.Kw",
            "valve.derived.K2",
            "valve.derived.K3",
            "valve.derived.f_n",
            "valve.derived.tau",
            "valve.derived.f_90",
            "valve.derived.f_3dB",
            "valve.derived.lap",
            "valve.derived.Q_leak_null",
            "valve.derived.Q_pilot",
            "valve.derived.pressure_gain",
        ];
        assert_eq!(names[..pinned.len()], pinned);
    }

    #[test]
    fn enumerations_list_the_physics_items_in_their_order() {
        assert_eq!(DRIVER_TYPE.items.len(), DriverKind::ALL.len());
        assert_eq!(CONTROL_MODE_TYPE.items.len(), ControlMode::ALL.len());
        for (kind, (name, _)) in DriverKind::ALL.iter().zip(DRIVER_TYPE.items) {
            assert_eq!(DriverKind::from_code(kind.code()), Ok(*kind), "{name}");
        }
        assert_eq!(DriverKind::ALL[4], DriverKind::HBridge);
        assert_eq!(DRIVER_TYPE.items[4].0, "hbridge_pid");
        assert_eq!(ControlMode::ALL[2], ControlMode::Position);
        assert_eq!(CONTROL_MODE_TYPE.items[2].0, "position");
        assert!(DriverKind::from_code(5.0).unwrap_err().contains("driver = 5"));
        assert!(ControlMode::from_code(-1.0).is_err());
        assert_eq!(VARIABLES[vr::DRIVER].max, Some(4.0));
        for (form, (name, _)) in
            ValveParameterization::ALL.iter().zip(VALVE_PARAMETERIZATION_TYPE.items)
        {
            assert_eq!(ValveParameterization::from_code(form.code()), Ok(*form), "{name}");
        }
        assert_eq!(VALVE_PARAMETERIZATION_TYPE.items[1].0, "datasheet");
    }

    #[test]
    fn the_binding_reads_and_writes_the_typed_fields() {
        assert_eq!(params(&start_values()), Ok(Params::PAPER));
        assert_eq!(inputs(&start_values()), Inputs::PAPER);
        let mut values = start_values();
        values[vr::DRIVER] = 3.0;
        values[vr::INDUSTRIAL_KP] = 1234.0;
        values[vr::POSITION_KD] = 0.5;
        values[vr::HBRIDGE_FEEDFORWARD] = 0.0;
        values[vr::X_REF] = 0.01;
        let p = params(&values).unwrap();
        assert_eq!(p.driver, DriverKind::Industrial);
        assert_eq!(p.industrial.kp, 1234.0);
        assert_eq!(p.outer_loop.position, [1.0, 0.0, 0.5]);
        assert!(!p.hbridge.feedforward);
        assert_eq!(inputs(&values).x_ref, 0.01);
        let outputs =
            Outputs { driver_saturated: true, p_b: 7.0, f_hydraulic: 9.0, ..Outputs::default() };
        write_outputs(&outputs, &mut values);
        assert_eq!(
            (values[vr::DRIVER_SATURATED], values[vr::P_B], values[vr::F_HYDRAULIC]),
            (1.0, 7.0, 9.0)
        );
        assert_eq!(values[vr::P_A], 0.0);
    }

    #[test]
    fn start_values_pass_their_own_checks() {
        for v in VARIABLES.iter().filter(|v| v.has_start()) {
            v.check(v.start).unwrap();
        }
    }

    #[test]
    fn a_value_the_set_rule_surely_accepts_passes_the_check() {
        for (v, rule) in VARIABLES.iter().zip(SET_RULES.iter()) {
            assert_eq!(rule.may_be_set(false), v.may_be_set(false), "{}", v.name);
            assert_eq!(rule.may_be_set(true), v.may_be_set(true), "{}", v.name);
            assert_eq!(rule.parameter, v.causality == Parameter, "{}", v.name);
            let mut probes = vec![0.0, -0.0, 1.0, -1.0, v.start, f64::NAN, f64::INFINITY];
            probes.extend([f64::NEG_INFINITY, f64::MAX, f64::MIN, f64::MIN_POSITIVE, 5e-324]);
            for bound in [v.min, v.max].into_iter().flatten() {
                probes.extend([bound, bound.next_up(), bound.next_down(), -bound]);
            }
            for value in probes {
                let checked = v.check(value).is_ok();
                if rule.surely_accepts(value) {
                    assert!(checked, "{} = {value} passes the rule, not the check", v.name);
                } else if v.ty == VarType::Real {
                    assert!(!checked, "{} = {value} passes the check, not the rule", v.name);
                }
            }
        }
    }

    #[test]
    fn check_names_variable_and_range() {
        let l = &VARIABLES[vr::COIL_L];
        let msg = l.check(-1.0).unwrap_err();
        assert!(msg.contains("coil.L = -1 rejected") && msg.contains("[1e-4, 1000]"), "{msg}");
        assert!(l.check(f64::NAN).unwrap_err().contains("NaN rejected: the value must be finite"));
        let slew = VARIABLES[vr::DRIVER_SLEW_RATE].check(1e300).unwrap_err();
        assert_eq!(slew, "driver.slew_rate = 1e300 rejected: allowed range is (0, 1e10]");
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
