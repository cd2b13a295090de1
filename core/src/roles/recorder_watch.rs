//! `tcpf record`'s process as one machine: from what the recording holds after each step, the
//! world's liveliness and the answers about it (`fleet::watch::RecorderWaits`), when it stops
//! recording, and why; then how long it waits for the exit reports before it writes the run.
//! The recording itself (`recorder_node`) is the shell's: this machine sees only its counts.
//! Times are instants on the recorder's monotonic clock.

use std::collections::VecDeque;

use crate::fleet::watch::{Due, RecorderWaits};
use crate::roles::machine::Machine;
use crate::time::Moment;

/// What the recorder's process tells its watch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// The recording after a step.
    Recorded {
        /// Ticks written.
        ticks: u64,
        /// Messages taken from the world.
        from_world: u64,
        /// The world's end came.
        ended: bool,
        /// The end came and every tick before it is written.
        complete: bool,
        /// Exit reports the end calls for that have not come.
        unreported: usize,
    },
    /// A step of the recording failed, with `ticks` written.
    Failed { ticks: u64 },
    /// The world's token came (`true`) or went.
    World(bool),
    /// The answer to `Output::Ask` (`WorldWatch::on_answer`): `None` if it failed.
    Answer(Option<bool>),
    /// A signal.
    Interrupted,
}

/// What the recorder's process is to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Output {
    /// Ask who is present, and answer with `Input::Answer`.
    Ask,
    /// The world's token came for the first time.
    WorldHere,
    /// Answers without the world took it for gone, though its token's going was never seen.
    LeftUnseen,
    /// The world ended or left and the recording stalled: the run is written as it is.
    Stalled { ended: bool },
}

/// Why the recording stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stop {
    /// The end came and every tick before it is written.
    Complete,
    Interrupted,
    /// No world came within the startup timeout: nothing to write.
    NoWorld,
    /// A step failed before any tick was written: nothing to write.
    Unrecorded,
    /// A step failed: what was recorded is written.
    Failed,
    /// The world ended or left, and no tick came for a while.
    Stalled,
}

/// How the recording stopped, and when: the run's wall time ends there, not after the wait for
/// the reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Exit {
    pub stop: Stop,
    pub at: Moment,
}

pub struct RecorderWatch {
    waits: RecorderWaits,
    written: u64,
    from_world: u64,
    /// Reports missing, as of the last step.
    unreported: usize,
    /// The world's end came.
    ended: bool,
    /// Stopped, and waiting for the reports.
    stopped: Option<Exit>,
    exit: Option<Exit>,
    outputs: VecDeque<Output>,
}

impl RecorderWatch {
    pub fn new(now: Moment, startup_timeout_s: f64, realtime: bool) -> RecorderWatch {
        RecorderWatch {
            waits: RecorderWaits::new(now, startup_timeout_s, realtime),
            written: 0,
            from_world: 0,
            unreported: 0,
            ended: false,
            stopped: None,
            exit: None,
            outputs: VecDeque::new(),
        }
    }

    /// Stops recording at `now`. A run with something to write waits for the reports it still
    /// lacks, unless none is missing; one interrupted or with nothing to write is done at once.
    fn stop(&mut self, stop: Stop, now: Moment) {
        let exit = Exit { stop, at: now };
        match stop {
            Stop::Complete | Stop::Failed | Stop::Stalled if self.unreported > 0 => {
                self.waits.closing(now);
                self.stopped = Some(exit);
            }
            _ => self.exit = Some(exit),
        }
    }

    fn recorded(&mut self, ticks: u64, from_world: u64, ended: bool, now: Moment) {
        if ticks > self.written {
            self.written = ticks;
            self.waits.progressed(now);
        }
        if from_world > self.from_world {
            self.from_world = from_world;
            self.waits.heard(now);
        }
        if ended && !self.ended {
            self.ended = true;
            self.waits.ended();
        }
    }
}

impl Machine for RecorderWatch {
    type Input = Input;
    type Output = Output;
    type Exit = Exit;

    fn handle(&mut self, input: Input, now: Moment) {
        if self.exit.is_some() {
            return;
        }
        if let Some(stopped) = self.stopped {
            // Only the reports are waited for now, and a signal cuts that short.
            match input {
                Input::Recorded { unreported: 0, .. } | Input::Failed { .. } | Input::Interrupted => {
                    self.exit = Some(stopped)
                }
                _ => {}
            }
            return;
        }
        match input {
            Input::Recorded {
                ticks,
                from_world,
                ended,
                complete,
                unreported,
            } => {
                self.unreported = unreported;
                self.recorded(ticks, from_world, ended, now);
                if complete {
                    self.stop(Stop::Complete, now);
                }
            }
            Input::Failed { ticks: 0 } => self.stop(Stop::Unrecorded, now),
            Input::Failed { .. } => self.stop(Stop::Failed, now),
            Input::World(alive) => {
                if alive && !self.waits.seen() {
                    self.outputs.push_back(Output::WorldHere);
                }
                self.waits.on_presence(alive, now);
            }
            Input::Answer(there) => {
                self.waits.on_answer(there, now);
                if self.waits.left().is_some() {
                    self.outputs.push_back(Output::LeftUnseen);
                }
            }
            Input::Interrupted => self.stop(Stop::Interrupted, now),
        }
    }

    fn poll_timeout(&self) -> Option<Moment> {
        self.exit.is_none().then(|| self.waits.poll_timeout()).flatten()
    }

    fn handle_timeout(&mut self, now: Moment, _due: Moment) {
        if self.exit.is_some() {
            return;
        }
        match self.waits.handle_timeout(now) {
            None => {}
            Some(Due::ReportsLate) => self.exit = self.stopped,
            Some(Due::Ask) => self.outputs.push_back(Output::Ask),
            Some(Due::NoWorld) => self.stop(Stop::NoWorld, now),
            Some(Due::Stalled) => {
                self.outputs.push_back(Output::Stalled { ended: self.ended });
                self.stop(Stop::Stalled, now);
            }
        }
    }

    fn poll_output(&mut self) -> Option<Output> {
        self.outputs.pop_front()
    }

    fn poll_exit(&mut self) -> Option<Exit> {
        self.exit
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fleet::watch::{END_STALL_S, REPORTS_GRACE_S, SILENCE_S};

    fn at(s: f64) -> Moment {
        Moment::from_secs(s)
    }

    fn recorded(ticks: u64, complete: bool, unreported: usize) -> Input {
        Input::Recorded {
            ticks,
            from_world: ticks,
            ended: complete,
            complete,
            unreported,
        }
    }

    fn outputs(m: &mut RecorderWatch) -> Vec<Output> {
        std::iter::from_fn(|| m.poll_output()).collect()
    }

    /// Wakes the watch whenever it asked, up to `to` s.
    fn wake_until(m: &mut RecorderWatch, to: f64) {
        while let Some(due) = m.poll_timeout().filter(|&due| due <= at(to)) {
            m.handle_timeout(due, due);
        }
    }

    #[test]
    fn a_complete_recording_waits_for_the_missing_reports_and_no_longer() {
        let mut m = RecorderWatch::new(at(0.0), 60.0, false);
        m.handle(Input::World(true), at(0.5));
        assert_eq!(outputs(&mut m), [Output::WorldHere]);
        m.handle(Input::World(true), at(0.6));
        assert_eq!(outputs(&mut m), [], "said once");
        m.handle(recorded(10, false, 0), at(1.0));
        m.handle(recorded(20, true, 2), at(2.0));
        assert_eq!(m.poll_exit(), None, "two reports missing");
        assert_eq!(m.poll_timeout(), Some(at(2.0 + REPORTS_GRACE_S)));
        m.handle(Input::World(false), at(2.1));
        m.handle(recorded(20, true, 1), at(2.2));
        assert_eq!(m.poll_exit(), None);
        m.handle(recorded(20, true, 0), at(2.3));
        let stopped_at_the_end = Exit {
            stop: Stop::Complete,
            at: at(2.0),
        };
        assert_eq!(
            m.poll_exit(),
            Some(stopped_at_the_end),
            "the wall time ends with the recording"
        );
        // Reports that never come.
        let mut m = RecorderWatch::new(at(0.0), 60.0, false);
        m.handle(recorded(20, true, 1), at(2.0));
        wake_until(&mut m, 10.0);
        assert_eq!(m.poll_exit(), Some(stopped_at_the_end));
        // None missing: done at once.
        let mut m = RecorderWatch::new(at(0.0), 60.0, false);
        m.handle(recorded(20, true, 0), at(2.0));
        assert_eq!(m.poll_exit(), Some(stopped_at_the_end));
    }

    #[test]
    fn a_recorder_whose_world_never_comes_stops_at_its_startup_timeout_with_nothing_to_write() {
        let mut m = RecorderWatch::new(at(0.0), 30.0, false);
        wake_until(&mut m, 29.9);
        assert_eq!(m.poll_exit(), None);
        wake_until(&mut m, 30.0);
        assert_eq!(
            m.poll_exit(),
            Some(Exit {
                stop: Stop::NoWorld,
                at: at(30.0)
            })
        );
        assert_eq!(m.poll_timeout(), None, "done: nothing more to wake for");
    }

    #[test]
    fn a_silent_world_is_asked_after_and_one_gone_unseen_stalls_the_recording() {
        let mut m = RecorderWatch::new(at(0.0), 60.0, false);
        m.handle(Input::World(true), at(1.0));
        m.handle(recorded(5, false, 1), at(2.0));
        outputs(&mut m);
        // Silent since its last message at 2 s: asked at 7 s, and again 5 s after each answer.
        assert_eq!(m.poll_timeout(), Some(at(2.0) + SILENCE_S));
        m.handle_timeout(at(7.0), at(7.0));
        assert_eq!(outputs(&mut m), [Output::Ask]);
        assert_eq!(m.poll_timeout(), None, "not asked again while the question is out");
        m.handle(Input::Answer(Some(false)), at(7.1));
        assert_eq!(outputs(&mut m), [], "one answer without it may be cut short");
        m.handle_timeout(at(12.1), at(12.1));
        assert_eq!(outputs(&mut m), [Output::Ask]);
        m.handle(Input::Answer(Some(false)), at(12.2));
        assert_eq!(outputs(&mut m), [Output::LeftUnseen]);
        // Gone: the last ticks are waited for from the last one written, then the run stalls.
        assert_eq!(m.poll_timeout(), Some(at(2.0) + END_STALL_S));
        m.handle_timeout(at(12.2), at(7.0));
        assert_eq!(outputs(&mut m), [Output::Stalled { ended: false }]);
        assert_eq!(m.poll_exit(), None, "its reports have their grace");
        wake_until(&mut m, 12.2 + REPORTS_GRACE_S);
        assert_eq!(
            m.poll_exit(),
            Some(Exit {
                stop: Stop::Stalled,
                at: at(12.2)
            })
        );
    }

    #[test]
    fn a_failed_step_stops_the_recording_and_a_signal_cuts_the_wait_for_reports_short() {
        let mut m = RecorderWatch::new(at(0.0), 60.0, false);
        m.handle(Input::Failed { ticks: 0 }, at(1.0));
        assert_eq!(m.poll_exit().map(|e| e.stop), Some(Stop::Unrecorded));
        let mut m = RecorderWatch::new(at(0.0), 60.0, false);
        m.handle(recorded(3, false, 0), at(1.0));
        m.handle(Input::Failed { ticks: 3 }, at(1.5));
        assert_eq!(
            m.poll_exit().map(|e| e.stop),
            Some(Stop::Failed),
            "no report missing: at once"
        );
        let mut m = RecorderWatch::new(at(0.0), 60.0, false);
        m.handle(recorded(3, false, 1), at(1.0));
        m.handle(Input::Failed { ticks: 3 }, at(1.5));
        assert_eq!(m.poll_exit(), None, "the reports still have their grace");
        m.handle(Input::Interrupted, at(1.6));
        assert_eq!(
            m.poll_exit(),
            Some(Exit {
                stop: Stop::Failed,
                at: at(1.5)
            })
        );
        let mut m = RecorderWatch::new(at(0.0), 60.0, false);
        m.handle(recorded(3, false, 0), at(1.0));
        m.handle(Input::Interrupted, at(1.6));
        assert_eq!(m.poll_exit().map(|e| e.stop), Some(Stop::Interrupted), "at once");
    }
}
