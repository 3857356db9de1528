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
    pub fn check(&self, value: f64) -> Result<(), String> {
        if !value.is_finite() {
            return Err(format!("{} = {value} rejected: the value must be finite", self.name));
        }
        match self.ty {
            VarType::Boolean if value != 0.0 && value != 1.0 => {
                return Err(format!("{} = {value} rejected: a Boolean is 0 or 1", self.name));
            }
            VarType::Enumeration(_) if value.fract() != 0.0 => {
                return Err(format!(
                    "{} = {value} rejected: an enumeration value is an integer",
                    self.name
                ));
            }
            _ => {}
        }
        let below = match self.min {
            Some(min) if self.min_exclusive => value <= min,
            Some(min) => value < min,
            None => false,
        };
        let above = matches!(self.max, Some(max) if value > max);
        if below || above {
            return Err(format!(
                "{} = {value} rejected: allowed range is {}",
                self.name,
                self.range_text()
            ));
        }
        Ok(())
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
}

/// Index (= value reference) of every variable, so code names variables, never numbers.
pub mod vr {
    pub const TIME: usize = 0;
    pub const I_REF: usize = 1;
    pub const V_SUPPLY: usize = 2;
    pub const I_COIL: usize = 3;
    pub const U_DRIVER: usize = 4;
    pub const DRIVER_SATURATED: usize = 5;
    pub const X_FLAPPER: usize = 6;
    pub const X_SPOOL: usize = 7;
    pub const Q_VALVE: usize = 8;
    pub const DRIVER: usize = 9;
    pub const CONTROL_MODE: usize = 10;
    pub const DRIVER_KP: usize = 11;
    pub const DRIVER_KI: usize = 12;
    pub const DRIVER_V_DROP: usize = 13;
    pub const DRIVER_SLEW_RATE: usize = 14;
    pub const COIL_L: usize = 15;
    pub const COIL_R: usize = 16;
    pub const COIL_R_SENSE: usize = 17;
    pub const COIL_K_B: usize = 18;
    pub const VALVE_K1: usize = 19;
    pub const VALVE_KF: usize = 20;
    pub const VALVE_KW: usize = 21;
    pub const VALVE_K2: usize = 22;
    pub const VALVE_K3: usize = 23;
    pub const VALVE_A_S: usize = 24;
    pub const VALVE_ZETA: usize = 25;
    pub const VALVE_F_N: usize = 26;
    pub const INDUSTRIAL_KP: usize = 27;
    pub const INDUSTRIAL_KI: usize = 28;
    pub const INDUSTRIAL_SLEW_RATE: usize = 29;
    pub const HBRIDGE_F_PWM: usize = 30;
    pub const HBRIDGE_F_SAMPLE: usize = 31;
    pub const HBRIDGE_KP: usize = 32;
    pub const HBRIDGE_KI: usize = 33;
    pub const HBRIDGE_FEEDFORWARD: usize = 34;
    pub const VALVE_X_FLAPPER_MAX: usize = 35;
    pub const VALVE_X_SPOOL_MAX: usize = 36;
    pub const P_SUPPLY: usize = 37;
    pub const F_EXT: usize = 38;
    pub const Q_REF: usize = 39;
    pub const X_REF: usize = 40;
    pub const Q_A: usize = 41;
    pub const Q_B: usize = 42;
    pub const P_A: usize = 43;
    pub const P_B: usize = 44;
    pub const X_PISTON: usize = 45;
    pub const V_PISTON: usize = 46;
    pub const F_HYDRAULIC: usize = 47;
    pub const CYLINDER_BORE: usize = 48;
    pub const CYLINDER_ROD: usize = 49;
    pub const CYLINDER_STROKE: usize = 50;
    pub const CYLINDER_MASS: usize = 51;
    pub const CYLINDER_BETA: usize = 52;
    pub const CYLINDER_V_DEAD: usize = 53;
    pub const CYLINDER_B_VISCOUS: usize = 54;
    pub const CYLINDER_F_COULOMB: usize = 55;
    pub const CYLINDER_F_STATIC: usize = 56;
    pub const CYLINDER_V_STRIBECK: usize = 57;
    pub const CYLINDER_V_FRICTION_SMOOTH: usize = 58;
    pub const CYLINDER_K_ENDSTOP: usize = 59;
    pub const CYLINDER_C_ENDSTOP: usize = 60;
    pub const CYLINDER_C_LEAK: usize = 61;
    pub const CYLINDER_C_LEAK_EXTERNAL: usize = 62;
    pub const VALVE_DP_RATED: usize = 63;
    pub const VALVE_DP_LAMINAR: usize = 64;
    pub const HYDRAULICS_P_TANK: usize = 65;
    pub const HYDRAULICS_P_CAVITATION: usize = 66;
    pub const HYDRAULICS_DP_CAVITATION_BAND: usize = 67;
    pub const LOOP_F_SAMPLE: usize = 68;
    pub const LOOP_I_MAX: usize = 69;
    pub const FLOW_KP: usize = 70;
    pub const FLOW_KI: usize = 71;
    pub const FLOW_KD: usize = 72;
    pub const POSITION_KP: usize = 73;
    pub const POSITION_KI: usize = 74;
    pub const POSITION_KD: usize = 75;
}

pub const N_VARIABLES: usize = 76;

pub static VARIABLES: [Variable; N_VARIABLES] = [
    Variable {
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
    input("i_ref", "A", Some("mA"), 0.0, "Coil current command (used when control_mode = current)"),
    input("V_supply", "V", None, 72.0, "Driver supply: the output rails are at +V_supply and -V_supply")
        .range(Some(0.0), Some(1000.0)),
    // Outputs
    output("i_coil", "A", Some("mA"), "Torque-motor coil current"),
    output("u_driver", "V", None, "Driver output voltage across coil and sense resistor"),
    Variable {
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
    output("x_flapper", "m", Some("um"), "Armature/flapper displacement at the nozzles"),
    output("x_spool", "m", Some("mm"), "Main spool displacement"),
    output("Q_valve", "m3/s", Some("L/min"), "No-load valve flow K3*x_spool (the paper's hydraulic-amplifier load flow)"),
    // Structural parameters
    Variable {
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
    Variable {
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
    param("driver.Kp", Some("V/A"), 1.6e5, "Op-amp PI proportional gain (= G*R_s; the paper's linear analysis writes R_s)")
        .non_negative(),
    param("driver.Ki", Some("V/(A.s)"), 5.0e7, "Op-amp PI integral gain (= G*R_s/(R_f*C_f)); default Ki/Kp = R/L cancels the coil pole")
        .non_negative(),
    param("driver.V_drop", Some("V"), 0.0, "Output stage drop: the output saturates at +-(V_supply - V_drop)")
        .non_negative(),
    param("driver.slew_rate", Some("V/s"), 2.0e7, "Op-amp output slew-rate limit (20 V/us)").positive(),
    // Coil
    param("coil.L", Some("H"), 3.2, "Torque-motor coil (apparent) inductance").positive(),
    param("coil.R", Some("Ohm"), 1000.0, "Torque-motor coil resistance").positive(),
    param("coil.R_sense", Some("Ohm"), 0.0, "Current-sense resistor in series with the coil").non_negative(),
    param("coil.K_b", Some("V.s/m"), 0.0, "Back-EMF constant on the flapper velocity (0: already in the apparent inductance)")
        .non_negative(),
    // Valve (Moog 30 linear model)
    param("valve.K1", Some("N.m/A"), 2.82462, "Torque-motor gain (0.025 in-lb/mA)").positive(),
    param("valve.Kf", Some("N.m/m"), 511.545, "Net stiffness on flapper/armature (115 in-lb/in)").positive(),
    param("valve.Kw", Some("N.m/m"), 74.2853, "Feedback wire stiffness (16.7 in-lb/in)").positive(),
    param("valve.K2", Some("m2/s"), 0.0967740, "Hydraulic amplifier flow gain (150 in3/s/in)").positive(),
    param("valve.K3", Some("m2/s"), 0.664515, "Spool/bushing flow gain (1030 in3/s/in)").positive(),
    param("valve.A_s", Some("m2"), 1.67742e-5, "Spool end area (0.026 in2)").positive(),
    param("valve.zeta", None, 0.4, "Damping ratio of the first stage").range(Some(0.0), Some(10.0)),
    param("valve.f_n", Some("Hz"), 814.0, "Natural frequency of the first stage").positive(),
    // Industrial linear current amplifier (driver 3): a PI loop like the op-amp driver's
    // but with the slow gains of an off-the-shelf unit. L/Kp = 1.28 ms gives the My-502's
    // 5 ms (2 %) settling; Ki/Kp = R/L cancels the coil pole.
    param("industrial.Kp", Some("V/A"), 2500.0, "Industrial amplifier proportional gain").non_negative(),
    param("industrial.Ki", Some("V/(A.s)"), 781250.0, "Industrial amplifier integral gain").non_negative(),
    param("industrial.slew_rate", Some("V/s"), 1.0e6, "Industrial amplifier output slew-rate limit (1 V/us)").positive(),
    // H-bridge with PWM and a digital PI current loop (driver 4).
    param("hbridge.f_pwm", Some("Hz"), 20000.0, "PWM switching frequency (bipolar, centre-aligned)")
        .positive()
        .range(Some(0.0), Some(1.0e6)),
    param("hbridge.f_sample", Some("Hz"), 20000.0, "Sampling rate of the digital PI current loop (one-sample computation delay)")
        .positive()
        .range(Some(0.0), Some(1.0e6)),
    // With feed-forward and Ki/Kp = R/L, a 5 mA step at 12 V runs at 100 % duty to ~4.2 mA
    // (the supply limits the slope, as on the paper's bench), then the loop closes with
    // L/Kp = 0.36 ms: 1.9 ms settling of the period-averaged current.
    param("hbridge.Kp", Some("V/A"), 9000.0, "Digital PI proportional gain").non_negative(),
    param("hbridge.Ki", Some("V/(A.s)"), 2812500.0, "Digital PI integral gain").non_negative(),
    Variable {
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
    param("valve.x_flapper_max", Some("m"), 0.0, "Flapper travel limit at the nozzles, inelastic stop (0: none)").non_negative(),
    param("valve.x_spool_max", Some("m"), 0.0, "Spool travel limit, inelastic stop (0: none)").non_negative(),
    // Cylinder side: inputs and outputs.
    input("p_supply", "Pa", Some("bar"), 6.8948e6, "Hydraulic supply pressure, gauge (1000 psi: the valve's rated drop, so the no-load flow is K3*x_spool)")
        .range(Some(0.0), Some(1.0e8)),
    input("F_ext", "N", None, 0.0, "External force on the rod, positive in the direction of +x (extension)"),
    input("Q_ref", "m3/s", Some("L/min"), 0.0, "Valve flow command (used when control_mode = flow)"),
    input("x_ref", "m", Some("mm"), 0.0, "Piston position command, 0 = mid-stroke (used when control_mode = position)"),
    output("Q_A", "m3/s", Some("L/min"), "Actual flow into chamber A"),
    output("Q_B", "m3/s", Some("L/min"), "Actual flow out of chamber B"),
    output("p_A", "Pa", Some("bar"), "Chamber A (piston side) pressure, gauge"),
    output("p_B", "Pa", Some("bar"), "Chamber B (rod side) pressure, gauge"),
    output("x_piston", "m", Some("mm"), "Piston position, 0 = mid-stroke, positive = extension"),
    output("v_piston", "m/s", None, "Piston velocity"),
    output("F_hydraulic", "N", None, "Hydraulic force p_A*A_A - p_B*A_B"),
    // Cylinder, load and hydraulic fluid.
    param("cylinder.bore", Some("m"), 0.016, "Piston (bore) diameter").positive(),
    param("cylinder.rod", Some("m"), 0.010, "Rod diameter (single rod on the B side; 0 gives equal areas)").non_negative(),
    param("cylinder.stroke", Some("m"), 0.080, "Full stroke; x_piston = 0 at mid-stroke, end stops at +-stroke/2").positive(),
    param("cylinder.mass", Some("kg"), 5.0, "Moving mass of piston, rod and load").positive(),
    param("cylinder.beta", Some("Pa"), 1.0e9, "Effective bulk modulus of oil, hoses and walls").positive(),
    param("cylinder.V_dead", Some("m3"), 2.0e-6, "Dead volume of each chamber at its end of stroke (ports, hoses)").positive(),
    param("cylinder.b_viscous", Some("N.s/m"), 200.0, "Viscous friction coefficient").non_negative(),
    param("cylinder.F_coulomb", Some("N"), 20.0, "Coulomb friction force").non_negative(),
    param("cylinder.F_static", Some("N"), 30.0, "Breakaway (static) friction force: peak of the Stribeck curve").non_negative(),
    param("cylinder.v_stribeck", Some("m/s"), 0.01, "Stribeck velocity: friction falls from F_static to F_coulomb over this speed").positive(),
    param("cylinder.v_friction_smooth", Some("m/s"), 1.0e-4, "Creep velocity scale of tanh(v/v) replacing sign(v) in the friction (no sticking singularity)").positive(),
    param("cylinder.k_endstop", Some("N/m"), 1.0e8, "End-stop contact stiffness beyond +-stroke/2").positive(),
    param("cylinder.c_endstop", Some("N.s/m"), 1.0e4, "End-stop contact damping (only while penetrating; the contact never pulls)").non_negative(),
    param("cylinder.C_leak", Some("m3/(s.Pa)"), 0.0, "Internal leakage coefficient across the piston, A to B").non_negative(),
    param("cylinder.C_leak_external", Some("m3/(s.Pa)"), 0.0, "External leakage coefficient from each chamber to the drain at p_tank").non_negative(),
    param("valve.dp_rated", Some("Pa"), 6.8948e6, "Total rated valve pressure drop (1000 psi): the no-load flow K3*x_s is specified at this drop").positive(),
    param("valve.dp_laminar", Some("Pa"), 1.0e5, "Port pressure drop below which the orifice flow law is regularised (laminar, finite slope)").positive(),
    param("hydraulics.p_tank", Some("Pa"), 0.0, "Tank (return) pressure, gauge").range(Some(-1.01325e5), None),
    param("hydraulics.p_cavitation", Some("Pa"), -0.9e5, "Cavitation floor (gauge; -0.9e5 = 0.1 bar absolute): chamber pressures never fall below it").range(Some(-1.01325e5), None),
    param("hydraulics.dp_cavitation_band", Some("Pa"), 5.0e4, "Pressure band above the floor over which an emptying chamber's bulk modulus fades to zero").positive(),
    // Outer loops (control_mode 1 flow, 2 position): a digital PID producing the current command.
    param("loop.f_sample", Some("Hz"), 20000.0, "Sampling rate of the outer flow/position PID (the command is held between samples)")
        .positive()
        .range(Some(0.0), Some(1.0e6)),
    param("loop.i_max", Some("A"), 0.01, "Limit of the current command from the outer loops (rated current)").positive(),
    // Flow defaults, a gentle P on top of the exact feed-forward like the paper's untuned
    // loop: a 2e-4 m3/s step settles in 3.37 ms at 72 V and 6.08 ms at 10 V (180 %; paper
    // 3.3 ms, 6 ms, 181 %). With the feed-forward exact, P alone leaves no steady-state
    // error; an integral adds a slow tail (the area it collects in the transient) and winds
    // up against the 10 V supply limit, where the coil current can only rise with L/R.
    param("flow.Kp", Some("A.s/m3"), 2.0, "Flow PID proportional gain (on Q_ref - Q_valve; feed-forward Q_ref/(K3*K1/Kw) added)"),
    param("flow.Ki", Some("A/m3"), 0.0, "Flow PID integral gain"),
    param("flow.Kd", Some("A.s2/m3"), 0.0, "Flow PID derivative gain"),
    // Position defaults: P only (1 mA per mm). The valve-controlled cylinder integrates flow,
    // and a critically centred valve holds a constant load with zero flow only at null spool,
    // so P alone has zero steady-state error; Ki is for leakage or a valve offset. Derivative
    // action excites the hydraulic resonance at these gains.
    param("position.Kp", Some("A/m"), 1.0, "Position PID proportional gain (on x_ref - x_piston)"),
    param("position.Ki", Some("A/(m.s)"), 0.0, "Position PID integral gain"),
    param("position.Kd", Some("A.s/m"), 0.0, "Position PID derivative gain"),
];

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
    fn names_unique_and_constants_match_table() {
        for (i, a) in VARIABLES.iter().enumerate() {
            for b in &VARIABLES[i + 1..] {
                assert_ne!(a.name, b.name);
            }
        }
        assert_eq!(index_of("i_ref"), Some(vr::I_REF));
        assert_eq!(index_of("Q_valve"), Some(vr::Q_VALVE));
        assert_eq!(index_of("valve.f_n"), Some(vr::VALVE_F_N));
        assert_eq!(index_of("coil.K_b"), Some(vr::COIL_K_B));
        assert_eq!(index_of("driver"), Some(vr::DRIVER));
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
    fn token_is_a_guid() {
        let t = interface_token();
        assert_eq!(t.len(), 38);
        assert!(t.starts_with('{') && t.ends_with('}'));
    }
}
