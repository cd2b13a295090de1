//! The vehicle's controller as a state machine (DESIGN: sans-IO): measured state and neighbours' γ
//! in, command and own γ out. Path following (SPEC §2) with time coordination (SPEC §3).

use crate::coord;
use crate::follow::{self, Gains};
use std::collections::VecDeque;

use crate::links::{Link, LinkSpec};
use crate::mission::{Mission, PostArrival};
use crate::msg::{Command, Gamma, Reception, State, PROTOCOL_VERSION};
use crate::path::{GeneralizedPath, Vec2};

/// An inbound link and the messages it delivered that are not yet usable (SPEC D12 with delay).
#[derive(Debug, Clone)]
struct Inbound {
    link: Link,
    /// Ticks from sending to use: the delay rounded up to whole communication periods, since γ
    /// is only used at communication instants.
    delay_ticks: u64,
    /// (tick sent, γ_j) of delivered messages, oldest first.
    delivered: VecDeque<(u64, f64)>,
}

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
    links: Vec<Inbound>,
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
                .map(|&j| {
                    let link = Link::new(mission.mission.seed, j, id, LinkSpec::of(mission, j, id));
                    let periods = (link.delay() / mission.comms.period - 1e-9).ceil().max(0.0) as u64;
                    Inbound {
                        link,
                        delay_ticks: periods * mission.comm_every(),
                        delivered: VecDeque::new(),
                    }
                })
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
        self.links.iter().map(|l| l.link.from)
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
            let t = tick as f64 * self.dt;
            for inbound in &mut self.links {
                let from = inbound.link.from;
                let message = inbox.iter().find(|m| m.from == from && m.tick == tick);
                let delivered = inbound.link.transmit(t);
                if let Some(m) = message {
                    receptions.push(Reception { from, delivered });
                    if delivered {
                        inbound.delivered.push_back((tick, m.gamma));
                    }
                }
                // The message of t_k − delay, if it got through, is what j is heard saying now.
                let sent = tick.checked_sub(inbound.delay_ticks);
                while inbound.delivered.front().is_some_and(|(k, _)| Some(*k) < sent) {
                    inbound.delivered.pop_front();
                }
                if let Some(&(_, gamma_j)) = inbound.delivered.front().filter(|(k, _)| Some(*k) == sent) {
                    *sum.get_or_insert(0.0) += self.gamma - gamma_j;
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
