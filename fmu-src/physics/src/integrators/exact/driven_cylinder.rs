//! The cylinder as the exact integrator drives it: along the spool's exact path over each
//! piece of a step, by the Rosenbrock integrator; not at all while it rests, and by its
//! speed alone while it glides.

use crate::components::cylinder;
use crate::components::cylinder::CylinderParams;
use crate::components::cylinder::CylinderState;
use crate::components::metering_ports::{AnyLap, Centred};
use crate::components::valve::SpoolPath;
use crate::events::Work;
use crate::held_inputs::HeldInputs;
use crate::numerics::augmented_state::Vector;
use crate::numerics::augmented_state::XS;
use crate::numerics::mode_systems::ModeSystem;
use crate::numerics::rosenbrock;
use crate::numerics::rosenbrock::advance_with_rate;
use crate::numerics::rosenbrock::RosenbrockMemory;

/// Pieces this short (events right at a piece start) take an Euler step in the cylinder, s.
const TINY_PIECE: f64 = 1e-10;
/// A cylinder counts as at rest when it would drift less than 1e-10 of its scale in this time, s.
const REST_HORIZON: f64 = 1.0;

/// The cylinder's state and its integrator's memory (both part of the instance state), and
/// the (spool, supply, load) bits at which it was last found at rest (a pure cache).
#[derive(Clone, Copy)]
pub(crate) struct DrivenCylinder {
    pub(crate) state: CylinderState,
    pub(crate) memory: RosenbrockMemory,
    resting_at: Option<[u64; 3]>,
}

impl DrivenCylinder {
    pub(crate) fn new(state: CylinderState, memory: RosenbrockMemory) -> Self {
        DrivenCylinder { state, memory, resting_at: None }
    }

    /// Advances the cylinder over a piece of `h` seconds in which the valve (driven by
    /// `sys`) went from `z0` to `z1`: the spool path is the quintic Hermite interpolant of
    /// its exact position, velocity and acceleration at both ends. A cylinder at rest behind
    /// a still spool is left as it is; one gliding behind it moves on at its speed.
    pub(crate) fn drive(
        &mut self,
        sys: &ModeSystem,
        params: &CylinderParams,
        work: &mut Work,
        (z0, z1, h): (&Vector, &Vector, f64),
        inputs: &HeldInputs,
    ) -> Result<(), String> {
        let spool_still = (z1[XS] - z0[XS]).abs() <= 1e-13 * z0[XS].abs().max(1e-9);
        if spool_still {
            let key = [z0[XS].to_bits(), inputs.p_supply.to_bits(), inputs.load.to_bits()];
            if self.resting_at == Some(key) {
                return Ok(());
            }
            // At rest means an equilibrium, whatever the piece length: no state drifting
            // ([`settled`]). dx/dt is v: a moving piston needs no model evaluation to tell.
            if settled(self.state.v, cylinder::X) && self.steady(params, z0[XS], inputs) {
                self.resting_at = Some(key);
                return Ok(());
            }
        }
        self.resting_at = None;
        // A steady piston that is not at rest is moving: it may glide.
        if spool_still
            && !settled(self.state.v, cylinder::X)
            && self.glide(params, z0[XS], inputs, h)
        {
            return Ok(());
        }
        if h <= TINY_PIECE {
            // Far below every cylinder time constant (|lambda| h < 2e-5): one Euler step.
            let f = cylinder::derivatives::<AnyLap>(
                params,
                &self.state,
                0.5 * (z0[XS] + z1[XS]),
                inputs.p_supply,
                inputs.load,
            );
            let mut y = self.state.to_array();
            for (y, d) in y.iter_mut().zip(f) {
                *y += h * d;
            }
            self.state = CylinderState::from_array(&y);
            return Ok(());
        }
        let path = SpoolPath::new(h, sys.spool_motion(z0), sys.spool_motion(z1));
        // The port laws change sides at null spool (with a lap: at the lands' openings), a
        // kink in the flows that Rodas4 would reject its way across: the piece is split there.
        let (ends, pieces) = piece_ends(&path, params.ports.kinks());
        let mut done = 0.0;
        for &end in &ends[..pieces] {
            let offset = done;
            let spool = |tau: f64| (path.position(offset + tau), path.rate(offset + tau));
            let (state, memory) = (&mut self.state, &mut self.memory);
            let (span, p_supply, load) = (end - offset, inputs.p_supply, inputs.load);
            // The ports' law chosen here, once per call of the integrator (see `PortLaw`).
            let stats = if params.ports.lap == 0.0 {
                advance_with_rate::<Centred>(params, state, span, p_supply, load, spool, memory)
            } else {
                advance_with_rate::<AnyLap>(params, state, span, p_supply, load, spool, memory)
            }?;
            work.add(&stats);
            done = end;
        }
        Ok(())
    }

    /// Both pressures and the speed settled behind a spool held at `x_s` (the rates of
    /// [`cylinder::derivatives`] but the position's). The force balance first: while the
    /// piston accelerates, no flow needs evaluating.
    fn steady(&self, params: &CylinderParams, x_s: f64, inputs: &HeldInputs) -> bool {
        let state = &self.state;
        settled(cylinder::acceleration(params, state, inputs.load), cylinder::V) && {
            let d =
                cylinder::derivatives::<AnyLap>(params, state, x_s, inputs.p_supply, inputs.load);
            settled(d[cylinder::PA], cylinder::PA) && settled(d[cylinder::PB], cylinder::PB)
        }
    }

    /// A piston gliding behind a still spool: steady, clear of the end stops over the whole
    /// piece, where nothing depends on the position (the chamber volumes only scale the
    /// pressure rates, which are settled). Its motion over `h` is then `x += v h` and nothing
    /// else changes: one model evaluation instead of a Rosenbrock step (a constant command
    /// drives the piston so across most of its stroke).
    fn glide(&mut self, params: &CylinderParams, x_s: f64, inputs: &HeldInputs, h: f64) -> bool {
        let half = params.half_stroke();
        let x_end = self.state.x + self.state.v * h;
        if !(self.state.x.abs() < half && x_end.abs() < half && self.steady(params, x_s, inputs)) {
            return false;
        }
        self.state.x = x_end;
        true
    }
}

/// The ends of the pieces a call of `path` is split into at the `kinks` it crosses (in
/// time order, the call's end last), and how many there are.
fn piece_ends(path: &SpoolPath, kinks: [Option<f64>; 2]) -> ([f64; 3], usize) {
    let mut ends = [path.h; 3];
    let mut n = 0;
    for level in kinks.into_iter().flatten() {
        if let Some(t) = path.level_crossing(level) {
            ends[n] = t;
            n += 1;
        }
    }
    if n == 2 && ends[1] < ends[0] {
        ends.swap(0, 1);
    }
    (ends, n + 1)
}

/// Whether a rate `d` of state `n` is settled: it would move the state less than 1e-10 of
/// its scale in [`REST_HORIZON`] (whatever the piece length: a short piece must not make
/// motion look still).
fn settled(d: f64, n: usize) -> bool {
    d.abs() * REST_HORIZON <= 1e-10 * rosenbrock::STATE_SCALE[n]
}
