//! A digest of every output of every benchmark workload, both methods, through the FMI 2
//! C API: for checking that a change meant to leave the results alone (a faster path, a
//! reorganisation) does, bit for bit.
//!
//! ```text
//! output_digest [STEPS]       # default 5000 steps of 1e-4 s (the bench's 0.5 s)
//! ```
//!
//! Prints one line per workload and method: the FNV-1a hash of the bits of every output
//! (all of the table's outputs, read after every step of every instance, in order), and the
//! last step's x_piston and p_A for a look. Compare the lines before and after a change.

use std::process::ExitCode;

use ehsv_tests::capi_steps;
use ehsv_tests::workloads::{self, FIXED_COST};

const DEFAULT_STEPS: usize = 5000;
const H: f64 = 1e-4;

fn main() -> ExitCode {
    let steps = match std::env::args().nth(1).map(|s| s.parse::<usize>()) {
        None => DEFAULT_STEPS,
        Some(Ok(n)) => n,
        Some(Err(_)) => {
            eprintln!("usage: output_digest [STEPS]");
            return ExitCode::FAILURE;
        }
    };
    let mut failed = false;
    for workload in workloads::all() {
        for method in [workloads::EXACT, FIXED_COST] {
            let w = workload.with_method(method);
            match capi_steps::digest(&w, steps, H) {
                Ok((hash, last)) => {
                    println!(
                        "{:<28} {hash:016x}  x_piston {:+.9e}  p_A {:.9e}",
                        w.name, last[0], last[1]
                    )
                }
                Err(e) => {
                    println!("{:<28} failed: {e}", w.name);
                    failed = true;
                }
            }
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}
