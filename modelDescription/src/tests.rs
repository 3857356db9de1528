//! Parse the rendered XML back with quick-xml's reader and check it against the table.

use super::*;
use quick_xml::events::{BytesStart, Event};
use quick_xml::XmlVersion;
use std::collections::HashMap;

/// Just enough of a DOM for the checks: element name, attributes, children.
#[derive(Debug, Default)]
struct Element {
    name: String,
    attrs: HashMap<String, String>,
    children: Vec<Element>,
}

impl Element {
    fn attr(&self, name: &str) -> &str {
        self.attrs.get(name).unwrap_or_else(|| panic!("<{}> has no {name}", self.name))
    }
    fn child(&self, name: &str) -> &Element {
        self.children
            .iter()
            .find(|c| c.name == name)
            .unwrap_or_else(|| panic!("<{}> has no <{name}>", self.name))
    }
    fn all<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a Element> + 'a {
        self.children.iter().filter(move |c| c.name == name)
    }
}

fn element(start: &BytesStart) -> Element {
    let attrs = start
        .attributes()
        .map(|a| {
            let a = a.expect("well-formed attribute");
            let key = a.key.as_ref().to_string();
            let value =
                a.normalized_value(XmlVersion::Implicit1_0).expect("valid escapes").into_owned();
            (key, value)
        })
        .collect();
    Element { name: start.name().as_ref().to_string(), attrs, children: vec![] }
}

/// Parses the whole document; panics on malformed XML.
fn parse(xml: &str) -> Element {
    let mut reader = quick_xml::Reader::from_str(xml);
    let mut stack = vec![Element::default()];
    loop {
        match reader.read_event().expect("well-formed XML") {
            Event::Start(start) => stack.push(element(&start)),
            Event::Empty(start) => stack.last_mut().unwrap().children.push(element(&start)),
            Event::End(_) => {
                let done = stack.pop().unwrap();
                stack.last_mut().unwrap().children.push(done);
            }
            Event::Eof => break,
            _ => {}
        }
    }
    assert_eq!(stack.len(), 1, "unclosed elements");
    stack.pop().unwrap().children.pop().expect("a root element")
}

fn number(text: &str) -> f64 {
    text.parse().unwrap_or_else(|_| panic!("{text:?} is not a number"))
}

/// Checks both versions share: root, token, units, variable attributes in table order.
fn check_common(root: &Element, token_attribute: &str) {
    assert_eq!(root.name, "fmiModelDescription");
    assert_eq!(root.attr("modelName"), "EhsvActuator");
    assert_eq!(root.attr(token_attribute), ehsv_actuator::variables::interface_token());
    assert_eq!(root.attr("variableNamingConvention"), "structured");
    assert_eq!(root.child("CoSimulation").attr("modelIdentifier"), "EhsvActuator");

    let units = root.child("UnitDefinitions");
    assert_eq!(units.all("Unit").count(), UNITS.len());
    let volt = units.all("Unit").find(|u| u.attr("name") == "V").unwrap();
    let base = &volt.child("BaseUnit").attrs;
    assert_eq!(
        (base["kg"].as_str(), base["m"].as_str(), base["s"].as_str(), base["A"].as_str()),
        ("1", "2", "-3", "-1")
    );
    assert!(!base.contains_key("K"), "zero exponents are omitted");
    let flow = units.all("Unit").find(|u| u.attr("name") == "m3/s").unwrap();
    let lpm = flow.child("DisplayUnit");
    assert_eq!((lpm.attr("name"), number(lpm.attr("factor"))), ("L/min", 6e4));

    let experiment = root.child("DefaultExperiment");
    assert_eq!(number(experiment.attr("stopTime")), 0.01);
    assert_eq!(number(experiment.attr("stepSize")), 1e-4);
}

/// The `<Item>`s of each enumeration type are exactly those of ENUMERATIONS, in order.
fn check_items<'a>(types: impl Iterator<Item = (&'a str, &'a Element)>) {
    let rendered: Vec<(String, Vec<(i64, String)>)> = types
        .map(|(name, items)| {
            let items = items
                .all("Item")
                .map(|i| (i.attr("value").parse().unwrap(), i.attr("name").to_string()));
            (name.to_string(), items.collect())
        })
        .collect();
    let expected: Vec<(String, Vec<(i64, String)>)> = ENUMERATIONS
        .iter()
        .map(|e| {
            (e.name.to_string(), e.valued_items().map(|(v, n, _)| (v, n.to_string())).collect())
        })
        .collect();
    assert_eq!(rendered, expected);
}

/// Attributes of a variable that both versions write the same way.
fn check_variable(element: &Element, index: usize) {
    let v = &VARIABLES[index];
    assert_eq!(element.attr("name"), v.name);
    assert_eq!(element.attr("valueReference"), index.to_string());
    assert_eq!(element.attr("causality"), causality_name(v.causality));
    assert_eq!(element.attr("variability"), variability_name(v.variability));
    assert_eq!(element.attrs.get("initial").map(String::as_str), initial_name(v));
}

/// Attributes of the type element (FMI 2 child, FMI 3 the variable element itself).
fn check_value(value: &Element, v: &Variable) {
    let start = value.attrs.get("start");
    assert_eq!(start.is_some(), v.has_start(), "{}: start", v.name);
    match v.ty {
        VarType::Real => {
            assert_eq!(value.attrs.get("unit").map(String::as_str), v.unit);
            assert_eq!(value.attrs.get("displayUnit").map(String::as_str), v.display_unit);
            if let Some(start) = start {
                assert_eq!(number(start), v.start, "{}: start round-trips", v.name);
            }
            assert_eq!(value.attrs.get("min").map(|m| number(m)), v.min);
            assert_eq!(value.attrs.get("max").map(|m| number(m)), v.max);
        }
        VarType::Boolean => {
            if let Some(start) = start {
                assert_eq!(start, if v.start != 0.0 { "true" } else { "false" });
            }
        }
        VarType::Enumeration(type_name) => {
            assert_eq!(value.attr("declaredType"), type_name);
            if let Some(start) = start {
                assert_eq!(start.parse::<i64>().unwrap() as f64, v.start);
            }
        }
    }
}

#[test]
fn fmi2_matches_table() {
    let xml = fmi2_xml();
    let root = parse(&xml);
    assert_eq!(root.attr("fmiVersion"), "2.0");
    check_common(&root, "guid");
    let cs = root.child("CoSimulation");
    assert_eq!(cs.attr("canGetAndSetFMUstate"), "true");
    assert_eq!(cs.attr("canRunAsynchronuously"), "false");

    let types = root.child("TypeDefinitions").all("SimpleType");
    check_items(types.map(|t| (t.attr("name"), t.child("Enumeration"))));

    let variables: Vec<&Element> = root.child("ModelVariables").all("ScalarVariable").collect();
    assert_eq!(variables.len(), VARIABLES.len());
    for (index, element) in variables.iter().enumerate() {
        check_variable(element, index);
        let v = &VARIABLES[index];
        let type_name = match v.ty {
            VarType::Real => "Real",
            VarType::Boolean => "Boolean",
            VarType::Enumeration(_) => "Enumeration",
        };
        assert_eq!(element.children.len(), 1);
        check_value(element.child(type_name), v);
    }

    // Unknown/@index is 1-based into ModelVariables.
    let structure = root.child("ModelStructure");
    let outputs: Vec<usize> = structure
        .child("Outputs")
        .all("Unknown")
        .map(|u| u.attr("index").parse().unwrap())
        .collect();
    let expected: Vec<usize> = (0..VARIABLES.len())
        .filter(|&i| VARIABLES[i].causality == Causality::Output)
        .map(|i| i + 1)
        .collect();
    assert!(!outputs.is_empty());
    assert_eq!(outputs, expected);
    for index in &outputs {
        assert_eq!(variables[index - 1].attr("causality"), "output");
    }
    let initial: Vec<&str> =
        structure.child("InitialUnknowns").all("Unknown").map(|u| u.attr("index")).collect();
    for index in initial {
        assert_eq!(variables[index.parse::<usize>().unwrap() - 1].attr("initial"), "calculated");
    }
}

#[test]
fn fmi3_matches_table() {
    let xml = fmi3_xml();
    let root = parse(&xml);
    assert_eq!(root.attr("fmiVersion"), "3.0");
    check_common(&root, "instantiationToken");
    let cs = root.child("CoSimulation");
    assert_eq!(cs.attr("canGetAndSetFMUState"), "true");
    assert_eq!(cs.attr("hasEventMode"), "false");

    let types = root.child("TypeDefinitions").all("EnumerationType");
    check_items(types.map(|t| (t.attr("name"), t)));

    let variables = &root.child("ModelVariables").children;
    assert_eq!(variables.len(), VARIABLES.len());
    for (index, element) in variables.iter().enumerate() {
        check_variable(element, index);
        let v = &VARIABLES[index];
        let type_name = match v.ty {
            VarType::Real => "Float64",
            VarType::Boolean => "Boolean",
            VarType::Enumeration(_) => "Enumeration",
        };
        assert_eq!(element.name, type_name);
        check_value(element, v);
    }

    let structure = root.child("ModelStructure");
    let outputs: Vec<usize> =
        structure.all("Output").map(|u| u.attr("valueReference").parse().unwrap()).collect();
    assert!(!outputs.is_empty());
    for vr in &outputs {
        assert_eq!(VARIABLES[*vr].causality, Causality::Output);
    }
    assert_eq!(
        outputs.len(),
        VARIABLES.iter().filter(|v| v.causality == Causality::Output).count()
    );
    // FMI 3 lists the calculated parameters among the initial unknowns, beside the outputs.
    let calculated =
        VARIABLES.iter().filter(|v| v.causality == Causality::CalculatedParameter).count();
    assert_eq!(structure.all("InitialUnknown").count(), outputs.len() + calculated);
}

#[test]
fn large_and_small_numbers_print_parseably() {
    let xml = fmi2_xml();
    assert!(xml.contains("start=\"160000\""), "driver.Kp");
    assert!(xml.contains("start=\"0.0000167742\""), "valve.A_s");
    assert!(!xml.contains("inf") && !xml.contains("NaN"));
}

#[test]
fn markdown_has_a_row_per_variable() {
    let md = variables_markdown();
    assert_eq!(md.lines().count(), 2 + VARIABLES.len());
    assert!(md.contains("| `coil.L` | parameter | H | 3.2 | [1e-4, 1000] |"), "{md}");
    assert!(md.contains("| 2 (opamp_pi) |"));
    assert!(enumerations_markdown().contains("- 2 `opamp_pi`"));
}

#[test]
fn log_categories_are_the_c_api_list_in_schema_order() {
    for xml in [fmi2_xml(), fmi3_xml()] {
        let root = parse(&xml);
        let rendered: Vec<(&str, &str)> = root
            .child("LogCategories")
            .all("Category")
            .map(|c| (c.attr("name"), c.attr("description")))
            .collect();
        let expected: Vec<(&str, &str)> = ehsv_actuator::fmi_common::LOG_CATEGORIES.to_vec();
        assert_eq!(rendered, expected);
        // Schema order: ... TypeDefinitions, LogCategories, DefaultExperiment ...
        let names: Vec<&str> = root.children.iter().map(|c| c.name.as_str()).collect();
        let at = |n: &str| names.iter().position(|&x| x == n).unwrap();
        assert!(
            at("TypeDefinitions") < at("LogCategories")
                && at("LogCategories") < at("DefaultExperiment"),
            "{names:?}"
        );
    }
}

/// Physics the probe must find: no output feeds an input through within a step; the
/// initial equilibrium follows the commands and the parameters that size it.
#[test]
fn dependencies_are_the_measured_physics() {
    let deps = dependencies();
    let names = |knowns: &[u32]| -> Vec<&str> {
        knowns.iter().map(|&k| VARIABLES[k as usize].name).collect()
    };
    for (output, knowns) in &deps.outputs {
        assert!(
            knowns.is_empty(),
            "{} feeds through {:?}",
            VARIABLES[*output as usize].name,
            names(knowns)
        );
    }
    for (output, knowns) in &deps.initial_unknowns {
        assert_eq!(VARIABLES[*output as usize].initial(), Some(Initial::Calculated));
        assert!(knowns.windows(2).all(|w| w[0] < w[1]), "ascending");
        println!("{}: {}", VARIABLES[*output as usize].name, names(knowns).join(" "));
    }
    let of = |name: &str| {
        let vr = VARIABLES.iter().position(|v| v.name == name).unwrap() as u32;
        names(&deps.initial_unknowns.iter().find(|(o, _)| *o == vr).unwrap().1)
    };
    // At the rail the coil current is the rail voltage over the resistance, and the
    // ideal source (driver 0) has no rail.
    for known in ["i_ref", "V_supply", "Q_ref", "x_ref", "driver", "control_mode", "coil.R"] {
        assert!(of("i_coil").contains(&known), "i_coil on {known}: {:?}", of("i_coil"));
    }
    assert!(of("x_spool").contains(&"valve.Kw"));
    // A spool at its stop leaves the rest of the torque to the flapper's stiffness.
    assert!(of("x_flapper").contains(&"valve.Kf") && of("x_flapper").contains(&"V_supply"));
    assert!(of("p_A").contains(&"p_supply") && of("p_A").contains(&"F_ext"));
    assert!(!of("i_coil").contains(&"cylinder.mass"), "{:?}", of("i_coil"));
}

#[test]
fn both_xmls_say_who_made_them_when_and_under_which_licence() {
    for xml in [fmi2_xml(), fmi3_xml()] {
        let root = parse(&xml);
        assert_eq!(root.attr("author"), AUTHOR);
        assert!(root.attr("copyright").starts_with("Copyright (c) 2026"));
        assert_eq!(root.attr("license"), "SPDX-License-Identifier: MIT");
        let date = root.attr("generationDateAndTime");
        assert_eq!((date.len(), &date[10..11], &date[19..]), (20, "T", "Z"), "{date}");
    }
    assert!(LICENSE_TEXT.starts_with("MIT License"));
}

#[test]
fn dates_are_utc_xs_date_times() {
    assert_eq!(utc_date_time(0), "1970-01-01T00:00:00Z");
    assert_eq!(utc_date_time(951_782_400), "2000-02-29T00:00:00Z");
    assert_eq!(utc_date_time(1_795_405_200), "2026-11-23T03:40:00Z");
    assert_eq!(utc_date_time(4_102_444_799), "2099-12-31T23:59:59Z");
}

#[test]
fn documentation_has_the_paper_the_modes_an_example_and_every_variable() {
    let html = documentation_html(&["fig_1.png".to_string()]);
    assert_eq!(html.matches("<tr>").count(), 1 + VARIABLES.len());
    assert!(html.contains("<code>coil.L</code>"));
    assert!(html.contains("Abdulmalek") && html.contains("Legged Robot's Applications"));
    for e in ENUMERATIONS {
        for (name, _) in e.items {
            assert!(html.contains(&format!("<code>{name}</code>")), "{name}");
        }
    }
    assert!(html.contains("from fmpy import simulate_fmu") && html.contains("current_step.csv"));
    assert!(html.contains("src=\"figures/fig_1.png\""));
    assert!(!documentation_html(&[]).contains("<h2>Figures</h2>"));
    // The documented input file is the 0 -> 5 mA step at 1 ms.
    let rows: Vec<&str> = CURRENT_STEP_CSV.lines().collect();
    assert_eq!((rows[0], rows[2], rows[3]), ("time,i_ref", "0.001,0", "0.001,0.005"));
}

#[test]
fn terminals_name_existing_variables_and_the_rod_is_a_causal_flange() {
    let root = parse(&terminals_and_icons_xml());
    assert_eq!((root.name.as_str(), root.attr("fmiVersion")), ("fmiTerminalsAndIcons", "3.0"));
    let terminals: Vec<&Element> = root.child("Terminals").all("Terminal").collect();
    let causality = |name: &str| VARIABLES.iter().find(|v| v.name == name).unwrap().causality;
    for t in &terminals {
        for m in t.all("TerminalMemberVariable") {
            assert!(matches!(
                causality(m.attr("variableName")),
                Causality::Input | Causality::Output
            ));
        }
    }
    let rod = terminals.iter().find(|t| t.attr("name") == "rod").unwrap();
    let members: Vec<(&str, Causality)> = rod
        .all("TerminalMemberVariable")
        .map(|m| (m.attr("memberName"), causality(m.attr("variableName"))))
        .collect();
    assert_eq!(
        members,
        [("s", Causality::Output), ("v", Causality::Output), ("f", Causality::Input)]
    );
}
