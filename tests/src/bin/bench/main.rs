//! Benchmark of the FMU through its real C API (FMI 2.0 and 3.0), loaded like an importer
//! would (dlopen), on the workloads of a legged robot, beside a peer (SUNDIALS CVODE on the
//! same equations) and against a tight-tolerance reference run of the same model.
//!
//!     cargo build --release -p ehsv-actuator     # the cdylib (scripts/test.sh builds it)
//!     cargo run --release -p ehsv-tests --bin bench [-- OPTIONS]
//!
//! Options: `--quick` (0.02 s, h = 1e-4, one run: the smoke test of
//! scripts/test.sh), `--t-end S` (default 2), `--h 1e-4,1e-3` (default 1e-3,1e-4,1e-5),
//! `--fmi 2|3|both`, `--only NAME,NAME`, `--repeat N` (untimed runs, best RTF, and timed runs,
//! per-call shortest; default 3),
//! `--peer-rtol R` (default 1e-10, where the peer's accuracy comes near the FMU's),
//! `--reference-rtol R` (default 1e-10), `--fmu-rtol R` (the FMU's `solver.rtol`: accuracy
//! traded for speed; default its own, 1e-7), `--no-peer`, `--require-peer` (fail if CVODE cannot
//! be loaded), `--all-h` (the quadruped at every h, not only 1e-4), `--lib PATH`,
//! `--instructions-only` (only the instructions per communication step, counted with
//! callgrind: `instructions.rs`), `--instr-steps N` (steps counted, default 5000, 500 with
//! `--quick`), `--no-instructions` (no callgrind runs; without valgrind they are skipped),
//! `--mujoco` (after the table, the quadruped as MuJoCo plugins against MuJoCo's own
//! position actuators: `mujoco.rs`), `--mujoco-only` (that alone).
//!
//! It exits non-zero if any call fails, FMI 2 and FMI 3 give different outputs, the idle
//! instance's outputs move, the step-to-rest current does not end at 5 mA, an output strays
//! more than 1 % of its range from the reference (where it is also 10x more than the
//! reference from a tighter one), or
//! the peer (at rtol 1e-10 or tighter) more than 1e-5 of it where the reference is within
//! 1e-9 of the tighter one.

mod fmi;
mod fmu_run;
mod instructions;
mod mujoco;
mod peer;
mod reference;
mod report;
mod timing;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use ehsv_actuator::variables::{vr, VARIABLES};
// The signals live in the crate's library: `step_profile` runs the same workloads.
use ehsv_tests::workloads;
use fmi::{Fmu, Version};
use reference::Trace;
use report::{PeerSummary, Row};
use timing::{Repeats, Samples, Summary};
use workloads::{Signal, Workload, I_AMPLITUDE};

/// An output further than this fraction of its range from the reference (and further than
/// the trajectory's conditioning explains, see `measure`) is an error.
const DEVIATION_LIMIT: f64 = 1e-2;
/// The same for `solver.method = fixed_cost`: bounded and stable (docs/solvers.md).
const FIXED_COST_DEVIATION_LIMIT: f64 = 0.2;
/// The peer's default tolerance: near the FMU's accuracy (see `docs/benchmark.md`).
const PEER_RTOL: f64 = 1e-10;
/// At [`PEER_RTOL`] or tighter, the peer further than this fraction of an output's range
/// from the reference is an error where the trajectory is [`WELL_CONDITIONED`].
const FIDELITY_LIMIT: f64 = 1e-5;
/// A reference no further than this fraction of the range from a 10x tighter one: the
/// trajectory does not amplify small differences of the equations (every workload stays
/// below 6e-10 where it is well-conditioned).
const WELL_CONDITIONED: f64 = 1e-9;
/// The quadruped runs at this step only unless `--all-h`.
const QUADRUPED_H: f64 = report::TARGET_STEP;

struct Options {
    lib: PathBuf,
    t_end: f64,
    steps: Vec<f64>,
    versions: Vec<Version>,
    only: Option<String>,
    /// `solver.method` codes to run every workload with (`--method`).
    methods: Vec<i64>,
    repeat: usize,
    peer_rtol: f64,
    reference_rtol: f64,
    peer: bool,
    require_peer: bool,
    all_h: bool,
    /// `solver.rtol` of the FMU (None: its default).
    fmu_rtol: Option<f64>,
    /// `solver.h_internal` of the FMU (None: its default).
    h_internal: Option<f64>,
    /// Count instructions per communication step with callgrind (off without valgrind).
    instructions: bool,
    /// Print only those (`--instructions-only`), and over how many steps.
    instructions_only: bool,
    instr_steps: usize,
    /// The MuJoCo plugin's rollouts after the table (`--mujoco`), or alone (`--mujoco-only`).
    mujoco: bool,
    mujoco_only: bool,
}

fn default_library() -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join("target"));
    let file = if cfg!(target_os = "windows") {
        "ehsv_actuator.dll"
    } else if cfg!(target_os = "macos") {
        "libehsv_actuator.dylib"
    } else {
        "libehsv_actuator.so"
    };
    let lib = target.join("release").join(file);
    lib.canonicalize().unwrap_or(lib)
}

fn parse() -> Result<Options, String> {
    let mut o = Options {
        lib: default_library(),
        t_end: 2.0,
        steps: vec![1e-3, 1e-4, 1e-5],
        versions: vec![Version::Fmi2, Version::Fmi3],
        only: None,
        methods: vec![workloads::EXACT, workloads::FIXED_COST],
        repeat: 3,
        peer_rtol: PEER_RTOL,
        reference_rtol: reference::REFERENCE_RTOL,
        peer: true,
        require_peer: false,
        all_h: false,
        fmu_rtol: None,
        h_internal: None,
        instructions: true,
        instructions_only: false,
        instr_steps: instructions::STEPS,
        mujoco: false,
        mujoco_only: false,
    };
    let mut args = std::env::args().skip(1);
    let number = |v: Option<String>, what: &str| -> Result<f64, String> {
        v.and_then(|s| s.parse().ok()).ok_or(format!("{what} needs a number"))
    };
    while let Some(a) = args.next() {
        match a.as_str() {
            "--quick" => {
                o.t_end = 0.02;
                o.steps = vec![1e-4];
                o.repeat = 1;
                o.instr_steps = instructions::QUICK_STEPS;
            }
            "--t-end" => o.t_end = number(args.next(), "--t-end")?,
            "--h" => {
                o.steps = args
                    .next()
                    .ok_or("--h needs a list")?
                    .split(',')
                    .map(|s| s.parse().map_err(|_| format!("--h: bad step {s}")))
                    .collect::<Result<_, _>>()?
            }
            "--fmi" => {
                o.versions = match args.next().as_deref() {
                    Some("2") => vec![Version::Fmi2],
                    Some("3") => vec![Version::Fmi3],
                    Some("both") => vec![Version::Fmi2, Version::Fmi3],
                    _ => return Err("--fmi takes 2, 3 or both".into()),
                }
            }
            "--method" => {
                o.methods = match args.next().as_deref() {
                    Some("exact") => vec![workloads::EXACT],
                    Some("fixed_cost") => vec![workloads::FIXED_COST],
                    Some("both") => vec![workloads::EXACT, workloads::FIXED_COST],
                    _ => return Err("--method needs exact, fixed_cost or both".into()),
                }
            }
            "--only" => o.only = Some(args.next().ok_or("--only needs a name")?),
            "--repeat" => o.repeat = number(args.next(), "--repeat")?.max(1.0) as usize,
            "--peer-rtol" => o.peer_rtol = number(args.next(), "--peer-rtol")?,
            "--reference-rtol" => o.reference_rtol = number(args.next(), "--reference-rtol")?,
            "--fmu-rtol" => o.fmu_rtol = Some(number(args.next(), "--fmu-rtol")?),
            "--h-internal" => o.h_internal = Some(number(args.next(), "--h-internal")?),
            "--no-peer" => o.peer = false,
            "--require-peer" => o.require_peer = true,
            "--all-h" => o.all_h = true,
            "--no-instructions" => o.instructions = false,
            "--mujoco" => o.mujoco = true,
            "--mujoco-only" => o.mujoco_only = true,
            "--instructions-only" => o.instructions_only = true,
            "--instr-steps" => {
                o.instr_steps = number(args.next(), "--instr-steps")?.max(1.0) as usize
            }
            "--lib" => o.lib = PathBuf::from(args.next().ok_or("--lib needs a path")?),
            "-h" | "--help" => return Err(String::new()),
            other => return Err(format!("unknown argument {other}")),
        }
    }
    Ok(o)
}

/// Every figure of one workload at one step size; rows for each FMI version.
fn measure(
    o: &Options,
    fmus: &[Fmu],
    cvode: Option<&peer::Api>,
    w: &Workload,
    h: f64,
    problems: &mut Vec<String>,
) -> Result<Vec<Row>, String> {
    let case = Case::new(o, w, h)?;
    let mut rows = Vec::new();
    let mut first_trace: Option<Trace> = None;
    for fmu in fmus {
        let (row, trace) = case.measure_version(fmu, cvode, first_trace.as_ref(), problems)?;
        rows.push(row);
        first_trace.get_or_insert(trace);
    }
    // Counted once per workload, method and step (through FMI 2), shown on the first row.
    if let Some(first) = rows.first_mut() {
        first.instructions = count_instructions(o, w, h, problems);
    }
    Ok(rows)
}

/// Instructions per communication step of `w` at `h` (callgrind), if counted; a failed
/// count is a problem.
fn count_instructions(
    o: &Options,
    w: &Workload,
    h: f64,
    problems: &mut Vec<String>,
) -> Option<f64> {
    if !o.instructions {
        return None;
    }
    instructions::per_step(w, o.instr_steps, h)
        .map_err(|e| problems.push(format!("{}: instructions per step at h = {h}: {e}", w.name)))
        .ok()
}

/// One workload at one step size and the reference its rows are judged against.
struct Case<'a> {
    o: &'a Options,
    w: &'a Workload,
    h: f64,
    steps: usize,
    reference: Trace,
    /// The worst distance of the reference from the same run 10x tighter.
    reference_spread: (f64, usize),
    /// How much looser the FMU integrates than the reference (see `check_deviation`).
    looser: f64,
    /// The FMU's integrator work on the run (through the rlib).
    work: report::WorkSummary,
}

impl<'a> Case<'a> {
    fn new(o: &'a Options, w: &'a Workload, h: f64) -> Result<Self, String> {
        let steps = (o.t_end / h).round() as usize;
        let reference = reference::run(w, w.legs[0], h, steps, o.reference_rtol)?;
        // How far the yardstick itself is converged: the same run 10x tighter.
        let tighter = reference::run(w, w.legs[0], h, steps, 0.1 * o.reference_rtol)?;
        let reference_spread = report::worst(&reference::deviation(&reference, &tighter));
        let looser =
            (o.fmu_rtol.unwrap_or(VARIABLES[vr::SOLVER_RTOL].start) / o.reference_rtol).max(1.0);
        let work = report::WorkSummary::new(&reference::fmu_work(w, w.legs[0], h, steps)?, steps);
        Ok(Case { o, w, h, steps, reference, reference_spread, looser, work })
    }

    /// The row of one FMI version and its outputs. `first_trace` is the outputs of the
    /// version measured before, if any: the slowest steps are diagnosed and the peer is
    /// run only with the first version, as either runs the same computation.
    fn measure_version(
        &self,
        fmu: &Fmu,
        cvode: Option<&peer::Api>,
        first_trace: Option<&Trace>,
        problems: &mut Vec<String>,
    ) -> Result<(Row, Trace), String> {
        let (w, h) = (self.w, self.h);
        let best = self.best_untimed_run(fmu)?;
        let timed = self.timed_runs(fmu)?;
        let step_cpu = timed.cpu.shortest.summary();
        let slowest = match first_trace {
            None => Some(self.diagnose_slowest(&timed.cpu.shortest, step_cpu)?),
            Some(_) => None,
        };
        if first_trace.is_some_and(|first| *first != best.trace) {
            return Err(format!("{}: FMI 2 and FMI 3 outputs differ at h = {h}", w.name));
        }
        let dev = self.check_deviation(fmu, &best.trace, problems);
        self.check_signal_outcome(&best.trace)?;
        let peer = match cvode.filter(|_| first_trace.is_none()) {
            Some(api) => Some(run_peer(self.o, api, w, h, self.steps, best.cpu, &self.reference)?),
            None => None,
        };
        if let Some(p) = &peer {
            self.check_peer_fidelity(p, problems);
        }
        let sim_time = self.steps as f64 * h;
        let row = Row {
            workload: w.name.clone(),
            instances: w.legs.len(),
            h,
            version: fmu.version(),
            rtf_wall: sim_time / best.wall,
            rtf_cpu: sim_time / best.cpu,
            instructions: None,
            step_cpu,
            step_cpu_raw: timed.cpu.longest,
            step_wall_raw: timed.wall.longest,
            lock_step: timed
                .lock_step
                .map(|r| report::LockStep { work: r.shortest.summary(), raw: r.longest }),
            slowest,
            deviation: Some(dev),
            reference_spread: self.reference_spread,
            work: self.work,
            peer,
        };
        Ok((row, best.trace))
    }

    /// The untimed run with the shortest wall time of `repeat`.
    fn best_untimed_run(&self, fmu: &Fmu) -> Result<fmu_run::FmuRun, String> {
        let mut best: Option<fmu_run::FmuRun> = None;
        for _ in 0..self.o.repeat {
            let r = fmu_run::run(fmu, self.w, self.h, self.steps, false)?;
            if best.as_ref().is_none_or(|b| r.wall < b.wall) {
                best = Some(r);
            }
        }
        Ok(best.unwrap())
    }

    /// `repeat` timed runs: per doStep (and per lock-step of all instances, if more than one)
    /// the shortest time over the runs, the work of the call, and the longest sample of all.
    /// A run preallocates its samples, so the timed loop itself allocates nothing.
    fn timed_runs(&self, fmu: &Fmu) -> Result<TimedRuns, String> {
        let (w, h, steps) = (self.w, self.h, self.steps);
        let legs = w.legs.len();
        let mut runs: Option<TimedRuns> = None;
        for _ in 0..self.o.repeat {
            let run = fmu_run::run(fmu, w, h, steps, true)?;
            let lock_step = (legs > 1).then(|| run.step_cpu.lock_steps(legs));
            match runs.as_mut() {
                None => {
                    runs = Some(TimedRuns {
                        cpu: Repeats::new(run.step_cpu),
                        wall: Repeats::new(run.step_wall),
                        lock_step: lock_step.map(Repeats::new),
                    })
                }
                Some(r) => {
                    r.cpu.add(&run.step_cpu);
                    r.wall.add(&run.step_wall);
                    if let (Some(r), Some(l)) = (r.lock_step.as_mut(), lock_step) {
                        r.add(&l);
                    }
                }
            }
        }
        runs.ok_or_else(|| "no timed run".into())
    }

    /// The slowest doStep and, if that was a first step, the slowest after the first steps,
    /// each with the work the FMU's integrators did in it.
    fn diagnose_slowest(
        &self,
        least: &Samples,
        step_cpu: Summary,
    ) -> Result<(report::SlowStep, Option<report::SlowStep>), String> {
        let (w, h) = (self.w, self.h);
        let legs = w.legs.len();
        let diagnose = |call: usize, cpu: f64| -> Result<report::SlowStep, String> {
            let (k, leg) = (call / legs, call % legs);
            let work = reference::work_of_step(w, w.legs[leg], h, k)?;
            Ok(report::SlowStep { cpu, t: k as f64 * h, leg, work })
        };
        // The first step builds the propagators: the slowest after it, too.
        let later = match least.slowest_from(legs) {
            Some((call, cpu)) if call != step_cpu.slowest => Some(diagnose(call, cpu)?),
            _ => None,
        };
        Ok((diagnose(step_cpu.slowest, step_cpu.max)?, later))
    }

    /// The worst deviation of `trace` from the reference (a fraction of the output's range,
    /// and which output); a problem if it is beyond the limit.
    fn check_deviation(
        &self,
        fmu: &Fmu,
        trace: &Trace,
        problems: &mut Vec<String>,
    ) -> (f64, usize) {
        let mut deviations = reference::deviation(trace, &self.reference);
        if self.w.solver_method == workloads::FIXED_COST && self.w.driver == workloads::HBRIDGE_PID
        {
            // fixed_cost's bridge voltage is its PWM period's mean, the reference's the side the
            // bridge is on at that instant: not the same quantity (docs/solvers.md, H-bridge).
            deviations[workloads::U_DRIVER_COLUMN] = 0.0;
        }
        let dev = report::worst(&deviations);
        // Beyond the limit and well beyond what the trajectory's conditioning explains: the
        // reference moved by its spread for a 10x tighter tolerance, so an FMU that many
        // times looser may move that much more (hbridge_square_100Hz over 0.5 s: spread
        // 8.8e-4, the FMU at 1e-7 5.3e-1 off).
        // fixed_cost has no tolerance to loosen: its error is its internal step's.
        let limit = if self.w.solver_method == workloads::FIXED_COST {
            FIXED_COST_DEVIATION_LIMIT
        } else {
            DEVIATION_LIMIT
        };
        if dev.0.is_nan() || (dev.0 > limit && dev.0 > 10.0 * self.looser * self.reference_spread.0)
        {
            let (k, value, expected) = reference::worst_point(trace, &self.reference, dev.1);
            problems.push(format!(
                "{} {}: {} deviates {:.2e} of its range from the reference, most at t = {:.6} s: {value:e} instead of {expected:e}",
                fmu.version().label(),
                self.w.name,
                workloads::OUTPUT_NAMES[dev.1],
                dev.0,
                (k + 1) as f64 * self.h
            ));
        }
        dev
    }

    /// The outcomes two workloads are built for: idle stays where it starts, step_to_rest
    /// ends at its commanded current.
    fn check_signal_outcome(&self, trace: &Trace) -> Result<(), String> {
        let w = self.w;
        // Idle measures the calls alone: an instance whose state moves is doing other work.
        if w.legs[0] == Signal::Idle {
            if let Some(k) = trace.iter().position(|y| y != &trace[0]) {
                return Err(format!(
                    "{}: the outputs moved at t = {:.6} s though every input stays 0",
                    w.name,
                    (k + 1) as f64 * self.h
                ));
            }
        }
        if w.legs[0] == Signal::StepToRest {
            let i_end = trace.last().map_or(f64::NAN, |y| y[0]);
            if i_end.is_nan() || (i_end - I_AMPLITUDE).abs() > 1e-4 * I_AMPLITUDE {
                return Err(format!(
                    "{}: i_coil ended at {i_end} A, expected {I_AMPLITUDE} A",
                    w.name
                ));
            }
        }
        Ok(())
    }

    /// The fidelity target: the model the FMU integrates stays within 1e-5 of each
    /// output's range of an independent tight-tolerance integration of its equations,
    /// judged where the trajectory is well-conditioned (a ref spread of 2e-8 already
    /// came with the peer 3.9e-5 off: `hbridge_square_100Hz` at 0.3 s). Judged only with
    /// the peer at [`PEER_RTOL`] or tighter.
    fn check_peer_fidelity(&self, p: &PeerSummary, problems: &mut Vec<String>) {
        if self.o.peer_rtol > PEER_RTOL {
            return;
        }
        let (dev, output) = p.deviation;
        let judged = self.reference_spread.0 <= WELL_CONDITIONED;
        if dev.is_nan() || (judged && dev > FIDELITY_LIMIT) {
            problems.push(format!(
                "{}: the peer at rtol {:e} deviates {dev:.2e} of {}'s range from the reference (limit {FIDELITY_LIMIT:e})",
                self.w.name,
                self.o.peer_rtol,
                workloads::OUTPUT_NAMES[output]
            ));
        }
    }
}

/// The doStep times of a workload's timed runs, in thread CPU and wall time, and for a
/// lock-step of several instances the thread CPU time of each step's doSteps together.
struct TimedRuns {
    cpu: Repeats,
    wall: Repeats,
    lock_step: Option<Repeats>,
}

/// The peer on every leg of the workload (its accuracy on the first).
fn run_peer(
    o: &Options,
    api: &peer::Api,
    w: &Workload,
    h: f64,
    steps: usize,
    fmu_cpu: f64,
    reference: &reference::Trace,
) -> Result<PeerSummary, String> {
    let mut total: Option<peer::PeerRun> = None;
    for &signal in &w.legs {
        let r = peer::run(api, w, signal, h, steps, o.peer_rtol)?;
        match total.as_mut() {
            None => total = Some(r),
            Some(t) => {
                t.cpu += r.cpu;
                t.wall += r.wall;
                t.counters.steps += r.counters.steps;
                t.counters.jacobians += r.counters.jacobians;
                t.counters.lu += r.counters.lu;
                t.counters.error_test_failures += r.counters.error_test_failures;
                t.restarts += r.restarts;
            }
        }
    }
    let total = total.unwrap();
    let dev = report::worst(&reference::deviation(&total.trace, reference));
    let points = steps * w.legs.len();
    Ok(PeerSummary::new(&total, steps as f64 * h, points, fmu_cpu, dev))
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().is_some_and(|a| a == instructions::CHILD_FLAG) {
        return exit_with(instructions::child(&args[1..]));
    }
    let mut o = match parse() {
        Ok(o) => o,
        Err(e) => {
            if !e.is_empty() {
                eprintln!("bench: {e}");
            }
            eprintln!("usage: bench [--quick] [--t-end S] [--h LIST] [--fmi 2|3|both] [--only NAME,NAME] [--repeat N] [--peer-rtol R] [--reference-rtol R] [--fmu-rtol R] [--h-internal S] [--no-peer] [--require-peer] [--all-h] [--lib PATH] [--instructions-only] [--instr-steps N] [--no-instructions] [--mujoco] [--mujoco-only]");
            return if e.is_empty() { ExitCode::SUCCESS } else { ExitCode::FAILURE };
        }
    };
    if o.instructions {
        if let Some(why) = instructions::unavailable() {
            println!("instr/step: skipped, {why} (install valgrind to count instructions)");
            o.instructions = false;
        }
    }
    if o.instructions_only {
        return exit_with(print_instructions_only(&o));
    }
    if o.mujoco_only {
        return exit_with(mujoco::print_rollouts());
    }
    let (fmus, cvode) = match load_fmus(&o).and_then(|fmus| Ok((fmus, load_peer(&o)?))) {
        Ok(loaded) => loaded,
        Err(e) => {
            eprintln!("bench: {e}");
            return ExitCode::FAILURE;
        }
    };
    print_preamble(&o);
    let mut results = measure_all(&o, &fmus, cvode.as_ref());
    print_closing(&o, &results);
    if o.mujoco {
        if let Err(e) = mujoco::print_rollouts() {
            results.problems.push(e);
        }
    }
    for p in &results.problems {
        eprintln!("bench: {p}");
    }
    if results.failed || !results.problems.is_empty() {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

/// Success, or the error printed and failure.
fn exit_with(result: Result<(), String>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("bench: {e}");
            ExitCode::FAILURE
        }
    }
}

/// `--instructions-only`: instructions per communication step of every selected workload,
/// method and step, nothing timed (the FMU's library is not loaded: the rlib is stepped).
fn print_instructions_only(o: &Options) -> Result<(), String> {
    if !o.instructions {
        return Err("--instructions-only needs valgrind".into());
    }
    println!("{}", instructions::HOPSAN_REFERENCE);
    println!("{}", report::INSTRUCTIONS_NOTE);
    println!("{:<26} {:>5} {:>10} {:>12}", "workload", "h", "method", "instr/step");
    for (h, w) in selected_runs(o) {
        let per_step = instructions::per_step(&w, o.instr_steps, h)?;
        let method = instructions::method_name(w.solver_method);
        let count = report::instructions(Some(per_step));
        println!("{:<26} {h:>5.0e} {method:>10} {count:>12}", w.name);
    }
    Ok(())
}

/// The FMU's library, once per FMI version asked for.
fn load_fmus(o: &Options) -> Result<Vec<Fmu>, String> {
    if !o.lib.exists() {
        return Err(format!(
            "{} not found: build it with `cargo build --release -p ehsv-actuator`",
            o.lib.display()
        ));
    }
    o.versions.iter().map(|&v| Fmu::load(&o.lib, v)).collect()
}

/// CVODE if the peer is wanted and installed; without it the peer columns stay empty,
/// unless `--require-peer`.
fn load_peer(o: &Options) -> Result<Option<peer::Api>, String> {
    if !o.peer {
        return Ok(None);
    }
    match peer::Api::load() {
        Ok(api) => Ok(Some(api)),
        Err(e) if !o.require_peer => {
            println!("peer: {e}; the peer columns stay empty (scripts/setup-bench.sh installs it)");
            Ok(None)
        }
        Err(e) => Err(format!("--require-peer: {e} (scripts/setup-bench.sh installs it)")),
    }
}

/// What the run is, the workloads, and the table's header.
fn print_preamble(o: &Options) {
    println!("EhsvActuator benchmark through the FMI C API ({})", o.lib.display());
    println!(
        "{} s simulated per run, best of {} untimed run(s); peer rtol {:e}",
        o.t_end, o.repeat, o.peer_rtol
    );
    println!("{}", report::timed_runs_note(o.repeat));
    println!("{}", workloads::DESCRIPTION);
    if o.instructions {
        println!("{}", report::INSTRUCTIONS_NOTE);
    }
    println!("{}", instructions::HOPSAN_REFERENCE);
    println!();
    report::header();
}

/// What the rows leave for after the table.
#[derive(Default)]
struct Results {
    /// A workload could not be measured (its error is printed when it happens).
    failed: bool,
    /// Checks that failed, printed at the end.
    problems: Vec<String>,
    /// The lines about each row's slowest doStep.
    slowest: Vec<String>,
    /// The lines about each row against the targets.
    targets: Vec<String>,
    /// The exact method's RTFcpu on the workload just measured (FMI 2, at the targets' step),
    /// which fixed_cost's is judged against.
    exact_rtf: Option<f64>,
}

/// Every selected workload at every step size, its rows printed as they are measured.
fn measure_all(o: &Options, fmus: &[Fmu], cvode: Option<&peer::Api>) -> Results {
    let mut results = Results::default();
    for (h, w) in selected_runs(o) {
        measure_method(o, (fmus, cvode), &w, h, &mut results);
    }
    results
}

/// Every selected workload, with each method asked for, at every step size, in the order
/// the bench runs them: `(h, workload)`.
fn selected_runs(o: &Options) -> Vec<(f64, Workload)> {
    let mut runs = Vec::new();
    for &h in &o.steps {
        for w in workloads::all() {
            let w = Workload { solver_rtol: o.fmu_rtol, h_internal: o.h_internal, ..w };
            if selected(o, &w, h) {
                runs.extend(o.methods.iter().map(|&method| (h, w.with_method(method))));
            }
        }
    }
    runs
}

/// One workload through one method at `h`: its rows printed and their lines kept.
fn measure_method(
    o: &Options,
    (fmus, cvode): (&[Fmu], Option<&peer::Api>),
    w: &Workload,
    h: f64,
    results: &mut Results,
) {
    match measure(o, fmus, cvode, w, h, &mut results.problems) {
        Ok(rows) => {
            rows.iter().for_each(report::print);
            results.slowest.extend(rows.iter().filter_map(report::slowest_steps));
            let current_mode = w.control_mode == workloads::CURRENT;
            if w.solver_method != workloads::FIXED_COST {
                results.exact_rtf = rows.iter().find_map(report::rtf_at_target);
            }
            let exact_rtf = results.exact_rtf;
            let verdict = |row| match w.solver_method {
                workloads::FIXED_COST => report::fixed_cost_targets(row, current_mode, exact_rtf),
                _ => report::targets(row),
            };
            results.targets.extend(rows.iter().filter_map(verdict));
        }
        Err(e) => {
            eprintln!("bench: {}, h = {h}: {e}", w.name);
            results.failed = true;
        }
    }
}

/// Whether `--only` names the workload, and the quadruped at `h` unless `--all-h`.
fn selected(o: &Options, w: &Workload, h: f64) -> bool {
    if o.only.as_ref().is_some_and(|names| !names.split(',').any(|n| n == w.name)) {
        return false;
    }
    !(w.is_quadruped() && h != QUADRUPED_H && !o.all_h)
}

/// The legend, the slowest steps and the rows against the targets.
fn print_closing(o: &Options, results: &Results) {
    println!();
    println!("{}", report::LEGEND);
    println!();
    println!("{}", report::SLOWEST_HEADER);
    results.slowest.iter().for_each(|line| println!("{line}"));
    if !results.targets.is_empty() {
        println!();
        println!("{}", report::targets_header(o.t_end));
        println!("{}", report::FIXED_COST_TARGETS);
        results.targets.iter().for_each(|line| println!("{line}"));
    }
}
