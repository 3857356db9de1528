//! Coil drivers with a continuous or algebraic output: the ideal current source, the
//! open-loop voltage driver, and the PI current loops of the op-amp driver (the paper's
//! proposal) and of the industrial amplifier. (The H-bridge is in [`super::hbridge`].)
//!
//! The PI drivers output `u = Kp (i_ref - i) + ui` with `ui' = Ki (i_ref - i)`, limited by
//! the rails `+-(V_supply - V_drop)` (the integrator stops while the output sits at a rail
//! and the error pushes further: anti-windup) and by the slew rate `|u'| <= S`. Each of
//! these situations is a *mode* with linear dynamics; the mode ends where one of its linear
//! guards turns positive.

use crate::components::coefficients::Coefficients;
use crate::components::hbridge::HBridgeState;
use crate::events::StepEvents;
use crate::numerics::augmented_state::{row_dot, unit, Mat, Vector, I, I_CMD, ONE, RAIL, U, UI};
use crate::params::DriverKind;

/// Driver modes. The PI drivers move between the last seven.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Mode {
    Ideal,
    Voltage,
    Linear,
    /// At the + rail, error pushing further up: integrator stopped (anti-windup).
    HighFrozen,
    /// At the + rail, error pulling back: integrator running.
    HighIntegrating,
    LowFrozen,
    LowIntegrating,
    SlewUp,
    SlewDown,
    /// H-bridge: output held at +V or -V between switching instants.
    Switched,
}

pub(crate) const MODES: [Mode; 10] = [
    Mode::Ideal,
    Mode::Voltage,
    Mode::Linear,
    Mode::HighFrozen,
    Mode::HighIntegrating,
    Mode::LowFrozen,
    Mode::LowIntegrating,
    Mode::SlewUp,
    Mode::SlewDown,
    Mode::Switched,
];

impl Mode {
    pub(crate) fn index(self) -> usize {
        self as usize
    }
    pub(crate) fn at_rail(self) -> bool {
        matches!(
            self,
            Mode::HighFrozen | Mode::HighIntegrating | Mode::LowFrozen | Mode::LowIntegrating
        )
    }
}

/// Rail voltage for a supply voltage (never negative).
pub(crate) fn rail(c: &Coefficients, v_supply: f64) -> f64 {
    (v_supply - c.v_drop).max(0.0)
}

/// The PI law's output at `z`, `u_lin_row(c) . z` written out: the same bits as that dot
/// product (its two lanes hold `-Kp i + Kp i_ref` and `ui`), without building the row.
#[inline]
pub(crate) fn u_lin(c: &Coefficients, z: &Vector) -> f64 {
    (c.kp * z[I_CMD] - c.kp * z[I]) + z[UI]
}

/// Row vector of u_lin = Kp (i_ref - i) + ui.
pub(crate) fn u_lin_row(c: &Coefficients) -> Vector {
    let mut r = Vector::zeros();
    r[I_CMD] = c.kp;
    r[I] = -c.kp;
    r[UI] = 1.0;
    r
}

/// Row vector of the current error i_ref - i.
fn error_row() -> Vector {
    unit(I_CMD) - unit(I)
}

/// Writes the driver rows of `z' = A z` (after the coil and valve rows: the linear mode's
/// `u' = -Kp i' + Ki e` reads the coil row).
pub(crate) fn driver_rows(c: &Coefficients, mode: Mode, a: &mut Mat) {
    let integrate = c.ki * error_row();
    match mode {
        Mode::Linear => {
            a.set_row(UI, &integrate.transpose());
            let i_row = a.row(I).into_owned();
            a.set_row(U, &(-c.kp * i_row + integrate.transpose()));
        }
        Mode::HighIntegrating | Mode::LowIntegrating => a.set_row(UI, &integrate.transpose()),
        Mode::Switched => {}
        Mode::SlewUp | Mode::SlewDown => {
            a.set_row(UI, &integrate.transpose());
            a[(U, ONE)] = slew_velocity(c, mode);
        }
        Mode::Ideal | Mode::Voltage | Mode::HighFrozen | Mode::LowFrozen => {}
    }
}

/// The output's rate in a slewing mode (V/s): the slew rate, up or down.
pub(crate) fn slew_velocity(c: &Coefficients, mode: Mode) -> f64 {
    if mode == Mode::SlewUp {
        c.slew_rate
    } else {
        -c.slew_rate
    }
}

/// Exit guards of a mode: the mode ends where any of them turns from <= 0 to > 0 (edge
/// triggered: a guard already positive when the mode starts is a condition that has been
/// passed, e.g. the + rail while slewing down from above it after a supply drop).
pub(crate) fn mode_guards(c: &Coefficients, mode: Mode, a: &Mat) -> Vec<Vector> {
    let u = unit(U);
    let vmax = unit(RAIL);
    let u_lin = u_lin_row(c);
    let e = error_row();
    let slew = c.slew_rate * unit(ONE);
    match mode {
        Mode::Ideal | Mode::Voltage | Mode::Switched => vec![],
        Mode::Linear => {
            let du = a.row(U).transpose();
            vec![u - vmax, -u - vmax, du - slew, -du - slew]
        }
        Mode::HighFrozen => vec![vmax - u_lin, -e],
        Mode::HighIntegrating => vec![vmax - u_lin, e],
        Mode::LowFrozen => vec![u_lin + vmax, e],
        Mode::LowIntegrating => vec![u_lin + vmax, -e],
        // Slewing ends where u meets clamp(u_lin, -vmax, vmax).
        Mode::SlewUp => vec![u - vmax, u - u_lin, u + vmax],
        Mode::SlewDown => vec![-u - vmax, u_lin - u, vmax - u],
    }
}

/// The linear mode's guards ([`mode_guards`]) at `z`, `a` its dynamics, written out: the
/// rails' pair reads two entries and the slew's pair one row of `a`, where the guards' dot
/// products read all nine entries of four rows. The same bits, as its `ONE` column is zero
/// (the law has no constant term; a test holds them to it).
#[inline]
pub(crate) fn linear_guard_values(c: &Coefficients, a: &Mat, z: &Vector) -> [f64; 4] {
    linear_guards_at_rate(c, z, output_rate(a, z))
}

/// [`linear_guard_values`] where the output's rate `du` ([`output_rate`]) is known.
#[inline]
pub(crate) fn linear_guards_at_rate(c: &Coefficients, z: &Vector, du: f64) -> [f64; 4] {
    [z[U] - z[RAIL], -z[U] - z[RAIL], du - c.slew_rate, -du - c.slew_rate]
}

/// The output's rate in the linear mode at `z`, `a` that mode's dynamics.
#[inline]
pub(crate) fn output_rate(a: &Mat, z: &Vector) -> f64 {
    row_dot(a, U, z)
}

/// How far (V) a PI driver's output may be from the law's value and still count as on it.
#[inline]
fn law_tolerance(vmax: f64) -> f64 {
    1e-9 * (1.0 + vmax)
}

/// Whether [`consistent_mode`] puts a PI driver at `z`, on the linear mode's manifold
/// (`z[U]` its law's value), in the linear mode, `du` the output's rate there in that mode
/// ([`output_rate`]): clear of the rails by more than its tolerance, and the output's rate
/// within the slew rate. Its tests in its order, for the one outcome (`false`: ask it).
#[inline]
pub(crate) fn surely_linear(c: &Coefficients, z: &Vector, du: f64) -> bool {
    let (vmax, u_lin) = (z[RAIL], u_lin(c, z));
    let tol = law_tolerance(vmax);
    // A NaN is not surely linear: the general way refuses it.
    u_lin < vmax - tol && u_lin > -vmax + tol && (-c.slew_rate..=c.slew_rate).contains(&du)
}

/// A PI driver's slew where its output at `z` is further than the tolerance from the law's
/// value (clamped to the rails): [`consistent_mode`]'s first tests. `None` within it.
#[inline]
pub(crate) fn slew_towards_law(c: &Coefficients, z: &Vector) -> Option<Mode> {
    let vmax = z[RAIL];
    let target = u_lin(c, z).clamp(-vmax, vmax);
    let tol = law_tolerance(vmax);
    if z[U] < target - tol {
        Some(Mode::SlewUp)
    } else if z[U] > target + tol {
        Some(Mode::SlewDown)
    } else {
        None
    }
}

/// The mode the driver is in at state `z` (`a_of`: each mode's system); on a boundary the
/// direction of motion decides, so a mode is never entered only to be left at once.
pub(crate) fn consistent_mode<'a>(
    c: &Coefficients,
    z: &Vector,
    a_of: impl Fn(Mode) -> &'a Mat,
) -> Mode {
    match c.driver {
        DriverKind::IdealCurrent => return Mode::Ideal,
        DriverKind::Voltage => return Mode::Voltage,
        DriverKind::HBridge => return Mode::Switched,
        DriverKind::OpampPi | DriverKind::Industrial => {}
    }
    if let Some(slew) = slew_towards_law(c, z) {
        return slew;
    }
    let vmax = z[RAIL];
    let e = z[I_CMD] - z[I];
    let u_lin = u_lin(c, z);
    let target = u_lin.clamp(-vmax, vmax);
    let tol = law_tolerance(vmax);
    let high = if e > 0.0 { Mode::HighFrozen } else { Mode::HighIntegrating };
    let low = if e < 0.0 { Mode::LowFrozen } else { Mode::LowIntegrating };
    let rate_in = |mode: Mode| {
        let mut at = *z;
        at[U] = target;
        u_lin_row(c).dot(&(a_of(mode) * at))
    };
    if u_lin > vmax + tol || (u_lin >= vmax - tol && rate_in(high) > 0.0) {
        return high;
    }
    if u_lin < -vmax - tol || (u_lin <= -vmax + tol && rate_in(low) < 0.0) {
        return low;
    }
    let mut at = *z;
    at[U] = u_lin;
    let du = row_dot(a_of(Mode::Linear), U, &at);
    if du > c.slew_rate {
        Mode::SlewUp
    } else if du < -c.slew_rate {
        Mode::SlewDown
    } else {
        Mode::Linear
    }
}

/// How long a slewing mode takes to bring the output to the PI law's value (clamped to the
/// rails) at the slew rate, were that value to stay where it is at `z`; `None` in the other
/// modes. An estimate: the law moves with the coil current meanwhile.
pub(crate) fn slew_time(c: &Coefficients, mode: Mode, z: &Vector) -> Option<f64> {
    matches!(mode, Mode::SlewUp | Mode::SlewDown).then(|| {
        let target = u_lin(c, z).clamp(-z[RAIL], z[RAIL]);
        (target - z[U]).abs() / c.slew_rate
    })
}

/// Takes back what a whole step in `mode` carried the output past the end of that mode: a
/// slew past its target (the PI law's value clamped to the rails), a linear output past a
/// rail. A stepper that decides modes only at step boundaries calls it before
/// [`consistent_mode`], which would otherwise read the overshoot as a slew the other way.
/// `ended`: a slew's end was placed here (to within the placement's error, either side): the
/// output takes its target.
pub(crate) fn clip_overshoot(c: &Coefficients, z: &mut Vector, mode: Mode, ended: bool) {
    let vmax = z[RAIL];
    let target = || u_lin(c, z).clamp(-vmax, vmax);
    match mode {
        Mode::SlewUp | Mode::SlewDown if ended => z[U] = target(),
        Mode::SlewUp => z[U] = z[U].min(target()),
        Mode::SlewDown => z[U] = z[U].max(target()),
        Mode::Linear => z[U] = z[U].clamp(-vmax, vmax),
        _ => {}
    }
}

/// Puts the algebraic part of the state on the mode's manifold (after every propagation
/// too, so held values stay exact rather than within rounding of exp()).
pub(crate) fn project_onto(c: &Coefficients, hbridge: &HBridgeState, z: &mut Vector, mode: Mode) {
    match mode {
        Mode::Ideal => z[I] = z[I_CMD],
        Mode::Voltage => z[U] = (c.r_total * z[I_CMD]).clamp(-z[RAIL], z[RAIL]),
        Mode::Switched => z[U] = hbridge.output(&c.hbridge, z[RAIL]),
        Mode::Linear => z[U] = u_lin(c, z),
        Mode::HighFrozen | Mode::HighIntegrating => z[U] = z[RAIL],
        Mode::LowFrozen | Mode::LowIntegrating => z[U] = -z[RAIL],
        Mode::SlewUp | Mode::SlewDown => {}
    }
}

/// Applies the inputs held over the coming step: the algebraic drivers follow them at once.
pub(crate) fn apply_inputs(c: &Coefficients, z: &mut Vector, i_ref: f64, rail: f64) {
    z[I_CMD] = i_ref;
    z[RAIL] = rail;
    match c.driver {
        // The ideal source's voltage is what holds the current (its L di/dt impulse aside).
        DriverKind::IdealCurrent => z[U] = c.r_total * i_ref,
        DriverKind::Voltage
        | DriverKind::HBridge
        | DriverKind::OpampPi
        | DriverKind::Industrial => {}
    }
}

/// The driver output is at a supply rail.
pub(crate) fn saturated(c: &Coefficients, mode: Mode, hbridge: &HBridgeState, z: &Vector) -> bool {
    match mode {
        Mode::Voltage => (c.r_total * z[I_CMD]).abs() > z[RAIL],
        Mode::Switched => hbridge.saturated(z[RAIL]),
        m => m.at_rail(),
    }
}

/// Counts rail entries and exits for event logging.
pub(crate) fn count_switch(events: &mut StepEvents, from: Mode, to: Mode) {
    if !from.at_rail() && to.at_rail() {
        events.rail_entered += 1;
    }
    if from.at_rail() && !to.at_rail() {
        events.rail_left += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The written-out guards of the linear mode give the guards' dot products bit for bit,
    /// for both PI drivers, on and off the rails.
    #[test]
    fn the_linear_modes_guards_written_out_are_its_guards() {
        for driver in [DriverKind::OpampPi, DriverKind::Industrial] {
            let c = Coefficients::new(&crate::params::Params {
                driver,
                ..crate::params::Params::PAPER
            })
            .unwrap();
            let sys = crate::actuator::mode_system(&c, Mode::Linear);
            assert_eq!(sys.a[(U, ONE)], 0.0);
            for k in 0..50 {
                let x = k as f64;
                let z = Vector::from_fn(|i, _| match i {
                    ONE => 1.0,
                    RAIL => 72.0,
                    _ => {
                        (x * (i as f64 + 1.3)).sin() * [1e-2, 30.0, 80.0, 1e-5, 1e-2, 1e-4, 1e-2][i]
                    }
                });
                let generic: Vec<f64> = (0..sys.n_guards).map(|g| sys.guard_value(g, &z)).collect();
                let written = linear_guard_values(&c, &sys.a, &z);
                assert_eq!(generic.len(), 4);
                for (g, w) in generic.iter().zip(written) {
                    assert_eq!(g.to_bits(), w.to_bits(), "{driver:?} z = {z:?}");
                }
            }
        }
    }

    #[test]
    fn rail_guards_of_the_linear_mode_bound_the_output() {
        let c = Coefficients::new(&crate::params::Params::PAPER).unwrap();
        let mut z = Vector::zeros();
        z[RAIL] = 72.0;
        z[ONE] = 1.0;
        let guards = mode_guards(&c, Mode::Linear, &Mat::zeros());
        z[U] = 71.0;
        assert!(guards[0].dot(&z) < 0.0 && guards[1].dot(&z) < 0.0);
        z[U] = 73.0;
        assert!(guards[0].dot(&z) > 0.0, "above the + rail the linear mode ends");
        assert_eq!(rail(&c, 72.0), 72.0);
    }
}
