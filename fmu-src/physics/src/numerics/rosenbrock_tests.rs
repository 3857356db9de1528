use super::*;
use crate::components::cylinder::{equilibrium, CylinderState};

const P_RATED: f64 = 6.8948e6;
/// Spool opening for the rated 10 mA flow (2.5268e-4 m3/s, K3 times the spool opening).
const X_S_RATED: f64 = 2.5268e-4 / 0.664515;

/// Runs `t_end` seconds in calls of `interval`, spool position `x_s(t)` in absolute time;
/// `observe` sees the state after every call. Returns the summed statistics.
pub(crate) fn simulate(
    params: &CylinderParams,
    state: &mut CylinderState,
    memory: &mut RosenbrockMemory,
    x_s: &dyn Fn(f64) -> f64,
    (p_supply, f_ext): (f64, f64),
    (t_start, t_end, interval): (f64, f64, f64),
    mut observe: impl FnMut(f64, &CylinderState),
) -> (Stats, u32) {
    let mut total = Stats::default();
    let mut most_steps = 0;
    let calls = ((t_end - t_start) / interval).round() as usize;
    for n in 0..calls {
        let t = t_start + n as f64 * interval;
        let s =
            advance(params, state, interval, p_supply, f_ext, |tau| x_s(t + tau), memory).unwrap();
        total.accepted += s.accepted;
        total.rejected += s.rejected;
        total.function_evaluations += s.function_evaluations;
        total.jacobian_evaluations += s.jacobian_evaluations;
        total.rodas3_accepted += s.rodas3_accepted;
        total.rodas3_failed += s.rodas3_failed;
        total.landings += s.landings;
        total.floor_clamp = total.floor_clamp.max(s.floor_clamp);
        most_steps = most_steps.max(s.accepted + s.rejected);
        observe(t + interval, state);
    }
    (total, most_steps)
}

#[test]
fn result_does_not_depend_on_the_call_interval() {
    // A time-varying spool through both directions, an end stop and back: 1 us ... 10 ms calls.
    let p = CylinderParams::default();
    let x_s = |t: f64| 0.3e-3 * (2.0 * std::f64::consts::PI * 10.0 * t).sin();
    let run = |interval: f64, rtol: f64| {
        let mut s = equilibrium(&p, P_RATED, 200.0);
        let mut memory = RosenbrockMemory::new(rtol);
        simulate(&p, &mut s, &mut memory, &x_s, (P_RATED, 200.0), (0.0, 0.06, interval), |_, _| {});
        s
    };
    let reference = run(1e-3, 1e-11);
    for interval in [1e-6, 1e-4, 1e-3, 1e-2] {
        let s = run(interval, 1e-8);
        let e = [
            (s.p_a - reference.p_a) / 1e6,
            (s.p_b - reference.p_b) / 1e6,
            (s.x - reference.x) / 1e-2,
            (s.v - reference.v) / 1e-1,
        ];
        assert!(e.iter().all(|e| e.abs() < 1e-5), "interval {interval}: {e:?}");
    }
}

#[test]
fn restored_state_and_memory_repeat_the_run_bit_for_bit() {
    let p = CylinderParams::default();
    let x_s = |t: f64| 0.2e-3 * (1.0 - (-t / 1e-3).exp());
    let mut s = equilibrium(&p, P_RATED, 100.0);
    let mut memory = RosenbrockMemory::default();
    simulate(&p, &mut s, &mut memory, &x_s, (P_RATED, 100.0), (0.0, 0.005, 1e-3), |_, _| {});
    let (saved_state, saved_memory) = (s.to_array(), memory.to_array());
    simulate(&p, &mut s, &mut memory, &x_s, (P_RATED, 100.0), (0.005, 0.01, 1e-3), |_, _| {});
    let mut again = CylinderState::from_array(&saved_state);
    let mut again_work = RosenbrockMemory::from_array(&saved_memory);
    simulate(
        &p,
        &mut again,
        &mut again_work,
        &x_s,
        (P_RATED, 100.0),
        (0.005, 0.01, 1e-3),
        |_, _| {},
    );
    assert_eq!(again, s);
    assert_eq!(again_work, memory);
    // A refused step leaves the state alone.
    let before = s;
    assert!(advance(&p, &mut s, f64::NAN, P_RATED, 0.0, |_| 0.0, &mut memory).is_err());
    assert_eq!(s, before);
}

/// A Rodas3 attempt that fails is not made again on the next 1, 2, 4, ... steps that could
/// try it (its failures come in runs); one that passes resets the backoff.
#[test]
fn failed_rodas3_attempts_back_off() {
    let p = CylinderParams::default();
    let x_s = |t: f64| 0.3e-3 * (2.0 * std::f64::consts::PI * 10.0 * t).sin();
    let mut s = equilibrium(&p, P_RATED, 200.0);
    let mut memory = RosenbrockMemory::default();
    let (mut failures, mut skipped) = (0, 0);
    for n in 0..5000 {
        let t = n as f64 * 2e-5;
        let before = memory;
        let stats =
            advance(&p, &mut s, 2e-5, P_RATED, 200.0, |tau| x_s(t + tau), &mut memory).unwrap();
        let tried = stats.rodas3_accepted + stats.rodas3_failed;
        if before.rodas3_skip > 0 {
            assert_eq!(tried, 0, "call {n} tried Rodas3 while backing off");
            skipped += u32::from(memory.rodas3_skip < before.rodas3_skip);
        }
        if stats.rodas3_failed > 0 {
            failures += 1;
            let expected = (2 * before.rodas3_backoff).clamp(1, MAX_RODAS3_BACKOFF);
            assert_eq!(memory.rodas3_backoff, expected, "call {n}");
            // Steps after the failure within the call (a rejection) count down already.
            let counted_down = memory.rodas3_skip < expected && stats.rejected > 0;
            assert!(memory.rodas3_skip == expected || counted_down, "call {n}");
        } else if stats.rodas3_accepted > 0 {
            assert_eq!(memory.rodas3_backoff, 0, "call {n}: a pass resets the backoff");
        }
    }
    assert!(failures > 10 && skipped > 10, "{failures} failures, {skipped} calls skipped");
}

/// Every 0.1 ms call at the default tolerance (Rodas3 where it passes, located contact
/// instants) against a reference at rtol 1e-12, over motion, impact on both stops,
/// cavitation and a spool through zero: the largest scaled deviation along the trajectory.
#[test]
fn default_tolerance_tracks_a_tight_reference() {
    let p = CylinderParams::default();
    let sine = |t: f64| 0.3e-3 * (2.0 * std::f64::consts::PI * 10.0 * t).sin();
    type Case<'a> = (&'a str, &'a dyn Fn(f64) -> f64, f64, f64);
    let cases: [Case; 4] = [
        ("rated flow into the + stop", &|_| X_S_RATED, 0.0, 0.08),
        ("0.2 mm into the + stop, pressing", &|_| 0.2e-3, 0.0, 0.12),
        ("overrunning load, cavitating, - stop", &|_| -0.5e-3, -6000.0, 0.05),
        ("10 Hz sine through both directions", &sine, 200.0, 0.1),
    ];
    for (name, x_s, f_ext, t_end) in cases {
        let run = |rtol: f64| {
            let mut s = equilibrium(&p, P_RATED, 0.0);
            let mut memory = RosenbrockMemory::new(rtol);
            let mut trace = Vec::new();
            let (stats, most) = simulate(
                &p,
                &mut s,
                &mut memory,
                x_s,
                (P_RATED, f_ext),
                (0.0, t_end, 1e-4),
                |_, s| trace.push(*s),
            );
            (trace, stats, most)
        };
        let (reference, _, _) = run(1e-12);
        let (trace, stats, most) = run(1e-8);
        let mut worst: f64 = 0.0;
        for (s, r) in trace.iter().zip(&reference) {
            let e = [
                (s.p_a - r.p_a) / 1e6,
                (s.p_b - r.p_b) / 1e6,
                (s.x - r.x) / 1e-2,
                (s.v - r.v) / 1e-1,
            ];
            worst = e.iter().fold(worst, |w, e| w.max(e.abs()));
        }
        println!(
                "{name:38} max scaled deviation {worst:.2e}; {} steps ({} Rodas3, {} Rodas3 failed, {} rejected), {} f-evals, max {most} per call",
                stats.accepted, stats.rodas3_accepted, stats.rodas3_failed, stats.rejected, stats.function_evaluations
            );
        assert!(worst < 1e-5, "{name}: {worst}");
    }
}

/// The calls in which the piston reaches the + stop (0.2 mm spool, 10 us calls, three
/// bounces) step onto the contact instant: 38, 28, 39 internal steps (accepted + rejected)
/// without the location (`MAX_LANDINGS = 0`), 27, 7, 28 with it.
#[test]
fn contact_instants_are_stepped_onto() {
    let p = CylinderParams::default();
    let mut s = equilibrium(&p, P_RATED, 0.0);
    let mut memory = RosenbrockMemory::default();
    let (mut entries, mut landings, mut most) = (0, 0, 0);
    for n in 0..60_000 {
        let before = s.x;
        let stats = advance(&p, &mut s, 1e-5, P_RATED, 0.0, |_| 0.2e-3, &mut memory).unwrap();
        if before <= p.stroke / 2.0 && s.x > p.stroke / 2.0 {
            entries += 1;
            landings += stats.landings;
            most = most.max(stats.accepted + stats.rejected);
            println!(
                "entry in call {n}: {} steps ({} rejected, {} landings)",
                stats.accepted, stats.rejected, stats.landings
            );
        }
    }
    assert!(entries >= 2 && landings >= entries, "{entries} entries, {landings} landings");
    assert!(most <= 30, "{most} steps in an entry call");
}

/// A chamber in the cavitation band that turns from filling to emptying: the bulk-modulus
/// factor drops from 1 to `u(2-u)` there, a kink in `p'`. The state is one at a velocity
/// reversal under a touchdown load (chamber B at -0.6 bar, the spool closing towards null).
/// The attempt that first holds the kink fails; the step after it lands on the kink: at
/// most 1 rejection, where error control alone would shrink the step again and again (a
/// kink, not the step size, sets the error).
#[test]
fn a_cavitation_kink_that_failed_a_step_is_stepped_onto() {
    let p = CylinderParams::default();
    let start = CylinderState { p_a: 7.23636e6, p_b: -6.08529e4, x: 1.269312e-2, v: -6.8789e-5 };
    let f_ext = -1500.0 * (std::f64::consts::PI * 0.138 / 0.25).sin();
    let (h, x_s) = (4.3332e-5, |tau: f64| 1.285e-7 - 2.96e-3 * tau);
    let run = |rtol: f64| {
        let mut s = start;
        let mut memory = RosenbrockMemory::new(rtol);
        memory.h_next = 1e-4;
        let stats = advance(&p, &mut s, h, P_RATED, f_ext, x_s, &mut memory).unwrap();
        (s, stats)
    };
    let (reference, _) = run(1e-12);
    let (s, stats) = run(RosenbrockMemory::default().rtol);
    println!(
        "{} accepted, {} rejected, {} landings",
        stats.accepted, stats.rejected, stats.landings
    );
    assert!(stats.landings >= 1 && stats.rejected <= 1, "{stats:?}");
    let e =
        [(s.p_a - reference.p_a) / 1e6, (s.p_b - reference.p_b) / 1e6, (s.v - reference.v) / 1e-1];
    assert!(e.iter().all(|e| e.abs() < 1e-7), "{e:?}");
}

#[test]
fn cost_per_interval() {
    let p = CylinderParams::default();
    let interval = 1e-4;
    let measure = |name: &str, mut s: CylinderState, x_s: f64, warmup: f64, span: f64| {
        let mut memory = RosenbrockMemory::default();
        simulate(
            &p,
            &mut s,
            &mut memory,
            &|_| x_s,
            (P_RATED, 0.0),
            (0.0, warmup, interval),
            |_, _| {},
        );
        let calls = (span / interval).round();
        let start = std::time::Instant::now();
        let (stats, most) = simulate(
            &p,
            &mut s,
            &mut memory,
            &|_| x_s,
            (P_RATED, 0.0),
            (0.0, span, interval),
            |_, _| {},
        );
        let per_call = start.elapsed().as_secs_f64() / calls;
        println!(
                "{name:44} per 0.1 ms call: {:.2} steps ({:.2} rejected, max {most}), {:.1} f-evals, {:.2} us",
                stats.accepted as f64 / calls,
                stats.rejected as f64 / calls,
                stats.function_evaluations as f64 / calls,
                per_call * 1e6
            );
        stats.accepted as f64 / calls
    };
    let rest = equilibrium(&p, P_RATED, 0.0);
    let start_low = CylinderState { x: -0.035, ..rest };
    let at_rest = measure("at rest, x_s = 0", rest, 0.0, 0.001, 0.02);
    measure("rated flow from rest (first 20 ms)", start_low, X_S_RATED, 0.0, 0.02);
    measure("rated flow, steady", start_low, X_S_RATED, 0.02, 0.02);
    measure("0.2 mm, impact on the end stop (40..60 ms)", rest, 0.2e-3, 0.04, 0.02);
    measure("0.2 mm, pressing on the end stop", rest, 0.2e-3, 0.1, 0.02);
    assert!(at_rest <= 1.0, "at rest: {at_rest} steps per call");
}
