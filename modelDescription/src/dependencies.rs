//! `dependencies` of the ModelStructure, found by perturbing the model itself.
//!
//! FMI (2.0.4 section 2.2.8, 3.0 section 2.4.8): an Output's dependencies are the inputs
//! its value at a communication point changes with, without a step (direct feedthrough);
//! an InitialUnknown's are the knowns of Initialization Mode, inputs and variables with
//! `initial="exact"` (here: every parameter), its initial value changes with. The
//! independent variable is never a known there. A missing attribute means "depends on
//! everything", which masters read as an algebraic loop; a wrong empty list would hide a
//! real one. So the lists are measured, not written down: for every driver and control
//! mode, at rest and with every command non-zero, each known is moved to a few other
//! allowed values and the outputs that change are recorded. The Python test
//! tests/python/test_model_structure.py checks the shipped binary against the XML.

use super::*;
use ehsv_actuator::model::Model;
use ehsv_actuator::variables::{vr, N_VARIABLES};
use std::sync::OnceLock;

/// For each output (value reference, in table order): the knowns it depends on.
pub(crate) struct Dependencies {
    pub(crate) outputs: Vec<(u32, Vec<u32>)>,
    pub(crate) initial_unknowns: Vec<(u32, Vec<u32>)>,
}

/// Measured once per process: the probe runs a few thousand model initialisations.
pub(crate) fn dependencies() -> &'static Dependencies {
    static MEASURED: OnceLock<Dependencies> = OnceLock::new();
    MEASURED.get_or_init(measure)
}

/// Commands that move every part of the model (valve open, piston loaded, loops active,
/// the rod moved by a host).
const MOVING: &[(usize, f64)] = &[
    (vr::I_REF, 5e-3),
    (vr::Q_REF, 1e-4),
    (vr::X_REF, 5e-3),
    (vr::F_EXT, 100.0),
    (vr::X_ROD, 2e-3),
    (vr::V_ROD, 0.05),
];
/// Branches a small perturbation of one known does not reach from rest: the driver at its
/// rail (5 mA needs 5 V across 1 kOhm) and just below it, the valve against its travel
/// stops and just short of the spool's (5 mA hold it at K1 i / Kw = 0.19 mm).
const SATURATED: &[(usize, f64)] = &[(vr::V_SUPPLY, 1.0)];
const NEAR_RAIL: &[(usize, f64)] = &[(vr::V_SUPPLY, 5.2)];
const SPOOL_STOP: &[(usize, f64)] = &[(vr::VALVE_X_SPOOL_MAX, 1e-5)];
const NEAR_SPOOL_STOP: &[(usize, f64)] = &[(vr::VALVE_X_SPOOL_MAX, 2e-4)];
const FLAPPER_STOP: &[(usize, f64)] = &[(vr::VALVE_X_FLAPPER_MAX, 1e-6)];

fn measure() -> Dependencies {
    let outputs: Vec<usize> = outputs().map(|(vr, _)| vr as usize).collect();
    // Initialization Mode's unknowns: the outputs and the calculated parameters.
    let unknowns: Vec<usize> = initial_unknowns().map(|(vr, _)| vr as usize).collect();
    let knowns: Vec<usize> = table()
        .filter(|(_, v)| matches!(v.causality, Causality::Input | Causality::Parameter))
        .map(|(vr, _)| vr as usize)
        .collect();
    let inputs: Vec<usize> =
        knowns.iter().copied().filter(|&k| VARIABLES[k].causality == Causality::Input).collect();
    let mut initial = vec![[false; N_VARIABLES]; N_VARIABLES];
    let mut at_step = vec![[false; N_VARIABLES]; N_VARIABLES];

    for base in operating_points() {
        let reference = output_values(&base, &unknowns);
        for &known in &knowns {
            for value in other_values(known, base.get(known).expect("a known")) {
                let mut model = base.clone();
                if model.set(known, value).is_err() {
                    continue; // refused together with this configuration: not a reachable value
                }
                let values = output_values(&model, &unknowns);
                record(&mut initial, known, &unknowns, &reference, &values);
            }
        }
        // After initialisation the importer sets inputs between steps.
        let mut running = base.clone();
        if running.initialize().is_err() {
            continue;
        }
        let reference = output_values(&running, &outputs);
        for &input in &inputs {
            for value in other_values(input, running.get(input).expect("an input")) {
                let mut model = running.clone();
                if model.set(input, value).is_ok() {
                    let values = output_values(&model, &outputs);
                    record(&mut at_step, input, &outputs, &reference, &values);
                }
            }
        }
    }
    let lists = |found: &[[bool; N_VARIABLES]], of: &[usize]| {
        of.iter()
            .map(|&o| {
                let on = knowns.iter().filter(|&&k| found[o][k]).map(|&k| k as u32);
                (o as u32, on.collect())
            })
            .collect()
    };
    Dependencies {
        outputs: lists(&at_step, &outputs),
        initial_unknowns: lists(&initial, &unknowns),
    }
}

/// Every driver in every control mode: at rest (start values), with every command
/// non-zero, and moving at the rail and at the stops; refused configurations are left out.
fn operating_points() -> Vec<Model> {
    let settings = [
        vec![],
        MOVING.to_vec(),
        [MOVING, SATURATED].concat(),
        [MOVING, NEAR_RAIL].concat(),
        [MOVING, SPOOL_STOP].concat(),
        [MOVING, NEAR_SPOOL_STOP].concat(),
        [MOVING, SATURATED, SPOOL_STOP].concat(),
        [MOVING, SPOOL_STOP, FLAPPER_STOP].concat(),
    ];
    let mut points = vec![];
    for port in enumeration_values(vr::CYLINDER_PORT) {
        for driver in enumeration_values(vr::DRIVER) {
            for mode in enumeration_values(vr::CONTROL_MODE) {
                for setting in &settings {
                    let mut model = Model::new();
                    let structure =
                        [(vr::CYLINDER_PORT, port), (vr::DRIVER, driver), (vr::CONTROL_MODE, mode)];
                    if structure.iter().chain(setting).all(|&(k, x)| model.set(k, x).is_ok()) {
                        points.push(model);
                    }
                }
            }
        }
    }
    points
}

fn enumeration_values(index: usize) -> Vec<f64> {
    let v = &VARIABLES[index];
    let (lo, hi) = (v.min.unwrap_or(0.0) as i64, v.max.unwrap_or(0.0) as i64);
    (lo..=hi).map(|x| x as f64).collect()
}

/// Values to move a known to: every other item of an enumeration or Boolean; for a real,
/// +-10 % and factors 2 and 10 both ways (across a rail or a stop nearby) and, for a zero
/// value (often "off": no limit, no resistor), small to large values of both signs.
/// Values outside the declared range are dropped.
fn other_values(index: usize, current: f64) -> Vec<f64> {
    let v = &VARIABLES[index];
    let candidates: Vec<f64> = match v.ty {
        VarType::Boolean => vec![1.0 - current],
        VarType::Enumeration(_) => enumeration_values(index),
        VarType::Real if current != 0.0 => {
            [1.1, 0.9, 2.0, 0.5, 10.0, 0.1].map(|f| current * f).to_vec()
        }
        VarType::Real => [1e-6, 1e-3, 1.0, 1e3].iter().flat_map(|&x| [x, -x]).collect(),
    };
    candidates.into_iter().filter(|&x| x != current && v.check(x).is_ok()).collect()
}

fn output_values(model: &Model, outputs: &[usize]) -> Vec<f64> {
    outputs.iter().map(|&o| model.get(o).expect("an unknown")).collect()
}

/// Marks `known` for every output whose value differs (bitwise: NaN or a last-digit change
/// counts too).
fn record(
    found: &mut [[bool; N_VARIABLES]],
    known: usize,
    outputs: &[usize],
    before: &[f64],
    after: &[f64],
) {
    for ((&o, b), a) in outputs.iter().zip(before).zip(after) {
        if b.to_bits() != a.to_bits() {
            found[o][known] = true;
        }
    }
}
