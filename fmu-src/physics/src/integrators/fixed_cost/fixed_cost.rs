//! The fixed-cost integrator behind the seam ([`crate::integrators::seam`]): work fixed by the
//! segment's length, for real-time rigs. Each segment is cut into `n` equal internal steps,
//! `n = ceil(span / h_internal)` (`solver.h_internal`, 50 us by default: the digital
//! loops' period, so every control mode steps on the same grid, two internal steps per
//! 1e-4 s communication step), and where the internal step divides the communication step
//! the cuts do not depend on it.
//! Per internal step:
//! * driver, coil and valve go by the mode's propagator over the step (one matrix per mode
//!   and span, [`super::whole_steps`]; built when the first step is prepared); a guard that
//!   crossed inside the step is placed by one linear interpolation, the mode chosen again
//!   there ([`Actuator::settle`]) and the rest of the step taken in the new one: no event
//!   search; the parts of a step either side of such a change go by the mode's ladder of
//!   prebuilt exponentials ([`super::dyadic_ladder`]), so no doStep builds one; a brief
//!   slew from the step's start is taken as a jump with its volt-seconds made good
//!   ([`brief_slew_as_a_jump`]);
//! * the cylinder (stiff: eigenvalues to -1.4e5 1/s) takes one linearly implicit step of
//!   [`super::lean_cylinder`] (cut where the piston meets or leaves a stop, where a chamber
//!   enters the cavitation band or passes a relief valve's cracking pressure; in halves in a
//!   stop's contact), the spool on the straight line
//!   between its positions at the step's ends.

use crate::actuator::{current_system, pi_driver_free_of_stops, system_key, Actuator};
use crate::components::coefficients::Coefficients;
use crate::components::driver;
use crate::components::driver::Mode;
use crate::components::driver::MODES;
use crate::components::hbridge::HBridgeState;
use crate::components::metering_ports::{AnyLap, Centred, PortLaw};
use crate::components::valve;
use crate::events::StepEvents;
use crate::events::Work;
use crate::held_inputs::HeldInputs;
use crate::integrators::fixed_cost::dyadic_ladder::DyadicLadders;
use crate::integrators::fixed_cost::lean_cylinder;
use crate::integrators::fixed_cost::whole_steps::WholeSteps;
use crate::integrators::seam::{Integrator, Segment};
use crate::numerics::augmented_state;
use crate::numerics::augmented_state::Vector;
use crate::numerics::augmented_state::{I, RAIL, U};
use crate::numerics::mode_systems::{Propagator, MAX_GUARDS};
use crate::numerics::slew_end;
use crate::params::ControlMode;

/// Mode changes placed inside one internal step at most; more are decided at its end.
const MAX_SWITCHES: usize = 3;

/// The fixed-cost integrator's own state: the propagators it built (a pure cache).
#[derive(Clone)]
pub(crate) struct FixedCostIntegrator {
    /// The longest internal step (s), `solver.h_internal`.
    h_internal: f64,
    /// Whole internal steps' propagators, per mode and step.
    whole: WholeSteps,
    /// Parts of internal steps (either side of a mode change placed inside one).
    ladders: DyadicLadders,
    /// The mode pairs whose slew ends [`slew_end`] takes.
    slew_exits: slew_end::SlewExits,
    /// The communication step the propagators were built ahead for, to build them again
    /// when a retune changes the systems.
    prepared_for: Option<f64>,
    /// The last segment's span (its bits) and its cut, `n` internal steps of `h`: the
    /// spans repeat (the communication step, the loop period), and the cut costs two
    /// divisions and a rounding.
    last_cut: (u64, usize, f64),
}

impl FixedCostIntegrator {
    pub(crate) fn new(h_internal: f64, actuator: &Actuator) -> FixedCostIntegrator {
        FixedCostIntegrator {
            h_internal,
            whole: WholeSteps::new(),
            ladders: DyadicLadders::new(h_internal),
            slew_exits: slew_end::slew_exits(&actuator.systems),
            prepared_for: None,
            // The cut of a NaN span: a key no other span matches.
            last_cut: (f64::NAN.to_bits(), 1, f64::NAN),
        }
    }

    /// How many internal steps cut a segment of `span`.
    fn internal_steps(&self, span: f64) -> usize {
        augmented_state::ceil_count(span / self.h_internal).max(1)
    }

    /// A segment of `span` cut into `n` internal steps of `h`: `(n, h)`.
    #[inline]
    fn cut(&mut self, span: f64) -> (usize, f64) {
        let (bits, n, h) = self.last_cut;
        if bits == span.to_bits() {
            return (n, h);
        }
        let n = self.internal_steps(span);
        let h = span / n as f64;
        self.last_cut = (span.to_bits(), n, h);
        (n, h)
    }
}

impl Integrator for FixedCostIntegrator {
    fn evolve(
        &mut self,
        actuator: &mut Actuator,
        segment: Segment,
        inputs: &HeldInputs,
        events: &mut StepEvents,
    ) -> Result<(), String> {
        let (n, h) = self.cut(segment.span);
        // The ports' law chosen once per segment (see `PortLaw`): the internal steps of
        // critically centred ports carry no test of the lap.
        if actuator.params.cylinder.ports.centred() {
            self.run_internal_steps::<Centred>(actuator, (n, h), inputs, events)
        } else {
            self.lapped_internal_steps(actuator, (n, h), inputs, events)
        }
    }

    /// The propagators of whole internal steps over the communication step and the loop
    /// period, for every mode at the stops the probe ended in: a mode's first use inside a
    /// doStep would otherwise build its exponential there (the slowest doSteps).
    fn prepare(&mut self, actuator: &Actuator, step: f64) {
        self.prepared_for = Some(step);
        let c = &actuator.params;
        let looping = c.loops.mode != ControlMode::Current;
        for span in [Some(step), looping.then(|| 1.0 / c.loops.f_sample)].into_iter().flatten() {
            let h = span / self.internal_steps(span) as f64;
            for mode in MODES.into_iter().filter(|&m| m != Mode::Switched) {
                let key = system_key(mode, actuator.stops);
                let sys = actuator.systems[mode.index()].with_stops(c, actuator.stops);
                // A mode this driver never enters may have no propagator: nothing to build.
                let _ = self.whole.slot(key, &sys, h);
                let _ = self.ladders.slot(key, &sys);
            }
        }
    }

    fn adopt_prepared(&mut self, probe: FixedCostIntegrator) {
        self.whole = probe.whole;
        self.ladders = probe.ladders;
        self.prepared_for = probe.prepared_for;
    }

    /// New systems: their propagators built here, in the setter that retuned, as at
    /// initialisation, so that no doStep after it builds one.
    fn retuned(&mut self, actuator: &Actuator, systems_rebuilt: bool) {
        if systems_rebuilt {
            self.whole.clear();
            self.ladders.clear();
            self.slew_exits = slew_end::slew_exits(&actuator.systems);
            if let Some(step) = self.prepared_for {
                self.prepare(actuator, step);
            }
        }
    }

    fn count_work(&self, work: &mut Work) {
        work.exponentials += self.whole.exponentials + self.ladders.exponentials;
    }
}

impl FixedCostIntegrator {
    /// `n` internal steps of `h`, the ports by the law `L`.
    #[inline(always)]
    fn run_internal_steps<L: PortLaw>(
        &mut self,
        actuator: &mut Actuator,
        (n, h): (usize, f64),
        inputs: &HeldInputs,
        events: &mut StepEvents,
    ) -> Result<(), String> {
        // An internal step's end is the next one's start (the cylinder's step leaves the
        // driver and valve as they are).
        let mut start = spool_position(actuator);
        let mut output_rate = None;
        for _ in 0..n {
            output_rate = self.driver_and_valve(actuator, h, output_rate, events)?;
            let end = spool_position(actuator);
            lean_cylinder::step::<L>(actuator, [start, end], h, inputs)?;
            start = end;
        }
        Ok(())
    }

    /// [`Self::run_internal_steps`] of lapped ports, out of line: the segment of critically
    /// centred ports, which its internal steps are inlined into, stays as it was.
    #[cold]
    #[inline(never)]
    fn lapped_internal_steps(
        &mut self,
        actuator: &mut Actuator,
        cut: (usize, f64),
        inputs: &HeldInputs,
        events: &mut StepEvents,
    ) -> Result<(), String> {
        self.run_internal_steps::<AnyLap>(actuator, cut, inputs, events)
    }

    /// Driver, coil and valve over one internal step of `h`. A guard of the mode that
    /// crossed inside it is placed by linear interpolation of its values at the ends (no
    /// iteration), the state propagated there, the mode changed and the rest of the step
    /// taken in the new one; after [`MAX_SWITCHES`] of those the mode is decided at the
    /// step's end alone. A slew from the step's start into the linear mode (a new command:
    /// a step of it, or a loop's sample) is placed exactly first ([`Self::slew_from_start`]).
    /// `output_rate` and the result: the linear output's rate at the state where the linear
    /// lane left it, passed on to the segment's next internal step (see [`Self::linear_lane`]).
    /// Inlined in each law's copy of the internal steps.
    #[inline(always)]
    fn driver_and_valve(
        &mut self,
        actuator: &mut Actuator,
        h: f64,
        output_rate: Option<f64>,
        events: &mut StepEvents,
    ) -> Result<Option<f64>, String> {
        if let Some(rate) = self.linear_lane(actuator, h, output_rate)? {
            return Ok(Some(rate));
        }
        self.switching_step(actuator, h, events)?;
        Ok(None)
    }

    /// [`Self::driver_and_valve`] off the linear lane. Out of line: its bookkeeping would
    /// otherwise set up its frame on every internal step, the lane's too.
    #[inline(never)]
    fn switching_step(
        &mut self,
        actuator: &mut Actuator,
        h: f64,
        events: &mut StepEvents,
    ) -> Result<(), String> {
        let (mut left, mut ahead) = (h, None);
        let mut first = 0;
        if let Some((tau, end)) = self.slew_from_start(actuator, h, events)? {
            (left, ahead, first) = (h - tau, end, 1);
        }
        for switches in first..=MAX_SWITCHES {
            let mut z1 = match ahead.take() {
                Some(end) => end,
                None => self.propagate(actuator, left, left == h)?,
            };
            let (crossing, inside) = guards_along(actuator, &z1);
            let crossing = crossing.filter(|&fraction| switches < MAX_SWITCHES && fraction < 1.0);
            if let Some(fraction) = crossing {
                let tau = left * fraction;
                z1 = self.propagate(actuator, tau, false)?;
                left -= tau;
            }
            // Inside every guard of its mode the state stays in that mode: nothing to clip
            // or choose again.
            if crossing.is_some() || !inside {
                let before = actuator.mode;
                driver::clip_overshoot(&actuator.params, &mut z1, before, crossing.is_some());
                actuator.settle(&mut z1);
                driver::count_switch(events, before, actuator.mode);
            }
            actuator.z = z1;
            if crossing.is_none() || left <= 0.0 {
                break;
            }
        }
        Ok(())
    }

    /// The most common internal step, the way [`Self::driver_and_valve`] takes it but without
    /// its bookkeeping: a PI driver free of valve stops that stays in its linear mode over
    /// the step, from the step's start or after a brief slew into it from there (a loop's
    /// sample, a new command: taken as a jump, [`jumped_to_linear`]). The same arithmetic in
    /// the same order, so the same bits. `None`, with nothing changed, for any other step:
    /// a slew that is not brief, a state within the tolerance of a rail, a guard reached.
    /// `known_rate`: the output's rate at the actuator's state where the lane left it in
    /// the segment's last internal step (its end guards computed it; the cylinder's step
    /// leaves that state as it is). Taking the lane, the output's rate at its end. Inlined in
    /// each law's copy of the internal steps.
    #[inline(always)]
    fn linear_lane(
        &mut self,
        actuator: &mut Actuator,
        h: f64,
        known_rate: Option<f64>,
    ) -> Result<Option<f64>, String> {
        let c = &actuator.params;
        if !pi_driver_free_of_stops(c) {
            return Ok(None);
        }
        let start = match actuator.mode {
            Mode::Linear => actuator.z,
            Mode::SlewUp | Mode::SlewDown => match self.slew_end(actuator, h) {
                Some(tau) if tau <= h * BRIEF_SLEW => {
                    jumped_to_linear(c, &actuator.hbridge, actuator.mode, tau, &actuator.z)
                }
                _ => return Ok(None),
            },
            _ => return Ok(None),
        };
        let linear = &actuator.systems[Mode::Linear.index()];
        let start_rate = match (actuator.mode, known_rate) {
            (Mode::Linear, Some(rate)) => rate,
            _ => driver::output_rate(&linear.a, &start),
        };
        if !driver::surely_linear(c, &start, start_rate) {
            return Ok(None);
        }
        let key = system_key(Mode::Linear, valve::Stops::default());
        let mut end = self.whole.propagate(key, linear, h, &start)?;
        driver::project_onto(c, &actuator.hbridge, &mut end, Mode::Linear);
        let end_rate = driver::output_rate(&linear.a, &end);
        if driver::linear_guards_at_rate(c, &end, end_rate).iter().any(|&g| g >= 0.0) {
            return Ok(None);
        }
        (actuator.mode, actuator.z) = (Mode::Linear, end);
        Ok(Some(end_rate))
    }

    /// A slew from the internal step's start that ends inside it in the linear mode, without
    /// the valve at a stop: its end is the root of a quadratic ([`slew_end::end_time`]:
    /// exact, no search), the state is taken there and settled, and the linear mode's end of
    /// the step is its start pulled back to the step's ([`slew_end::pulled_back`]) through
    /// the whole step's propagator (where the pair does not qualify `None`: the rest goes by
    /// the ladder). Its end and that state; `None` for any other step. A slew that ends
    /// within [`BRIEF_SLEW`] of the step is taken as a jump instead (its end 0, no state).
    fn slew_from_start(
        &mut self,
        actuator: &mut Actuator,
        h: f64,
        events: &mut StepEvents,
    ) -> Result<Option<(f64, Option<Vector>)>, String> {
        let Some(tau) = self.slew_end(actuator, h) else {
            return Ok(None);
        };
        if tau <= h * BRIEF_SLEW {
            brief_slew_as_a_jump(actuator, tau, events);
            return Ok(Some((0.0, None)));
        }
        let (start, from) = (actuator.z, actuator.mode);
        let mut z1 = self.propagate(actuator, tau, false)?;
        driver::clip_overshoot(&actuator.params, &mut z1, from, true);
        actuator.settle(&mut z1);
        driver::count_switch(events, from, actuator.mode);
        actuator.z = z1;
        let Some(exit) = slew_end::exit(&self.slew_exits, from, actuator.mode) else {
            return Ok(Some((tau, None)));
        };
        let to = &actuator.systems[actuator.mode.index()];
        let Some(mut pulled) = slew_end::pulled_back(to, exit, &start, tau) else {
            return Ok(Some((tau, None)));
        };
        // On the new mode's manifold, as the state at the switch is (the manifold is
        // invariant: putting the start on it puts the switch on it).
        driver::project_onto(&actuator.params, &actuator.hbridge, &mut pulled, actuator.mode);
        Ok(Some((tau, Some(self.propagate_from(actuator, &pulled, h, true)?))))
    }

    /// Where a slew of the actuator's mode, from its state, into the linear mode ends inside
    /// an internal step of `h` short of the rails; `None` where it does not or the valve is
    /// at a stop (its system is not the one the pulled-back start is for).
    fn slew_end(&self, actuator: &Actuator, h: f64) -> Option<f64> {
        if actuator.stops != valve::Stops::default() {
            return None;
        }
        let exit = slew_end::exit(&self.slew_exits, actuator.mode, Mode::Linear)?;
        let (c, z) = (&actuator.params, &actuator.z);
        let tau = slew_end::end_time(c, exit, z)?;
        let rate = driver::slew_velocity(c, actuator.mode);
        (tau < h && (z[U] + rate * tau).abs() < z[RAIL]).then_some(tau)
    }

    /// Driver, coil and valve over `h` in the current mode from the actuator's state (see
    /// [`Self::propagate_from`]).
    fn propagate(&mut self, actuator: &Actuator, h: f64, nominal: bool) -> Result<Vector, String> {
        self.propagate_from(actuator, &actuator.z, h, nominal)
    }

    /// Driver, coil and valve over `h` in the actuator's current mode from `z`, put on its
    /// manifold: a whole internal step (`nominal`) by its cached propagator, a part of one by
    /// the mode's ladder. The H-bridge's switched spans go by Taylor series, as in the exact
    /// integrator (short and irregular: a series beats an exponential), but for whole steps
    /// of its periods' means.
    fn propagate_from(
        &mut self,
        actuator: &Actuator,
        z: &Vector,
        h: f64,
        nominal: bool,
    ) -> Result<Vector, String> {
        let c = &actuator.params;
        let sys = current_system(c, &actuator.active, &actuator.systems, actuator.mode);
        // The bridge's PWM by its periods' means holds one voltage over whole steps, which
        // then go by their propagator as the other modes' do.
        let switching = actuator.mode == Mode::Switched && !(nominal && c.hbridge.pwm_mean);
        let mut z1 = if switching {
            Propagator::taylor_only(sys, h, 1).apply_all(sys, z)
        } else if nominal {
            self.whole.propagate(actuator.system_key(), sys, h, z)?
        } else {
            self.ladders.propagate(actuator.system_key(), sys, h, z)?
        };
        driver::project_onto(c, &actuator.hbridge, &mut z1, actuator.mode);
        Ok(z1)
    }
}

/// A slew from an internal step's start that ends within this share of the step is taken
/// as a jump to the linear mode with its volt-seconds made good ([`brief_slew_as_a_jump`]):
/// a loop's sample or a command's change moves the op-amp's output by a few volts, a slew
/// of a fraction of a microsecond, which otherwise costs a propagation of its own.
const BRIEF_SLEW: f64 = 1.0 / 16.0;

/// The actuator's slew of `tau` into the linear mode as a jump to it at the step's start:
/// a ramp from `u0` to `u0 + S tau` puts `S tau^2 / 2` volt-seconds less across the coil than
/// the jump, which the coil's current gives back at once (`L di = S tau^2 / 2`). What is
/// left is of second order in `tau` and decays with the current loop (20 us at the
/// defaults).
fn brief_slew_as_a_jump(actuator: &mut Actuator, tau: f64, events: &mut StepEvents) {
    let from = actuator.mode;
    let mut z = jumped_to_linear(&actuator.params, &actuator.hbridge, from, tau, &actuator.z);
    actuator.settle(&mut z);
    driver::count_switch(events, from, actuator.mode);
    actuator.z = z;
}

/// `z`, in a slew of `mode` that ends after `tau`, taken to the linear mode at once: the
/// current less the slew's missing volt-seconds, on the linear mode's manifold (see
/// [`brief_slew_as_a_jump`]).
fn jumped_to_linear(
    c: &Coefficients,
    hbridge: &HBridgeState,
    mode: Mode,
    tau: f64,
    z: &Vector,
) -> Vector {
    let rate = driver::slew_velocity(c, mode);
    let mut z = *z;
    z[I] -= 0.5 * rate * tau * tau / c.inductance;
    driver::project_onto(c, hbridge, &mut z, Mode::Linear);
    z
}

/// Where in a propagation from the actuator's state to `z1` the first of its mode's guards
/// crossed zero upwards, as a fraction of the span (linear interpolation; `None` if none
/// did), and whether every guard is negative at `z1`. A guard's start is looked at only
/// where its end is positive.
fn guards_along(actuator: &Actuator, z1: &Vector) -> (Option<f64>, bool) {
    let (ends, n) = guard_values(actuator, z1);
    let (mut first, mut inside) = (None, true);
    for (g, &v1) in ends[..n].iter().enumerate() {
        inside &= v1 < 0.0;
        if v1 > 0.0 {
            let v0 = guard_values(actuator, &actuator.z).0[g];
            if v0 < 0.0 {
                let fraction = v0 / (v0 - v1);
                first = Some(first.map_or(fraction, |f: f64| f.min(fraction)));
            }
        }
    }
    (first, inside)
}

/// The values of the actuator's mode's guards at `z`, and how many there are: the linear
/// mode's free of valve stops written out ([`driver::linear_guard_values`]: most steps are
/// in it), the others by their rows.
fn guard_values(actuator: &Actuator, z: &Vector) -> ([f64; MAX_GUARDS], usize) {
    let c = &actuator.params;
    let mut values = [0.0; MAX_GUARDS];
    if actuator.mode == Mode::Linear && !valve::has_stops(c) {
        let linear = driver::linear_guard_values(c, &actuator.systems[Mode::Linear.index()].a, z);
        values[..linear.len()].copy_from_slice(&linear);
        return (values, linear.len());
    }
    let sys = current_system(c, &actuator.active, &actuator.systems, actuator.mode);
    for (g, value) in values[..sys.n_guards].iter_mut().enumerate() {
        *value = sys.guard_value(g, z);
    }
    (values, sys.n_guards)
}

/// The spool's position in the actuator's current mode (held at a stop where it has one).
fn spool_position(actuator: &Actuator) -> f64 {
    let c = &actuator.params;
    let sys = current_system(c, &actuator.active, &actuator.systems, actuator.mode);
    sys.spool_motion(&actuator.z)[0]
}
