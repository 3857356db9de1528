//! What the physics crate's integration tests share: saving and restoring a state's bytes,
//! a call that must answer within a time, and a step that must be refused at once.
#![allow(dead_code)]

use ehsv_physics::bytes::ByteReader;
use ehsv_physics::{Inputs, Params, Physics};

/// The physics' state bytes.
pub fn save(physics: &Physics) -> Vec<u8> {
    let mut bytes = Vec::new();
    physics.write_bytes(&mut bytes);
    bytes
}

/// An instance of `p` and `i` restored from `bytes`.
pub fn restore(p: &Params, i: &Inputs, bytes: &[u8]) -> Result<Physics, String> {
    Physics::read_bytes(p, i, &mut ByteReader::new(bytes))
}

/// Runs `f` on its own thread and gives up after `seconds` (a step that is not refused may
/// run for minutes).
pub fn within<T: Send + 'static>(seconds: f64, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(std::time::Duration::from_secs_f64(seconds))
        .unwrap_or_else(|_| panic!("no answer within {seconds} s"))
}

/// The error a step of `step` s from a start with `p` and `i` gives, which must come within
/// 10 s: a step that is not refused may run for minutes, and that it is taken fails.
pub fn refusal_of_step(p: &Params, i: &Inputs, step: f64) -> String {
    let physics = Physics::start(p, i, 0.0).unwrap();
    let i = *i;
    let result = within(10.0, move || {
        let mut physics = physics;
        physics.step(&i, 0.0, step).map(|_| ())
    });
    result.expect_err(&format!("a step of {step} s was taken"))
}
