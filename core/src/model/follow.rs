//! Path following (MODEL §2, Lemma 2): errors in the Serret–Frenet frame, the control law of
//! eqs. 22–23 and the error kinematics of eq. 21 it was designed against.

use crate::model::path::{PathPoint, Vec2};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gains {
    pub k1: f64,
    pub k2: f64,
    pub k3: f64,
    pub d1: f64,
}

/// (x_e, y_e) in frame {T} at p_d(γ), and ψ_e = ψ_F − ψ_T wrapped to (−π, π].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Errors {
    pub x_e: f64,
    pub y_e: f64,
    pub psi_e: f64,
    /// sin ψ_e and cos ψ_e, which eqs. 21, 23 and 25 all take: evaluated together, once, and
    /// private so that they are always ψ_e's.
    sin_psi_e: f64,
    cos_psi_e: f64,
}

impl Errors {
    pub fn new(x_e: f64, y_e: f64, psi_e: f64) -> Errors {
        let (sin_psi_e, cos_psi_e) = psi_e.sin_cos();
        Errors {
            x_e,
            y_e,
            psi_e,
            sin_psi_e,
            cos_psi_e,
        }
    }

    pub fn cos_psi_e(&self) -> f64 {
        self.cos_psi_e
    }
}

/// The law's outputs: speed through the water, yaw rate and the virtual-time rate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Law {
    pub v: f64,
    pub r: f64,
    pub gamma_dot: f64,
}

pub fn wrap(angle: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let x = angle + PI;
    // rem_euclid returns x itself in [0, 2π), bit for bit: the common case needs no fmod.
    let a = if (0.0..TAU).contains(&x) { x } else { x.rem_euclid(TAU) } - PI;
    if a == -PI {
        PI
    } else {
        a
    }
}

/// Unit saturation.
pub fn sat(x: f64) -> f64 {
    x.clamp(-1.0, 1.0)
}

/// A frame rotated by ψ, with R(ψ)ᵀ evaluated once for every vector brought into it.
#[derive(Debug, Clone, Copy)]
pub struct Frame {
    sin: f64,
    cos: f64,
}

impl Frame {
    pub fn new(psi: f64) -> Frame {
        let (sin, cos) = psi.sin_cos();
        Frame { sin, cos }
    }

    /// R(ψ)ᵀ w: an inertial vector in this frame.
    pub fn of(&self, w: Vec2) -> Vec2 {
        Vec2::new(self.cos * w.x + self.sin * w.y, -self.sin * w.x + self.cos * w.y)
    }
}

/// The errors of a vehicle at `position` with course ψ_F, against `point` whose frame {T} is
/// `t_frame` (`Frame::new(point.heading)`).
pub fn errors(position: Vec2, psi_f: f64, point: &PathPoint, t_frame: &Frame) -> Errors {
    let e = t_frame.of(position - point.position);
    Errors::new(e.x, e.y, wrap(psi_f - point.heading))
}

/// ζ = −arcsin(k2 y_e/(|y_e| + d1)), the approach angle.
pub fn zeta(g: &Gains, y_e: f64) -> f64 {
    -(g.k2 * y_e / (y_e.abs() + g.d1)).asin()
}

/// ∂ζ/∂y_e.
pub fn dzeta(g: &Gains, y_e: f64) -> f64 {
    let den = y_e.abs() + g.d1;
    let u = g.k2 * y_e / den;
    -(g.k2 * g.d1 / (den * den)) / (1.0 - u * u).sqrt()
}

/// σ = (sin ψ_e − sin ζ)/(ψ_e − ζ), written so that it is finite at ψ_e = ζ.
pub fn sigma(psi_e: f64, zeta: f64) -> f64 {
    let h = 0.5 * (psi_e - zeta);
    let sinc = if h.abs() < 1e-8 { 1.0 - h * h / 6.0 } else { h.sin() / h };
    (0.5 * (psi_e + zeta)).cos() * sinc
}

/// eq. 21: (ẋ_e, ẏ_e, ψ̇_e) given the inputs. `current` is the current in frame {T}
/// (v_c cos ψ_cT, v_c sin ψ_cT).
pub fn error_rates(
    point: &PathPoint,
    e: &Errors,
    v: f64,
    r: f64,
    gamma_dot: f64,
    current: Vec2,
    beta_dot: f64,
) -> [f64; 3] {
    let s = point.speed * gamma_dot;
    [
        (e.y_e * point.curvature - 1.0) * s + v * e.cos_psi_e + current.x,
        -e.x_e * point.curvature * s + v * e.sin_psi_e + current.y,
        r - point.curvature * s + beta_dot,
    ]
}

/// eqs. 22b and 23 for a speed command `v` already set by eq. 22a/25, on a vehicle whose speed
/// through the water is `speed`: `v` itself on a kinematic vehicle, the measured U on a dynamic
/// one, whose speed only follows the command (D22c).
pub fn control(g: &Gains, point: &PathPoint, e: &Errors, v: f64, speed: f64, current: Vec2, beta_dot: f64) -> Law {
    let v_d = point.speed;
    // eq. 23, with 1 + ṽ_d/v_d = v/v_d
    let gamma_dot = speed / v_d * e.cos_psi_e + g.k1 / v_d * sat(e.x_e);
    // D7: ζ̇ from the measured ẏ_e of eq. 21
    let y_e_dot = error_rates(point, e, speed, 0.0, gamma_dot, current, 0.0)[1];
    let z = zeta(g, e.y_e);
    let z_dot = dzeta(g, e.y_e) * y_e_dot;
    // eq. 22b
    let r = point.curvature * v_d * gamma_dot + z_dot
        - g.k3 * (e.psi_e - z)
        - g.k3 * e.y_e * speed * sigma(e.psi_e, z)
        - beta_dot;
    Law { v, r, gamma_dot }
}

/// V = ½(x_e² + y_e²) + (ψ_e − ζ)²/(2 k3).
pub fn lyapunov(g: &Gains, e: &Errors) -> f64 {
    let d = e.psi_e - zeta(g, e.y_e);
    0.5 * (e.x_e * e.x_e + e.y_e * e.y_e) + d * d / (2.0 * g.k3)
}

/// V̇ along the closed loop, as Lemma 2 states it: negative but for the current's term.
pub fn lyapunov_rate(g: &Gains, e: &Errors, v: f64, current: Vec2) -> f64 {
    let d = e.psi_e - zeta(g, e.y_e);
    -g.k1 * e.x_e * sat(e.x_e) - g.k2 * v * e.y_e * e.y_e / (e.y_e.abs() + g.d1) - d * d
        + e.x_e * current.x
        + e.y_e * current.y
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_chacha::rand_core::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * ((rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64)
    }

    const G: Gains = Gains {
        k1: 5.0,
        k2: 1.0,
        k3: 0.34,
        d1: 1.0,
    };

    #[test]
    fn eq_21_is_how_the_errors_move_along_a_planned_path() {
        // A vehicle near case (b)'s first path, moved by the kinematics the world integrates
        // (ṗ = v (cos ψ_F, sin ψ_F) + v_c, ψ̇_F = r + β̇) while γ moves at γ̇: the errors'
        // central differences against eq. 21.
        let (_, paths, t_f) = crate::fixtures::case_b();
        let path = &paths[0].1;
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        for _ in 0..2_000 {
            let gamma = uniform(&mut rng, 0.0, t_f);
            let point = path.at(gamma);
            let frame = Frame::new(point.heading);
            let offset = Vec2::new(uniform(&mut rng, -2.0, 2.0), uniform(&mut rng, -2.0, 2.0));
            let position = point.position + offset;
            let psi_f = point.heading + uniform(&mut rng, -1.2, 1.2);
            let (v, r, gamma_dot) = (
                uniform(&mut rng, 0.1, 1.0),
                uniform(&mut rng, -0.5, 0.5),
                uniform(&mut rng, 0.5, 1.5),
            );
            let (current, beta_dot) = (
                Vec2::new(uniform(&mut rng, -0.2, 0.2), uniform(&mut rng, -0.2, 0.2)),
                uniform(&mut rng, -0.3, 0.3),
            );
            let at = |h: f64| {
                let p = path.at(gamma + h * gamma_dot);
                let course = psi_f + h * (r + beta_dot);
                let moved = position + h * (v * Vec2::new(course.cos(), course.sin()) + current);
                errors(moved, course, &p, &Frame::new(p.heading))
            };
            let h = 1e-5;
            let (ahead, behind) = (at(h), at(-h));
            let numeric = [
                (ahead.x_e - behind.x_e) / (2.0 * h),
                (ahead.y_e - behind.y_e) / (2.0 * h),
                wrap(ahead.psi_e - behind.psi_e) / (2.0 * h),
            ];
            let e = errors(position, psi_f, &point, &frame);
            let rates = error_rates(&point, &e, v, r, gamma_dot, frame.of(current), beta_dot);
            for (n, a) in numeric.iter().zip(rates) {
                assert!(
                    (n - a).abs() < 1e-5 * (1.0 + a.abs()),
                    "γ {gamma}: {numeric:?} against eq. 21 {rates:?}"
                );
            }
        }
    }

    /// A path point, errors and a current at random, for the property tests of Lemma 2.
    fn random_state(rng: &mut ChaCha8Rng) -> (PathPoint, Errors, Vec2) {
        let point = PathPoint {
            position: Vec2::zeros(),
            tangent: Vec2::zeros(),
            second: Vec2::zeros(),
            heading: uniform(rng, -3.0, 3.0),
            curvature: uniform(rng, -2.0, 2.0),
            speed: uniform(rng, 0.05, 1.5),
        };
        let e = Errors::new(
            uniform(rng, -5.0, 5.0),
            uniform(rng, -5.0, 5.0),
            uniform(rng, -3.1, 3.1),
        );
        let current = Vec2::new(uniform(rng, -0.3, 0.3), uniform(rng, -0.3, 0.3));
        (point, e, current)
    }

    /// V̇ by the chain rule, from eq. 21's rates.
    fn chain_rule(g: &Gains, e: &Errors, [xd, yd, pd]: [f64; 3]) -> f64 {
        let z = zeta(g, e.y_e);
        e.x_e * xd + e.y_e * yd + (e.psi_e - z) * (pd - dzeta(g, e.y_e) * yd) / g.k3
    }

    #[test]
    fn lyapunov_derivative_matches_lemma_2_at_random_states() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..20_000 {
            let (point, e, current) = random_state(&mut rng);
            let g = Gains {
                k2: uniform(&mut rng, 0.1, 1.0),
                ..G
            };
            let v = uniform(&mut rng, 0.05, 3.0);
            let beta_dot = uniform(&mut rng, -0.5, 0.5);
            let law = control(&g, &point, &e, v, v, current, beta_dot);
            let rates = error_rates(&point, &e, law.v, law.r, law.gamma_dot, current, beta_dot);
            // The chain rule on V with eq. 21's rates, against the closed form.
            let (chain, closed) = (chain_rule(&g, &e, rates), lyapunov_rate(&g, &e, v, current));
            assert!(
                (chain - closed).abs() < 1e-9 * (1.0 + closed.abs()),
                "{e:?} {chain} vs {closed}"
            );
        }
    }

    #[test]
    fn on_a_dynamic_vehicle_the_measured_speed_cancels_in_lemma_2() {
        // D22c: the law takes the speed the vehicle has, not the one it was asked for; with eq. 21
        // driven by that speed, V̇ is Lemma 2's at that speed, whatever the command.
        let mut rng = ChaCha8Rng::seed_from_u64(22);
        for _ in 0..5_000 {
            let (point, e, current) = random_state(&mut rng);
            let (asked, measured) = (uniform(&mut rng, 0.05, 3.0), uniform(&mut rng, 0.05, 3.0));
            let law = control(&G, &point, &e, asked, measured, current, 0.0);
            assert_eq!(law.v, asked, "the command is the reference");
            let rates = error_rates(&point, &e, measured, law.r, law.gamma_dot, current, 0.0);
            let (chain, closed) = (chain_rule(&G, &e, rates), lyapunov_rate(&G, &e, measured, current));
            assert!(
                (chain - closed).abs() < 1e-9 * (1.0 + closed.abs()),
                "{chain} vs {closed}"
            );
        }
    }

    #[test]
    fn dzeta_matches_finite_difference() {
        for y in [-3.0, -0.2, 0.3, 4.0] {
            let h = 1e-6;
            let fd = (zeta(&G, y + h) - zeta(&G, y - h)) / (2.0 * h);
            assert!((fd - dzeta(&G, y)).abs() < 1e-7);
        }
    }

    #[test]
    fn sigma_is_the_difference_quotient_and_finite_at_equality() {
        for (a, b) in [(0.3, -0.2), (2.5, 1.0), (-1.0, 0.4)] {
            assert!((sigma(a, b) - (f64::sin(a) - f64::sin(b)) / (a - b)).abs() < 1e-12);
        }
        assert!((sigma(0.7, 0.7) - 0.7f64.cos()).abs() < 1e-12);
    }

    #[test]
    fn wrap_stays_in_half_open_interval() {
        assert!((wrap(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap(-0.5 - std::f64::consts::TAU) + 0.5).abs() < 1e-12);
        assert_eq!(wrap(0.25), 0.25);
    }

    #[test]
    fn on_the_path_the_law_tracks_the_nominal_speed() {
        let point = PathPoint {
            position: Vec2::zeros(),
            tangent: Vec2::new(0.6, 0.0),
            second: Vec2::zeros(),
            heading: 0.0,
            curvature: 0.2,
            speed: 0.6,
        };
        let e = Errors::new(0.0, 0.0, 0.0);
        let law = control(&G, &point, &e, 0.6, 0.6, Vec2::zeros(), 0.0);
        assert!((law.gamma_dot - 1.0).abs() < 1e-15);
        assert!((law.r - 0.2 * 0.6).abs() < 1e-15, "turns at c_c v_d");
    }
}
