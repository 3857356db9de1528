//! The cylinder's internal step in the fixed-cost integrator ([`super::fixed_cost`]).
//!
//! One step of Rodas3 (L-stable, stiffly accurate, order 3; one analytic Jacobian, one 4x4
//! LU, two right-hand sides) along the spool's cubic path through its positions and
//! velocities at the step's ends (a path error of order h^4, below the method's own), with
//! no step control. Where its embedded estimate says the step crossed something its stages
//! overshoot (a kink of the model inside the step: an end stop's contact, a relief valve
//! cracking, a port's flow turning round; the stage points reach past it with a Jacobian
//! that does not know it), the step is taken again as two Rodas3 steps of half the size.
//! An internal step so costs one or three Rodas3 steps: bounded, with no iteration.

use super::cylinder::Vec4;
use super::rosenbrock::{rodas3_fixed_step, Stats};
use super::*;

/// Rodas3's embedded error estimate, as a share of the state's scale (1 MPa, 10 mm,
/// 0.1 m/s, or the state itself where larger), beyond which the step is taken again in two
/// halves. Smooth 25 us steps stay far below it; a step across a kink exceeds it (without
/// the halves Rodas3 overshot an end stop's pressure peak by 1.6 MPa on 100 Hz squares at
/// twice the rated current). Looser thresholds let that through, tighter ones change little.
const HALVING_RTOL: f64 = 1e-3;

/// The spool's position and velocity at the start and the end of an internal step.
pub(crate) type SpoolEnds = ([f64; 2], [f64; 2]);

/// Advances the actuator's cylinder by `h`, the spool moving from `spool.0` to `spool.1`.
pub(crate) fn step(
    actuator: &mut Actuator,
    spool: SpoolEnds,
    h: f64,
    inputs: &HeldInputs,
) -> Result<(), String> {
    let y0 = actuator.cylinder.state.to_array();
    let mut stats = Stats::default();
    let loads = (inputs.p_supply, inputs.load);
    let y1 = advance(&actuator.params.cylinder, &y0, spool, h, loads, &mut stats)?;
    actuator.cylinder.state = CylinderState::from_array(&y1);
    actuator.work.add(&stats);
    Ok(())
}

/// The state after one internal step of `h` from `y0`: one Rodas3 step, or two of `h / 2`
/// where the one step's estimate fails [`HALVING_RTOL`] (counted as rejected).
fn advance(
    params: &CylinderParams,
    y0: &Vec4,
    spool: SpoolEnds,
    h: f64,
    loads: (f64, f64),
    stats: &mut Stats,
) -> Result<Vec4, String> {
    let path = cubic_path(spool, h);
    let (whole, err) = rodas3_fixed_step(params, (y0, h), &path, loads, HALVING_RTOL, stats)?;
    let y1 = if err <= 1.0 {
        stats.accepted += 1;
        whole
    } else {
        stats.rejected += 1;
        let (x_mid, v_mid) = path(0.5 * h);
        let mid = [x_mid, v_mid];
        let first = cubic_path((spool.0, mid), 0.5 * h);
        let (y_mid, _) = rodas3_fixed_step(params, (y0, 0.5 * h), &first, loads, 1.0, stats)?;
        let second = cubic_path((mid, spool.1), 0.5 * h);
        let (y1, _) = rodas3_fixed_step(params, (&y_mid, 0.5 * h), &second, loads, 1.0, stats)?;
        stats.accepted += 2;
        y1
    };
    if y1.iter().any(|v| !v.is_finite()) {
        return Err("the cylinder's state is not finite; step refused".into());
    }
    Ok(y1)
}

/// The cubic (Hermite) through the spool's position and velocity at both ends of a step of
/// `h`: position and rate at a time into the step.
fn cubic_path(([x0, v0], [x1, v1]): SpoolEnds, h: f64) -> impl Fn(f64) -> (f64, f64) {
    move |tau: f64| {
        let s = tau / h;
        let r = 1.0 - s;
        let position =
            (1.0 + 2.0 * s) * r * r * x0 + s * r * r * h * v0 + s * s * (3.0 - 2.0 * s) * x1
                - s * s * r * h * v1;
        let rate =
            6.0 * s * r * (x1 - x0) / h + r * (1.0 - 3.0 * s) * v0 + s * (3.0 * s - 2.0) * v1;
        (position, rate)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cylinder::equilibrium;

    fn paper_cylinder() -> (CylinderParams, f64) {
        let c = Coefficients::new(&Params::PAPER).unwrap();
        (c.cylinder, Inputs::PAPER.p_supply)
    }

    /// Why a naive fixed step fails here: with the spool open (0.3 mm) and chamber A near
    /// the supply pressure (a piston pushing at full command), the port's laminar slope puts
    /// the chambers' rates at -4e4 to -6e4 1/s (the stiffest, -1.4e5, elsewhere on the
    /// stroke); explicit Euler at 1e-4 s (|1 + h lambda| >= 3) overshoots and leaves the
    /// range the pressures can physically reach (between tank and supply) by several bar
    /// within 2 ms, where the fixed-cost step (80 internal steps of 25 us) keeps both inside
    /// it. The orifice law's square root flattens as the pressure drop grows, which is what
    /// stops Euler's growth here short of overflow.
    #[test]
    fn explicit_euler_at_a_tenth_of_a_millisecond_leaves_the_physical_range() {
        let (params, p_supply) = paper_cylinder();
        let xs = 3e-4;
        let mut start = equilibrium(&params, p_supply, 0.0).to_array();
        (start[cylinder::PA], start[cylinder::PB]) = (p_supply - 1e3, 1e3);
        let (_, jac, _) = crate::cylinder_jacobian::linearise(&params, &start, xs, p_supply, 0.0);
        assert!(jac[cylinder::PA][cylinder::PA] * 1e-4 < -2.0, "{:e}", jac[0][0]);
        let mut euler = start;
        let mut euler_worst: f64 = 0.0;
        for _ in 0..20 {
            let state = CylinderState::from_array(&euler);
            let f = cylinder::derivatives(&params, &state, xs, p_supply, 0.0);
            for (y, d) in euler.iter_mut().zip(f) {
                *y += 1e-4 * d;
            }
            let outside = |p: f64| (p - p_supply).max(params.p_tank - p).max(0.0);
            euler_worst = euler_worst.max(outside(euler[0])).max(outside(euler[1]));
        }
        let mut y = start;
        let held = ([xs, 0.0], [xs, 0.0]);
        for _ in 0..80 {
            y = advance(&params, &y, held, 25e-6, (p_supply, 0.0), &mut Stats::default()).unwrap();
        }
        println!("explicit Euler: {euler_worst:e} Pa outside [tank, supply]");
        assert!(euler_worst > 1e5, "explicit Euler: {euler_worst:e} Pa outside");
        for p in [y[cylinder::PA], y[cylinder::PB]] {
            assert!((params.p_cavitation..=p_supply + 1e3).contains(&p), "fixed cost: {p:e}");
        }
    }

    /// One internal step: parameters, state, spool ends, step, supply pressure and load.
    type StepFn<'a> = dyn Fn(&CylinderParams, &Vec4, SpoolEnds, f64, (f64, f64)) -> Vec4 + 'a;

    /// A smooth spool path: opening from 0.1 to 0.3 mm over 4 ms, position and velocity.
    fn opening(t: f64) -> [f64; 2] {
        let s = t / 4e-3;
        [1e-4 + 2e-4 * s * s * (3.0 - 2.0 * s), 2e-4 * 6.0 * s * (1.0 - s) / 4e-3]
    }

    /// The state after `n` steps of `step` over 4 ms from a piston already moving, relative
    /// to the state scale (1 MPa, 10 mm, 0.1 m/s).
    fn run_opening(n: usize, step: &StepFn) -> Vec4 {
        let (params, p_supply) = paper_cylinder();
        let mut y = equilibrium(&params, p_supply, 0.0).to_array();
        y[cylinder::V] = 0.05;
        let h = 4e-3 / n as f64;
        for k in 0..n {
            let ends = (opening(k as f64 * h), opening((k + 1) as f64 * h));
            y = step(&params, &y, ends, h, (p_supply, 0.0));
        }
        std::array::from_fn(|i| y[i] / crate::rosenbrock::STATE_SCALE[i])
    }

    /// The order of a step on a smooth run (no contact, no cavitation, the piston moving
    /// away from the friction's steep zero-velocity region): the error of 64, 128, 256 steps
    /// (62.5 to 15.6 us) against 8192.
    fn measured_orders(step: &StepFn) -> [f64; 2] {
        let reference = run_opening(8192, step);
        let error = |n| {
            let y = run_opening(n, step);
            (0..4).map(|i| (y[i] - reference[i]).abs()).fold(0.0, f64::max)
        };
        let e: Vec<f64> = [64, 128, 256].into_iter().map(error).collect();
        println!("errors {:?}", e.iter().map(|x| format!("{x:.2e}")).collect::<Vec<_>>());
        [(e[0] / e[1]).log2(), (e[1] / e[2]).log2()]
    }

    /// Rodas3 along the cubic spool path converges with order 3, approaching it from below
    /// as the step shrinks (stiff modes to -1.4e5 1/s are not resolved at these steps).
    #[test]
    fn the_fixed_cost_step_is_of_order_three() {
        let rodas3 = |p: &CylinderParams, y: &Vec4, ends, h, loads| {
            let path = cubic_path(ends, h);
            rodas3_fixed_step(p, (y, h), &path, loads, 1.0, &mut Stats::default()).unwrap().0
        };
        // At the default internal step the run never halves a step: it is one Rodas3 each.
        let fallbacks = std::cell::Cell::new(0);
        run_opening(160, &|p, y, ends, h, loads| {
            let mut stats = Stats::default();
            let y1 = advance(p, y, ends, h, loads, &mut stats).unwrap();
            fallbacks.set(fallbacks.get() + stats.rejected);
            y1
        });
        assert_eq!(fallbacks.get(), 0);
        let o3 = measured_orders(&rodas3);
        println!("Rodas3 along the cubic path: {o3:.2?}");
        assert!(o3.iter().all(|&o| o > 2.6), "Rodas3: {o3:?}");
    }
}
