//! The fixed-cost integrator behind the seam ([`super::integrator`]): work fixed by the
//! segment's length, for real-time rigs. Each segment is cut into `n` equal internal steps,
//! `n = ceil(span / h_internal)` (`solver.h_internal`, 25 us by default): a loop period
//! of 50 us gives two steps of 25 us, and where the internal step divides the
//! communication step the cuts do not depend on it. Per internal step:
//! * driver, coil and valve go by the mode's propagator over the step (cached per mode
//!   and span, built once), then the driver mode and valve stops are chosen again for the
//!   state reached ([`Actuator::settle`]): mode changes fall on step boundaries, with no
//!   event search;
//! * the cylinder (stiff: eigenvalues to -1.4e5 1/s) takes one step of ROS2 (Verwer's
//!   L-stable two-stage Rosenbrock method of order 2, order 2 for any matrix in W, so the
//!   spool's time dependence needs no df/dt term) with the analytic Jacobian and one 4x4
//!   LU; the spool moves linearly between the step's ends. No error control, no rejection.

use super::actuator::{current_system, Actuator};
use super::cylinder_jacobian::linearise;
use super::integrator::{Integrator, Segment};
use super::lu4::Lu4;
use super::*;

/// Mode changes placed inside one internal step at most; more are decided at its end.
const MAX_SWITCHES: usize = 3;

/// ROS2's gamma, 1 + 1/sqrt(2): L-stable.
const GAMMA: f64 = 1.707_106_781_186_547_5;

/// The fixed-cost integrator's own state: the propagators it built (a pure cache).
#[derive(Clone)]
pub(crate) struct FixedCostIntegrator {
    /// The longest internal step (s), `solver.h_internal`.
    h_internal: f64,
    cache: PropagatorCache,
}

impl FixedCostIntegrator {
    pub(crate) fn new(h_internal: f64) -> FixedCostIntegrator {
        FixedCostIntegrator { h_internal, cache: PropagatorCache::new() }
    }

    /// How many internal steps cut a segment of `span`.
    fn internal_steps(&self, span: f64) -> usize {
        augmented_state::ceil_count(span / self.h_internal).max(1)
    }
}

/// The propagator cache's name for the actuator's (mode, stops) pair.
fn propagator_key(actuator: &Actuator) -> usize {
    actuator.mode.index() + MODES.len() * actuator.stops.code()
}

impl Integrator for FixedCostIntegrator {
    fn evolve(
        &mut self,
        actuator: &mut Actuator,
        segment: Segment,
        inputs: &HeldInputs,
        events: &mut StepEvents,
    ) -> Result<(), String> {
        let n = self.internal_steps(segment.span);
        let h = segment.span / n as f64;
        for _ in 0..n {
            let xs0 = actuator.z[XS];
            self.driver_and_valve(actuator, h, events)?;
            ros2_step(actuator, (xs0, actuator.z[XS]), h, inputs)?;
        }
        Ok(())
    }

    /// The propagators whole segments need (loop periods and communication steps).
    fn prepare(&mut self, actuator: &Actuator, step: f64) {
        let c = &actuator.params;
        let looping = c.loops.mode != ControlMode::Current;
        for span in [Some(step), looping.then(|| 1.0 / c.loops.f_sample)].into_iter().flatten() {
            let n = self.internal_steps(span);
            let key = propagator_key(actuator);
            let sys = current_system(c, &actuator.active, &actuator.systems, actuator.mode);
            let _ = self.cache.get(key, sys, span / n as f64, true, 1);
        }
    }

    fn adopt_prepared(&mut self, probe: FixedCostIntegrator) {
        self.cache = probe.cache;
    }

    fn retuned(&mut self, _actuator: &Actuator, systems_rebuilt: bool) {
        if systems_rebuilt {
            self.cache.clear();
        }
    }

    fn count_work(&self, work: &mut Work) {
        work.exponentials += self.cache.exponentials;
    }
}

impl FixedCostIntegrator {
    /// Driver, coil and valve over one internal step of `h`. A guard of the mode that
    /// crossed inside it is placed by linear interpolation of its values at the ends (no
    /// iteration: exact for the slews' straight lines), the state propagated there, the
    /// mode changed and the rest of the step taken in the new one; after
    /// [`MAX_SWITCHES`] of those the mode is decided at the step's end alone.
    fn driver_and_valve(
        &mut self,
        actuator: &mut Actuator,
        h: f64,
        events: &mut StepEvents,
    ) -> Result<(), String> {
        let mut left = h;
        for switches in 0..=MAX_SWITCHES {
            let mut z1 = self.propagate(actuator, left, left == h)?;
            let crossing = (switches < MAX_SWITCHES)
                .then(|| first_crossing(actuator, &z1))
                .flatten()
                .filter(|&fraction| fraction < 1.0);
            if let Some(fraction) = crossing {
                let tau = left * fraction;
                z1 = self.propagate(actuator, tau, false)?;
                left -= tau;
            }
            let before = actuator.mode;
            driver::clip_overshoot(&actuator.params, &mut z1, before, crossing.is_some());
            actuator.settle(&mut z1);
            driver::count_switch(events, before, actuator.mode);
            actuator.z = z1;
            if crossing.is_none() || left <= 0.0 {
                break;
            }
        }
        Ok(())
    }

    /// Driver, coil and valve over one internal step of `h` in the current mode, put on
    /// its manifold. The H-bridge's switched spans go by Taylor series, as in the exact
    /// integrator (short and irregular: a series beats an exponential).
    fn propagate(&mut self, actuator: &Actuator, h: f64, nominal: bool) -> Result<Vector, String> {
        let c = &actuator.params;
        let sys = current_system(c, &actuator.active, &actuator.systems, actuator.mode);
        let z = &actuator.z;
        let mut z1 = if actuator.mode == Mode::Switched {
            let p = Propagator::taylor_only(sys, h, 1);
            let mut z = *z;
            for _ in 0..p.substeps {
                z = p.apply(sys, &z);
            }
            z
        } else {
            let key = propagator_key(actuator);
            let p = self.cache.get(key, sys, h, nominal, 1)?;
            let mut z = *z;
            for _ in 0..p.substeps {
                z = p.apply(sys, &z);
            }
            z
        };
        driver::project_onto(c, &actuator.hbridge, &mut z1, actuator.mode);
        Ok(z1)
    }
}

/// Where in a propagation from the actuator's state to `z1` the first of its mode's guards
/// crossed zero upwards, as a fraction of the span (linear interpolation); `None` if none did.
fn first_crossing(actuator: &Actuator, z1: &Vector) -> Option<f64> {
    let c = &actuator.params;
    let sys = current_system(c, &actuator.active, &actuator.systems, actuator.mode);
    (0..sys.n_guards)
        .filter_map(|g| {
            let (v0, v1) = (sys.guard_value(g, &actuator.z), sys.guard_value(g, z1));
            (v0 < 0.0 && v1 > 0.0).then(|| v0 / (v0 - v1))
        })
        .reduce(f64::min)
}

/// One ROS2 step of the cylinder over `h`, the spool going linearly from `xs.0` to `xs.1`:
/// `W = I - gamma h J`, `k1 = W^-1 f(y0, t0)`, `k2 = W^-1 (f(y0 + h k1, t0 + h) - 2 k1)`,
/// `y1 = y0 + h (3 k1 + k2) / 2`.
fn ros2_step(
    actuator: &mut Actuator,
    xs: (f64, f64),
    h: f64,
    inputs: &HeldInputs,
) -> Result<(), String> {
    let params = &actuator.params.cylinder;
    let y0 = actuator.cylinder.state.to_array();
    let (f0, jac, _) = linearise(params, &y0, xs.0, inputs.p_supply, inputs.load);
    let mut w = jac;
    for (i, row) in w.iter_mut().enumerate() {
        for (j, a) in row.iter_mut().enumerate() {
            *a = f64::from(u8::from(i == j)) - GAMMA * h * *a;
        }
    }
    let lu = Lu4::factor(w).ok_or("the cylinder's Rosenbrock matrix is singular; step refused")?;
    let k1 = lu.solve(f0);
    let mut y = y0;
    for i in 0..4 {
        y[i] += h * k1[i];
    }
    let f1 = cylinder::derivatives(
        params,
        &CylinderState::from_array(&y),
        xs.1,
        inputs.p_supply,
        inputs.load,
    );
    let mut rhs = f1;
    for i in 0..4 {
        rhs[i] -= 2.0 * k1[i];
    }
    let k2 = lu.solve(rhs);
    let mut y1 = y0;
    for i in 0..4 {
        y1[i] += 0.5 * h * (3.0 * k1[i] + k2[i]);
    }
    // The chambers' bulk modulus fades to zero at the cavitation floor, which the exact
    // solution never crosses; a step without error control can overshoot it: put back.
    for p in [cylinder::PA, cylinder::PB] {
        y1[p] = y1[p].max(params.p_cavitation);
    }
    if y1.iter().any(|v| !v.is_finite()) {
        return Err("the cylinder's state is not finite; step refused".into());
    }
    actuator.cylinder.state = CylinderState::from_array(&y1);
    let work = &mut actuator.work;
    work.steps_accepted += 1;
    (work.jacobians, work.factorisations) = (work.jacobians + 1, work.factorisations + 1);
    work.function_evaluations += 1;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cylinder::equilibrium;

    /// Why a naive fixed step fails here: with the spool open (0.3 mm) and chamber A near
    /// the supply pressure (a piston pushing at full command), the port's laminar slope puts
    /// the chambers' rates at -4e4 to -6e4 1/s (the stiffest, -1.4e5, elsewhere on the
    /// stroke); explicit Euler at 1e-4 s (|1 + h lambda| >= 3) overshoots and leaves the
    /// range the pressures can physically reach (between tank and supply) by several bar
    /// within 2 ms, where ROS2 (80 internal steps of 25 us) keeps both inside it. The
    /// orifice law's square root flattens as the pressure drop grows, which is what stops
    /// Euler's growth here short of overflow.
    #[test]
    fn explicit_euler_at_a_tenth_of_a_millisecond_leaves_the_physical_range() {
        let c = Coefficients::new(&Params::PAPER).unwrap();
        let params = &c.cylinder;
        let p_supply = Inputs::PAPER.p_supply;
        let xs = 3e-4;
        let mut start = equilibrium(params, p_supply, 0.0).to_array();
        (start[cylinder::PA], start[cylinder::PB]) = (p_supply - 1e3, 1e3);
        let (_, jac, _) = linearise(params, &start, xs, p_supply, 0.0);
        assert!(jac[cylinder::PA][cylinder::PA] * 1e-4 < -2.0, "{:e}", jac[0][0]);
        let mut euler = start;
        let mut euler_worst: f64 = 0.0;
        for _ in 0..20 {
            let state = CylinderState::from_array(&euler);
            let f = cylinder::derivatives(params, &state, xs, p_supply, 0.0);
            for (y, d) in euler.iter_mut().zip(f) {
                *y += 1e-4 * d;
            }
            let outside = |p: f64| (p - p_supply).max(params.p_tank - p).max(0.0);
            euler_worst = euler_worst.max(outside(euler[0])).max(outside(euler[1]));
        }
        let mut y = start;
        for _ in 0..80 {
            y = ros2(params, &y, xs, p_supply, 25e-6);
        }
        println!("explicit Euler: {euler_worst:e} Pa outside [tank, supply]");
        assert!(euler_worst > 1e5, "explicit Euler: {euler_worst:e} Pa outside");
        for p in [y[cylinder::PA], y[cylinder::PB]] {
            assert!((params.p_cavitation..=p_supply + 1e3).contains(&p), "ROS2: {p:e}");
        }
    }

    /// One ROS2 step of `h` with the spool held at `xs` (as `ros2_step` takes it).
    fn ros2(params: &CylinderParams, y: &[f64; 4], xs: f64, p_supply: f64, h: f64) -> [f64; 4] {
        let (f0, jac, _) = linearise(params, y, xs, p_supply, 0.0);
        let mut w = jac;
        for (i, row) in w.iter_mut().enumerate() {
            for (j, a) in row.iter_mut().enumerate() {
                *a = f64::from(u8::from(i == j)) - GAMMA * h * *a;
            }
        }
        let lu = Lu4::factor(w).unwrap();
        let k1 = lu.solve(f0);
        let y_mid: [f64; 4] = std::array::from_fn(|i| y[i] + h * k1[i]);
        let mid = CylinderState::from_array(&y_mid);
        let f1 = cylinder::derivatives(params, &mid, xs, p_supply, 0.0);
        let k2 = lu.solve(std::array::from_fn(|i| f1[i] - 2.0 * k1[i]));
        std::array::from_fn(|i| y[i] + 0.5 * h * (3.0 * k1[i] + k2[i]))
    }
}
