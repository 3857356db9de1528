//! Advancing [`Physics`] over one communication step: the time events of the digital
//! loops cut the step; between them the chosen integrator evolves the actuator's continuous
//! part ([`crate::integrators::seam`]).

use crate::actuator::Actuator;
use crate::components::cylinder;
use crate::components::valve;
use crate::events::StepEvents;
use crate::held_inputs::HeldInputs;
use crate::integrators::chosen::ChosenIntegrator;
use crate::integrators::seam::{Integrator, Segment};
use crate::numerics::augmented_state::all_finite;
use crate::numerics::augmented_state::I;
use crate::numerics::augmented_state::I_CMD;
use crate::numerics::augmented_state::RAIL;
use crate::numerics::augmented_state::U;
use crate::numerics::augmented_state::XS;
use crate::params::ControlMode;
use crate::params::Inputs;
use crate::physics::Physics;
use crate::physics::RestKey;

/// Bounds the work of one step with the PWM driver (each instant ends a segment): a step
/// holding more instants is refused as far too long for the PWM.
const MAX_TIME_EVENTS_PER_STEP: u64 = 10_000_000;

/// The key of [`Physics`]'s `resting`: the inputs and the step size, as bits.
fn rest_key(i: &Inputs, step: f64) -> RestKey {
    [i.i_ref, i.v_supply, i.p_supply, i.f_ext, i.q_ref, i.x_ref, i.x_rod, i.v_rod, i.a_rod, step]
        .map(f64::to_bits)
}

impl Physics {
    /// Whether a step of `step` with `inputs` changes nothing: the last step had the same
    /// inputs and size, no clock runs, and it left the state as it was, bit for bit.
    #[inline]
    pub(super) fn rests(&self, inputs: &Inputs, step: f64) -> bool {
        // The keys compared bit for bit without a branch (nor a call to memcmp) per word.
        let same = |held: &RestKey| {
            held.iter().zip(rest_key(inputs, step)).fold(0, |diff, (a, b)| diff | (a ^ b)) == 0
        };
        self.resting.as_ref().is_some_and(same) && self.clocks_idle()
    }

    /// No sampling or PWM clock will ever tick (the loops are continuous or absent).
    #[inline]
    fn clocks_idle(&self) -> bool {
        let a = &self.actuator;
        a.hbridge.events_until(&a.params.hbridge, f64::INFINITY) == 0
            && a.outer.events_until(&a.params.loops, f64::INFINITY) == 0
    }

    /// Advances from `t_start` by `step` seconds with `inputs` held constant.
    /// On error the state is left as it was.
    pub(crate) fn advance(
        &mut self,
        inputs: &Inputs,
        t_start: f64,
        step: f64,
    ) -> Result<StepEvents, String> {
        let a = &self.actuator;
        // As `clocks_idle`, from the flags alone (no event counts).
        let clocks_idle = !a.hbridge.clocked() && !a.outer.clocked();
        let saved = (a.z, a.mode, a.stops, a.hbridge, a.outer, a.cylinder, a.p_supply);
        // A piston through the end of the cylinder is a broken state, refused like any error.
        let result = self.advance_inner(inputs, t_start, step).and_then(|events| {
            let a = &self.actuator;
            cylinder::check_inside(&a.params.cylinder, &a.cylinder.state)?;
            Ok(events)
        });
        let a = &mut self.actuator;
        let bits = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
        // Compared only where a rest could be kept (no clock runs, the step succeeded).
        let unchanged = || {
            bits(a.z.as_slice(), saved.0.as_slice())
                && (a.mode, a.stops) == (saved.1, saved.2)
                && bits(&a.cylinder.state.to_array(), &saved.5.state.to_array())
                && bits(&a.cylinder.memory.to_array(), &saved.5.memory.to_array())
                && a.p_supply.to_bits() == saved.6.to_bits()
        };
        // The key is built only for a step that rests.
        let rests = clocks_idle && result.is_ok() && unchanged();
        self.resting = if rests { Some(rest_key(inputs, step)) } else { None };
        if result.is_err() {
            (a.z, a.mode, a.stops, a.hbridge, a.outer, a.cylinder, a.p_supply) = saved;
            a.active = a.systems[a.mode.index()].with_stops(&a.params, a.stops);
        }
        result
    }

    fn advance_inner(
        &mut self,
        inputs: &Inputs,
        t_start: f64,
        step: f64,
    ) -> Result<StepEvents, String> {
        let mut events = StepEvents::default();
        let Physics { actuator: a, integrator, .. } = self;
        let inputs = HeldInputs::new(&a.params, inputs);
        a.p_supply = inputs.p_supply;
        a.follow_command(&inputs, &mut events);
        let p = &a.params;
        // Time events within a hair of the step end (rounding of t_start + step, either
        // side) belong to it and fire at its end: no segment of a few ulp after them, each
        // a full evolution for nothing.
        let period = 1.0 / p.loops.f_sample;
        let slack = 1e-9 * step.min(p.hbridge.period()).min(period);
        let times = StepTimes { t_start, t_end: t_start + step, step, period, slack };
        if a.hbridge.clocked() || a.outer.clocked() {
            through_time_events(a, integrator, &inputs, &times, &mut events)?;
        } else if times.t_end > t_start {
            // No clock runs: the step is one segment (the loop below would find no event).
            let span = times.nominal_span(times.t_end - t_start);
            integrator.evolve(a, Segment { span, whole: true }, &inputs, &mut events)?;
        }
        if !all_finite(&a.z) {
            return Err("the state became non-finite; step refused".into());
        }
        Ok(events)
    }
}

/// The instants of one communication step and the spans its segments are measured by.
struct StepTimes {
    t_start: f64,
    t_end: f64,
    step: f64,
    /// The outer loop's sample period.
    period: f64,
    /// How close to the step's end a time event belongs to it (see `advance_inner`).
    slack: f64,
}

impl StepTimes {
    fn nominal_span(&self, span: f64) -> f64 {
        nominal_span(span, [self.step, self.period], self.slack)
    }
}

/// The step cut at the time events of the H-bridge and the outer loop: the segments
/// between them evolved, each event fired at its instant.
fn through_time_events(
    a: &mut Actuator,
    integrator: &mut ChosenIntegrator,
    inputs: &HeldInputs,
    times: &StepTimes,
    events: &mut StepEvents,
) -> Result<(), String> {
    let StepTimes { t_start, t_end, step, slack, .. } = *times;
    // The coefficients borrowed where they are read, not copied: the loop reads a few of
    // them, and a copy is a memcpy of the whole struct on every step. The borrow is taken
    // again after each call that takes the whole actuator.
    let p = &a.params;
    let time_events =
        a.hbridge.events_until(&p.hbridge, t_end) + a.outer.events_until(&p.loops, t_end);
    if time_events > MAX_TIME_EVENTS_PER_STEP {
        return Err(too_many_events(step));
    }
    let mut t = t_start;
    loop {
        let p = &a.params;
        let t_bridge = a.hbridge.next_event(&p.hbridge);
        let t_loop = a.outer.next_event(&p.loops);
        let t_event = t_bridge.min(t_loop);
        let fire = t_event <= t_end + slack;
        let segment_end = if fire && t_event < t_end - slack { t_event } else { t_end };
        if segment_end > t {
            let whole = t == t_start && segment_end == t_end;
            let span = times.nominal_span(segment_end - t);
            integrator.evolve(a, Segment { span, whole }, inputs, events)?;
            t = segment_end;
        }
        if !fire {
            return Ok(());
        }
        let p = &a.params;
        if t_loop <= t_bridge {
            // The outer loop samples first, so a bridge sample at the same instant sees its command.
            let measured = match p.loops.mode {
                ControlMode::Flow => valve::no_load_flow(p, a.z[XS]),
                _ => a.cylinder.state.x,
            };
            a.outer.sample(&p.loops, inputs.reference, measured);
            a.follow_command(inputs, events);
        } else {
            a.hbridge.fire(&p.hbridge, a.z[I], a.z[I_CMD], p.r_total, a.z[RAIL]);
            a.z[U] = a.hbridge.output(&p.hbridge, a.z[RAIL]);
        }
    }
}

/// The span a segment is propagated over: the communication step or the outer loop's period
/// where it is one of those up to `slack` (the rounding of the instants that bound it), else
/// its own. Segments of the same nominal length then share their propagators bit for bit:
/// the rounding of `k / f_sample` and of `t + step` makes sample periods differ in their
/// last bits, and each difference would need a matrix exponential of its own.
fn nominal_span(span: f64, nominal: [f64; 2], slack: f64) -> f64 {
    nominal.into_iter().find(|n| (span - n).abs() <= slack).unwrap_or(span)
}

/// The refusal of a step with more time events than [`MAX_TIME_EVENTS_PER_STEP`]. Cold and
/// out of line: the count is checked on every step.
#[cold]
#[inline(never)]
fn too_many_events(step: f64) -> String {
    format!(
        "a step of {} s holds more than {MAX_TIME_EVENTS_PER_STEP} PWM/sampling instants; use \
         shorter communication steps",
        crate::readable::readable(step)
    )
}
