//! The benchmark table.

use crate::fmi::Version;
use ehsv_actuator::physics::Work;

use crate::peer::PeerRun;
use crate::timing::Summary;
use crate::workloads::OUTPUT_NAMES;
use crate::{FIDELITY_LIMIT, WELL_CONDITIONED};

/// One row: a workload at one step size through one FMI version.
pub struct Row {
    pub workload: String,
    /// Instances stepped in lock-step (12 for the quadruped).
    pub instances: usize,
    pub h: f64,
    pub version: Version,
    /// Best real-time factor over the untimed runs: wall, thread CPU.
    pub rtf_wall: f64,
    pub rtf_cpu: f64,
    /// Instructions per communication step of one instance through the FMI 2 C API
    /// (callgrind), on the first row of a (workload, method, step); None if not counted.
    pub instructions: Option<f64>,
    /// Per-doStep thread CPU time, each call's shortest over the timed runs: the work.
    pub step_cpu: Summary,
    /// The slowest doStep of all timed runs as measured, in thread CPU and in wall time.
    pub step_cpu_raw: f64,
    pub step_wall_raw: f64,
    /// For several instances in lock-step: each step's doSteps of all instances together.
    pub lock_step: Option<LockStep>,
    /// The slowest doStep (of `step_cpu`) and, if that was the first, the slowest after it;
    /// for the first FMI version only.
    pub slowest: Option<(SlowStep, Option<SlowStep>)>,
    /// Worst output deviation from the reference as a fraction of its range, and which.
    pub deviation: Option<(f64, usize)>,
    /// The same for the reference against a 10x tighter one (how converged the yardstick is).
    pub reference_spread: (f64, usize),
    /// The FMU's integrator work on the workload's first leg.
    pub work: WorkSummary,
    pub peer: Option<PeerSummary>,
}

/// The thread CPU time of one step's doSteps of all instances of a lock-step run.
pub struct LockStep {
    /// Step by step, the shortest over the timed runs (the work).
    pub work: Summary,
    /// The slowest step of all timed runs as measured.
    pub raw: f64,
}

/// A slow doStep: its thread CPU time, where it starts, which leg, and the work of the FMU's
/// integrators in it.
pub struct SlowStep {
    pub cpu: f64,
    pub t: f64,
    pub leg: usize,
    pub work: Work,
}

/// The FMU's integrator work per communication point.
#[derive(Clone, Copy)]
pub struct WorkSummary {
    /// Rosenbrock steps of the cylinder (accepted and rejected).
    pub steps: f64,
    pub jacobians: f64,
    pub factorisations: f64,
    /// 9x9 matrix exponentials (propagator cache misses).
    pub exponentials: f64,
    /// State-event searches.
    pub locations: f64,
}

impl WorkSummary {
    pub fn new(w: &Work, points: usize) -> Self {
        let per = |n: u64| n as f64 / points as f64;
        WorkSummary {
            steps: per(w.steps_accepted + w.steps_rejected),
            jacobians: per(w.jacobians),
            factorisations: per(w.factorisations),
            exponentials: per(w.exponentials),
            locations: per(w.guard_locations),
        }
    }
}

/// The peer's figures for a (workload, step) pair.
pub struct PeerSummary {
    pub rtf_cpu: f64,
    /// Peer thread-CPU time / FMU thread-CPU time (> 1: the FMU is faster).
    pub ratio: f64,
    pub deviation: (f64, usize),
    pub steps_per_point: f64,
    pub jacobians_per_point: f64,
    pub lu_per_point: f64,
    pub restarts_per_point: f64,
}

impl PeerSummary {
    pub fn new(
        run: &PeerRun,
        sim_time: f64,
        points: usize,
        fmu_cpu: f64,
        deviation: (f64, usize),
    ) -> Self {
        let per = |n: i64| n as f64 / points as f64;
        PeerSummary {
            rtf_cpu: sim_time / run.cpu,
            ratio: run.cpu / fmu_cpu,
            deviation,
            steps_per_point: per(run.counters.steps),
            jacobians_per_point: per(run.counters.jacobians),
            lu_per_point: per(run.counters.lu),
            restarts_per_point: run.restarts as f64 / points as f64,
        }
    }
}

/// Largest entry and its index.
pub fn worst(deviations: &[f64]) -> (f64, usize) {
    deviations
        .iter()
        .enumerate()
        .fold((0.0, 0), |acc, (j, &d)| if d > acc.0 { (d, j) } else { acc })
}

/// Instructions per step, in thousands separated by commas ("14,730"), or "-".
pub fn instructions(count: Option<f64>) -> String {
    let Some(count) = count else { return "-".into() };
    let digits = format!("{:.0}", count);
    let mut out = String::new();
    for (k, c) in digits.chars().enumerate() {
        if k > 0 && (digits.len() - k) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// What `instr/step` counts (printed above the table when counted).
pub const INSTRUCTIONS_NOTE: &str = "\
instr/step: instructions per communication step of one instance, counted by callgrind over the
  run's first --instr-steps steps through the FMI 2 C API: fmi2SetReal of the inputs, fmi2DoStep,
  fmi2GetReal of i_coil, x_piston, p_A and Q_valve (issue 37's measure; docs/benchmark.md).";

fn us(s: f64) -> String {
    format!("{:.2}", s * 1e6)
}

fn deviation(d: Option<(f64, usize)>) -> String {
    match d {
        Some((v, j)) => format!("{v:.1e} {}", OUTPUT_NAMES[j]),
        None => "-".into(),
    }
}

pub fn header() {
    println!(
        "{:<22} {:>5} {:>4} {:>7} {:>7} {:>10} {:>7} {:>8} {:>8} {:>8} {:>8} {:>17} {:>17} {:>6} {:>6} {:>6} {:>6} {:>6} | {:>7} {:>17} {:>6} {:>6} {:>6} {:>6} {:>8}",
        "workload",
        "h",
        "FMI",
        "RTF",
        "RTFcpu",
        "instr/step",
        "mean",
        "p99.9",
        "maxwork",
        "maxraw",
        "maxwall",
        "dev/range",
        "ref spread",
        "st/pt",
        "jac/pt",
        "LU/pt",
        "exp/pt",
        "loc/pt",
        "peerRTF",
        "peer dev/range",
        "st/pt",
        "jac/pt",
        "LU/pt",
        "rst/pt",
        "peer/FMU"
    );
}

pub fn print(row: &Row) {
    let peer = match &row.peer {
        Some(p) => format!(
            "{:>7.1} {:>17} {:>6.2} {:>6.2} {:>6.2} {:>6.2} {:>7.1}x",
            p.rtf_cpu,
            deviation(Some(p.deviation)),
            p.steps_per_point,
            p.jacobians_per_point,
            p.lu_per_point,
            p.restarts_per_point,
            p.ratio
        ),
        None => {
            format!("{:>7} {:>17} {:>6} {:>6} {:>6} {:>6} {:>8}", "-", "-", "-", "-", "-", "-", "-")
        }
    };
    println!(
        "{:<22} {:>5.0e} {:>4} {:>7.1} {:>7.1} {:>10} {:>7} {:>8} {:>8} {:>8} {:>8} {:>17} {:>17} {:>6.2} {:>6.2} {:>6.2} {:>6.3} {:>6.2} | {peer}",
        row.workload,
        row.h,
        row.version.label(),
        row.rtf_wall,
        row.rtf_cpu,
        instructions(row.instructions),
        us(row.step_cpu.mean),
        us(row.step_cpu.p999),
        us(row.step_cpu.max),
        us(row.step_cpu_raw),
        us(row.step_wall_raw),
        deviation(row.deviation),
        deviation(Some(row.reference_spread)),
        row.work.steps,
        row.work.jacobians,
        row.work.factorisations,
        row.work.exponentials,
        row.work.locations,
    );
}

pub const LEGEND: &str = "\
RTF: simulated time / wall time of the best untimed run (all instances; doStep + SetReal of 4
  inputs + GetReal of 12 outputs per instance and step); RTFcpu: the same on thread CPU time.
instr/step: instructions per communication step of one instance through the FMI 2 C API
  (SetReal of 4 inputs, DoStep, GetReal of i_coil, x_piston, p_A, Q_valve), callgrind, over the
  first --instr-steps steps (5000; 500 with --quick); on the first row of each workload and
  method, a dash where not counted (no valgrind, --no-instructions).
mean, p99.9, maxwork: one doStep in thread CPU time (CLOCK_THREAD_CPUTIME_ID) [us], each call
  taken at its shortest over the timed runs (as many as --repeat): the work of the call, the
  same in every run; maxwork is the slowest of those, the figure the targets judge. maxraw: the
  slowest single call of all timed runs as measured (on a shared machine interrupts and
  hypervisor stalls are charged to the running thread); maxwall: the same in wall time (the
  difference is preemption). Timed runs are separate from the untimed ones (two clock reads
  per call).
dev/range: worst max|output - reference| / range of that output over the run; reference: the
  same model through the rlib at solver.rtol 1e-10 or --reference-rtol (the FMU at its 1e-7
  or --fmu-rtol), same grid and inputs.
ref spread: the same measure between that reference and one 10x tighter: where it is not small
  the workload itself is ill-conditioned (a deviation of that size says nothing of the FMU).
peer: SUNDIALS CVODE (BDF, Newton, dense LU, DQ Jacobian) on the same equations, rtol as given,
  restarted at every input change and time event; st/pt, jac/pt, LU/pt, rst/pt: its steps,
  Jacobians, LU factorisations and restarts per communication point; peer/FMU: its thread CPU
  time over the FMU's (untimed run): > 1 means the FMU is that many times faster.
st/pt, jac/pt, LU/pt, exp/pt, loc/pt before the bar: the FMU's own work per communication point
  (`Model::work()` through the rlib on the same run): cylinder Rosenbrock steps (accepted and
  rejected), Jacobians, LU factorisations, 9x9 matrix exponentials, state-event searches.";

pub const SLOWEST_HEADER: &str = "\
The slowest doStep of each row by its work (`maxwork`) and, where that was the first step
(which builds the propagators), the slowest after it; the work of the FMU's integrators in
that step (through the rlib): cylinder Rosenbrock steps accepted + rejected, state-event
searches, 9x9 matrix exponentials. For several instances in lock-step, also the slowest step
of all their doSteps together (each step at its shortest over the timed runs, and the slowest
as measured).";

fn slow_step(s: &SlowStep) -> String {
    let leg = if s.leg > 0 { format!(", leg {}", s.leg) } else { String::new() };
    format!(
        "{} us at t = {:.4} s{leg}: {} + {} Rosenbrock steps, {} event searches, {} exponentials",
        us(s.cpu),
        s.t,
        s.work.steps_accepted,
        s.work.steps_rejected,
        s.work.guard_locations,
        s.work.exponentials,
    )
}

/// The lines on the slowest doSteps of `row`, if they were diagnosed.
pub fn slowest_steps(row: &Row) -> Option<String> {
    let (slowest, later) = row.slowest.as_ref()?;
    let head = format!("  {:<22} {:>5.0e}: ", row.workload, row.h);
    let mut text = format!("{head}{}", slow_step(slowest));
    if let Some(later) = later {
        text += &format!("\n  {:<28}  after it: {}", "", slow_step(later));
    }
    if let Some(lock) = &row.lock_step {
        text += &format!(
            "\n  {:<28}  lock-step of {} doSteps: slowest {} us of work ({:.1}x its mean {} us), {} us as measured",
            "",
            row.instances,
            us(lock.work.max),
            lock.work.max / lock.work.mean,
            us(lock.work.mean),
            us(lock.raw)
        );
    }
    Some(text)
}

/// What the doStep times are, for `repeat` timed runs.
pub fn timed_runs_note(repeat: usize) -> String {
    let (clock_wall, clock_cpu) = crate::timing::clock_cost();
    let (clock_wall, clock_cpu) = (clock_wall * 1e6, clock_cpu * 1e6);
    let note = format!(
        "\
doStep times in thread CPU: maxwork, the slowest doStep's work (each step at its shortest over
the timed runs: every workload is deterministic, so a step does the same work in every run, and
what one run adds is the machine's), judged against the targets; maxraw, the slowest single call
of all timed runs as measured. Every timed call less what the clocks cost on an empty call
({clock_cpu:.2} us thread CPU, {clock_wall:.2} us wall on this machine: the shortest of many)."
    );
    if repeat < 2 {
        format!(
            "{note}\nWith one timed run (--repeat 1) maxwork is the raw figure: use --repeat 3."
        )
    } else {
        format!("{note} {repeat} timed runs.")
    }
}

/// The team's targets at this communication step (s).
pub const TARGET_STEP: f64 = 1e-4;
/// Real-time factor per actuator, and of the whole quadruped on one core.
const TARGET_RTF: f64 = 1000.0;
const TARGET_QUADRUPED_RTF: f64 = 80.0;
/// Slowest doStep (s of thread CPU): a 10 kHz hardware-in-the-loop frame with room to spare.
const TARGET_SLOWEST: f64 = 10e-6;
/// Peer thread-CPU time over the FMU's. (The accuracy target is the bench's
/// [`FIDELITY_LIMIT`], judged where the trajectory is [`WELL_CONDITIONED`].)
const TARGET_PEER_RATIO: f64 = 10.0;

/// What the lines of [`targets`] judge, for a run of `t_end` simulated seconds.
pub fn targets_header(t_end: f64) -> String {
    format!(
        "\
Against the team's targets at h = {TARGET_STEP:e} s, over this run's {t_end} s (FMI 2 rows):
RTFcpu >= {TARGET_RTF} per actuator (the 12-instance quadruped >= {TARGET_QUADRUPED_RTF} in all),
slowest doStep < {} us of thread CPU (its work, maxwork), >= {TARGET_PEER_RATIO}x faster than the peer, every
output within {FIDELITY_LIMIT:e} of its range of the reference (judged where the reference is
within {WELL_CONDITIONED:e} of a 10x tighter one; elsewhere the workload is ill-conditioned).
Printed, never asserted: speed depends on the machine.",
        TARGET_SLOWEST * 1e6
    )
}

/// `solver.method = fixed_cost`'s targets at [`TARGET_STEP`] (issue 37, docs/benchmark.md):
/// instructions per communication step through the C API (per actuator), in current mode and
/// with the 20 kHz loops; RTFcpu against exact's on the same workload; the slowest doStep
/// against the mean; accuracy against the reference where it is well-conditioned.
const FC_INSTRUCTIONS_CURRENT: f64 = 1400.0;
const FC_INSTRUCTIONS_LOOPS: f64 = 1500.0;
const FC_OVER_EXACT: f64 = 10.0;
const FC_SLOWEST_OVER_MEAN: f64 = 2.0;
const FC_ACCURACY: f64 = 1e-2;

/// The fixed_cost targets' header.
pub const FIXED_COST_TARGETS: &str =
    "fixed_cost rows (/fc): at most 1,400 instructions per step through the C API in current mode,
1,500 with the 20 kHz loops (per actuator; Hopsan's valve-cylinder model: 1,377-1,476), RTFcpu
>= 10x exact's on the same workload, slowest doStep <= 2x the mean (work figure: each step at
its shortest over the timed runs; the raw slowest beside it), outputs within 1e-2 of their range
of the reference where it is well-conditioned. The quadruped's slowest is per doStep; its
lock-step (the 12 doSteps of one step together) is shown beside it.";

/// A row's RTFcpu if it is one the targets judge (FMI 2 at [`TARGET_STEP`]).
pub fn rtf_at_target(row: &Row) -> Option<f64> {
    (row.h == TARGET_STEP && row.version == Version::Fmi2).then_some(row.rtf_cpu)
}

/// One line of the fixed_cost targets' verdict for `row` (FMI 2 rows at [`TARGET_STEP`]),
/// `exact_rtf` exact's RTFcpu on the same workload.
pub fn fixed_cost_targets(row: &Row, current_mode: bool, exact_rtf: Option<f64>) -> Option<String> {
    rtf_at_target(row)?;
    let verdict = |met: bool| if met { "met" } else { "NOT met" };
    let budget = if current_mode { FC_INSTRUCTIONS_CURRENT } else { FC_INSTRUCTIONS_LOOPS };
    let instructions = match row.instructions {
        Some(n) => format!("instructions {} ({n:.0} of {budget})", verdict(n <= budget)),
        None => "instructions -".into(),
    };
    let rtf = match exact_rtf {
        Some(exact) => {
            let ratio = row.rtf_cpu / exact;
            format!("RTF {} ({ratio:.1}x exact's)", verdict(ratio >= FC_OVER_EXACT))
        }
        None => format!("RTF {:.1} (exact's not measured)", row.rtf_cpu),
    };
    let (max, mean) = (row.step_cpu.max, row.step_cpu.mean);
    let lock_step = row.lock_step.as_ref().map_or(String::new(), |l| {
        format!(", lock-step {} us, {:.1}x its mean", us(l.work.max), l.work.max / l.work.mean)
    });
    let slowest = format!(
        "slowest {} ({:.1}x mean{lock_step}; work {} us, raw {} us)",
        verdict(max <= FC_SLOWEST_OVER_MEAN * mean),
        max / mean,
        us(max),
        us(row.step_cpu_raw)
    );
    let accuracy = match row.deviation {
        Some(_) if row.reference_spread.0 > WELL_CONDITIONED => {
            "accuracy not judged (ill-conditioned)".into()
        }
        Some((d, _)) => format!("accuracy {} ({d:.1e})", verdict(d <= FC_ACCURACY)),
        None => "accuracy -".into(),
    };
    Some(format!("  {:<22} {instructions}; {rtf}; {slowest}; {accuracy}", row.workload))
}

/// One line of the targets' verdict for `row`, if it is a row they apply to.
pub fn targets(row: &Row) -> Option<String> {
    if row.h != TARGET_STEP || row.version != Version::Fmi2 {
        return None;
    }
    let verdict = |met: bool| if met { "met" } else { "NOT met" };
    let rtf_target = if row.instances > 1 { TARGET_QUADRUPED_RTF } else { TARGET_RTF };
    let rtf =
        format!("RTF {} ({:.1} of {rtf_target})", verdict(row.rtf_cpu >= rtf_target), row.rtf_cpu);
    let slowest = format!(
        "slowest {} (work {} us; raw {} us)",
        verdict(row.step_cpu.max < TARGET_SLOWEST),
        us(row.step_cpu.max),
        us(row.step_cpu_raw)
    );
    let peer = match &row.peer {
        Some(p) => format!("peer {} ({:.1}x)", verdict(p.ratio >= TARGET_PEER_RATIO), p.ratio),
        None => "peer -".into(),
    };
    let accuracy = match row.deviation {
        Some(_) if row.reference_spread.0 > WELL_CONDITIONED => {
            "accuracy not judged (ill-conditioned)".into()
        }
        Some((d, _)) => format!("accuracy {} ({d:.1e})", verdict(d <= FIDELITY_LIMIT)),
        None => "accuracy -".into(),
    };
    Some(format!("  {:<22} {rtf}; {slowest}; {peer}; {accuracy}", row.workload))
}
