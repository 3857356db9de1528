//! The cylinder's parameters and state, below everything that computes with them (its terms
//! in [`super::cylinder_terms`], its rates in [`super::cylinder`], its linearisation): the
//! state's layout `[p_A, p_B, x, v]`, the hydraulic side's parameters with the rules
//! between them, the areas and the rod's travel, and the chambers' volume clamp.

use crate::components::metering_ports::MeteringPorts;
use crate::params::{CylinderLoadParams, ValveParams};

/// Chamber volumes never shrink below this fraction of the dead volume (keeps the pressure
/// equations finite). Reaching it means the piston went through the end of the cylinder:
/// [`super::cylinder::check_inside`] refuses such a state.
pub(crate) const MIN_VOLUME_FRACTION: f64 = 1e-3;

/// Number of states: `[p_A, p_B, x, v]`.
pub(crate) const N_STATES: usize = 4;
pub(crate) const PA: usize = 0;
pub(crate) const PB: usize = 1;
pub(crate) const X: usize = 2;
pub(crate) const V: usize = 3;

pub(crate) type Vec4 = [f64; N_STATES];
pub(crate) type Mat4 = [[f64; N_STATES]; N_STATES];

/// Physical parameters of valve ports, cylinder and load, in SI (pressures gauge): the
/// cylinder, load and fluid as the model gives them (reached through `Deref`) and the
/// valve's metering-port data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CylinderParams {
    /// Cylinder, load, leakage and fluid.
    pub load: CylinderLoadParams,
    /// The valve's metering-port data.
    pub ports: MeteringPorts,
}

impl std::ops::Deref for CylinderParams {
    type Target = CylinderLoadParams;

    fn deref(&self) -> &CylinderLoadParams {
        &self.load
    }
}

#[cfg(test)]
impl Default for CylinderParams {
    /// The paper's device ([`crate::params::Params::PAPER`]).
    fn default() -> Self {
        let p = crate::params::Params::PAPER;
        CylinderParams::new(&p.cylinder, &p.valve).expect("start values are valid")
    }
}

impl CylinderParams {
    /// The hydraulic side's parameters: cylinder, load and fluid, with the valve's
    /// metering-port data. Checks the rules between parameters (single values were
    /// checked against their ranges at the model boundary).
    pub(crate) fn new(
        cylinder: &CylinderLoadParams,
        valve: &ValveParams,
    ) -> Result<CylinderParams, String> {
        let p = CylinderParams {
            load: *cylinder,
            ports: MeteringPorts {
                k3: valve.k3,
                dp_rated: valve.dp_rated,
                dp_laminar: valve.dp_laminar,
            },
        };
        p.validate()?;
        Ok(p)
    }

    /// The rules between parameters.
    pub(crate) fn validate(&self) -> Result<(), String> {
        if !(self.ports.k3.is_finite() && self.ports.k3 > 0.0) {
            return Err(format!("valve.K3 = {} rejected: must be positive", self.ports.k3));
        }
        if self.rod >= self.bore {
            return Err(format!(
                "cylinder.rod = {} rejected: must be smaller than cylinder.bore = {}",
                self.rod, self.bore
            ));
        }
        if self.p_cavitation >= self.p_tank {
            return Err(format!(
                "hydraulics.p_cavitation = {} rejected: must be below hydraulics.p_tank = {}",
                self.p_cavitation, self.p_tank
            ));
        }
        Ok(())
    }

    /// The relief valves must be set above the supply, or they would open in normal
    /// operation (a chamber holds up to p_S at stall or on a stop).
    pub(crate) fn check_supply(&self, p_supply: f64) -> Result<(), String> {
        if self.relief_p_crack > 0.0 && p_supply - self.p_tank >= self.relief_p_crack {
            return Err(format!(
                "p_supply = {p_supply} Pa is not below the relief valves' setting \
                 hydraulics.p_tank + relief.p_crack = {} Pa: they would open in normal \
                 operation; raise relief.p_crack, or set it to 0 to remove them",
                self.p_tank + self.relief_p_crack
            ));
        }
        Ok(())
    }

    #[cfg(test)]
    /// Extension stall force p_S*A_A (B at tank) (N).
    pub(crate) fn stall_force(&self, p_supply: f64) -> f64 {
        (p_supply - self.p_tank) * self.area_a()
    }
}

/// Chamber pressures (Pa, gauge), piston position (m) and velocity (m/s).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct CylinderState {
    pub p_a: f64,
    pub p_b: f64,
    pub x: f64,
    pub v: f64,
}

impl CylinderState {
    pub(crate) fn to_array(self) -> [f64; N_STATES] {
        [self.p_a, self.p_b, self.x, self.v]
    }
    pub(crate) fn from_array(y: &[f64; N_STATES]) -> CylinderState {
        CylinderState { p_a: y[PA], p_b: y[PB], x: y[X], v: y[V] }
    }
}

impl CylinderLoadParams {
    /// Piston area on the A (cap) side (m2).
    pub fn area_a(&self) -> f64 {
        std::f64::consts::FRAC_PI_4 * self.bore * self.bore
    }

    /// Annulus area on the B (rod) side (m2).
    pub fn area_b(&self) -> f64 {
        self.area_a() - std::f64::consts::FRAC_PI_4 * self.rod * self.rod
    }

    /// The rod positions the chambers allow (m): the stroke and, beyond each end, the end
    /// stop's deepest penetration before the chamber's volume reaches its clamp
    /// (a state beyond is refused).
    pub fn rod_travel(&self) -> (f64, f64) {
        let depth = (1.0 - MIN_VOLUME_FRACTION) * self.v_dead;
        let half = 0.5 * self.stroke;
        (-half - depth / self.area_a(), half + depth / self.area_b())
    }
}
