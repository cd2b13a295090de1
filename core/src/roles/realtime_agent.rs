//! A realtime agent's process as one machine: its node (`realtime::RealtimeAgent`), which acts
//! every period on the freshest state, and its wait for a world out of reach
//! (`fleet::membership::WorldAway`). The process's metronome says which period starts and how
//! late; its clock says, as each message comes, the latest tick it allows (`horizon`). A message
//! the node refuses goes back out with the key it came on (`K`, the shell's), to be counted by
//! sender. Times are instants on the agent's monotonic clock.

use std::collections::VecDeque;
use std::time::Duration;

use crate::fleet::membership::{WorldAway, WorldReach};
use crate::msg::{Command, Gamma, State};
use crate::roles::lockstep::Reject;
use crate::roles::machine::Machine;
use crate::roles::realtime::RealtimeAgent;
use crate::time::Moment;

/// What a realtime agent's process hears.
#[derive(Debug, Clone, PartialEq)]
pub enum Input<K> {
    /// The period of `tick` starts, `late_s` wall seconds past its deadline, after `skipped`
    /// periods that never ran.
    Beat { tick: u64, late_s: f64, skipped: u64 },
    /// A state of this agent's vehicle.
    State { state: State, horizon: u64, key: K },
    /// A neighbour's γ, which came on its own key.
    Gamma { gamma: Gamma, horizon: u64, key: K },
    /// The world's token came (`true`) or went.
    World(bool),
    /// The planner's token went: the agent has its path already.
    PlannerGone,
    /// The world's end.
    End,
    /// A signal.
    Interrupted,
}

/// What a realtime agent's process does, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Output<K> {
    /// γ_i for the neighbours: a communication instant whose trigger fired.
    Gamma(Gamma),
    /// The command of the period.
    Command(Command),
    /// A message refused, to be counted by the key it came on.
    Refused(Reject, K),
    /// The world is out of reach: the agent acts on what it last sent, and waits this long.
    WorldAway(Duration),
    WorldBack,
    PlannerGone,
}

/// Why a realtime agent stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    Ended,
    /// The world stayed out of reach past the grace.
    Orphaned,
    Interrupted,
}

pub struct RealtimeAgentNode<K> {
    node: RealtimeAgent,
    /// The control period, in wall seconds.
    period_s: f64,
    away: WorldAway,
    outputs: VecDeque<Output<K>>,
    exit: Option<Exit>,
}

impl<K> RealtimeAgentNode<K> {
    /// `world_away`: how long a world out of reach is waited for.
    pub fn new(node: RealtimeAgent, period_s: f64, world_away: Duration) -> RealtimeAgentNode<K> {
        RealtimeAgentNode {
            node,
            period_s,
            away: WorldAway::new(world_away),
            outputs: VecDeque::new(),
            exit: None,
        }
    }

    pub fn node(&self) -> &RealtimeAgent {
        &self.node
    }

    fn refused(&mut self, taken: Result<(), Reject>, key: K) {
        if let Err(why) = taken {
            self.outputs.push_back(Output::Refused(why, key));
        }
    }
}

impl<K> Machine for RealtimeAgentNode<K> {
    type Input = Input<K>;
    type Output = Output<K>;
    type Exit = Exit;

    fn handle(&mut self, input: Input<K>, now: Moment) {
        if self.exit.is_some() {
            return;
        }
        match input {
            Input::Beat { tick, late_s, skipped } => {
                if let Some(action) = self.node.act(tick, late_s, self.period_s, skipped) {
                    self.outputs.extend(action.gamma.map(Output::Gamma));
                    self.outputs.push_back(Output::Command(action.command));
                }
            }
            Input::State { state, horizon, key } => {
                let taken = self.node.on_state(state, horizon);
                self.refused(taken, key);
            }
            Input::Gamma { gamma, horizon, key } => {
                let taken = self.node.on_gamma(gamma, horizon);
                self.refused(taken, key);
            }
            Input::World(alive) => match self.away.on_world(alive, now) {
                Some(WorldReach::Away(grace)) => self.outputs.push_back(Output::WorldAway(grace)),
                Some(WorldReach::Back) => self.outputs.push_back(Output::WorldBack),
                None => {}
            },
            Input::PlannerGone => self.outputs.push_back(Output::PlannerGone),
            Input::End => self.exit = Some(Exit::Ended),
            Input::Interrupted => self.exit = Some(Exit::Interrupted),
        }
    }

    fn poll_timeout(&self) -> Option<Moment> {
        self.away.poll_timeout().filter(|_| self.exit.is_none())
    }

    fn handle_timeout(&mut self, now: Moment, _due: Moment) {
        if self.exit.is_none() && self.away.handle_timeout(now) {
            self.exit = Some(Exit::Orphaned);
        }
    }

    fn poll_output(&mut self) -> Option<Output<K>> {
        self.outputs.pop_front()
    }

    /// Asked once every output is taken: a period's command leaves before an end that came
    /// with it stops the agent.
    fn poll_exit(&mut self) -> Option<Exit> {
        self.exit
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::{case_b, still};
    use crate::msg::PROTOCOL_VERSION;
    use crate::roles::agent::Agent;

    const GRACE: Duration = Duration::from_secs(60);
    const HORIZON: u64 = 1_000;

    fn at(s: f64) -> Moment {
        Moment::from_secs(s)
    }

    /// Vehicle 2's agent of case (b).
    fn agent() -> RealtimeAgentNode<&'static str> {
        let (m, paths, _) = case_b();
        let node = RealtimeAgent::new(Agent::new(&m, 2, paths[1].1), &m, false);
        RealtimeAgentNode::new(node, m.mission.control_period, GRACE)
    }

    fn outputs(m: &mut RealtimeAgentNode<&'static str>) -> Vec<Output<&'static str>> {
        std::iter::from_fn(|| m.poll_output()).collect()
    }

    fn beat(tick: u64) -> Input<&'static str> {
        Input::Beat {
            tick,
            late_s: 0.0,
            skipped: 0,
        }
    }

    #[test]
    fn each_period_commands_on_the_freshest_state_and_a_refused_message_keeps_its_key() {
        let mut m = agent();
        m.handle(beat(0), at(0.0));
        assert_eq!(outputs(&mut m), [], "no state yet: nothing to act on");
        let state = still(2, 3, 0.01, [0.0, 5.0]);
        let key = "tcpf/m/state/2";
        let heard = || Input::State {
            state,
            horizon: HORIZON,
            key,
        };
        m.handle(heard(), at(0.1));
        m.handle(heard(), at(0.1));
        assert_eq!(outputs(&mut m), [Output::Refused(Reject::Duplicate, key)]);
        let ahead = State { tick: 5, ..state };
        m.handle(
            Input::State {
                state: ahead,
                horizon: 4,
                key,
            },
            at(0.1),
        );
        assert_eq!(outputs(&mut m), [Output::Refused(Reject::Future, key)]);
        let stranger = Gamma {
            version: PROTOCOL_VERSION,
            tick: 3,
            from: 9,
            sample: None,
            busy: false,
        };
        let from = "tcpf/m/gamma/9";
        m.handle(
            Input::Gamma {
                gamma: stranger,
                horizon: HORIZON,
                key: from,
            },
            at(0.1),
        );
        assert_eq!(outputs(&mut m), [Output::Refused(Reject::NotANeighbour, from)]);
        m.handle(beat(4), at(0.2));
        let out = outputs(&mut m);
        let Some(Output::Command(command)) = out.last() else {
            panic!("a command every period: {out:?}");
        };
        assert_eq!((command.id, command.tick), (2, 4));
        assert!(
            out[..out.len() - 1].iter().all(|o| matches!(o, Output::Gamma(_))),
            "γ first"
        );
        m.handle(beat(4), at(0.2));
        assert_eq!(outputs(&mut m), [], "a period is acted on once");
        m.handle(Input::End, at(0.3));
        assert_eq!(m.poll_exit(), Some(Exit::Ended));
        m.handle(beat(5), at(0.3));
        assert_eq!(outputs(&mut m), [], "nothing after the end");
    }

    #[test]
    fn a_world_out_of_reach_is_waited_for_then_the_agent_stops() {
        let mut m = agent();
        m.handle(Input::World(true), at(0.0));
        m.handle(Input::World(false), at(10.0));
        assert_eq!(outputs(&mut m), [Output::WorldAway(GRACE)]);
        assert_eq!(m.poll_timeout(), Some(at(70.0)));
        m.handle(Input::World(true), at(30.0));
        assert_eq!(outputs(&mut m), [Output::WorldBack]);
        assert_eq!(m.poll_timeout(), None, "back: nothing to wait for");
        m.handle(Input::PlannerGone, at(31.0));
        assert_eq!(outputs(&mut m), [Output::PlannerGone]);
        assert_eq!(m.poll_exit(), None, "the agent has its path");
        m.handle(Input::World(false), at(40.0));
        m.handle_timeout(at(99.9), at(100.0));
        assert_eq!(m.poll_exit(), None);
        m.handle_timeout(at(100.0), at(100.0));
        assert_eq!(m.poll_exit(), Some(Exit::Orphaned));
        assert_eq!(m.poll_timeout(), None);
    }

    #[test]
    fn a_signal_stops_the_agent_at_once() {
        let mut m = agent();
        m.handle(Input::Interrupted, at(1.0));
        assert_eq!(m.poll_exit(), Some(Exit::Interrupted));
    }
}
