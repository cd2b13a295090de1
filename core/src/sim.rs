//! The in-process simulator: the very machines the processes run, driven in lockstep in one loop.
//! Every control period the agents sample and command, then the world integrates one RK4 step.

use crate::agent::Agent;
use crate::lockstep::WorldNode;
use crate::metrics::Results;
use crate::mission::Mission;
use crate::msg::{Command, Gamma, State};
use crate::planner::Plan;

pub struct Fleet {
    world: WorldNode,
    agents: Vec<Agent>,
}

impl Fleet {
    pub fn new(mission: &Mission, plan: &Plan) -> Fleet {
        let paths: Vec<_> = plan.vehicles.iter().map(|v| (v.id, v.path)).collect();
        Fleet {
            world: WorldNode::new(mission, &paths, plan.t_f),
            agents: paths.iter().map(|&(id, path)| Agent::new(mission, id, path)).collect(),
        }
    }

    /// Runs to the end (every vehicle arrived, or max_duration); `observe` sees every tick.
    pub fn run(mut self, mut observe: impl FnMut(&[State], &[Option<&Command>])) -> Results {
        let mut inbox: Vec<Gamma> = Vec::with_capacity(self.agents.len());
        loop {
            inbox.clear();
            let states = self.world.states().to_vec();
            inbox.extend(self.agents.iter_mut().zip(&states).filter_map(|(a, s)| a.broadcast(s)));
            for (agent, state) in self.agents.iter_mut().zip(&states) {
                let command = agent.step(state, &inbox);
                self.world
                    .on_command(command)
                    .expect("in-process commands are always of this tick");
            }
            if self.world.advance(&mut observe).is_some() {
                return self.world.metrics().results();
            }
        }
    }
}
