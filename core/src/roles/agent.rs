//! The vehicle's controller as a state machine (sans-IO): measured state and neighbours' γ
//! in, command and own γ out. Path following (MODEL §2) with time coordination (MODEL §3), on links
//! that lose, delay and ration messages (MODEL §6).

use std::collections::VecDeque;

use crate::links::modem::{Arrival, Receiver};
use crate::links::{Cause, Link, LinkSpec};
use crate::mission::{BetaDot, Mission, ModemConfig, PostArrival, Trigger, VehicleModelConfig};
use crate::model::coord;
use crate::model::follow::{self, Gains};
use crate::model::path::{GeneralizedPath, Vec2};
use crate::msg::{Command, Gamma, Reception, Sample, State, PROTOCOL_VERSION};

/// An inbound link j→i and what it delivered.
#[derive(Debug, Clone)]
struct Inbound {
    link: Link,
    /// Delivered samples still travelling: (tick from which usable, sample).
    in_flight: VecDeque<(u64, Sample)>,
    /// The newest sample that has arrived, and the tick it arrived.
    latest: Option<(u64, Sample)>,
}

/// A shared acoustic medium (D21): the vehicle at `position` of the ascending ids sends only in
/// slots position, position + n, position + 2n, …
#[derive(Debug, Clone, Copy)]
struct Tdma {
    slot_ticks: u64,
    vehicles: u64,
    position: u64,
}

/// A vehicle's half-duplex modem (D23): when it last transmitted, what it hears in the water,
/// and the frames of its neighbours not yet judged.
#[derive(Debug, Clone)]
struct Acoustic {
    /// The fleet's waveform: the airtime.
    modem: ModemConfig,
    /// Per audible vehicle, the modem its frames reach this one with, and the speed they travel.
    senders: Vec<(u32, ModemConfig, f64)>,
    last_sent: Option<f64>,
    receiver: Receiver,
    /// In the order sent, each judged at its tick.
    pending: VecDeque<Pending>,
}

/// A neighbour's frame in the water, judged once its last bit is in (and every frame that could
/// overlap it has been sent).
#[derive(Debug, Clone)]
struct Pending {
    /// Index of its inbound link.
    link: usize,
    due: u64,
    arrival: Arrival,
    sample: Sample,
    distance: f64,
    /// What the link's own models (D12, D21) made of it, applied once it survives the physics.
    verdict: Cause,
    /// The link's draw for it.
    u: f64,
}

impl Acoustic {
    fn busy(&self, t: f64) -> bool {
        self.last_sent.is_some_and(|s| t < s + self.modem.airtime())
    }

    /// The frame `sample` of vehicle `from` as it reaches this vehicle, at `here` when it was sent.
    fn arrival(&self, from: u32, sample: &Sample, here: Vec2) -> Option<Arrival> {
        let (_, modem, c) = self.senders.iter().find(|(j, ..)| *j == from)?;
        let d = (Vec2::from(sample.position) - here).norm();
        Some(Arrival {
            from,
            sent: sample.t,
            start: sample.t + d / c,
            level: modem.received_level(d),
        })
    }

    /// Every frame sent at this instant reaches this vehicle, at `here`, neighbour's or not: heard
    /// in the order of the senders' ids, whatever order the network brought them in.
    fn hear(&mut self, inbox: &[Gamma], here: Vec2) {
        let heard = self.receiver.heard();
        for g in inbox {
            if let Some(a) = g.sample.and_then(|s| self.arrival(g.from, &s, here)) {
                self.receiver.hear(a);
            }
        }
        self.receiver.sort_from(heard);
    }

    /// Judges the frames due by `tick`, in the order sent: receptions for each, and the
    /// delivered ones usable now.
    fn judge(&mut self, tick: u64, t: f64, links: &mut [Inbound], receptions: &mut Vec<Reception>) {
        let mut k = 0;
        while k < self.pending.len() {
            if self.pending[k].due > tick {
                k += 1;
                continue;
            }
            let p = self.pending.remove(k).expect("a frame is due");
            let inbound = &mut links[p.link];
            let modem = inbound.link.spec().modem.expect("a link with a modem");
            let judged = self.receiver.judge(&modem, &p.arrival, p.u);
            let cause = if judged.cause.delivered() {
                p.verdict
            } else {
                judged.cause
            };
            receptions.push(Reception {
                from: inbound.link.from,
                delivered: cause.delivered(),
                sent: p.sample.t,
                distance: Some(p.distance),
                sinr_db: judged.sinr_db,
                cause,
            });
            if cause.delivered() {
                inbound.in_flight.push_back((tick, p.sample));
            }
        }
        let oldest = self.pending.iter().map(|p| p.arrival.start).fold(t, f64::min);
        self.receiver.forget_before(oldest, self.modem.airtime());
    }
}

impl Tdma {
    fn slot(&self, tick: u64) -> u64 {
        tick / self.slot_ticks
    }

    fn is_mine(&self, tick: u64) -> bool {
        self.slot(tick) % self.vehicles == self.position
    }

    fn cycle_ticks(&self) -> u64 {
        self.slot_ticks * self.vehicles
    }
}

#[derive(Debug, Clone)]
pub struct Agent {
    id: u32,
    path: GeneralizedPath,
    gains: Gains,
    /// k_c, capped by the largest delay when delay is compensated (D19).
    kc: f64,
    dt: f64,
    /// T_c, s, and in ticks.
    comm_period: f64,
    comm_every: u64,
    post_arrival: PostArrival,
    compensate: bool,
    trigger: Trigger,
    threshold: f64,
    heartbeat_ticks: u64,
    tdma: Option<Tdma>,
    /// Ticks for which an arrived sample stands for its sender: one period when every instant
    /// brings a new one (D12's drop semantics), longer when senders may stay silent.
    hold_ticks: u64,
    /// Inbound links j→i, ascending j.
    links: Vec<Inbound>,
    /// The vehicles whose γ messages this agent takes: its neighbours, or with a modem every
    /// other vehicle, whose frames the water carries whatever the graph (D23).
    audible: Vec<u32>,
    acoustic: Option<Acoustic>,
    gamma: f64,
    /// γ̇ over the last control period: the rate a sample carries.
    gamma_dot: f64,
    /// The last sample sent, and its tick: what the neighbours believe of γ_i (D20).
    sent: Option<(u64, Sample)>,
    /// Σ_j (γ_i(t_k) − γ̂_j(t_k)) over the neighbours heard at the last instant t_k, held until
    /// the next (D12, D19); `None` when none was heard.
    sum: Option<f64>,
    stopped: bool,
    /// The model of a dynamic vehicle, whose law takes its measured speed (D22c); `None` for a
    /// kinematic one.
    dynamic: Option<VehicleModelConfig>,
    /// The tick of the last `step`: a realtime agent may skip periods, a lockstep one never does.
    last_tick: Option<u64>,
}

/// Ticks for `seconds`, rounded up to whole communication periods: γ is used at communication
/// instants only, so a delay or a heartbeat counts from one to the next.
fn in_ticks(seconds: f64, period: f64, comm_every: u64) -> u64 {
    // Saturating: a forged position far away must not wrap a delay around to none.
    ((seconds / period - 1e-9).ceil().max(0.0) as u64).saturating_mul(comm_every)
}

/// What a sample says of its sender's γ at time t: predicted from its age and rate (D19), or
/// taken as it was sent.
fn estimate(sample: &Sample, t: f64, compensate: bool) -> f64 {
    if compensate {
        sample.gamma + sample.gamma_dot * (t - sample.t)
    } else {
        sample.gamma
    }
}

/// The coordination gain every agent of a mission uses (D19): k_c, capped by the largest delay
/// any link can impose (as the receivers count it, in whole periods) when delay is compensated.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CoordinationGain {
    /// `control.kc` as the mission sets it.
    pub kc: f64,
    /// k_c,eff: what the agents use.
    pub effective: f64,
    /// s: the largest delay the cap was computed from.
    pub max_delay_s: f64,
}

impl CoordinationGain {
    pub fn of(mission: &Mission) -> CoordinationGain {
        let (c, k) = (&mission.control, &mission.comms);
        let graph = mission.graph();
        let comm_every = mission.comm_every();
        let dt = mission.mission.control_period;
        let max_delay_s = graph
            .iter()
            .flat_map(|(&to, from)| from.iter().map(move |&j| LinkSpec::of(mission, j, to).max_delay()))
            .map(|d| in_ticks(d, k.period, comm_every) as f64 * dt)
            .fold(0.0, f64::max);
        // λ_max costs O(N³), and only a delay asks for it (D19 caps nothing without one).
        let effective = if c.delay_compensation && max_delay_s > 0.0 {
            coord::capped_gain(c.kc, coord::laplacian_max_eigenvalue(&graph), max_delay_s)
        } else {
            c.kc
        };
        CoordinationGain {
            kc: c.kc,
            effective,
            max_delay_s,
        }
    }
}

impl Agent {
    /// The agent of vehicle `id`, at the start of its path (D15).
    pub fn new(mission: &Mission, id: u32, path: GeneralizedPath) -> Agent {
        Agent::with_gain(mission, &CoordinationGain::of(mission), id, path)
    }

    /// `new`, with the mission's coordination gain already worked out: a fleet in one process
    /// works it out once, not once per agent.
    pub fn with_gain(mission: &Mission, gain: &CoordinationGain, id: u32, path: GeneralizedPath) -> Agent {
        let c = &mission.control;
        let k = &mission.comms;
        let graph = mission.graph();
        let comm_every = mission.comm_every();
        let whole_periods = |seconds: f64| in_ticks(seconds, k.period, comm_every);
        let kc = gain.effective;
        let dt = mission.mission.control_period;
        let tdma = k.tdma_slot.map(|slot| Tdma {
            slot_ticks: (slot / k.period).round() as u64 * comm_every,
            vehicles: graph.len() as u64,
            position: graph.keys().position(|&j| j == id).unwrap_or(0) as u64,
        });
        let heartbeat_ticks = whole_periods(k.heartbeat);
        let silence = match k.trigger {
            Trigger::Periodic => comm_every,
            Trigger::Event => heartbeat_ticks,
        };
        let hold_ticks = match (k.trigger, tdma) {
            (_, None) => silence,
            (Trigger::Periodic, Some(t)) => t.cycle_ticks(),
            (Trigger::Event, Some(t)) => silence + t.cycle_ticks(),
        };
        // A modem busy with its last frame stays silent at the instants its airtime covers.
        let hold_ticks = hold_ticks.max(k.modem.map_or(0, |m| whole_periods(m.airtime())));
        let neighbours = graph.get(&id).cloned().unwrap_or_default();
        // Without a link in the graph (no coordination) nobody sends, so nobody need be heard.
        let audible: Vec<u32> = match k.modem {
            Some(_) if graph.values().any(|n| !n.is_empty()) => graph.keys().copied().filter(|&j| j != id).collect(),
            _ => neighbours.clone(),
        };
        let acoustic = k.modem.map(|modem| Acoustic {
            modem,
            senders: audible
                .iter()
                .map(|&j| {
                    let spec = LinkSpec::of(mission, j, id);
                    let c = spec.sound_speed().expect("a modem's frames travel");
                    (j, spec.modem.expect("a mission with a modem"), c)
                })
                .collect(),
            last_sent: None,
            receiver: Receiver::default(),
            pending: VecDeque::new(),
        });
        Agent {
            id,
            path,
            gains: Gains {
                k1: c.k1,
                k2: c.k2,
                k3: c.k3,
                d1: c.d1,
            },
            kc,
            dt,
            comm_period: k.period,
            comm_every,
            post_arrival: mission.mission.post_arrival,
            compensate: c.delay_compensation,
            trigger: k.trigger,
            threshold: k.threshold,
            heartbeat_ticks,
            tdma,
            hold_ticks,
            links: neighbours
                .iter()
                .map(|&j| Inbound {
                    link: Link::new(mission.mission.seed, j, id, LinkSpec::of(mission, j, id)),
                    in_flight: VecDeque::new(),
                    latest: None,
                })
                .collect(),
            audible,
            acoustic,
            gamma: 0.0,
            // On schedule, virtual time runs at the rate of time.
            gamma_dot: 1.0,
            sent: None,
            sum: None,
            stopped: false,
            dynamic: Some(*mission.vehicle_model(id)).filter(VehicleModelConfig::is_dynamic),
            last_tick: None,
        }
    }

    /// An agent started again while its vehicle is under way takes up its path where the vehicle
    /// is: γ_i of the path point nearest to `position` (as D15 starts every vehicle on its path).
    pub fn rejoin(&mut self, position: [f64; 2]) {
        self.gamma = self.path.nearest(Vec2::from(position));
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

    /// The vehicles whose γ messages this agent takes and, in lockstep, waits for: its
    /// neighbours, or with a modem every other vehicle (D23).
    pub fn audible(&self) -> impl Iterator<Item = u32> + '_ {
        self.audible.iter().copied()
    }

    /// Whether a modem sends this agent's γ: then a trigger may find it busy (D23).
    pub fn has_modem(&self) -> bool {
        self.acoustic.is_some()
    }

    /// Whether `tick`, the next after the last `step`, is a communication instant: a multiple of
    /// the period, or the first tick past one that a realtime agent skipped.
    pub fn is_comm_tick(&self, tick: u64) -> bool {
        !self.audible.is_empty()
            && (tick.is_multiple_of(self.comm_every)
                || self
                    .last_tick
                    .is_some_and(|l| l / self.comm_every < tick / self.comm_every))
    }

    /// At a communication instant, what goes to the neighbours: a sample of γ_i if the trigger
    /// fires (every instant when periodic; D20 when event-triggered; in its own slot only under
    /// TDMA, D21), else a message without one. Call once per tick, before `step`.
    pub fn broadcast(&mut self, tick: u64, state: &State) -> Option<Gamma> {
        if !self.is_comm_tick(tick) {
            return None;
        }
        let t = tick as f64 * self.dt;
        let in_slot = self
            .tdma
            .is_none_or(|s| s.is_mine(tick) && self.sent.is_none_or(|(k, _)| s.slot(k) != s.slot(tick)));
        let due = match (self.trigger, &self.sent) {
            (Trigger::Periodic, _) | (Trigger::Event, None) => true,
            (Trigger::Event, Some((k, last))) => {
                tick - k >= self.heartbeat_ticks
                    || (self.gamma - estimate(last, t, self.compensate)).abs() > self.threshold
            }
        };
        // A trigger that fires while the modem still sends its last frame sends nothing (D23).
        let busy = in_slot && due && self.acoustic.as_ref().is_some_and(|a| a.busy(t));
        let sample = (in_slot && due && !busy).then_some(Sample {
            t,
            gamma: self.gamma,
            gamma_dot: self.gamma_dot,
            position: state.position,
        });
        if let Some(s) = sample {
            self.sent = Some((tick, s));
            if let Some(a) = &mut self.acoustic {
                a.last_sent = Some(t);
                a.receiver.transmitted(t);
            }
        }
        Some(Gamma {
            version: PROTOCOL_VERSION,
            tick,
            from: self.id,
            sample,
            busy,
        })
    }

    /// One control period: `inbox` holds at most one message per neighbour, the newest since the
    /// last instant (used at a communication instant; else ignored). `state` is the freshest
    /// measurement, of this tick in lockstep, possibly older in realtime. Returns the command to
    /// hold until the next tick.
    pub fn step(&mut self, tick: u64, state: &State, inbox: &[Gamma]) -> Command {
        // Periods skipped since the last step (realtime only): γ went on at the rate it had.
        if let Some(skipped) = self.last_tick.map(|l| tick.saturating_sub(l + 1)).filter(|&n| n > 0) {
            self.gamma += skipped as f64 * self.dt * self.gamma_dot;
        }
        let mut receptions = Vec::new();
        if self.is_comm_tick(tick) {
            let mut sum = None;
            let t = tick as f64 * self.dt;
            let here = Vec2::from(state.position);
            if let Some(a) = &mut self.acoustic {
                a.hear(inbox, here);
            }
            for (n, inbound) in self.links.iter_mut().enumerate() {
                let from = inbound.link.from;
                let message = inbox.iter().find(|m| m.from == from);
                let sample = message.and_then(|m| m.sample);
                let distance = sample.map(|s| (Vec2::from(s.position) - here).norm());
                let verdict = inbound.link.transmit(t, distance);
                let delay = inbound.link.spec().delay(distance.unwrap_or(0.0));
                let arrives = tick.saturating_add(in_ticks(delay, self.comm_period, self.comm_every));
                match (&mut self.acoustic, sample) {
                    (None, Some(s)) => {
                        receptions.push(Reception::of(from, verdict, s.t, distance));
                        if verdict.delivered() {
                            inbound.in_flight.push_back((arrives, s));
                        }
                    }
                    (Some(a), Some(s)) => {
                        a.pending.push_back(Pending {
                            link: n,
                            due: arrives,
                            arrival: a.arrival(from, &s, here).expect("a neighbour is audible"),
                            sample: s,
                            distance: distance.expect("a sample's distance"),
                            verdict,
                            u: inbound.link.phy_draw(),
                        });
                    }
                    (Some(_), None) if message.is_some_and(|m| m.busy) => {
                        receptions.push(Reception::of(from, Cause::Busy, t, None));
                    }
                    (_, None) => {}
                }
            }
            if let Some(a) = &mut self.acoustic {
                a.judge(tick, t, &mut self.links, &mut receptions);
            }
            for inbound in &mut self.links {
                // Delays differ by distance, so a later message may overtake an earlier one.
                while let Some(n) = inbound.in_flight.iter().position(|(at, _)| *at <= tick) {
                    let (at, s) = inbound.in_flight.remove(n).expect("found just now");
                    if inbound.latest.is_none_or(|(_, l)| l.t < s.t) {
                        inbound.latest = Some((at, s));
                    }
                }
                if let Some((_, s)) = inbound.latest.filter(|(at, _)| tick - at < self.hold_ticks) {
                    *sum.get_or_insert(0.0) += self.gamma - estimate(&s, t, self.compensate);
                }
            }
            self.sum = sum;
        }

        let point = self.path.at(self.gamma);
        let position = Vec2::from(state.position);
        let t_frame = follow::Frame::new(point.heading);
        let errors = follow::errors(position, state.heading + state.sideslip, &point, &t_frame);
        let gamma = self.gamma;
        if !self.stopped && self.post_arrival == PostArrival::Stop && gamma >= self.path.t_f() {
            self.stopped = true;
        }
        let (v, r, gamma_dot, accel) = if self.stopped {
            (0.0, 0.0, 0.0, 0.0)
        } else {
            let v = coord::speed(point.speed, errors.cos_psi_e(), self.kc, self.sum); // eq. 25
            let current = t_frame.of(Vec2::from(state.current));
            match &self.dynamic {
                None => {
                    let law = follow::control(&self.gains, &point, &errors, v, v, current, state.sideslip_rate);
                    (law.v, law.r, law.gamma_dot, 0.0)
                }
                Some(model) => {
                    // D22c: the measured U wherever the vehicle's speed appears, β̇ := 0 unless
                    // the diagnostic asks for the model's.
                    let speed = state.dynamics.map_or(v, |d| d.surge.hypot(d.sway));
                    let beta_dot = match model.beta_dot {
                        BetaDot::Zero => 0.0,
                        BetaDot::Model => state.sideslip_rate,
                    };
                    let law = follow::control(&self.gains, &point, &errors, v, speed, current, beta_dot);
                    let accel = if model.accel_ff {
                        self.path.speed_rate(gamma) * law.gamma_dot
                    } else {
                        0.0
                    };
                    (law.v, law.r, law.gamma_dot, accel)
                }
            }
        };
        self.gamma += self.dt * gamma_dot;
        self.gamma_dot = gamma_dot;
        self.last_tick = Some(tick);
        Command {
            version: PROTOCOL_VERSION,
            tick,
            id: self.id,
            v,
            r,
            accel,
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
