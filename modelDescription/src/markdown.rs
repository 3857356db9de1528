//! Markdown tables for the README and the FMU's documentation, from the same table as the XML.

use super::*;
use ehsv_actuator::variables::Enumeration;

/// One row per variable, in value-reference order.
pub fn variables_markdown() -> String {
    let mut md = String::from(
        "| vr | name | causality | unit (display) | start | range | description |\n\
         |---:|------|-----------|----------------|------:|-------|-------------|\n",
    );
    for (vr, v) in table() {
        let unit = match (v.unit, v.display_unit) {
            (Some(u), Some(d)) => format!("{u} ({d})"),
            (Some(u), None) => u.to_string(),
            (None, _) => String::new(),
        };
        let range = if v.min.is_some() || v.max.is_some() { v.range_text() } else { String::new() };
        md += &format!(
            "| {vr} | `{}` | {} | {} | {} | {} | {} |\n",
            v.name,
            causality_name(v.causality),
            cell(&unit),
            start_text(v),
            cell(&range),
            cell(v.description),
        );
    }
    md
}

/// One list per enumeration type: value, item name, description.
pub fn enumerations_markdown() -> String {
    let mut md = String::new();
    for e in ENUMERATIONS {
        md += &format!("**{}**: {}\n\n", e.name, e.description);
        for (value, name, description) in e.items {
            md += &format!("- {value} `{name}`: {description}\n");
        }
        md.push('\n');
    }
    md
}

fn start_text(v: &Variable) -> String {
    if !v.has_start() {
        return String::new();
    }
    match v.ty {
        VarType::Real => v.start.to_string(),
        VarType::Boolean => (v.start != 0.0).to_string(),
        VarType::Enumeration(type_name) => {
            let value = v.start as i64;
            let item =
                enumeration(type_name).and_then(|e| e.items.iter().find(|(n, _, _)| *n == value));
            match item {
                Some((_, name, _)) => format!("{value} ({name})"),
                None => value.to_string(),
            }
        }
    }
}

fn enumeration(name: &str) -> Option<&'static Enumeration> {
    ENUMERATIONS.iter().find(|e| e.name == name)
}

/// A pipe would end the table cell.
fn cell(text: &str) -> String {
    text.replace('|', "\\|")
}
