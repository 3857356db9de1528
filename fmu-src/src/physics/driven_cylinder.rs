//! The cylinder as the exact integrator drives it: along the spool's exact path over each
//! piece of a step, by the Rosenbrock integrator, or not at all while it rests.

use super::*;

/// The cylinder's state and its integrator's memory (both part of the instance state), and
/// the (spool, supply, load) bits at which it was last found at rest (a pure cache).
#[derive(Clone, Copy)]
pub(crate) struct DrivenCylinder {
    pub(crate) state: CylinderState,
    pub(crate) memory: IntegratorMemory,
    rest: Option<[u64; 3]>,
}

impl DrivenCylinder {
    pub(crate) fn new(state: CylinderState, memory: IntegratorMemory) -> Self {
        DrivenCylinder { state, memory, rest: None }
    }

    /// Advances the cylinder over a piece of `h` seconds in which the valve (driven by
    /// `sys`) went from `z0` to `z1`: the spool path is the quintic Hermite interpolant of
    /// its exact position, velocity and acceleration at both ends. A cylinder at rest behind
    /// a still spool is left as it is.
    pub(crate) fn drive(
        &mut self,
        sys: &ModeSystem,
        params: &CylinderParams,
        work: &mut Work,
        (z0, z1, h): (&Vector, &Vector, f64),
        inputs: &Held,
    ) -> Result<(), String> {
        if (z1[XS] - z0[XS]).abs() <= 1e-13 * z0[XS].abs().max(1e-9) {
            let key = [z0[XS].to_bits(), inputs.p_supply.to_bits(), inputs.f_ext.to_bits()];
            if self.rest == Some(key) {
                return Ok(());
            }
            // At rest means an equilibrium, whatever the piece length: drifting less than
            // 1e-10 of its scale in a second (a short piece must not make motion look still).
            // dx/dt is v: a moving piston needs no model evaluation to tell.
            let still =
                |d: f64, n: usize| d.abs() * REST_HORIZON <= 1e-10 * rosenbrock::STATE_SCALE[n];
            if still(self.state.v, cylinder::X)
                && cylinder::derivatives(params, &self.state, z0[XS], inputs.p_supply, inputs.f_ext)
                    .iter()
                    .enumerate()
                    .all(|(n, &d)| still(d, n))
            {
                self.rest = Some(key);
                return Ok(());
            }
        }
        self.rest = None;
        if h <= TINY_PIECE {
            // Far below every cylinder time constant (|lambda| h < 2e-5): one Euler step.
            let f = cylinder::derivatives(
                params,
                &self.state,
                0.5 * (z0[XS] + z1[XS]),
                inputs.p_supply,
                inputs.f_ext,
            );
            let mut y = self.state.to_array();
            for (y, d) in y.iter_mut().zip(f) {
                *y += h * d;
            }
            self.state = CylinderState::from_array(&y);
            return Ok(());
        }
        let path = SpoolPath::new(h, sys.spool_motion(z0), sys.spool_motion(z1));
        // The port laws change sides at null spool, a kink in the flows that Rodas4 would
        // reject its way across: the piece is split there.
        let mut done = 0.0;
        for end in [path.null_crossing(), Some(h)].into_iter().flatten() {
            let offset = done;
            let spool = |tau: f64| (path.position(offset + tau), path.rate(offset + tau));
            let stats = rosenbrock::advance_with_rate(
                params,
                &mut self.state,
                end - offset,
                inputs.p_supply,
                inputs.f_ext,
                spool,
                &mut self.memory,
            )?;
            work.add(&stats);
            done = end;
        }
        Ok(())
    }
}
