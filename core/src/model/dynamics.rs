//! A MEDUSA-class vehicle (MODEL D22): 3-DOF dynamics in the water current, two stern thrusters
//! with a dead zone, a dead time and a motor lag, and the inner loops that track the law's speed
//! and yaw-rate references. The world integrates it; the agent only reads its measured velocity.

use std::collections::VecDeque;

use crate::mission::VehicleModelConfig;
use crate::model::path::Vec2;

/// m₁₁ = m − X_u̇, kg (D22a).
pub const M11: f64 = 50.0;
/// m₂₂ = m − Y_v̇, kg.
pub const M22: f64 = 60.0;
/// m₃₃ = I_z − N_ṙ, kg m².
pub const M33: f64 = 4.64;
/// l, m: thruster 1 at y_b = −l, thruster 2 at y_b = +l.
pub const ARM: f64 = 0.15;
/// %: commands below this in magnitude do not turn the motor (D22b).
pub const DEAD_ZONE: f64 = 8.6;
/// %: the largest command.
pub const FULL: f64 = 100.0;
/// T_d, s: the thrusters' dead time.
pub const DEAD_TIME: f64 = 0.345;
/// p, rad/s: the motor pole.
pub const MOTOR_POLE: f64 = 7.2115;
/// a, N/RPM²: the thrust curve F = a (g n)|g n|.
pub const THRUST_COEFFICIENT: f64 = 1.77778e-6;
/// g, RPM/%.
pub const RPM_PER_PERCENT: f64 = 45.0;

/// d_u(u) = −X_u − X_|u|u |u|, kg/s.
pub fn surge_damping(u: f64) -> f64 {
    27.5 * u.abs()
}

/// d_v(v) = −Y_v − Y_|v|v |v|, kg/s.
pub fn sway_damping(v: f64) -> f64 {
    55.1 + 101.0 * v.abs()
}

/// d_r(r) = −N_r − N_|r|r |r|, kg m²/s.
pub fn yaw_damping(r: f64) -> f64 {
    4.14 + 6.23 * r.abs()
}

/// A(c): a command as the motor takes it, clipped to ±100 % and zero inside the dead zone (D22b).
pub fn motor_input(c: f64) -> f64 {
    let c = c.clamp(-FULL, FULL);
    if c.abs() < DEAD_ZONE {
        0.0
    } else {
        c
    }
}

/// F = a (g n)|g n|, N, of a motor at n %.
pub fn thrust(n: f64) -> f64 {
    let rpm = RPM_PER_PERCENT * n;
    THRUST_COEFFICIENT * rpm * rpm.abs()
}

/// c(T) = sign(T) √(|T|/a) / g: the command, %, for a thrust T, N (D22b).
pub fn command_for(thrust: f64) -> f64 {
    (thrust.abs() / THRUST_COEFFICIENT).sqrt().copysign(thrust) / RPM_PER_PERCENT
}

/// n_d = ⌊T_d/h + ½⌋: whole control periods of dead time.
pub fn dead_time_ticks(h: f64) -> usize {
    (DEAD_TIME / h + 0.5).floor() as usize
}

/// The plant's state s = (x, y, ψ, u, v, r, n₁, n₂) (D22a): ν = (u, v, r) is the body velocity
/// relative to the water, n the motors' states in %.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plant {
    pub position: Vec2,
    pub heading: f64,
    pub u: f64,
    pub v: f64,
    pub r: f64,
    pub motor: [f64; 2],
}

impl Plant {
    /// ν̇ = M⁻¹ (τ − C(ν) ν − D(ν) ν), with τ from the motors' present thrust.
    pub fn acceleration(&self) -> [f64; 3] {
        let (f1, f2) = (thrust(self.motor[0]), thrust(self.motor[1]));
        let (u, v, r) = (self.u, self.v, self.r);
        [
            (f1 + f2 + M22 * v * r - surge_damping(u) * u) / M11,
            (-M11 * u * r - sway_damping(v) * v) / M22,
            (ARM * (f1 - f2) - (M22 - M11) * u * v - yaw_damping(r) * r) / M33,
        ]
    }

    /// ṡ with the motor inputs `w` held and the current `current` (inertial, m/s).
    fn rate(&self, w: [f64; 2], current: Vec2) -> Plant {
        let (sin, cos) = self.heading.sin_cos();
        let [du, dv, dr] = self.acceleration();
        Plant {
            position: Vec2::new(self.u * cos - self.v * sin, self.u * sin + self.v * cos) + current,
            heading: self.r,
            u: du,
            v: dv,
            r: dr,
            motor: [0, 1].map(|i| MOTOR_POLE * (w[i] - self.motor[i])),
        }
    }

    /// self + h · d.
    fn plus(&self, h: f64, d: &Plant) -> Plant {
        Plant {
            position: self.position + h * d.position,
            heading: self.heading + h * d.heading,
            u: self.u + h * d.u,
            v: self.v + h * d.v,
            r: self.r + h * d.r,
            motor: [0, 1].map(|i| self.motor[i] + h * d.motor[i]),
        }
    }

    /// One classical RK4 step of length h, `w` held (D22e, step 6). ψ is left unwrapped: the
    /// world wraps it as it publishes.
    pub fn step(&self, h: f64, w: [f64; 2], current: Vec2) -> Plant {
        let k1 = self.rate(w, current);
        let k2 = self.plus(0.5 * h, &k1).rate(w, current);
        let k3 = self.plus(0.5 * h, &k2).rate(w, current);
        let k4 = self.plus(h, &k3).rate(w, current);
        let sum = |a: f64, b: f64, c: f64, d: f64| (a + 2.0 * b + 2.0 * c + d) / 6.0;
        let average = Plant {
            position: (k1.position + 2.0 * k2.position + 2.0 * k3.position + k4.position) / 6.0,
            heading: sum(k1.heading, k2.heading, k3.heading, k4.heading),
            u: sum(k1.u, k2.u, k3.u, k4.u),
            v: sum(k1.v, k2.v, k3.v, k4.v),
            r: sum(k1.r, k2.r, k3.r, k4.r),
            motor: [0, 1].map(|i| sum(k1.motor[i], k2.motor[i], k3.motor[i], k4.motor[i])),
        };
        self.plus(h, &average)
    }

    /// β = atan2(v, u), the side-slip (D22c).
    pub fn sideslip(&self) -> f64 {
        self.v.atan2(self.u)
    }

    /// β̇ = (u v̇ − v u̇)/U², 0 at rest: what [vehicle_model] beta_dot = "model" feeds eq. 22b.
    pub fn sideslip_rate(&self) -> f64 {
        let speed2 = self.u * self.u + self.v * self.v;
        if speed2 == 0.0 {
            return 0.0;
        }
        let [du, dv, _] = self.acceleration();
        (self.u * dv - self.v * du) / speed2
    }

    /// ½ νᵀ M ν, J.
    pub fn kinetic_energy(&self) -> f64 {
        0.5 * (M11 * self.u * self.u + M22 * self.v * self.v + M33 * self.r * self.r)
    }
}

/// The dead time as a whole-step delay line (D22b): the motor input of t_k is applied over
/// [t_{k+n_d}, t_{k+n_d+1}).
#[derive(Debug, Clone, PartialEq)]
pub struct DelayLine {
    queue: VecDeque<[f64; 2]>,
}

impl DelayLine {
    /// n_d entries of `w`, as if it had been commanded for the whole dead time.
    pub fn full_of(ticks: usize, w: [f64; 2]) -> DelayLine {
        DelayLine {
            queue: std::iter::repeat_n(w, ticks).collect(),
        }
    }

    /// Pushes this tick's input and pops the one whose dead time has passed.
    pub fn shift(&mut self, w: [f64; 2]) -> [f64; 2] {
        self.queue.push_back(w);
        self.queue.pop_front().expect("just pushed")
    }
}

/// What the law asks of the vehicle at one tick (D22c): the speed through the water v_ref, the yaw
/// rate r_ref and the fed-forward acceleration a_ff.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reference {
    pub speed: f64,
    pub yaw_rate: f64,
    pub accel: f64,
}

/// The surge and yaw-rate loops with their integrators (D22d).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InnerLoops {
    surge_kp: f64,
    surge_ki: f64,
    yaw_rate_kp: f64,
    yaw_rate_ki: f64,
    surge_integral: f64,
    yaw_rate_integral: f64,
}

/// The thruster commands of one tick, %, and whether either had to be clipped to ±100 %.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Commands {
    pub c: [f64; 2],
    pub clipped: bool,
}

impl InnerLoops {
    pub fn new(config: &VehicleModelConfig) -> InnerLoops {
        InnerLoops {
            surge_kp: config.surge_kp,
            surge_ki: config.surge_ki,
            yaw_rate_kp: config.yaw_rate_kp,
            yaw_rate_ki: config.yaw_rate_ki,
            surge_integral: 0.0,
            yaw_rate_integral: 0.0,
        }
    }

    /// The commands that track `reference` from the sampled state `s`, then the integrators'
    /// step unless a command was clipped (anti-windup, D22d).
    pub fn commands(&mut self, s: &Plant, reference: &Reference, h: f64) -> Commands {
        // D22c: the surge reference that makes U = v_ref when u = u_ref.
        let u_ref = reference.speed * s.sideslip().cos();
        let r_ref = reference.yaw_rate;
        let (e_u, e_r) = (u_ref - s.u, r_ref - s.r);
        let surge_force = surge_damping(u_ref) * u_ref - M22 * s.v * s.r
            + M11 * (reference.accel + self.surge_kp * e_u + self.surge_ki * self.surge_integral);
        let yaw_moment = yaw_damping(r_ref) * r_ref
            + (M22 - M11) * s.u * s.v
            + M33 * (self.yaw_rate_kp * e_r + self.yaw_rate_ki * self.yaw_rate_integral);
        let wanted = [
            command_for(surge_force / 2.0 + yaw_moment / (2.0 * ARM)),
            command_for(surge_force / 2.0 - yaw_moment / (2.0 * ARM)),
        ];
        let clipped = wanted.iter().any(|c| c.abs() > FULL);
        if !clipped {
            self.surge_integral += h * e_u;
            self.yaw_rate_integral += h * e_r;
        }
        Commands {
            c: wanted.map(|c| c.clamp(-FULL, FULL)),
            clipped,
        }
    }
}

/// A MEDUSA-class vehicle as the world integrates it: plant, thrusters and inner loops.
#[derive(Debug, Clone, PartialEq)]
pub struct Medusa {
    pub plant: Plant,
    delay: DelayLine,
    loops: InnerLoops,
    /// The thruster commands of the last tick, as the inner loops gave them.
    pub last: Commands,
}

impl Medusa {
    /// At rest relative to its path (D22e): heading `heading`, surge `speed`, no sway or turn, the
    /// motors and the delay line at the command that holds that speed.
    pub fn new(config: &VehicleModelConfig, position: Vec2, heading: f64, speed: f64, h: f64) -> Medusa {
        let c = command_for(0.5 * surge_damping(speed) * speed);
        let n = motor_input(c);
        Medusa {
            plant: Plant {
                position,
                heading,
                u: speed,
                v: 0.0,
                r: 0.0,
                motor: [n, n],
            },
            delay: DelayLine::full_of(dead_time_ticks(h), [n, n]),
            loops: InnerLoops::new(config),
            last: Commands {
                c: [c, c],
                clipped: false,
            },
        }
    }

    /// One control period (D22e, steps 4–6): the inner loops track `reference`, or the thrusters
    /// are off without one.
    pub fn step(&mut self, reference: Option<&Reference>, current: Vec2, h: f64) {
        self.last = match reference {
            Some(reference) => self.loops.commands(&self.plant, reference, h),
            None => Commands {
                c: [0.0; 2],
                clipped: false,
            },
        };
        let w = self.delay.shift(self.last.c.map(motor_input));
        self.plant = self.plant.step(h, w, current);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_chacha::rand_core::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    const H: f64 = 0.01;

    fn at_rest() -> Plant {
        Plant {
            position: Vec2::zeros(),
            heading: 0.0,
            u: 0.0,
            v: 0.0,
            r: 0.0,
            motor: [0.0; 2],
        }
    }

    /// Open loop from rest, the delay line full of zeros, commands `c` from t = 0: the plant at
    /// every tick up to `seconds`.
    fn open_loop(c: [f64; 2], seconds: f64) -> Vec<Plant> {
        let mut delay = DelayLine::full_of(dead_time_ticks(H), [0.0; 2]);
        let mut s = at_rest();
        let mut out = vec![s];
        for _ in 0..(seconds / H).round() as usize {
            let w = delay.shift(c.map(motor_input));
            s = s.step(H, w, Vec2::zeros());
            out.push(s);
        }
        out
    }

    /// The first time, s, at which `f` reaches `level`, interpolated inside the tick.
    fn crossing(run: &[Plant], f: impl Fn(&Plant) -> f64, level: f64) -> f64 {
        let k = run.iter().position(|s| f(s) >= level).expect("reaches the level");
        let (a, b) = (f(&run[k - 1]), f(&run[k]));
        ((k - 1) as f64 + (level - a) / (b - a)) * H
    }

    /// 63.2 %: 1 − 1/e, one time constant of a first-order lag.
    const RISE: f64 = 1.0 - 1.0 / std::f64::consts::E;

    #[test]
    fn full_thrust_gives_the_steady_surge_and_its_rise_times() {
        let run = open_loop([FULL, FULL], 60.0);
        let end = run.last().unwrap();
        // √(2·36.000045/27.5)
        assert!((end.u - 1.618081).abs() < 5e-7, "u = {}", end.u);
        assert_eq!((end.v, end.r), (0.0, 0.0), "no sway or turn, exactly");
        assert!((thrust(FULL) - 36.000045).abs() < 1e-9);
        let first = run.iter().position(|s| s.motor[0] > 0.0).unwrap();
        assert!((first as f64 * H - 0.36).abs() < 1e-9, "first tick with n > 0: {first}");
        let motor = crossing(&run, |s| s.motor[0], RISE * FULL);
        assert!((motor - 0.4887).abs() < 5e-4, "motor 63.2 % at {motor}");
        let force = crossing(&run, |s| thrust(s.motor[0]), RISE * thrust(FULL));
        assert!((force - 0.5698).abs() < 5e-4, "thrust 63.2 % at {force}");
        let surge = crossing(&run, |s| s.u, RISE * 1.618081);
        assert!((surge - 1.3971).abs() < 5e-4, "surge 63.2 % at {surge}");
    }

    #[test]
    fn opposite_thrust_gives_the_steady_yaw_rate() {
        let run = open_loop([FULL, -FULL], 60.0);
        let end = run.last().unwrap();
        // 4.14 r + 6.23 r² = 2 · 0.15 · 36.000045
        assert!((end.r - 1.025657).abs() < 5e-7, "r = {}", end.r);
        assert_eq!((end.u, end.v), (0.0, 0.0));
        let turn = crossing(&run, |s| s.r, RISE * 1.025657);
        assert!((turn - 0.9315).abs() < 5e-4, "yaw rate 63.2 % at {turn}");
    }

    /// From steady 0.5 m/s, the inner loops given a step of `reference` at t = 0: the 63 % time of
    /// `f` from its start to `target`, and its overshoot past the target, relative to the step.
    fn step_response(reference: Reference, f: impl Fn(&Plant) -> f64, target: f64) -> (f64, f64) {
        let config = VehicleModelConfig::default();
        let mut vehicle = Medusa::new(&config, Vec2::zeros(), 0.0, 0.5, H);
        let start = f(&vehicle.plant);
        let mut run = vec![vehicle.plant];
        for _ in 0..2000 {
            vehicle.step(Some(&reference), Vec2::zeros(), H);
            run.push(vehicle.plant);
        }
        let sign = (target - start).signum();
        let rise = crossing(&run, |s| sign * f(s), sign * (start + RISE * (target - start)));
        let peak = run.iter().map(|s| sign * (f(s) - target)).fold(0.0, f64::max);
        (rise, peak / (target - start).abs())
    }

    #[test]
    fn the_inner_loops_answer_a_step_as_d22d_says() {
        let surge = |s: &Plant| s.u;
        let turn = |s: &Plant| s.r;
        for (reference, f, target, rise, overshoot) in [
            ((0.7, 0.0), &surge as &dyn Fn(&Plant) -> f64, 0.7, 0.941, 0.112),
            ((0.3, 0.0), &surge, 0.3, 1.022, 0.120),
            ((0.5, 0.1), &turn, 0.1, 0.830, 0.181),
            ((0.5, 0.3), &turn, 0.3, 0.853, 0.151),
        ] {
            let reference = Reference {
                speed: reference.0,
                yaw_rate: reference.1,
                accel: 0.0,
            };
            let (t, o) = step_response(reference, f, target);
            assert!(
                (t - rise).abs() <= 5e-4 && (o - overshoot).abs() <= 5e-4,
                "{reference:?}: 63 % at {t} s, overshoot {o}"
            );
        }
    }

    #[test]
    fn the_dead_zone_and_the_thrust_curve() {
        assert!((thrust(motor_input(8.6)) - 0.266256).abs() < 5e-7);
        assert_eq!(thrust(motor_input(8.5)), 0.0);
        assert_eq!(motor_input(-8.5), 0.0);
        assert_eq!(motor_input(250.0), FULL);
        assert_eq!(motor_input(-250.0), -FULL);
        for t in [-30.0, -0.5, 0.0, 0.266256, 12.0, 36.000045] {
            assert!((thrust(command_for(t)) - t).abs() < 1e-9, "c(T) inverts F at {t}");
        }
        assert_eq!(dead_time_ticks(0.01), 35);
        // The initial state of D22e: the command that holds 0.5 m/s.
        let c = command_for(0.5 * surge_damping(0.5) * 0.5);
        assert!((motor_input(c) - 30.900808).abs() < 5e-7, "{c}");
    }

    #[test]
    fn the_delay_line_gives_back_a_tick_n_d_ticks_later() {
        let mut line = DelayLine::full_of(3, [0.0; 2]);
        let out: Vec<f64> = (1..=6).map(|k| line.shift([k as f64, -(k as f64)])[0]).collect();
        assert_eq!(out, [0.0, 0.0, 0.0, 1.0, 2.0, 3.0]);
    }

    #[test]
    fn kinetic_energy_falls_at_every_step_without_input() {
        let energy_after = |from: Plant, seconds: f64| {
            let mut s = from;
            let mut e = s.kinetic_energy();
            for _ in 0..(seconds / H).round() as usize {
                s = s.step(H, [0.0; 2], Vec2::new(0.1, -0.05));
                let next = s.kinetic_energy();
                assert!(next <= e, "{from:?}: energy rose from {e} to {next}");
                e = next;
            }
            e
        };
        let start = Plant {
            u: 1.0,
            v: 0.3,
            r: 0.5,
            ..at_rest()
        };
        assert!((start.kinetic_energy() - 28.28).abs() < 1e-12);
        let e10 = energy_after(start, 10.0);
        assert!((e10 - 0.5998).abs() < 5e-5, "{e10}");
        let e30 = energy_after(start, 30.0);
        assert!((e30 - 0.0820).abs() < 5e-5, "{e30}");
        // νᵀ C ν = 0: from any state, the energy never grows.
        let mut rng = ChaCha8Rng::seed_from_u64(22);
        let mut uniform = |lo: f64, hi: f64| lo + (hi - lo) * ((rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64);
        for _ in 0..200 {
            let from = Plant {
                heading: uniform(-3.0, 3.0),
                u: uniform(-2.0, 2.0),
                v: uniform(-1.0, 1.0),
                r: uniform(-1.5, 1.5),
                ..at_rest()
            };
            energy_after(from, 2.0);
        }
    }

    #[test]
    fn the_sideslip_rate_is_the_derivative_of_atan2() {
        let s = Plant {
            u: 0.6,
            v: -0.05,
            r: 0.2,
            motor: [40.0, 20.0],
            ..at_rest()
        };
        let h = 1e-6;
        let ahead = s.step(h, s.motor, Vec2::zeros());
        let behind = s.step(-h, s.motor, Vec2::zeros());
        let numeric = (ahead.sideslip() - behind.sideslip()) / (2.0 * h);
        assert!(
            (numeric - s.sideslip_rate()).abs() < 1e-8,
            "{numeric} {}",
            s.sideslip_rate()
        );
    }
}
