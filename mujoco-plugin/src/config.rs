//! A plugin instance's configuration: MJCF `<config key=... value=...>` pairs, whose keys
//! are the FMU's variable names (parameters, and the inputs the host does not drive) plus
//! the plugin's own [`SUBSTEP`] and [`LENGTH_MID`]. Values are numbers, or for an
//! enumeration its item's name. Defaults are the FMU's start values, with
//! `cylinder.port = motion` (the only port a MuJoCo actuator has).

use ehsv_physics::{readable, ControlMode, Params, RodPort};
use ehsv_variables::variables::{
    params, start_values, vr, Causality, Coded, VarType, Variable, ENUMERATIONS, N_VARIABLES,
    VARIABLES,
};

/// The plugin's longest internal step (s); MuJoCo's timestep is cut into equal steps no
/// longer than this.
pub const SUBSTEP: &str = "substep";
/// The actuator length (m, after the gear) at mid-stroke: x_rod = length - length_mid.
pub const LENGTH_MID: &str = "length_mid";
/// Default of [`SUBSTEP`] (s).
pub const DEFAULT_SUBSTEP: f64 = 1e-4;
/// The shortest [`SUBSTEP`] (s), where a sub-step stops making sense: the model's fastest
/// clock ticks at 1 MHz (`loop.f_sample`, `hbridge.f_pwm` and `hbridge.f_sample` end at
/// 1e6 Hz, and the physics cuts its steps at their instants anyway) and fixed_cost's
/// shortest internal step (`solver.h_internal`) is 1 us. A shorter sub-step resolves
/// nothing more and only costs: MuJoCo's step is cut into timestep / substep physics steps,
/// so 1e-300 made the first mj_step run forever and 1e-12 took 11 s for one 1e-4 s step.
/// At 1e-6 a 1e-3 s MuJoCo step is 1000 physics steps.
pub const MIN_SUBSTEP: f64 = 1e-6;
/// The longest [`SUBSTEP`] (s): 10 ms, five times the longest host timestep the robots
/// are shown to stand at (2e-3 s, docs/mujoco.md).
pub const MAX_SUBSTEP: f64 = 0.01;

/// Inputs the host drives (the transmission gives x_rod and v_rod, the control the
/// command), or that mean nothing with the motion port (F_ext): not configurable.
const DRIVEN: [usize; 6] = [vr::I_REF, vr::Q_REF, vr::X_REF, vr::X_ROD, vr::V_ROD, vr::F_EXT];

/// A parsed configuration.
#[derive(Clone, Debug)]
pub struct Config {
    /// The FMU's value array: start values with the configured ones written over them.
    pub values: [f64; N_VARIABLES],
    pub params: Params,
    pub substep: f64,
    pub length_mid: f64,
}

/// Whether variable `index` is a configuration key.
fn configurable(index: usize) -> bool {
    let var = &VARIABLES[index];
    match var.causality {
        Causality::Parameter => true,
        Causality::Input => !DRIVEN.contains(&index),
        _ => false,
    }
}

/// Every configuration key, in table order, then the plugin's own.
pub fn keys() -> Vec<&'static str> {
    let table = (0..VARIABLES.len()).filter(|&i| configurable(i)).map(|i| VARIABLES[i].name);
    table.chain([SUBSTEP, LENGTH_MID]).collect()
}

/// Parses `text` as the value of `var`: a number, `true`/`false` for a Boolean, an item's
/// name or number for an enumeration; checked against the variable's type and range.
fn parse_value(var: &Variable, text: &str) -> Result<f64, String> {
    let text = text.trim();
    let named = match var.ty {
        VarType::Enumeration(type_name) => ENUMERATIONS
            .iter()
            .find(|e| e.name == type_name)
            .and_then(|e| e.valued_items().find(|(_, name, _)| *name == text))
            .map(|(value, _, _)| value as f64),
        VarType::Boolean => match text {
            "true" => Some(1.0),
            "false" => Some(0.0),
            _ => None,
        },
        VarType::Real => None,
    };
    let value = match named {
        Some(value) => value,
        None => text.parse::<f64>().map_err(|_| {
            format!("{} = '{text}' rejected: not a number{}", var.name, items_text(var))
        })?,
    };
    var.check(value)?;
    Ok(value)
}

/// ", nor one of: a, b, c" for an enumeration.
fn items_text(var: &Variable) -> String {
    let VarType::Enumeration(type_name) = var.ty else { return String::new() };
    let names: Vec<&str> = ENUMERATIONS
        .iter()
        .filter(|e| e.name == type_name)
        .flat_map(|e| e.valued_items().map(|(_, name, _)| name))
        .collect();
    format!(", nor one of: {}", names.join(", "))
}

/// A plugin key's value: finite, and a substep within [[`MIN_SUBSTEP`], [`MAX_SUBSTEP`]].
fn parse_own(key: &str, text: &str) -> Result<f64, String> {
    let value: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("{key} = '{}' rejected: not a number", text.trim()))?;
    let fits = match key {
        SUBSTEP => (MIN_SUBSTEP..=MAX_SUBSTEP).contains(&value),
        _ => value.is_finite(),
    };
    if !fits {
        let range = match key {
            SUBSTEP => format!("[{}, {}] s", readable(MIN_SUBSTEP), readable(MAX_SUBSTEP)),
            _ => "a finite length in m".to_string(),
        };
        return Err(format!("{key} = {} rejected: allowed is {range}", readable(value)));
    }
    Ok(value)
}

/// Parses the configuration that `lookup` gives (the value of a key, `None` or empty if
/// absent). Refuses, naming the key, a value out of its type or range, a rod port other
/// than motion, and parameters that do not fit together.
pub fn parse(lookup: impl Fn(&str) -> Option<String>) -> Result<Config, String> {
    let given = |key: &str| lookup(key).filter(|text| !text.trim().is_empty());
    let mut values = start_values();
    values[vr::CYLINDER_PORT] = RodPort::Motion.code();
    for (index, var) in VARIABLES.iter().enumerate().filter(|(i, _)| configurable(*i)) {
        if let Some(text) = given(var.name) {
            values[index] = parse_value(var, &text)?;
        }
    }
    if RodPort::from_code(values[vr::CYLINDER_PORT])? != RodPort::Motion {
        return Err("cylinder.port = force rejected: a MuJoCo actuator drives the rod by its \
                    motion (cylinder.port = motion)"
            .into());
    }
    let substep = given(SUBSTEP).map_or(Ok(DEFAULT_SUBSTEP), |t| parse_own(SUBSTEP, &t))?;
    let length_mid = given(LENGTH_MID).map_or(Ok(0.0), |t| parse_own(LENGTH_MID, &t))?;
    let params = params(&values)?;
    Ok(Config { values, params, substep, length_mid })
}

impl Config {
    /// The control mode, whose command the actuator's control is.
    pub fn control_mode(&self) -> ControlMode {
        self.params.control_mode
    }

    /// The command's variable (x_ref, Q_ref or i_ref) by value reference.
    pub fn command_index(&self) -> usize {
        match self.control_mode() {
            ControlMode::Current => vr::I_REF,
            ControlMode::Flow => vr::Q_REF,
            ControlMode::Position => vr::X_REF,
        }
    }

    /// The command limited to its variable's range (x_ref also to +-stroke/2).
    pub fn clamp_command(&self, ctrl: f64) -> f64 {
        let var = &VARIABLES[self.command_index()];
        let (mut lo, mut hi) = (var.min.unwrap_or(f64::MIN), var.max.unwrap_or(f64::MAX));
        if self.control_mode() == ControlMode::Position {
            let half = 0.5 * self.values[vr::CYLINDER_STROKE];
            (lo, hi) = (lo.max(-half), hi.min(half));
        }
        if ctrl.is_nan() {
            return 0.0;
        }
        ctrl.clamp(lo, hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ehsv_physics::{DriverKind, SolverMethod};
    use std::collections::HashMap;

    fn parse_pairs(pairs: &[(&str, &str)]) -> Result<Config, String> {
        let map: HashMap<String, String> =
            pairs.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
        parse(|key| map.get(key).cloned())
    }

    #[test]
    fn defaults_are_the_fmus_with_the_motion_port() {
        let c = parse_pairs(&[]).unwrap();
        assert_eq!(c.params.cylinder.port, RodPort::Motion);
        assert_eq!(c.params.driver, Params::PAPER.driver);
        assert_eq!(c.params.cylinder.bore, Params::PAPER.cylinder.bore);
        assert_eq!((c.substep, c.length_mid), (DEFAULT_SUBSTEP, 0.0));
    }

    #[test]
    fn enumerations_by_name_or_number_and_reals() {
        let c = parse_pairs(&[
            ("control_mode", "position"),
            ("driver", "0"),
            ("solver.method", "fixed_cost"),
            ("cylinder.bore", " 0.02 "),
            ("position.Kp", "0.6"),
            ("substep", "5e-5"),
            ("length_mid", "0.21"),
            ("cylinder.port", "motion"),
        ])
        .unwrap();
        assert_eq!(c.control_mode(), ControlMode::Position);
        assert_eq!(c.params.driver, DriverKind::ALL[0]);
        assert_eq!(c.params.solver_method, SolverMethod::FixedCost);
        assert_eq!(c.params.cylinder.bore, 0.02);
        assert_eq!(c.params.outer_loop.position[0], 0.6);
        assert_eq!((c.substep, c.length_mid), (5e-5, 0.21));
        assert_eq!(c.command_index(), vr::X_REF);
        assert_eq!(c.clamp_command(1.0), 0.04);
        assert_eq!(c.clamp_command(-1.0), -0.04);
    }

    #[test]
    fn refusals_name_the_key() {
        let cases = [
            ("cylinder.bore", "-1"),
            ("cylinder.bore", "wide"),
            ("driver", "turbo"),
            ("driver", "17"),
            ("control_mode", "1.5"),
            ("solver.method", "euler"),
            ("p_supply", "nan"),
            ("substep", "0"),
            ("substep", "1"),
            ("substep", "1e-300"),
            ("substep", "9.99e-7"),
            ("length_mid", "inf"),
            ("cylinder.port", "force"),
        ];
        for (key, value) in cases {
            let err = parse_pairs(&[(key, value)]).unwrap_err();
            assert!(err.contains(key), "{key} = {value}: {err}");
        }
    }

    /// Numbers in refusals as a person reads them (1e300, not 301 digits).
    #[test]
    fn refusals_print_numbers_readably() {
        let cases = [
            (
                "driver.slew_rate",
                "1e300",
                "driver.slew_rate = 1e300 rejected: allowed range is (0, 1e10]",
            ),
            ("coil.L", "1e-300", "coil.L = 1e-300 rejected: allowed range is [1e-4, 1000]"),
            ("substep", "1e-300", "substep = 1e-300 rejected: allowed is [1e-6, 0.01] s"),
            ("p_supply", "-1e300", "p_supply = -1e300 rejected: allowed range is [0, 1e8]"),
        ];
        for (key, value, message) in cases {
            assert_eq!(parse_pairs(&[(key, value)]).unwrap_err(), message);
        }
        let c = parse_pairs(&[("substep", "1e-6")]).unwrap();
        assert_eq!(c.substep, MIN_SUBSTEP);
    }

    #[test]
    fn keys_are_the_configurable_variables_and_the_plugins_own() {
        let keys = keys();
        for key in ["control_mode", "driver", "p_supply", "cylinder.bore", "position.Kp"] {
            assert!(keys.contains(&key), "{key}");
        }
        for driven in ["x_ref", "Q_ref", "i_ref", "x_rod", "v_rod", "F_ext", "F_rod", "time"] {
            assert!(!keys.contains(&driven), "{driven}");
        }
        assert_eq!(keys[keys.len() - 2..], [SUBSTEP, LENGTH_MID]);
    }
}
