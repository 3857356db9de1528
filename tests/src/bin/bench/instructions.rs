//! Instructions per communication step, counted with callgrind (they do not move with the
//! machine's load, unlike the times): the bench runs itself under valgrind in a child mode
//! ([`CHILD_FLAG`]) that steps the workload through the FMI 2 C API
//! (`ehsv_tests::capi_steps`: SetReal of the inputs, DoStep, GetReal of i_coil, x_piston, p_A
//! and Q_valve per instance and step), with `--toggle-collect` on the function that holds
//! those calls, and divides the total by the steps taken.

use std::path::PathBuf;
use std::process::Command;

use ehsv_tests::capi_steps;
use ehsv_tests::workloads::{self, Workload};

/// The first argument that makes the bench the child that valgrind runs.
pub const CHILD_FLAG: &str = "--instructions-child";
/// Steps counted per (workload, method): 0.5 s at 1e-4 (as `scripts/profile-step.sh`), and
/// with `--quick`.
pub const STEPS: usize = 5000;
pub const QUICK_STEPS: usize = 500;

/// Hopsan's figure, the reference (not measured here).
pub const HOPSAN_REFERENCE: &str = "\
reference (issue 37, measured there, not by this bench): Hopsan 2.24's servo valve + cylinder + mass model \
at a fixed 1e-4 s step: 1,377 (step command) - 1,476 (square command) instructions per step";

/// Whether valgrind can be run; `None` with the reason if not.
pub fn unavailable() -> Option<String> {
    match Command::new("valgrind").arg("--version").output() {
        Ok(out) if out.status.success() => None,
        Ok(out) => Some(format!("valgrind --version failed ({})", out.status)),
        Err(e) => Some(format!("valgrind not found ({e})")),
    }
}

/// Instructions per communication step of one instance (all instances' steps counted) for
/// `workload` with its method, `steps` steps of `h`.
pub fn per_step(workload: &Workload, steps: usize, h: f64) -> Result<f64, String> {
    let exe = std::env::current_exe().map_err(|e| format!("current_exe: {e}"))?;
    let out_file = temp_file(&workload.name, workload.solver_method);
    let run = Command::new("valgrind")
        .arg("--tool=callgrind")
        .arg(format!("--toggle-collect=*{}*", capi_steps::MARKER))
        .arg(format!("--callgrind-out-file={}", out_file.display()))
        .arg(exe)
        .args([CHILD_FLAG, base_name(workload), method_name(workload.solver_method)])
        .args([steps.to_string(), h.to_string()])
        .args([optional(workload.solver_rtol), optional(workload.h_internal)])
        .output()
        .map_err(|e| format!("valgrind: {e}"))?;
    let counted = std::fs::read_to_string(&out_file);
    let _ = std::fs::remove_file(&out_file);
    if !run.status.success() {
        let stderr = String::from_utf8_lossy(&run.stderr);
        let tail: Vec<&str> = stderr.lines().rev().take(5).collect();
        return Err(format!("valgrind run failed: {}", tail.join(" / ")));
    }
    let calls = String::from_utf8_lossy(&run.stdout)
        .split_whitespace()
        .find_map(|w| w.parse::<usize>().ok())
        .ok_or("the child printed no step count")?;
    let total = total_instructions(&counted.map_err(|e| format!("callgrind output: {e}"))?)?;
    Ok(total as f64 / calls as f64)
}

/// The workload's name without the method's suffix (`with_method`).
fn base_name(workload: &Workload) -> &str {
    workload.name.strip_suffix("/fc").unwrap_or(&workload.name)
}

/// `solver.rtol` or `solver.h_internal` for the child: the value, or `-` for the default.
fn optional(value: Option<f64>) -> String {
    value.map_or("-".into(), |v| v.to_string())
}

fn temp_file(workload: &str, method: i64) -> PathBuf {
    let workload = workload.replace('/', "_");
    std::env::temp_dir().join(format!("bench-callgrind-{}-{workload}-{method}", std::process::id()))
}

pub fn method_name(method: i64) -> &'static str {
    if method == workloads::FIXED_COST {
        "fixed_cost"
    } else {
        "exact"
    }
}

/// The `summary:` (or `totals:`) line of a callgrind output file: the instructions counted.
fn total_instructions(callgrind: &str) -> Result<u64, String> {
    callgrind
        .lines()
        .find_map(|l| l.strip_prefix("summary:").or_else(|| l.strip_prefix("totals:")))
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .ok_or_else(|| "no summary line in the callgrind output".into())
}

/// The child valgrind runs: `bench --instructions-child WORKLOAD METHOD STEPS H RTOL
/// H_INTERNAL` (the last two `-` for the FMU's defaults) steps the workload through the C API
/// and prints the number of communication steps taken.
pub fn child(args: &[String]) -> Result<(), String> {
    let [name, method, steps, h, rtol, h_internal] = args else {
        return Err(format!(
            "usage: bench {CHILD_FLAG} WORKLOAD exact|fixed_cost STEPS H RTOL|- H_INTERNAL|-"
        ));
    };
    let method = match method.as_str() {
        "exact" => workloads::EXACT,
        "fixed_cost" => workloads::FIXED_COST,
        other => return Err(format!("method {other}: exact or fixed_cost")),
    };
    let workload = workloads::all()
        .into_iter()
        .find(|w| &w.name == name)
        .ok_or_else(|| format!("no workload {name}"))?
        .with_method(method);
    let steps: usize = steps.parse().map_err(|_| format!("bad step count {steps}"))?;
    let h: f64 = h.parse().map_err(|_| format!("bad step {h}"))?;
    let number = |s: &String| -> Result<Option<f64>, String> {
        (s != "-").then(|| s.parse().map_err(|_| format!("bad number {s}"))).transpose()
    };
    let workload =
        Workload { solver_rtol: number(rtol)?, h_internal: number(h_internal)?, ..workload };
    let calls = capi_steps::run(&workload, steps, h)?;
    println!("{calls} communication steps");
    Ok(())
}
