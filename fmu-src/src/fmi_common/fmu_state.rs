//! FMU states behind `fmi2FMUstate` / `fmi3FMUState`: what one holds, its bytes, and the
//! instance's get/set/free/serialize/deserialize. An instance owns the FMU states it
//! handed out and refuses any pointer it did not make.

use std::ffi::c_void;

use super::instance::Instance;
use super::logging::Status;
use super::state_machine::State::{self, StepMode, Terminated};
use crate::contract::ModelContract;
use crate::variables::Causality;

/// An FMU state behind `fmi2FMUstate` / `fmi3FMUState`: everything needed to continue
/// (FMI 2.0.4 2.1.8, FMI 3.0): the model, the FMI state it was taken in, the stop time.
pub(super) struct SavedState<M> {
    model: M,
    mode: State,
    stop_time: Option<f64>,
}

/// Format and version of the serialized FMU state (the model's own bytes are inside).
const FMU_STATE_MAGIC: &[u8; 8] = b"EHSVFS01";

impl<M: ModelContract> SavedState<M> {
    /// mode | stop time defined (0/1) | stop time (0 if undefined) | model bytes, framed
    /// and checksummed as the model's bytes are.
    fn to_bytes(&self) -> Vec<u8> {
        let mut body = vec![self.mode.code(), self.stop_time.is_some() as u8];
        body.extend_from_slice(&self.stop_time.unwrap_or(0.0).to_le_bytes());
        body.extend_from_slice(&self.model.to_bytes());
        crate::physics::bytes::frame(FMU_STATE_MAGIC, &body)
    }

    /// Inverse of [`SavedState::to_bytes`]; refuses what the FMU would never have written.
    fn from_bytes(bytes: &[u8]) -> Result<SavedState<M>, String> {
        let body = crate::physics::bytes::unframe(FMU_STATE_MAGIC, bytes)?;
        let (head, model) = body.split_at_checked(10).ok_or("state is truncated")?;
        let mode = State::from_code(head[0])
            .ok_or_else(|| format!("state has an unknown FMI mode code {}", head[0]))?;
        let stop = f64::from_le_bytes(head[2..10].try_into().expect("8 bytes"));
        let stop_time = match head[1] {
            0 if stop.to_bits() == 0 => None,
            1 if stop.is_finite() => Some(stop),
            flag => return Err(format!("state has an invalid stop time ({flag}, {stop})")),
        };
        let mut model = M::from_bytes(model)?;
        check_restored(&mut model)?;
        if model.is_initialized() != matches!(mode, StepMode | Terminated) {
            return Err(format!(
                "state's FMI mode code {} does not match its model (initialised: {})",
                head[0],
                model.is_initialized()
            ));
        }
        Ok(SavedState { model, mode, stop_time })
    }
}

impl<M: ModelContract> Instance<M> {
    /// The FMU state behind a pointer the importer hands back, if this instance made it
    /// and it was not freed; anything else is refused without being read.
    fn saved(&self, ptr: *mut c_void) -> Result<&SavedState<M>, Status> {
        match self.fmu_states.get(&(ptr as usize)) {
            Some(saved) => Ok(saved),
            None => self.error(
                "the FMU state is NULL, freed, or not one this instance made \
                 (an FMU state belongs to the instance that took or deserialized it)",
            ),
        }
    }

    /// Stores `saved` into `*state`: a new FMU state for a NULL `*state`, else the one
    /// given is overwritten (as the standards require).
    ///
    /// # Safety
    /// `state` is NULL or points to a writable FMU-state pointer.
    unsafe fn store_state(
        &mut self,
        state: *mut *mut c_void,
        saved: SavedState<M>,
    ) -> Result<Status, Status> {
        // SAFETY: forwarded contract.
        let slot = unsafe { self.out("FMUState", state)? };
        if slot.is_null() {
            let mut boxed = Box::new(saved);
            let address: *mut SavedState<M> = &mut *boxed;
            self.fmu_states.insert(address as usize, boxed);
            *slot = address.cast();
        } else {
            match self.fmu_states.get_mut(&(*slot as usize)) {
                Some(old) => **old = saved,
                None => return self.saved(*slot).map(|_| Status::OK),
            }
        }
        Ok(Status::OK)
    }

    /// # Safety
    /// See [`Instance::store_state`].
    pub(crate) unsafe fn get_fmu_state(
        &mut self,
        state: *mut *mut c_void,
    ) -> Result<Status, Status> {
        let saved =
            SavedState { model: self.model.clone(), mode: self.state, stop_time: self.stop_time };
        // SAFETY: forwarded contract.
        unsafe { self.store_state(state, saved) }
    }

    /// Restores the model, the FMI state the FMU state was taken in and the stop time:
    /// the instance continues as it would have from there (also out of the Error state).
    pub(crate) fn set_fmu_state(&mut self, state: *mut c_void) -> Result<Status, Status> {
        let saved = self.saved(state)?;
        let (model, mode, stop_time) = (saved.model.clone(), saved.mode, saved.stop_time);
        self.model = model;
        self.state = mode;
        self.stop_time = stop_time;
        Ok(Status::OK)
    }

    /// Frees `*state` and sets it to NULL; NULL `state` or `*state` is a no-op.
    ///
    /// # Safety
    /// `state` is NULL or points to a readable and writable FMU-state pointer.
    pub(crate) unsafe fn free_fmu_state(
        &mut self,
        state: *mut *mut c_void,
    ) -> Result<Status, Status> {
        // SAFETY: a non-NULL `state` is a readable/writable pointer slot (contract).
        let Some(slot) = (unsafe { state.as_mut() }) else { return Ok(Status::OK) };
        if slot.is_null() {
            return Ok(Status::OK);
        }
        match self.fmu_states.remove(&(*slot as usize)) {
            Some(freed) => drop(freed),
            None => return self.saved(*slot).map(|_| Status::OK),
        }
        *slot = std::ptr::null_mut();
        Ok(Status::OK)
    }

    /// # Safety
    /// `size` is NULL or writable.
    pub(crate) unsafe fn serialized_size(
        &self,
        state: *mut c_void,
        size: *mut usize,
    ) -> Result<Status, Status> {
        let bytes = self.saved(state)?.to_bytes();
        // SAFETY: forwarded contract.
        *unsafe { self.out("size", size)? } = bytes.len();
        Ok(Status::OK)
    }

    /// # Safety
    /// `bytes` points to `size` writable bytes.
    pub(crate) unsafe fn serialize(
        &self,
        state: *mut c_void,
        bytes: *mut u8,
        size: usize,
    ) -> Result<Status, Status> {
        let data = self.saved(state)?.to_bytes();
        if size < data.len() {
            return self.error(&format!(
                "size {size} is too small: the serialized state has {} bytes",
                data.len()
            ));
        }
        // SAFETY: forwarded array contract.
        let out = unsafe { self.slice_mut("serializedState", bytes, size)? };
        out[..data.len()].copy_from_slice(&data);
        Ok(Status::OK)
    }

    /// # Safety
    /// `bytes` points to `size` readable bytes; `state` as in [`Instance::store_state`].
    pub(crate) unsafe fn deserialize(
        &mut self,
        bytes: *const u8,
        size: usize,
        state: *mut *mut c_void,
    ) -> Result<Status, Status> {
        // SAFETY: forwarded array contract.
        let data = unsafe { self.slice("serializedState", bytes, size)? };
        let saved = match SavedState::from_bytes(data) {
            Ok(saved) => saved,
            Err(e) => return self.error(&format!("cannot deserialize the FMU state: {e}")),
        };
        // SAFETY: forwarded contract.
        unsafe { self.store_state(state, saved) }
    }
}

/// What the checksum cannot vouch for in a well-formed frame built elsewhere: the time
/// is finite, parameters and inputs pass the checks of the setters, outputs are finite.
fn check_restored<M: ModelContract>(model: &mut M) -> Result<(), String> {
    if !model.time().is_finite() {
        return Err(format!("the state's time {} is not finite", model.time()));
    }
    let mut read = model.reader();
    for (index, var) in M::VARIABLES.iter().enumerate() {
        let value = read(index);
        match var.causality {
            Causality::Parameter | Causality::Input => var.check(value)?,
            Causality::Output | Causality::CalculatedParameter if !value.is_finite() => {
                return Err(format!("the state's {} = {value} is not finite", var.name))
            }
            _ => {}
        }
    }
    Ok(())
}
