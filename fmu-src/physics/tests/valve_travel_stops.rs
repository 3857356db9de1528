//! The valve's travel stops through the physics crate's public API: no part ever passes its
//! stop, whatever the communication step; stops the valve never reaches change nothing; and
//! a state saved in any combination of held and free parts (flapper and spool each free or
//! at either stop) is restored to the same bytes.

mod common;

use common::save;
use ehsv_physics::bytes::ByteReader;
use ehsv_physics::{DriverKind, Inputs, Params, Physics};

/// A staircase of current commands through both signs, (until, i_ref): each change makes
/// the op-amp driver slew and switch mode, with the flapper swinging either way.
const STAIRCASE: [(f64, f64); 6] =
    [(1e-3, 4e-3), (2e-3, -6e-3), (3e-3, 9e-3), (4e-3, 20e-3), (5e-3, -20e-3), (6e-3, -2e-3)];

fn command_at(t: f64) -> f64 {
    STAIRCASE.iter().find(|(until, _)| t < *until - 1e-12).map_or(STAIRCASE[5].1, |s| s.1)
}

fn with_stops(x_flapper_max: f64, x_spool_max: f64) -> Params {
    let mut p = Params::PAPER;
    p.valve.x_flapper_max = x_flapper_max;
    p.valve.x_spool_max = x_spool_max;
    p
}

/// Commands far beyond the stops, both ways, through the op-amp and the voltage driver, at
/// communication steps from 0.1 to 5 ms: at no communication point is the flapper or the
/// spool beyond its stop (each part reaching its stop inside a step, where the guard rises
/// faster than its slope at the sub-step's start predicts, is an event like any other).
#[test]
fn no_part_passes_its_stop_at_any_communication_step() {
    let commands = [20e-3, -15e-3, 60e-3, -60e-3, 3e-3];
    for driver in [DriverKind::OpampPi, DriverKind::Voltage] {
        for h in [1e-4_f64, 3e-4, 1e-3, 5e-3] {
            for (x_flapper_max, x_spool_max) in [(30e-6, 0.2e-3), (0.0, 0.1e-3), (15e-6, 0.0)] {
                let mut p = with_stops(x_flapper_max, x_spool_max);
                p.driver = driver;
                let mut physics = Physics::start(&p, &Inputs::PAPER, 0.0).unwrap();
                let n = (0.03 / h).round() as usize;
                for k in 0..n {
                    let t = k as f64 * h;
                    let i_ref = commands[(5 * k / n).min(4)];
                    physics.step(&Inputs { i_ref, ..Inputs::PAPER }, t, h).unwrap();
                    let out = physics.outputs();
                    let label =
                        format!("{driver:?}, h {h}, stops {x_flapper_max} {x_spool_max}, t {t}");
                    if x_flapper_max > 0.0 {
                        assert!(
                            out.x_flapper.abs() <= x_flapper_max * (1.0 + 1e-12),
                            "{label}: x_flapper {}",
                            out.x_flapper
                        );
                    }
                    if x_spool_max > 0.0 {
                        assert!(
                            out.x_spool.abs() <= x_spool_max * (1.0 + 1e-12),
                            "{label}: x_spool {}",
                            out.x_spool
                        );
                    }
                }
            }
        }
    }
}

/// With the ideal current source a current step makes the free flapper overshoot (zeta =
/// 0.4) and fall back as the spool follows. A stop just below that peak is grazed: the
/// flapper is above it for some tens of microseconds, inside one sub-step of a long
/// communication step, below it at both ends. It must stop there all the same (inelastic
/// impact) and fall back from the stop: the run at 1 ms steps is the run at 10 us steps.
#[test]
fn a_stop_grazed_inside_a_long_step_holds_the_flapper_as_at_short_steps() {
    let mut p = Params::PAPER;
    p.driver = DriverKind::IdealCurrent;
    let command = Inputs { i_ref: 8e-3, ..Inputs::PAPER };
    let run = |p: &Params, h: f64| {
        let mut physics = Physics::start(p, &Inputs::PAPER, 0.0).unwrap();
        let per_ms = (1e-3 / h).round() as usize;
        let mut at_ms = Vec::new();
        for k in 0..10 * per_ms {
            physics.step(&command, k as f64 * h, h).unwrap();
            if (k + 1) % per_ms == 0 {
                at_ms.push(physics.outputs());
            }
        }
        at_ms
    };
    // The free flapper's peak, from a fine run.
    let mut physics = Physics::start(&p, &Inputs::PAPER, 0.0).unwrap();
    let mut peak = 0.0_f64;
    for k in 0..2000 {
        physics.step(&command, k as f64 * 1e-6, 1e-6).unwrap();
        peak = peak.max(physics.outputs().x_flapper);
    }
    let settled = physics.outputs().x_flapper;
    assert!(peak > 1.2 * settled.abs() && peak > 1e-6, "peak {peak}, after 2 ms {settled}");
    for fraction in [0.95, 0.99, 0.999] {
        p.valve.x_flapper_max = fraction * peak;
        let fine = run(&p, 1e-5);
        for h in [2.5e-4, 1e-3] {
            for (ms, (a, b)) in run(&p, h).iter().zip(&fine).enumerate() {
                let label = format!("stop at {fraction} of the peak, h {h}, {} ms", ms + 1);
                assert!((a.x_flapper - b.x_flapper).abs() <= 1e-8 * peak, "{label}: x_flapper");
                assert!((a.x_spool - b.x_spool).abs() <= 1e-8 * 1e-4, "{label}: x_spool");
            }
        }
    }
}

/// Stops far beyond any travel (1 m) give the trajectory of a valve without stops: the
/// stop logic that runs at every mode switch (an impact takes the flapper's outward
/// velocity only at its limit) leaves a free flapper's motion alone, whichever way it
/// moves.
#[test]
fn stops_never_reached_change_nothing() {
    let h = 2.5e-5;
    let run = |p: Params| {
        let mut physics = Physics::start(&p, &Inputs::PAPER, 0.0).unwrap();
        (0..240)
            .map(|k| {
                let t = k as f64 * h;
                let i = Inputs { i_ref: command_at(t), ..Inputs::PAPER };
                physics.step(&i, t, h).unwrap();
                physics.outputs()
            })
            .collect::<Vec<_>>()
    };
    let free = run(Params::PAPER);
    let distant = run(with_stops(1.0, 1.0));
    let flapper_scale = free.iter().map(|o| o.x_flapper.abs()).fold(0.0, f64::max);
    let spool_scale = free.iter().map(|o| o.x_spool.abs()).fold(0.0, f64::max);
    assert!(flapper_scale > 1e-6 && spool_scale > 1e-4, "{flapper_scale} {spool_scale}");
    for (k, (a, b)) in free.iter().zip(&distant).enumerate() {
        assert!(
            (a.x_flapper - b.x_flapper).abs() <= 1e-9 * flapper_scale,
            "step {k}: x_flapper {} vs {}",
            a.x_flapper,
            b.x_flapper
        );
        assert!(
            (a.x_spool - b.x_spool).abs() <= 1e-9 * spool_scale,
            "step {k}: x_spool {} vs {}",
            a.x_spool,
            b.x_spool
        );
        assert!((a.i_coil - b.i_coil).abs() <= 1e-9 * 20e-3, "step {k}: i_coil");
    }
}

/// Through the staircase with a 0.2 mm spool stop and a 30 um flapper stop, the spool
/// reaches its stops from 5.3 mA on and the flapper its own from about 14 mA on (and on
/// its swing before the spool arrives): states saved free, with either part or both held,
/// on either side, restore to the same bytes and continue bit for bit.
#[test]
fn states_saved_in_every_stop_combination_restore_exactly() {
    let p = with_stops(30e-6, 0.2e-3);
    let h = 1e-4;
    let mut physics = Physics::start(&p, &Inputs::PAPER, 0.0).unwrap();
    let mut codes = std::collections::BTreeSet::new();
    for k in 0..240 {
        let t = k as f64 * h;
        // The staircase at a quarter of its speed: 4 ms a stair.
        let i = Inputs { i_ref: command_at(0.25 * t), ..Inputs::PAPER };
        physics.step(&i, t, h).unwrap();
        let bytes = save(&physics);
        codes.insert(bytes[1]);
        let mut restored = Physics::read_bytes(&p, &i, &mut ByteReader::new(&bytes))
            .unwrap_or_else(|e| panic!("step {k}: {e}"));
        assert_eq!(save(&restored), bytes, "step {k}: stop code {}", bytes[1]);
        let mut ahead = physics.clone();
        for j in 1..3 {
            let t = (k + j) as f64 * h;
            ahead.step(&i, t, h).unwrap();
            restored.step(&i, t, h).unwrap();
            assert_eq!(ahead.outputs(), restored.outputs(), "step {k} + {j}");
        }
    }
    // Codes (flapper + 1) * 3 + spool + 1: free 4, spool held 3 and 5, both held 0 and 8,
    // the flapper alone held (on its way) 1 and 7.
    for code in [0, 1, 3, 4, 5, 7, 8] {
        assert!(codes.contains(&code), "stop code {code} never saved: {codes:?}");
    }
}
