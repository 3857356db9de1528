//! The slew-rate limit of the PI drivers through the Model API: a large current step makes
//! the output ramp at exactly the slew rate, up and down, until it meets the rail or the
//! linear PI output.

mod scenario;

use ehsv_actuator::variables::vr;
use scenario::{first_output, model, run};

/// Output voltage over `duration` after a current step `from -> to` (the driver first
/// settled at `from`), sampled every `h`.
fn output_after_step(
    driver: f64,
    v_supply: f64,
    from: f64,
    to: f64,
    duration: f64,
    h: f64,
) -> Vec<(f64, f64)> {
    let mut m = model(&[("driver", driver), ("V_supply", v_supply)]);
    m.set(vr::I_REF, from).unwrap();
    run(&mut m, 50e-3, 1e-4, &[]);
    m.set(vr::I_REF, to).unwrap();
    let trace = first_output(run(&mut m, duration, h, &[vr::U_DRIVER]));
    let t0 = trace[0].0;
    trace.into_iter().map(|(t, u)| (t - t0, u)).collect()
}

/// Checks `u(t) = u(0) + slope t` while `t <= ramp_end`; returns the voltage at the end.
fn assert_ramp(trace: &[(f64, f64)], slope: f64, ramp_end: f64, scale: f64) -> f64 {
    let u0 = trace[0].1;
    let mut checked = 0;
    for &(t, u) in trace.iter().filter(|(t, _)| *t <= ramp_end) {
        // The slewing mode is the linear ODE u' = +-S, integrated exactly: only rounding
        // separates the output from the straight line (1e-9 of the rail is far above it
        // and far below a 1 % change of the slope).
        assert!((u - (u0 + slope * t)).abs() <= 1e-9 * scale, "t {t}: u {u} vs {}", u0 + slope * t);
        checked += 1;
    }
    assert!(checked >= 10, "the ramp was sampled: {checked} points");
    trace.last().unwrap().1
}

#[test]
fn opamp_output_slews_at_20_volts_per_microsecond_to_the_rail_and_back() {
    // 5 mA from rest asks Kp e = 800 V: the output slews at S = 20 V/us to the 72 V rail,
    // reached after 3.6 us, and stays there (the coil current needs ~0.15 ms).
    let (slew, rail) = (2.0e7, 72.0);
    let up = output_after_step(2.0, rail, 0.0, 5e-3, 6e-6, 1e-7);
    assert_eq!(up[0].1, 0.0);
    let end = assert_ramp(&up, slew, 3.5e-6, rail);
    assert!((end - rail).abs() <= 1e-9 * rail, "at the rail after the ramp: {end}");
    // From the settled 5 V (R i) back to zero current: -800 V asked, slews down to -72 V.
    let down = output_after_step(2.0, rail, 5e-3, 0.0, 6e-6, 1e-7);
    assert!((down[0].1 - 5.0).abs() < 1e-6, "settled at R i: {}", down[0].1);
    let end = assert_ramp(&down, -slew, (rail + 5.0) / slew - 0.1e-6, rail);
    assert!((end + rail).abs() <= 1e-9 * rail, "at the - rail after the ramp: {end}");
}

#[test]
fn industrial_output_slews_at_1_volt_per_microsecond_until_the_pi_output() {
    // The industrial amplifier (Kp 2500 V/A, 24 V supply): a 5 mA step asks 12.5 V, reached
    // at 1 V/us in ~12.5 us (the coil current and the integrator barely move meanwhile).
    let slew = 1.0e6;
    let up = output_after_step(3.0, 24.0, 0.0, 5e-3, 20e-6, 1e-7);
    let end = assert_ramp(&up, slew, 12.0e-6, 24.0);
    // Then it follows the linear PI output, 12.5 V plus what the integrator added.
    assert!((end - 12.5).abs() < 0.5, "on the PI output after the ramp: {end}");
    let down = output_after_step(3.0, 24.0, 5e-3, 0.0, 20e-6, 1e-7);
    assert_ramp(&down, -slew, 12.0e-6, 24.0);
}

#[test]
fn output_never_moves_faster_than_the_slew_rate() {
    // A fast coil (L = 0.1 H: L/R = 0.1 ms) makes the linear PI output fall faster than
    // 20 V/us where it leaves the rail (Kp di/dt ~ 1e8 V/s): there the output must slew.
    let slew = 2.0e7;
    let mut m = model(&[("driver", 2.0), ("coil.L", 0.1)]);
    let h = 1e-8;
    let (mut fastest, mut slewing) = (0.0_f64, 0);
    for i_ref in [5e-3, -5e-3, 2e-3] {
        m.set(vr::I_REF, i_ref).unwrap();
        let trace = first_output(run(&mut m, 0.3e-3, h, &[vr::U_DRIVER]));
        for w in trace.windows(2) {
            let rate = (w[1].1 - w[0].1) / h;
            fastest = fastest.max(rate.abs());
            if (rate.abs() / slew - 1.0).abs() < 1e-6 {
                slewing += 1;
            }
        }
    }
    println!("fastest {fastest:e} V/s, {slewing} samples slewing");
    // Exact propagation: a slewing output moves S h per sample up to rounding of u (1e-14
    // V over 1e-8 s: 1e-6 relative).
    assert!(fastest <= slew * (1.0 + 1e-6), "{fastest:e} V/s");
    assert!(slewing > 100, "the output slews: {slewing}");
}
