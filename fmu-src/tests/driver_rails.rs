//! The drivers' supply rails through the Model API: where each driver saturates, the
//! saturation flag, and the rail entries and exits a step reports.

mod scenario;

use ehsv_actuator::variables::vr;
use scenario::{model, run};

/// Settles a driver on a command and returns (u_driver, i_coil, driver_saturated).
fn settled(settings: &[(&str, f64)], i_ref: f64) -> (f64, f64, f64) {
    let mut m = model(settings);
    m.set(vr::I_REF, i_ref).unwrap();
    // 30 coil time constants (L/R = 3.2 ms): the current is settled to far below 1e-9.
    run(&mut m, 0.1, 1e-3, &[]);
    let get = |r| m.get(r).unwrap();
    (get(vr::U_DRIVER), get(vr::I_COIL), get(vr::DRIVER_SATURATED))
}

#[test]
fn opamp_output_stage_drop_lowers_both_rails() {
    // 100 mA cannot be driven through 1 kOhm: the op-amp sits at V_supply - V_drop = 70 V
    // and the coil carries 70 mA; reversed, at -70 V. Held values are exact (the output is
    // projected onto the rail), the current converges as exp(-t R/L).
    for sign in [1.0, -1.0] {
        let (u, i, saturated) = settled(&[("driver", 2.0), ("driver.V_drop", 2.0)], sign * 0.1);
        assert_eq!(u, sign * 70.0);
        assert!((i - sign * 0.070).abs() < 1e-9, "{i}");
        assert_eq!(saturated, 1.0);
    }
    // The industrial amplifier has no such drop: its rail is the supply.
    let (u, _, saturated) =
        settled(&[("driver", 3.0), ("driver.V_drop", 2.0), ("V_supply", 24.0)], 0.1);
    assert_eq!((u, saturated), (24.0, 1.0));
}

/// Current after a reversal `from -> to` (settled at `from` first), sampled every 1 us.
fn reversal(driver: f64, v_supply: f64, from: f64, to: f64) -> Vec<(f64, f64)> {
    let mut m = model(&[("driver", driver), ("V_supply", v_supply)]);
    m.set(vr::I_REF, from).unwrap();
    run(&mut m, 0.1, 1e-3, &[]);
    m.set(vr::I_REF, to).unwrap();
    scenario::first_output(run(&mut m, 5e-3, 1e-6, &[vr::I_COIL]))
}

#[test]
fn integrator_stops_at_the_rail_so_a_reversal_does_not_overshoot() {
    // A reversal -5 -> +3 mA (and its mirror) drives the output to the rail for the ~0.3 ms
    // the coil needs. Both PI drivers have Ki/Kp = R/L, cancelling the coil pole: off the
    // rail the loop is first order and the current approaches the command from one side
    // (measured: no overshoot at all, 0.29 % / 5.1 % still to go after 5 ms). An integrator
    // left running at the rail would wind up by ~Ki * 8 mA * 0.3 ms = tens of volts and
    // overshoot by tens of percent; 1e-9 of the command is rounding.
    for (driver, v_supply) in [(2.0, 72.0), (3.0, 24.0)] {
        for (from, to) in [(-5e-3, 3e-3), (5e-3, -3e-3)] {
            let trace = reversal(driver, v_supply, from, to);
            let overshoot = trace.iter().map(|s| (s.1 - to) / to).fold(f64::MIN, f64::max);
            println!("driver {driver}, {from} -> {to} A: overshoot {overshoot:e}");
            assert!(overshoot <= 1e-9, "driver {driver}, {from} -> {to}: {overshoot:e}");
        }
    }
}

#[test]
fn voltage_driver_clips_at_the_supply_and_says_so() {
    // The open-loop driver applies R i_ref while that is within the supply, else the rail.
    for (i_ref, u, saturated) in
        [(0.05, 50.0, 0.0), (-0.05, -50.0, 0.0), (0.1, 72.0, 1.0), (-0.1, -72.0, 1.0)]
    {
        let (u_driver, i, flag) = settled(&[("driver", 1.0)], i_ref);
        assert_eq!((u_driver, flag), (u, saturated), "i_ref {i_ref}");
        assert!((i - u / 1000.0).abs() < 1e-9, "i_ref {i_ref}: {i}");
    }
}

#[test]
fn ideal_source_holds_the_current_with_the_voltage_r_i() {
    // The ideal current source's voltage is what holds the current: (R + R_sense) i_ref.
    let (u, i, flag) = settled(&[("driver", 0.0), ("coil.R_sense", 50.0)], 4e-3);
    assert_eq!(i, 4e-3);
    assert!((u - 1050.0 * 4e-3).abs() <= 1e-12, "{u}");
    assert_eq!(flag, 0.0);
}

#[test]
fn a_step_reports_the_rail_entries_and_exits_it_contains() {
    // 5 mA from rest: the op-amp slews to the + rail (3.6 us), rides it while the current
    // rises (~0.2 ms) and leaves it: one entry and one exit within a 1 ms step.
    let mut m = model(&[("driver", 2.0)]);
    m.set(vr::I_REF, 5e-3).unwrap();
    let events = m.do_step(0.0, 1e-3).unwrap();
    assert_eq!((events.rail_entered, events.rail_left), (1, 1));
    // 100 mA cannot be reached: it enters the rail and stays.
    m.set(vr::I_REF, 0.1).unwrap();
    let events = m.do_step(m.time(), 1e-3).unwrap();
    assert_eq!((events.rail_entered, events.rail_left), (1, 0));
    assert_eq!(m.get(vr::DRIVER_SATURATED), Some(1.0));
    let events = m.do_step(m.time(), 1e-3).unwrap();
    assert_eq!((events.rail_entered, events.rail_left), (0, 0), "still at the rail");
}
