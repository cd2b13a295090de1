//! The vehicle's controller as a state machine (DESIGN: sans-IO): measured state and neighbours' γ
//! in, command and own γ out. Path following (SPEC §2) with time coordination (SPEC §3).

use crate::coord;
use crate::follow::{self, Gains};
use crate::links::Link;
use crate::mission::{Mission, PostArrival};
use crate::msg::{Command, Gamma, Reception, State, PROTOCOL_VERSION};
use crate::path::{GeneralizedPath, Vec2};

#[derive(Debug, Clone)]
pub struct Agent {
    id: u32,
    path: GeneralizedPath,
    gains: Gains,
    kc: f64,
    dt: f64,
    comm_every: u64,
    post_arrival: PostArrival,
    /// Inbound links j→i, ascending j.
    links: Vec<Link>,
    gamma: f64,
    /// Σ_j (γ_i(t_k) − γ_j(t_k)) over the neighbours heard at the last instant t_k, held until
    /// the next (D12); `None` when none was heard.
    sum: Option<f64>,
    stopped: bool,
}

impl Agent {
    /// The agent of vehicle `id`, at the start of its path (D15).
    pub fn new(mission: &Mission, id: u32, path: GeneralizedPath) -> Agent {
        let c = &mission.control;
        let neighbours = coord::neighbours(mission).remove(&id).unwrap_or_default();
        Agent {
            id,
            path,
            gains: Gains {
                k1: c.k1,
                k2: c.k2,
                k3: c.k3,
                d1: c.d1,
            },
            kc: c.kc,
            dt: mission.mission.control_period,
            comm_every: mission.comm_every(),
            post_arrival: mission.mission.post_arrival,
            links: neighbours
                .iter()
                .map(|&j| Link::new(mission.mission.seed, j, id, mission.comms.loss))
                .collect(),
            gamma: 0.0,
            sum: None,
            stopped: false,
        }
    }

    pub fn id(&self) -> u32 {
        self.id
    }

    pub fn path(&self) -> &GeneralizedPath {
        &self.path
    }

    pub fn gamma(&self) -> f64 {
        self.gamma
    }

    pub fn neighbours(&self) -> impl Iterator<Item = u32> + '_ {
        self.links.iter().map(|l| l.from)
    }

    pub fn is_comm_tick(&self, tick: u64) -> bool {
        !self.links.is_empty() && tick.is_multiple_of(self.comm_every)
    }

    /// γ_i(t_k) for the neighbours, at a communication instant.
    pub fn gamma_to_send(&self, tick: u64) -> Option<Gamma> {
        self.is_comm_tick(tick).then_some(Gamma {
            version: PROTOCOL_VERSION,
            tick,
            from: self.id,
            gamma: self.gamma,
        })
    }

    /// One control period: `inbox` holds the neighbours' γ of this tick (at a communication
    /// instant; others are ignored). Returns the command to hold until the next tick.
    pub fn step(&mut self, state: &State, inbox: &[Gamma]) -> Command {
        let tick = state.tick;
        let mut receptions = Vec::new();
        if self.is_comm_tick(tick) {
            let mut sum = None;
            for link in &mut self.links {
                let message = inbox.iter().find(|m| m.from == link.from && m.tick == tick);
                let delivered = link.transmit();
                if let Some(m) = message {
                    receptions.push(Reception {
                        from: link.from,
                        delivered,
                    });
                    if delivered {
                        *sum.get_or_insert(0.0) += self.gamma - m.gamma;
                    }
                }
            }
            self.sum = sum;
        }

        let point = self.path.at(self.gamma);
        let position = Vec2::from(state.position);
        let errors = follow::errors(position, state.heading + state.sideslip, &point);
        let gamma = self.gamma;
        if !self.stopped && self.post_arrival == PostArrival::Stop && gamma >= self.path.t_f() {
            self.stopped = true;
        }
        let (v, r, gamma_dot) = if self.stopped {
            (0.0, 0.0, 0.0)
        } else {
            let v = coord::speed(point.speed, errors.psi_e, self.kc, self.sum); // eq. 25
            let current = follow::to_frame(point.heading, Vec2::from(state.current));
            let law = follow::control(&self.gains, &point, &errors, v, current, state.sideslip_rate);
            (law.v, law.r, law.gamma_dot)
        };
        self.gamma += self.dt * gamma_dot;
        Command {
            version: PROTOCOL_VERSION,
            tick,
            id: self.id,
            v,
            r,
            hold: self.stopped,
            gamma,
            gamma_dot,
            v_d: point.speed,
            x_e: errors.x_e,
            y_e: errors.y_e,
            psi_e: errors.psi_e,
            receptions,
        }
    }
}
