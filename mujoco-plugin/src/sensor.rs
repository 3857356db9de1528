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

/// Where instance `instance`'s plugin sensors sit in `sensordata`: `(address, dimension)`
/// of each. Found once, when the instance is built: the model does not change under it, and
/// a forward pass then copies without looking through every sensor of the model.
///
/// # Safety
/// `m` live, `instance` one of its plugin instances.
pub unsafe fn of_instance(m: *const MjModel, instance: c_int) -> Vec<(usize, usize)> {
    let nsensor: i64 = field(m.cast(), o::MODEL_NSENSOR);
    (0..nsensor as usize)
        .filter(|&j| {
            element::<c_int>(m.cast(), o::MODEL_SENSOR_TYPE, j) == SENS_PLUGIN
                && element::<c_int>(m.cast(), o::MODEL_SENSOR_PLUGIN, j) == instance
        })
        .map(|j| {
            let adr = element::<c_int>(m.cast(), o::MODEL_SENSOR_ADR, j) as usize;
            let dim = element::<c_int>(m.cast(), o::MODEL_SENSOR_DIM, j).max(0) as usize;
            (adr, dim)
        })
        .collect()
}

/// Copies `outputs` (the head of the instance's slots) into each of its `sensors`
/// ([`of_instance`]): at most the sensor's dimension, never past `outputs`. MuJoCo asks
/// every instance at the sensor stage, with or without a sensor: one without writes nothing.
///
/// # Safety
/// `d` live, of the model `sensors` was found in.
pub unsafe fn write(d: *mut MjData, sensors: &[(usize, usize)], outputs: &[f64]) {
    let sensordata: *mut f64 = field(d.cast(), o::DATA_SENSORDATA);
    for &(adr, dim) in sensors {
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
        assert_eq!(dimension(), 17);
        assert_eq!(names[..3], ["i_coil", "u_driver", "driver_saturated"]);
        assert_eq!(names[8..10], ["p_A", "p_B"]);
        assert_eq!(names[13..], ["F_rod", "dF_rod_dx", "dF_rod_dv", "Q_supply"]);
    }
}
