//! The valve's metering ports (critically centred, no lap, no leakage): the orifice law
//! between supply, tank and the two chambers that feeds the cylinder
//! ([`super::cylinder`]). It knows only the numbers it needs: the valve's port data, the
//! spool position and the pressures at the ports.
//!
//! For `x_s >= 0` (P -> A and B -> T open) `Q_A = K3 x_s rsqrt(p_S - p_A)/sqrt(dp_r/2)` and
//! `Q_B = K3 x_s rsqrt(p_B - p_T)/sqrt(dp_r/2)`, mirrored for `x_s < 0` (A -> T and P -> B).
//! `rsqrt` is [`regularised_sqrt`]: a signed square root, so a load pressure above supply
//! reverses the flow, turned laminar below `dp_laminar` so that the slopes stay finite at a
//! closed or balanced port.

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
        }
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
}
