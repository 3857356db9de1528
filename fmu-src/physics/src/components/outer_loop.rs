//! Outer loops ([`ControlMode::Flow`], [`ControlMode::Position`]): a digital PID sampled at
//! `f_sample` on an absolute clock, producing the coil current command, held between
//! samples and limited to +-`i_max` ([`OuterLoopParams`]). The flow loop adds the feed-forward
//! Q_ref / (K3*K1/Kw), the valve's static flow gain.

use crate::params::{ControlMode, OuterLoopParams};
use crate::state::bytes::ByteReader;

/// The active loop's parameters.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LoopParams {
    pub mode: ControlMode,
    pub f_sample: f64,
    pub i_max: f64,
    /// (Kp, Ki, Kd) of the active loop.
    pub gains: [f64; 3],
    /// Current per unit of reference fed forward (flow loop: 1 / static flow gain).
    pub feedforward: f64,
}

impl LoopParams {
    /// `static_flow_gain`: the valve's no-load flow per coil current, K3 K1 / Kw.
    pub(crate) fn new(p: &OuterLoopParams, mode: ControlMode, static_flow_gain: f64) -> Self {
        let (gains, feedforward) = match mode {
            ControlMode::Flow => (p.flow, 1.0 / static_flow_gain),
            _ => (p.position, 0.0),
        };
        LoopParams { mode, f_sample: p.f_sample, i_max: p.i_max, gains, feedforward }
    }

    fn sample_time(&self, k: i64) -> f64 {
        k as f64 / self.f_sample
    }
}

/// Discrete state of the outer PID.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct OuterLoop {
    active: bool,
    integral: f64,
    previous_error: f64,
    /// Current command in force (A).
    pub(crate) command: f64,
    next_sample: i64,
}

impl OuterLoop {
    /// Settled on `reference` at `start_time` (flow: the feed-forward alone holds it).
    pub(crate) fn at_start(p: &LoopParams, reference: f64, start_time: f64) -> Self {
        if p.mode == ControlMode::Current {
            return OuterLoop::default();
        }
        OuterLoop {
            active: true,
            command: (p.feedforward * reference).clamp(-p.i_max, p.i_max),
            next_sample: (start_time * p.f_sample - 1e-9).ceil() as i64,
            ..OuterLoop::default()
        }
    }

    /// Whether the loop samples at all (a current-mode actuator has none).
    #[inline]
    pub(crate) fn clocked(&self) -> bool {
        self.active
    }

    pub(crate) fn next_event(&self, p: &LoopParams) -> f64 {
        if self.active {
            p.sample_time(self.next_sample)
        } else {
            f64::INFINITY
        }
    }

    pub(crate) fn events_until(&self, p: &LoopParams, t_end: f64) -> u64 {
        if !self.active {
            return 0;
        }
        ((t_end - self.next_event(p)).max(0.0) * p.f_sample).min(u64::MAX as f64 / 2.0) as u64 + 2
    }

    /// One PID sample; the integrator holds while the command is limited and the error
    /// pushes further (conditional integration).
    pub(crate) fn sample(&mut self, p: &LoopParams, reference: f64, measured: f64) {
        let [kp, ki, kd] = p.gains;
        let e = reference - measured;
        let derivative = kd * (e - self.previous_error) * p.f_sample;
        let base = p.feedforward * reference + kp * e + derivative;
        let integral = self.integral + ki * e / p.f_sample;
        let wanted = base + integral;
        if !(wanted > p.i_max && e > 0.0 || wanted < -p.i_max && e < 0.0) {
            self.integral = integral;
        }
        self.command = (base + self.integral).clamp(-p.i_max, p.i_max);
        self.previous_error = e;
        self.next_sample += 1;
    }

    pub(crate) fn write_bytes(&self, out: &mut Vec<u8>) {
        out.push(self.active as u8);
        for x in [self.integral, self.previous_error, self.command, self.next_sample as f64] {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }

    pub(crate) fn read_bytes(r: &mut ByteReader) -> Result<Self, String> {
        let active = r.u8()?;
        let mut x = [0.0; 4];
        for v in x.iter_mut() {
            *v = r.f64()?;
        }
        if active > 1
            || !x.iter().all(|v| v.is_finite())
            || x[3].fract() != 0.0
            || x[3].abs() > 9e15
        {
            return Err("state holds an invalid outer-loop record".into());
        }
        Ok(OuterLoop {
            active: active == 1,
            integral: x[0],
            previous_error: x[1],
            command: x[2],
            next_sample: x[3] as i64,
        })
    }
}
