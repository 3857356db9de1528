//! FMI 3.0 `terminalsAndIcons/terminalsAndIcons.xml`: the variables grouped the way a
//! diagram connects them (fmi3TerminalsAndIcons.xsd, fmi3Terminal.xsd). The rod is a
//! causal mechanical flange (position and velocity out, force in); the other terminals are
//! signal buses of the commands, the supplies and the measured valve and cylinder signals.

use super::*;

/// (terminal name, matchingRule, terminalKind, description, members (memberName, variable)).
type TerminalRow = (
    &'static str,
    &'static str,
    &'static str,
    &'static str,
    &'static [(&'static str, &'static str)],
);

const TERMINALS: &[TerminalRow] = &[
    (
        "command",
        "bus",
        "signal",
        "Commands: coil current, valve flow, piston position (control_mode selects one)",
        &[("i_ref", "i_ref"), ("Q_ref", "Q_ref"), ("x_ref", "x_ref")],
    ),
    (
        "supply",
        "bus",
        "signal",
        "Driver supply voltage and hydraulic supply pressure",
        &[("V_supply", "V_supply"), ("p_supply", "p_supply")],
    ),
    (
        "rod",
        "plug",
        "mechanical.translational",
        "Piston rod: position and velocity out, external force in",
        &[("s", "x_piston"), ("v", "v_piston"), ("f", "F_ext")],
    ),
    (
        "valve",
        "bus",
        "signal",
        "Driver, coil and servo-valve signals",
        &[
            ("i_coil", "i_coil"),
            ("u_driver", "u_driver"),
            ("driver_saturated", "driver_saturated"),
            ("x_flapper", "x_flapper"),
            ("x_spool", "x_spool"),
            ("Q_valve", "Q_valve"),
        ],
    ),
    (
        "cylinder",
        "bus",
        "signal",
        "Chamber flows and pressures, hydraulic force",
        &[
            ("Q_A", "Q_A"),
            ("Q_B", "Q_B"),
            ("p_A", "p_A"),
            ("p_B", "p_B"),
            ("F_hydraulic", "F_hydraulic"),
        ],
    ),
];

#[derive(Serialize)]
#[serde(rename = "fmiTerminalsAndIcons")]
struct TerminalsAndIcons {
    #[serde(rename = "@fmiVersion")]
    fmi_version: &'static str,
    #[serde(rename = "Terminals")]
    terminals: Terminals,
}

#[derive(Serialize)]
struct Terminals {
    #[serde(rename = "Terminal")]
    terminals: Vec<Terminal>,
}

#[derive(Serialize)]
struct Terminal {
    #[serde(rename = "@name")]
    name: &'static str,
    #[serde(rename = "@matchingRule")]
    matching_rule: &'static str,
    #[serde(rename = "@terminalKind")]
    terminal_kind: &'static str,
    #[serde(rename = "@description")]
    description: &'static str,
    #[serde(rename = "TerminalMemberVariable")]
    members: Vec<Member>,
}

#[derive(Serialize)]
struct Member {
    #[serde(rename = "@variableName")]
    variable_name: &'static str,
    #[serde(rename = "@memberName")]
    member_name: &'static str,
    #[serde(rename = "@variableKind")]
    variable_kind: &'static str,
}

/// `terminalsAndIcons/terminalsAndIcons.xml` of the FMI 3.0 archive.
pub fn terminals_and_icons_xml() -> String {
    let terminal = |&(name, matching_rule, terminal_kind, description, members): &TerminalRow| {
        let members = members
            .iter()
            .map(|&(member_name, variable_name)| {
                assert!(VARIABLES.iter().any(|v| v.name == variable_name), "{variable_name}");
                Member { variable_name, member_name, variable_kind: "signal" }
            })
            .collect();
        Terminal { name, matching_rule, terminal_kind, description, members }
    };
    to_xml(&TerminalsAndIcons {
        fmi_version: "3.0",
        terminals: Terminals { terminals: TERMINALS.iter().map(terminal).collect() },
    })
}
