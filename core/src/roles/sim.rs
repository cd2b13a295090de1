//! The in-process fleet: the machines the processes run (the world's `WorldNode`, one
//! `AgentNode` per vehicle, the `Recorder`), driven by direct calls in the order in which the
//! lockstep shells pass their messages over Zenoh. Nothing here decides anything the machines do
//! not: that is what makes in-process and process runs bit-identical.

use crate::mission::Mission;
use crate::model::planner::Plan;
use crate::msg::{Command, Gamma, LossReason, Rejections, State, PROTOCOL_VERSION};
use crate::outputs::metrics::Results;
use crate::roles::agent::{Agent, CoordinationGain};
use crate::roles::lockstep::{AgentNode, WorldNode};
use crate::roles::record::Recorder;
use crate::roles::world::World;

pub struct Fleet {
    world: WorldNode,
    agents: Vec<AgentNode>,
    recorder: Recorder,
    /// Per agent, the agents that hear its γ: the subscriptions of those it is audible to.
    listeners: Vec<Vec<usize>>,
    /// Agents the world still waits for.
    live: Vec<bool>,
}

impl Fleet {
    pub fn new(mission: &Mission, plan: &Plan) -> Fleet {
        let paths = plan.paths();
        let ids: Vec<u32> = paths.iter().map(|p| p.0).collect();
        let gain = CoordinationGain::of(mission);
        let agents: Vec<AgentNode> = paths
            .iter()
            .map(|&(id, path)| AgentNode::new(Agent::with_gain(mission, &gain, id, path)))
            .collect();
        let listeners = ids
            .iter()
            .map(|&j| {
                (0..agents.len())
                    .filter(|&i| agents[i].agent().audible().any(|n| n == j))
                    .collect()
            })
            .collect();
        Fleet {
            world: WorldNode::new(mission, &paths),
            recorder: Recorder::new(&ids, plan.t_f, mission.mission.control_period).with_faults(mission),
            live: vec![true; agents.len()],
            agents,
            listeners,
        }
    }

    /// The world gives up on agent `n`, as it does over Zenoh when a command never comes (one
    /// with a non-finite number is refused there as it is decoded): its vehicle drifts and its
    /// neighbours stop waiting for it.
    fn silence(&mut self, n: usize) {
        self.live[n] = false;
        let id = self.agents[n].agent().id();
        if let Some(lost) = self.world.on_lost(id, LossReason::Silent) {
            self.recorder.on_lost(lost).expect("one of the mission's vehicles");
        }
        for &i in &self.listeners[n] {
            self.agents[i].set_gone(id, true);
        }
    }

    /// Runs to the end (every vehicle arrived, or max_duration); `observe` sees every tick as the
    /// recorder hands it on.
    pub fn run(self, observe: impl FnMut(&[State], &[Option<Command>])) -> Results {
        self.run_until(observe, || false).0
    }

    /// `run`, but asking `stop` before each tick: when it says so, the results are those of the
    /// whole ticks run so far. Also returns what the world and the agents refused, counted as
    /// the processes count what they drop.
    pub fn run_until(
        mut self,
        mut observe: impl FnMut(&[State], &[Option<Command>]),
        mut stop: impl FnMut() -> bool,
    ) -> (Results, Rejections) {
        let mut sent: Vec<(usize, Gamma)> = Vec::with_capacity(self.agents.len());
        let mut rejections = Rejections::default();
        loop {
            if stop() {
                return (self.recorder.results(), rejections);
            }
            // The world publishes the states of the tick; each agent answers its own.
            let mut refused = Vec::new();
            for (n, &state) in self.world.states().iter().enumerate() {
                // What the agents refuse here, the processes drop as they decode.
                if self.live[n] {
                    match self.agents[n].on_state(state) {
                        Ok(gamma) => sent.extend(gamma.map(|g| (n, g))),
                        Err(why) => {
                            why.count(&mut rejections);
                            refused.push(n);
                        }
                    }
                }
            }
            refused.drain(..).for_each(|n| self.silence(n));
            for (n, gamma) in sent.drain(..) {
                for &i in self.listeners[n].iter().filter(|&&i| self.live[i]) {
                    let _ = self.agents[i].on_gamma(gamma);
                }
            }
            for n in (0..self.agents.len()).filter(|&n| self.live[n]) {
                let command = self.agents[n]
                    .command()
                    .expect("the state and every γ of the tick are in");
                if let Err(why) = self.world.on_command(command) {
                    why.count(&mut rejections);
                    refused.push(n);
                }
            }
            refused.drain(..).for_each(|n| self.silence(n));
            // As the tick closes, the recorder takes the world's record of it.
            let end = self.world.advance(|record| {
                self.recorder
                    .on_tick(record)
                    .expect("the world's record of the next tick");
            });
            self.recorder.drain(&mut observe);
            if let Some(end) = end {
                self.recorder.on_end(end).expect("the world's end, once");
                return (self.recorder.results(), rejections);
            }
        }
    }
}

/// The baseline of the simulator's throughput: the world alone integrating the plan's vehicles
/// for `ticks` with constant commands (no agents, no recorder). Returns the world at the end.
pub fn world_alone(mission: &Mission, plan: &Plan, ticks: u64) -> World {
    let paths = plan.paths();
    let held: Vec<Option<Command>> = paths
        .iter()
        .map(|&(id, _)| {
            Some(Command {
                version: PROTOCOL_VERSION,
                tick: 0,
                id,
                v: 0.6,
                r: 0.01,
                accel: 0.0,
                hold: false,
                gamma: 0.0,
                gamma_dot: 1.0,
                v_d: 0.6,
                x_e: 0.0,
                y_e: 0.0,
                psi_e: 0.0,
                receptions: Vec::new(),
            })
        })
        .collect();
    let mut world = World::new(mission, &paths);
    let mut states = Vec::with_capacity(paths.len());
    for _ in 0..ticks {
        world.states(&mut states);
        std::hint::black_box(&states);
        world.step(&held);
    }
    world
}

/// The floor under the fleet's throughput: the world and every agent's law for `ticks`, states
/// and γ handed over directly, without the machines' checks, the recorder or the metrics: the
/// arithmetic of a run in which no agent is lost, and nothing else (nothing here refuses a
/// message or gives up on an agent). Returns the world at the end.
pub fn world_and_laws(mission: &Mission, plan: &Plan, ticks: u64) -> World {
    let paths = plan.paths();
    let gain = CoordinationGain::of(mission);
    let mut agents: Vec<Agent> = paths
        .iter()
        .map(|&(id, path)| Agent::with_gain(mission, &gain, id, path))
        .collect();
    let mut world = World::new(mission, &paths);
    let mut states = Vec::with_capacity(paths.len());
    let mut gammas = Vec::with_capacity(paths.len());
    let mut commands = vec![None; paths.len()];
    for tick in 0..ticks {
        world.states(&mut states);
        gammas.clear();
        gammas.extend(agents.iter_mut().zip(&states).filter_map(|(a, s)| a.broadcast(tick, s)));
        for ((agent, state), command) in agents.iter_mut().zip(&states).zip(&mut commands) {
            *command = Some(agent.step(tick, state, &gammas));
        }
        world.step(&commands);
    }
    world
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission;
    use crate::model::planner;
    use crate::msg::Checked;

    #[test]
    fn the_machines_add_checks_but_no_arithmetic_to_a_run() {
        // Lossy links; acoustic links that delay by distance, under TDMA and event triggering;
        // side-slip.
        let missions = [
            (
                "d-lossy.toml",
                include_str!("../../../configs/paper/d-lossy.toml"),
                vec![],
            ),
            (
                "acoustic.toml",
                include_str!("../../../configs/acoustic.toml"),
                vec!["comms.trigger=event".to_string(), "comms.tdma_slot=0.2".to_string()],
            ),
            (
                "b-current.toml",
                include_str!("../../../configs/paper/b-current.toml"),
                vec!["sideslip.amplitude=0.2".to_string(), "sideslip.period=7.0".to_string()],
            ),
        ];
        for (file, text, overrides) in missions {
            let m = mission::parse(file, text, &overrides).unwrap();
            let plan = planner::plan(&m).unwrap();
            let mut last = Vec::new();
            let ticks = Fleet::new(&m, &plan).run(|states, _| last = states.to_vec()).ticks;
            let mut bare = Vec::new();
            world_and_laws(&m, &plan, ticks - 1).states(&mut bare);
            assert_eq!(bare, last, "{file} {overrides:?}: the last tick's states, bit for bit");
        }
    }

    #[test]
    fn an_agent_whose_command_is_not_finite_is_lost_as_silent_and_the_others_go_on() {
        let text = include_str!("../../../configs/paper/b-current.toml");
        let m = mission::parse("b-current.toml", text, &[]).unwrap();
        let plan = planner::plan(&m).unwrap();
        let mut fleet = Fleet::new(&m, &plan);
        // A control law gone wrong in vehicle 2's agent only: its first command holds a NaN.
        let mut broken = m.clone();
        broken.control.k1 = f64::NAN;
        fleet.agents[1] = AgentNode::new(Agent::new(&broken, 2, plan.vehicles[1].path));
        let mut rows = 0;
        let results = fleet.run(|states, commands| {
            assert!(states.iter().all(|s| s.finite()), "no NaN reaches the world");
            rows += 1;
            assert!(commands[1].is_none(), "vehicle 2 has no command from the first tick on");
        });
        assert_eq!(rows, results.ticks, "the recorder wrote every tick");
        let (one, two) = (&results.vehicles[0], &results.vehicles[1]);
        assert!(two.lost && two.lost_reason == Some(LossReason::Silent), "{two:?}");
        assert!(!one.lost && one.arrival_time.is_some(), "{one:?}");
    }
}
