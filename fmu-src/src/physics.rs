//! Physics core (stub while the integrator is written).
use crate::model::Reader;
use crate::variables::N_VARIABLES;

/// What happened inside one step, for event logging.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepEvents {
    pub rail_entered: u32,
    pub rail_left: u32,
}

#[derive(Clone, Default)]
pub struct Physics {}

impl Physics {
    pub fn start(_values: &[f64; N_VARIABLES]) -> Result<Physics, String> {
        Ok(Physics {})
    }
    pub fn write_outputs(&self, _values: &mut [f64; N_VARIABLES]) {}
    pub fn advance(&mut self, _values: &[f64; N_VARIABLES], _step: f64) -> Result<StepEvents, String> {
        Ok(StepEvents::default())
    }
    pub fn write_bytes(&self, _out: &mut Vec<u8>) {}
    pub fn read_bytes(_values: &[f64; N_VARIABLES], _r: &mut Reader) -> Result<Physics, String> {
        Ok(Physics {})
    }
}
