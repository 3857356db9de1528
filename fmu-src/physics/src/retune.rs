//! New values of tunable parameters during a run: the mode systems, guards and caches are
//! rebuilt for the new coefficients and the state reached so far is kept, so the change
//! takes effect from the next communication point. Called when the parameters are set,
//! never from `advance` (building the systems is not for doStep's hot path).

use super::*;

impl Physics {
    /// The same state under `params`, which differ from the current ones in tunable
    /// parameters only (gains, limits, friction, load, leakage): the structure (driver,
    /// control mode, sampling clocks) and the hardware are the caller's to keep. `inputs`
    /// and `time` only seed the rebuild; the state is the current one. On error nothing
    /// changes.
    pub fn retune(&mut self, params: &Params, inputs: &Inputs, time: f64) -> Result<(), String> {
        let mut next = Physics::start(params, inputs, time)?;
        let (a, old) = (&mut next.actuator, &self.actuator);
        a.digital = old.digital;
        a.outer = old.outer;
        // Not the rest cache: it holds for the old parameters.
        a.cylinder = DrivenCylinder::new(old.cylinder.state, old.cylinder.memory);
        a.p_supply = old.p_supply;
        // New gains or limits can make another driver mode (rail, slew) the consistent
        // one for the state reached: choose it again, as for a new command.
        let mut z = old.z;
        a.settle(&mut z);
        a.z = z;
        *self = next;
        Ok(())
    }
}
