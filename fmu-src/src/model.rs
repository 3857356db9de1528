//! The actuator as a model instance: values by value reference, initialise, step, reset,
//! and a self-checking byte form of the whole state; it fills in the FMI layer's
//! [`ModelContract`].
//!
//! The value array (indexed by value reference) is turned into the physics' typed
//! parameters and inputs, and its outputs written back, by the bindings the variable table
//! generates ([`crate::variables::params`], [`crate::variables::inputs`],
//! [`crate::variables::write_outputs`]). The physics never sees a value reference or a
//! variable name.

use std::cell::RefCell;

use crate::units::readable;

use crate::contract::{communication_point_tolerance, ModelContract};
use crate::physics::bytes::{frame, unframe, ByteReader};
use crate::physics::{
    ControlMode, CylinderLoadParams, DriverKind, Inputs, Params, Physics, StepEvents, Work,
    RATE_PROBE,
};
use crate::variables::{
    inputs, params, start_values, vr, write_calculated, write_outputs, Causality, Coded,
    Variability, Variable, N_VARIABLES, SET_RULES, VARIABLES,
};

/// The communication step of the default experiment (modelDescription.xml), for which
/// initialisation builds the first step's propagators ahead.
pub const DEFAULT_STEP_SIZE: f64 = 1e-4;

#[derive(Clone)]
pub struct Model {
    time: f64,
    initialized: bool,
    /// Values and physics; in a cell because outputs read before initialisation are built
    /// lazily, on the first read after a change (a read is `&self`).
    state: RefCell<State>,
}

#[derive(Clone)]
struct State {
    /// Parameters and inputs as set by the importer, outputs as last computed; by value reference.
    values: [f64; N_VARIABLES],
    physics: Physics,
    /// The host's input derivative of v_rod (m/s2), held until it sets another (0: none).
    rod_acceleration: f64,
    /// Before initialisation: parameters, inputs or the start time changed since `physics`
    /// and the outputs were built.
    stale: bool,
    /// The outputs that evaluate the cylinder's laws ([`LAW_OUTPUTS`]: the port flows and the
    /// rod's slopes) are not yet written since the last step: they are computed when first
    /// read (a host reads a few outputs each step, most of them read off the state).
    laws_due: bool,
}

/// The outputs that [`Physics::state_outputs`] leaves out: the port flows and the rod's
/// slopes, which evaluate the cylinder's laws.
const LAW_OUTPUTS: [usize; 5] = [vr::Q_A, vr::Q_B, vr::Q_SUPPLY, vr::DF_ROD_DX, vr::DF_ROD_DV];

/// Where [`Model::reader`] finds a variable's value.
#[derive(Clone, Copy)]
enum ReadFrom {
    /// The value array.
    Values,
    /// The model time ([`vr::TIME`]).
    Time,
    /// The value array, once the laws' outputs are written ([`LAW_OUTPUTS`]).
    Laws,
}

/// [`ReadFrom`] of every variable, by value reference: one look-up per read.
static READ_FROM: [ReadFrom; N_VARIABLES] = {
    let mut table = [ReadFrom::Values; N_VARIABLES];
    table[vr::TIME] = ReadFrom::Time;
    let mut k = 0;
    while k < LAW_OUTPUTS.len() {
        table[LAW_OUTPUTS[k]] = ReadFrom::Laws;
        k += 1;
    }
    table
};

impl State {
    /// The inputs in force: the value array's and the input derivative.
    fn inputs(&self) -> Inputs {
        Inputs { a_rod: self.rod_acceleration, ..inputs(&self.values) }
    }

    /// A law output ([`LAW_OUTPUTS`]), written first if the last step left it unwritten.
    /// Out of line: evaluating the laws would weigh on every read.
    #[inline(never)]
    fn law_output(&mut self, index: usize) -> f64 {
        self.write_laws_if_due();
        self.values[index]
    }

    /// Writes the outputs the last step left unwritten (the laws' outputs, [`LAW_OUTPUTS`]).
    fn write_laws_if_due(&mut self) {
        if self.laws_due {
            self.write_outputs();
        }
    }
}

impl Default for Model {
    fn default() -> Self {
        Self::new()
    }
}

impl Model {
    pub fn new() -> Self {
        let values = start_values();
        let physics = Physics::start(&start_params(), &inputs(&values), 0.0)
            .expect("the start values are valid");
        let mut state =
            State { values, physics, rod_acceleration: 0.0, stale: false, laws_due: false };
        state.write_outputs();
        state.write_valve_figures();
        Model { time: 0.0, initialized: false, state: RefCell::new(state) }
    }

    /// Back to start values (FMI Reset).
    pub fn reset(&mut self) {
        *self = Model::new();
    }

    pub fn time(&self) -> f64 {
        self.time
    }

    pub fn is_initialized(&self) -> bool {
        self.initialized
    }

    /// Value by value reference (index into the variable table); `None` for an unknown reference.
    pub fn get(&self, index: usize) -> Option<f64> {
        VARIABLES.get(index)?;
        Some(self.reader()(index))
    }

    /// Reads values by value reference (known ones: the index must be in the table); before
    /// initialisation the outputs are brought up to date first, after a step the laws'
    /// outputs when one of them is first read.
    pub fn reader(&self) -> impl Fn(usize) -> f64 + '_ {
        if !self.initialized {
            self.refresh_before_start();
        }
        let time = self.time;
        move |index| match READ_FROM[index] {
            ReadFrom::Values => self.state.borrow().values[index],
            ReadFrom::Time => time,
            ReadFrom::Laws => self.read_law_output(index),
        }
    }

    /// [`Model::reader`] of a model held exclusively (the FMI layer's): the reads take no
    /// borrow of the state's cell.
    pub fn reader_mut(&mut self) -> impl FnMut(usize) -> f64 + '_ {
        if !self.initialized {
            self.refresh_before_start();
        }
        let time = self.time;
        let state = self.state.get_mut();
        move |index| match READ_FROM[index] {
            ReadFrom::Values => state.values[index],
            ReadFrom::Time => time,
            ReadFrom::Laws => state.law_output(index),
        }
    }

    /// A law output ([`LAW_OUTPUTS`]), written first if the last step left it unwritten.
    fn read_law_output(&self, index: usize) -> f64 {
        self.state.borrow_mut().law_output(index)
    }

    /// Stores a parameter or input after checking type and range; see [`Model::set_all`].
    pub fn set(&mut self, index: usize, value: f64) -> Result<(), String> {
        self.set_all([(index, value)])
    }

    /// Stores parameters and inputs `(value reference, value)`, all or nothing: each value
    /// is checked against its type and range; once initialised, a fixed parameter is
    /// refused, x_ref must lie within the stroke, and new values of tunable parameters
    /// rebuild the physics here (not in doStep) from the state reached, so they take
    /// effect at the next communication point (the outputs stay those of the last one).
    /// Which variables may be set in which FMI state is otherwise the FMI layer's business.
    pub fn set_all<I>(&mut self, changes: I) -> Result<(), String>
    where
        I: IntoIterator<Item = (usize, f64)>,
        I::IntoIter: Clone,
    {
        let initialized = self.initialized;
        let state = self.state.get_mut();
        let changes = changes.into_iter();
        let may_be_set = &MAY_BE_SET[initialized as usize];
        // Everything that can refuse a value alone is checked before anything is written.
        let (mut retune, mut changed) = (false, false);
        let (mut moved_ref, mut moved_rod) = (false, false);
        for (index, value) in changes.clone() {
            if !may_be_set.get(index).is_some_and(|&may| may) {
                return Err(not_settable(index));
            }
            // A value the model holds already was accepted when it was set (or is a start
            // value): only who may set what is checked again (importers resend unchanged
            // inputs at every step).
            if state.values[index].to_bits() == value.to_bits() {
                continue;
            }
            let rule = &SET_RULES[index];
            if !rule.surely_accepts(value) {
                VARIABLES[index].check(value)?;
            }
            changed = true;
            retune |= rule.parameter;
            moved_ref |= index == vr::X_REF;
            moved_rod |= index == vr::X_ROD;
        }
        if !changed {
            // Every value is the one held: nothing to write, no output to rebuild.
            return Ok(());
        }
        // The geometry is fixed once initialised: a position held fitted it when set.
        if initialized && moved_ref {
            check_x_ref_fits(last_value(changes.clone(), vr::X_REF), &state.values)?;
        }
        if initialized && moved_rod {
            check_x_rod_fits(last_value(changes.clone(), vr::X_ROD), &state.values)?;
        }
        if initialized && retune {
            return state.retune(&mut changes.into_iter(), self.time);
        }
        for (index, value) in changes {
            state.values[index] = value;
        }
        state.stale |= !initialized;
        Ok(())
    }

    /// Sets the start time (FMI SetupExperiment / EnterInitializationMode).
    pub fn set_start_time(&mut self, start_time: f64) -> Result<(), String> {
        if !start_time.is_finite() {
            return Err(format!("start time {start_time} is not finite"));
        }
        self.time = start_time;
        if !self.initialized {
            self.state.get_mut().stale = true;
        }
        Ok(())
    }

    /// Before initialisation ends the outputs are those of the initial equilibrium for
    /// the current parameters and inputs, so importers can read initial unknowns. They are
    /// built once, when first read after a change, not on every set; parameters that do
    /// not fit together leave the last consistent outputs in place.
    fn refresh_before_start(&self) {
        let mut state = self.state.borrow_mut();
        if !state.stale {
            return;
        }
        state.stale = false;
        let built =
            params(&state.values).and_then(|p| Physics::start(&p, &state.inputs(), self.time));
        if let Ok(physics) = built {
            state.physics = physics;
            state.write_outputs();
            state.write_valve_figures();
        }
    }

    /// Ends initialisation: checks the parameters together, builds the integrator, puts the
    /// model in equilibrium for the current inputs.
    pub fn initialize(&mut self) -> Result<(), String> {
        let state = self.state.get_mut();
        let p = params(&state.values)?;
        check_inputs_fit(&state.values)?;
        let inputs = state.inputs();
        state.physics = Physics::start(&p, &inputs, self.time)?;
        state.physics.prepare_first_step(&inputs, self.time, DEFAULT_STEP_SIZE);
        state.write_outputs();
        state.write_valve_figures();
        state.stale = false;
        self.initialized = true;
        Ok(())
    }

    /// Advances by `step` seconds from the current time. On error the instance keeps its
    /// state from before the call.
    pub fn do_step(&mut self, current_time: f64, step: f64) -> Result<StepEvents, String> {
        self.check_step(current_time, step)?;
        self.do_checked_step(current_time, step)
    }

    /// [`Model::do_step`] after [`Model::check_step`] has passed: for the FMI layer, which
    /// checks first to tell a refused step (nothing changes) from a failed one.
    #[inline(always)]
    pub(crate) fn do_checked_step(
        &mut self,
        current_time: f64,
        step: f64,
    ) -> Result<StepEvents, String> {
        let state = self.state.get_mut();
        // A step that changes nothing keeps the outputs written after the last one.
        let events = match state.physics.step(&state.inputs(), self.time, step)? {
            Some(events) => {
                state.write_state_outputs();
                events
            }
            None => StepEvents::default(),
        };
        self.time = current_time + step;
        Ok(events)
    }

    /// Sets the `order`-th time derivative of input `index` for the steps that follow (FMI 2
    /// `canInterpolateInputs`, order 1): that of v_rod is the rod's acceleration over the
    /// step; the other inputs are held over the step, so their derivatives are checked and
    /// not used.
    pub fn set_input_derivative(
        &mut self,
        index: usize,
        order: i32,
        value: f64,
    ) -> Result<(), String> {
        let var = VARIABLES.get(index).ok_or_else(|| format!("unknown value reference {index}"))?;
        if var.causality != Causality::Input {
            return Err(format!("{} is not an input: it has no input derivative", var.name));
        }
        if order != 1 {
            return Err(format!(
                "order {order} for {}: input derivatives of order 1 are supported",
                var.name
            ));
        }
        check_input_derivative(index, value)?;
        if index == vr::V_ROD {
            self.state.get_mut().rod_acceleration = value;
        }
        Ok(())
    }

    /// The `order`-th time derivative of output `index` at the current communication point
    /// (order 1: the rate of the instantaneous value; for F_rod, of the force at the
    /// step's end).
    pub fn output_derivative(&self, index: usize, order: i32) -> Result<f64, String> {
        let var = VARIABLES.get(index).ok_or_else(|| format!("unknown value reference {index}"))?;
        if var.causality != Causality::Output || var.ty != crate::variables::VarType::Real {
            return Err(format!("{} is not a real output: it has no output derivative", var.name));
        }
        if order != 1 {
            return Err(format!(
                "order {order} for {}: output derivatives of order 1 are provided \
                 (maxOutputDerivativeOrder = 1)",
                var.name
            ));
        }
        if !self.initialized {
            self.refresh_before_start();
        }
        // A central difference along the state's exact rates: second order in the probe's
        // span, which is short against every time constant.
        let state = self.state.borrow();
        let (mut ahead, mut behind) = ([0.0; N_VARIABLES], [0.0; N_VARIABLES]);
        let inputs = state.inputs();
        write_outputs(&state.physics.outputs_along(&inputs, RATE_PROBE), &mut ahead);
        write_outputs(&state.physics.outputs_along(&inputs, -RATE_PROBE), &mut behind);
        Ok((ahead[index] - behind[index]) / (2.0 * RATE_PROBE))
    }

    /// Cumulative work counters of the integrators (for benchmarks; not part of the state).
    pub fn work(&self) -> Work {
        self.state.borrow().physics.work()
    }

    /// Refuses, without touching the model, a step no importer should ask for: before
    /// initialisation, a step size that is not positive and finite, a communication point
    /// away from the FMU time, a step too small to advance it. An error of
    /// [`Model::do_step`] after this passed is a failure of the computation.
    pub fn check_step(&self, current_time: f64, step: f64) -> Result<(), String> {
        match self.step_fault(current_time, step) {
            None => Ok(()),
            Some(fault) => Err(self.step_refusal(current_time, step, fault)),
        }
    }

    /// What is wrong with a step, if anything: the rules of [`Model::check_step`], in the
    /// order its messages take them.
    #[inline]
    fn step_fault(&self, current_time: f64, step: f64) -> Option<StepFault> {
        if !self.initialized {
            return Some(StepFault::BeforeInitialisation);
        }
        // Positive and finite in two compares (NaN fails both).
        if !(step > 0.0 && step <= f64::MAX) {
            return Some(StepFault::StepSize);
        }
        if !current_time.is_finite() {
            return Some(StepFault::TimeNotFinite);
        }
        // The tolerance is at least a millionth of the step: only a point further off than
        // that needs the rest of it worked out.
        let off = (current_time - self.time).abs();
        if off > 1e-6 * step {
            let tolerance = communication_point_tolerance(self.time, step);
            if off > tolerance {
                return Some(StepFault::OffTime { tolerance });
            }
        }
        (current_time + step <= self.time).then_some(StepFault::NoAdvance)
    }

    /// The message for a step [`Model::step_fault`] refuses. Out of line: the formatting
    /// would weigh on every step.
    #[cold]
    #[inline(never)]
    fn step_refusal(&self, current_time: f64, step: f64, fault: StepFault) -> String {
        match fault {
            StepFault::BeforeInitialisation => "doStep before initialisation ended".into(),
            StepFault::StepSize => {
                format!(
                    "communication step size {} is not a positive finite number",
                    readable(step)
                )
            }
            StepFault::TimeNotFinite => {
                format!("currentCommunicationPoint {current_time} is not finite")
            }
            StepFault::OffTime { tolerance } => format!(
                "currentCommunicationPoint {current_time} does not match the FMU time {} \
                 (tolerance {tolerance:e} s)",
                self.time
            ),
            StepFault::NoAdvance => format!(
                "a step of {step} s from {current_time} does not advance the FMU time {}",
                self.time
            ),
        }
    }

    /// Versioned, self-checking byte form of the whole instance (no pointers).
    pub fn to_bytes(&self) -> Vec<u8> {
        self.refresh_before_start();
        self.state.borrow_mut().write_laws_if_due();
        let state = self.state.borrow();
        let mut body = Vec::with_capacity(16 + 8 * (N_VARIABLES + 16));
        body.extend_from_slice(&(N_VARIABLES as u32).to_le_bytes());
        body.push(self.initialized as u8);
        body.extend_from_slice(&self.time.to_le_bytes());
        body.extend_from_slice(&state.rod_acceleration.to_le_bytes());
        for v in &state.values {
            body.extend_from_slice(&v.to_le_bytes());
        }
        state.physics.write_bytes(&mut body);
        frame(MAGIC, &body)
    }

    /// Inverse of [`Model::to_bytes`]; refuses truncated, corrupted or foreign bytes.
    pub fn from_bytes(bytes: &[u8]) -> Result<Model, String> {
        let body = unframe(MAGIC, bytes)?;
        let mut r = ByteReader::new(body);
        let n = r.u32()? as usize;
        if n != N_VARIABLES {
            return Err(format!("state has {n} variables, this FMU has {N_VARIABLES}"));
        }
        let initialized = r.u8()? != 0;
        let time = r.f64()?;
        let rod_acceleration = r.f64()?;
        check_input_derivative(vr::V_ROD, rod_acceleration)
            .map_err(|e| format!("state holds an invalid input derivative: {e}"))?;
        let mut values = [0.0; N_VARIABLES];
        for v in values.iter_mut() {
            *v = r.f64()?;
        }
        check_all(&values).map_err(|e| format!("state holds invalid values: {e}"))?;
        let p = params(&values)?;
        if initialized {
            check_inputs_fit(&values).map_err(|e| format!("state holds invalid inputs: {e}"))?;
        }
        let inputs = Inputs { a_rod: rod_acceleration, ..inputs(&values) };
        let physics = Physics::read_bytes(&p, &inputs, &mut r)?;
        if !r.is_at_end() {
            return Err("state has trailing bytes".into());
        }
        let state = State { values, physics, rod_acceleration, stale: false, laws_due: false };
        Ok(Model { time, initialized, state: RefCell::new(state) })
    }
}

/// [`Variable::may_be_set`] of every variable, by value reference, before (row 0) and after
/// (row 1) initialisation: a setter's check of a reference is one byte.
static MAY_BE_SET: [[bool; N_VARIABLES]; 2] = {
    let mut table = [[false; N_VARIABLES]; 2];
    let mut i = 0;
    while i < N_VARIABLES {
        table[0][i] = VARIABLES[i].may_be_set(false);
        table[1][i] = VARIABLES[i].may_be_set(true);
        i += 1;
    }
    table
};

/// The value that `changes` leave variable `index` with: the last one given for it (the
/// caller knows there is one).
fn last_value(changes: impl Iterator<Item = (usize, f64)>, index: usize) -> f64 {
    changes.filter(|&(i, _)| i == index).last().expect("the variable is among the changes").1
}

/// Why [`Model::set_all`] refuses to set `index` (a message is only built for a refusal).
#[cold]
#[inline(never)]
fn not_settable(index: usize) -> String {
    let Some(var) = VARIABLES.get(index) else {
        return format!("unknown value reference {index}");
    };
    match (var.causality, var.variability) {
        (Causality::Parameter, Variability::Fixed) => format!(
            "{} is a fixed parameter: it can only be set before initialisation ends",
            var.name
        ),
        (causality, _) => format!("{} is {causality:?}: it cannot be set", var.name),
    }
}

/// The rules between inputs and parameters that the table's ranges cannot express:
/// The largest rod acceleration a host may prescribe (m/s2): far beyond any servo
/// cylinder (10 m/s reached in 0.1 ms).
const MAX_ROD_ACCELERATION: f64 = 1e5;

/// An input derivative must be finite, and the rod's acceleration physically sized.
fn check_input_derivative(index: usize, value: f64) -> Result<(), String> {
    let bound = if index == vr::V_ROD { MAX_ROD_ACCELERATION } else { f64::INFINITY };
    if !value.is_finite() || value.abs() > bound {
        return Err(format!(
            "the derivative of {} = {} rejected: allowed range is [-{bound}, {bound}] per second",
            VARIABLES[index].name,
            readable(value),
            bound = readable(bound)
        ));
    }
    Ok(())
}

/// x_ref within the stroke and x_rod within the rod's travel (the table bounds them by the
/// longest stroke allowed).
fn check_inputs_fit(v: &[f64; N_VARIABLES]) -> Result<(), String> {
    check_x_ref_fits(v[vr::X_REF], v)?;
    check_x_rod_fits(v[vr::X_ROD], v)
}

/// x_ref within +-stroke/2 for the geometry in `v`.
fn check_x_ref_fits(x_ref: f64, v: &[f64; N_VARIABLES]) -> Result<(), String> {
    let half = 0.5 * v[vr::CYLINDER_STROKE];
    if x_ref.abs() > half {
        return Err(position_refusal("x_ref", x_ref, (-half, half), "+-cylinder.stroke/2"));
    }
    Ok(())
}

/// The refusal of a position input outside its travel `(lo, hi)`. Out of line and cold:
/// the checks run whenever the position is set, the formatting only when one fails.
#[cold]
#[inline(never)]
fn position_refusal(name: &str, value: f64, (lo, hi): (f64, f64), why: &str) -> String {
    format!(
        "{name} = {} rejected: allowed range is [{}, {}] ({why})",
        readable(value),
        readable(lo),
        readable(hi)
    )
}

/// x_rod within the stroke and the end stops' deepest penetration,
/// [`CylinderLoadParams::rod_travel`], for the geometry in `v`.
fn check_x_rod_fits(x_rod: f64, v: &[f64; N_VARIABLES]) -> Result<(), String> {
    let geometry = CylinderLoadParams {
        bore: v[vr::CYLINDER_BORE],
        rod: v[vr::CYLINDER_ROD],
        stroke: v[vr::CYLINDER_STROKE],
        v_dead: v[vr::CYLINDER_V_DEAD],
        ..Params::PAPER.cylinder
    };
    let (lo, hi) = geometry.rod_travel();
    if !(lo..=hi).contains(&x_rod) {
        let why = "the stroke and, beyond each end, the end stop's deepest penetration before \
                   the chamber's dead volume is used up";
        return Err(position_refusal("x_rod", x_rod, (lo, hi), why));
    }
    Ok(())
}

/// Input conditions that are legal but rarely meant: the FMI layer reports each with a
/// warning when it begins (not on every step while it lasts).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputWarning {
    /// i_ref above the valve's rated current while it is the command.
    CurrentAboveRating,
    /// V_supply at 0 while a command asks for motion (the driver cannot drive the coil).
    NoDriverSupply,
    /// p_supply at 0 while a command asks for motion (the piston cannot move).
    NoHydraulicSupply,
}

impl InputWarning {
    pub const ALL: [InputWarning; 3] = [
        InputWarning::CurrentAboveRating,
        InputWarning::NoDriverSupply,
        InputWarning::NoHydraulicSupply,
    ];
}

/// A position command this close to the piston asks for no motion (m): the position loop
/// holds the piston within 0.3 um.
const POSITION_AT_REST: f64 = 1e-6;

impl Model {
    /// Which conditions of [`InputWarning::ALL`] hold for the inputs in force (cheap, no
    /// allocation, one look at the state for all). Every step asks: the modes are decoded
    /// only where a value test holds (few steps).
    #[inline]
    pub fn input_warnings(&self) -> [bool; InputWarning::ALL.len()] {
        let v = &self.state.borrow().values;
        let suspects = WarningSuspects::of(v);
        if !suspects.any() {
            return [false; InputWarning::ALL.len()];
        }
        suspects.confirmed(v)
    }

    /// The log line for `warning`, naming the inputs.
    pub fn input_warning_text(&self, warning: InputWarning) -> String {
        let v = &self.state.borrow().values;
        let unconnected = |input: &str, unit: &str, what: &str| {
            format!(
                "{input} = 0 {unit} while {} asks for motion: {what} (is the {input} input \
                 unconnected? an importer may feed 0 to an unconnected input)",
                command_text(v)
            )
        };
        match warning {
            InputWarning::CurrentAboveRating => format!(
                "i_ref = {} A is above the valve's rated current {} A: the linear valve model \
                 is extrapolated (the command is in A: 5 mA is 0.005)",
                readable(v[vr::I_REF]),
                readable(v[vr::VALVE_I_RATED])
            ),
            InputWarning::NoDriverSupply => {
                unconnected("V_supply", "V", "the driver has no supply and cannot drive the coil")
            }
            InputWarning::NoHydraulicSupply => unconnected(
                "p_supply",
                "Pa",
                "the valve has no supply pressure and the piston cannot be driven",
            ),
        }
    }
}

/// The value tests of [`Model::input_warnings`], before the modes are decoded.
struct WarningSuspects {
    current_above_rating: bool,
    no_driver_supply: bool,
    no_hydraulic_supply: bool,
}

impl WarningSuspects {
    /// The value tests at the values `v`.
    #[inline]
    fn of(v: &[f64; N_VARIABLES]) -> WarningSuspects {
        WarningSuspects {
            // valve.i_rated: a datasheet valve's, and in gains form the Moog 30's (a figure
            // that form does not read stays at its start value, initialisation checks it).
            current_above_rating: v[vr::I_REF].abs() > v[vr::VALVE_I_RATED],
            no_driver_supply: v[vr::V_SUPPLY] == 0.0,
            no_hydraulic_supply: v[vr::P_SUPPLY] == 0.0,
        }
    }

    /// Whether a value test holds.
    #[inline]
    fn any(&self) -> bool {
        self.current_above_rating || self.no_driver_supply || self.no_hydraulic_supply
    }

    /// Which conditions hold, now that a value test held. Out of line: the common step
    /// has no suspect and stops at the tests.
    #[inline(never)]
    fn confirmed(&self, v: &[f64; N_VARIABLES]) -> [bool; InputWarning::ALL.len()] {
        let mode = control_mode(v);
        let moving = asks_for_motion(mode, v);
        // The ideal current driver has no supply to miss.
        let ideal = matches!(DriverKind::from_code(v[vr::DRIVER]), Ok(DriverKind::IdealCurrent));
        InputWarning::ALL.map(|warning| match warning {
            InputWarning::CurrentAboveRating => {
                self.current_above_rating && mode == ControlMode::Current
            }
            InputWarning::NoDriverSupply => self.no_driver_supply && !ideal && moving,
            InputWarning::NoHydraulicSupply => self.no_hydraulic_supply && moving,
        })
    }
}

/// Does the command of the active control mode ask the actuator to move?
fn asks_for_motion(mode: ControlMode, v: &[f64; N_VARIABLES]) -> bool {
    match mode {
        ControlMode::Current => v[vr::I_REF] != 0.0,
        ControlMode::Flow => v[vr::Q_REF] != 0.0,
        ControlMode::Position => (v[vr::X_REF] - v[vr::X_PISTON]).abs() > POSITION_AT_REST,
    }
}

fn command_text(v: &[f64; N_VARIABLES]) -> String {
    match control_mode(v) {
        ControlMode::Current => format!("i_ref = {} A", readable(v[vr::I_REF])),
        ControlMode::Flow => format!("Q_ref = {} m3/s", readable(v[vr::Q_REF])),
        ControlMode::Position => format!(
            "x_ref = {} m (x_piston = {} m)",
            readable(v[vr::X_REF]),
            readable(v[vr::X_PISTON])
        ),
    }
}

/// The control mode in the value array (checked when set, so always one of the three).
fn control_mode(v: &[f64; N_VARIABLES]) -> ControlMode {
    ControlMode::from_code(v[vr::CONTROL_MODE]).unwrap_or(ControlMode::Current)
}

impl State {
    /// Applies `changes` that include new tunable parameters and rebuilds the physics from
    /// the state reached; a retune checks the parameters together and may still refuse,
    /// and then the old values stay. Out of line: the rebuild's temporaries take tens of
    /// kilobytes of stack, which every setter would otherwise reserve and probe on each
    /// call, inputs included.
    #[cold]
    #[inline(never)]
    fn retune(
        &mut self,
        changes: &mut dyn Iterator<Item = (usize, f64)>,
        time: f64,
    ) -> Result<(), String> {
        // The outputs stay those of the last communication point: written before the
        // coefficients they would be computed with change.
        self.write_laws_if_due();
        let before = self.values;
        for (index, value) in changes {
            self.values[index] = value;
        }
        let rebuilt =
            params(&self.values).and_then(|p| self.physics.retune(&p, &self.inputs(), time));
        if let Err(e) = rebuilt {
            self.values = before;
            return Err(e);
        }
        Ok(())
    }

    /// Writes the outputs read off the state after a step that moved; the laws' outputs,
    /// written as 0 here, are computed when read. Out of line: a resting step skips it,
    /// and inlined it would weigh on every step's frame.
    #[inline(never)]
    fn write_state_outputs(&mut self) {
        write_outputs(&self.physics.state_outputs(), &mut self.values);
        self.laws_due = true;
    }

    /// Writes what the valve's gains amount to into the calculated parameters (worked out
    /// once, at initialisation: they change with fixed parameters only).
    fn write_valve_figures(&mut self) {
        write_calculated(&self.physics.valve_figures(), &mut self.values);
    }

    /// Writes the physics' outputs into their value references.
    fn write_outputs(&mut self) {
        write_outputs(&self.physics.outputs(), &mut self.values);
        self.laws_due = false;
    }
}

/// The parameters at their start values.
pub(crate) fn start_params() -> Params {
    params(&start_values()).expect("the start values are valid")
}

/// Checks every parameter and input of a value array against its type and range: the
/// values of a restored state, which did not come through a setter.
fn check_all(values: &[f64; N_VARIABLES]) -> Result<(), String> {
    for (var, &value) in VARIABLES.iter().zip(values.iter()) {
        if var.has_start() {
            var.check(value)?;
        }
    }
    Ok(())
}

/// Why [`Model::check_step`] refuses a step.
#[derive(Clone, Copy)]
enum StepFault {
    BeforeInitialisation,
    /// Not positive and finite.
    StepSize,
    TimeNotFinite,
    /// The communication point is further than `tolerance` from the FMU time.
    OffTime {
        tolerance: f64,
    },
    /// Too small to advance the FMU time.
    NoAdvance,
}

const MAGIC: &[u8; 8] = b"EHSVST03";

impl ModelContract for Model {
    const VARIABLES: &'static [Variable] = &VARIABLES;
    const N_WARNINGS: usize = InputWarning::ALL.len();

    fn interface_token() -> String {
        crate::variables::interface_token()
    }
    fn start() -> Self {
        Model::new()
    }
    fn time(&self) -> f64 {
        self.time
    }
    fn is_initialized(&self) -> bool {
        self.initialized
    }
    fn set_start_time(&mut self, start_time: f64) -> Result<(), String> {
        Model::set_start_time(self, start_time)
    }
    fn set_values<I>(&mut self, changes: I) -> Result<(), String>
    where
        I: IntoIterator<Item = (usize, f64)>,
        I::IntoIter: Clone,
    {
        self.set_all(changes)
    }
    fn reader(&mut self) -> impl FnMut(usize) -> f64 + '_ {
        Model::reader_mut(self)
    }
    fn initialize(&mut self) -> Result<(), String> {
        Model::initialize(self)
    }
    fn check_step(&self, current_time: f64, step: f64) -> Result<(), String> {
        Model::check_step(self, current_time, step)
    }
    fn step(
        &mut self,
        current_time: f64,
        step: f64,
        log_event: Option<&mut dyn FnMut(&str)>,
    ) -> Result<(), String> {
        let events = self.do_checked_step(current_time, step)?;
        if let Some(log) = log_event {
            if events != StepEvents::default() {
                log_step_events(&events, current_time, step, log);
            }
        }
        Ok(())
    }
    fn set_input_derivative(&mut self, index: usize, order: i32, value: f64) -> Result<(), String> {
        Model::set_input_derivative(self, index, order, value)
    }
    fn output_derivative(&self, index: usize, order: i32) -> Result<f64, String> {
        Model::output_derivative(self, index, order)
    }
    fn to_bytes(&self) -> Vec<u8> {
        Model::to_bytes(self)
    }
    fn from_bytes(bytes: &[u8]) -> Result<Self, String> {
        Model::from_bytes(bytes)
    }
    fn warnings(&mut self) -> u32 {
        // The common step has no suspect: its values tested without a borrow of the cell.
        if !WarningSuspects::of(&self.state.get_mut().values).any() {
            return 0;
        }
        self.input_warnings().iter().enumerate().map(|(i, &holds)| (holds as u32) << i).sum()
    }
    fn warning_text(&self, index: usize) -> String {
        self.input_warning_text(InputWarning::ALL[index])
    }
}

/// The log lines of the events inside the step `[t, t + h]`.
#[cold]
fn log_step_events(events: &StepEvents, t: f64, h: f64, log: &mut dyn FnMut(&str)) {
    if events.rail_entered + events.rail_left > 0 {
        log(&format!(
            "step [{t}, {}]: driver output reached a supply rail {} time(s), left it {} time(s)",
            t + h,
            events.rail_entered,
            events.rail_left
        ));
    }
    for (opened, chamber) in events.relief_opened.iter().zip(["A", "B"]) {
        if *opened {
            log(&format!(
                "step [{t}, {}]: relief valve of chamber {chamber} opened (p_{chamber} above relief.p_crack)",
                t + h
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_are_checked_against_the_table_and_name_the_variable() {
        let mut values = start_values();
        values[vr::CYLINDER_MASS] = 0.0;
        assert!(check_all(&values).unwrap_err().contains("cylinder.mass"));
        values[vr::CYLINDER_MASS] = 5.0;
        values[vr::CYLINDER_BETA] = f64::NAN;
        assert!(check_all(&values).unwrap_err().contains("cylinder.beta"));
        values[vr::CYLINDER_BETA] = 1e9;
        values[vr::CYLINDER_ROD] = 0.02;
        assert!(Physics::start(&params(&values).unwrap(), &inputs(&values), 0.0)
            .err()
            .unwrap()
            .contains("cylinder.rod"));
    }

    #[test]
    fn outputs_before_initialisation_follow_the_last_set() {
        let mut m = Model::new();
        assert_eq!(m.get(vr::I_COIL), Some(0.0));
        m.set(vr::I_REF, 0.005).unwrap();
        m.set(vr::I_REF, 0.01).unwrap();
        assert_eq!(m.get(vr::I_COIL), Some(0.01));
        assert!(m.get(vr::Q_VALVE).unwrap() > 0.0);
        // Parameters that do not fit together keep the last consistent outputs.
        m.set(vr::CYLINDER_ROD, 0.02).unwrap();
        assert_eq!(m.get(vr::I_COIL), Some(0.01));
        assert!(m.initialize().unwrap_err().contains("cylinder.rod"));
    }
}
