//! `documentation/index.html` of both archives: what the model is, the paper, the drivers
//! and modes (from the enumeration table), an fmpy example, the known properties and the
//! variable table, all rendered from the same tables as the XML.

use super::*;
use markdown::variable_rows;

/// The paper the model reproduces, as the archive and the README cite it.
pub const PAPER_CITATION: &str = "G. Abdulmalek, A. Ammounah, N. Ait Oukfroukh, S. Alfayad and \
S. Mammar, \"Electronic Implementation of High Bandwidth Linear Hydraulic Actuator for Legged \
Robot's Applications\", open-access article (CC BY 4.0), IBISC, Univ Evry, Universit\u{e9} \
Paris-Saclay, 2023 (manuscript accepted 30 May 2023).";

/// Input file for the documented first run: i_ref steps from 0 to 5 mA at t = 1 ms (fmpy
/// holds the last value; the two rows at 1 ms make the step sharp).
pub const CURRENT_STEP_CSV: &str = "time,i_ref\n0,0\n0.001,0\n0.001,0.005\n0.01,0.005\n";

const OVERVIEW: &str = "<p>An electro-hydraulic servo actuator as an FMI 2.0 and FMI 3.0 \
Co-Simulation FMU: a coil driver, the torque-motor coil (L = 3.2 H, R = 1 k&Omega;), a Moog \
30-series two-stage flapper-nozzle servo valve (its linear model, optional travel stops) and a \
double-acting cylinder with a mass load, friction and end stops. Every variable, unit and \
start value below is one row of the model's variable table. The integrator is exact for the \
piecewise-linear driver, coil and valve; the cylinder is integrated by an L-stable \
Rosenbrock method inside each step.</p>";

const FIRST_RUN: &str = "<p>The model starts in equilibrium for its start inputs: with \
<code>i_ref = 0</code> everything is at rest, so a simulation without inputs shows flat lines \
(on purpose: an unconnected command never moves the piston). The archive carries \
<code>documentation/current_step.csv</code>, the paper's headline test, a 0 &rarr; 5 mA step \
at 1 ms; the op-amp driver settles the coil current in about 0.25 ms:</p>\n\
<pre>fmpy simulate EhsvActuator-fmi3.fmu --input-file current_step.csv \\\n\
    --output-variables i_coil u_driver x_spool Q_valve</pre>\n\
<p>or from Python:</p>\n\
<pre>import numpy as np\nfrom fmpy import simulate_fmu\n\n\
step = np.array([(0.0, 0.0), (1e-3, 0.0), (1e-3, 5e-3), (10e-3, 5e-3)],\n\
                dtype=[(\"time\", float), (\"i_ref\", float)])\n\
result = simulate_fmu(\"EhsvActuator-fmi3.fmu\", input=step, output_interval=1e-5,\n\
                      start_values={\"driver\": 2, \"V_supply\": 72.0},\n\
                      output=[\"i_coil\", \"u_driver\", \"x_spool\", \"Q_valve\"])\n\
print(result[\"i_coil\"][-1])  # about 0.005 A</pre>\n\
<p>fmpy names the inputs the file leaves at their start values (V_supply 72 V, p_supply \
6.9 MPa, F_ext, Q_ref, x_ref 0); that is expected.</p>";

const PROPERTIES: &[&str] = &[
    "No output feeds an input through within a step (every Output declares \
     <code>dependencies=\"\"</code>): closing a loop from <code>x_piston</code> to \
     <code>i_ref</code> in a master is no algebraic loop. Inputs are held over each \
     communication step.",
    "Pressures are gauge; the tank is at 0 Pa and the cavitation floor at -0.9e5 Pa.",
    "<code>Q_valve</code> is the paper's no-load flow K3 x_spool; <code>Q_A</code> is the \
     real port flow with the chamber pressures.",
    "The position loop is P only by default (1 mA per mm); the flow loop adds an exact \
     feed-forward Q_ref/(K3 K1/Kw).",
    "Invalid values (NaN, out of range, combinations too stiff to represent) are refused \
     with a log line naming the variable and its range.",
    "The FMU state can be read, restored and serialized; instances are independent.",
];

/// The page; `figures` are file names under `documentation/figures/` shown at the end.
pub fn documentation_html(figures: &[String]) -> String {
    let mut html = format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>{MODEL_IDENTIFIER}</title></head><body>\n<h1>{MODEL_IDENTIFIER} {VERSION}</h1>\n\
         <p><img src=\"../model.png\" alt=\"\" width=\"128\" style=\"float:right\">{}</p>\n{OVERVIEW}\n",
        escape(MODEL_DESCRIPTION)
    );
    html += &format!("<h2>The paper</h2>\n<p>{}</p>\n", escape(PAPER_CITATION));
    for e in ENUMERATIONS {
        html += &format!("<h2>{}</h2>\n<p>{}</p>\n<ul>\n", escape(e.name), escape(e.description));
        for (value, name, description) in e.valued_items() {
            html += &format!("<li>{value} <code>{name}</code>: {}</li>\n", escape(description));
        }
        html += "</ul>\n";
    }
    html += &format!("<h2>A first run</h2>\n{FIRST_RUN}\n<h2>Known properties</h2>\n<ul>\n");
    for property in PROPERTIES {
        html += &format!("<li>{property}</li>\n");
    }
    html += "</ul>\n<h2>Variables</h2>\n<table border=\"1\">\n";
    for (i, row) in variable_rows().iter().enumerate() {
        let tag = if i == 0 { "th" } else { "td" };
        html += "<tr>";
        for cell in row {
            html += &format!("<{tag}>{}</{tag}>", code_spans(&escape(cell)));
        }
        html += "</tr>\n";
    }
    html += "</table>\n";
    if !figures.is_empty() {
        html += "<h2>Figures</h2>\n";
        for figure in figures {
            html += &format!("<p><img src=\"figures/{0}\" alt=\"{0}\"></p>\n", escape(figure));
        }
    }
    html += &format!(
        "<h2>Licence</h2>\n<p>{COPYRIGHT}. {LICENSE} (<a href=\"licenses/license.txt\">text</a>).</p>\n\
         </body></html>\n"
    );
    html
}

/// `code` -> <code>code</code>
fn code_spans(text: &str) -> String {
    text.split('`')
        .enumerate()
        .map(|(i, part)| if i % 2 == 1 { format!("<code>{part}</code>") } else { part.to_string() })
        .collect()
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}
