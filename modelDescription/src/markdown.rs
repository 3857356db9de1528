//! Markdown tables for the README and the FMU's documentation, from the same table as the XML.

use super::*;
use ehsv_actuator::variables::Enumeration;

/// One row per variable, in value-reference order.
pub fn variables_markdown() -> String {
    let rows = variable_rows();
    let mut md = String::new();
    for (i, row) in rows.iter().enumerate() {
        let cells: Vec<String> = row.iter().map(|c| cell(c)).collect();
        md += &format!("| {} |\n", cells.join(" | "));
        if i == 0 {
            md += "|---:|------|-----------|----------------|------:|-------|-------------|\n";
        }
    }
    md
}

/// The variable table as text cells, header first; names in `code` spans.
pub(crate) fn variable_rows() -> Vec<[String; 7]> {
    let header = ["vr", "name", "causality", "unit (display)", "start", "range", "description"];
    let mut rows = vec![header.map(String::from)];
    for (vr, v) in table() {
        let unit = match (v.unit, v.display_unit) {
            (Some(u), Some(d)) => format!("{u} ({d})"),
            (Some(u), None) => u.to_string(),
            (None, _) => String::new(),
        };
        let range = if v.min.is_some() || v.max.is_some() { v.range_text() } else { String::new() };
        rows.push([
            vr.to_string(),
            format!("`{}`", v.name),
            causality_name(v.causality).to_string(),
            unit,
            start_text(v),
            range,
            v.description.to_string(),
        ]);
    }
    rows
}

/// One list per enumeration type: value, item name, description.
pub fn enumerations_markdown() -> String {
    let mut md = String::new();
    for e in ENUMERATIONS {
        md += &format!("**{}**: {}\n\n", e.name, e.description);
        for (value, name, description) in e.valued_items() {
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
            let item = enumeration(type_name).and_then(|e| e.items.get(value as usize));
            match item {
                Some((name, _)) => format!("{value} ({name})"),
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
