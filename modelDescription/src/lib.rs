//! modelDescription.xml for FMI 2.0 and FMI 3.0 Co-Simulation, rendered from the
//! one variable table (`ehsv_actuator::variables`) and unit list (`ehsv_actuator::units`).
//!
//! The structs in `fmi2` and `fmi3` mirror the XML schemas; quick-xml's serde
//! serializer writes fields named `@x` as attributes and other fields as child elements.
//! Nothing about a variable is written down here: every fact comes from the table.

use dependencies::dependencies;
use ehsv_actuator::units::{Unit, UNITS};
use ehsv_actuator::variables::{
    Causality, Enumeration, Initial, VarType, Variability, Variable, ENUMERATIONS, VARIABLES,
};
use serde::Serialize;

mod dependencies;
mod documentation;
mod fmi2;
mod fmi3;
mod markdown;
mod terminals;

pub use documentation::{documentation_html, CURRENT_STEP_CSV, PAPER_CITATION};
pub use markdown::{enumerations_markdown, variables_markdown};
pub use terminals::terminals_and_icons_xml;

/// `modelIdentifier`: the shared-library name inside `binaries/<platform>/`.
pub const MODEL_IDENTIFIER: &str = "EhsvActuator";
pub const MODEL_NAME: &str = "EhsvActuator";
pub const MODEL_DESCRIPTION: &str =
    "Electro-hydraulic servo actuator: coil driver, torque-motor coil and two-stage (Moog 30) servo valve";
pub const GENERATION_TOOL: &str = concat!(
    "EhsvActuator model-description ",
    env!("CARGO_PKG_VERSION"),
    " (Rust, serde + quick-xml)"
);
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
pub const AUTHOR: &str = "The EhsvActuator developers";
pub const COPYRIGHT: &str = "Copyright (c) 2026 The EhsvActuator developers";
/// The workspace's licence (Cargo.toml); the text is LICENSE at the repository root and
/// documentation/licenses/license.txt in the archives.
pub const LICENSE: &str = concat!("SPDX-License-Identifier: ", env!("CARGO_PKG_LICENSE"));
pub const LICENSE_TEXT: &str = include_str!("../../LICENSE");

/// `generationDateAndTime` (xs:dateTime, UTC): SOURCE_DATE_EPOCH if set (reproducible
/// builds), else now.
pub fn generation_date_and_time() -> String {
    let seconds = std::env::var("SOURCE_DATE_EPOCH")
        .ok()
        .and_then(|s| s.trim().parse::<u64>().ok())
        .unwrap_or_else(|| {
            let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH);
            now.map(|d| d.as_secs()).unwrap_or(0)
        });
    utc_date_time(seconds)
}

/// Seconds since 1970 as `YYYY-MM-DDThh:mm:ssZ` (proleptic Gregorian calendar).
fn utc_date_time(seconds: u64) -> String {
    let (days, rest) = ((seconds / 86400) as i64, seconds % 86400);
    // Days to civil date (H. Hinnant's algorithm): eras of 400 years from 0000-03-01.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    let (h, m, s) = (rest / 3600, rest / 60 % 60, rest % 60);
    format!("{year:04}-{month:02}-{day:02}T{h:02}:{m:02}:{s:02}Z")
}

/// Default experiment: 10 ms at 100 us communication steps.
const START_TIME: f64 = 0.0;
const STOP_TIME: f64 = 0.01;
const STEP_SIZE: f64 = ehsv_actuator::model::DEFAULT_STEP_SIZE;

/// FMI 2.0 Co-Simulation modelDescription.xml.
pub fn fmi2_xml() -> String {
    to_xml(&fmi2::model_description())
}

/// FMI 3.0 Co-Simulation modelDescription.xml.
pub fn fmi3_xml() -> String {
    to_xml(&fmi3::model_description())
}

fn to_xml<T: Serialize>(document: &T) -> String {
    let mut xml = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let mut serializer = quick_xml::se::Serializer::new(&mut xml);
    serializer.indent(' ', 2);
    document.serialize(serializer).expect("modelDescription structs always serialize");
    xml.push('\n');
    xml
}

// ---- pieces shared by both FMI versions -------------------------------------------------

/// `<Unit>`: identical in FMI 2 and FMI 3 (FMI 3 only adds the optional `inverse`).
#[derive(Serialize)]
struct UnitElement {
    #[serde(rename = "@name")]
    name: &'static str,
    #[serde(rename = "BaseUnit")]
    base_unit: BaseUnit,
    #[serde(rename = "DisplayUnit")]
    display_units: Vec<DisplayUnitElement>,
}

/// SI exponents; zero exponents are left out (the schema default is 0).
#[derive(Serialize)]
struct BaseUnit {
    #[serde(rename = "@kg", skip_serializing_if = "Option::is_none")]
    kg: Option<i8>,
    #[serde(rename = "@m", skip_serializing_if = "Option::is_none")]
    m: Option<i8>,
    #[serde(rename = "@s", skip_serializing_if = "Option::is_none")]
    s: Option<i8>,
    #[serde(rename = "@A", skip_serializing_if = "Option::is_none")]
    a: Option<i8>,
    #[serde(rename = "@K", skip_serializing_if = "Option::is_none")]
    k: Option<i8>,
    #[serde(rename = "@mol", skip_serializing_if = "Option::is_none")]
    mol: Option<i8>,
    #[serde(rename = "@cd", skip_serializing_if = "Option::is_none")]
    cd: Option<i8>,
    #[serde(rename = "@rad", skip_serializing_if = "Option::is_none")]
    rad: Option<i8>,
}

#[derive(Serialize)]
struct DisplayUnitElement {
    #[serde(rename = "@name")]
    name: &'static str,
    #[serde(rename = "@factor")]
    factor: f64,
    #[serde(rename = "@offset")]
    offset: f64,
}

#[derive(Serialize)]
struct UnitDefinitions {
    #[serde(rename = "Unit")]
    units: Vec<UnitElement>,
}

fn unit_definitions() -> UnitDefinitions {
    let nonzero = |e: i8| (e != 0).then_some(e);
    let element = |u: &Unit| {
        let [kg, m, s, a, k, mol, cd, rad] = u.base.map(nonzero);
        UnitElement {
            name: u.name,
            base_unit: BaseUnit { kg, m, s, a, k, mol, cd, rad },
            display_units: u
                .display
                .iter()
                .map(|d| DisplayUnitElement { name: d.name, factor: d.factor, offset: d.offset })
                .collect(),
        }
    };
    UnitDefinitions { units: UNITS.iter().map(element).collect() }
}

/// `<Item>` of an enumeration type: same attributes in FMI 2 and FMI 3.
#[derive(Serialize)]
struct Item {
    #[serde(rename = "@name")]
    name: &'static str,
    #[serde(rename = "@value")]
    value: i64,
    #[serde(rename = "@description")]
    description: &'static str,
}

fn items(enumeration: &'static Enumeration) -> Vec<Item> {
    enumeration
        .valued_items()
        .map(|(value, name, description)| Item { name, value, description })
        .collect()
}

/// `<LogCategories>`: same element in FMI 2 and FMI 3, rendered from the one list the C
/// API accepts ([`ehsv_actuator::fmi_common::LOG_CATEGORIES`]).
#[derive(Serialize)]
struct LogCategories {
    #[serde(rename = "Category")]
    categories: Vec<Category>,
}

#[derive(Serialize)]
struct Category {
    #[serde(rename = "@name")]
    name: &'static str,
    #[serde(rename = "@description")]
    description: &'static str,
}

fn log_categories() -> LogCategories {
    LogCategories {
        categories: ehsv_actuator::fmi_common::LOG_CATEGORIES
            .iter()
            .map(|&(name, description)| Category { name, description })
            .collect(),
    }
}

#[derive(Serialize)]
struct DefaultExperiment {
    #[serde(rename = "@startTime")]
    start_time: f64,
    #[serde(rename = "@stopTime")]
    stop_time: f64,
    #[serde(rename = "@stepSize")]
    step_size: f64,
}

const DEFAULT_EXPERIMENT: DefaultExperiment =
    DefaultExperiment { start_time: START_TIME, stop_time: STOP_TIME, step_size: STEP_SIZE };

/// Attributes every variable element has (FMI 2 `ScalarVariable`, FMI 3 `Float64`, ...).
#[derive(Serialize)]
pub(crate) struct Common {
    #[serde(rename = "@name")]
    name: &'static str,
    #[serde(rename = "@valueReference")]
    value_reference: u32,
    #[serde(rename = "@description")]
    description: &'static str,
    #[serde(rename = "@causality")]
    causality: &'static str,
    #[serde(rename = "@variability")]
    variability: &'static str,
    #[serde(rename = "@initial", skip_serializing_if = "Option::is_none")]
    initial: Option<&'static str>,
}

impl Common {
    fn new(value_reference: u32, v: &'static Variable) -> Common {
        Common {
            name: v.name,
            value_reference,
            description: v.description,
            causality: causality_name(v.causality),
            variability: variability_name(v.variability),
            initial: initial_name(v),
        }
    }
}

fn causality_name(c: Causality) -> &'static str {
    match c {
        Causality::Independent => "independent",
        Causality::Parameter => "parameter",
        Causality::CalculatedParameter => "calculatedParameter",
        Causality::Input => "input",
        Causality::Output => "output",
    }
}

fn variability_name(v: Variability) -> &'static str {
    match v {
        Variability::Fixed => "fixed",
        Variability::Tunable => "tunable",
        Variability::Discrete => "discrete",
        Variability::Continuous => "continuous",
    }
}

fn initial_name(v: &Variable) -> Option<&'static str> {
    v.initial().map(|i| match i {
        Initial::Exact => "exact",
        Initial::Calculated => "calculated",
    })
}

/// The table stores every start value as f64; these give it the XML type of the variable.
fn real_start(v: &Variable) -> Option<f64> {
    v.has_start().then_some(v.start)
}
fn boolean_start(v: &Variable) -> Option<bool> {
    v.has_start().then_some(v.start != 0.0)
}
fn integer_start(v: &Variable) -> Option<i64> {
    v.has_start().then_some(v.start as i64)
}
fn integer_bound(bound: Option<f64>) -> Option<i64> {
    bound.map(|b| b as i64)
}

/// Table rows with their value reference (= index).
fn table() -> impl Iterator<Item = (u32, &'static Variable)> {
    VARIABLES.iter().enumerate().map(|(i, v)| (v.value_reference(i), v))
}

/// Outputs listed in ModelStructure; all of them are also initial unknowns (initial =
/// calculated).
fn outputs() -> impl Iterator<Item = (u32, &'static Variable)> {
    table().filter(|(_, v)| v.causality == Causality::Output)
}

/// Initialization Mode's unknowns: the outputs and the calculated parameters, in table order.
fn initial_unknowns() -> impl Iterator<Item = (u32, &'static Variable)> {
    table()
        .filter(|(_, v)| matches!(v.causality, Causality::Output | Causality::CalculatedParameter))
}

#[cfg(test)]
mod tests;
