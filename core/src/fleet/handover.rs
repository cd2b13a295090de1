//! A hand-over of last words to the recorders (an exit report, the end, a loss), as its sender
//! runs it (`tcpf_bus::handover`): each attempt counts the recorders present and asks every one,
//! each reply an acknowledgement. It asks again while some of those present have not answered,
//! up to its attempts, and says how it went. Asked once even with no recorder present: one that
//! has every report it waits for withdraws its token, and still takes what comes (the planner's
//! report, last of all).

use std::collections::BTreeSet;

use crate::roles::machine::Machine;
use crate::time::Moment;

/// What the sender is to do next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    /// Count the recorders present.
    Count,
    /// Ask every recorder, each reply an acknowledgement.
    Ask,
}

/// What came of a step.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Done<R> {
    /// So many recorders are present.
    Counted(usize),
    /// These answered the question: each names its replier.
    Answered(Vec<R>),
}

/// How a hand-over went: of the recorders present at the last count, how many acknowledged,
/// after how many attempts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Handed {
    pub acknowledged: usize,
    pub recorders: usize,
    pub attempts: u32,
}

impl Handed {
    /// Recorders present that never acknowledged.
    pub fn unacknowledged(&self) -> usize {
        self.recorders.saturating_sub(self.acknowledged)
    }
}

/// A hand-over of one message; `R` names a replier.
#[derive(Debug)]
pub struct Handover<R> {
    attempts: u32,
    attempt: u32,
    acknowledged: BTreeSet<R>,
    recorders: usize,
    next: Option<Step>,
    handed: Option<Handed>,
}

impl<R: Ord> Handover<R> {
    /// Asked at most `attempts` times.
    pub fn new(attempts: u32) -> Handover<R> {
        Handover {
            attempts,
            attempt: 1,
            acknowledged: BTreeSet::new(),
            recorders: 0,
            next: Some(Step::Count),
            handed: None,
        }
    }

    fn handed(&mut self, attempts: u32) {
        self.handed = Some(Handed {
            acknowledged: self.acknowledged.len(),
            recorders: self.recorders,
            attempts,
        });
    }
}

/// No clock: each attempt's question carries its own timeout.
impl<R: Ord> Machine for Handover<R> {
    type Input = Done<R>;
    type Output = Step;
    type Exit = Handed;

    fn handle(&mut self, done: Done<R>, _: Moment) {
        match done {
            Done::Counted(recorders) => {
                self.recorders = recorders;
                if self.attempt > 1 && self.acknowledged.len() >= recorders {
                    self.handed(self.attempt - 1);
                } else {
                    self.next = Some(Step::Ask);
                }
            }
            Done::Answered(repliers) => {
                self.acknowledged.extend(repliers);
                if self.attempt == self.attempts {
                    self.handed(self.attempts);
                } else {
                    self.attempt += 1;
                    self.next = Some(Step::Count);
                }
            }
        }
    }

    fn poll_timeout(&self) -> Option<Moment> {
        None
    }

    fn handle_timeout(&mut self, _: Moment, _: Moment) {}

    fn poll_output(&mut self) -> Option<Step> {
        self.next.take()
    }

    fn poll_exit(&mut self) -> Option<Handed> {
        self.handed.take()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs a hand-over of 3 attempts against recorders counted by `count` at each attempt,
    /// answering as `answer` says at each: the steps it took and how it went.
    fn run(count: impl Fn(u32) -> usize, answer: impl Fn(u32) -> Vec<&'static str>) -> (Vec<Step>, Handed) {
        let mut handover = Handover::new(3);
        let (mut steps, mut attempt) = (Vec::new(), 1);
        loop {
            while let Some(step) = handover.poll_output() {
                steps.push(step);
                let done = match step {
                    Step::Count => Done::Counted(count(attempt)),
                    Step::Ask => {
                        attempt += 1;
                        Done::Answered(answer(attempt - 1))
                    }
                };
                handover.handle(done, Moment::default());
            }
            if let Some(handed) = handover.poll_exit() {
                return (steps, handed);
            }
        }
    }

    use Step::{Ask, Count};

    #[test]
    fn every_recorder_present_acknowledging_ends_the_hand_over() {
        let (steps, handed) = run(|_| 2, |_| vec!["a", "b"]);
        assert_eq!(steps, [Count, Ask, Count]);
        assert_eq!(
            handed,
            Handed {
                acknowledged: 2,
                recorders: 2,
                attempts: 1
            }
        );

        let (steps, handed) = run(|_| 0, |_| Vec::new());
        assert_eq!(steps, [Count, Ask, Count], "asked once with no recorder present");
        assert_eq!(handed.attempts, 1);
    }

    #[test]
    fn a_recorder_that_holds_its_acknowledgement_is_asked_again() {
        // `b` acknowledges at the third attempt (it fetched the ticks it lost meanwhile).
        let (steps, handed) = run(|_| 2, |attempt| if attempt < 3 { vec!["a"] } else { vec!["a", "b"] });
        assert_eq!(steps, [Count, Ask, Count, Ask, Count, Ask]);
        assert_eq!(
            handed,
            Handed {
                acknowledged: 2,
                recorders: 2,
                attempts: 3
            }
        );
        assert_eq!(handed.unacknowledged(), 0);

        // A recorder that came between two attempts is asked too.
        let (_, handed) = run(
            |attempt| if attempt == 1 { 1 } else { 2 },
            |attempt| vec![["a", "b"][attempt as usize - 1]],
        );
        assert_eq!(
            handed,
            Handed {
                acknowledged: 2,
                recorders: 2,
                attempts: 2
            }
        );
    }

    #[test]
    fn one_that_never_acknowledges_is_counted_after_the_last_attempt() {
        let (steps, handed) = run(|_| 2, |_| vec!["a"]);
        assert_eq!(steps.iter().filter(|s| **s == Ask).count(), 3);
        assert_eq!(
            handed,
            Handed {
                acknowledged: 1,
                recorders: 2,
                attempts: 3
            }
        );
        assert_eq!(handed.unacknowledged(), 1);
    }
}
