//! Generalized paths (MODEL §1): a quintic p_r(τ) in the virtual arc τ, an affine speed profile
//! η(τ) = dτ/dt, and the reparameterisation by virtual time γ = t_p that the agents follow.

use nalgebra::{Matrix6, Vector2, Vector6};
use serde::{Deserialize, Serialize};

pub type Vec2 = Vector2<f64>;

/// Position, velocity and acceleration in the inertial frame at one end of a path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Boundary {
    pub position: Vec2,
    pub velocity: Vec2,
    pub acceleration: Vec2,
}

/// x_k(τ) = Σ a_{k,m} τ^m for k = 1, 2 (eq. 14).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quintic {
    pub coefficients: [[f64; 6]; 2],
}

impl Quintic {
    /// Matches value, first and second derivative at τ = 0 and τ = τ_f (eq. 15).
    /// `start` and `end` are [x, x′, x″] per coordinate.
    pub fn from_boundary(tau_f: f64, start: [Vec2; 3], end: [Vec2; 3]) -> Quintic {
        let t = tau_f;
        let (t2, t3, t4, t5) = (t * t, t * t * t, t.powi(4), t.powi(5));
        #[rustfmt::skip]
        let a = Matrix6::new(
            1.0, 0.0, 0.0, 0.0, 0.0, 0.0,
            0.0, 1.0, 0.0, 0.0, 0.0, 0.0,
            0.0, 0.0, 2.0, 0.0, 0.0, 0.0,
            1.0, t, t2, t3, t4, t5,
            0.0, 1.0, 2.0 * t, 3.0 * t2, 4.0 * t3, 5.0 * t4,
            0.0, 0.0, 2.0, 6.0 * t, 12.0 * t2, 20.0 * t3,
        );
        let lu = a.lu();
        let mut coefficients = [[0.0; 6]; 2];
        for (k, c) in coefficients.iter_mut().enumerate() {
            let b = Vector6::new(start[0][k], start[1][k], start[2][k], end[0][k], end[1][k], end[2][k]);
            let x = lu.solve(&b).expect("eq. 15 is regular for τ_f > 0");
            c.copy_from_slice(x.as_slice());
        }
        Quintic { coefficients }
    }

    /// p′ at τ alone, by the same Horner as `eval` (so the same bits): what the planner's
    /// quadrature of eq. 19 samples, a hundred times per candidate t_f and vehicle.
    pub fn tangent(&self, tau: f64) -> Vec2 {
        let [x, y] = self
            .coefficients
            .map(|a| (((5.0 * a[5] * tau + 4.0 * a[4]) * tau + 3.0 * a[3]) * tau + 2.0 * a[2]) * tau + a[1]);
        Vec2::new(x, y)
    }

    /// (p, p′, p″) at τ, by Horner.
    pub fn eval(&self, tau: f64) -> [Vec2; 3] {
        let mut out = [Vec2::zeros(); 3];
        for (k, a) in self.coefficients.iter().enumerate() {
            out[0][k] = ((((a[5] * tau + a[4]) * tau + a[3]) * tau + a[2]) * tau + a[1]) * tau + a[0];
            out[1][k] = (((5.0 * a[5] * tau + 4.0 * a[4]) * tau + 3.0 * a[3]) * tau + 2.0 * a[2]) * tau + a[1];
            out[2][k] = ((20.0 * a[5] * tau + 12.0 * a[4]) * tau + 6.0 * a[3]) * tau + 2.0 * a[2];
        }
        out
    }
}

/// The affine speed profile η(τ) = η0 + (ηf − η0) τ/τ_f over [0, t_f].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(from = "ProfileOnTheWire")]
pub struct SpeedProfile {
    pub eta0: f64,
    pub etaf: f64,
    pub t_f: f64,
    pub tau_f: f64,
    /// ln(ηf/η0), which τ(t) needs at every call: kept rather than recomputed, and not sent.
    #[serde(skip)]
    lambda: f64,
}

/// The fields a `SpeedProfile` is sent with.
#[derive(Deserialize)]
struct ProfileOnTheWire {
    eta0: f64,
    etaf: f64,
    t_f: f64,
    tau_f: f64,
}

impl From<ProfileOnTheWire> for SpeedProfile {
    fn from(p: ProfileOnTheWire) -> SpeedProfile {
        SpeedProfile {
            lambda: log_ratio(p.eta0, p.etaf),
            eta0: p.eta0,
            etaf: p.etaf,
            t_f: p.t_f,
            tau_f: p.tau_f,
        }
    }
}

/// Below this |ln(ηf/η0)| the profile is treated as constant (eqs. 17–18, first branch).
const EQUAL_ETA: f64 = 1e-12;

/// ln(ηf/η0). When the two are close, as ln_1p((ηf − η0)/η0): the quotient ηf/η0 rounds to
/// within 1e-16 of 1, which is all of ln's answer then (at a difference of 1e-9, τ_f off by
/// 6e-7), while the difference is exact. Far from 1 the quotient is the accurate one (ln_1p of a
/// ratio of 1e-17 less one is −∞).
fn log_ratio(eta0: f64, etaf: f64) -> f64 {
    if (etaf - eta0).abs() < 0.5 * eta0 {
        ((etaf - eta0) / eta0).ln_1p()
    } else {
        (etaf / eta0).ln()
    }
}

impl SpeedProfile {
    pub fn new(eta0: f64, etaf: f64, t_f: f64) -> SpeedProfile {
        let lambda = log_ratio(eta0, etaf);
        // eq. 17
        let tau_f = if lambda.abs() < EQUAL_ETA {
            eta0 * t_f
        } else {
            (etaf - eta0) * t_f / lambda
        };
        SpeedProfile {
            eta0,
            etaf,
            t_f,
            tau_f,
            lambda,
        }
    }

    /// τ(t), eq. 18, written with expm1 so that it is accurate as ηf → η0.
    pub fn tau(&self, t: f64) -> f64 {
        let lambda = self.lambda;
        if lambda.abs() < EQUAL_ETA {
            self.eta0 * t
        } else {
            self.eta0 * self.t_f * (lambda * t / self.t_f).exp_m1() / lambda
        }
    }

    /// η along the path as a function of τ.
    pub fn eta(&self, tau: f64) -> f64 {
        self.eta0 + self.deta() * tau
    }

    /// η′ = dη/dτ, constant.
    pub fn deta(&self) -> f64 {
        (self.etaf - self.eta0) / self.tau_f
    }
}

/// p_d(γ) and what the path-following law needs of it at one γ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathPoint {
    pub position: Vec2,
    /// dp_d/dγ
    pub tangent: Vec2,
    /// d²p_d/dγ²
    pub second: Vec2,
    /// ψ_T, heading of dp_d/dγ
    pub heading: f64,
    /// c_c, signed curvature
    pub curvature: f64,
    /// v_d(γ) = |dp_d/dγ|
    pub speed: f64,
}

/// How far from p_d(γ) a vehicle may be and have arrived, m. A vehicle that follows its path is
/// within a metre of it (the paper's cases: 0.6 m at most, with 90 % loss); ten leaves room for
/// a disturbed one, and none for a claim from elsewhere.
pub const ARRIVAL_RADIUS: f64 = 10.0;

/// A vehicle's generalized path, parameterised by virtual time γ ∈ ℝ (D11 outside [0, t_f]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GeneralizedPath {
    pub quintic: Quintic,
    pub profile: SpeedProfile,
    pub start: [f64; 2],
    pub start_velocity: [f64; 2],
    pub goal: [f64; 2],
    pub goal_velocity: [f64; 2],
}

impl GeneralizedPath {
    /// The path from `start` to `goal` that takes exactly `t_f` (D1, D2).
    pub fn plan(start: Boundary, goal: Boundary, t_f: f64) -> GeneralizedPath {
        let eta0 = start.velocity.norm();
        let etaf = goal.velocity.norm();
        let profile = SpeedProfile::new(eta0, etaf, t_f);
        let deta = profile.deta();
        // D1: unit tangents; D2: p̈ = η η′ p′ + η² p″ (eq. 16) solved for p″.
        let end = |b: &Boundary, eta: f64| {
            let d1 = b.velocity / eta;
            let d2 = (b.acceleration - eta * deta * d1) / (eta * eta);
            [b.position, d1, d2]
        };
        let quintic = Quintic::from_boundary(profile.tau_f, end(&start, eta0), end(&goal, etaf));
        GeneralizedPath {
            quintic,
            profile,
            start: start.position.into(),
            start_velocity: start.velocity.into(),
            goal: goal.position.into(),
            goal_velocity: goal.velocity.into(),
        }
    }

    pub fn t_f(&self) -> f64 {
        self.profile.t_f
    }

    /// p_d(γ), dp_d/dγ and d²p_d/dγ² (eq. 16 with γ as time), with the straight-line
    /// extensions of D11 outside [0, t_f].
    pub fn at(&self, gamma: f64) -> PathPoint {
        let [position, tangent, second] = self.derivatives(gamma);
        let speed = tangent.norm();
        PathPoint {
            position,
            tangent,
            second,
            heading: tangent.y.atan2(tangent.x),
            curvature: (tangent.x * second.y - tangent.y * second.x) / (speed * speed * speed),
            speed,
        }
    }

    /// p_d(γ), dp_d/dγ and d²p_d/dγ² alone: what the planner samples, without the heading's
    /// arctangent that `at` adds for the path-following law.
    pub fn derivatives(&self, gamma: f64) -> [Vec2; 3] {
        if gamma < 0.0 {
            let v0 = Vec2::from(self.start_velocity);
            [Vec2::from(self.start) + v0 * gamma, v0, Vec2::zeros()]
        } else if gamma > self.profile.t_f {
            let vf = Vec2::from(self.goal_velocity);
            [
                Vec2::from(self.goal) + vf * (gamma - self.profile.t_f),
                vf,
                Vec2::zeros(),
            ]
        } else {
            let tau = self.profile.tau(gamma);
            let eta = self.profile.eta(tau);
            let [p, d1, d2] = self.quintic.eval(tau);
            [p, eta * d1, eta * self.profile.deta() * d1 + eta * eta * d2]
        }
    }

    /// Whether a vehicle at `position` whose agent reports `gamma` has arrived: γ ≥ t_f (D16),
    /// and the vehicle within `ARRIVAL_RADIUS` of p_d(γ). The world ends a run on it, from its
    /// own knowledge of where the vehicle is: a γ that says "arrived" far from the vehicle (one
    /// forged command of γ = 1000 ended a run with the fleet 100 m short) is not an arrival.
    pub fn arrived(&self, gamma: f64, position: [f64; 2]) -> bool {
        gamma >= self.t_f() && (self.derivatives(gamma)[0] - Vec2::from(position)).norm() <= ARRIVAL_RADIUS
    }

    /// dv_d/dγ = η (η′|p′| + η p′·p″/|p′|) at τ(γ), and 0 on the straight extensions (D11): the
    /// acceleration along the path per unit of γ̇, which a dynamic vehicle feeds forward (D22c).
    pub fn speed_rate(&self, gamma: f64) -> f64 {
        if !(0.0..=self.profile.t_f).contains(&gamma) {
            return 0.0;
        }
        let tau = self.profile.tau(gamma);
        let eta = self.profile.eta(tau);
        let [_, d1, d2] = self.quintic.eval(tau);
        let norm = d1.norm();
        eta * (self.profile.deta() * norm + eta * d1.dot(&d2) / norm)
    }

    /// The γ in [0, t_f] of the path point nearest to `position`: the best of a scan at 1000
    /// points, refined by golden-section search between its neighbours (the distance is
    /// unimodal there for any path a vehicle can follow).
    pub fn nearest(&self, position: Vec2) -> f64 {
        const SCAN: usize = 1000;
        let t_f = self.profile.t_f;
        let h = t_f / SCAN as f64;
        let distance = |g: f64| (self.derivatives(g)[0] - position).norm_squared();
        let best = (0..=SCAN)
            .map(|n| n as f64 * h)
            .min_by(|a, b| distance(*a).total_cmp(&distance(*b)))
            .unwrap_or(0.0);
        let (mut a, mut b) = ((best - h).max(0.0), (best + h).min(t_f));
        let ratio = (5f64.sqrt() - 1.0) / 2.0;
        for _ in 0..60 {
            let (c, d) = (b - ratio * (b - a), a + ratio * (b - a));
            if distance(c) < distance(d) {
                b = d;
            } else {
                a = c;
            }
        }
        0.5 * (a + b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paper_vehicle_1(t_f: f64) -> GeneralizedPath {
        let b = |p: [f64; 2], v: [f64; 2]| Boundary {
            position: p.into(),
            velocity: v.into(),
            acceleration: Vec2::zeros(),
        };
        GeneralizedPath::plan(b([0.0, 0.0], [0.5, 0.0]), b([10.0, 10.0], [0.75, 0.0]), t_f)
    }

    #[test]
    fn quintic_meets_its_boundary_conditions() {
        let start = [Vec2::new(1.0, -2.0), Vec2::new(0.3, 0.7), Vec2::new(-0.01, 0.02)];
        let end = [Vec2::new(14.0, 9.0), Vec2::new(0.9, -0.1), Vec2::new(0.0, 0.03)];
        for tau_f in [0.5, 7.0, 28.3, 60.0] {
            let q = Quintic::from_boundary(tau_f, start, end);
            for (got, want) in q.eval(0.0).iter().zip(start.iter()) {
                assert!((got - want).norm() < 1e-9, "τ=0: {got} vs {want}");
            }
            for (got, want) in q.eval(tau_f).iter().zip(end.iter()) {
                assert!((got - want).norm() < 1e-9, "τ=τf={tau_f}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn the_tangent_alone_is_evals_bit_for_bit() {
        let q = paper_vehicle_1(45.0).quintic;
        for k in 0..=1000 {
            let tau = k as f64 * 0.037;
            assert_eq!(q.tangent(tau), q.eval(tau)[1], "τ = {tau}");
        }
    }

    #[test]
    fn a_profile_from_a_far_higher_speed_stays_finite() {
        let profile = SpeedProfile::new(0.75, 1e-17, 45.0);
        let expected = -0.75 * 45.0 / (1e-17f64 / 0.75).ln();
        assert!((profile.tau_f - expected).abs() < 1e-12 * expected, "{}", profile.tau_f);
    }

    #[test]
    fn tau_of_t_integrates_the_speed_profile() {
        // Near-equal: 1e-9 apart takes eq. 18's exponential, 1e-13 apart its constant branch.
        for (eta0, etaf) in [
            (0.5, 0.75),
            (0.9, 0.2),
            (0.6, 0.6),
            (0.6, 0.6 + 1e-9),
            (0.6, 0.6 + 1e-13),
        ] {
            let profile = SpeedProfile::new(eta0, etaf, 45.0);
            // RK4 on dτ/dt = η(τ).
            let (mut tau, dt) = (0.0, 0.01);
            for k in 0..4500 {
                let f = |x: f64| profile.eta(x);
                let k1 = f(tau);
                let k2 = f(tau + 0.5 * dt * k1);
                let k3 = f(tau + 0.5 * dt * k2);
                let k4 = f(tau + dt * k3);
                tau += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
                let t = (k + 1) as f64 * dt;
                assert!((tau - profile.tau(t)).abs() < 1e-9, "η0={eta0} ηf={etaf} t={t}");
            }
            assert!((profile.tau(45.0) - profile.tau_f).abs() < 1e-9);
            assert!((profile.eta(profile.tau_f) - etaf).abs() < 1e-12);
        }
    }

    #[test]
    fn path_velocity_and_acceleration_match_the_boundary() {
        let path = paper_vehicle_1(45.689);
        let p0 = path.at(0.0);
        let pf = path.at(45.689);
        assert!((p0.position - Vec2::new(0.0, 0.0)).norm() < 1e-9);
        assert!((p0.tangent - Vec2::new(0.5, 0.0)).norm() < 1e-9);
        assert!(p0.second.norm() < 1e-9, "D2: zero acceleration at the start");
        assert!((pf.position - Vec2::new(10.0, 10.0)).norm() < 1e-9);
        assert!((pf.tangent - Vec2::new(0.75, 0.0)).norm() < 1e-9);
        assert!(pf.second.norm() < 1e-9, "D2: zero acceleration at the goal");
    }

    #[test]
    fn derivatives_in_gamma_match_finite_differences() {
        let path = paper_vehicle_1(45.689);
        let h = 1e-5;
        for gamma in [0.3, 5.0, 22.2, 40.0, 45.0] {
            let a = path.at(gamma - h);
            let b = path.at(gamma + h);
            let mid = path.at(gamma);
            assert!(((b.position - a.position) / (2.0 * h) - mid.tangent).norm() < 1e-7);
            assert!(((b.tangent - a.tangent) / (2.0 * h) - mid.second).norm() < 1e-7);
        }
    }

    #[test]
    fn speed_rate_is_the_derivative_of_the_desired_speed() {
        let path = paper_vehicle_1(45.689);
        for gamma in [0.5, 7.0, 22.8, 40.1, 45.0] {
            let h = 1e-5;
            let numeric = (path.at(gamma + h).speed - path.at(gamma - h).speed) / (2.0 * h);
            let rate = path.speed_rate(gamma);
            assert!((numeric - rate).abs() < 1e-8, "γ {gamma}: {numeric} against {rate}");
        }
        assert_eq!((path.speed_rate(-1.0), path.speed_rate(50.0)), (0.0, 0.0));
    }

    #[test]
    fn extensions_are_straight_and_c1() {
        let path = paper_vehicle_1(40.0);
        let before = path.at(-3.0);
        assert!((before.position - Vec2::new(-1.5, 0.0)).norm() < 1e-12);
        assert_eq!(before.curvature, 0.0);
        let after = path.at(43.0);
        assert!((after.position - Vec2::new(12.25, 10.0)).norm() < 1e-9);
        assert_eq!(after.curvature, 0.0);
        let eps = 1e-9;
        for edge in [0.0, 40.0] {
            let (l, r) = (path.at(edge - eps), path.at(edge + eps));
            assert!((l.position - r.position).norm() < 1e-6);
            assert!((l.tangent - r.tangent).norm() < 1e-6);
        }
    }

    #[test]
    fn curvature_is_the_turn_rate_of_the_tangent_per_metre() {
        // dψ_T/dγ = c_c v_d, independently of how c_c is computed.
        let path = paper_vehicle_1(45.0);
        let h = 1e-5;
        for gamma in [1.0, 10.0, 30.0, 44.0] {
            let turn = (path.at(gamma + h).heading - path.at(gamma - h).heading) / (2.0 * h);
            let point = path.at(gamma);
            assert!((turn - point.curvature * point.speed).abs() < 1e-7, "γ={gamma}");
        }
    }

    #[test]
    fn the_nearest_point_of_a_path_is_found_from_off_the_path() {
        let path = paper_vehicle_1(45.0);
        for gamma in [0.0, 3.3, 20.0, 44.9] {
            let point = path.at(gamma);
            // 0.3 m to the left of the path, across its tangent.
            let normal = Vec2::new(-point.tangent.y, point.tangent.x) / point.speed;
            let found = path.nearest(point.position + 0.3 * normal);
            assert!((found - gamma).abs() < 1e-6, "γ = {gamma}: found {found}");
        }
    }
}
