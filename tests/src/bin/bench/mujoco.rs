//! `--mujoco`: the actuator as MuJoCo's engine plugin (`ehsv.actuator`, the crate
//! `ehsv-mujoco`) in the quadruped of `cosim-examples/mjcf/quadruped.xml`, beside the same
//! robot with MuJoCo's own position actuators, through `mujoco.rollout` in MuJoCo's C
//! threads: `cosim-examples/rollout.py` run in the project's venv, its table printed here,
//! at each host timestep of [`HOST_TIMESTEPS`] with the plugin's internal step 1e-4 s.
//! Robots, commands and the comparison model are the script's (one place for them).

use std::path::{Path, PathBuf};
use std::process::Command;

/// MuJoCo's timesteps the rollouts run at (s).
const HOST_TIMESTEPS: [&str; 2] = ["1e-4", "1e-3"];
/// Robots per rollout and simulated seconds of each: small enough for a bench run.
const ROBOTS: &str = "4";
const DURATION: &str = "0.3";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Runs the rollouts and prints their tables; an error names what is missing (the venv of
/// `scripts/setup-venv.sh`, the plugin of `cargo build --release -p ehsv-mujoco`).
pub fn print_rollouts() -> Result<(), String> {
    let root = root();
    let python = root.join(".venv/bin/python");
    if !python.exists() {
        return Err(format!(
            "--mujoco needs the venv ({}): scripts/setup-venv.sh",
            python.display()
        ));
    }
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target"));
    let plugin = target.join("release/libehsv_mujoco.so");
    if !plugin.exists() {
        return Err(format!(
            "--mujoco needs the plugin ({}): cargo build --release -p ehsv-mujoco",
            plugin.display()
        ));
    }
    println!("\nMuJoCo plugin: cosim-examples/rollout.py (ratio = hydraulic / position actuators)");
    for timestep in HOST_TIMESTEPS {
        let out = Command::new(&python)
            .current_dir(&root)
            .env("EHSV_MUJOCO_PLUGIN", &plugin)
            .args(["cosim-examples/rollout.py", "--n", ROBOTS, "--duration", DURATION])
            .args(["--timestep", timestep, "--substep", "1e-4", "--method", "both"])
            .output()
            .map_err(|e| format!("cannot run {}: {e}", python.display()))?;
        print!("{}", String::from_utf8_lossy(&out.stdout));
        if !out.status.success() {
            return Err(format!(
                "rollout.py at timestep {timestep} failed: {}",
                String::from_utf8_lossy(&out.stderr)
            ));
        }
    }
    Ok(())
}
