//! The planner's process as a machine: it serves the plan until the world goes away, and says
//! whether the world had ended the run first. The world's `End` and the deletion of its token
//! travel separately, so the End may come after the token has gone: a world gone without one is
//! given `end_grace` for it (`fleet::watch::EndGrace`, as an agent gives it). An End alone lets nothing go (it may come from anyone the bus lets
//! speak; only the world's going away takes the paths from a running fleet). Times are inputs:
//! instants on the planner's monotonic clock.

use std::convert::Infallible;
use std::time::Duration;

use crate::fleet::watch::EndGrace;
use crate::roles::machine::Machine;
use crate::time::Moment;

/// What the planner's process hears besides the queries for paths.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// The world's liveliness token came (`true`) or went.
    World(bool),
    /// An `End` of the run.
    End,
    /// A signal: stop now.
    Interrupted,
}

/// Why the planner stopped serving.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    Ended,
    WorldGone,
    Interrupted,
}

impl std::fmt::Display for Exit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Exit::Ended => "ended",
            Exit::WorldGone => "stopped: the world left without announcing the end",
            Exit::Interrupted => "interrupted",
        })
    }
}

pub struct PlannerNode {
    world_seen: bool,
    ended: bool,
    gone: EndGrace,
    exit: Option<Exit>,
}

impl PlannerNode {
    pub fn new(end_grace: Duration) -> PlannerNode {
        PlannerNode {
            world_seen: false,
            ended: false,
            gone: EndGrace::new(end_grace),
            exit: None,
        }
    }
}

impl Machine for PlannerNode {
    type Input = Input;
    /// The planner's only output, its paths, is served by its process as asked.
    type Output = Infallible;
    type Exit = Exit;

    fn handle(&mut self, input: Input, now: Moment) {
        if self.exit.is_some() {
            return;
        }
        match input {
            Input::World(true) => {
                self.world_seen = true;
                self.gone.back();
            }
            // A token gone before any was seen is not this run's world leaving.
            Input::World(false) if !self.world_seen => {}
            Input::World(false) if self.ended => self.exit = Some(Exit::Ended),
            Input::World(false) => self.gone.left(now),
            Input::End => {
                self.ended = true;
                if self.gone.waiting() {
                    self.exit = Some(Exit::Ended);
                }
            }
            Input::Interrupted => self.exit = Some(Exit::Interrupted),
        }
    }

    /// When the grace for a gone world's End runs out, if one runs.
    fn poll_timeout(&self) -> Option<Moment> {
        self.gone.poll_timeout().filter(|_| self.exit.is_none())
    }

    /// A world gone for the grace without an End is gone for good.
    fn handle_timeout(&mut self, now: Moment, _due: Moment) {
        if self.exit.is_none() && self.gone.handle_timeout(now) {
            self.exit = Some(Exit::WorldGone);
        }
    }

    fn poll_output(&mut self) -> Option<Infallible> {
        None
    }

    /// Whether, and why, serving is over.
    fn poll_exit(&mut self) -> Option<Exit> {
        self.exit
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GRACE: Duration = Duration::from_millis(500);

    fn at(s: f64) -> Moment {
        Moment::from_secs(s)
    }

    fn serving() -> PlannerNode {
        let mut m = PlannerNode::new(GRACE);
        m.handle(Input::World(true), at(1.0));
        m
    }

    #[test]
    fn a_world_that_ended_the_run_and_left_ends_the_planner_at_once() {
        let mut m = serving();
        m.handle(Input::End, at(50.0));
        assert_eq!(m.poll_exit(), None, "an End alone takes no path away");
        m.handle(Input::World(false), at(50.1));
        assert_eq!(m.poll_exit(), Some(Exit::Ended));
        assert_eq!(m.poll_timeout(), None);
    }

    #[test]
    fn an_end_behind_the_worlds_token_within_the_grace_is_an_end() {
        let mut m = serving();
        m.handle(Input::World(false), at(50.0));
        assert_eq!(m.poll_timeout(), Some(at(50.5)));
        m.handle_timeout(at(50.4), at(50.4));
        assert_eq!(m.poll_exit(), None, "the grace has not run out");
        m.handle(Input::End, at(50.45));
        assert_eq!(m.poll_exit(), Some(Exit::Ended));
    }

    #[test]
    fn a_world_gone_for_the_grace_without_an_end_is_gone() {
        let mut m = serving();
        m.handle(Input::World(false), at(50.0));
        m.handle_timeout(at(50.5), at(50.5));
        assert_eq!(m.poll_exit(), Some(Exit::WorldGone));
        m.handle(Input::End, at(50.6));
        assert_eq!(m.poll_exit(), Some(Exit::WorldGone), "what is decided stays");
    }

    #[test]
    fn a_token_gone_before_the_world_was_seen_is_not_its_leaving() {
        let mut m = PlannerNode::new(GRACE);
        m.handle(Input::World(false), at(0.1));
        assert_eq!((m.poll_exit(), m.poll_timeout()), (None, None));
        m.handle(Input::World(true), at(0.2));
        m.handle(Input::World(false), at(9.0));
        assert_eq!(m.poll_timeout(), Some(at(9.5)));
    }

    #[test]
    fn a_world_back_within_the_grace_is_served_on() {
        let mut m = serving();
        m.handle(Input::World(false), at(10.0));
        m.handle(Input::World(true), at(10.2));
        assert_eq!(m.poll_timeout(), None);
        m.handle_timeout(at(11.0), at(11.0));
        assert_eq!(m.poll_exit(), None);
    }

    #[test]
    fn a_signal_stops_serving_whatever_the_world_does() {
        let mut m = serving();
        m.handle(Input::World(false), at(10.0));
        m.handle(Input::Interrupted, at(10.1));
        assert_eq!(m.poll_exit(), Some(Exit::Interrupted));
        assert_eq!(m.poll_timeout(), None);
    }
}
