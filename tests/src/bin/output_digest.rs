//! A digest of every output of every benchmark workload, both methods, through the FMI 2
//! C API: for checking that a change meant to leave the results alone (a faster path, a
//! reorganisation) does, bit for bit.
//!
//! ```text
//! output_digest [STEPS] [--skip NAME[,NAME...]]
//!     # default 5000 steps of 1e-4 s (the bench's 0.5 s); --skip leaves the named outputs
//!     # out, to compare with a build that predates them (Q_supply: before issue 44)
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
    let (mut steps, mut skip) = (DEFAULT_STEPS, Vec::<String>::new());
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let parsed = match arg.as_str() {
            "--skip" => {
                args.next().map(|names| skip = names.split(',').map(str::to_string).collect())
            }
            _ => arg.parse().ok().map(|n| steps = n),
        };
        if parsed.is_none() {
            eprintln!("usage: output_digest [STEPS] [--skip NAME[,NAME...]]");
            return ExitCode::FAILURE;
        }
    }
    let mut failed = false;
    for workload in workloads::all() {
        for method in [workloads::EXACT, FIXED_COST] {
            let w = workload.with_method(method);
            match capi_steps::digest(&w, steps, H, &skip) {
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
