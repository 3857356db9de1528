//! No parameter value, however far past physics, makes a step loop without end: the
//! variable table's ranges stop such values at the FMU's door, and behind it the physics
//! refuses what it cannot propagate (issue 37: a slew rate of 1e300 V/s used to ask the
//! fixed-cost method's matrix exponential for 2^31 squarings).

use ehsv_physics::{Inputs, Params, Physics, SolverMethod};

/// The op-amp at a slew rate of 1e300 V/s: the fixed-cost method's first step is refused
/// with a message, after preparing returned, instead of squaring a matrix 2^31 times.
#[test]
fn a_slew_rate_past_f64s_exponentials_is_refused_not_looped_on() {
    let mut params = Params::PAPER;
    params.opamp.slew_rate = 1e300;
    params.solver_method = SolverMethod::FixedCost;
    let inputs = Inputs::PAPER;
    let mut physics = Physics::start(&params, &inputs, 0.0).unwrap();
    physics.prepare_first_step(&inputs, 0.0, 1e-4);
    let command = Inputs { i_ref: 5e-3, ..inputs };
    let error = physics.step(&command, 0.0, 1e-4).unwrap_err();
    assert!(error.contains("beyond exact propagation"), "{error}");
}
