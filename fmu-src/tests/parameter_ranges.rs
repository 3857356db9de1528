//! Every real parameter at the ends of its range and beyond (+-1e300, 1e-300): with both
//! integrators, the instance either initialises and takes its steps in bounded time, or the
//! value is refused with an Error that names the parameter (at the set, or at the
//! initialisation where a rule between parameters refuses it). Issue 37: `driver.slew_rate`
//! = 1e300 was accepted (its range was only positive) and made fixed_cost's
//! ExitInitializationMode run forever. FMI 2 only: the ranges and the physics behind them
//! are the same for both versions.

use std::time::{Duration, Instant};

mod common;
use common::*;
use ehsv_actuator::variables::{vr, Causality, VarType, VARIABLES};

/// Communication steps taken after a successful initialisation.
const STEPS: usize = 20;
const H: f64 = 1e-4;
/// Longest a case may take (set, initialisation, the steps); the paper's setup takes
/// milliseconds.
const LIMIT: Duration = Duration::from_secs(10);

/// What happened to one (parameter, value, method) case.
#[derive(Debug, Clone, PartialEq)]
enum Outcome {
    /// Refused by the set (Error), the log naming the parameter.
    RefusedAtSet,
    /// Refused by the initialisation (Error), the log naming the parameter.
    RefusedAtInit,
    /// Initialised and took every step.
    Ran,
    /// Something else: the case fails.
    Failed(String),
}

/// The driver and control mode under which a parameter matters (names of the enumeration
/// items' values: driver 3 industrial_pi, 4 hbridge_pid; control_mode 1 flow, 2 position).
fn setup(name: &str) -> (i64, i64) {
    match name.split('.').next() {
        Some("industrial") => (3, 0),
        Some("hbridge") => (4, 0),
        Some("flow") => (2, 1),
        Some("loop") | Some("position") => (2, 2),
        _ => (2, 0),
    }
}

/// The command that moves the actuator in `control_mode`.
fn command(control_mode: i64) -> (usize, f64) {
    match control_mode {
        1 => (vr::Q_REF, 1e-4),
        2 => (vr::X_REF, 5e-3),
        _ => (vr::I_REF, 5e-3),
    }
}

/// The start of the log, for a failure's message.
fn log_head(f: &Fmu2) -> String {
    f.log().dump().chars().take(300).collect()
}

fn run_case(r: usize, value: f64, method: i64) -> Outcome {
    let name = VARIABLES[r].name;
    let f = Fmu2::create("ranges");
    let (driver, control_mode) = setup(name);
    for (e, v) in
        [(vr::DRIVER, driver), (vr::CONTROL_MODE, control_mode), (vr::SOLVER_METHOD, method)]
    {
        assert_eq!(f.set_enum(e, v), OK, "{}", f.log().dump());
    }
    let named = |stage: Outcome| {
        if f.log().has(&[name]) {
            stage
        } else {
            Outcome::Failed(format!("{stage:?} without naming {name}: {}", log_head(&f)))
        }
    };
    match Api::set(&f, r, value) {
        OK => {}
        ERROR => return named(Outcome::RefusedAtSet),
        s => return Outcome::Failed(format!("set returned {s:?}")),
    }
    match f.init(None) {
        OK => {}
        ERROR => return named(Outcome::RefusedAtInit),
        s => return Outcome::Failed(format!("init returned {s:?}")),
    }
    let (input, target) = command(control_mode);
    assert_eq!(Api::set(&f, input, target), OK, "{}", f.log().dump());
    for k in 0..STEPS {
        let t = k as f64 * H;
        let status = Api::step(&f, t, H);
        if status != OK {
            return Outcome::Failed(format!("step {k} returned {status:?}: {}", log_head(&f)));
        }
    }
    Outcome::Ran
}

/// The range's ends (as the table gives them) and beyond.
fn values(r: usize) -> Vec<f64> {
    let v = &VARIABLES[r];
    let mut values = vec![1e300, -1e300, 1e-300];
    values.extend(v.min.into_iter().chain(v.max));
    values
}

#[test]
fn every_real_parameter_at_and_beyond_its_range_runs_or_is_refused_naming_it() {
    let parameters = (0..VARIABLES.len())
        .filter(|&r| VARIABLES[r].causality == Causality::Parameter)
        .filter(|&r| VARIABLES[r].ty == VarType::Real);
    let mut failures = Vec::new();
    let mut cases = 0;
    for r in parameters {
        let v = &VARIABLES[r];
        // Both ends finite: no parameter's range stays open where the physics ends.
        if !(v.min.is_some_and(f64::is_finite) && v.max.is_some_and(f64::is_finite)) {
            failures.push(format!("{}: range {} is open", v.name, v.range_text()));
        }
        for value in values(r) {
            for method in [0, 1] {
                cases += 1;
                let (tx, rx) = std::sync::mpsc::channel();
                let start = Instant::now();
                std::thread::spawn(move || {
                    let _ = tx.send(run_case(r, value, method));
                });
                let outcome = rx.recv_timeout(LIMIT).unwrap_or_else(|_| {
                    Outcome::Failed(format!("no answer within {LIMIT:?} (a call hangs)"))
                });
                let name = VARIABLES[r].name;
                println!(
                    "{name} = {value:e}, method {method}: {outcome:?} in {:?}",
                    start.elapsed()
                );
                if let Outcome::Failed(why) = outcome {
                    failures.push(format!("{name} = {value:e}, method {method}: {why}"));
                }
            }
        }
    }
    assert!(cases > 200, "only {cases} cases");
    assert!(
        failures.is_empty(),
        "{} of {cases} cases failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
