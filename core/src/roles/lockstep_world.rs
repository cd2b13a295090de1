//! A lockstep world as one machine: the node of `lockstep`, its deadlines
//! (`fleet::membership::Deadlines`) and what its process did around them. Until the run starts,
//! commands that come are held, in order; from the start, every tick that waits for nobody closes
//! at once and the next one's states leave; a vehicle given up on is announced before the states
//! of the tick that no longer waits for it; once the end is out, nothing more leaves.
//!
//! The shell calls it under one lock, on the thread a command came in on, and does what it is
//! told through `Io` as the machine goes: the states and the tick's record are lent out of the
//! node, so a tick leaves without a copy (a queue of owned outputs, as `lockstep_agent`'s, would
//! copy every state and every record; this is the fleet's hot path).

use std::time::Duration;

use crate::fleet::membership::{Deadlines, Decision};
use crate::msg::{Command, End, LossReason, Lost, State, TickRecord};
use crate::roles::lockstep::{Reject, WorldNode};
use crate::time::Moment;

/// What the shell does for a lockstep world, called in the order it is to be done.
pub trait Io {
    /// The states of tick `tick` are ready: publish each, and answer the clock with the tick.
    fn states(&mut self, tick: u64, states: &[State]);
    /// A tick closed: its record, for the recorders.
    fn record(&mut self, record: TickRecord<'_>);
    /// The run is over: publish its end. Called once.
    fn end(&mut self, end: &End);
    /// A vehicle is lost: tell its agents and the recorders.
    fn lost(&mut self, lost: Lost);
    /// The command of vehicle `id` was refused.
    fn rejected(&mut self, id: u32, reject: Reject);
    /// What the deadlines decided, at simulated time `t`, carried out already but for the log.
    fn decided(&mut self, decision: &Decision, t: f64);
    /// The state of the `n`th vehicle, again: its agent came back, and subscribed too late to
    /// hear it.
    fn again(&mut self, n: usize, state: &State);
}

pub struct LockstepWorld {
    node: WorldNode,
    /// Before the start, the commands that came.
    held: Option<Vec<Command>>,
    deadlines: Deadlines,
    /// The end is out.
    over: bool,
}

impl LockstepWorld {
    pub fn new(node: WorldNode, command_timeout: Duration, rejoin_timeout: Option<Duration>, now: Moment) -> Self {
        LockstepWorld {
            node,
            held: Some(Vec::new()),
            deadlines: Deadlines::new(command_timeout, rejoin_timeout, now),
            over: false,
        }
    }

    /// The run starts: the first states leave, then what came before them goes in.
    pub fn start(&mut self, now: Moment, io: &mut (impl Io + ?Sized)) {
        let Some(held) = self.held.take() else {
            return;
        };
        self.publish(now, io);
        for command in held {
            self.take(command, io);
        }
        self.step(now, io);
    }

    /// A command came at `now`, on its vehicle's key.
    pub fn handle_command(&mut self, command: Command, now: Moment, io: &mut (impl Io + ?Sized)) {
        if let Some(held) = &mut self.held {
            held.push(command);
        } else if !self.over {
            self.take(command, io);
            self.step(now, io);
        }
    }

    /// Agent `id` of the fleet came (`alive`) or went.
    pub fn handle_agent(&mut self, id: u32, alive: bool, now: Moment, io: &mut (impl Io + ?Sized)) {
        let lost = self.node.loss_of(id);
        if let Some(decision) = self.deadlines.on_agent(id, alive, lost, now) {
            self.decide(decision, now, io);
        }
    }

    /// When to call `handle_timeout`: the tick's command timeout or a rejoin deadline; never once
    /// the end is out.
    pub fn poll_timeout(&self) -> Option<Moment> {
        (!self.over).then(|| self.deadlines.poll_timeout())
    }

    /// Woken at `now` from a sleep until `woken_for`.
    pub fn handle_timeout(&mut self, now: Moment, woken_for: Moment, io: &mut (impl Io + ?Sized)) {
        let node = &self.node;
        for decision in self.deadlines.handle_timeout(now, woken_for, || node.waiting_for()) {
            self.decide(decision, now, io);
        }
    }

    /// A signal: the run ends before the tick under way closes, unless its end is out already.
    pub fn interrupt(&mut self, io: &mut (impl Io + ?Sized)) {
        if !self.over {
            self.over = true;
            io.end(&self.node.interrupted());
        }
    }

    /// The end is out: nothing more is taken or published.
    pub fn over(&self) -> bool {
        self.over
    }

    /// The vehicles neither arrived nor lost.
    pub fn not_arrived(&self) -> usize {
        self.node.not_arrived()
    }

    fn take(&mut self, command: Command, io: &mut (impl Io + ?Sized)) {
        let id = command.id;
        if let Err(reject) = self.node.on_command(command) {
            io.rejected(id, reject);
        }
    }

    /// Closes every tick that waits for nobody, publishing each next one's states, or the end.
    fn step(&mut self, now: Moment, io: &mut (impl Io + ?Sized)) {
        while !self.over && !self.node.waiting() {
            match self.node.advance(|record| io.record(record)) {
                Some(end) => {
                    self.over = true;
                    io.end(&end);
                }
                None => self.publish(now, io),
            }
        }
    }

    fn publish(&mut self, now: Moment, io: &mut (impl Io + ?Sized)) {
        io.states(self.node.tick(), self.node.states());
        self.deadlines.on_tick(now);
    }

    fn decide(&mut self, decision: Decision, now: Moment, io: &mut (impl Io + ?Sized)) {
        // One wake-up may decide a vehicle's loss twice (gone past its rejoin deadline, and
        // silent past the tick's command timeout): it is lost, and said, once.
        if let Decision::Lose { id, .. } = decision {
            if self.node.loss_of(id).is_some() {
                return;
            }
        }
        io.decided(&decision, self.node.states()[0].t);
        match decision {
            Decision::Lose { id, reason, .. } => self.lose(id, reason, now, io),
            // A new agent of a lost vehicle: the world refuses its commands, and its neighbours
            // would wait for it again. It is told, and stops.
            Decision::TellAgain(lost) => io.lost(lost),
            Decision::Back(id) if !self.over => {
                if let Some(n) = self.node.position(id) {
                    io.again(n, &self.node.states()[n]);
                }
            }
            Decision::Back(_) | Decision::AwaitReturn { .. } | Decision::Resumed(_) => {}
        }
    }

    /// Vehicle `id` is given up on: said first, then the tick goes on without it.
    fn lose(&mut self, id: u32, reason: LossReason, now: Moment, io: &mut (impl Io + ?Sized)) {
        if let Some(lost) = self.node.on_lost(id, reason) {
            io.lost(lost);
        }
        self.step(now, io);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::{case_b, command_at};

    /// What the world did, in order.
    #[derive(Debug, Clone, PartialEq)]
    enum Did {
        States(u64),
        Record(u64),
        End(u64),
        Lost(u32, LossReason),
        Rejected(u32, Reject),
        Decided(Decision),
        Again(usize),
    }

    #[derive(Default)]
    struct Log(Vec<Did>);

    impl Io for Log {
        fn states(&mut self, tick: u64, _: &[State]) {
            self.0.push(Did::States(tick));
        }
        fn record(&mut self, record: TickRecord<'_>) {
            self.0.push(Did::Record(record.tick));
        }
        fn end(&mut self, end: &End) {
            self.0.push(Did::End(end.ticks));
        }
        fn lost(&mut self, lost: Lost) {
            self.0.push(Did::Lost(lost.id, lost.reason));
        }
        fn rejected(&mut self, id: u32, reject: Reject) {
            self.0.push(Did::Rejected(id, reject));
        }
        fn decided(&mut self, decision: &Decision, _: f64) {
            self.0.push(Did::Decided(*decision));
        }
        fn again(&mut self, n: usize, _: &State) {
            self.0.push(Did::Again(n));
        }
    }

    impl Log {
        fn take(&mut self) -> Vec<Did> {
            std::mem::take(&mut self.0)
        }
    }

    const COMMAND_TIMEOUT: Duration = Duration::from_secs(10);
    const REJOIN: Duration = Duration::from_secs(20);

    fn world(rejoin: Option<Duration>) -> (LockstepWorld, Vec<u32>) {
        let (mission, paths, _) = case_b();
        let ids = paths.iter().map(|p| p.0).collect();
        let node = WorldNode::new(&mission, &paths);
        (LockstepWorld::new(node, COMMAND_TIMEOUT, rejoin, at(0.0)), ids)
    }

    /// A world started at 0 s, what its start did already taken from the log.
    fn started(rejoin: Option<Duration>) -> (LockstepWorld, Vec<u32>, Log) {
        let (mut world, ids) = world(rejoin);
        let mut log = Log::default();
        world.start(at(0.0), &mut log);
        log.take();
        (world, ids, log)
    }

    fn at(s: f64) -> Moment {
        Moment::from_secs(s)
    }

    fn command(id: u32, tick: u64) -> Command {
        command_at(id, tick, 0.0)
    }

    #[test]
    fn commands_before_the_start_are_held_then_taken_in_order_after_the_first_states() {
        let (mut world, ids) = world(None);
        let mut log = Log::default();
        world.handle_command(command(ids[0], 0), at(0.1), &mut log);
        world.handle_command(command(ids[0], 0), at(0.1), &mut log);
        assert_eq!(log.take(), [], "nothing leaves before the start");
        world.start(at(1.0), &mut log);
        assert_eq!(
            log.take(),
            [Did::States(0), Did::Rejected(ids[0], Reject::Duplicate)],
            "the first states, then the held commands: the second a duplicate"
        );
        world.start(at(1.5), &mut log);
        assert_eq!(log.take(), [], "a run starts once");
        world.handle_command(command(ids[1], 0), at(2.0), &mut log);
        assert_eq!(
            log.take(),
            [Did::Record(0), Did::States(1)],
            "the tick closes with the last command"
        );
    }

    #[test]
    fn a_silent_agent_is_lost_at_the_command_timeout_of_its_tick_and_the_tick_goes_on() {
        let (mut world, ids, mut log) = started(None);
        world.handle_command(command(ids[0], 0), at(0.5), &mut log);
        log.take();
        let due = world.poll_timeout().unwrap();
        assert_eq!(due, at(0.0) + COMMAND_TIMEOUT);
        world.handle_timeout(at(5.0), at(5.0), &mut log);
        assert_eq!(log.take(), [], "woken early, on time: nothing due");
        world.handle_timeout(due, due, &mut log);
        let lose = Decision::Lose {
            id: ids[1],
            reason: LossReason::Silent,
            awaited: false,
        };
        assert_eq!(
            log.take(),
            [
                Did::Decided(lose),
                Did::Lost(ids[1], LossReason::Silent),
                Did::Record(0),
                Did::States(1)
            ],
            "the loss is said before the tick that no longer waits for the vehicle"
        );
        assert_eq!(
            world.poll_timeout(),
            Some(due + COMMAND_TIMEOUT),
            "the next tick's timeout"
        );
        world.handle_command(command(ids[1], 1), due, &mut log);
        assert_eq!(log.take(), [Did::Rejected(ids[1], Reject::LostVehicle)]);
    }

    #[test]
    fn a_gone_agent_is_awaited_then_sent_its_state_again_or_lost() {
        let (mut world, ids, mut log) = started(Some(REJOIN));
        world.handle_agent(ids[1], false, at(1.0), &mut log);
        let awaiting = Decision::AwaitReturn {
            id: ids[1],
            within: REJOIN,
        };
        assert_eq!(log.take(), [Did::Decided(awaiting)]);
        world.handle_agent(ids[1], true, at(2.0), &mut log);
        assert_eq!(log.take(), [Did::Decided(Decision::Back(ids[1])), Did::Again(1)]);

        world.handle_agent(ids[1], false, at(3.0), &mut log);
        log.take();
        // Past tick 0's command timeout too, for which vehicle 2 was silent: it is lost once.
        world.handle_command(command(ids[0], 0), at(3.5), &mut log);
        let rejoin_due = at(3.0) + REJOIN;
        world.handle_timeout(rejoin_due, rejoin_due, &mut log);
        let done = log.take();
        assert_eq!(
            done[..2],
            [
                Did::Decided(Decision::Lose {
                    id: ids[1],
                    reason: LossReason::Gone,
                    awaited: true
                }),
                Did::Lost(ids[1], LossReason::Gone)
            ]
        );
        assert_eq!(done[2..], [Did::Record(0), Did::States(1)], "{done:?}");
        world.handle_agent(ids[1], true, at(24.0), &mut log);
        let told = log.take();
        assert!(
            matches!(told[..], [Did::Decided(Decision::TellAgain(_)), Did::Lost(id, LossReason::Gone)] if id == ids[1]),
            "{told:?}"
        );
    }

    #[test]
    fn an_interrupt_ends_the_tick_under_way_once_and_nothing_leaves_after_the_end() {
        let (mut world, ids, mut log) = started(None);
        world.interrupt(&mut log);
        assert_eq!(log.take(), [Did::End(0)], "no tick closed");
        world.interrupt(&mut log);
        world.handle_command(command(ids[0], 0), at(1.0), &mut log);
        world.handle_command(command(ids[1], 0), at(1.0), &mut log);
        assert_eq!(log.take(), [], "the end is out: nothing more");
        assert_eq!(world.poll_timeout(), None);
        assert_eq!(world.not_arrived(), 2);
    }
}
