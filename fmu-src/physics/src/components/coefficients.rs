//! The parameters in the form the equations use, derived from [`Params`] once: the
//! driver's PI loop, the H-bridge, the outer loops, the cylinder, coil and valve.

use crate::components::cylinder::CylinderParams;
use crate::components::outer_loop::LoopParams;
use crate::components::valve_datasheet;
use crate::params::{DriverKind, HBridgeParams, Params, SolverMethod, ValveParams};

/// The parameters in the form the equations use (derived from [`Params`] once).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Coefficients {
    pub driver: DriverKind,
    /// Gains, output drop and slew rate of the continuous PI loop of the chosen driver.
    pub kp: f64,
    pub ki: f64,
    pub v_drop: f64,
    pub slew_rate: f64,
    pub hbridge: HBridgeParams,
    pub loops: LoopParams,
    pub cylinder: CylinderParams,
    pub inductance: f64,
    pub r_total: f64,
    pub k_backemf: f64,
    pub valve: ValveParams,
    /// Natural angular frequency of the first stage, 2 pi f_n.
    pub wn: f64,
}

impl Coefficients {
    /// Derives the coefficients and checks the rules between parameters.
    pub(crate) fn new(p: &Params) -> Result<Coefficients, String> {
        let pi = if p.driver == DriverKind::Industrial { p.industrial } else { p.opamp };
        // In datasheet form the gains are worked out here, once.
        let v = &valve_datasheet::resolve(&p.valve)?;
        Ok(Coefficients {
            driver: p.driver,
            kp: pi.kp,
            ki: pi.ki,
            // The op-amp's output stage drop; the other drivers reach the supply.
            v_drop: if p.driver == DriverKind::OpampPi { p.opamp_v_drop } else { 0.0 },
            slew_rate: pi.slew_rate,
            // The fixed-cost method takes the PWM by its periods' means: a step's cost then
            // does not grow with the switchings in it.
            hbridge: HBridgeParams {
                pwm_mean: p.solver_method == SolverMethod::FixedCost,
                ..p.hbridge
            },
            loops: LoopParams::new(&p.outer_loop, p.control_mode, v.k3 * v.k1 / v.kw),
            cylinder: CylinderParams::new(&p.cylinder, v)?,
            inductance: p.coil.inductance,
            r_total: p.coil.resistance + p.coil.r_sense,
            k_backemf: p.coil.k_backemf,
            valve: *v,
            wn: 2.0 * std::f64::consts::PI * v.f_n,
        })
    }

    /// What the mode systems are built from, as bits: the driver's PI loop (gains, slew
    /// rate), the coil, and the valve (first stage, spool, stops). Equal keys give the same
    /// systems bit for bit.
    pub(crate) fn mode_system_key(&self) -> [u64; 19] {
        let v = &self.valve;
        [
            self.kp,
            self.ki,
            self.slew_rate,
            self.inductance,
            self.r_total,
            self.k_backemf,
            self.wn,
            v.k1,
            v.kf,
            v.kw,
            v.k2,
            v.k3,
            v.spool_area,
            v.zeta,
            v.f_n,
            v.x_flapper_max,
            v.x_spool_max,
            v.dp_rated,
            v.dp_laminar,
        ]
        .map(f64::to_bits)
    }
}
