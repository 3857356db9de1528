//! The exact integrator behind the seam ([`crate::integrators::seam`]): over a segment, driver,
//! coil and valve evolve exactly, mode by mode, their state events located on the way
//! ([`crate::numerics::mode_systems`]), and the cylinder follows along the exact spool path
//! ([`super::driven_cylinder`]).

use crate::actuator::{current_system, Actuator};
use crate::components::coefficients::Coefficients;
use crate::components::cylinder::CylinderParams;
use crate::components::driver;
use crate::components::driver::Mode;
use crate::components::hbridge::HBridgeState;
use crate::components::valve;
use crate::events::StepEvents;
use crate::events::Work;
use crate::held_inputs::HeldInputs;
use crate::integrators::exact::driven_cylinder::DrivenCylinder;
use crate::integrators::seam::{Integrator, Segment};
use crate::numerics::augmented_state;
use crate::numerics::augmented_state::Vector;
use crate::numerics::augmented_state::U;
use crate::numerics::mode_systems::locate_event;
use crate::numerics::mode_systems::may_cross;
use crate::numerics::mode_systems::GuardsAt;
use crate::numerics::mode_systems::ModeSystem;
use crate::numerics::mode_systems::Propagator;
use crate::numerics::mode_systems::PropagatorCache;
use crate::numerics::slew_end;
use crate::params::ControlMode;

/// A step that switches mode more often than this is chattering: refuse it.
const MAX_EVENTS_PER_STEP: u32 = 1000;

/// Pieces of spool path before a driver mode change that the cylinder takes together with
/// the piece after it are at most this long (s): see `evolve`.
const MERGE_SPAN: f64 = 1e-6;

/// The rest of a segment after a mode change inside it (at most this |lambda| per sub-step)
/// goes by Taylor series: a span that seldom comes again (it ends where the event fell) is
/// not worth a matrix exponential, which a short series costs a fraction of. Larger ones,
/// and whole nominal spans (they recur), keep their cached propagators.
const ONE_OFF_TAYLOR: f64 = 0.25;

/// The cylinder sees the spool through a quintic between the exact ends of each sub-step;
/// a sub-step spans at most this angle of the first stage's natural frequency (at the
/// default 814 Hz, 1.17e-4 s: a 1e-4 s step is one piece). Over longer pieces the quintic
/// strays from the exact spool path, and the cylinder follows the quintic.
const SPOOL_PATH_ANGLE: f64 = 0.6;

/// Sub-steps that keep each piece of spool path within [`SPOOL_PATH_ANGLE`] (`wn` in
/// rad/s); the propagators bound them (a huge step stays bounded in time, its pieces coarser).
fn spool_path_pieces(span: f64, wn: f64) -> usize {
    // The cast saturates: an overflowing count is bounded where it is used.
    augmented_state::ceil_count(span * wn / SPOOL_PATH_ANGLE).max(1)
}

/// The exact integrator's own state: caches derived from the actuator's mode systems,
/// none of them part of the instance state.
#[derive(Clone)]
pub(crate) struct ExactIntegrator {
    /// The mode pairs whose slew ends [`slew_end`] takes.
    slew_exits: slew_end::SlewExits,
    /// A state the propagator of (system, sub-step bits) maps onto itself bit for bit: the
    /// valve and driver have settled, so the product and the guard checks can be skipped
    /// with identical results (a pure cache).
    fixed_point: Option<(usize, u64, Vector)>,
    cache: PropagatorCache,
}

impl ExactIntegrator {
    pub(crate) fn new(actuator: &Actuator) -> ExactIntegrator {
        ExactIntegrator {
            slew_exits: slew_end::slew_exits(&actuator.systems),
            fixed_point: None,
            cache: PropagatorCache::new(),
        }
    }
}

impl Integrator for ExactIntegrator {
    /// Continuous evolution over the segment with state events (driver mode changes). Each
    /// mode runs until an event or the segment's end ([`ExactIntegrator::propagate_mode`]),
    /// then the mode after the event is chosen ([`ExactIntegrator::switch_mode`]).
    fn evolve(
        &mut self,
        actuator: &mut Actuator,
        segment: Segment,
        inputs: &HeldInputs,
        events: &mut StepEvents,
    ) -> Result<(), String> {
        let mut run = SegmentRun {
            z: actuator.z,
            done: 0.0,
            switches: 0,
            passed_guards: 0,
            merge: !valve::has_stops(&actuator.params),
            pending: None,
            segment_start: actuator.z,
            pulled_back: None,
        };
        while run.done < segment.span {
            match self.propagate_mode(actuator, &mut run, segment, inputs)? {
                Some(event) => self.switch_mode(actuator, &mut run, &event, events)?,
                None => break,
            }
        }
        if let Some((z0, d)) = run.pending {
            // The segment ended on an event.
            actuator.cylinder.drive(
                &actuator.systems[actuator.mode.index()],
                &actuator.params.cylinder,
                &mut actuator.work,
                (&z0, &run.z, d),
                inputs,
            )?;
        }
        actuator.z = run.z;
        Ok(())
    }

    /// Builds the current mode's propagators of whole segments (keyed by their exact span,
    /// as `evolve` takes them after a slew from a segment's start) over the communication
    /// step and the outer loop's period.
    fn prepare(&mut self, actuator: &Actuator, step: f64) {
        let key = actuator.system_key();
        let c = &actuator.params;
        let sys = current_system(c, &actuator.active, &actuator.systems, actuator.mode);
        let looping = c.loops.mode != ControlMode::Current;
        for span in [Some(step), looping.then(|| 1.0 / c.loops.f_sample)].into_iter().flatten() {
            // A span the cache cannot take is refused again, with its message, when stepped.
            let _ = self.cache.get(key, sys, span, true, 1);
        }
    }

    /// The probe's propagators (its fixed point and the rest are its own).
    fn adopt_prepared(&mut self, probe: ExactIntegrator) {
        self.cache = probe.cache;
    }

    /// The fixed point goes (it was found under the old coefficients); with new mode systems
    /// the propagators and slew exits go too.
    fn retuned(&mut self, actuator: &Actuator, systems_rebuilt: bool) {
        self.fixed_point = None;
        if systems_rebuilt {
            self.slew_exits = slew_end::slew_exits(&actuator.systems);
            self.cache.clear();
        }
    }

    fn count_work(&self, work: &mut Work) {
        work.exponentials += self.cache.exponentials;
    }
}

impl ExactIntegrator {
    /// Propagates the current mode from `run`'s state over the rest of the segment, sub-step
    /// by sub-step, the cylinder following along each piece of spool path; stops at the first
    /// event (returned, the cylinder driven up to it or its piece left pending).
    fn propagate_mode(
        &mut self,
        actuator: &mut Actuator,
        run: &mut SegmentRun,
        Segment { span: span_total, whole }: Segment,
        inputs: &HeldInputs,
    ) -> Result<Option<ModeEvent>, String> {
        let span = span_total - run.done;
        let sys =
            current_system(&actuator.params, &actuator.active, &actuator.systems, actuator.mode);
        // Between PWM edges by Taylor series, otherwise with a cached propagator; either
        // way no sub-step longer than a piece of spool path may be. A slew that ends
        // inside the first sub-step (a command step's: within a microsecond) is searched
        // at once, and the propagator of its span would never be applied (on a cache
        // miss, an exponential for nothing): Taylor series serve if it lasts after all,
        // on sub-steps they cover in one piece (others, and absurd parameters, go through
        // the propagator's checks).
        let key = actuator.system_key();
        let pieces = spool_path_pieces(span, actuator.params.wn);
        let first = span / pieces as f64;
        let brief_slew = first * sys.radius <= 1.0
            && driver::slew_time(&actuator.params, actuator.mode, &run.z)
                .is_some_and(|t| t < first);
        // The end of the rest of the segment in one sub-step, if it is pulled back.
        let mut whole_segment_end = None;
        if let Some(start) = run.pulled_back.take().filter(|_| pieces == 1) {
            let whole = self.cache.get(key, sys, span_total, true, 1)?;
            if whole.substeps == 1 && whole.has_matrix() {
                let mut end = whole.apply(sys, &start);
                driver::project_onto(&actuator.params, &actuator.hbridge, &mut end, actuator.mode);
                whole_segment_end = Some(end);
            }
        }
        let propagator = if whole_segment_end.is_some() {
            // One sub-step, never applied: `whole_segment_end` is its end.
            Propagator::taylor_only(sys, span, 1)
        } else if actuator.mode == Mode::Switched
            || brief_slew
            || (run.done > 0.0 && first * sys.radius <= ONE_OFF_TAYLOR)
        {
            Propagator::taylor_only(sys, span, pieces)
        } else {
            self.cache.get(key, sys, span, whole && run.done == 0.0, pieces)?
        };
        let mode_span = ModeSpan {
            sys,
            propagator,
            whole_segment_end,
            key,
            c: &actuator.params,
            hbridge: &actuator.hbridge,
            mode: actuator.mode,
        };
        let h = mode_span.propagator.h;
        for k in 0..mode_span.propagator.substeps {
            let end = substep(
                &mode_span,
                &run.z,
                run.passed_guards,
                &mut self.fixed_point,
                &mut actuator.work,
            );
            let cylinder = (&mut actuator.cylinder, &mut actuator.work, &actuator.params.cylinder);
            match end {
                SubstepEnd::Reached(next) => {
                    drive_piece(cylinder, sys, run, (&next, h), false, inputs)?;
                    run.z = next;
                }
                SubstepEnd::Event { tau, guard, at } => {
                    drive_piece(cylinder, sys, run, (&at, tau), run.merge, inputs)?;
                    return Ok(Some(ModeEvent { k, h, tau, guard, at }));
                }
            }
        }
        Ok(None)
    }

    /// Takes the segment onto the mode after `event`: settles the state there, pulls the new
    /// mode's start back to the segment's start after a slew from it ([`slew_end`]), counts
    /// the switch; refuses chattering.
    fn switch_mode(
        &self,
        actuator: &mut Actuator,
        run: &mut SegmentRun,
        event: &ModeEvent,
        events: &mut StepEvents,
    ) -> Result<(), String> {
        let from_segment_start = run.done == 0.0 && event.k == 0 && run.switches == 0;
        run.z = event.at;
        run.done += event.k as f64 * event.h + event.tau;
        let before = actuator.mode;
        let changed = actuator.settle(&mut run.z);
        if from_segment_start && run.merge {
            run.pulled_back =
                slew_end::exit(&self.slew_exits, before, actuator.mode).and_then(|exit| {
                    let to = &actuator.systems[actuator.mode.index()];
                    let mut start = slew_end::pulled_back(to, exit, &run.segment_start, event.tau)?;
                    // The new mode's projection at the switch (rounding).
                    start[U] += run.z[U] - event.at[U];
                    Some(start)
                });
        }
        driver::count_switch(events, before, actuator.mode);
        run.passed_guards = if changed { 0 } else { run.passed_guards | 1 << event.guard };
        run.switches += 1;
        if run.switches > MAX_EVENTS_PER_STEP {
            return Err(format!(
                "driver switched mode more than {MAX_EVENTS_PER_STEP} times in one step (chattering); step refused"
            ));
        }
        Ok(())
    }
}

/// How far the evolution of one segment has come ([`ExactIntegrator::evolve`]).
struct SegmentRun {
    /// The state reached.
    z: Vector,
    /// Time since the segment's start (s).
    done: f64,
    /// Driver mode switches so far.
    switches: u32,
    /// Guards that fired without changing the mode: passed, ignored for this segment.
    passed_guards: u8,
    /// A driver mode change leaves the spool's position, rate and acceleration continuous,
    /// so the cylinder may take the piece up to an event together with the piece after
    /// it: one Rosenbrock call instead of two. Only a short one (a command step's
    /// slewing): the jerk jumps at the event, which the merged piece's quintic cannot
    /// follow, so the longer the piece before it the further the quintic strays. Not with
    /// travel stops, whose impacts break the path.
    merge: bool,
    /// The piece the cylinder has yet to take: (start, duration).
    pending: Option<(Vector, f64)>,
    /// After a slew from the segment's start, the next mode's start pulled back to it
    /// ([`slew_end`]): its sub-step then ends where the whole segment's propagator takes it.
    segment_start: Vector,
    pulled_back: Option<Vector>,
}

/// A state event inside sub-step `k` (of `h`) of a mode: `tau` into it, guard `guard`
/// fired, the state there `at`.
struct ModeEvent {
    k: usize,
    h: f64,
    tau: f64,
    guard: usize,
    at: Vector,
}

/// A mode's propagation over the rest of a segment: its system and sub-step propagator.
struct ModeSpan<'a> {
    sys: &'a ModeSystem,
    propagator: Propagator<'a>,
    /// The end of the one sub-step, when the mode's start was pulled back ([`slew_end`]).
    whole_segment_end: Option<Vector>,
    /// The propagator cache's name for the (mode, stops) pair.
    key: usize,
    c: &'a Coefficients,
    hbridge: &'a HBridgeState,
    mode: Mode,
}

impl ModeSpan<'_> {
    /// One sub-step from `z`, put on the mode's manifold; `at_fixed_point`: the propagator
    /// maps `z` onto itself.
    #[inline]
    fn propagate(&self, z: &Vector, at_fixed_point: bool) -> Vector {
        if let Some(end) = self.whole_segment_end {
            return end;
        }
        let mut next = if self.propagator.has_matrix() && at_fixed_point {
            *z
        } else {
            self.propagator.apply(self.sys, z)
        };
        driver::project_onto(self.c, self.hbridge, &mut next, self.mode);
        next
    }
}

/// Where a sub-step ends: its end, or the first state event inside it.
enum SubstepEnd {
    Reached(Vector),
    Event { tau: f64, guard: usize, at: Vector },
}

/// One sub-step of `span`'s mode from `z`, with its state events located (`passed_guards`:
/// guards ignored). `fixed_point` is [`ExactIntegrator`]'s cache of a state its propagator maps
/// onto itself.
#[inline(always)]
fn substep(
    span: &ModeSpan,
    z: &Vector,
    passed_guards: u8,
    fixed_point: &mut Option<(usize, u64, Vector)>,
    work: &mut Work,
) -> SubstepEnd {
    let (sys, h) = (span.sys, span.propagator.h);
    let settled = (span.key, h.to_bits(), *z);
    let at_fixed_point = *fixed_point == Some(settled);
    // A guard whose slope already reaches zero inside the sub-step (a command step's
    // slewing ends within nanoseconds): search at once, without first propagating over a
    // sub-step that the event will cut. A state that its propagator maps onto itself
    // crosses nothing: no prediction needed.
    let mut guards = (!(at_fixed_point && span.propagator.has_matrix()))
        .then(|| GuardsAt::new(sys, z, passed_guards));
    let predicted = guards.as_ref().map_or(f64::INFINITY, |g| g.predicted_crossing());
    let imminent = predicted < h
        && (sys.closed_form_search(passed_guards)
            || guards.as_ref().is_some_and(|g| g.crossing_imminent(sys, z, h)));
    let next = (!imminent).then(|| span.propagate(z, at_fixed_point));
    let search = match next {
        None => true,
        // A stable system that returns to its state bit for bit is at rest: no guard can
        // have crossed on the way.
        Some(next) if next == *z => {
            if span.propagator.has_matrix() {
                *fixed_point = Some(settled);
            }
            false
        }
        Some(next) => {
            let guards = guards.get_or_insert_with(|| GuardsAt::new(sys, z, passed_guards));
            may_cross(sys, guards, &next, h)
        }
    };
    if search {
        work.guard_locations += 1;
        let guards = guards.get_or_insert_with(|| GuardsAt::new(sys, z, passed_guards));
        if let Some((tau, guard, at)) = locate_event(sys, z, h, guards, predicted) {
            return SubstepEnd::Event { tau, guard, at };
        }
    }
    SubstepEnd::Reached(next.unwrap_or_else(|| span.propagate(z, at_fixed_point)))
}

/// Drives the cylinder along the piece of spool path from `run`'s state to `end`
/// (`duration` s later), joined to the piece pending before it; `defer`: the piece ends
/// on an event, and if short it is left pending to go with the piece after the event.
fn drive_piece(
    (cylinder, work, c): (&mut DrivenCylinder, &mut Work, &CylinderParams),
    sys: &ModeSystem,
    run: &mut SegmentRun,
    (end, duration): (&Vector, f64),
    defer: bool,
    inputs: &HeldInputs,
) -> Result<(), String> {
    let (z0, d) = run.pending.take().map_or((run.z, duration), |(z0, d)| (z0, d + duration));
    if defer && d <= MERGE_SPAN {
        run.pending = Some((z0, d));
        Ok(())
    } else {
        cylinder.drive(sys, c, work, (&z0, end, d), inputs)
    }
}
