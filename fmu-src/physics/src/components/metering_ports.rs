//! The valve's metering ports: the orifice law between supply, tank and the two chambers
//! that feeds the cylinder ([`super::cylinder`]). It knows only the numbers it needs: the
//! valve's port data, the spool position and the pressures at the ports.
//!
//! Critically centred (lap 0, the default): for `x_s >= 0` (P -> A and B -> T open)
//! `Q_A = K3 x_s rsqrt(p_S - p_A)/sqrt(dp_r/2)` and `Q_B = K3 x_s rsqrt(p_B - p_T)/sqrt(dp_r/2)`,
//! mirrored for `x_s < 0` (A -> T and P -> B). `rsqrt` is [`regularised_sqrt`]: a signed
//! square root, so a load pressure above supply reverses the flow, turned laminar below
//! `dp_laminar` so that the slopes stay finite at a closed or balanced port.
//!
//! With a lap `u` each of the four edges has its own opening: `x_s + u` for P -> A and
//! B -> T, `u - x_s` for A -> T and P -> B, each closed below zero (an underlap, `u > 0`,
//! leaves all four open around null; an overlap, `u < 0`, closes all four in a dead band).
//! Each open edge passes `K3 opening rsqrt(drop)/sqrt(dp_r/2)`. The flows are continuous
//! in `x_s`; their slope in it changes at the lands' openings `x_s = -u` and `x_s = u`,
//! where the law above the opening holds (at `u = 0` both are null, read as `x_s >= 0`).

/// The valve's metering-port data (the values of [`ValveParams`](crate::ValveParams)'s `k3`,
/// `dp_rated` and `dp_laminar`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MeteringPorts {
    /// Spool/bushing flow gain K3 (m2/s).
    pub k3: f64,
    /// Total rated valve pressure drop at which the no-load flow is K3*x_s (Pa).
    pub dp_rated: f64,
    /// Port pressure drop below which the orifice law turns laminar (regularisation) (Pa).
    pub dp_laminar: f64,
    /// `sqrt(dp_rated / 2)`, `K3 / sqrt(dp_rated / 2)` and `sqrt(dp_laminar)`, computed once
    /// ([`MeteringPorts::new`]) rather than at every evaluation.
    rated_root: f64,
    gain_per_xs: f64,
    laminar_root: f64,
    /// The spool's lap at null (m): > 0 underlap, < 0 overlap.
    pub lap: f64,
    /// The first stage's pilot flow (supply to tank) per square root of the supply's drop
    /// to tank (m3/s/sqrt(Pa)).
    pilot_per_root: f64,
}

/// The flows through the open ports and their slopes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PortFlows {
    /// Flow into chamber A and out of chamber B (m3/s).
    pub q_a: f64,
    pub q_b: f64,
    /// `dQ_A/dp_A` and `dQ_B/dp_B`: each flow's slope in its own chamber's pressure (m3/(s Pa)).
    pub dqa_dpa: f64,
    pub dqb_dpb: f64,
    /// `dQ_A/dx_s` and `dQ_B/dx_s` (m2/s).
    pub dqa_dxs: f64,
    pub dqb_dxs: f64,
}

impl MeteringPorts {
    /// The ports of flow gain `k3` (m2/s), rated drop `dp_rated` and laminar limit
    /// `dp_laminar` (Pa).
    pub(crate) fn new(k3: f64, dp_rated: f64, dp_laminar: f64) -> MeteringPorts {
        let rated_root = (0.5 * dp_rated).sqrt();
        MeteringPorts {
            k3,
            dp_rated,
            dp_laminar,
            rated_root,
            gain_per_xs: k3 / rated_root,
            laminar_root: dp_laminar.sqrt(),
            lap: 0.0,
            pilot_per_root: 0.0,
        }
    }

    /// These ports with a lap `lap` (m) and a pilot flow `q_pilot` (m3/s) at a supply
    /// `p_ref` (Pa) above tank.
    pub(crate) fn with_leakage(self, lap: f64, q_pilot: f64, p_ref: f64) -> MeteringPorts {
        MeteringPorts { lap, pilot_per_root: q_pilot / p_ref.sqrt(), ..self }
    }

    /// Whether the ports are critically centred, their lap +0, by its bits: one integer
    /// comparison (a lap of -0 is left to [`AnyLap`], which reads it as 0).
    #[inline(always)]
    pub(crate) fn centred(&self) -> bool {
        self.lap.to_bits() == 0
    }

    /// Where a spool moving on a straight line from `spool[0]` to `spool[1]` first reaches
    /// a land's opening (`x_s = -lap` or `x_s = lap`, where the flows' slope in `x_s`
    /// changes), as a fraction of the way in (0, 1). None without a lap: at null the
    /// critically centred ports change only the side whose slope they take, as before.
    #[inline(always)]
    pub(crate) fn edge_crossing(&self, spool: [f64; 2]) -> Option<f64> {
        if self.lap == 0.0 {
            return None;
        }
        self.lapped_edge_crossing(spool)
    }

    #[inline(never)]
    fn lapped_edge_crossing(&self, [s0, s1]: [f64; 2]) -> Option<f64> {
        self.kinks()
            .into_iter()
            .flatten()
            .filter(|&level| (s0 - level) * (s1 - level) < 0.0)
            .map(|level| (level - s0) / (s1 - s0))
            .filter(|&f| f > 0.0 && f < 1.0)
            .reduce(f64::min)
    }

    /// The levels of `x_s` at which the flows' slope in it changes: null without a lap,
    /// the lands' openings `-|lap|` and `|lap|` with one.
    pub(crate) fn kinks(&self) -> [Option<f64>; 2] {
        if self.lap == 0.0 {
            [Some(0.0), None]
        } else {
            [Some(-self.lap.abs()), Some(self.lap.abs())]
        }
    }

    /// The flow drawn from the supply at spool position `x_s` (m3/s): through the P -> A
    /// and P -> B edges, and the first stage's pilot flow to tank.
    pub(crate) fn supply_flow(
        &self,
        x_s: f64,
        [p_a, p_b]: [f64; 2],
        p_supply: f64,
        p_tank: f64,
    ) -> f64 {
        let lam = Laminar { dp: self.dp_laminar, root: self.laminar_root };
        let (up, down) = self.openings(x_s);
        let edges = up.0 * regularised_sqrt(p_supply - p_a, lam)
            + down.0 * regularised_sqrt(p_supply - p_b, lam);
        self.gain_per_xs * edges + self.pilot_per_root * regularised_sqrt(p_supply - p_tank, lam)
    }

    /// The openings of the P -> A and B -> T edges (`x_s + lap`) and of the A -> T and
    /// P -> B edges (`lap - x_s`), each with its slope in its own opening (1 open, 0
    /// closed); at its land's opening an edge takes the law above it.
    #[inline(always)]
    fn openings(&self, x_s: f64) -> ((f64, f64), (f64, f64)) {
        let (up, down) = (x_s + self.lap, self.lap - x_s);
        (
            if up >= 0.0 { (up, 1.0) } else { (0.0, 0.0) },
            if down > 0.0 { (down, 1.0) } else { (0.0, 0.0) },
        )
    }

    /// The flows at spool position `x_s` with the chambers at `[p_a, p_b]`, supply
    /// `p_supply` and tank `p_tank`, and their slopes. Inlined: a caller that needs the flows
    /// alone does not compute the slopes.
    #[inline(always)]
    pub(crate) fn flows(
        &self,
        x_s: f64,
        [p_a, p_b]: [f64; 2],
        p_supply: f64,
        p_tank: f64,
    ) -> PortFlows {
        if self.lap != 0.0 {
            return self.lapped_flows(x_s, [p_a, p_b], p_supply, p_tank);
        }
        self.centred_flows(x_s, [p_a, p_b], p_supply, p_tank)
    }

    /// [`MeteringPorts::flows`] of critically centred ports (lap 0), without the test.
    #[inline(always)]
    fn centred_flows(
        &self,
        x_s: f64,
        [p_a, p_b]: [f64; 2],
        p_supply: f64,
        p_tank: f64,
    ) -> PortFlows {
        debug_assert!(self.lap == 0.0, "the centred law of lapped ports");
        let gain_per_xs = self.gain_per_xs;
        let gain = self.k3 * x_s / self.rated_root;
        let lam = Laminar { dp: self.dp_laminar, root: self.laminar_root };
        // Per open edge, `regularised_sqrt` of its pressure drop and its slope in the
        // chamber's pressure.
        let ((r_a, dra_dpa), (r_b, drb_dpb)) = if x_s >= 0.0 {
            // P -> A and B -> T open.
            let (da, db) = (p_supply - p_a, p_b - p_tank);
            (
                (regularised_sqrt(da, lam), -regularised_sqrt_slope(da, lam)),
                (regularised_sqrt(db, lam), regularised_sqrt_slope(db, lam)),
            )
        } else {
            // A -> T and P -> B open (gain < 0 turns the flows around).
            let (da, db) = (p_a - p_tank, p_supply - p_b);
            (
                (regularised_sqrt(da, lam), regularised_sqrt_slope(da, lam)),
                (regularised_sqrt(db, lam), -regularised_sqrt_slope(db, lam)),
            )
        };
        PortFlows {
            q_a: gain * r_a,
            q_b: gain * r_b,
            dqa_dpa: gain * dra_dpa,
            dqb_dpb: gain * drb_dpb,
            dqa_dxs: gain_per_xs * r_a,
            dqb_dxs: gain_per_xs * r_b,
        }
    }
}

impl MeteringPorts {
    /// [`MeteringPorts::flows`] with a lap: each chamber's two edges, each by its own
    /// opening (module documentation). Inlined where the ports are: a call, even one not
    /// taken, costs the critically centred ports' callers more than the code.
    #[inline(always)]
    fn lapped_flows(
        &self,
        x_s: f64,
        [p_a, p_b]: [f64; 2],
        p_supply: f64,
        p_tank: f64,
    ) -> PortFlows {
        let g = self.gain_per_xs;
        let lam = Laminar { dp: self.dp_laminar, root: self.laminar_root };
        let ((up, up_open), (down, down_open)) = self.openings(x_s);
        // Drops across P -> A, A -> T, B -> T and P -> B, their roots and slopes.
        let edge = |drop: f64| (regularised_sqrt(drop, lam), regularised_sqrt_slope(drop, lam));
        let (pa, at) = (edge(p_supply - p_a), edge(p_a - p_tank));
        let (bt, pb) = (edge(p_b - p_tank), edge(p_supply - p_b));
        PortFlows {
            q_a: g * (up * pa.0 - down * at.0),
            q_b: g * (up * bt.0 - down * pb.0),
            dqa_dpa: -g * (up * pa.1 + down * at.1),
            dqb_dpb: g * (up * bt.1 + down * pb.1),
            dqa_dxs: g * (up_open * pa.0 + down_open * at.0),
            dqb_dxs: g * (up_open * bt.0 + down_open * pb.0),
        }
    }
}

/// The ports' law as a caller is compiled for it: [`Centred`] where the lap is known to be
/// 0, [`AnyLap`] elsewhere. The integrators choose once, above their hot loops (the
/// fixed-cost method per segment, the exact one per call of the cylinder's integrator): a
/// test of the lap where the law is evaluated, several times per step with the lapped law
/// inlined beside the centred one, made the critically centred ports' steps dearer.
pub(crate) trait PortLaw {
    /// [`MeteringPorts::flows`].
    fn flows(ports: &MeteringPorts, x_s: f64, p: [f64; 2], p_supply: f64, p_tank: f64)
        -> PortFlows;
    /// [`MeteringPorts::edge_crossing`].
    fn edge_crossing(ports: &MeteringPorts, spool: [f64; 2]) -> Option<f64>;
}

/// Critically centred ports (lap 0): their law without a test of the lap.
pub(crate) struct Centred;

/// Ports with any lap, 0 included: the law the lap asks for.
pub(crate) struct AnyLap;

impl PortLaw for Centred {
    #[inline(always)]
    fn flows(
        ports: &MeteringPorts,
        x_s: f64,
        p: [f64; 2],
        p_supply: f64,
        p_tank: f64,
    ) -> PortFlows {
        ports.centred_flows(x_s, p, p_supply, p_tank)
    }

    #[inline(always)]
    fn edge_crossing(ports: &MeteringPorts, _: [f64; 2]) -> Option<f64> {
        debug_assert!(ports.lap == 0.0, "the centred law of lapped ports");
        None
    }
}

impl PortLaw for AnyLap {
    #[inline(always)]
    fn flows(
        ports: &MeteringPorts,
        x_s: f64,
        p: [f64; 2],
        p_supply: f64,
        p_tank: f64,
    ) -> PortFlows {
        ports.flows(x_s, p, p_supply, p_tank)
    }

    #[inline(always)]
    fn edge_crossing(ports: &MeteringPorts, spool: [f64; 2]) -> Option<f64> {
        ports.edge_crossing(spool)
    }
}

/// The laminar limit of the orifice law, `dp_lam`, with its square root.
#[derive(Clone, Copy)]
struct Laminar {
    dp: f64,
    root: f64,
}

/// Signed square root, regularised below `dp_lam` by the odd cubic `a dp + b dp^3` that
/// matches value and slope of `sqrt` at `dp_lam` (C1; slope 1.25/sqrt(dp_lam) at zero).
#[inline(always)]
fn regularised_sqrt(dp: f64, lam: Laminar) -> f64 {
    let magnitude = dp.abs();
    if magnitude >= lam.dp {
        // dp.signum() * sqrt(|dp|) (dp is not NaN here), without signum's NaN handling.
        magnitude.sqrt().copysign(dp)
    } else {
        let s = dp / lam.dp;
        lam.root * s * (1.25 - 0.25 * s * s)
    }
}

/// Slope of [`regularised_sqrt`] with respect to `dp` (finite everywhere, 1.25/sqrt(dp_lam) at
/// 0), the laminar limit's root known.
#[inline(always)]
fn regularised_sqrt_slope(dp: f64, lam: Laminar) -> f64 {
    let magnitude = dp.abs();
    if magnitude >= lam.dp {
        0.5 / magnitude.sqrt()
    } else {
        let s = dp / lam.dp;
        (1.25 - 0.75 * s * s) / lam.root
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const P_RATED: f64 = 6.8948e6;

    fn paper_ports() -> MeteringPorts {
        let v = crate::params::Params::PAPER.valve;
        MeteringPorts::new(v.k3, v.dp_rated, v.dp_laminar)
    }

    /// [`super::regularised_sqrt`] below `lam`.
    fn regularised_sqrt(dp: f64, lam: f64) -> f64 {
        super::regularised_sqrt(dp, Laminar { dp: lam, root: lam.sqrt() })
    }

    #[test]
    fn regularised_sqrt_is_c1_and_exact_above_laminar() {
        let lam = 1e5;
        for dp in [1e5, 2e5, 3.4474e6, -5e6] {
            assert_eq!(regularised_sqrt(dp, lam), f64::signum(dp) * f64::sqrt(dp.abs()));
        }
        let below = regularised_sqrt(lam * (1.0 - 1e-9), lam);
        assert!((below - lam.sqrt()).abs() < 1e-9 * lam.sqrt());
        let slope =
            |dp: f64| (regularised_sqrt(dp + 1e-3, lam) - regularised_sqrt(dp - 1e-3, lam)) / 2e-3;
        assert!((slope(lam - 1.0) - slope(lam + 1.0)).abs() < 1e-4 * slope(lam + 1.0));
        assert!((slope(0.0) - 1.25 / lam.sqrt()).abs() < 1e-9);
        assert_eq!(regularised_sqrt(-3e4, lam), -regularised_sqrt(3e4, lam));
    }

    #[test]
    fn valve_ports_follow_the_orifice_law() {
        let ports = paper_ports();
        // Each port at dp_r/2 gives exactly the paper's no-load flow K3*x_s.
        let half = 0.5 * P_RATED;
        let balanced = [half, half];
        let q = ports.flows(1e-4, balanced, P_RATED, 0.0);
        assert!((q.q_a - ports.k3 * 1e-4).abs() < 1e-12 * q.q_a.abs());
        assert!((q.q_b - q.q_a).abs() < 1e-18);
        let q = ports.flows(-1e-4, balanced, P_RATED, 0.0);
        assert!((q.q_a + ports.k3 * 1e-4).abs() < 1e-12 * q.q_a.abs());
        assert!((q.q_b - q.q_a).abs() < 1e-18);
        // Closed valve: no flow at any pressure; load pressure above supply: reverse flow.
        let closed = ports.flows(0.0, balanced, P_RATED, 0.0);
        assert_eq!((closed.q_a, closed.q_b), (0.0, 0.0));
        assert!(ports.flows(1e-4, [1.2 * P_RATED, half], P_RATED, 0.0).q_a < 0.0);
    }

    /// The slopes are those of the flows: against central differences, on both sides of
    /// null and across the laminar region.
    #[test]
    fn port_flow_slopes_match_differences() {
        let ports = paper_ports();
        for x_s in [2e-4, -1.5e-4] {
            for [p_a, p_b] in [[3.0e6, 3.5e6], [P_RATED - 2e4, 4e4], [1e4, P_RATED - 3e4]] {
                let q = ports.flows(x_s, [p_a, p_b], P_RATED, 0.0);
                let d = 1.0;
                let fd_a = (ports.flows(x_s, [p_a + d, p_b], P_RATED, 0.0).q_a
                    - ports.flows(x_s, [p_a - d, p_b], P_RATED, 0.0).q_a)
                    / (2.0 * d);
                let fd_b = (ports.flows(x_s, [p_a, p_b + d], P_RATED, 0.0).q_b
                    - ports.flows(x_s, [p_a, p_b - d], P_RATED, 0.0).q_b)
                    / (2.0 * d);
                assert!((q.dqa_dpa - fd_a).abs() <= 1e-6 * fd_a.abs(), "{x_s} {p_a}");
                assert!((q.dqb_dpb - fd_b).abs() <= 1e-6 * fd_b.abs(), "{x_s} {p_b}");
                let dx = 1e-9;
                let up = ports.flows(x_s + dx, [p_a, p_b], P_RATED, 0.0);
                let down = ports.flows(x_s - dx, [p_a, p_b], P_RATED, 0.0);
                let fd_xs = (up.q_a - down.q_a) / (2.0 * dx);
                assert!((q.dqa_dxs - fd_xs).abs() <= 1e-6 * fd_xs.abs(), "{x_s} {p_a}");
            }
        }
    }

    /// The return edges measure their drop from the tank (here at 4 bar): `Q_B = K3 x_s
    /// sqrt(p_B - p_T)/sqrt(dp_r/2)` for `x_s > 0`, `Q_A = K3 x_s sqrt(p_A - p_T)/sqrt(dp_r/2)`
    /// for `x_s < 0`, the supply edges `sqrt(p_S - p)`, all drops turbulent; each flow's slope
    /// in its chamber's pressure is `d sqrt(drop)/dp`, in the spool position the flow over `x_s`.
    #[test]
    fn return_edges_drain_to_the_tank_pressure() {
        let ports = paper_ports();
        let p_tank = 4e5;
        let per_xs = ports.k3 / (0.5 * P_RATED).sqrt();
        let [p_a, p_b] = [3.0e6, 2.5e6];
        for x_s in [1.5e-4, -1.5e-4] {
            let q = ports.flows(x_s, [p_a, p_b], P_RATED, p_tank);
            // The drops and their signs in the chamber's own pressure.
            let [(drop_a, sign_a), (drop_b, sign_b)] = if x_s > 0.0 {
                [(P_RATED - p_a, -1.0), (p_b - p_tank, 1.0)]
            } else {
                [(p_a - p_tank, 1.0), (P_RATED - p_b, -1.0)]
            };
            let (q_a, q_b) = (per_xs * x_s * drop_a.sqrt(), per_xs * x_s * drop_b.sqrt());
            let close = |got: f64, law: f64| (got - law).abs() <= 1e-12 * law.abs();
            assert!(close(q.q_a, q_a), "{x_s}: Q_A {} vs {q_a}", q.q_a);
            assert!(close(q.q_b, q_b), "{x_s}: Q_B {} vs {q_b}", q.q_b);
            assert!(close(q.dqa_dpa, sign_a * q_a / (2.0 * drop_a)), "{x_s}: {}", q.dqa_dpa);
            assert!(close(q.dqb_dpb, sign_b * q_b / (2.0 * drop_b)), "{x_s}: {}", q.dqb_dpb);
            assert!(close(q.dqa_dxs, q_a / x_s), "{x_s}: {}", q.dqa_dxs);
            assert!(close(q.dqb_dxs, q_b / x_s), "{x_s}: {}", q.dqb_dxs);
        }
    }

    /// A lapped valve's flows: the four edges each by its own opening; continuous in the
    /// spool position across the lands' openings, slopes equal to differences, and at
    /// lap 0 the critically centred law exactly.
    #[test]
    fn lapped_edges_follow_their_openings() {
        let base = paper_ports();
        let p = [2.5e6, 4.0e6];
        for x_s in [-2e-4, -1e-6, 0.0, 1e-6, 2e-4] {
            let plain = base.flows(x_s, p, P_RATED, 0.0);
            let zero_lap = base.with_leakage(0.0, 0.0, P_RATED).flows(x_s, p, P_RATED, 0.0);
            assert_eq!(plain, zero_lap);
        }
        for lap in [5e-6, -5e-6] {
            let ports = base.with_leakage(lap, 0.0, P_RATED);
            let g = ports.gain_per_xs;
            let open = |o: f64| o.max(0.0);
            for x_s in [-3e-5, -4e-6, -1e-6, 0.0, 2e-6, 4.5e-6, 3e-5] {
                let q = ports.flows(x_s, p, P_RATED, 0.0);
                let (up, down) = (open(x_s + lap), open(lap - x_s));
                let q_a = g * (up * (P_RATED - p[0]).sqrt() - down * p[0].sqrt());
                let q_b = g * (up * p[1].sqrt() - down * (P_RATED - p[1]).sqrt());
                assert!((q.q_a - q_a).abs() <= 1e-12 * g * 1e-4, "{lap} {x_s}: {} vs {q_a}", q.q_a);
                assert!((q.q_b - q_b).abs() <= 1e-12 * g * 1e-4, "{lap} {x_s}: {} vs {q_b}", q.q_b);
                let d = 1e-9;
                let fd = (ports.flows(x_s + d, p, P_RATED, 0.0).q_a
                    - ports.flows(x_s - d, p, P_RATED, 0.0).q_a)
                    / (2.0 * d);
                assert!(
                    (q.dqa_dxs - fd).abs() <= 1e-6 * fd.abs(),
                    "{lap} {x_s}: {} vs {fd}",
                    q.dqa_dxs
                );
                let dp = 1.0;
                let fd_b = (ports.flows(x_s, [p[0], p[1] + dp], P_RATED, 0.0).q_b
                    - ports.flows(x_s, [p[0], p[1] - dp], P_RATED, 0.0).q_b)
                    / (2.0 * dp);
                assert!((q.dqb_dpb - fd_b).abs() <= 1e-6 * fd_b.abs().max(1e-20), "{lap} {x_s}");
            }
            // Continuous across each land's opening.
            for level in [-lap.abs(), lap.abs()] {
                let (below, above) = (
                    ports.flows(level * (1.0 + 1e-12) - 1e-18, p, P_RATED, 0.0),
                    ports.flows(level, p, P_RATED, 0.0),
                );
                assert!((below.q_a - above.q_a).abs() < 1e-15, "{lap} {level}");
            }
        }
        // Overlap: no flow anywhere in the dead band.
        let overlapped = base.with_leakage(-5e-6, 0.0, P_RATED);
        let q = overlapped.flows(3e-6, p, P_RATED, 0.0);
        assert_eq!((q.q_a, q.q_b, q.dqa_dxs), (0.0, 0.0, 0.0));
    }

    /// Blocked ports at null: an underlapped valve holds both chambers at half the supply,
    /// draws `2 K3 u sqrt(p_S/dp_r)` from it (plus the pilot's flow), and a small spool
    /// offset moves the load pressure by `2 p_S/u` per metre.
    #[test]
    fn an_underlapped_valve_leaks_and_has_a_finite_pressure_gain() {
        let lap = 4e-6;
        let q_pilot = 1e-6;
        let ports = paper_ports().with_leakage(lap, q_pilot, P_RATED);
        let half = [0.5 * P_RATED; 2];
        let q = ports.flows(0.0, half, P_RATED, 0.0);
        assert!(q.q_a.abs() < 1e-20 && q.q_b.abs() < 1e-20);
        let leak = 2.0 * ports.k3 * lap;
        let supply = ports.supply_flow(0.0, half, P_RATED, 0.0);
        assert!((supply - (leak + q_pilot)).abs() < 1e-12 * supply, "{supply}");
        // Where chamber A's flow balances for a small x_s: p_A = p_S (u+x)^2/((u+x)^2+(u-x)^2).
        let x = 1e-8;
        let balance = P_RATED * (lap + x).powi(2) / ((lap + x).powi(2) + (lap - x).powi(2));
        assert!(ports.flows(x, [balance, 0.5 * P_RATED], P_RATED, 0.0).q_a.abs() < 1e-18);
        let gain = (balance - 0.5 * P_RATED) / x;
        assert!((gain - P_RATED / lap).abs() < 1e-4 * gain, "{gain}");
    }
}
