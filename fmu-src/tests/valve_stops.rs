//! The valve's travel stops through the Model API: a start in equilibrium against them, and
//! a state saved while they hold the flapper and spool that continues exactly.

mod scenario;

use ehsv_actuator::model::Model;
use ehsv_actuator::variables::vr;
use scenario::{model, run};

const K1: f64 = 2.82462;
const KF: f64 = 511.545;
const KW: f64 = 74.2853;

#[test]
fn start_at_a_current_beyond_the_stops_rests_against_them() {
    // 10 mA would hold the spool at K1 i/Kw = 0.38 mm: the 0.2 mm stop holds it, and the
    // flapper carries the torque the feedback wire cannot, (K1 i - Kw x_s)/Kf = 26.2 um,
    // unless its own 20 um stop holds it too. At rest nothing moves afterwards.
    for (flapper_max, sign) in [(0.0, 1.0), (20e-6, 1.0), (0.0, -1.0), (20e-6, -1.0)] {
        let settings = [
            ("valve.x_spool_max", 0.2e-3),
            ("valve.x_flapper_max", flapper_max),
            ("i_ref", sign * 10e-3),
        ];
        let mut m = model(&settings);
        let free_flapper = (K1 * 10e-3 - KW * 0.2e-3) / KF;
        let flapper = if flapper_max > 0.0 { flapper_max } else { free_flapper };
        for _ in 0..2 {
            let (x_s, x_f) = (m.get(vr::X_SPOOL).unwrap(), m.get(vr::X_FLAPPER).unwrap());
            assert_eq!(x_s, sign * 0.2e-3, "flapper stop {flapper_max}");
            assert!(
                (x_f - sign * flapper).abs() <= 1e-12 * flapper,
                "flapper stop {flapper_max}: {x_f}"
            );
            run(&mut m, 10e-3, 1e-3, &[]);
        }
    }
}

#[test]
fn a_state_saved_at_the_stops_continues_exactly() {
    let limits = [("driver", 0.0), ("valve.x_flapper_max", 30e-6), ("valve.x_spool_max", 0.2e-3)];
    let outputs = [vr::X_FLAPPER, vr::X_SPOOL, vr::X_PISTON, vr::P_A];
    for sign in [1.0, -1.0] {
        let mut m = model(&limits);
        m.set(vr::I_REF, sign * 10e-3).unwrap();
        run(&mut m, 5e-3, 1e-4, &[]);
        assert_eq!(m.get(vr::X_SPOOL), Some(sign * 0.2e-3), "at the spool stop");
        let mut restored = Model::from_bytes(&m.to_bytes()).unwrap();
        // Released by a reversal: both leave their stops at the same instants.
        for model in [&mut m, &mut restored] {
            model.set(vr::I_REF, -sign * 4e-3).unwrap();
        }
        let a = run(&mut m, 10e-3, 1e-4, &outputs);
        let b = run(&mut restored, 10e-3, 1e-4, &outputs);
        assert_eq!(a, b, "a restored state continues bit for bit");
    }
}

#[test]
fn driven_into_the_stops_either_way_they_hold() {
    // +-10 mA from the centre: the flapper overshoots towards ~55 um and the spool heads
    // for 0.38 mm; the 30 um and 0.2 mm stops stop both, on either side.
    let limits = [("driver", 0.0), ("valve.x_flapper_max", 30e-6), ("valve.x_spool_max", 0.2e-3)];
    for sign in [1.0, -1.0] {
        let mut m = model(&limits);
        m.set(vr::I_REF, sign * 10e-3).unwrap();
        let trace = run(&mut m, 20e-3, 1e-5, &[vr::X_FLAPPER, vr::X_SPOOL]);
        let reach = |k: usize| trace.iter().map(|s| sign * s.1[k]).fold(f64::MIN, f64::max);
        // Held exactly at the limit (the held value is projected; 1e-12 is rounding).
        assert!((reach(0) - 30e-6).abs() <= 1e-12 * 30e-6, "flapper {}", reach(0));
        assert!((reach(1) - 0.2e-3).abs() <= 1e-12 * 0.2e-3, "spool {}", reach(1));
        let flapper_hold = (K1 * 10e-3 - KW * 0.2e-3) / KF;
        let last = &trace.last().unwrap().1;
        assert_eq!(last[1], sign * 0.2e-3);
        assert!((last[0] - sign * flapper_hold).abs() <= 1e-9 * flapper_hold, "{}", last[0]);
    }
}

#[test]
fn a_state_saved_in_motion_with_stops_configured_continues_exactly() {
    // Saved 1 ms after a 10 mA step, flapper and spool still free and moving, continued
    // with the same input: they reach and hold their stops exactly as without the restore.
    let limits = [("driver", 0.0), ("valve.x_flapper_max", 30e-6), ("valve.x_spool_max", 0.2e-3)];
    let outputs = [vr::X_FLAPPER, vr::X_SPOOL, vr::X_PISTON, vr::P_A];
    let mut m = model(&limits);
    m.set(vr::I_REF, 10e-3).unwrap();
    run(&mut m, 1e-3, 1e-4, &[]);
    assert!(m.get(vr::X_SPOOL).unwrap() < 0.2e-3, "the spool is still free");
    let mut restored = Model::from_bytes(&m.to_bytes()).unwrap();
    assert_eq!(run(&mut m, 10e-3, 1e-4, &outputs), run(&mut restored, 10e-3, 1e-4, &outputs));
}

#[test]
fn flapper_hitting_its_stop_at_the_top_of_its_swing_falls_back_from_it() {
    // A 20 mA step swings the free flapper out to a peak; with the stop just inside that
    // peak the flapper reaches it while the torque already pulls it back. The impact is
    // inelastic: it stops there (no travel beyond the limit) and falls back at once.
    for sign in [1.0, -1.0] {
        let swing = |limit: f64| {
            let mut m = model(&[("driver", 0.0), ("valve.x_flapper_max", limit)]);
            m.set(vr::I_REF, sign * 20e-3).unwrap();
            scenario::first_output(run(&mut m, 2e-3, 1e-6, &[vr::X_FLAPPER]))
        };
        let outmost =
            |trace: &[(f64, f64)]| trace.iter().map(|s| sign * s.1).fold(f64::MIN, f64::max);
        let peak = outmost(&swing(0.0));
        let limit = 0.999 * peak;
        let stopped = swing(limit);
        let highest = outmost(&stopped);
        println!("sign {sign}: free peak {peak:e} m, limit {limit:e} m, reached {highest:e} m");
        // Sampled every 1 us it falls back from the limit by ~1e-6 of it; the free swing
        // passes the limit by 1e-3 of it.
        assert!(highest <= limit * (1.0 + 1e-12) && highest > limit * (1.0 - 1e-5), "{highest}");
        let at_stop = stopped.iter().filter(|s| sign * s.1 >= limit * (1.0 - 1e-12)).count();
        assert!(at_stop <= 1, "released at once, not held: {at_stop} samples at the stop");
    }
}
