//! The cylinder's parameters and state, below everything that computes with them (its terms
//! in [`super::cylinder_terms`], its rates in [`super::cylinder`], its linearisation): the
//! state's layout `[p_A, p_B, x, v]`, the hydraulic side's parameters with the rules
//! between them, the areas and the rod's travel, and the chambers' volume clamp.

use crate::components::metering_ports::MeteringPorts;
use crate::params::{CylinderLoadParams, ValveParams};
use crate::readable::readable;

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
/// valve's metering-port data, with the constants the equations derive from them.
/// Built by [`CylinderParams::new`] alone (the constants are private), so that they always
/// match `load`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CylinderParams {
    /// Cylinder, load, leakage and fluid.
    pub load: CylinderLoadParams,
    /// The valve's metering-port data.
    pub ports: MeteringPorts,
    derived: Derived,
}

/// What the equations derive from the cylinder's and load's parameters alone, computed once
/// when they are set rather than at every evaluation (the fixed-cost step linearises twice
/// per communication step), each by the expression its users evaluated before, so that the
/// results keep their bits.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Derived {
    area_a: f64,
    area_b: f64,
    half_stroke: f64,
    min_volume: f64,
    cavitation_band_top: f64,
    relief_opening: f64,
    relief_ceiling: f64,
    friction_excess: f64,
    v_stribeck_squared: f64,
    area_a_per_mass: f64,
    area_b_per_mass: f64,
    creep_band: f64,
    stribeck_tails: StribeckTails,
}

impl Derived {
    fn of(load: &CylinderLoadParams) -> Derived {
        let (area_a, area_b) = (load.area_a(), load.area_b());
        Derived {
            area_a,
            area_b,
            half_stroke: 0.5 * load.stroke,
            min_volume: MIN_VOLUME_FRACTION * load.v_dead,
            cavitation_band_top: load.p_cavitation + load.dp_cavitation_band,
            relief_opening: load.p_tank + load.relief_p_crack,
            relief_ceiling: if load.relief_p_crack != 0.0 {
                load.p_tank + load.relief_p_crack
            } else {
                f64::INFINITY
            },
            friction_excess: load.f_static - load.f_coulomb,
            v_stribeck_squared: load.v_stribeck * load.v_stribeck,
            area_a_per_mass: area_a / load.mass,
            area_b_per_mass: area_b / load.mass,
            creep_band: CREEP_BAND * load.v_friction_smooth,
            stribeck_tails: StribeckTails::of(load),
        }
    }
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
            ports: MeteringPorts::new(valve.k3, valve.dp_rated, valve.dp_laminar).with_leakage(
                valve.lap,
                valve.q_pilot,
                valve.datasheet.p_leak_ref,
            ),
            derived: Derived::of(cylinder),
        };
        p.validate()?;
        Ok(p)
    }

    /// These parameters with the cylinder and load replaced by `load` (not validated).
    #[cfg(test)]
    pub(crate) fn with_load(&self, load: CylinderLoadParams) -> CylinderParams {
        CylinderParams { load, ports: self.ports, derived: Derived::of(&load) }
    }

    /// Piston area on the A (cap) side (m2), [`CylinderLoadParams::area_a`].
    #[inline(always)]
    pub(crate) fn area_a(&self) -> f64 {
        self.derived.area_a
    }

    /// Annulus area on the B (rod) side (m2), [`CylinderLoadParams::area_b`].
    #[inline(always)]
    pub(crate) fn area_b(&self) -> f64 {
        self.derived.area_b
    }

    /// Half the stroke: the stops' faces are at `+-` this (m).
    #[inline(always)]
    pub(crate) fn half_stroke(&self) -> f64 {
        self.derived.half_stroke
    }

    /// The chambers' smallest volume, [`MIN_VOLUME_FRACTION`] of the dead volume (m3).
    #[inline(always)]
    pub(crate) fn min_volume(&self) -> f64 {
        self.derived.min_volume
    }

    /// The top of the cavitation band, `p_cavitation + dp_cavitation_band` (Pa).
    #[inline(always)]
    pub(crate) fn cavitation_band_top(&self) -> f64 {
        self.derived.cavitation_band_top
    }

    /// The relief valves' cracking pressure above the tank, `p_tank + relief_p_crack` (Pa).
    #[inline(always)]
    pub(crate) fn relief_opening(&self) -> f64 {
        self.derived.relief_opening
    }

    /// The pressure above which a chamber's relief valve opens: [`Self::relief_opening`],
    /// or infinity where there are no valves (one comparison tells a step that cannot reach
    /// a valve's law, with or without them).
    #[inline(always)]
    pub(crate) fn relief_ceiling(&self) -> f64 {
        self.derived.relief_ceiling
    }

    /// Whether the chambers have relief valves (`relief_p_crack` 0 removes them).
    #[inline(always)]
    pub(crate) fn has_relief(&self) -> bool {
        self.relief_p_crack != 0.0
    }

    /// The friction's Stribeck peak above the Coulomb level, `f_static - f_coulomb` (N).
    #[inline(always)]
    pub(crate) fn friction_excess(&self) -> f64 {
        self.derived.friction_excess
    }

    /// `v_stribeck^2` (m2/s2).
    #[inline(always)]
    pub(crate) fn v_stribeck_squared(&self) -> f64 {
        self.derived.v_stribeck_squared
    }

    /// The friction's creep band's half-width, `CREEP_BAND v_friction_smooth` (m/s).
    #[inline(always)]
    pub(crate) fn creep_band(&self) -> f64 {
        self.derived.creep_band
    }

    /// Which of the friction's Stribeck tails are lost in rounding ([`StribeckTails`]).
    #[inline(always)]
    pub(crate) fn stribeck_tails(&self) -> StribeckTails {
        self.derived.stribeck_tails
    }

    /// `(A_A / m, A_B / m)`: the rod's acceleration per unit of each chamber's pressure.
    #[inline(always)]
    pub(crate) fn areas_per_mass(&self) -> (f64, f64) {
        (self.derived.area_a_per_mass, self.derived.area_b_per_mass)
    }

    /// The rules between parameters.
    pub(crate) fn validate(&self) -> Result<(), String> {
        if !(self.ports.k3.is_finite() && self.ports.k3 > 0.0) {
            return Err(format!(
                "valve.K3 = {} rejected: must be positive",
                readable(self.ports.k3)
            ));
        }
        if self.rod >= self.bore {
            return Err(format!(
                "cylinder.rod = {} rejected: must be smaller than cylinder.bore = {}",
                readable(self.rod),
                readable(self.bore)
            ));
        }
        if self.p_cavitation >= self.p_tank {
            return Err(format!(
                "hydraulics.p_cavitation = {} rejected: must be below hydraulics.p_tank = {}",
                readable(self.p_cavitation),
                readable(self.p_tank)
            ));
        }
        Ok(())
    }

    /// The relief valves must be set above the supply, or they would open in normal
    /// operation (a chamber holds up to p_S at stall or on a stop).
    pub(crate) fn check_supply(&self, p_supply: f64) -> Result<(), String> {
        if self.relief_p_crack > 0.0 && p_supply - self.p_tank >= self.relief_p_crack {
            return Err(self.supply_refusal(p_supply));
        }
        Ok(())
    }

    /// [`CylinderParams::check_supply`]'s message. Cold and out of line: the check runs
    /// on every step.
    #[cold]
    #[inline(never)]
    fn supply_refusal(&self, p_supply: f64) -> String {
        format!(
            "p_supply = {} Pa is not below the relief valves' setting hydraulics.p_tank + \
             relief.p_crack = {} Pa: they would open in normal operation; raise \
             relief.p_crack, or set it to 0 to remove them",
            readable(p_supply),
            readable(self.relief_opening())
        )
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

/// Friction's creep band, in `cylinder.v_friction_smooth`: past this many its `tanh` is 1 to
/// rounding (tanh(20) = 1 - 8e-18), and a step outside it sees the friction's tangent.
const CREEP_BAND: f64 = 20.0;

/// `(s, b)`: for `stribeck > s` the computed `exp(-stribeck)` is below `b` (`e^-50 =
/// 1.93e-22`, with room for libm's rounding).
pub(crate) const STRIBECK_TAIL: (f64, f64) = (50.0, 2.0e-22);

/// Whether past [`STRIBECK_TAIL`] the friction's decayed part is lost in rounding: in the
/// force (below a quarter ulp of `F_coulomb`) and, where the smooth sign is saturated, in
/// the slope (below a quarter ulp of the viscous slope). They depend on the parameters
/// alone, so they are worked out once, with the other derived parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct StribeckTails {
    pub force_lost: bool,
    pub slope_lost: bool,
}

impl StribeckTails {
    pub(crate) fn of(load: &CylinderLoadParams) -> StribeckTails {
        let excess = load.f_static - load.f_coulomb;
        StribeckTails {
            force_lost: excess.abs() * STRIBECK_TAIL.1 <= load.f_coulomb * (0.25 * f64::EPSILON),
            slope_lost: excess.abs() * STRIBECK_SLOPE_TAIL / load.v_stribeck
                <= load.b_viscous.abs() * (0.25 * f64::EPSILON),
        }
    }
}

/// For `stribeck > STRIBECK_TAIL.0` the decayed part's slope `(F_s - F_c) d/dv
/// exp(-(v/v_s)^2)` is below `|F_s - F_c| / v_s` times this: `2 u exp(-u^2)`, `u = |v|/v_s`,
/// falls beyond `u^2 = 50`, where it is `2 sqrt(50) e^-50 = 2.73e-21` (with room for rounding).
const STRIBECK_SLOPE_TAIL: f64 = 3.0e-21;
