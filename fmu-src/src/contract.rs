//! The small contract between the FMI layer and a model: everything [`crate::fmi_common`]
//! (and through it [`crate::fmi2`] and [`crate::fmi3`]) asks of the actuator. The FMI
//! layer is generic over it and knows nothing of hydraulics: it sees a table of
//! variables, values by value reference, a step that may log events, input conditions to
//! warn about, and bytes for the FMU state. [`crate::model::Model`] fills it in.

use crate::variables::Variable;

pub trait ModelContract: Clone {
    /// Every variable, indexed by value reference.
    const VARIABLES: &'static [Variable];
    /// How many input conditions [`ModelContract::warnings`] reports (at most 32).
    const N_WARNINGS: usize;

    /// A hash of every attribute an importer binds to (the FMI 2 guid, the FMI 3
    /// instantiation token).
    fn interface_token() -> String;

    /// A new model at its start values (FMI Instantiate, Reset).
    fn start() -> Self;
    fn time(&self) -> f64;
    fn is_initialized(&self) -> bool;
    /// The start time (FMI SetupExperiment / EnterInitializationMode).
    fn set_start_time(&mut self, start_time: f64) -> Result<(), String>;
    /// Sets parameters and inputs `(value reference, value)`, all or nothing; each value
    /// checked against its variable (type, range, may it be set now); tunable parameters
    /// set after initialisation take effect at the next communication point.
    fn set_values<I>(&mut self, changes: I) -> Result<(), String>
    where
        I: IntoIterator<Item = (usize, f64)>,
        I::IntoIter: Clone;
    /// Reads values by (known) value reference, outputs up to date. Mutable: outputs left
    /// unwritten are written when first read, and the FMI layer holds the instance
    /// exclusively anyway.
    fn reader(&mut self) -> impl FnMut(usize) -> f64 + '_;
    /// Ends initialisation: the parameters checked together, the model at equilibrium.
    fn initialize(&mut self) -> Result<(), String>;
    /// Refuses, without touching the model, a step no importer should ask for.
    fn check_step(&self, current_time: f64, step: f64) -> Result<(), String>;
    /// Advances by `step` after [`ModelContract::check_step`] passed; each event inside
    /// the step goes to `log_event` when there is one. On error the model is as before.
    fn step(
        &mut self,
        current_time: f64,
        step: f64,
        log_event: Option<&mut dyn FnMut(&str)>,
    ) -> Result<(), String>;
    /// Sets the `order`-th time derivative of input `index` for the steps that follow.
    fn set_input_derivative(&mut self, index: usize, order: i32, value: f64) -> Result<(), String>;
    /// The `order`-th time derivative of output `index` at the current communication point.
    fn output_derivative(&self, index: usize, order: i32) -> Result<f64, String>;
    /// The whole state as self-checking bytes, and back (refusing bytes it did not write).
    fn to_bytes(&self) -> Vec<u8>;
    fn from_bytes(bytes: &[u8]) -> Result<Self, String>;
    /// Which input conditions hold (bit i: condition i), legal but rarely meant: the FMI
    /// layer warns once when each begins. Mutable for the reason of
    /// [`ModelContract::reader`]: asked before every step.
    fn warnings(&mut self) -> u32;
    /// The log line of condition `index`.
    fn warning_text(&self, index: usize) -> String;
}

/// How far an importer's communication point may be from the FMU time: the rounding of
/// its own `t + h` sums (4 ulps of t) plus a millionth of the step, so never more than a
/// small fraction of the step however large t is (an epoch start time of 1.7e9 s has
/// ulps of 0.24 us).
pub fn communication_point_tolerance(time: f64, step: f64) -> f64 {
    let abs = time.abs();
    let ulp = f64::from_bits(abs.to_bits() + 1) - abs;
    4.0 * ulp + 1e-6 * step
}
