//! A lockstep agent as one machine: the node of `lockstep` and what its process did around it.
//! Until the world's clock answers (the run is this agent's mission, under way) what arrives is
//! held, in order, and no command leaves; a state held says the world has started, so the clock
//! is worth asking; a live neighbour silent for the stale timeout stops being waited for; once
//! stopped, nothing that comes is answered, so an agent told to stop steers its vehicle no more
//! while it reports and leaves. The shell feeds it what arrives, once it has checked that each
//! came on its sender's key, and performs what `poll_output` returns.

use std::collections::VecDeque;
use std::time::Duration;

use crate::fleet::membership::{StaleCheck, StaleTimer};
use crate::msg::{Command, End, Gamma, Lost, State};
use crate::roles::lockstep::{AgentNode, Reject, Timing};
use crate::time::Moment;

/// What reaches a lockstep agent on the fleet's bus.
#[derive(Debug, Clone, PartialEq)]
pub enum Input {
    State(State),
    Gamma(Gamma),
}

impl Input {
    /// Whose it is: the vehicle's state, or neighbour `j`'s γ.
    pub fn source(&self) -> Source {
        match self {
            Input::State(_) => Source::State,
            Input::Gamma(g) => Source::Gamma(g.from),
        }
    }
}

/// Where a refused input came from, for the shell to name its key.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    State,
    Gamma(u32),
}

/// What the shell does for a lockstep agent.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// Publish this agent's γ.
    Gamma(Gamma),
    /// Publish the command of a tick.
    Command(Command),
    /// Count what came from `Source` and was refused.
    Rejected(Reject, Source),
    /// A state came before the start: the world runs, and its clock answers when asked.
    WorldStarted,
    /// Neighbour `id` was silent for the stale timeout: this tick goes on without its γ, and so
    /// do the next ones until it speaks again.
    Stale(u32),
    /// The agent itself was stopped or starved: the neighbours get this long more.
    Resumed(Duration),
}

enum Phase {
    /// Before the world's clock answered: what came, in order.
    Held(Vec<Input>),
    Started,
    Stopped,
}

pub struct LockstepAgent {
    node: AgentNode,
    phase: Phase,
    /// How long the node has been waiting for a neighbour's γ.
    stale: StaleTimer,
    stale_timeout: Duration,
    outputs: VecDeque<Output>,
}

impl LockstepAgent {
    pub fn new(node: AgentNode, stale_timeout: Duration) -> LockstepAgent {
        LockstepAgent {
            node,
            phase: Phase::Held(Vec::new()),
            stale: StaleTimer::new(stale_timeout),
            stale_timeout,
            outputs: VecDeque::new(),
        }
    }

    /// A state or γ came at `now`.
    pub fn handle(&mut self, input: Input, now: Moment) {
        match &mut self.phase {
            Phase::Stopped => {}
            Phase::Held(held) => {
                let first_state =
                    matches!(input, Input::State(_)) && !held.iter().any(|i| matches!(i, Input::State(_)));
                held.push(input);
                if first_state {
                    self.outputs.push_back(Output::WorldStarted);
                }
            }
            Phase::Started => {
                self.apply(input);
                self.settle(now);
            }
        }
    }

    /// The world's clock answered for this agent's mission: what was held goes into the node.
    pub fn start(&mut self, now: Moment) {
        if let Phase::Held(held) = std::mem::replace(&mut self.phase, Phase::Started) {
            for input in held {
                self.apply(input);
            }
            self.settle(now);
        }
    }

    /// The loop has ended: nothing that comes is answered any more.
    pub fn stop(&mut self) {
        self.phase = Phase::Stopped;
    }

    /// Does `change` to the node (a neighbour gone or back, a rejoining), then what is ready.
    pub fn with<R>(&mut self, now: Moment, change: impl FnOnce(&mut AgentNode) -> R) -> R {
        let result = change(&mut self.node);
        if matches!(self.phase, Phase::Started) {
            self.settle(now);
        }
        result
    }

    /// The world's end of the run, if it is one this agent accepts.
    pub fn on_end(&self, end: &End) -> Result<(), Reject> {
        self.node.on_end(end)
    }

    /// The world gave up on a vehicle; whether it is this agent's own.
    pub fn on_lost(&mut self, lost: &Lost, now: Moment) -> Result<bool, Reject> {
        self.with(now, |node| node.on_lost(lost))
    }

    /// When the stale timeout falls due, if the node waits.
    pub fn poll_timeout(&self) -> Option<Moment> {
        self.stale.poll_timeout()
    }

    /// Woken at `now` from a sleep until `woken_for`.
    pub fn handle_timeout(&mut self, now: Moment, woken_for: Moment) {
        match self.stale.handle_timeout(now, woken_for) {
            StaleCheck::Nothing => {}
            StaleCheck::Resumed(more) => self.outputs.push_back(Output::Resumed(more)),
            StaleCheck::Stale => {
                for j in self.node.waiting_for() {
                    self.outputs.push_back(Output::Stale(j));
                    self.node.on_stale(j);
                }
                self.settle(now);
            }
        }
    }

    /// How long a live neighbour may be silent before it is gone on without.
    pub fn stale_timeout(&self) -> Duration {
        self.stale_timeout
    }

    pub fn poll_output(&mut self) -> Option<Output> {
        self.outputs.pop_front()
    }

    pub fn node(&self) -> &AgentNode {
        &self.node
    }

    /// What wall-clock rules did to the node.
    pub fn timing(&self) -> &Timing {
        self.node.timing()
    }

    fn apply(&mut self, input: Input) {
        let source = input.source();
        let taken = match input {
            Input::State(state) => self.node.on_state(state).map(|gamma| {
                self.outputs.extend(gamma.map(Output::Gamma));
            }),
            Input::Gamma(gamma) => self.node.on_gamma(gamma),
        };
        if let Err(why) = taken {
            self.outputs.push_back(Output::Rejected(why, source));
        }
    }

    /// The commands the node has ready, and whether it now waits.
    fn settle(&mut self, now: Moment) {
        while let Some(command) = self.node.command() {
            self.outputs.push_back(Output::Command(command));
        }
        self.stale.note(self.node.waiting(), now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::case_b;
    use crate::roles::agent::Agent;
    use crate::roles::lockstep::WorldNode;

    const TIMEOUT: Duration = Duration::from_secs(3);

    fn at(s: f64) -> Moment {
        Moment::from_secs(s)
    }

    fn agent_1() -> (LockstepAgent, State, Gamma) {
        let (m, paths, _) = case_b();
        let world = WorldNode::new(&m, &paths);
        let mut node = AgentNode::new(Agent::new(&m, 2, paths[1].1));
        let state = world.states()[0];
        let theirs = node.on_state(world.states()[1]).unwrap().expect("tick 0 is an instant");
        let machine = LockstepAgent::new(AgentNode::new(Agent::new(&m, 1, paths[0].1)), TIMEOUT);
        (machine, state, theirs)
    }

    fn outputs(m: &mut LockstepAgent) -> Vec<Output> {
        std::iter::from_fn(|| m.poll_output()).collect()
    }

    #[test]
    fn what_comes_before_the_start_is_held_in_order_and_then_answered() {
        let (mut m, state, theirs) = agent_1();
        m.handle(Input::Gamma(theirs), at(0.0));
        m.handle(Input::State(state), at(0.1));
        m.handle(Input::State(state), at(0.2));
        assert_eq!(
            outputs(&mut m),
            vec![Output::WorldStarted],
            "nothing leaves before the clock answers; the first state says the world runs"
        );
        m.start(at(1.0));
        let out = outputs(&mut m);
        assert!(
            matches!(out[0], Output::Gamma(g) if g.from == 1 && g.tick == 0),
            "{out:?}"
        );
        assert_eq!(
            out[1],
            Output::Rejected(Reject::Duplicate, Source::State),
            "all that was held goes in before the node is asked for its command"
        );
        assert!(
            matches!(&out[2], Output::Command(c) if c.tick == 0 && c.receptions.len() == 1),
            "neighbour 2's γ, held before the state, is in tick 0's command: {out:?}"
        );
        assert_eq!(out.len(), 3, "{out:?}");
        m.start(at(2.0));
        assert!(outputs(&mut m).is_empty(), "started once");
    }

    #[test]
    fn a_stopped_agent_answers_nothing() {
        let (mut m, state, theirs) = agent_1();
        m.start(at(0.0));
        m.stop();
        m.handle(Input::State(state), at(0.1));
        m.handle(Input::Gamma(theirs), at(0.1));
        assert!(outputs(&mut m).is_empty());
    }

    #[test]
    fn a_neighbour_silent_for_the_stale_timeout_is_gone_on_without() {
        let (mut m, state, _) = agent_1();
        m.start(at(0.0));
        assert_eq!(m.poll_timeout(), None, "nothing awaited yet");
        m.handle(Input::State(state), at(1.0));
        assert!(matches!(outputs(&mut m)[..], [Output::Gamma(_)]), "its γ, no command");
        let due = m.poll_timeout().expect("waits for neighbour 2");
        assert_eq!(due, at(1.0) + TIMEOUT);
        m.handle_timeout(due - 0.5, due - 0.5);
        assert!(outputs(&mut m).is_empty(), "not yet");
        m.handle_timeout(due, due);
        let out = outputs(&mut m);
        assert_eq!(out[0], Output::Stale(2));
        assert!(
            matches!(&out[1], Output::Command(c) if c.receptions.is_empty()),
            "{out:?}"
        );
        assert_eq!(m.timing().stale_timeouts, 1);
    }

    #[test]
    fn an_agent_woken_long_after_its_timeout_gives_its_neighbours_that_long_more() {
        let (mut m, state, _) = agent_1();
        m.start(at(0.0));
        m.handle(Input::State(state), at(1.0));
        outputs(&mut m);
        let due = m.poll_timeout().unwrap();
        m.handle_timeout(due + 10.0, due);
        let out = outputs(&mut m);
        assert!(
            matches!(out[..], [Output::Resumed(more)] if more >= Duration::from_secs(9)),
            "{out:?}"
        );
        assert!(
            m.poll_timeout().unwrap() > due + 9.0,
            "the timer moved on with the pause"
        );
    }
}
