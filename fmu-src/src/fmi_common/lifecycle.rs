//! The instance's way through the run: experiment setup, entering and leaving
//! initialisation, terminate, reset, and doStep with what a step reports (events inside
//! the step, input conditions that began).

use super::instance::Instance;
use super::logging::{Status, LOG_CATEGORIES, LOG_EVENTS, LOG_WARNING};
use super::state_machine::State::{self, InitializationMode, Instantiated, StepMode, Terminated};
use crate::contract::{communication_point_tolerance, ModelContract};

impl<M: ModelContract> Instance<M> {
    /// Start (and optional stop) time of the experiment.
    pub(crate) fn setup_experiment(
        &mut self,
        start: f64,
        stop: Option<f64>,
    ) -> Result<Status, Status> {
        if let Some(stop) = stop {
            if !stop.is_finite() || stop < start || start.is_nan() {
                return self.error(&format!(
                    "stopTime {stop} must be finite and not before startTime {start}"
                ));
            }
        }
        if let Err(e) = self.model.set_start_time(start) {
            return self.error(&e);
        }
        self.stop_time = stop;
        Ok(Status::OK)
    }

    pub(crate) fn enter_initialization(&mut self) -> Result<Status, Status> {
        self.state = InitializationMode;
        Ok(Status::OK)
    }

    pub(crate) fn terminate(&mut self) -> Result<Status, Status> {
        self.state = Terminated;
        Ok(Status::OK)
    }

    /// Ends initialisation: the model checks its parameters together (a refusal leaves
    /// the instance in Initialization Mode, to correct them).
    pub(crate) fn exit_initialization(&mut self) -> Result<Status, Status> {
        match self.model.initialize() {
            Ok(()) => {
                self.state = StepMode;
                Ok(Status::OK)
            }
            Err(e) => self.error(&format!("initialization failed: {e}")),
        }
    }

    /// Back to the state after instantiation (logging settings are kept).
    pub(crate) fn reset(&mut self) -> Result<Status, Status> {
        self.model = M::start();
        self.state = Instantiated;
        self.stop_time = None;
        self.warned = 0;
        Ok(Status::OK)
    }

    /// One communication step. A step the model refuses up front, or one past the stop
    /// time, is a refusal (nothing changes); a step whose computation fails puts the
    /// instance in the Error state (the model itself is left as before the call).
    /// Inlined into fmi2DoStep/fmi3DoStep: the refusals' messages are built out of line.
    #[inline(always)]
    pub(crate) fn do_step(&mut self, t: f64, h: f64) -> Result<Status, Status> {
        if let Err(e) = self.model.check_step(t, h) {
            return self.error(&e);
        }
        if let Some(stop) = self.stop_time {
            // The tolerance (h is positive and finite here) is only worked out for a step
            // that ends after stopTime at all.
            let end = t + h;
            if end > stop && end > stop + communication_point_tolerance(stop, h) {
                return self.refuse_step_past_stop(t, h, stop);
            }
        }
        let conditions = self.model.warnings();
        let stepped = if self.enabled(LOG_EVENTS) {
            self.step_logging_events(t, h)
        } else {
            self.model.step(t, h, None)
        };
        match stepped {
            Ok(()) => Ok(self.warn_about_inputs(t, conditions)),
            Err(e) => self.step_failed(&e),
        }
    }

    /// Error for a step that would end after the stop time.
    #[cold]
    #[inline(never)]
    fn refuse_step_past_stop(&self, t: f64, h: f64, stop: f64) -> Result<Status, Status> {
        self.error(&format!("a step from {t} by {h} ends at {}, after stopTime {stop}", t + h))
    }

    /// The model's step with its events collected and, once it succeeded, logged. Out of
    /// line: only a host that asked for logEvents pays for the collection.
    #[inline(never)]
    fn step_logging_events(&mut self, t: f64, h: f64) -> Result<(), String> {
        let mut events = Vec::new();
        let mut collect = |line: &str| events.push(line.to_owned());
        self.model.step(t, h, Some(&mut collect))?;
        for line in &events {
            self.log(Status::OK, LOG_EVENTS, line);
        }
        Ok(())
    }

    /// A step whose computation failed: the Error state, and the log line saying so.
    #[cold]
    #[inline(never)]
    fn step_failed(&mut self, e: &str) -> Result<Status, Status> {
        self.state = State::Error;
        self.error(&format!(
            "{e}; the step failed and the instance is in the Error state \
             (SetFMUState to an earlier state, Reset or FreeInstance go on)"
        ))
    }

    /// Warning (and one logStatusWarning line each) for the input conditions that began
    /// with this step; OK while none began (a lasting condition is not repeated).
    #[inline]
    fn warn_about_inputs(&mut self, t: f64, conditions: u32) -> Status {
        let began = conditions & !self.warned;
        self.warned = conditions;
        if began == 0 {
            return Status::OK;
        }
        self.warn_began(t, began)
    }

    /// The Warning of [`Instance::warn_about_inputs`] once a condition began. Out of line:
    /// the common step has none.
    #[cold]
    #[inline(never)]
    fn warn_began(&self, t: f64, began: u32) -> Status {
        if self.enabled(LOG_WARNING) {
            for index in (0..M::N_WARNINGS).filter(|i| began & (1 << i) != 0) {
                let text = self.model.warning_text(index);
                let message = format!("{}: step from {t}: {text}", self.func);
                self.logger.emit(
                    &self.name,
                    Status::Warning,
                    LOG_CATEGORIES[LOG_WARNING].0,
                    &message,
                );
            }
        }
        Status::Warning
    }
}
