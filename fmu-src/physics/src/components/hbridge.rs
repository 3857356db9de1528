//! H-bridge driver ([`DriverKind::HBridge`](crate::params::DriverKind::HBridge)): bipolar,
//! centre-aligned PWM at `hbridge.f_pwm` switches the coil between +V_supply and -V_supply;
//! a digital PI current loop sampled at `hbridge.f_sample` sets the duty cycle. The command computed at one sample takes effect
//! at the next (one-sample computation delay) and is latched at the start of a PWM period.
//!
//! Everything here happens at *time events* on an absolute clock (sample k at k/f_sample,
//! period k at k/f_pwm), so the switching instants are exact and the same at any
//! communication step. Between them the bridge voltage is constant and the continuous
//! part is linear (see [`crate::numerics::mode_systems`]).
//!
//! With [`HBridgeParams::pwm_mean`] (the fixed-cost method) the switchings are no events:
//! over each period the bridge gives the period's mean voltage, `duty * V`, and only the
//! samples and the periods' starts cut a step.

use crate::params::HBridgeParams;
use crate::state::bytes::ByteReader;

impl HBridgeParams {
    pub(crate) fn period(&self) -> f64 {
        1.0 / self.f_pwm
    }

    fn sample_time(&self, k: i64) -> f64 {
        k as f64 / self.f_sample
    }

    fn period_time(&self, k: i64) -> f64 {
        k as f64 / self.f_pwm
    }
}

/// Discrete state of the digital loop and the PWM.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct HBridgeState {
    active: bool,
    /// PI integrator (V).
    integral: f64,
    /// Command computed at the last sample, in force from the next one (V).
    pending: f64,
    /// Command in force (latched by the next PWM period) (V).
    applied: f64,
    next_sample: i64,
    next_period: i64,
    /// Absolute times of this period's switch to +V and back to -V.
    edges: [f64; 2],
    /// Index of the next edge in `edges` (2: none left in this period).
    next_edge: u8,
    /// Bridge output at +V (else -V).
    high: bool,
}

impl HBridgeState {
    /// Holding `u` on average (the equilibrium voltage) at `start_time`. (Without an
    /// H-bridge the digital state is `HBridgeState::default()`, inactive.)
    pub(crate) fn at_equilibrium(
        p: &HBridgeParams,
        u: f64,
        feedforward_u: f64,
        rail: f64,
        start_time: f64,
    ) -> Self {
        let first_period = (start_time * p.f_pwm + 1e-9).floor() as i64;
        let mut d = HBridgeState {
            active: true,
            integral: u - if p.feedforward { feedforward_u } else { 0.0 },
            pending: u,
            applied: u,
            next_sample: (start_time * p.f_sample - 1e-9).ceil() as i64,
            next_period: first_period,
            ..HBridgeState::default()
        };
        // Enter the period under way, with its edges already passed applied.
        d.start_period(p, rail);
        while d.next_edge < 2 && d.edges[d.next_edge as usize] <= start_time {
            d.take_edge();
        }
        d
    }

    /// Whether the bridge switches and samples at all (there is one).
    #[inline]
    pub(crate) fn clocked(&self) -> bool {
        self.active
    }

    /// Time of the next switching or sampling instant (infinite without an H-bridge).
    pub(crate) fn next_event(&self, p: &HBridgeParams) -> f64 {
        if !self.active {
            return f64::INFINITY;
        }
        let edge = if self.next_edge < 2 && !p.pwm_mean {
            self.edges[self.next_edge as usize]
        } else {
            f64::INFINITY
        };
        edge.min(p.sample_time(self.next_sample)).min(p.period_time(self.next_period))
    }

    /// Upper bound of the time events before `t_end`.
    pub(crate) fn events_until(&self, p: &HBridgeParams, t_end: f64) -> u64 {
        if !self.active {
            return 0;
        }
        let span = (t_end - self.next_event(p)).max(0.0);
        (span * (3.0 * p.f_pwm + p.f_sample)).min(u64::MAX as f64 / 2.0) as u64 + 4
    }

    /// Handles the earliest pending instant. At equal times: edges of the ending period,
    /// then the sample (so its predecessor's command is in force), then the new period.
    pub(crate) fn fire(
        &mut self,
        p: &HBridgeParams,
        i_coil: f64,
        i_cmd: f64,
        r_total: f64,
        rail: f64,
    ) {
        let t = self.next_event(p);
        if self.next_edge < 2 && self.edges[self.next_edge as usize] <= t && !p.pwm_mean {
            self.take_edge();
        } else if p.sample_time(self.next_sample) <= t {
            self.sample(p, i_coil, i_cmd, r_total, rail);
        } else {
            self.start_period(p, rail);
        }
    }

    fn take_edge(&mut self) {
        self.high = self.next_edge == 0;
        self.next_edge += 1;
    }

    /// PI on the sampled current with conditional integration (the integrator holds while
    /// the command is beyond a rail and the error pushes further).
    fn sample(&mut self, p: &HBridgeParams, i_coil: f64, i_cmd: f64, r_total: f64, rail: f64) {
        let e = i_cmd - i_coil;
        let feedforward = if p.feedforward { r_total * i_cmd } else { 0.0 };
        let integral = self.integral + p.ki * e / p.f_sample;
        let wanted = p.kp * e + integral + feedforward;
        if !(wanted > rail && e > 0.0 || wanted < -rail && e < 0.0) {
            self.integral = integral;
        }
        self.applied = self.pending;
        self.pending = (p.kp * e + self.integral + feedforward).clamp(-rail, rail);
        self.next_sample += 1;
    }

    /// Latches the duty cycle: +V for (1 + d)/2 of the period, centred.
    fn start_period(&mut self, p: &HBridgeParams, rail: f64) {
        let t0 = p.period_time(self.next_period);
        let period = p.period();
        let duty = if rail > 0.0 { (self.applied / rail).clamp(-1.0, 1.0) } else { 0.0 };
        let on = 0.5 * (1.0 + duty) * period;
        self.edges = [t0 + 0.5 * (period - on), t0 + 0.5 * (period + on)];
        self.next_edge = 0;
        self.high = false;
        self.next_period += 1;
    }

    pub(crate) fn output(&self, p: &HBridgeParams, rail: f64) -> f64 {
        if p.pwm_mean {
            // The period's duty, from its edges: +V for (1 + duty)/2 of it.
            let duty = 2.0 * (self.edges[1] - self.edges[0]) * p.f_pwm - 1.0;
            return duty * rail;
        }
        if self.high {
            rail
        } else {
            -rail
        }
    }

    /// The commanded voltage is at a rail (duty 0 % or 100 %).
    pub(crate) fn saturated(&self, rail: f64) -> bool {
        self.active && self.applied.abs() >= rail
    }

    pub(crate) fn write_bytes(&self, out: &mut Vec<u8>) {
        out.push(self.active as u8 | (self.high as u8) << 1);
        out.push(self.next_edge);
        for x in [
            self.integral,
            self.pending,
            self.applied,
            self.next_sample as f64,
            self.next_period as f64,
            self.edges[0],
            self.edges[1],
        ] {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }

    pub(crate) fn read_bytes(r: &mut ByteReader) -> Result<Self, String> {
        let flags = r.u8()?;
        let next_edge = r.u8()?;
        let mut x = [0.0; 7];
        for v in x.iter_mut() {
            *v = r.f64()?;
        }
        let counters_ok = [x[3], x[4]].iter().all(|c| c.fract() == 0.0 && c.abs() < 9e15);
        if flags > 3 || next_edge > 2 || !x.iter().all(|v| v.is_finite()) || !counters_ok {
            return Err("state holds an invalid H-bridge record".into());
        }
        Ok(HBridgeState {
            active: flags & 1 != 0,
            high: flags & 2 != 0,
            next_edge,
            integral: x[0],
            pending: x[1],
            applied: x[2],
            next_sample: x[3] as i64,
            next_period: x[4] as i64,
            edges: [x[5], x[6]],
        })
    }
}
