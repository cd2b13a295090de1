//! The in-process fleet: the machines the processes run (the world's `WorldNode`, one
//! `AgentNode` per vehicle, the `Recorder`), driven by direct calls in the order in which the
//! lockstep shells pass their messages over Zenoh. Nothing here decides anything the machines do
//! not: that is what makes in-process and process runs bit-identical.

use crate::agent::Agent;
use crate::lockstep::{AgentNode, WorldNode};
use crate::metrics::Results;
use crate::mission::Mission;
use crate::msg::{Command, Gamma, State};
use crate::planner::Plan;
use crate::record::Recorder;

pub struct Fleet {
    world: WorldNode,
    agents: Vec<AgentNode>,
    recorder: Recorder,
    /// Per agent, the agents that hear its γ: its neighbours' subscriptions.
    listeners: Vec<Vec<usize>>,
}

impl Fleet {
    pub fn new(mission: &Mission, plan: &Plan) -> Fleet {
        let paths: Vec<_> = plan.vehicles.iter().map(|v| (v.id, v.path)).collect();
        let ids: Vec<u32> = paths.iter().map(|p| p.0).collect();
        let agents: Vec<AgentNode> = paths
            .iter()
            .map(|&(id, path)| AgentNode::new(Agent::new(mission, id, path)))
            .collect();
        let listeners = ids
            .iter()
            .map(|&j| {
                (0..agents.len())
                    .filter(|&i| agents[i].agent().neighbours().any(|n| n == j))
                    .collect()
            })
            .collect();
        Fleet {
            world: WorldNode::new(mission, &paths, plan.t_f),
            recorder: Recorder::new(&ids, plan.t_f, mission.mission.control_period),
            agents,
            listeners,
        }
    }

    /// Runs to the end (every vehicle arrived, or max_duration); `observe` sees every tick as the
    /// recorder hands it on.
    pub fn run(self, observe: impl FnMut(&[State], &[Option<Command>])) -> Results {
        self.run_until(observe, || false)
    }

    /// `run`, but asking `stop` before each tick: when it says so, the results are those of the
    /// whole ticks run so far.
    pub fn run_until(
        mut self,
        mut observe: impl FnMut(&[State], &[Option<Command>]),
        mut stop: impl FnMut() -> bool,
    ) -> Results {
        let mut sent: Vec<(usize, Gamma)> = Vec::with_capacity(self.agents.len());
        loop {
            if stop() {
                return self.recorder.results();
            }
            // The world publishes the states of the tick; each agent answers its own.
            for (n, (agent, &state)) in self.agents.iter_mut().zip(self.world.states()).enumerate() {
                self.recorder.on_state(state).expect("one state per vehicle and tick");
                let gamma = agent.on_state(state).expect("the state of the agent's next tick");
                sent.extend(gamma.map(|g| (n, g)));
            }
            for (n, gamma) in sent.drain(..) {
                for &i in &self.listeners[n] {
                    self.agents[i].on_gamma(gamma).expect("a neighbour's γ of this tick");
                }
            }
            for agent in &mut self.agents {
                let command = agent.command().expect("the state and every γ of the tick are in");
                self.recorder
                    .on_command(command.clone())
                    .expect("one command per vehicle and tick");
                self.world.on_command(command).expect("a command of this tick");
            }
            let end = self.world.advance(|_, _| {});
            self.recorder.drain(&mut observe);
            if let Some(end) = end {
                self.recorder.on_end(end).expect("the world's end, once");
                return self.recorder.results();
            }
        }
    }
}
