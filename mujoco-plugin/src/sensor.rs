//! The plugin's sensors: `<sensor><plugin instance="..."/>` on an `ehsv.actuator` instance
//! reads that actuator's outputs, every output of the FMU in table order
//! ([`output_names`]), copied from the instance's `plugin_state` slots (the outputs
//! [`Actuator::commit`](crate::actuator::Actuator::commit) wrote: the state at `d->time`).
//! A sensor never steps the physics, so a model's sensors change none of its numbers.

use std::ffi::c_int;

use crate::actuator::output_names;
use crate::ffi::{element, field, offsets as o, MjData, MjModel, SENS_PLUGIN};

/// Values per sensor: one per output of the FMU (the layout of the slots' head).
pub fn dimension() -> usize {
    output_names().len()
}

/// MuJoCo's `nsensordata`: every sensor on an instance has the same layout.
pub(crate) unsafe extern "C" fn nsensordata(
    _m: *const MjModel,
    _instance: c_int,
    _sensor: c_int,
) -> c_int {
    crate::guard(0, || dimension() as c_int)
}

/// Copies `outputs` (the head of the instance's slots) into every plugin sensor of
/// `instance`: at most the sensor's dimension, never past `outputs`. MuJoCo asks every
/// instance at the sensor stage, with or without a sensor: one without writes nothing.
///
/// # Safety
/// `m`, `d` live, `instance` one of `m`'s plugin instances.
pub unsafe fn write(m: *const MjModel, d: *mut MjData, instance: c_int, outputs: &[f64]) {
    let nsensor: i64 = field(m.cast(), o::MODEL_NSENSOR);
    let sensordata: *mut f64 = field(d.cast(), o::DATA_SENSORDATA);
    for j in 0..nsensor as usize {
        if element::<c_int>(m.cast(), o::MODEL_SENSOR_TYPE, j) != SENS_PLUGIN
            || element::<c_int>(m.cast(), o::MODEL_SENSOR_PLUGIN, j) != instance
        {
            continue;
        }
        let adr = element::<c_int>(m.cast(), o::MODEL_SENSOR_ADR, j) as usize;
        let dim = element::<c_int>(m.cast(), o::MODEL_SENSOR_DIM, j).max(0) as usize;
        let n = dim.min(outputs.len());
        std::ptr::copy_nonoverlapping(outputs.as_ptr(), sensordata.add(adr), n);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sensor's layout is the FMU's output table: the order docs/mujoco.md lists.
    #[test]
    fn a_sensor_gives_the_outputs_in_table_order() {
        let names = output_names();
        assert_eq!(dimension(), 16);
        assert_eq!(names[..3], ["i_coil", "u_driver", "driver_saturated"]);
        assert_eq!(names[8..10], ["p_A", "p_B"]);
        assert_eq!(names[13..], ["F_rod", "dF_rod_dx", "dF_rod_dv"]);
    }
}
