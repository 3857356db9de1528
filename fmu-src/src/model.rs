//! A model instance as the FMI layer sees it: values by value reference, initialise,
//! step, reset, and a self-checking byte form of the whole state.

use crate::physics::{Physics, StepEvents};
use crate::variables::{start_values, Causality, N_VARIABLES, VARIABLES};

#[derive(Clone)]
pub struct Model {
    /// Parameters and inputs as set by the importer, outputs as last computed; by value reference.
    values: [f64; N_VARIABLES],
    physics: Physics,
    time: f64,
    initialized: bool,
}

impl Default for Model {
    fn default() -> Self {
        Self::new()
    }
}

impl Model {
    pub fn new() -> Self {
        let values = start_values();
        let mut m = Model { values, physics: Physics::default(), time: 0.0, initialized: false };
        m.refresh_before_start();
        m
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
        if index == crate::variables::vr::TIME {
            return Some(self.time);
        }
        self.values.get(index).copied()
    }

    /// Stores a parameter or input after checking type and range. Which variables may be
    /// set in which FMI state is the FMI layer's business; this checks the value only.
    pub fn set(&mut self, index: usize, value: f64) -> Result<(), String> {
        let var = VARIABLES.get(index).ok_or_else(|| format!("unknown value reference {index}"))?;
        if !matches!(var.causality, Causality::Parameter | Causality::Input) {
            return Err(format!("{} is {:?}: it cannot be set", var.name, var.causality));
        }
        var.check(value)?;
        self.values[index] = value;
        if !self.initialized {
            self.refresh_before_start();
        }
        Ok(())
    }

    /// Sets the start time (FMI SetupExperiment / EnterInitializationMode).
    pub fn set_start_time(&mut self, start_time: f64) -> Result<(), String> {
        if !start_time.is_finite() {
            return Err(format!("start time {start_time} is not finite"));
        }
        self.time = start_time;
        Ok(())
    }

    /// Before initialisation ends the outputs are those of the initial equilibrium for
    /// the current parameters and inputs, so importers can read initial unknowns.
    fn refresh_before_start(&mut self) {
        if let Ok(p) = Physics::start(&self.values, self.time) {
            self.physics = p;
            self.physics.write_outputs(&mut self.values);
        }
    }

    /// Ends initialisation: checks the parameters together, builds the integrator, puts the
    /// model in equilibrium for the current inputs.
    pub fn initialize(&mut self) -> Result<(), String> {
        self.physics = Physics::start(&self.values, self.time)?;
        self.physics.write_outputs(&mut self.values);
        self.initialized = true;
        Ok(())
    }

    /// Advances by `step` seconds from the current time. On error the instance keeps its
    /// state from before the call.
    pub fn do_step(&mut self, current_time: f64, step: f64) -> Result<StepEvents, String> {
        self.check_step(current_time, step)?;
        let events = self.physics.advance(&self.values, self.time, step)?;
        self.physics.write_outputs(&mut self.values);
        self.time = current_time + step;
        Ok(events)
    }

    /// Refuses, without touching the model, a step no importer should ask for: before
    /// initialisation, a step size that is not positive and finite, a communication point
    /// away from the FMU time, a step too small to advance it. An error of
    /// [`Model::do_step`] after this passed is a failure of the computation.
    pub fn check_step(&self, current_time: f64, step: f64) -> Result<(), String> {
        if !self.initialized {
            return Err("doStep before initialisation ended".into());
        }
        if !step.is_finite() || step <= 0.0 {
            return Err(format!("communication step size {step} is not a positive finite number"));
        }
        if !current_time.is_finite() {
            return Err(format!("currentCommunicationPoint {current_time} is not finite"));
        }
        let tolerance = communication_point_tolerance(self.time, step);
        if (current_time - self.time).abs() > tolerance {
            return Err(format!(
                "currentCommunicationPoint {current_time} does not match the FMU time {} \
                 (tolerance {tolerance:e} s)",
                self.time
            ));
        }
        if current_time + step <= self.time {
            return Err(format!(
                "a step of {step} s from {current_time} does not advance the FMU time {}",
                self.time
            ));
        }
        Ok(())
    }

    /// Versioned, self-checking byte form of the whole instance (no pointers).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut body = Vec::with_capacity(16 + 8 * (N_VARIABLES + 16));
        body.extend_from_slice(&(N_VARIABLES as u32).to_le_bytes());
        body.push(self.initialized as u8);
        body.extend_from_slice(&self.time.to_le_bytes());
        for v in &self.values {
            body.extend_from_slice(&v.to_le_bytes());
        }
        self.physics.write_bytes(&mut body);
        frame(MAGIC, &body)
    }

    /// Inverse of [`Model::to_bytes`]; refuses truncated, corrupted or foreign bytes.
    pub fn from_bytes(bytes: &[u8]) -> Result<Model, String> {
        let body = unframe(MAGIC, bytes)?;
        let mut r = Reader { bytes: body, at: 0 };
        let n = r.u32()? as usize;
        if n != N_VARIABLES {
            return Err(format!("state has {n} variables, this FMU has {N_VARIABLES}"));
        }
        let initialized = r.u8()? != 0;
        let time = r.f64()?;
        let mut values = [0.0; N_VARIABLES];
        for v in values.iter_mut() {
            *v = r.f64()?;
        }
        let physics = Physics::read_bytes(&values, &mut r)?;
        if r.at != body.len() {
            return Err("state has trailing bytes".into());
        }
        Ok(Model { values, physics, time, initialized })
    }
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

const MAGIC: &[u8; 8] = b"EHSVST01";

fn checksum(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf29ce484222325u64, |h, &b| (h ^ b as u64).wrapping_mul(0x100000001b3))
}

/// magic | body length (u64) | body | FNV-1a 64 of body. The magic names the format
/// and its version (the model's bytes, the FMI layer's FMU state around them).
pub(crate) fn frame(magic: &[u8; 8], body: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(body.len() + 24);
    out.extend_from_slice(magic);
    out.extend_from_slice(&(body.len() as u64).to_le_bytes());
    out.extend_from_slice(body);
    out.extend_from_slice(&checksum(body).to_le_bytes());
    out
}

pub(crate) fn unframe<'a>(magic: &[u8; 8], bytes: &'a [u8]) -> Result<&'a [u8], String> {
    if bytes.len() < 24 || &bytes[..8] != magic {
        return Err("not an EhsvActuator state (wrong magic or version)".into());
    }
    let len = u64::from_le_bytes(bytes[8..16].try_into().unwrap());
    if len != (bytes.len() - 24) as u64 {
        return Err(format!("state length {} does not match its header ({len})", bytes.len() - 24));
    }
    let body = &bytes[16..bytes.len() - 8];
    let sum = u64::from_le_bytes(bytes[bytes.len() - 8..].try_into().unwrap());
    if sum != checksum(body) {
        return Err("state checksum mismatch (corrupted bytes)".into());
    }
    Ok(body)
}

/// Bounds-checked little-endian reader for state bytes.
pub struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], String> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or("state is truncated")?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    pub fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    pub fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().unwrap()))
    }
    pub fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_le_bytes(self.take(8)?.try_into().unwrap()))
    }
}
