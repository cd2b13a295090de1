//! The in-process simulator: the very machines the processes run, driven in lockstep in one loop.
//! Every control period the agents sample and command, then the world integrates one RK4 step.

use crate::agent::Agent;
use crate::metrics::{Metrics, Results};
use crate::mission::Mission;
use crate::msg::{Command, Gamma, State};
use crate::planner::Plan;
use crate::world::World;

/// Ticks after which a run stops whether or not every vehicle arrived.
pub fn max_ticks(mission: &Mission) -> u64 {
    (mission.mission.max_duration / mission.mission.control_period).round() as u64
}

pub struct Fleet {
    world: World,
    agents: Vec<Agent>,
    metrics: Metrics,
    max_ticks: u64,
}

impl Fleet {
    pub fn new(mission: &Mission, plan: &Plan) -> Fleet {
        let paths: Vec<_> = plan.vehicles.iter().map(|v| (v.id, v.path)).collect();
        let ids: Vec<u32> = paths.iter().map(|p| p.0).collect();
        Fleet {
            world: World::new(mission, &paths),
            agents: paths.iter().map(|&(id, path)| Agent::new(mission, id, path)).collect(),
            metrics: Metrics::new(&ids, plan.t_f, mission.mission.control_period),
            max_ticks: max_ticks(mission),
        }
    }

    /// Runs to the end (every vehicle arrived, or max_duration); `observe` sees every tick.
    pub fn run(mut self, mut observe: impl FnMut(&[State], &[Command])) -> Results {
        let mut inbox: Vec<Gamma> = Vec::with_capacity(self.agents.len());
        let mut commands: Vec<Command> = Vec::with_capacity(self.agents.len());
        loop {
            let tick = self.world.tick();
            let states = self.world.states();
            inbox.clear();
            inbox.extend(self.agents.iter().filter_map(|a| a.gamma_to_send(tick)));
            commands.clear();
            commands.extend(self.agents.iter_mut().zip(&states).map(|(a, s)| a.step(s, &inbox)));
            let held: Vec<Option<&Command>> = commands.iter().map(Some).collect();
            self.metrics.record(tick, &states, &held);
            observe(&states, &commands);
            if self.metrics.all_arrived() || tick >= self.max_ticks {
                return self.metrics.results();
            }
            self.world.step(&held);
        }
    }
}
