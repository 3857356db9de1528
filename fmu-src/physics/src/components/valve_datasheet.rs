//! The valve from its datasheet: the gains of the Moog 30 model worked out from the figures a
//! servo-valve catalogue states (rated flow and current, the -90 degree and -3 dB
//! frequencies, null leakage and pressure gain), once, when the coefficients are built; and
//! the same figures read back from any valve's gains (the calculated parameters
//! `valve.derived.*`). docs/model.md gives the formulas.
//!
//! With an ideal current source the valve's small-signal flow is
//! `Q/i = K / (1 + tau s (s^2/wn^2 + 2 zeta s/wn + 1))`, `K = K3 K1/Kw`, `tau = A_s Kf/(Kw K2)`.
//! At `s = j W` the denominator is `D = 1 - 2 zeta tau W^2/wn + j W tau (1 - W^2/wn^2)`: the
//! flow lags 90 degrees where its real part vanishes, `W90^2 = wn/(2 zeta tau)`, and its
//! amplitude is 3 dB down where `|D|^2 = 2`.

use crate::params::{ValveDatasheet, ValveParameterization, ValveParams, VALVE_RATED_CURRENT};
use crate::readable::readable as r;
use std::f64::consts::PI;

/// The Moog 30's spool stroke at its rated current (m), `K1 i_r / Kw` of the paper's gains.
/// A datasheet does not state the stroke, and the flow sees only `K3` times it: a datasheet
/// valve keeps this stroke, so that its spool moves as far as the paper's.
pub(crate) const RATED_STROKE: f64 = 2.82462 * VALVE_RATED_CURRENT / 74.2853;

/// The paper's first stage: its natural frequency over the spool loop's bandwidth, `wn tau`
/// (2 pi 814 Hz times `A_s Kf/(Kw K2)`), which a datasheet valve given no -3 dB frequency
/// keeps.
pub(crate) const PAPER_WN_TAU: f64 =
    2.0 * PI * 814.0 * (1.67742e-5 * 511.545) / (74.2853 * 0.0967740);

/// The fastest first stage the model takes (Hz): `valve.f_n`'s maximum.
pub const MAX_FIRST_STAGE_HZ: f64 = 1.0e5;
/// The largest hydraulic-amplifier gain K2 (m2/s): `valve.K2`'s maximum.
pub const MAX_AMPLIFIER_GAIN: f64 = 10.0;
/// The largest lap, either way (m): a spool's stroke is a few millimetres.
pub const MAX_LAP: f64 = 1.0e-3;
/// The datasheet frequencies' range (Hz): from 1 Hz to ten times the fastest servo valve's.
pub const DATASHEET_HZ: (f64, f64) = (1.0, 1.0e4);

/// What a valve's gains amount to, in a datasheet's terms (the calculated parameters).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ValveFigures {
    pub k1: f64,
    pub kw: f64,
    pub k2: f64,
    pub k3: f64,
    /// First-stage natural frequency (Hz).
    pub f_n: f64,
    /// The spool loop's time constant `A_s Kf/(Kw K2)` (s).
    pub tau: f64,
    /// Where the flow lags 90 degrees (Hz); 0 where it never does (no damping).
    pub f_90: f64,
    /// Where the flow's amplitude is 3 dB down (Hz).
    pub f_3db: f64,
    /// The spool's lap (m).
    pub lap: f64,
    /// Null leakage at the reference supply (m3/s): the lap's and the pilot's.
    pub q_leak_null: f64,
    /// The first stage's pilot flow at the reference supply (m3/s).
    pub q_pilot: f64,
    /// Blocked-port pressure gain at null at the reference supply (Pa/A); 0 where it is
    /// unbounded (a lap of 0 or an overlap).
    pub pressure_gain: f64,
}

/// The valve with its gains in place: in gains form the parameters as given (bit for bit),
/// in datasheet form the gains, the lap and the pilot flow worked out from the figures.
/// Refuses figures no valve of this structure has, naming them.
pub(crate) fn resolve(v: &ValveParams) -> Result<ValveParams, String> {
    match v.parameterization {
        ValveParameterization::Gains => {
            datasheet_figures_unset(&v.datasheet)?;
            Ok(*v)
        }
        ValveParameterization::Datasheet => from_datasheet(v),
    }
}

/// The figures of a valve whose gains are in place ([`resolve`]d).
pub(crate) fn figures(v: &ValveParams) -> ValveFigures {
    let tau = v.spool_area * v.kf / (v.kw * v.k2);
    let wn = 2.0 * PI * v.f_n;
    let w90 = (wn / (2.0 * v.zeta * tau)).sqrt();
    let p_ref = v.datasheet.p_leak_ref;
    let lap_leak = lap_leakage_per_metre(v.k3, p_ref, v.dp_rated) * v.lap.max(0.0);
    ValveFigures {
        k1: v.k1,
        kw: v.kw,
        k2: v.k2,
        k3: v.k3,
        f_n: v.f_n,
        tau,
        f_90: if w90.is_finite() { w90 / (2.0 * PI) } else { 0.0 },
        f_3db: first_3db_crossing(wn, tau, v.zeta) / (2.0 * PI),
        lap: v.lap,
        q_leak_null: lap_leak + v.q_pilot,
        q_pilot: v.q_pilot,
        pressure_gain: if v.lap > 0.0 { 2.0 * p_ref * v.k1 / (v.kw * v.lap) } else { 0.0 },
    }
}

/// In gains form the datasheet's own figures are not read: one set to anything but its
/// start value is a mistake worth an Error, not a figure silently ignored.
fn datasheet_figures_unset(d: &ValveDatasheet) -> Result<(), String> {
    let start = crate::params::Params::PAPER.valve.datasheet;
    let named = [
        ("valve.Q_rated", d.q_rated, start.q_rated),
        ("valve.i_rated", d.i_rated, start.i_rated),
        ("valve.f_90", d.f_90, start.f_90),
        ("valve.f_3dB", d.f_3db, start.f_3db),
        ("valve.Q_leak_null", d.q_leak_null, start.q_leak_null),
        ("valve.pressure_gain", d.pressure_gain, start.pressure_gain),
    ];
    match named.iter().find(|(_, value, start)| value.to_bits() != start.to_bits()) {
        None => Ok(()),
        Some((name, value, _)) => Err(format!(
            "{name} = {} is a datasheet figure, but valve.parameterization = gains does not \
             read it: set valve.parameterization = datasheet, or leave {name} at its start value",
            r(*value)
        )),
    }
}

/// The gains, lap and pilot flow from the datasheet's figures (module documentation).
fn from_datasheet(v: &ValveParams) -> Result<ValveParams, String> {
    let d = &v.datasheet;
    let (wn, tau) = first_stage(d.f_90, d.f_3db, v.zeta)?;
    let f_n = wn / (2.0 * PI);
    let k2 = v.spool_area * v.kf / (v.kw * tau);
    if f_n > MAX_FIRST_STAGE_HZ || k2 > MAX_AMPLIFIER_GAIN {
        return Err(format!(
            "valve.f_90 = {} Hz and valve.f_3dB = {} Hz (valve.zeta = {}) need a first stage \
             at {} Hz with K2 = {} m2/s (A_s Kf/(Kw tau), tau = {} s): beyond {} Hz or {} m2/s, \
             where this model of a valve ends",
            r(d.f_90),
            r(d.f_3db),
            r(v.zeta),
            r(f_n),
            r(k2),
            r(tau),
            r(MAX_FIRST_STAGE_HZ),
            r(MAX_AMPLIFIER_GAIN)
        ));
    }
    let k1 = v.kw * RATED_STROKE / d.i_rated;
    let k3 = d.q_rated / RATED_STROKE;
    let (lap, q_pilot) = lap_and_pilot(v, k1, k3)?;
    Ok(ValveParams { k1, k2, k3, f_n, lap, q_pilot, ..*v })
}

/// The first stage's natural frequency `wn` (rad/s) and the spool loop's time constant
/// `tau` (s) that put the -90 degree point at `f_90` and the -3 dB point at `f_3db` (0: the
/// paper's `wn tau`), the damping `zeta` given.
fn first_stage(f_90: f64, f_3db: f64, zeta: f64) -> Result<(f64, f64), String> {
    if zeta <= 0.0 {
        return Err(format!(
            "valve.zeta = {}: a valve set from its datasheet needs a damped first stage \
             (valve.zeta > 0), else its flow never lags 90 degrees",
            r(zeta)
        ));
    }
    let w90 = 2.0 * PI * f_90;
    if f_3db == 0.0 {
        // wn tau kept: W90^2 = wn/(2 zeta tau) = wn^2/(2 zeta wn tau).
        let q = (2.0 * zeta * PAPER_WN_TAU).sqrt();
        if q <= 1.0 {
            return Err(format!(
                "valve.zeta = {} with valve.f_3dB not given (the paper's wn tau = {}) puts the \
                 -90 degree point above the first stage: valve.zeta must exceed {}, or give \
                 valve.f_3dB",
                r(zeta),
                r(significant(PAPER_WN_TAU)),
                r(significant(0.5 / PAPER_WN_TAU))
            ));
        }
        let wn = q * w90;
        return Ok((wn, PAPER_WN_TAU / wn));
    }
    let r = f_3db / f_90;
    // wn = q W90 and tau = wn/(2 zeta W90^2) put the -90 degree point at W90 for any q > 1;
    // |D(j r W90)|^2 = 2 reads (1 - r^2)^2 + (r/(2 zeta))^2 (q - r^2/q)^2 = 2.
    let room = 2.0 - (1.0 - r * r).powi(2);
    let s = if room > 0.0 { room.sqrt() * 2.0 * zeta / r } else { f64::NAN };
    let roots = [1.0, -1.0].map(|sign| 0.5 * (sign * s + (s * s + 4.0 * r * r).sqrt()));
    let fits = |q: f64| {
        let (wn, tau) = (q * w90, q * w90 / (2.0 * zeta * w90 * w90));
        // The -3 dB point must be the first crossing, where the datasheet reads it.
        (q > 1.0 && (first_3db_crossing(wn, tau, zeta) / (r * w90) - 1.0).abs() < 1e-9)
            .then_some((wn, tau))
    };
    roots.into_iter().find_map(fits).ok_or_else(|| no_such_valve(f_90, f_3db, zeta))
}

/// The refusal of a -90 degree and -3 dB pair that no valve of this structure has, with the
/// ratios that one can have at this damping.
#[cold]
fn no_such_valve(f_90: f64, f_3db: f64, zeta: f64) -> String {
    let (lo, hi) = possible_ratios(zeta, MAX_FIRST_STAGE_HZ / f_90);
    // Within the variables' own ranges: f_90 from DATASHEET_HZ's lower end, f_3dB from 0.
    let within = |a: f64, b: f64, floor: f64| {
        let (a, b) = (a.max(floor), b.min(DATASHEET_HZ.1));
        format!("({}, {})", r(significant(a)), r(significant(b)))
    };
    format!(
        "valve.f_3dB = {} Hz with valve.f_90 = {} Hz and valve.zeta = {}: no valve of this \
         structure (torque motor, first stage, spool loop) has both. At this damping \
         f_3dB/f_90 lies in ({}, {}): with this f_90, valve.f_3dB in {} Hz; with this f_3dB, \
         valve.f_90 in {} Hz (or valve.f_3dB = 0: not given)",
        r(f_3db),
        r(f_90),
        r(zeta),
        r(significant(lo)),
        r(significant(hi)),
        within(lo * f_90, hi * f_90, 0.0),
        within(f_3db / hi, f_3db / lo, DATASHEET_HZ.0)
    )
}

/// `x` to four significant digits: a range's ends as a person reads them.
fn significant(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let scale = 10f64.powi(3 - x.abs().log10().floor() as i32);
    (x * scale).round() / scale
}

/// The range of `f_3dB / f_90` over every first stage faster than the -90 degree point
/// and at most `q_max` times as fast (`wn = q W90`, `1 < q <= q_max`), at damping `zeta`.
pub(crate) fn possible_ratios(zeta: f64, q_max: f64) -> (f64, f64) {
    let ratios = (0..=2000).map(|k| {
        let q = (q_max.ln() * k as f64 / 2000.0).exp().max(1.0 + 1e-9);
        first_3db_crossing(q, q / (2.0 * zeta), zeta)
    });
    ratios.fold((f64::INFINITY, 0.0), |(lo, hi), r| (lo.min(r), hi.max(r)))
}

/// The first angular frequency at which `|D(jW)|^2 = 2` (rad/s): the smallest positive
/// root in `x = W^2` of the cubic `(1 - a x)^2 + tau^2 x (1 - x/wn^2)^2 - 2`, `a = 2 zeta
/// tau/wn`, which is -1 at 0 and grows without bound, by bisection in the first interval
/// between its turning points where it changes sign.
pub(crate) fn first_3db_crossing(wn: f64, tau: f64, zeta: f64) -> f64 {
    let a = 2.0 * zeta * tau / wn;
    let b = tau * tau / (wn * wn);
    // Coefficients of x^3, x^2, x, 1.
    let c = [b / (wn * wn), a * a - 2.0 * b, tau * tau - 2.0 * a, -1.0];
    let cubic = |x: f64| ((c[0] * x + c[1]) * x + c[2]) * x + c[3];
    // Turning points: 3 c0 x^2 + 2 c1 x + c2 = 0.
    let disc = c[1] * c[1] - 3.0 * c[0] * c[2];
    let root = if disc > 0.0 { disc.sqrt() } else { f64::NAN };
    let turning = [-root, root].map(|r| (-c[1] + r) / (3.0 * c[0]));
    // Beyond the Cauchy bound the cubic is positive.
    let bound = 1.0 + c[1..].iter().map(|k| (k / c[0]).abs()).fold(0.0, f64::max);
    let mut lo = 0.0;
    for hi in [turning[0], turning[1], bound].into_iter().filter(|&x| x > 0.0) {
        if cubic(hi) >= 0.0 {
            return bisect(&cubic, lo, hi).sqrt();
        }
        lo = hi;
    }
    f64::NAN
}

/// The sign change of `f` in `[lo, hi]` (`f(lo) < 0 <= f(hi)`), to rounding.
fn bisect(f: &impl Fn(f64) -> f64, mut lo: f64, mut hi: f64) -> f64 {
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if f(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Null leakage through the lap per metre of underlap (m2/s) at supply `p` above tank:
/// with the spool centred and the ports blocked each chamber sits at half the supply, and
/// the P -> A and P -> B edges, open by the lap, each pass `K3 u sqrt((p/2)/(dp_r/2))`.
fn lap_leakage_per_metre(k3: f64, p: f64, dp_rated: f64) -> f64 {
    2.0 * k3 * (p / dp_rated).sqrt()
}

/// The lap and the pilot flow at the reference supply from the datasheet's null leakage
/// and pressure gain (`valve.lap` as given where no leakage is).
fn lap_and_pilot(v: &ValveParams, k1: f64, k3: f64) -> Result<(f64, f64), String> {
    let d = &v.datasheet;
    if d.q_leak_null == 0.0 {
        if d.pressure_gain != 0.0 {
            return Err(format!(
                "valve.pressure_gain = {} Pa/A needs valve.Q_leak_null: the lap that gives a \
                 pressure gain leaks",
                r(d.pressure_gain)
            ));
        }
        return Ok((v.lap, 0.0));
    }
    if v.lap != 0.0 {
        return Err(format!(
            "valve.lap = {} m and valve.Q_leak_null = {} m3/s both set: the leakage sets the \
             lap in datasheet form; leave valve.lap at 0",
            r(v.lap),
            r(d.q_leak_null)
        ));
    }
    let per_metre = lap_leakage_per_metre(k3, d.p_leak_ref, v.dp_rated);
    let widest = d.q_leak_null / per_metre;
    // Blocked ports at null: d(p_A - p_B)/dx_s = 2 p/u, and x_s = K1 i/Kw.
    let lap = if d.pressure_gain == 0.0 {
        widest
    } else {
        2.0 * d.p_leak_ref * k1 / (v.kw * d.pressure_gain)
    };
    if lap > widest * (1.0 + 1e-12) {
        return Err(format!(
            "valve.pressure_gain = {} Pa/A needs a lap of {} m, which leaks {} m3/s at \
             valve.p_leak_ref = {} Pa, more than valve.Q_leak_null = {} m3/s: with this leakage \
             the pressure gain is at least {} Pa/A",
            r(d.pressure_gain),
            r(significant(lap)),
            r(significant(per_metre * lap)),
            r(d.p_leak_ref),
            r(d.q_leak_null),
            r(significant(2.0 * d.p_leak_ref * k1 / (v.kw * widest) * (1.0 + 1e-3)))
        ));
    }
    if lap > MAX_LAP {
        return Err(format!(
            "valve.Q_leak_null = {} m3/s needs a lap of {} m, beyond {} m (a \
             spool's stroke is a few millimetres)",
            r(d.q_leak_null),
            r(significant(lap)),
            r(MAX_LAP)
        ));
    }
    Ok((lap, (d.q_leak_null - per_metre * lap).max(0.0)))
}

#[cfg(test)]
#[path = "valve_datasheet_tests.rs"]
mod tests;
