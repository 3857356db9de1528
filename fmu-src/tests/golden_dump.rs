//! The bit-for-bit safety net of refactoring: nine scenarios that between them reach every
//! driver, control mode, stop, contact, retune and state restore, digested to one FNV-1a
//! hash each over every variable's value and the state bytes after every step. A change
//! that moves code without changing behaviour keeps every digest; a change of behaviour
//! (or of the state format) must update them knowingly: the failure prints the new ones.

mod scenario;

use ehsv_actuator::model::Model;
use ehsv_actuator::variables::{vr, N_VARIABLES};
use scenario::{control_mode, driver};

const H: f64 = 1e-4;
/// The variables that existed when the digests were taken (value references never move).
const DIGESTED_VARIABLES: usize = 80;
const STEPS: usize = 600;

struct Digest(u64);

impl Digest {
    fn feed(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u64).wrapping_mul(0x100000001b3);
        }
    }
    /// The values of the variables the digests were first taken over, and the physics'
    /// part of the state bytes (what follows the value array), so that appending a
    /// variable leaves them as they were.
    fn feed_model(&mut self, m: &Model) {
        for index in 0..DIGESTED_VARIABLES {
            self.feed(&m.get(index).unwrap().to_le_bytes());
        }
        let bytes = m.to_bytes();
        // Frame: magic (8) | length (8) | body | checksum (8); body: count (4) | initialised
        // (1) | time (8) | the rod's input derivative (8) | values (8 each) | the physics.
        let physics_start = 16 + 4 + 1 + 8 + 8 + 8 * N_VARIABLES;
        self.feed(&bytes[physics_start..bytes.len() - 8]);
    }
}

/// Inputs `(value reference, value)` held over the step that starts at `t`.
type Signal = fn(f64) -> Vec<(usize, f64)>;

fn square(f: f64, t: f64) -> f64 {
    if (2.0 * f * t).floor() as i64 % 2 == 0 {
        1.0
    } else {
        -1.0
    }
}

/// Steps a scenario and digests it; `at_step` may act on the model between steps.
fn digest(settings: &[(&str, f64)], signal: Signal, at_step: fn(usize, &mut Model)) -> u64 {
    let mut m = scenario::model(settings);
    let mut d = Digest(0xcbf29ce484222325);
    d.feed_model(&m);
    for k in 0..STEPS {
        at_step(k, &mut m);
        let t = m.time();
        for (index, value) in signal(t) {
            m.set(index, value).unwrap();
        }
        m.do_step(t, H).unwrap();
        d.feed_model(&m);
    }
    d.0
}

fn nothing(_: usize, _: &mut Model) {}

/// Retunes mass and friction, then restores a state saved earlier and goes on from it.
fn retune_and_restore(k: usize, m: &mut Model) {
    thread_local!(static SAVED: std::cell::RefCell<Vec<u8>> = const { std::cell::RefCell::new(Vec::new()) });
    match k {
        100 => SAVED.with(|s| *s.borrow_mut() = m.to_bytes()),
        200 => {
            m.set(vr::CYLINDER_MASS, 20.0).unwrap();
            m.set(vr::CYLINDER_F_COULOMB, 60.0).unwrap();
        }
        400 => *m = SAVED.with(|s| Model::from_bytes(&s.borrow()).unwrap()),
        _ => {}
    }
}

fn scenarios() -> Vec<(&'static str, u64)> {
    let opamp = driver("opamp_pi");
    let current = control_mode("current");
    let position = control_mode("position");
    vec![
        ("current_step", digest(&[opamp, current], |_| vec![(vr::I_REF, 0.005)], nothing)),
        (
            "square_100Hz",
            digest(&[opamp], |t| vec![(vr::I_REF, 0.005 * square(100.0, t))], nothing),
        ),
        (
            "sine_20Hz",
            digest(
                &[opamp],
                |t| vec![(vr::I_REF, 0.005 * (2.0 * std::f64::consts::PI * 20.0 * t).sin())],
                nothing,
            ),
        ),
        (
            "position_touchdown",
            digest(
                &[opamp, position],
                |t| {
                    let load = if t > 0.02 { -1500.0 * (t * 50.0).sin().abs() } else { 0.0 };
                    vec![
                        (vr::X_REF, 0.01 * (2.0 * std::f64::consts::PI * 4.0 * t).sin()),
                        (vr::F_EXT, load),
                    ]
                },
                nothing,
            ),
        ),
        (
            "stand_under_load",
            digest(&[opamp, position], |_| vec![(vr::X_REF, 0.005), (vr::F_EXT, -750.0)], nothing),
        ),
        (
            "flow_square",
            digest(
                &[opamp, control_mode("flow")],
                |t| vec![(vr::Q_REF, 2e-5 * square(20.0, t))],
                nothing,
            ),
        ),
        (
            "hbridge_square",
            digest(
                &[driver("hbridge_pid"), ("V_supply", 12.0)],
                |t| vec![(vr::I_REF, 0.005 * square(100.0, t))],
                nothing,
            ),
        ),
        (
            "voltage_travel_stops_cavitation",
            digest(
                &[
                    driver("voltage"),
                    ("valve.x_flapper_max", 2e-5),
                    ("valve.x_spool_max", 2e-4),
                    ("cylinder.C_leak", 1e-13),
                ],
                |t| vec![(vr::I_REF, 0.01 * square(50.0, t)), (vr::F_EXT, 800.0 * square(25.0, t))],
                nothing,
            ),
        ),
        (
            "industrial_retune_restore",
            digest(
                &[driver("industrial"), ("cylinder.C_leak_external", 1e-13)],
                |t| vec![(vr::I_REF, 0.008 * square(30.0, t))],
                retune_and_restore,
            ),
        ),
    ]
}

/// The digests of [`scenarios`], as the model computes them today.
const EXPECTED: [(&str, u64); 9] = [
    ("current_step", 0x54def0c0abaaea61),
    ("square_100Hz", 0x9b2ba61a1732822b),
    ("sine_20Hz", 0x333db6309d0efb61),
    ("position_touchdown", 0xe258790e392c115e),
    ("stand_under_load", 0x218d5f12c1583ec6),
    ("flow_square", 0x2251ca7cf3c300e5),
    ("hbridge_square", 0xaaba08d42f2add55),
    ("voltage_travel_stops_cavitation", 0x472b009bd2f33797),
    ("industrial_retune_restore", 0x5903259ba15e8d4b),
];

#[test]
fn nine_scenarios_are_bit_for_bit_what_they_were() {
    let got = scenarios();
    let listing: String =
        got.iter().map(|(name, d)| format!("    (\"{name}\", {d:#018x}),\n")).collect();
    let expected: Vec<(&str, u64)> = EXPECTED.to_vec();
    assert_eq!(got, expected, "new digests:\n{listing}");
}
