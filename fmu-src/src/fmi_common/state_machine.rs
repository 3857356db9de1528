//! The FMI call sequence as one table, the same for FMI 2.0 and FMI 3.0: for each kind of
//! call (`Call`) the set of instance states (`State`) it is allowed in. The shared
//! `with_instance` frame looks every exported function up here before running it.
//!
//! Error semantics (docs/fmi.md, "Errors and what is refused", says the same):
//! * A call that is refused (illegal in the current state, NULL or malformed arguments,
//!   unknown value references, out-of-range values, a communication point away from the
//!   FMU time, a state that is not ours) returns Error with a log line and changes
//!   nothing: the instance stays in its state. The standards leave what follows an
//!   Error undefined; staying usable is the safe reading of that.
//! * A call that was accepted and then failed (the step computation of doStep, or an
//!   internal error caught at the C boundary) returns Error and puts the instance in
//!   the `Error` state. There, as FMI 2.0.4 (2.1.3) and FMI 3.0 (2.2.3) define, only
//!   SetFMUState (to a state taken before), Reset and FreeInstance go on; getters and the
//!   FMU-state bookkeeping answer for diagnostics; everything else is refused.

/// FMI state of an instance. FMI 2 calls [`State::StepMode`] "StepComplete". States the
/// FMU never enters are left out: StepInProgress/StepFailed/StepCanceled (steps are
/// synchronous), ConfigurationMode/EventMode (no structural parameters, no event mode).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum State {
    Instantiated,
    InitializationMode,
    StepMode,
    Terminated,
    /// After a failed call: see the module documentation.
    Error,
}

/// Which FMI standard an instance was created through.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Version {
    Fmi2,
    Fmi3,
}

impl State {
    pub(crate) const ALL: [State; 5] = [
        State::Instantiated,
        State::InitializationMode,
        State::StepMode,
        State::Terminated,
        State::Error,
    ];

    pub(crate) fn name(self, version: Version) -> &'static str {
        match (self, version) {
            (State::Instantiated, _) => "Instantiated",
            (State::InitializationMode, _) => "InitializationMode",
            (State::StepMode, Version::Fmi2) => "StepComplete",
            (State::StepMode, Version::Fmi3) => "StepMode",
            (State::Terminated, _) => "Terminated",
            (State::Error, _) => "Error",
        }
    }

    const fn bit(self) -> u8 {
        1 << self as u8
    }

    /// The byte that stands for the state in the serialized FMU state.
    pub(crate) fn code(self) -> u8 {
        self as u8
    }

    /// Inverse of [`State::code`] for the states an FMU state can be taken in.
    pub(crate) fn from_code(code: u8) -> Option<State> {
        State::ALL.into_iter().find(|s| s.code() == code && *s != State::Error)
    }
}

/// A set of states, one bit each.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct States(u8);

impl States {
    pub(crate) const NONE: States = States(0);

    const fn of(states: &[State]) -> States {
        let (mut bits, mut i) = (0, 0);
        while i < states.len() {
            bits |= states[i].bit();
            i += 1;
        }
        States(bits)
    }

    #[inline]
    pub(crate) fn contains(self, state: State) -> bool {
        self.0 & state.bit() != 0
    }

    /// The names of the states in the set, for messages.
    pub(crate) fn names(self, version: Version) -> String {
        let names: Vec<_> =
            State::ALL.iter().filter(|s| self.contains(**s)).map(|s| s.name(version)).collect();
        names.join(", ")
    }
}

/// The kinds of call the table distinguishes; each exported function is one of them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Call {
    SetDebugLogging,
    /// fmi2SetupExperiment (FMI 3 passes the experiment to EnterInitializationMode).
    SetupExperiment,
    EnterInitializationMode,
    ExitInitializationMode,
    Terminate,
    Reset,
    /// Every variable getter.
    GetValues,
    /// Every variable setter; which variable may be set when is the instance's check.
    SetValues,
    GetFMUState,
    SetFMUState,
    /// FreeFMUState, SerializedFMUStateSize, SerializeFMUState, DeserializeFMUState: they
    /// touch stored states only, never the instance's own.
    StoredFMUState,
    DoStep,
    /// The FMI 2 status inquiries (fmi2GetStatus, fmi2GetRealStatus, ...).
    GetStatus,
    /// Functions of capabilities this FMU does not have: always answered "not supported".
    Unsupported,
}

use crate::variables::Variable;
use State::{Error, InitializationMode as Init, Instantiated, StepMode as Step, Terminated};

const ANY: States = States::of(&State::ALL);
/// States the importer reaches by correct calls (all but Error).
const RUNNING: States = States::of(&[Instantiated, Init, Step, Terminated]);

impl Call {
    /// The table: the states in which the call is allowed.
    pub(crate) const fn allowed(self) -> States {
        match self {
            Call::SetDebugLogging => ANY,
            Call::SetupExperiment => States::of(&[Instantiated]),
            Call::EnterInitializationMode => States::of(&[Instantiated]),
            Call::ExitInitializationMode => States::of(&[Init]),
            Call::Terminate => States::of(&[Step]),
            Call::Reset => ANY,
            // Before initialisation the outputs are the initial equilibrium; in Error
            // they are those of the last good communication point (diagnostics).
            Call::GetValues => ANY,
            Call::SetValues => States::of(&[Instantiated, Init, Step]),
            // A state taken in Error could not be continued (FMI 2.0.4 2.1.3).
            Call::GetFMUState => RUNNING,
            Call::SetFMUState => ANY,
            Call::StoredFMUState => ANY,
            Call::DoStep => States::of(&[Step]),
            Call::GetStatus => States::of(&[Step, Terminated, Error]),
            Call::Unsupported => ANY,
        }
    }
}

/// The second half of the table for setters: the states in which `variable` may be set
/// (FMI 2.0 and 3.0 agree for the kinds used here), from the variable's own rule
/// ([`Variable::may_be_set`]) before and after initialisation: inputs and tunable
/// parameters also in Step Mode (FMI 2 StepComplete), taking effect at the next
/// communication point; fixed parameters only until initialisation ends; outputs and the
/// independent variable never (`None`).
pub(crate) const fn settable_in(variable: &Variable) -> Option<States> {
    match (variable.may_be_set(false), variable.may_be_set(true)) {
        (true, true) => Some(States::of(&[Instantiated, Init, Step])),
        (true, false) => Some(States::of(&[Instantiated, Init])),
        (false, true) => Some(States::of(&[Step])),
        (false, false) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_reads_as_the_standards_call_sequence() {
        let allowed = |call: Call| -> Vec<State> {
            State::ALL.into_iter().filter(|s| call.allowed().contains(*s)).collect()
        };
        assert_eq!(allowed(Call::DoStep), [Step]);
        assert_eq!(allowed(Call::EnterInitializationMode), [Instantiated]);
        assert_eq!(allowed(Call::SetValues), [Instantiated, Init, Step]);
        assert_eq!(allowed(Call::GetFMUState), [Instantiated, Init, Step, Terminated]);
        // After a failed call: restore, reset, diagnostics and freeing, nothing that goes on.
        let in_error: Vec<Call> = [
            Call::SetDebugLogging,
            Call::SetupExperiment,
            Call::EnterInitializationMode,
            Call::ExitInitializationMode,
            Call::Terminate,
            Call::Reset,
            Call::GetValues,
            Call::SetValues,
            Call::GetFMUState,
            Call::SetFMUState,
            Call::StoredFMUState,
            Call::DoStep,
            Call::GetStatus,
            Call::Unsupported,
        ]
        .into_iter()
        .filter(|c| c.allowed().contains(Error))
        .collect();
        assert_eq!(
            in_error,
            [
                Call::SetDebugLogging,
                Call::Reset,
                Call::GetValues,
                Call::SetFMUState,
                Call::StoredFMUState,
                Call::GetStatus,
                Call::Unsupported
            ]
        );
        assert_eq!(
            ANY.names(Version::Fmi2),
            "Instantiated, InitializationMode, StepComplete, Terminated, Error"
        );
    }

    #[test]
    fn tunable_parameters_and_inputs_are_settable_in_step_mode_fixed_ones_not() {
        use crate::variables::{vr, VARIABLES};
        let states = |index: usize| -> Vec<State> {
            let set = settable_in(&VARIABLES[index]).expect("settable");
            State::ALL.into_iter().filter(|s| set.contains(*s)).collect()
        };
        assert_eq!(states(vr::POSITION_KP), [Instantiated, Init, Step]);
        assert_eq!(states(vr::I_REF), [Instantiated, Init, Step]);
        assert_eq!(states(vr::COIL_L), [Instantiated, Init]);
        assert_eq!(settable_in(&VARIABLES[vr::X_PISTON]), None);
        assert_eq!(settable_in(&VARIABLES[vr::TIME]), None);
        // Each settable state is one where the setters are allowed at all.
        for v in VARIABLES.iter() {
            if let Some(set) = settable_in(v) {
                for s in State::ALL.into_iter().filter(|s| set.contains(*s)) {
                    assert!(Call::SetValues.allowed().contains(s), "{} in {s:?}", v.name);
                }
            }
        }
    }

    #[test]
    fn state_codes_round_trip_and_error_is_not_storable() {
        for s in State::ALL {
            let back = State::from_code(s.code());
            assert_eq!(back, (s != Error).then_some(s), "{s:?}");
        }
        assert_eq!(State::from_code(5), None);
        assert_eq!(State::from_code(0xff), None);
    }
}
