//! Moog 30 two-stage servo valve.
//!
//! * First stage (torque motor, flapper, nozzles) as a second-order system:
//!   `x_f'' + 2 zeta wn x_f' + wn^2 x_f = wn^2 (K1 i - Kw x_s) / Kf`.
//! * Spool, moved by the hydraulic amplifier: `x_s' = (K2 / A_s) x_f`.
//! * Optional travel stops (`valve.x_flapper_max`, `valve.x_spool_max`; the paper's linear
//!   model has none): a part reaching its limit is held there (inelastic impact) while it is
//!   driven outwards, and leaves when the drive turns back.
//! * Metering ports (critically centred): the orifice law of [`super::metering_ports`], which
//!   feeds the cylinder ([`super::cylinder`]).

use crate::components::coefficients::Coefficients;
use crate::numerics::augmented_state::{unit, Mat, Vector, I, ONE, VF, XF, XS};
use crate::numerics::root_finding::newton_in_bracket;

/// Writes the first-stage and spool rows of `z' = A z`.
pub(crate) fn valve_rows(c: &Coefficients, a: &mut Mat) {
    let wn2 = c.wn * c.wn;
    a[(XF, VF)] = 1.0;
    a[(VF, XF)] = -wn2;
    a[(VF, VF)] = -2.0 * c.valve.zeta * c.wn;
    a[(VF, I)] = wn2 * c.valve.k1 / c.valve.kf;
    a[(VF, XS)] = -wn2 * c.valve.kw / c.valve.kf;
    a[(XS, XF)] = c.valve.k2 / c.valve.spool_area;
}

/// Flapper and spool at a travel stop: -1 lower, 0 free, +1 upper.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Stops {
    pub flapper: i8,
    pub spool: i8,
}

impl Stops {
    pub(crate) fn code(self) -> usize {
        ((self.flapper + 1) * 3 + self.spool + 1) as usize
    }

    /// Inverse of [`Stops::code`].
    pub(crate) fn from_code(code: u8) -> Result<Stops, String> {
        if code > 8 {
            return Err(format!("state has unknown valve stop code {code}"));
        }
        let code = code as i8;
        Ok(Stops { flapper: code / 3 - 1, spool: code % 3 - 1 })
    }
}

/// Whether the valve has travel stops at all.
pub(crate) fn has_stops(c: &Coefficients) -> bool {
    c.valve.x_flapper_max > 0.0 || c.valve.x_spool_max > 0.0
}

/// Holds the parts at a stop: their rows of `z' = A z` are zeroed.
pub(crate) fn hold_at_stops(stops: Stops, a: &mut Mat) {
    if stops.flapper != 0 {
        a.row_mut(XF).fill(0.0);
        a.row_mut(VF).fill(0.0);
    }
    if stops.spool != 0 {
        a.row_mut(XS).fill(0.0);
    }
}

/// The stop guards: for a free part, reaching either stop; for a held part, the drive
/// turning back. `flapper_accel` is the free system's flapper acceleration row.
pub(crate) fn stop_guards(
    c: &Coefficients,
    stops: Stops,
    flapper_accel: Vector,
    mut push_guard: impl FnMut(Vector),
) {
    let one = unit(ONE);
    if c.valve.x_flapper_max > 0.0 {
        match stops.flapper {
            0 => {
                push_guard(unit(XF) - c.valve.x_flapper_max * one);
                push_guard(-unit(XF) - c.valve.x_flapper_max * one);
            }
            // Leaves the stop when the torque pulls it back.
            side => push_guard(-(side as f64) * flapper_accel),
        }
    }
    if c.valve.x_spool_max > 0.0 {
        match stops.spool {
            0 => {
                push_guard(unit(XS) - c.valve.x_spool_max * one);
                push_guard(-unit(XS) - c.valve.x_spool_max * one);
            }
            // Leaves the stop when the flapper drives it back.
            side => push_guard(-(side as f64) * unit(XF)),
        }
    }
}

/// Puts `z` on the stops: an inelastic impact takes the flapper's outward velocity at its
/// limit; then the stops consistent with `z` (`free_a`: the system without stops) hold their
/// parts at the limit.
pub(crate) fn settle_stops(c: &Coefficients, free_a: &Mat, z: &mut Vector) -> Stops {
    if !has_stops(c) {
        return Stops::default(); // no travel stops (the default): nothing to settle
    }
    let reach = c.valve.x_flapper_max * (1.0 - 1e-12);
    if c.valve.x_flapper_max > 0.0
        && (z[XF] >= reach && z[VF] > 0.0 || z[XF] <= -reach && z[VF] < 0.0)
    {
        z[XF] = z[XF].clamp(-c.valve.x_flapper_max, c.valve.x_flapper_max);
        z[VF] = 0.0;
    }
    let stops = consistent_stops(c, free_a, z);
    if stops.flapper != 0 {
        z[XF] = stops.flapper as f64 * c.valve.x_flapper_max;
        z[VF] = 0.0;
    }
    if stops.spool != 0 {
        z[XS] = stops.spool as f64 * c.valve.x_spool_max;
    }
    stops
}

/// Which travel stops hold the valve at `z`: a part at its limit stays there while it is
/// driven outwards (flapper: its free acceleration; spool: the flapper's sign).
fn consistent_stops(c: &Coefficients, free_a: &Mat, z: &Vector) -> Stops {
    let mut at_rest = *z;
    at_rest[VF] = 0.0;
    let flapper_accel = free_a.row(VF).transpose().dot(&at_rest);
    let side = |x: f64, limit: f64, drive: f64| -> i8 {
        let reach = limit * (1.0 - 1e-12);
        if limit <= 0.0 {
            0
        } else if x >= reach && drive > 0.0 {
            1
        } else if x <= -reach && drive < 0.0 {
            -1
        } else {
            0
        }
    };
    Stops {
        flapper: side(z[XF], c.valve.x_flapper_max, flapper_accel),
        spool: side(z[XS], c.valve.x_spool_max, z[XF]),
    }
}

/// Static equilibrium for a coil current: torque balance K1 i = Kw x_s + Kf x_f with the
/// flapper centred, unless the spool sits at its stop and the flapper carries the rest.
/// Returns (x_f, x_s).
pub(crate) fn equilibrium(c: &Coefficients, i_coil: f64) -> (f64, f64) {
    let free_spool = c.valve.k1 * i_coil / c.valve.kw;
    let x_s = if c.valve.x_spool_max > 0.0 {
        free_spool.clamp(-c.valve.x_spool_max, c.valve.x_spool_max)
    } else {
        free_spool
    };
    let flapper = (c.valve.k1 * i_coil - c.valve.kw * x_s) / c.valve.kf;
    let x_f = if c.valve.x_flapper_max > 0.0 {
        flapper.clamp(-c.valve.x_flapper_max, c.valve.x_flapper_max)
    } else {
        flapper
    };
    (x_f, x_s)
}

/// The paper's no-load flow of the hydraulic amplifier, K3 x_s.
pub(crate) fn no_load_flow(c: &Coefficients, x_s: f64) -> f64 {
    c.valve.k3 * x_s
}

/// The spool path over one call: the quintic Hermite interpolant through position, rate
/// and acceleration at both ends of `[0, h]` (the physics core knows them exactly), kept as
/// a polynomial in `s = tau / h` (the integrator evaluates it at every stage).
#[derive(Clone, Copy, Debug)]
pub(crate) struct SpoolPath {
    pub h: f64,
    /// Position = sum of `coef[k] s^k`.
    coef: [f64; 6],
    /// The end position as given (the polynomial's sum at s = 1 may differ by rounding).
    end: f64,
}

impl SpoolPath {
    /// The quintic through `start` and `end`, each `[position, rate, acceleration]`.
    pub(crate) fn new(h: f64, start: [f64; 3], end: [f64; 3]) -> SpoolPath {
        // Derivatives with respect to s are h and h^2 times those in time.
        let (x0, v0, a0) = (start[0], h * start[1], h * h * start[2]);
        let (x1, v1, a1) = (end[0], h * end[1], h * h * end[2]);
        // What the quadratic start leaves at s = 1 in value, slope and curvature.
        let d0 = x1 - x0 - v0 - 0.5 * a0;
        let d1 = v1 - v0 - a0;
        let d2 = a1 - a0;
        let coef = [
            x0,
            v0,
            0.5 * a0,
            10.0 * d0 - 4.0 * d1 + 0.5 * d2,
            -15.0 * d0 + 7.0 * d1 - d2,
            6.0 * d0 - 3.0 * d1 + 0.5 * d2,
        ];
        SpoolPath { h, coef, end: x1 }
    }

    pub(crate) fn position(&self, tau: f64) -> f64 {
        let s = tau / self.h;
        self.coef.iter().rev().fold(0.0, |acc, c| acc * s + c)
    }

    /// d/dtau of [`SpoolPath::position`].
    pub(crate) fn rate(&self, tau: f64) -> f64 {
        let s = tau / self.h;
        let c = &self.coef;
        (c[1] + s * (2.0 * c[2] + s * (3.0 * c[3] + s * (4.0 * c[4] + s * 5.0 * c[5])))) / self.h
    }

    /// Where the spool passes `level` inside `(0, h)`, if its ends lie on opposite sides:
    /// safeguarded Newton on the path, to rounding. The time returned is the first one
    /// found on the far side's port law ([`super::metering_ports`] reads a kink's level as
    /// the law above it: `x_s = 0` opens P -> A), so the piece that starts there is
    /// linearised on the branch it runs on: the flows are continuous at a kink but their
    /// slope in `x_s` is not.
    ///
    /// Inlined, the search out of line: most pieces end on the side they start on.
    #[inline(always)]
    pub(crate) fn level_crossing(&self, level: f64) -> Option<f64> {
        let (x0, x1) = (self.coef[0] - level, self.end - level);
        if x0 * x1 >= 0.0 {
            return None;
        }
        self.crossing_between(level, (x0, x1))
    }

    /// [`SpoolPath::level_crossing`] for ends `x0`, `x1` (from `level`) of opposite signs.
    #[inline(never)]
    fn crossing_between(&self, level: f64, (x0, x1): (f64, f64)) -> Option<f64> {
        let rising = x1 > 0.0;
        let (_, t) = newton_in_bracket(
            |t| (self.position(t) - level, self.rate(t)),
            |x| if rising { x >= 0.0 } else { x < 0.0 },
            (0.0, self.h),
            self.h * x0 / (x0 - x1),
            4.0 * f64::EPSILON,
        );
        (t > 1e-9 * self.h && t < (1.0 - 1e-9) * self.h).then_some(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spool_path_rate_is_the_derivative_of_its_position() {
        let (start, end) = ([1.0e-4, 0.3, -2.0e3], [1.3e-4, 0.1, 5.0e3]);
        let path = SpoolPath::new(1e-4, start, end);
        for tau in [0.0, 0.1, 0.5, 0.77, 1.0].map(|s| s * path.h) {
            let d = 1e-6 * path.h;
            let fd = (path.position(tau + d) - path.position(tau - d)) / (2.0 * d);
            assert!(
                (path.rate(tau) - fd).abs() < 1e-8 * 0.3,
                "tau {tau}: {} vs {fd}",
                path.rate(tau)
            );
        }
        assert!(
            (path.position(0.0) - start[0]).abs() < 1e-18
                && (path.position(path.h) - end[0]).abs() < 1e-18
        );
        assert!((path.rate(0.0) - start[1]).abs() < 1e-15);
        assert!((path.rate(path.h) - end[1]).abs() < 1e-14);
    }

    #[test]
    fn spool_path_null_crossing_is_the_root_of_the_path() {
        // x(t) = a + b t + c t^2 (the quintic reproduces it): root (-b + sqrt(b^2 - 4ac))/(2c).
        let (a, b, c, h) = (-2.0e-5, 0.5, -1.0e3, 1e-4);
        let x = |t: f64| [a + b * t + c * t * t, b + 2.0 * c * t, 2.0 * c];
        let path = SpoolPath::new(h, x(0.0), x(h));
        let root = (-b + (b * b - 4.0 * a * c).sqrt()) / (2.0 * c);
        assert!(root > 0.0 && root < h);
        let found = path.level_crossing(0.0).expect("the ends lie on opposite sides");
        assert!((found - root).abs() < 1e-12 * h, "{found} vs {root}");
        // The piece after the split starts on the far side's law: P -> A rising (x_s >= 0),
        // P -> B falling (x_s < 0).
        assert!(path.position(found) >= 0.0);
        let falling = SpoolPath::new(h, x(0.0).map(|v| -v), x(h).map(|v| -v));
        assert!(falling.position(falling.level_crossing(0.0).expect("crosses")) < 0.0);
        // Ends on the same side (or one end at null): nothing to split.
        assert_eq!(SpoolPath::new(h, x(0.0), x(0.5 * root)).level_crossing(0.0), None);
        assert_eq!(SpoolPath::new(h, [0.0, b, 0.0], x(h)).level_crossing(0.0), None);
    }
}
