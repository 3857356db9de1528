//! Advancing [`Physics`] over one communication step: the time events of the digital
//! loops cut the step; between them driver, coil and valve evolve exactly (state events
//! located on the way) and the cylinder follows along the exact spool path.

use super::*;

/// Pieces of spool path before a driver mode change that the cylinder takes together with
/// the piece after it are at most this long (s): see `evolve`.
const MERGE_SPAN: f64 = 1e-6;

/// The rest of a segment after a mode change inside it (at most this |lambda| per sub-step)
/// goes by Taylor series: about 0.8k instructions, where an exponential costs 13k for a span
/// that seldom comes again (the first step of a gait: the rail after the first sample's
/// slew and the linear piece after it, 4.6e-5 and 3.9e-6 s). Larger ones, and whole nominal
/// spans (they recur), keep their cached propagators.
const ONE_OFF_TAYLOR: f64 = 0.25;

/// The cylinder sees the spool through a quintic between the exact ends of each sub-step;
/// a sub-step spans at most this angle of the first stage's natural frequency (at the
/// default 814 Hz, 1.17e-4 s: a 1e-4 s step is one piece). At 5.1 rad (one 1e-3 s step)
/// the quintic put the cylinder 2.4e-4 of Q_A's range off an independent integration.
const SPOOL_PATH_ANGLE: f64 = 0.6;

/// Sub-steps that keep each piece of spool path within [`SPOOL_PATH_ANGLE`] (`wn` in
/// rad/s); the propagators bound them (a huge step stays bounded in time, its pieces coarser).
fn spool_path_pieces(span: f64, wn: f64) -> usize {
    // The cast saturates: an overflowing count is bounded where it is used.
    state::ceil_count(span * wn / SPOOL_PATH_ANGLE).max(1)
}

/// The key of [`Physics`]'s `resting`: the inputs and the step size, as bits.
fn rest_key(i: &Inputs, step: f64) -> RestKey {
    [i.i_ref, i.v_supply, i.p_supply, i.f_ext, i.q_ref, i.x_ref, step].map(f64::to_bits)
}

impl Physics {
    /// Whether a step of `step` with `inputs` changes nothing: the last step had the same
    /// inputs and size, no clock runs, and it left the state as it was, bit for bit.
    pub(super) fn rests(&self, inputs: &Inputs, step: f64) -> bool {
        self.resting == Some(rest_key(inputs, step)) && self.clocks_idle()
    }

    /// No sampling or PWM clock will ever tick (the loops are continuous or absent).
    fn clocks_idle(&self) -> bool {
        self.digital.events_until(&self.params.hbridge, f64::INFINITY) == 0
            && self.outer.events_until(&self.params.loops, f64::INFINITY) == 0
    }

    /// Advances from `t_start` by `step` seconds with `inputs` held constant.
    /// On error the state is left as it was.
    pub(crate) fn advance(
        &mut self,
        inputs: &Inputs,
        t_start: f64,
        step: f64,
    ) -> Result<StepEvents, String> {
        let key = rest_key(inputs, step);
        let clocks_idle = self.clocks_idle();
        let saved =
            (self.z, self.mode, self.stops, self.digital, self.outer, self.cylinder, self.p_supply);
        // A piston through the end of the cylinder is a broken state, refused like any error.
        let result = self.advance_inner(inputs, t_start, step).and_then(|events| {
            cylinder::check_inside(&self.params.cylinder, &self.cylinder.state)?;
            Ok(events)
        });
        let bits = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
        let unchanged = bits(self.z.as_slice(), saved.0.as_slice())
            && (self.mode, self.stops) == (saved.1, saved.2)
            && bits(&self.cylinder.state.to_array(), &saved.5.state.to_array())
            && bits(&self.cylinder.memory.to_array(), &saved.5.memory.to_array())
            && self.p_supply.to_bits() == saved.6.to_bits();
        self.resting = (clocks_idle && result.is_ok() && unchanged).then_some(key);
        if result.is_err() {
            (
                self.z,
                self.mode,
                self.stops,
                self.digital,
                self.outer,
                self.cylinder,
                self.p_supply,
            ) = saved;
            self.active = self.systems[self.mode.index()].with_stops(&self.params, self.stops);
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
        let inputs = Held::new(&self.params, inputs);
        self.p_supply = inputs.p_supply;
        self.follow_command(&inputs, &mut events);
        let t_end = t_start + step;
        let p = self.params;
        let time_events =
            self.digital.events_until(&p.hbridge, t_end) + self.outer.events_until(&p.loops, t_end);
        if time_events > MAX_TIME_EVENTS_PER_STEP {
            return Err(format!(
                "a step of {step} s holds more than {MAX_TIME_EVENTS_PER_STEP} PWM/sampling instants; use shorter communication steps"
            ));
        }
        // Time events within a hair of the step end (rounding of t_start + step, either
        // side) belong to it and fire at its end: no segment of a few ulp after them (7 %
        // of the gait's segments were 1-2e-16 s long, each a full evolution).
        let period = 1.0 / p.loops.f_sample;
        let slack = 1e-9 * step.min(p.hbridge.period()).min(period);
        let mut t = t_start;
        loop {
            let t_bridge = self.digital.next_event(&p.hbridge);
            let t_loop = self.outer.next_event(&p.loops);
            let t_event = t_bridge.min(t_loop);
            let fire = t_event <= t_end + slack;
            let segment_end = if fire && t_event < t_end - slack { t_event } else { t_end };
            if segment_end > t {
                let whole = t == t_start && segment_end == t_end;
                let span = nominal_span(segment_end - t, [step, period], slack);
                self.evolve(span, whole, &inputs, &mut events)?;
                t = segment_end;
            }
            if !fire {
                break;
            }
            if t_loop <= t_bridge {
                // The outer loop samples first, so a bridge sample at the same instant sees its command.
                let measured = match p.loops.mode {
                    ControlMode::Flow => valve::no_load_flow(&p, self.z[XS]),
                    _ => self.cylinder.state.x,
                };
                self.outer.sample(&p.loops, inputs.reference, measured);
                self.follow_command(&inputs, &mut events);
            } else {
                self.digital.fire(&p.hbridge, self.z[I], self.z[IREF], p.r_total, self.z[VMAX]);
                self.z[U] = self.digital.output(self.z[VMAX]);
            }
        }
        if !self.z.iter().all(|x| x.is_finite()) {
            return Err("the state became non-finite; step refused".into());
        }
        Ok(events)
    }

    /// Takes a new current command or rail into the state. A state that ended the last step
    /// is consistent with its mode; only a new command or rail (or a restored state) needs
    /// the mode chosen again.
    fn follow_command(&mut self, inputs: &Held, events: &mut StepEvents) {
        let i_cmd = self.current_command(inputs);
        if self.z[IREF] != i_cmd || self.z[VMAX] != inputs.rail {
            let mut z = self.z;
            driver::apply_inputs(&self.params, &mut z, i_cmd, inputs.rail);
            let before = self.mode;
            self.settle(&mut z);
            driver::count_switch(events, before, self.mode);
            self.z = z;
        }
    }

    /// The propagator cache's name for the current (mode, stops) pair.
    fn propagator_key(&self) -> usize {
        self.mode.index() + MODES.len() * self.stops.code()
    }

    /// Builds the current mode's propagators of whole segments (keyed by their exact span,
    /// as `evolve` takes them after a slew from a segment's start) over the communication
    /// step and the outer loop's period.
    pub(super) fn build_whole_segment_propagators(&mut self, step: f64) {
        let key = self.propagator_key();
        let sys = current_system(&self.params, &self.active, &self.systems, self.mode);
        let looping = self.params.loops.mode != ControlMode::Current;
        for span in
            [Some(step), looping.then(|| 1.0 / self.params.loops.f_sample)].into_iter().flatten()
        {
            // A span the cache cannot take is refused again, with its message, when stepped.
            let _ = self.cache.get(key, sys, span, true, 1);
        }
    }

    /// Continuous evolution over `span_total` seconds with state events (driver mode
    /// changes); `whole`: the span is a whole communication step (no time event cut it).
    /// Each mode runs until an event or the segment's end ([`Physics::propagate_mode`]),
    /// then the mode after the event is chosen ([`Physics::switch_mode`]).
    fn evolve(
        &mut self,
        span_total: f64,
        whole: bool,
        inputs: &Held,
        events: &mut StepEvents,
    ) -> Result<(), String> {
        let mut run = SegmentRun {
            z: self.z,
            done: 0.0,
            switches: 0,
            passed: 0,
            merge: !valve::has_stops(&self.params),
            pending: None,
            segment_start: self.z,
            pulled_back: None,
        };
        while run.done < span_total {
            match self.propagate_mode(&mut run, span_total, whole, inputs)? {
                Some(event) => self.switch_mode(&mut run, &event, events)?,
                None => break,
            }
        }
        if let Some((z0, d)) = run.pending {
            // The segment ended on an event.
            self.cylinder.drive(
                &self.systems[self.mode.index()],
                &self.params.cylinder,
                &mut self.work,
                (&z0, &run.z, d),
                inputs,
            )?;
        }
        self.z = run.z;
        Ok(())
    }

    /// Propagates the current mode from `run`'s state over the rest of the segment, sub-step
    /// by sub-step, the cylinder following along each piece of spool path; stops at the first
    /// event (returned, the cylinder driven up to it or its piece left pending).
    fn propagate_mode(
        &mut self,
        run: &mut SegmentRun,
        span_total: f64,
        whole: bool,
        inputs: &Held,
    ) -> Result<Option<ModeEvent>, String> {
        let span = span_total - run.done;
        let sys = current_system(&self.params, &self.active, &self.systems, self.mode);
        // Between PWM edges by Taylor series, otherwise with a cached propagator; either
        // way no sub-step longer than a piece of spool path may be. A slew that ends
        // inside the first sub-step (a command step's: within a microsecond) is searched
        // at once, and the propagator of its span would never be applied (on a cache
        // miss, an exponential for nothing): Taylor series serve if it lasts after all,
        // on sub-steps they cover in one piece (others, and absurd parameters, go through
        // the propagator's checks).
        let key = self.propagator_key();
        let pieces = spool_path_pieces(span, self.params.wn);
        let first = span / pieces as f64;
        let brief_slew = first * sys.radius <= 1.0
            && driver::slew_time(&self.params, self.mode, &run.z).is_some_and(|t| t < first);
        // The end of the rest of the segment in one sub-step, if it is pulled back.
        let mut whole_segment_end = None;
        if let Some(start) = run.pulled_back.take().filter(|_| pieces == 1) {
            let whole = self.cache.get(key, sys, span_total, true, 1)?;
            if whole.substeps == 1 && whole.has_matrix() {
                let mut end = whole.apply(sys, &start);
                driver::project_onto(&self.params, &self.digital, &mut end, self.mode);
                whole_segment_end = Some(end);
            }
        }
        let propagator = if whole_segment_end.is_some() {
            // One sub-step, never applied: `whole_segment_end` is its end.
            Propagator::taylor_only(sys, span, 1)
        } else if self.mode == Mode::Switched
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
            c: &self.params,
            digital: &self.digital,
            mode: self.mode,
        };
        let h = mode_span.propagator.h;
        for k in 0..mode_span.propagator.substeps {
            let end =
                substep(&mode_span, &run.z, run.passed, &mut self.fixed_point, &mut self.work);
            let cylinder = (&mut self.cylinder, &mut self.work, &self.params.cylinder);
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
        &mut self,
        run: &mut SegmentRun,
        event: &ModeEvent,
        events: &mut StepEvents,
    ) -> Result<(), String> {
        let from_segment_start = run.done == 0.0 && event.k == 0 && run.switches == 0;
        run.z = event.at;
        run.done += event.k as f64 * event.h + event.tau;
        let before = self.mode;
        let changed = self.settle(&mut run.z);
        if from_segment_start && run.merge {
            run.pulled_back =
                slew_end::exit(&self.slew_exits, before, self.mode).and_then(|exit| {
                    let to = &self.systems[self.mode.index()];
                    let mut start = slew_end::pulled_back(to, exit, &run.segment_start, event.tau)?;
                    // The new mode's projection at the switch (rounding).
                    start[U] += run.z[U] - event.at[U];
                    Some(start)
                });
        }
        driver::count_switch(events, before, self.mode);
        run.passed = if changed { 0 } else { run.passed | 1 << event.guard };
        run.switches += 1;
        if run.switches > MAX_EVENTS_PER_STEP {
            return Err(format!(
                "driver switched mode more than {MAX_EVENTS_PER_STEP} times in one step (chattering); step refused"
            ));
        }
        Ok(())
    }
}

/// How far the evolution of one segment has come ([`Physics::evolve`]).
struct SegmentRun {
    /// The state reached.
    z: Vector,
    /// Time since the segment's start (s).
    done: f64,
    /// Driver mode switches so far.
    switches: u32,
    /// Guards that fired without changing the mode: passed, ignored for this segment.
    passed: u8,
    /// A driver mode change leaves the spool's position, rate and acceleration continuous,
    /// so the cylinder may take the piece up to an event together with the piece after
    /// it: one Rosenbrock call instead of two. Only a short one (a command step's
    /// slewing): the jerk jumps at the event, which the merged piece's quintic cannot
    /// follow (merging every piece put square_20Hz 3.2e-6 of Q_A's range off an
    /// independent integration at 1e-3 s steps, 1.8e-7 this way). Not with travel
    /// stops, whose impacts break the path.
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
    digital: &'a Digital,
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
        driver::project_onto(self.c, self.digital, &mut next, self.mode);
        next
    }
}

/// Where a sub-step ends: its end, or the first state event inside it.
enum SubstepEnd {
    Reached(Vector),
    Event { tau: f64, guard: usize, at: Vector },
}

/// One sub-step of `span`'s mode from `z`, with its state events located (`passed`:
/// guards ignored). `fixed_point` is [`Physics`]'s cache of a state its propagator maps
/// onto itself.
#[inline]
fn substep(
    span: &ModeSpan,
    z: &Vector,
    passed: u8,
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
    let mut guards =
        (!(at_fixed_point && span.propagator.has_matrix())).then(|| GuardsAt::new(sys, z, passed));
    let predicted = guards.as_ref().map_or(f64::INFINITY, |g| g.predicted_crossing());
    let imminent = predicted < h
        && (sys.closed_form_search(passed)
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
            let guards = guards.get_or_insert_with(|| GuardsAt::new(sys, z, passed));
            may_cross(sys, guards, &next, h)
        }
    };
    if search {
        work.guard_locations += 1;
        let guards = guards.get_or_insert_with(|| GuardsAt::new(sys, z, passed));
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
    inputs: &Held,
) -> Result<(), String> {
    let (z0, d) = run.pending.take().map_or((run.z, duration), |(z0, d)| (z0, d + duration));
    if defer && d <= MERGE_SPAN {
        run.pending = Some((z0, d));
        Ok(())
    } else {
        cylinder.drive(sys, c, work, (&z0, end, d), inputs)
    }
}

/// The system `mode` runs on: its own without travel stops, else the one with the stops
/// that hold now ([`Physics::settle`] keeps it as `active`). Over the fields, so that the
/// caller may still borrow the cache and the cylinder.
fn current_system<'a>(
    params: &Coefficients,
    active: &'a ModeSystem,
    systems: &'a [ModeSystem; MODES.len()],
    mode: Mode,
) -> &'a ModeSystem {
    if valve::has_stops(params) {
        active
    } else {
        &systems[mode.index()]
    }
}

/// The span a segment is propagated over: the communication step or the outer loop's period
/// where it is one of those up to `slack` (the rounding of the instants that bound it), else
/// its own. Segments of the same nominal length then share their propagators bit for bit:
/// the rounding of `k / f_sample` and of `t + step` made the gait's sample periods differ in
/// their last bits, each difference a matrix exponential of its own.
fn nominal_span(span: f64, nominal: [f64; 2], slack: f64) -> f64 {
    nominal.into_iter().find(|n| (span - n).abs() <= slack).unwrap_or(span)
}
