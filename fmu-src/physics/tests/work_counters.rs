//! The work counters ([`ehsv_physics::Work`]) mean what they say, step by step: every
//! internal step of the cylinder's integrator, accepted (Rodas3 ones included) or rejected,
//! factorised its iteration matrix once (a Rodas3 attempt that failed and was redone by
//! Rodas4 once more); every linearisation is a Jacobian and a model evaluation, and an
//! attempt evaluates the model at most five times besides its linearisation (Rodas4; Rodas3
//! twice).

use ehsv_physics::{Inputs, Params, Physics, Work};

fn check(work: &Work, label: &str) {
    let steps = work.steps_accepted + work.steps_rejected;
    assert!(work.cylinder_calls <= steps, "{label}: {work:?}");
    // One LU per attempt: accepted and rejected Rodas4 steps, accepted and failed Rodas3
    // attempts (a failed one is redone, so at most two per step).
    assert!(steps <= work.factorisations && work.factorisations <= 2 * steps, "{label}: {work:?}");
    // A linearisation per point the integrator starts from (rejected attempts reuse it).
    assert!(
        work.jacobians <= work.factorisations && work.jacobians >= work.cylinder_calls,
        "{label}: {work:?}"
    );
    assert!(
        work.function_evaluations >= work.jacobians + 2 * work.factorisations
            && work.function_evaluations <= work.jacobians + 5 * work.factorisations,
        "{label}: {work:?}"
    );
}

/// Through command steps both ways, the piston running into its + end stop and back.
#[test]
fn work_counters_add_up_in_every_step() {
    let p = Params::PAPER;
    let mut physics = Physics::start(&p, &Inputs::PAPER, 0.0).unwrap();
    let h = 1e-4;
    for k in 0..800 {
        let t = k as f64 * h;
        let i_ref = [6e-3, -4e-3, 1e-4][(k / 300).min(2)];
        let before = physics.work();
        physics.step(&Inputs { i_ref, ..Inputs::PAPER }, t, h).unwrap();
        check(&physics.work().since(&before), &format!("step {k}"));
    }
    let total = physics.work();
    check(&total, "whole run");
    assert!(total.steps_accepted > 800 && total.steps_rejected > 0, "{total:?}");
    assert!(physics.outputs().x_piston.abs() > 1e-3, "the piston moved");
}
