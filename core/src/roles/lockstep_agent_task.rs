//! The lockstep agent's task: what the agent's process does around its machine
//! (`lockstep_agent::LockstepAgent`), which Zenoh's thread feeds the states and γ behind a lock
//! they share (`machine::Shared`). The task starts it once the world's clock answers, tells it
//! of neighbours come and gone, accepts the world's end or refuses it, stops when the world
//! gives up on this vehicle, wakes it for its stale timeout (and once per stale timeout while
//! the fleet moves on, to look again), and gives a world that went the grace for its end
//! (`fleet::watch::EndGrace`).

use std::collections::VecDeque;
use std::time::Duration;

use crate::fleet::watch::EndGrace;
use crate::msg::{End, Lost};
use crate::roles::lockstep::Reject;
use crate::roles::lockstep_agent::LockstepAgent;
use crate::roles::machine::{Machine, Shared};
use crate::time::Moment;

/// What the task hears; `K` is the key a message came on, which a refusal names.
#[derive(Debug, Clone, PartialEq)]
pub enum Input<K> {
    /// The world's clock answered, and it is this agent's mission's: the run starts.
    Started,
    /// The world's token came (`true`) or went.
    World(bool),
    PlannerGone,
    /// Neighbour `id`'s agent came (`true`) or went.
    Neighbour(u32, bool),
    End(End, K),
    /// The world gave up on a vehicle, said on its key.
    Lost(Lost, K),
    /// A publication failed, or the world's clock is not this agent's.
    Failed,
    Interrupted,
}

/// What the process is to do.
#[derive(Debug, Clone, PartialEq)]
pub enum Output<K> {
    /// The run has started: the code of the start can go.
    Started,
    /// Count what came on `K` and was refused.
    Refused(Reject, K),
    PlannerGone,
    /// The world gave up on this vehicle at this tick, for this reason.
    Lost(Lost),
    /// The world went and its end did not come within the grace.
    WorldGone,
}

/// Why the task stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    Ended,
    Lost,
    Orphaned,
    Interrupted,
    Failed,
}

pub struct LockstepAgentTask<'a, S, K> {
    shared: &'a S,
    gone: EndGrace,
    stale_timeout: Duration,
    /// Not waiting for anything, the machine is woken once per stale timeout while the fleet
    /// moves on, to look again: the next time, from the last input.
    look_at: Moment,
    outputs: VecDeque<Output<K>>,
    exit: Option<Exit>,
}

impl<'a, S: Shared<LockstepAgent>, K> LockstepAgentTask<'a, S, K> {
    /// `end_grace`: how long a world that went is given for its end.
    pub fn new(shared: &'a S, stale_timeout: Duration, end_grace: Duration, now: Moment) -> Self {
        LockstepAgentTask {
            shared,
            gone: EndGrace::new(end_grace),
            stale_timeout,
            look_at: now + stale_timeout,
            outputs: VecDeque::new(),
            exit: None,
        }
    }

    /// When the machine wants waking, or else the next look again.
    fn own_timeout(&self) -> Moment {
        self.shared
            .with(|machine, _| machine.poll_timeout())
            .unwrap_or(self.look_at)
    }
}

impl<S: Shared<LockstepAgent>, K> Machine for LockstepAgentTask<'_, S, K> {
    type Input = Input<K>;
    type Output = Output<K>;
    type Exit = Exit;

    fn handle(&mut self, input: Input<K>, now: Moment) {
        self.look_at = now + self.stale_timeout;
        match input {
            Input::Started => {
                self.shared.with(|machine, now| machine.start(now));
                self.outputs.push_back(Output::Started);
            }
            // The world's end may come after its token has gone.
            Input::World(true) => self.gone.back(),
            Input::World(false) => self.gone.left(now),
            Input::PlannerGone => self.outputs.push_back(Output::PlannerGone),
            Input::Neighbour(j, alive) => {
                self.shared
                    .with(|machine, now| machine.with(now, |node| node.set_gone(j, !alive)));
            }
            Input::End(end, key) => match self.shared.with(|machine, _| machine.on_end(&end)) {
                Ok(()) => self.exit = Some(Exit::Ended),
                Err(why) => self.outputs.push_back(Output::Refused(why, key)),
            },
            Input::Lost(lost, key) => match self.shared.with(|machine, now| machine.on_lost(&lost, now)) {
                Ok(true) => {
                    self.outputs.push_back(Output::Lost(lost));
                    self.exit = Some(Exit::Lost);
                }
                Ok(false) => {}
                Err(why) => self.outputs.push_back(Output::Refused(why, key)),
            },
            Input::Failed => self.exit = Some(Exit::Failed),
            Input::Interrupted => self.exit = Some(Exit::Interrupted),
        }
    }

    fn poll_timeout(&self) -> Option<Moment> {
        let own = self.own_timeout();
        Some(self.gone.poll_timeout().map_or(own, |grace| grace.min(own)))
    }

    fn handle_timeout(&mut self, now: Moment, _: Moment) {
        if self.gone.poll_timeout().is_some_and(|grace| grace <= now) && self.gone.handle_timeout(now) {
            self.outputs.push_back(Output::WorldGone);
            self.exit = Some(Exit::Orphaned);
            return;
        }
        let own = self.own_timeout();
        if own <= now {
            self.shared.with(|machine, now| machine.handle_timeout(now, own));
            self.look_at = now + self.stale_timeout;
        }
    }

    fn poll_output(&mut self) -> Option<Output<K>> {
        self.outputs.pop_front()
    }

    fn poll_exit(&mut self) -> Option<Exit> {
        self.exit.take()
    }
}

#[cfg(test)]
mod tests {
    use std::cell::{Cell, RefCell};

    use super::*;
    use crate::fixtures::case_b;
    use crate::msg::{LossReason, PROTOCOL_VERSION};
    use crate::roles::agent::Agent;
    use crate::roles::lockstep::{AgentNode, WorldNode};
    use crate::roles::lockstep_agent::{Input as Fed, Output as Said};

    const STALE: Duration = Duration::from_secs(3);
    const GRACE: Duration = Duration::from_millis(500);

    /// Agent 1 of case (b) behind a lock a test holds, on a clock it moves by hand.
    struct ByHand {
        machine: RefCell<LockstepAgent>,
        now: Cell<Moment>,
        state: crate::msg::State,
    }

    impl Shared<LockstepAgent> for ByHand {
        fn with<R>(&self, act: impl FnOnce(&mut LockstepAgent, Moment) -> R) -> R {
            act(&mut self.machine.borrow_mut(), self.now.get())
        }
    }

    fn agent_1() -> ByHand {
        let (m, paths, _) = case_b();
        let world = WorldNode::new(&m, &paths);
        ByHand {
            machine: RefCell::new(LockstepAgent::new(AgentNode::new(Agent::new(&m, 1, paths[0].1)), STALE)),
            now: Cell::new(Moment::default()),
            state: world.states()[0],
        }
    }

    fn at(s: f64) -> Moment {
        Moment::from_secs(s)
    }

    fn end(ticks: u64) -> End {
        End {
            version: PROTOCOL_VERSION,
            ticks,
            lost: Vec::new(),
            arrived: Vec::new(),
        }
    }

    fn outputs(task: &mut LockstepAgentTask<'_, ByHand, &'static str>) -> Vec<Output<&'static str>> {
        std::iter::from_fn(|| task.poll_output()).collect()
    }

    #[test]
    fn the_start_lets_through_what_the_machine_held() {
        let shared = agent_1();
        shared.with(|machine, now| machine.handle(Fed::State(shared.state), now));
        let mut task = LockstepAgentTask::new(&shared, STALE, GRACE, at(0.0));
        task.handle(Input::Started, at(0.2));
        assert_eq!(outputs(&mut task), [Output::Started]);
        let answered: Vec<_> = std::iter::from_fn(|| shared.machine.borrow_mut().poll_output()).collect();
        assert_eq!(answered[0], Said::WorldStarted);
        assert!(matches!(answered[1], Said::Gamma(_)), "{answered:?}");
        assert_eq!(task.poll_exit(), None);
    }

    #[test]
    fn a_world_gone_is_given_its_grace_for_the_end_and_then_left() {
        let shared = agent_1();
        let mut task = LockstepAgentTask::<_, &str>::new(&shared, STALE, GRACE, at(0.0));
        assert_eq!(
            task.poll_timeout(),
            Some(at(3.0)),
            "woken once per stale timeout to look again"
        );
        task.handle(Input::World(false), at(1.0));
        assert_eq!(task.poll_timeout(), Some(at(1.5)));
        task.handle(Input::World(true), at(1.2));
        assert_eq!(task.poll_timeout(), Some(at(4.2)), "back: no grace runs");

        task.handle(Input::World(false), at(2.0));
        task.handle_timeout(at(2.3), at(2.3));
        assert_eq!(task.poll_exit(), None, "within the grace");
        task.handle(Input::End(end(0), "end"), at(2.4));
        assert_eq!(task.poll_exit(), Some(Exit::Ended), "the end after the token");

        let mut task = LockstepAgentTask::<_, &str>::new(&shared, STALE, GRACE, at(0.0));
        task.handle(Input::World(false), at(2.0));
        task.handle_timeout(at(2.5), at(2.5));
        assert_eq!(outputs(&mut task), [Output::WorldGone]);
        assert_eq!(task.poll_exit(), Some(Exit::Orphaned));
    }

    #[test]
    fn an_end_from_the_future_is_refused_and_a_loss_of_this_vehicle_stops_it() {
        let shared = agent_1();
        let mut task = LockstepAgentTask::new(&shared, STALE, GRACE, at(0.0));
        task.handle(Input::End(end(5), "tcpf/m/end"), at(0.1));
        assert_eq!(outputs(&mut task), [Output::Refused(Reject::Future, "tcpf/m/end")]);
        assert_eq!(task.poll_exit(), None);

        let lost = |id| Lost {
            id,
            tick: 0,
            reason: LossReason::Silent,
        };
        task.handle(Input::Lost(lost(2), "tcpf/m/lost/2"), at(0.2));
        assert_eq!(
            (outputs(&mut task), task.poll_exit()),
            (Vec::new(), None),
            "a neighbour lost"
        );
        task.handle(Input::Lost(lost(1), "tcpf/m/lost/1"), at(0.3));
        assert_eq!(outputs(&mut task), [Output::Lost(lost(1))]);
        assert_eq!(task.poll_exit(), Some(Exit::Lost));
    }
}
