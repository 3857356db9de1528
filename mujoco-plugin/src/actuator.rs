//! One plugin actuator: an EhsvActuator with the motion port, whose whole state lives in a
//! slice of mjData's `plugin_state` ([`Layout`]); the [`Physics`] held here is a
//! cache of that state, rebuilt from the slots whenever they change under it (reset, copy,
//! `mj_setState`, a rollout's initial state).
//!
//! The slots of one actuator ([`Layout`]): first the outputs, one slot per output variable
//! of the FMU in table order ([`output_names`]; F_rod is the mean over the last MuJoCo
//! step), then the number of state bytes, then the state bytes six to a slot, each slot the
//! integer `2^52 + b0 + 256 b1 + ... + 256^5 b5` (an ordinary finite double, so any copy
//! carries it bit for bit).

use ehsv_physics::bytes::ByteReader;
use ehsv_physics::{readable, Inputs, Physics};
use ehsv_variables::variables::{inputs, vr, write_outputs, Causality, N_VARIABLES, VARIABLES};

use crate::config::Config;

/// State bytes per slot and the slot's offset (2^52: the integers from there to 2^53 are
/// exactly the doubles with exponent 52).
const BYTES_PER_SLOT: usize = 6;
const SLOT_BASE: u64 = 0x4330_0000_0000_0000;

/// The output variables' value references, in table order.
fn output_indices() -> impl Iterator<Item = usize> {
    (0..VARIABLES.len()).filter(|&i| VARIABLES[i].causality == Causality::Output)
}

/// The output variables' names, in the order of their slots.
pub fn output_names() -> Vec<&'static str> {
    output_indices().map(|i| VARIABLES[i].name).collect()
}

/// Where things are in an actuator's slots.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    pub outputs: usize,
    pub state_bytes: usize,
}

impl Layout {
    /// The slot holding the number of state bytes.
    pub fn length_slot(&self) -> usize {
        self.outputs
    }
    pub fn slots(&self) -> usize {
        self.outputs + 1 + self.state_bytes.div_ceil(BYTES_PER_SLOT)
    }
}

/// Packs `bytes` into slots after the header (see the module's documentation).
fn pack(bytes: &[u8], out: &mut [f64]) {
    let word = |chunk: &[u8]| {
        let mut word = [0u8; 8];
        word[..chunk.len()].copy_from_slice(chunk);
        f64::from_bits(SLOT_BASE | u64::from_le_bytes(word))
    };
    // Whole chunks by a copy of known length (every step packs the state: a copy of a
    // length known only at run time costs a call each), then what is left.
    let whole = bytes.chunks_exact(BYTES_PER_SLOT);
    let rest = whole.remainder();
    let mut slots = out.iter_mut();
    // The chunks first: zip asks its first iterator first, so no slot is taken past them.
    for (chunk, slot) in whole.zip(slots.by_ref()) {
        let chunk: &[u8; BYTES_PER_SLOT] = chunk.try_into().expect("chunks_exact");
        *slot = word(chunk);
    }
    if let (false, Some(slot)) = (rest.is_empty(), slots.next()) {
        *slot = word(rest);
    }
}

/// Inverse of [`pack`]; refuses a slot that is not a packed one.
fn unpack(slots: &[f64], n: usize) -> Result<Vec<u8>, String> {
    let mut bytes = Vec::with_capacity(slots.len() * BYTES_PER_SLOT);
    for slot in slots {
        let bits = slot.to_bits();
        if bits & !0xffff_ffff_ffff != SLOT_BASE {
            return Err(format!("plugin_state holds {}, not a packed state slot", readable(*slot)));
        }
        bytes.extend_from_slice(&bits.to_le_bytes()[..BYTES_PER_SLOT]);
    }
    if n > bytes.len() {
        return Err(format!("plugin_state says {n} state bytes, its slots hold {}", bytes.len()));
    }
    bytes.truncate(n);
    Ok(bytes)
}

/// Whether two slices hold the same doubles bit for bit (NaN and -0 included).
fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// The step computed for the host's current step, not yet taken into the slots.
#[derive(Clone, Copy)]
struct Pending {
    /// Time, timestep, length, velocity and control, as bits.
    key: [u64; 5],
    force: f64,
}

/// One actuator (see the module's documentation).
#[derive(Clone)]
pub struct Actuator {
    pub config: Config,
    /// Inputs from the configuration (supply, driver supply); the host's fill the rest.
    base: Inputs,
    physics: Physics,
    /// The state at start: what a reset puts back.
    start: Physics,
    start_slots: Vec<f64>,
    /// The slots that `physics` (before `pending`, if any) holds.
    held: Vec<f64>,
    pending: Option<Pending>,
    pub layout: Layout,
    /// The state bytes' buffer (reused: no allocation in a step).
    bytes: Vec<u8>,
    /// The outputs' value references in slot order, and a value array the outputs are
    /// written into (kept: neither is built again at every step).
    output_refs: Vec<usize>,
    values: [f64; N_VARIABLES],
}

impl Actuator {
    /// Builds the actuator at rest in equilibrium at mid-stroke, command 0; refuses
    /// parameters that do not fit together (naming them) and a supply at or above the
    /// relief setting.
    pub fn new(config: Config) -> Result<Actuator, String> {
        let base = Inputs { x_rod: 0.0, v_rod: 0.0, a_rod: 0.0, ..inputs(&config.values) };
        let rest = Inputs { i_ref: 0.0, q_ref: 0.0, x_ref: 0.0, ..base };
        let mut start = Physics::start(&config.params, &rest, 0.0)?;
        // A step at rest checks what only a step checks (the supply against the relief).
        start.clone().step(&rest, 0.0, config.substep)?;
        start.prepare_first_step(&rest, 0.0, config.substep);
        let mut bytes = Vec::new();
        start.write_bytes(&mut bytes);
        let outputs = output_indices().count();
        let layout = Layout { outputs, state_bytes: bytes.len() };
        let mut actuator = Actuator {
            config,
            base,
            physics: start.clone(),
            start,
            start_slots: vec![0.0; layout.slots()],
            held: Vec::new(),
            pending: None,
            layout,
            bytes,
            output_refs: output_indices().collect(),
            values: [0.0; N_VARIABLES],
        };
        let mut slots = vec![0.0; layout.slots()];
        actuator.write_slots(actuator.start.rod_force_mean(), &mut slots);
        actuator.start_slots = slots.clone();
        actuator.held = slots;
        Ok(actuator)
    }

    /// Back to the start: the physics and the slots.
    pub fn reset(&mut self, slots: &mut [f64]) {
        self.physics = self.start.clone();
        slots.copy_from_slice(&self.start_slots);
        self.held.clone_from(&self.start_slots);
        self.pending = None;
    }

    /// Writes the outputs (F_rod = `force`) and the state bytes of `self.physics`.
    fn write_slots(&mut self, force: f64, slots: &mut [f64]) {
        let mut outputs = self.physics.outputs();
        outputs.f_rod = force;
        write_outputs(&outputs, &mut self.values);
        for (slot, &index) in slots.iter_mut().zip(&self.output_refs) {
            *slot = self.values[index];
        }
        self.bytes.clear();
        self.physics.write_bytes(&mut self.bytes);
        slots[self.layout.length_slot()] = self.bytes.len() as f64;
        pack(&self.bytes, &mut slots[self.layout.length_slot() + 1..]);
    }

    /// Rebuilds the physics from `slots` (a state set under it).
    fn restore(&mut self, slots: &[f64]) -> Result<(), String> {
        self.pending = None;
        let n = slots[self.layout.length_slot()];
        if n != self.layout.state_bytes as f64 {
            return Err(format!(
                "plugin_state holds {} state bytes, this actuator has {}",
                readable(n),
                self.layout.state_bytes
            ));
        }
        let bytes = unpack(&slots[self.layout.length_slot() + 1..], self.layout.state_bytes)?;
        let mut reader = ByteReader::new(&bytes);
        let rest = Inputs { i_ref: 0.0, q_ref: 0.0, x_ref: 0.0, ..self.base };
        let mut physics = Physics::read_bytes(&self.config.params, &rest, &mut reader)?;
        if !reader.is_at_end() {
            return Err("plugin_state has trailing state bytes".into());
        }
        physics.prepare_first_step(&rest, 0.0, self.config.substep);
        self.physics = physics;
        self.held = slots.to_vec();
        Ok(())
    }
}

/// What the host gives an actuator for one of its steps.
#[derive(Clone, Copy, Debug)]
pub struct HostStep {
    pub time: f64,
    pub timestep: f64,
    /// The actuator's length and velocity (after the gear), and its control.
    pub length: f64,
    pub velocity: f64,
    pub ctrl: f64,
}

impl HostStep {
    fn key(&self) -> [u64; 5] {
        [self.time, self.timestep, self.length, self.velocity, self.ctrl].map(f64::to_bits)
    }
}

impl Actuator {
    /// The force on the rod (N, + = extension), the mean over the host's step from the
    /// state in `slots`, with the rod moving along the host's position and velocity in
    /// internal steps of at most `substep`. The step is held until [`Actuator::commit`];
    /// asked again for the same host step, it returns the same force without stepping.
    pub fn compute(&mut self, slots: &[f64], host: &HostStep) -> Result<f64, String> {
        let key = host.key();
        if !same_bits(slots, &self.held) {
            self.restore(slots)?;
        } else if let Some(pending) = self.pending {
            if pending.key == key {
                return Ok(pending.force);
            }
            let held = std::mem::take(&mut self.held);
            self.restore(&held)?;
        }
        match self.advance(host) {
            Ok(force) => {
                self.pending = Some(Pending { key, force });
                Ok(force)
            }
            Err(e) => {
                let held = std::mem::take(&mut self.held);
                self.restore(&held)?;
                Err(e)
            }
        }
    }

    /// Steps the physics over the host's step; the mean force.
    fn advance(&mut self, host: &HostStep) -> Result<f64, String> {
        let n = ((host.timestep / self.config.substep) * (1.0 - 1e-12)).ceil().max(1.0);
        let h = host.timestep / n;
        let x = host.length - self.config.length_mid;
        let mut inputs = Inputs { x_rod: x, v_rod: host.velocity, ..self.base };
        let command = self.config.clamp_command(host.ctrl);
        match self.config.command_index() {
            vr::I_REF => inputs.i_ref = command,
            vr::Q_REF => inputs.q_ref = command,
            _ => inputs.x_ref = command,
        }
        let mut sum = 0.0;
        for j in 0..n as usize {
            let offset = j as f64 * h;
            inputs.x_rod = x + host.velocity * offset;
            self.physics.step(&inputs, host.time + offset, h)?;
            sum += self.physics.rod_force_mean();
        }
        Ok(sum / n)
    }

    /// Takes the step computed last into `slots` (MuJoCo's `advance`, after it integrated);
    /// nothing if there is none.
    pub fn commit(&mut self, slots: &mut [f64]) {
        if let Some(pending) = self.pending.take() {
            self.write_slots(pending.force, slots);
            self.held.clear();
            self.held.extend_from_slice(slots);
        }
    }

    /// The slots of the state at start.
    pub fn start_slots(&self) -> &[f64] {
        &self.start_slots
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::parse;

    fn position_actuator(substep: &str) -> Actuator {
        let substep = substep.to_string();
        let config = parse(|key| match key {
            "control_mode" => Some("position".into()),
            "substep" => Some(substep.clone()),
            _ => None,
        })
        .unwrap();
        Actuator::new(config).unwrap()
    }

    fn host(k: usize, h: f64) -> HostStep {
        let t = k as f64 * h;
        HostStep { time: t, timestep: h, length: 0.0, velocity: 0.0, ctrl: 0.002 }
    }

    #[test]
    fn slots_pack_bytes_as_plain_doubles_and_back() {
        let bytes: Vec<u8> = (0..=255u8).chain([255; 5]).collect();
        let mut slots = vec![0.0; bytes.len().div_ceil(BYTES_PER_SLOT)];
        pack(&bytes, &mut slots);
        assert!(slots.iter().all(|s| s.is_finite() && *s >= 2f64.powi(52)));
        assert_eq!(unpack(&slots, bytes.len()).unwrap(), bytes);
        slots[3] = 1.5;
        assert!(unpack(&slots, bytes.len()).is_err());
    }

    /// The same host step asked twice steps once; a commit writes the state, and an
    /// actuator given those slots (a copy, a set state) continues bit for bit.
    #[test]
    fn state_in_the_slots_continues_bit_for_bit() {
        let mut a = position_actuator("1e-4");
        let mut slots = a.start_slots().to_vec();
        for k in 0..30 {
            let f = a.compute(&slots, &host(k, 1e-4)).unwrap();
            assert_eq!(a.compute(&slots, &host(k, 1e-4)).unwrap().to_bits(), f.to_bits());
            a.commit(&mut slots);
        }
        let mut b = position_actuator("1e-4");
        let mut copy = slots.clone();
        for k in 30..60 {
            let fa = a.compute(&slots, &host(k, 1e-4)).unwrap();
            let fb = b.compute(&copy, &host(k, 1e-4)).unwrap();
            assert_eq!(fa.to_bits(), fb.to_bits(), "step {k}");
            a.commit(&mut slots);
            b.commit(&mut copy);
        }
        assert_eq!(
            slots.iter().map(|s| s.to_bits()).collect::<Vec<_>>(),
            copy.iter().map(|s| s.to_bits()).collect::<Vec<_>>()
        );
        let pressure = slots[output_names().iter().position(|n| *n == "p_A").unwrap()];
        assert!(pressure > 1e5, "p_A {pressure}");
    }

    /// A host step of 1 ms with the default substep takes ten internal steps.
    #[test]
    fn a_long_host_step_is_cut_into_substeps() {
        let mut a = position_actuator("1e-4");
        let mut slots = a.start_slots().to_vec();
        let before = a.physics.clone();
        a.compute(&slots, &host(0, 1e-3)).unwrap();
        a.commit(&mut slots);
        let mut b = before;
        let inputs = Inputs { x_ref: 0.002, ..a.base };
        for j in 0..10 {
            b.step(&inputs, j as f64 * 1e-4, 1e-4).unwrap();
        }
        assert_eq!(a.physics.outputs().p_a.to_bits(), b.outputs().p_a.to_bits());
    }
}

#[cfg(test)]
mod overhead {
    use super::*;
    use crate::config::parse;
    use std::time::Instant;

    /// The plugin's bookkeeping against the bare physics step (prints; run with --ignored).
    #[test]
    #[ignore]
    fn plugin_overhead_per_step() {
        let config = parse(|key| (key == "control_mode").then(|| "position".into())).unwrap();
        let mut a = Actuator::new(config).unwrap();
        let mut bare = a.physics.clone();
        let mut slots = a.start_slots().to_vec();
        let n = 20000;
        let x_ref = |k: usize| 0.005 * (k as f64 * 1e-4 * 12.0).sin();
        let w = Instant::now();
        for k in 0..n {
            let inputs = Inputs { x_ref: x_ref(k), ..a.base };
            bare.step(&inputs, k as f64 * 1e-4, 1e-4).unwrap();
        }
        let physics = w.elapsed().as_secs_f64() / n as f64;
        let w = Instant::now();
        for k in 0..n {
            let host = HostStep {
                time: k as f64 * 1e-4,
                timestep: 1e-4,
                length: 0.0,
                velocity: 0.0,
                ctrl: x_ref(k),
            };
            a.compute(&slots, &host).unwrap();
            a.commit(&mut slots);
        }
        let plugin = w.elapsed().as_secs_f64() / n as f64;
        println!("plugin {:.2} us, physics {:.2} us per step", plugin * 1e6, physics * 1e6);
    }
}
