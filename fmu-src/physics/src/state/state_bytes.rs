//! The physics' part of the instance state as bytes (whoever embeds the physics frames and checks them):
//! driver mode, valve stops, the augmented state, the digital loops, the cylinder and its
//! integrator's memory. Caches are not part of the state.

use crate::components::cylinder::{CylinderState, N_STATES};
use crate::components::driver::MODES;
use crate::components::hbridge::HBridgeState;
use crate::components::outer_loop::OuterLoop;
use crate::components::valve::Stops;
use crate::integrators::exact::driven_cylinder::DrivenCylinder;
use crate::numerics::augmented_state::N;
use crate::numerics::rosenbrock::{RosenbrockMemory, MEMORY_VALUES};
use crate::params::{Inputs, Params};
use crate::physics::Physics;
use crate::state::bytes::ByteReader;

impl Physics {
    pub fn write_bytes(&self, out: &mut Vec<u8>) {
        let a = &self.actuator;
        out.push(a.mode.index() as u8);
        out.push(a.stops.code() as u8);
        for x in a.z.iter() {
            out.extend_from_slice(&x.to_le_bytes());
        }
        a.hbridge.write_bytes(out);
        a.outer.write_bytes(out);
        for x in a.cylinder.state.to_array().iter().chain(a.cylinder.memory.to_array().iter()) {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }

    /// Inverse of [`Physics::write_bytes`], for these parameters and inputs.
    pub fn read_bytes(
        params: &Params,
        inputs: &Inputs,
        r: &mut ByteReader,
    ) -> Result<Physics, String> {
        let mode_index = r.u8()? as usize;
        let mode = *MODES
            .get(mode_index)
            .ok_or_else(|| format!("state has unknown driver mode {mode_index}"))?;
        let stops = Stops::from_code(r.u8()?)?;
        let mut physics = Physics::start(params, inputs, 0.0)
            .map_err(|e| format!("state holds invalid parameters: {e}"))?;
        let a = &mut physics.actuator;
        for k in 0..N {
            a.z[k] = r.f64()?;
        }
        a.hbridge = HBridgeState::read_bytes(r)?;
        a.outer = OuterLoop::read_bytes(r)?;
        let mut cylinder = [0.0; N_STATES];
        for x in cylinder.iter_mut() {
            *x = r.f64()?;
        }
        let mut memory = [0.0; MEMORY_VALUES];
        for x in memory.iter_mut() {
            *x = r.f64()?;
        }
        if !cylinder.iter().chain(memory.iter()).all(|x| x.is_finite()) {
            return Err("state holds non-finite cylinder values".into());
        }
        let memory = RosenbrockMemory::from_array(&memory);
        // The tolerance is `Params::solver_rtol`, carried in the memory the integrator reads.
        if memory.rtol != a.cylinder.memory.rtol {
            return Err(format!(
                "state's integrator tolerance {:e} is not its solver.rtol {:e}",
                memory.rtol, a.cylinder.memory.rtol
            ));
        }
        a.cylinder = DrivenCylinder::new(CylinderState::from_array(&cylinder), memory);
        if !a.z.iter().all(|x| x.is_finite()) {
            return Err("state holds non-finite values".into());
        }
        (a.mode, a.stops) = (mode, stops);
        a.active = a.systems[mode.index()].with_stops(&a.params, stops);
        Ok(physics)
    }
}
