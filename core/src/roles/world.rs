//! The world as a state machine: every vehicle in the shared current, integrated by RK4 over one
//! control period with the commands held: the kinematic vehicle of MODEL §2, or a dynamic one with
//! its thrusters and inner loops (MODEL D22).

use crate::mission::{Mission, VehicleKind};
use crate::model::dynamics::{Medusa, Reference};
use crate::model::follow;
use crate::model::path::{GeneralizedPath, Vec2};
use crate::msg::{Command, Dynamics, State, PROTOCOL_VERSION};

#[derive(Debug, Clone)]
struct Body {
    id: u32,
    lost: bool,
    vehicle: Vehicle,
}

/// What the world integrates of a body.
#[derive(Debug, Clone)]
enum Vehicle {
    /// MODEL §2: position and body heading ψ_B.
    Kinematic { position: Vec2, heading: f64 },
    /// MODEL D22: its plant holds the position and heading.
    Medusa(Box<Medusa>),
}

#[derive(Debug, Clone)]
pub struct World {
    dt: f64,
    tick: u64,
    current: Vec2,
    sideslip_amplitude: f64,
    sideslip_omega: f64,
    bodies: Vec<Body>,
}

impl World {
    /// Vehicles start on their paths at P0, heading along v0, offset by `initial_offset` (D15).
    pub fn new(mission: &Mission, paths: &[(u32, GeneralizedPath)]) -> World {
        let mut world = World {
            dt: mission.mission.control_period,
            tick: 0,
            current: Vec2::new(mission.current.direction.cos(), mission.current.direction.sin())
                * mission.current.speed,
            sideslip_amplitude: mission.sideslip.amplitude,
            sideslip_omega: std::f64::consts::TAU / mission.sideslip.period,
            bodies: Vec::with_capacity(paths.len()),
        };
        for (id, path) in paths {
            let offset = mission
                .vehicles
                .iter()
                .find(|v| v.id == *id)
                .map_or([0.0; 3], |v| v.initial_offset);
            let p0 = path.at(0.0);
            let (s, c) = p0.heading.sin_cos();
            let position = p0.position + Vec2::new(c * offset[0] - s * offset[1], s * offset[0] + c * offset[1]);
            let model = mission.vehicle_model(*id);
            let vehicle = match model.kind {
                VehicleKind::Kinematic => Vehicle::Kinematic {
                    position,
                    heading: follow::wrap(p0.heading + offset[2] - world.sideslip(0.0).0),
                },
                // D22e: ψ along v₀ (no side-slip at rest in sway), u = |v₀|.
                VehicleKind::Medusa => Vehicle::Medusa(Box::new(Medusa::new(
                    model,
                    position,
                    follow::wrap(p0.heading + offset[2]),
                    p0.speed,
                    world.dt,
                ))),
            };
            world.bodies.push(Body {
                id: *id,
                lost: false,
                vehicle,
            });
        }
        world
    }

    /// β(t) and β̇(t) (D9).
    fn sideslip(&self, t: f64) -> (f64, f64) {
        let (s, c) = (self.sideslip_omega * t).sin_cos();
        (
            self.sideslip_amplitude * s,
            self.sideslip_amplitude * self.sideslip_omega * c,
        )
    }

    pub fn tick(&self) -> u64 {
        self.tick
    }

    pub fn time(&self) -> f64 {
        self.tick as f64 * self.dt
    }

    pub fn ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.bodies.iter().map(|b| b.id)
    }

    /// The n-th vehicle (in the order of `paths` given to `new`) has lost its agent: from now on
    /// it drifts with the current, thrusters off.
    pub fn mark_lost(&mut self, n: usize) {
        self.bodies[n].lost = true;
    }

    /// Whether the n-th vehicle has lost its agent.
    pub fn is_lost(&self, n: usize) -> bool {
        self.bodies[n].lost
    }

    /// The measured states of tick k, in the order of `paths` given to `new`, into `out` (whose
    /// allocation a run reuses tick after tick).
    pub fn states(&self, out: &mut Vec<State>) {
        let t = self.time();
        let (beta, beta_dot) = self.sideslip(t);
        out.clear();
        out.extend(self.bodies.iter().map(|b| match &b.vehicle {
            Vehicle::Kinematic { position, heading } => State {
                version: PROTOCOL_VERSION,
                tick: self.tick,
                id: b.id,
                t,
                position: (*position).into(),
                heading: *heading,
                sideslip: beta,
                sideslip_rate: beta_dot,
                current: self.current.into(),
                dynamics: None,
            },
            Vehicle::Medusa(m) => {
                let s = &m.plant;
                State {
                    version: PROTOCOL_VERSION,
                    tick: self.tick,
                    id: b.id,
                    t,
                    position: s.position.into(),
                    heading: follow::wrap(s.heading),
                    sideslip: s.sideslip(),
                    sideslip_rate: s.sideslip_rate(),
                    current: self.current.into(),
                    dynamics: Some(Dynamics {
                        surge: s.u,
                        sway: s.v,
                        yaw_rate: s.r,
                        command: m.last.c,
                        motor: s.motor,
                        thrust: s.motor.map(crate::model::dynamics::thrust),
                    }),
                }
            }
        }));
    }

    /// Integrates tick k → k+1. `commands[n]` is the held command of the n-th vehicle; `None`
    /// (or a lost vehicle) means thrusters off.
    pub fn step(&mut self, commands: &[Option<Command>]) {
        let t = self.time();
        let dt = self.dt;
        // β at the three instants RK4 samples, the same for every vehicle: evaluated once per tick,
        // and not at all without side-slip. (A branch inside the loop is not enough: LLVM hoists
        // the sines out of it, and, sine being free of side effects, runs them unconditionally.)
        let beta = (self.sideslip_amplitude != 0.0)
            .then(|| [0.0, 0.5 * dt, dt].map(|s| self.sideslip_amplitude * (self.sideslip_omega * (t + s)).sin()));
        let current = self.current;
        for (n, b) in self.bodies.iter_mut().enumerate() {
            let command = commands.get(n).and_then(Option::as_ref).filter(|_| !b.lost);
            if command.is_some_and(|c| c.hold) {
                continue;
            }
            let (position, heading) = match &mut b.vehicle {
                Vehicle::Kinematic { position, heading } => (position, heading),
                Vehicle::Medusa(m) => {
                    let reference = command.map(|c| Reference {
                        speed: c.v,
                        yaw_rate: c.r,
                        accel: c.accel,
                    });
                    m.step(reference.as_ref(), current, dt);
                    continue;
                }
            };
            let (v, r) = command.map_or((0.0, 0.0), |c| (c.v, c.r));
            // ṗ = v (cos ψ_F, sin ψ_F) + v_c (cos ψ_c, sin ψ_c), ψ_F = ψ_B + β(t), ψ̇_B = r.
            let f = |k: usize, heading: f64| {
                let psi_f = beta.map_or(heading, |beta| heading + beta[k]);
                Vec2::new(v * psi_f.cos(), v * psi_f.sin()) + current
            };
            let h0 = *heading;
            let k1 = f(0, h0);
            let k2 = f(1, h0 + 0.5 * dt * r);
            // The field depends on time and heading only, not on position, so k3 = k2.
            let k3 = k2;
            let k4 = f(2, h0 + dt * r);
            *position += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
            *heading = follow::wrap(h0 + dt * r);
        }
        self.tick += 1;
    }
}
