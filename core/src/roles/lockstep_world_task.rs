//! The lockstep world's task: what the world's process does around its machine
//! (`lockstep_world::LockstepWorld`), which Zenoh's thread feeds the commands behind a lock they
//! share (`SharedWorld`). The task tells it of agents come and gone, wakes it for its deadlines,
//! and stops when the end is out, a publication failed or a signal came, ending the run at once
//! for the last.

use std::convert::Infallible;

use crate::msg::End;
use crate::roles::lockstep_world::{Io, LockstepWorld};
use crate::roles::machine::Machine;
use crate::time::Moment;

/// The lockstep world's machine behind the lock it shares with Zenoh's thread: `with` does
/// `act` at the process's `now`, with what performs the machine's outputs as it goes (the
/// machine lends them, `lockstep_world`).
pub trait SharedWorld {
    fn with(&self, act: impl FnOnce(&mut LockstepWorld, Moment, &mut dyn Io));
}

/// What the task hears.
#[derive(Debug, Clone, PartialEq)]
pub enum Input {
    /// Agent `id` of the fleet came (`alive`) or went.
    Agent(u32, bool),
    /// The end is out.
    End(End),
    /// A publication failed.
    Failed,
    Interrupted,
}

/// Why the task stopped.
#[derive(Debug, Clone, PartialEq)]
pub enum Exit {
    Ended(End),
    Interrupted,
    Failed,
}

pub struct LockstepWorldTask<'a, S> {
    shared: &'a S,
    exit: Option<Exit>,
}

impl<'a, S: SharedWorld> LockstepWorldTask<'a, S> {
    pub fn new(shared: &'a S) -> Self {
        LockstepWorldTask { shared, exit: None }
    }
}

impl<S: SharedWorld> Machine for LockstepWorldTask<'_, S> {
    type Input = Input;
    type Output = Infallible;
    type Exit = Exit;

    fn handle(&mut self, input: Input, _: Moment) {
        match input {
            Input::Agent(id, alive) => {
                self.shared
                    .with(|world, now, io| world.handle_agent(id, alive, now, io));
            }
            Input::End(end) => self.exit = Some(Exit::Ended(end)),
            Input::Failed => self.exit = Some(Exit::Failed),
            Input::Interrupted => {
                self.shared.with(|world, _, io| world.interrupt(io));
                self.exit = Some(Exit::Interrupted);
            }
        }
    }

    fn poll_timeout(&self) -> Option<Moment> {
        let mut due = None;
        self.shared.with(|world, _, _| due = world.poll_timeout());
        due
    }

    fn handle_timeout(&mut self, _: Moment, due: Moment) {
        self.shared.with(|world, now, io| world.handle_timeout(now, due, io));
    }

    fn poll_output(&mut self) -> Option<Infallible> {
        None
    }

    fn poll_exit(&mut self) -> Option<Exit> {
        self.exit.take()
    }
}

#[cfg(test)]
mod tests {
    use std::cell::{Cell, RefCell};
    use std::time::Duration;

    use super::*;
    use crate::fixtures::case_b;
    use crate::fleet::membership::Decision;
    use crate::msg::{LossReason, Lost, State, TickRecord};
    use crate::roles::lockstep::{Reject, WorldNode};

    const COMMAND_TIMEOUT: Duration = Duration::from_secs(10);

    /// The losses and ends the world said.
    #[derive(Default)]
    struct Said {
        lost: Vec<(u32, LossReason)>,
        ends: Vec<u64>,
    }

    impl Io for Said {
        fn states(&mut self, _: u64, _: &[State]) {}
        fn record(&mut self, _: TickRecord<'_>) {}
        fn end(&mut self, end: &End) {
            self.ends.push(end.ticks);
        }
        fn lost(&mut self, lost: Lost) {
            self.lost.push((lost.id, lost.reason));
        }
        fn rejected(&mut self, _: u32, _: Reject) {}
        fn decided(&mut self, _: &Decision, _: f64) {}
        fn again(&mut self, _: usize, _: &State) {}
    }

    /// Case (b)'s world, started at 0 s, behind a lock a test holds, on a clock it moves by hand.
    struct ByHand {
        world: RefCell<LockstepWorld>,
        said: RefCell<Said>,
        now: Cell<Moment>,
    }

    impl SharedWorld for ByHand {
        fn with(&self, act: impl FnOnce(&mut LockstepWorld, Moment, &mut dyn Io)) {
            act(
                &mut self.world.borrow_mut(),
                self.now.get(),
                &mut *self.said.borrow_mut(),
            );
        }
    }

    fn started() -> (ByHand, Vec<u32>) {
        let (mission, paths, _) = case_b();
        let ids = paths.iter().map(|p| p.0).collect();
        let mut world = LockstepWorld::new(WorldNode::new(&mission, &paths), COMMAND_TIMEOUT, None, at(0.0));
        world.start(at(0.0), &mut Said::default());
        let shared = ByHand {
            world: RefCell::new(world),
            said: RefCell::default(),
            now: Cell::new(at(0.0)),
        };
        (shared, ids)
    }

    fn at(s: f64) -> Moment {
        Moment::from_secs(s)
    }

    #[test]
    fn the_task_tells_the_world_of_agents_gone_and_wakes_it_for_its_deadlines() {
        let (shared, ids) = started();
        let mut task = LockstepWorldTask::new(&shared);
        assert_eq!(task.poll_timeout(), Some(at(0.0) + COMMAND_TIMEOUT));
        shared.now.set(at(1.0));
        task.handle(Input::Agent(ids[1], false), at(1.0));
        assert_eq!(shared.said.borrow().lost, [(ids[1], LossReason::Gone)]);

        let due = task.poll_timeout().unwrap();
        shared.now.set(due);
        task.handle_timeout(due, due);
        assert_eq!(shared.said.borrow().lost[1], (ids[0], LossReason::Silent));
        assert_eq!(task.poll_exit(), None, "the task stops for the end, once it is out");
        let end = End {
            version: crate::msg::PROTOCOL_VERSION,
            ticks: 1,
            lost: Vec::new(),
            arrived: Vec::new(),
        };
        task.handle(Input::End(end.clone()), due);
        assert_eq!(task.poll_exit(), Some(Exit::Ended(end)));
    }

    #[test]
    fn a_signal_ends_the_run_once_and_stops_the_task() {
        let (shared, _) = started();
        let mut task = LockstepWorldTask::new(&shared);
        task.handle(Input::Interrupted, at(0.5));
        assert_eq!(shared.said.borrow().ends, [0]);
        assert_eq!(task.poll_exit(), Some(Exit::Interrupted));
        task.handle(Input::Interrupted, at(0.6));
        assert_eq!(shared.said.borrow().ends, [0], "said once");
        assert_eq!(task.poll_timeout(), None, "over: no deadline");

        let (shared, _) = started();
        let mut task = LockstepWorldTask::new(&shared);
        task.handle(Input::Failed, at(0.5));
        assert_eq!(task.poll_exit(), Some(Exit::Failed));
        assert!(
            shared.said.borrow().ends.is_empty(),
            "a failed publication ends nothing more"
        );
    }
}
