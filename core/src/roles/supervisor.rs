//! The supervisor of `tcpf run` as processes: from its children's exits and the recording's
//! progress, whether the run goes on, has failed (and why) or is over; which agent to start
//! again; and when the children have had their time to exit by themselves.
//!
//! Times are instants on the launcher's monotonic clock. The launcher looks at its children when
//! `poll_timeout` says (Zenoh gives no event for a child's exit), tells the supervisor what it
//! saw and what the recording holds, and does what `poll_output` asks: start an agent again,
//! warn, tell the children to stop, kill what is left.

use std::collections::VecDeque;
use std::fmt;

use crate::msg::Role;
use crate::outputs::summary::Restarts;
use crate::roles::machine::Machine;
use crate::time::Moment;

/// Every wait of the supervisor, each with its default.
#[derive(Debug, Clone, PartialEq)]
pub struct Timeouts {
    /// How often the children are looked at.
    pub check_s: f64,
    /// How long children get to exit by themselves after the end before they are killed.
    pub grace_s: f64,
    /// After an interrupt, how long children get to stop (and report) once told to, before
    /// they are killed: Ctrl-C stops a run within 2 s.
    pub interrupt_grace_s: f64,
    /// How long an exit report may lag behind its sender's exit.
    pub report_settle_s: f64,
    /// A run in which no tick completes for this long has stalled, unless the world waits
    /// longer on purpose (`Supervision::stall_limit_s`).
    pub stall_s: f64,
    /// How long the recorder may go without a tick once the world has exited after ending the
    /// run: what the world sent last may still be on its way.
    pub end_on_its_way_s: f64,
    /// The launcher waits this much longer than the world for the first tick, so that the world
    /// says first what it is missing.
    pub start_margin_s: f64,
    /// With restarts, how long a lockstep tick waits for an agent started again (the world's
    /// `--rejoin-timeout`).
    pub rejoin_s: f64,
}

impl Default for Timeouts {
    fn default() -> Timeouts {
        Timeouts {
            check_s: 0.1,
            grace_s: 3.0,
            interrupt_grace_s: 1.0,
            report_settle_s: 0.2,
            stall_s: 60.0,
            end_on_its_way_s: 5.0,
            start_margin_s: 10.0,
            rejoin_s: 20.0,
        }
    }
}

/// What the supervisor of one run knows of it before it starts.
#[derive(Debug, Clone)]
pub struct Supervision {
    /// An agent that dies is started again (`--restart on-failure`).
    pub restart: bool,
    /// The world waits for every command: a tick's messages come in order.
    pub lockstep: bool,
    /// How long the world waits for its agents and recorders before the first tick.
    pub startup_timeout_s: f64,
    /// How long a tick waits for a live agent's command.
    pub command_timeout_s: f64,
    /// The control period in wall seconds (the mission's period over its time scale).
    pub wall_period_s: f64,
    pub timeouts: Timeouts,
}

impl Supervision {
    /// How long a run may go without completing a tick before it has stalled: longer than what
    /// the world waits for on purpose (a silent agent's command, an agent started again) and
    /// than two of its wall periods, so that `--command-timeout` and a slow time scale mean
    /// what they say.
    pub fn stall_limit_s(&self) -> f64 {
        let rejoin = if self.restart { self.timeouts.rejoin_s } else { 0.0 };
        let waits = self.command_timeout_s.max(rejoin).max(2.0 * self.wall_period_s);
        self.timeouts.stall_s.max(waits + self.timeouts.start_margin_s)
    }
}

/// How a child process ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Exit {
    /// Its exit code, if it exited rather than being killed.
    pub code: Option<i32>,
    /// The signal that killed it, if one did.
    pub signal: Option<i32>,
}

impl Exit {
    fn clean(&self) -> bool {
        self.code == Some(0)
    }
}

/// "code 1", "killed by signal 9".
impl fmt::Display for Exit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.code, self.signal) {
            (Some(code), _) => write!(f, "code {code}"),
            (None, Some(signal)) => write!(f, "killed by signal {signal}"),
            (None, None) => f.write_str("killed by signal ?"),
        }
    }
}

/// A child of the launcher: the planner, the world or an agent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Child {
    pub role: Role,
    pub id: u32,
}

impl Child {
    /// "agent 3", "the world".
    pub fn who(&self) -> String {
        match self.role {
            Role::Agent => format!("agent {}", self.id),
            role => format!("the {role}"),
        }
    }

    /// Its log, under the run directory's `logs/`.
    pub fn log(&self) -> String {
        match self.role {
            Role::Agent => format!("agent-{}.log", self.id),
            role => format!("{role}.log"),
        }
    }
}

/// When a child died, as the failure says it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum When {
    AsItStarted,
    BeforeTheFirstTick,
    BeforeTheEnd,
    AfterServingThePaths,
}

impl fmt::Display for When {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            When::AsItStarted => "as it started",
            When::BeforeTheFirstTick => "before the first tick",
            When::BeforeTheEnd => "before the end",
            When::AfterServingThePaths => "after serving the paths",
        })
    }
}

/// Why a run failed.
#[derive(Debug, Clone, PartialEq)]
pub enum Failure {
    /// A child the run cannot go on without exited; `last_words` is the last error its log
    /// holds, which the launcher reads.
    Died {
        child: Child,
        exit: Exit,
        when: When,
        last_words: Option<String>,
    },
    /// The world ended the run and exited, and the rest of the recording never came.
    MissedTheEnd { ticks: u64, waited_s: f64 },
    /// No tick came within the world's startup timeout and the margin.
    DidNotStart { waited_s: f64 },
    /// Ticks far ahead came and were refused, and none of the next one.
    LostMessages {
        tick: u64,
        refused_ahead: u64,
        waited_s: f64,
    },
    /// No tick completed within the stall limit.
    Stalled { limit_s: f64, ticks: u64 },
    /// Said by the launcher: the recorder failed, an agent could not be started.
    Other(String),
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Failure::Died {
                child,
                exit,
                when,
                last_words,
            } => {
                let (who, log) = (child.who(), child.log());
                match last_words {
                    Some(why) => write!(f, "{who} exited ({exit}) {when}: {why} (logs/{log})"),
                    None => write!(f, "{who} exited ({exit}) {when}; see logs/{log}"),
                }
            }
            Failure::MissedTheEnd { ticks, waited_s } => write!(
                f,
                "the recorder missed the end: the world ended the run (exit 0), but the recording stops at tick {ticks}, and no more came within {waited_s} s; its link to the world lost them (was this process stopped, by SIGSTOP, or starved?)"
            ),
            Failure::DidNotStart { waited_s } => write!(
                f,
                "the run did not start within {} s; see logs/world.log",
                waited_s.trunc()
            ),
            Failure::LostMessages {
                tick,
                refused_ahead,
                waited_s,
            } => write!(
                f,
                "the recorder lost messages of tick {tick}: {refused_ahead} of later ticks came and were refused as too far ahead, none of it for {waited_s} s; its link to the world dropped them (was this process stopped, by SIGSTOP, or starved?). The fleet's own logs say how it ended"
            ),
            Failure::Stalled { limit_s, ticks } => write!(
                f,
                "no tick completed for {} s (stuck after tick {ticks})",
                limit_s.trunc()
            ),
            Failure::Other(why) => f.write_str(why),
        }
    }
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    Completed,
    Interrupted,
    Failed(Failure),
}

/// What the recording holds, as the launcher reads it after each of its steps.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Recorded {
    /// Ticks written.
    pub ticks: u64,
    /// The world's end has come.
    pub ended: bool,
    /// The end has come and every tick before it is written.
    pub complete: bool,
    /// The vehicles lost so far.
    pub lost: Vec<u32>,
    /// Messages refused as too far ahead of the ticks written.
    pub refused_ahead: u64,
}

/// What the launcher tells its supervisor.
#[derive(Debug, Clone, PartialEq)]
pub enum Input {
    /// Child `index` has exited so.
    Exited(usize, Exit),
    /// Child `index`'s exit report has come.
    Reported(usize),
    /// Child `index` (an agent asked for by `Output::Restart`) runs again.
    Restarted(usize),
    /// The recording after a step.
    Recorded(Recorded),
    /// The fleet went on after being stopped with the launcher (Ctrl-Z): no tick came because
    /// none could.
    Continued,
    /// Ctrl-C, or a signal to stop.
    Interrupted,
    /// The launcher failed the run: its recorder failed, or an agent could not be started.
    Failed(String),
}

/// What the launcher is to do.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// Start this child (an agent) again: it died, and its vehicle is not lost. The launcher
    /// answers with `Input::Restarted`, or with `Input::Failed` if it cannot.
    Restart { child: usize, exit: Exit },
    /// The planner exited once the fleet ran: the run goes on without it, and says so.
    PlannerGone { child: usize, exit: Exit, ticks: u64 },
    /// The run is over, so: the children get their grace, if any, then are killed.
    Over(Outcome),
    /// Tell every child still running to stop (after an interrupt, which the children's
    /// process groups did not get).
    Terminate,
    /// Kill every child still running, and close the run.
    Kill,
}

#[derive(Debug)]
struct Kid {
    child: Child,
    exit: Option<Exit>,
    /// Its exit report came (or it was killed by a signal, and sends none).
    reported: bool,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    Running,
    /// After the end or an interrupt, until `deadline`: the children exit by themselves. Once
    /// every one has (at `exited`), a report still missing has the settle time to come.
    Grace {
        deadline: Moment,
        exited: Option<Moment>,
    },
    Done,
}

/// The launcher's supervisor of one run.
#[derive(Debug)]
pub struct Supervisor {
    config: Supervision,
    kids: Vec<Kid>,
    recorded: Recorded,
    /// When a tick was last written (or the run began, or the fleet continued after a stop).
    progress_at: Moment,
    next_check: Moment,
    phase: Phase,
    planner_gone_said: bool,
    restarts: Vec<Restarts>,
    outputs: VecDeque<Output>,
}

impl Supervisor {
    /// A run of these children (in the order the launcher lists them), begun at `now`.
    pub fn new(config: Supervision, children: impl IntoIterator<Item = Child>, now: Moment) -> Supervisor {
        Supervisor {
            next_check: now,
            config,
            kids: children
                .into_iter()
                .map(|child| Kid {
                    child,
                    exit: None,
                    reported: false,
                })
                .collect(),
            recorded: Recorded::default(),
            progress_at: now,
            phase: Phase::Running,
            planner_gone_said: false,
            restarts: Vec::new(),
            outputs: VecDeque::new(),
        }
    }

    /// Child `index` has exited so.
    fn exited(&mut self, index: usize, exit: Exit) {
        let kid = &mut self.kids[index];
        kid.exit = Some(exit);
        // Killed by a signal: no report is coming.
        kid.reported |= exit.code.is_none();
    }

    /// Child `index`'s exit report has come.
    fn reported(&mut self, index: usize) {
        self.kids[index].reported = true;
    }

    /// Child `index` (an agent asked for by `Output::Restart`) runs again.
    fn restarted(&mut self, index: usize) {
        let kid = &mut self.kids[index];
        kid.exit = None;
        kid.reported = false;
        let id = kid.child.id;
        match self.restarts.iter_mut().find(|r| r.id == id) {
            Some(r) => r.restarts += 1,
            None => self.restarts.push(Restarts { id, restarts: 1 }),
        }
    }

    /// The recording after a step.
    fn recorded(&mut self, recorded: Recorded, now: Moment) {
        if recorded.ticks > self.recorded.ticks {
            self.progress_at = now;
        }
        let complete = recorded.complete;
        self.recorded = recorded;
        if complete {
            self.over(Outcome::Completed, now);
        }
    }

    /// The fleet went on after being stopped with the launcher (Ctrl-Z): no tick came because
    /// none could.
    fn continued(&mut self, now: Moment) {
        self.progress_at = now;
    }

    /// Ctrl-C, or a signal to stop.
    fn interrupted(&mut self, now: Moment) {
        self.over(Outcome::Interrupted, now);
    }

    /// The launcher failed the run: its recorder failed, or an agent could not be started.
    /// In the grace after the end, it only cuts the grace short.
    fn failed(&mut self, why: String, now: Moment) {
        match self.phase {
            Phase::Running => self.over(Outcome::Failed(Failure::Other(why)), now),
            Phase::Grace { .. } => self.finish(),
            Phase::Done => {}
        }
    }

    /// The agents started again, per vehicle.
    pub fn restarts(&self) -> &[Restarts] {
        &self.restarts
    }

    fn check(&mut self, now: Moment) {
        let waited = now - self.progress_at;
        let ticks = self.recorded.ticks;
        let timeouts = &self.config.timeouts;
        // An agent gone before the first tick, and not to be started again, would keep the
        // world waiting for it to its startup timeout. The planner serves agents as they start:
        // once the fleet runs it may go (a testbed's shore planner is no vehicle), and the run
        // says so.
        let mut planner_gone = None;
        let dead = self.kids.iter().enumerate().find_map(|(index, kid)| {
            let exit = kid.exit?;
            let died = |when| {
                Some(Failure::Died {
                    child: kid.child,
                    exit,
                    when,
                    last_words: None,
                })
            };
            match kid.child.role {
                // A world that ended the run (exit 0) sent its end: still on its way while the
                // recorder reads what came before it.
                Role::World if exit.clean() => (waited > timeouts.end_on_its_way_s).then_some(Failure::MissedTheEnd {
                    ticks,
                    waited_s: timeouts.end_on_its_way_s,
                }),
                Role::World => died(When::BeforeTheEnd),
                Role::Planner if ticks == 0 => died(When::BeforeTheFirstTick),
                Role::Planner => {
                    if !self.planner_gone_said {
                        planner_gone = Some(Output::PlannerGone {
                            child: index,
                            exit,
                            ticks,
                        });
                    }
                    None
                }
                Role::Agent if ticks == 0 && !self.config.restart => died(When::BeforeTheFirstTick),
                _ => None,
            }
        });
        if let Some(gone) = planner_gone {
            self.planner_gone_said = true;
            self.outputs.push_back(gone);
        }
        if let Some(why) = dead {
            if !self.recorded.ended {
                return self.over(Outcome::Failed(why), now);
            }
        }
        if self.config.restart && !self.recorded.ended {
            for (index, kid) in self.kids.iter_mut().enumerate() {
                let Some(exit) = kid.exit else { continue };
                // A new agent of a lost vehicle is told so by the world, and stops.
                if kid.child.role != Role::Agent || exit.clean() || self.recorded.lost.contains(&kid.child.id) {
                    continue;
                }
                // Until the launcher says it runs again.
                kid.exit = None;
                self.outputs.push_back(Output::Restart { child: index, exit });
            }
        }
        let stall = self.config.stall_limit_s();
        let timeouts = &self.config.timeouts;
        let refused_ahead = self.recorded.refused_ahead;
        let failure = match ticks {
            0 if waited > self.config.startup_timeout_s + timeouts.start_margin_s => {
                Some(Failure::DidNotStart { waited_s: waited })
            }
            0 => None,
            // Messages of ticks far ahead, and none of the next: the recorder's link lost some
            // (a lockstep fleet publishes a tick only once the one before is whole), and
            // waiting longer brings nothing.
            ticks if self.config.lockstep && waited > timeouts.end_on_its_way_s && refused_ahead > 0 => {
                Some(Failure::LostMessages {
                    tick: ticks + 1,
                    refused_ahead,
                    waited_s: timeouts.end_on_its_way_s,
                })
            }
            ticks if waited > stall => Some(Failure::Stalled { limit_s: stall, ticks }),
            _ => None,
        };
        if let Some(why) = failure {
            self.over(Outcome::Failed(why), now);
        }
    }

    fn over(&mut self, outcome: Outcome, now: Moment) {
        if self.phase != Phase::Running {
            return;
        }
        let grace = match outcome {
            Outcome::Completed => Some(self.config.timeouts.grace_s),
            Outcome::Interrupted => Some(self.config.timeouts.interrupt_grace_s),
            Outcome::Failed(_) => None,
        };
        let interrupted = outcome == Outcome::Interrupted;
        self.outputs.push_back(Output::Over(outcome));
        if interrupted {
            self.outputs.push_back(Output::Terminate);
        }
        match grace {
            Some(grace) => {
                self.phase = Phase::Grace {
                    deadline: now + grace,
                    exited: None,
                };
                self.next_check = now;
            }
            None => self.finish(),
        }
    }

    fn finish(&mut self) {
        self.phase = Phase::Done;
        self.outputs.push_back(Output::Kill);
    }
}

impl Machine for Supervisor {
    type Input = Input;
    type Output = Output;
    /// The outcome is said once, by `Output::Over`.
    type Exit = ();

    fn handle(&mut self, input: Input, now: Moment) {
        match input {
            Input::Exited(index, exit) => self.exited(index, exit),
            Input::Reported(index) => self.reported(index),
            Input::Restarted(index) => self.restarted(index),
            Input::Recorded(recorded) => self.recorded(recorded, now),
            Input::Continued => self.continued(now),
            Input::Interrupted => self.interrupted(now),
            Input::Failed(why) => self.failed(why, now),
        }
    }

    /// When the launcher should next call `handle_timeout`.
    fn poll_timeout(&self) -> Option<Moment> {
        match self.phase {
            Phase::Running => Some(self.next_check),
            Phase::Grace { deadline, .. } => Some(self.next_check.min(deadline)),
            Phase::Done => None,
        }
    }

    /// The children's exits as of `now` are told: what they mean.
    fn handle_timeout(&mut self, now: Moment, _due: Moment) {
        if now >= self.next_check {
            self.next_check = now + self.config.timeouts.check_s;
        }
        match self.phase {
            Phase::Running => self.check(now),
            Phase::Grace { deadline, exited } => {
                if now >= deadline {
                    return self.finish();
                }
                if self.kids.iter().all(|k| k.exit.is_some()) {
                    let since = exited.unwrap_or(now);
                    self.phase = Phase::Grace {
                        deadline,
                        exited: Some(since),
                    };
                    if now - since >= self.config.timeouts.report_settle_s || self.kids.iter().all(|k| k.reported) {
                        self.finish();
                    }
                }
            }
            Phase::Done => {}
        }
    }

    fn poll_output(&mut self) -> Option<Output> {
        self.outputs.pop_front()
    }

    /// Done once the children are gone, or killed.
    fn poll_exit(&mut self) -> Option<()> {
        (self.phase == Phase::Done).then_some(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn supervision(restart: bool) -> Supervision {
        Supervision {
            restart,
            lockstep: true,
            startup_timeout_s: 30.0,
            command_timeout_s: 5.0,
            wall_period_s: 0.1,
            timeouts: Timeouts::default(),
        }
    }

    /// The planner, the world and two agents, as the launcher lists them.
    fn fleet(restart: bool) -> Supervisor {
        let children = [
            Child {
                role: Role::Planner,
                id: 0,
            },
            Child {
                role: Role::World,
                id: 0,
            },
            Child {
                role: Role::Agent,
                id: 1,
            },
            Child {
                role: Role::Agent,
                id: 2,
            },
        ];
        Supervisor::new(supervision(restart), children, at(0.0))
    }

    const CODE_1: Exit = Exit {
        code: Some(1),
        signal: None,
    };
    const CLEAN: Exit = Exit {
        code: Some(0),
        signal: None,
    };
    const KILLED: Exit = Exit {
        code: None,
        signal: Some(9),
    };

    fn outputs(s: &mut Supervisor) -> Vec<Output> {
        std::iter::from_fn(|| s.poll_output()).collect()
    }

    fn ticks(ticks: u64) -> Recorded {
        Recorded {
            ticks,
            ..Recorded::default()
        }
    }

    fn at(s: f64) -> Moment {
        Moment::from_secs(s)
    }

    /// Checks at every `check_s` up to `to` s, as the launcher's timer would.
    fn run_until(s: &mut Supervisor, to: f64) -> Vec<Output> {
        let to = at(to);
        let mut out = Vec::new();
        while let Some(at) = s.poll_timeout().filter(|&at| at <= to) {
            s.handle_timeout(at, at);
            out.extend(outputs(s));
        }
        out
    }

    /// Quiet up to `until`, then failed within the next check: why.
    fn fails_after(s: &mut Supervisor, until: f64) -> Failure {
        assert_eq!(run_until(s, until), [], "quiet up to {until} s");
        failure(&run_until(s, until + 0.1)).cloned().expect("failed just after")
    }

    fn failure(out: &[Output]) -> Option<&Failure> {
        out.iter().find_map(|o| match o {
            Output::Over(Outcome::Failed(f)) => Some(f),
            _ => None,
        })
    }

    #[test]
    fn a_run_stalls_only_after_what_the_world_waits_for_on_purpose() {
        let mut config = supervision(false);
        assert_eq!(config.stall_limit_s(), 60.0);
        config.command_timeout_s = 120.0;
        assert_eq!(config.stall_limit_s(), 130.0);
        config.command_timeout_s = 5.0;
        config.wall_period_s = 100.0;
        assert_eq!(config.stall_limit_s(), 210.0);
        config.wall_period_s = 0.1;
        config.restart = true;
        config.timeouts.rejoin_s = 55.0;
        assert_eq!(config.stall_limit_s(), 65.0);
    }

    #[test]
    fn a_run_that_ticks_on_goes_on_until_it_is_complete_then_gives_the_children_their_grace() {
        let mut s = fleet(false);
        for k in 1..=100 {
            s.recorded(ticks(k), at(k as f64));
            assert_eq!(run_until(&mut s, k as f64), []);
        }
        s.recorded(
            Recorded {
                ticks: 101,
                ended: true,
                complete: true,
                ..Recorded::default()
            },
            at(101.0),
        );
        assert_eq!(outputs(&mut s), [Output::Over(Outcome::Completed)]);
        // Every child exits and reports within its grace: the run closes at once.
        for child in 0..4 {
            s.exited(child, CLEAN);
            s.reported(child);
        }
        assert_eq!(run_until(&mut s, 101.0), [Output::Kill]);
        assert_eq!(s.poll_exit(), Some(()));
        assert_eq!(s.poll_timeout(), None);
    }

    #[test]
    fn a_child_that_does_not_exit_within_its_grace_is_killed_at_its_end() {
        let mut s = fleet(false);
        s.recorded(
            Recorded {
                ticks: 10,
                ended: true,
                complete: true,
                ..Recorded::default()
            },
            at(10.0),
        );
        for child in 0..3 {
            s.exited(child, CLEAN);
        }
        assert_eq!(run_until(&mut s, 12.9), [Output::Over(Outcome::Completed)]);
        assert_eq!(run_until(&mut s, 13.0), [Output::Kill]);
    }

    #[test]
    fn reports_missing_once_every_child_has_exited_have_the_settle_time_to_come() {
        let mut s = fleet(false);
        s.recorded(
            Recorded {
                ticks: 10,
                ended: true,
                complete: true,
                ..Recorded::default()
            },
            at(10.0),
        );
        run_until(&mut s, 10.0);
        for child in 0..4 {
            s.exited(child, CLEAN);
        }
        s.reported(0);
        // Every exit is seen at the check of 10.1 s: three reports have until 10.3 s to come.
        assert_eq!(run_until(&mut s, 10.25), []);
        assert_eq!(run_until(&mut s, 10.45), [Output::Kill]);
    }

    #[test]
    fn an_interrupt_tells_the_children_to_stop_and_kills_them_a_second_later() {
        let mut s = fleet(false);
        s.recorded(ticks(5), at(5.0));
        s.interrupted(at(5.5));
        assert_eq!(outputs(&mut s), [Output::Over(Outcome::Interrupted), Output::Terminate]);
        assert_eq!(run_until(&mut s, 6.45), []);
        assert_eq!(run_until(&mut s, 6.5), [Output::Kill]);
    }

    #[test]
    fn the_world_dying_before_the_end_fails_the_run_naming_it_and_its_log() {
        let mut s = fleet(false);
        s.recorded(ticks(7), at(1.0));
        run_until(&mut s, 1.0);
        s.exited(1, KILLED);
        let out = run_until(&mut s, 1.1);
        assert_eq!(out.last(), Some(&Output::Kill));
        let mut why = failure(&out).cloned().expect("failed");
        assert_eq!(
            why.to_string(),
            "the world exited (killed by signal 9) before the end; see logs/world.log"
        );
        if let Failure::Died { last_words, .. } = &mut why {
            *last_words = Some("no route".into());
        }
        assert_eq!(
            why.to_string(),
            "the world exited (killed by signal 9) before the end: no route (logs/world.log)"
        );
    }

    #[test]
    fn a_world_that_ended_the_run_has_five_seconds_for_its_last_ticks_to_arrive() {
        let mut s = fleet(false);
        s.recorded(ticks(50), at(10.0));
        s.exited(1, CLEAN);
        assert_eq!(
            fails_after(&mut s, 15.0),
            Failure::MissedTheEnd {
                ticks: 50,
                waited_s: 5.0
            }
        );
    }

    #[test]
    fn an_agent_dead_before_the_first_tick_fails_the_run_unless_it_is_started_again() {
        let mut s = fleet(false);
        s.exited(3, CODE_1);
        let out = run_until(&mut s, 0.0);
        assert_eq!(
            failure(&out).map(ToString::to_string).as_deref(),
            Some("agent 2 exited (code 1) before the first tick; see logs/agent-2.log")
        );

        let mut s = fleet(true);
        s.exited(3, CODE_1);
        assert_eq!(run_until(&mut s, 0.0), [Output::Restart { child: 3, exit: CODE_1 }]);
        // Not asked for twice while the launcher starts it.
        assert_eq!(run_until(&mut s, 0.3), []);
        s.restarted(3);
        s.exited(3, KILLED);
        assert_eq!(run_until(&mut s, 0.4), [Output::Restart { child: 3, exit: KILLED }]);
        s.restarted(3);
        assert_eq!(s.restarts(), [Restarts { id: 2, restarts: 2 }]);
    }

    #[test]
    fn an_agent_of_a_lost_vehicle_or_one_that_exited_cleanly_is_not_started_again() {
        let mut s = fleet(true);
        s.recorded(
            Recorded {
                ticks: 3,
                lost: vec![1],
                ..Recorded::default()
            },
            at(0.0),
        );
        s.exited(2, CODE_1);
        s.exited(3, CLEAN);
        assert_eq!(run_until(&mut s, 1.0), []);
        // Nor after the end, when agents exit as they should.
        let mut s = fleet(true);
        s.recorded(
            Recorded {
                ticks: 3,
                ended: true,
                ..Recorded::default()
            },
            at(0.0),
        );
        s.exited(3, KILLED);
        assert_eq!(run_until(&mut s, 1.0), []);
    }

    #[test]
    fn a_planner_gone_after_the_first_tick_is_said_once_and_the_run_goes_on() {
        let mut s = fleet(false);
        s.exited(0, CODE_1);
        assert!(failure(&run_until(&mut s, 0.0)).is_some(), "no paths were served");

        let mut s = fleet(false);
        s.recorded(ticks(1), at(0.0));
        s.exited(0, CODE_1);
        let gone = Output::PlannerGone {
            child: 0,
            exit: CODE_1,
            ticks: 1,
        };
        assert_eq!(run_until(&mut s, 0.0), [gone]);
        s.recorded(ticks(2), at(0.5));
        assert_eq!(run_until(&mut s, 1.0), []);
    }

    #[test]
    fn a_run_with_no_tick_fails_after_the_worlds_startup_timeout_and_the_margin() {
        let mut s = fleet(false);
        assert_eq!(
            fails_after(&mut s, 40.0).to_string(),
            "the run did not start within 40 s; see logs/world.log"
        );
    }

    #[test]
    fn a_run_stuck_after_a_tick_fails_after_the_stall_limit() {
        let mut s = fleet(false);
        s.recorded(ticks(12), at(1.0));
        assert_eq!(
            fails_after(&mut s, 61.0),
            Failure::Stalled {
                limit_s: 60.0,
                ticks: 12
            }
        );
    }

    #[test]
    fn a_fleet_stopped_with_the_launcher_does_not_stall_by_it() {
        let mut s = fleet(false);
        s.recorded(ticks(12), at(1.0));
        assert_eq!(run_until(&mut s, 50.0), []);
        // Ctrl-Z at 50 s, `fg` at 500 s.
        s.continued(at(500.0));
        assert_eq!(run_until(&mut s, 559.9), []);
        assert!(failure(&run_until(&mut s, 560.1)).is_some());
    }

    #[test]
    fn lockstep_ticks_refused_ahead_with_none_of_the_next_fail_after_five_seconds() {
        let mut s = fleet(false);
        let ahead = Recorded {
            ticks: 20,
            refused_ahead: 3,
            ..Recorded::default()
        };
        s.recorded(ahead.clone(), at(2.0));
        assert_eq!(
            fails_after(&mut s, 7.0),
            Failure::LostMessages {
                tick: 21,
                refused_ahead: 3,
                waited_s: 5.0
            }
        );
        // In realtime the world does not wait for a tick to be whole: only the stall limit.
        let mut s = Supervisor::new(
            Supervision {
                lockstep: false,
                ..supervision(false)
            },
            [Child {
                role: Role::World,
                id: 0,
            }],
            at(0.0),
        );
        s.recorded(ahead, at(2.0));
        assert_eq!(run_until(&mut s, 30.0), []);
    }

    #[test]
    fn a_failure_said_by_the_launcher_ends_the_run_at_once_but_only_cuts_a_grace_short() {
        let mut s = fleet(false);
        s.failed("the recorder failed: gone".into(), at(1.0));
        assert_eq!(
            outputs(&mut s),
            [
                Output::Over(Outcome::Failed(Failure::Other("the recorder failed: gone".into()))),
                Output::Kill
            ]
        );
        let mut s = fleet(false);
        s.interrupted(at(1.0));
        s.failed("the recorder failed: gone".into(), at(1.2));
        assert_eq!(
            outputs(&mut s),
            [Output::Over(Outcome::Interrupted), Output::Terminate, Output::Kill]
        );
        assert_eq!(s.poll_exit(), Some(()));
    }
}
