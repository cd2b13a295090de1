//! A recorder's process as one machine: the tick machine of its clock (`record::Recorder` in
//! lockstep, `realtime::Sampler` in realtime) and what the process decided around it. Nothing is
//! written before the world's clock has said it runs this recorder's mission; a lockstep
//! recording that hears a first tick past 0 came too late; the end's acknowledgement, which the
//! world waits for, is held until every tick before the end is in; the recorder's token, which
//! the world and the agents wait for, goes once the recording is complete and every exit report
//! the end calls for is in.
//!
//! The shell checks that each message came on its sender's key, then hands it in; the machine
//! does its work through `Io`, as `lockstep_world` does, since the rows it writes are lent out of
//! the tick machines. Times are inputs: instants on the recorder's monotonic clock.

use crate::msg::{Clock, Command, End, Fetch, Lost, Report, Role, State, TickRecord};
use crate::outputs::metrics::Results;
use crate::outputs::summary::{self, Recorded};
use crate::roles::lockstep::Reject;
use crate::roles::realtime::Sampler;
use crate::roles::record::Recorder;
use crate::time::{Moment, UnixTime};

/// What a recorder takes, each from the key of its sender. `A` is the shell's acknowledgement of
/// the end, which the machine holds and hands back.
pub enum Input<A> {
    /// Lockstep: the world's record of a tick.
    Tick(TickRecord<'static>),
    /// Realtime: a vehicle's state or command.
    State(State),
    Command(Command),
    End(End, A),
    Loss(Lost),
    Report(Box<Report>),
    /// Realtime: a state the world's history gave, and the end of its answer (the vehicles it
    /// keeps none of).
    History(State),
    Fetched(Vec<u32>),
}

impl<A> Input<A> {
    /// Sent by the world: what says it is still there.
    fn is_the_worlds(&self) -> bool {
        matches!(
            self,
            Input::Tick(_) | Input::State(_) | Input::End(..) | Input::History(_)
        )
    }
}

/// What the shell does for a recorder, called in the order it is to be done.
pub trait Io<A> {
    /// A tick complete, in order: a row of telemetry per vehicle.
    fn write(&mut self, states: &[State], commands: &[Option<Command>]);
    /// Realtime: the latest tick a message may carry now, by the fleet's clock.
    fn horizon(&self) -> u64;
    /// Realtime: ask the world's history for the states that never came.
    fn fetch(&mut self, fetch: Fetch);
    /// Every tick before the end is in: the end's acknowledgement may go.
    fn acknowledge(&mut self, ack: A);
    /// Lockstep: the ticks have begun, so the world's clock answers now; ask it again should its
    /// announcement be slower, as the ticks wait for it.
    fn clock_due(&mut self);
    /// Realtime: no state of these vehicles has come yet, well into the run. Said once.
    fn overdue(&mut self, ids: &[u32]);
    /// The recording is complete and every report is in: withdraw the token. Called once.
    fn withdraw(&mut self);
}

/// Why a message was not taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refused {
    /// The message, counted.
    Message(Reject),
    /// Lockstep: the run was under way when this recorder came; it cannot go on.
    CameLate { first_tick: u64 },
}

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refused::Message(why) => write!(f, "{why:?}"),
            Refused::CameLate { first_tick } => write!(
                f,
                "the lockstep run was under way when this recorder came (the first tick it heard is {first_tick}): a lockstep recording starts at tick 0, so start the world with --recorders 1, which waits for it"
            ),
        }
    }
}

impl From<Reject> for Refused {
    fn from(why: Reject) -> Refused {
        Refused::Message(why)
    }
}

/// Each tick machine boxed: both are large (their metrics).
enum Ticks {
    Lockstep(Box<Recorder>),
    Realtime(Box<Sampler>),
}

pub struct RecorderNode<A> {
    ticks: Ticks,
    control_period: f64,
    /// The world's clock has answered, and was this recorder's mission's.
    clocked: bool,
    /// Lockstep: the first tick record has come.
    ticking: bool,
    end: Option<End>,
    /// The end's acknowledgements, until the recording has every tick before it.
    held: Vec<A>,
    reports: Vec<Report>,
    ids: Vec<u32>,
    /// Messages taken from the world so far.
    from_world: u64,
    first: Option<Moment>,
    /// When the last tick was written (or the recording started).
    progress: Moment,
    withdrawn: bool,
}

impl<A> RecorderNode<A> {
    pub fn new(mission: &crate::mission::Mission, t_f: f64, now: Moment) -> Self {
        let ids: Vec<u32> = mission.vehicles.iter().map(|v| v.id).collect();
        let dt = mission.mission.control_period;
        let ticks = match mission.mission.clock {
            crate::mission::ClockKind::Lockstep => {
                Ticks::Lockstep(Box::new(Recorder::new(&ids, t_f, dt).with_faults(mission)))
            }
            crate::mission::ClockKind::Realtime => Ticks::Realtime(Box::new(
                Sampler::new(&ids, &mission.graph(), t_f, dt).with_faults(mission),
            )),
        };
        RecorderNode {
            ticks,
            control_period: dt,
            clocked: false,
            ticking: false,
            end: None,
            held: Vec::new(),
            reports: Vec::new(),
            ids,
            from_world: 0,
            first: None,
            progress: now,
            withdrawn: false,
        }
    }

    pub fn control_period(&self) -> f64 {
        self.control_period
    }

    /// Whether the next message may be taken now. Realtime messages wait for the clock, which
    /// says how far ahead of it they may be. Lockstep ones, once the ticks have begun, wait for
    /// it too: nothing is written before it, and the recorder's window of ticks (a few ms of a
    /// fast fleet) would fill and refuse every later genuine tick as too far ahead.
    pub fn takes_messages(&self) -> bool {
        match self.ticks {
            Ticks::Lockstep(_) => !self.ticking || self.clocked,
            Ticks::Realtime(_) => self.clocked,
        }
    }

    /// The world's clock answered, and the shell found it this recorder's mission's.
    /// `subscribed` is when every subscription was in place, on the wall clock: what the world
    /// published since, this recorder heard (or may fetch).
    pub fn handle_clock(&mut self, clock: &Clock, subscribed: UnixTime, now: Moment, io: &mut impl Io<A>) {
        self.clocked = true;
        if let Ticks::Realtime(sampler) = &mut self.ticks {
            // The tick under way when the subscriptions were in place, on the fleet's clock
            // (never later than the one the clock's answer names).
            let since = (subscribed - clock.epoch) * clock.time_scale / self.control_period;
            sampler.start_at(clock.tick.min(since.max(0.0) as u64));
        }
        self.settle(now, io);
    }

    /// A message came, from the sender its key names.
    pub fn handle(&mut self, input: Input<A>, now: Moment, io: &mut impl Io<A>) -> Result<(), Refused> {
        self.from_world += input.is_the_worlds() as u64;
        let taken = self.take(input, io);
        self.settle(now, io);
        taken
    }

    fn take(&mut self, input: Input<A>, io: &mut impl Io<A>) -> Result<(), Refused> {
        match (&mut self.ticks, input) {
            (_, Input::Report(report)) => {
                keep(&mut self.reports, *report);
                Ok(())
            }
            (Ticks::Lockstep(recorder), Input::End(end, ack)) => {
                take_end(&mut self.end, &mut self.held, (end, ack), |e| recorder.on_end(e))
            }
            (Ticks::Realtime(sampler), Input::End(end, ack)) => {
                take_end(&mut self.end, &mut self.held, (end, ack), |e| sampler.on_end(e))
            }
            (Ticks::Lockstep(recorder), Input::Tick(tick)) => {
                if !std::mem::replace(&mut self.ticking, true) {
                    // The world waits for this recorder's token before its first tick: a first
                    // record of a later one is a run this recorder came to too late.
                    if tick.tick > 0 {
                        return Err(Refused::CameLate { first_tick: tick.tick });
                    }
                    io.clock_due();
                }
                Ok(recorder.on_tick(tick)?)
            }
            (Ticks::Lockstep(recorder), Input::Loss(lost)) => Ok(recorder.on_lost(lost)?),
            // A lockstep recorder takes states and commands from the tick record.
            (Ticks::Lockstep(_), Input::State(_) | Input::Command(_) | Input::History(_) | Input::Fetched(_)) => Ok(()),
            (Ticks::Realtime(sampler), Input::State(state)) => Ok(sampler.on_state(state, io.horizon())?),
            (Ticks::Realtime(sampler), Input::Command(command)) => Ok(sampler.on_command(command, io.horizon())?),
            (Ticks::Realtime(sampler), Input::History(state)) => Ok(sampler.on_history(state)?),
            (Ticks::Realtime(sampler), Input::Fetched(unkept)) => {
                sampler.on_fetched(&unkept);
                Ok(())
            }
            (Ticks::Realtime(_), Input::Tick(_) | Input::Loss(_)) => Ok(()),
        }
    }

    /// Writes what is complete, asks for what is missing, and lets go of what waited for it.
    fn settle(&mut self, now: Moment, io: &mut impl Io<A>) {
        let before = self.ticks_recorded();
        match &mut self.ticks {
            // Nothing is written before the world's clock says it runs this recorder's mission:
            // one of another would write ticks it is then refused for.
            Ticks::Lockstep(recorder) if self.clocked => recorder.drain(|states, commands| io.write(states, commands)),
            Ticks::Lockstep(_) => {}
            Ticks::Realtime(sampler) => {
                sampler.drain(|states, commands| io.write(states, commands));
                if let Some(fetch) = sampler.fetch() {
                    io.fetch(fetch);
                }
                if let Some(ids) = sampler.overdue_states() {
                    io.overdue(&ids);
                }
            }
        }
        if self.settled() {
            self.held.drain(..).for_each(|ack| io.acknowledge(ack));
        }
        if self.ticks_recorded() > before {
            self.progress = now;
            self.first.get_or_insert(now);
        }
        if !self.withdrawn && self.complete() && self.unreported().is_empty() {
            self.withdrawn = true;
            io.withdraw();
        }
    }

    /// Every tick before the end is in, or known lost: a lockstep recorder's came before the
    /// end; a realtime one's may wait for the world's history, which the world answers until it
    /// has the end's acknowledgement.
    fn settled(&self) -> bool {
        match &self.ticks {
            Ticks::Lockstep(_) => true,
            Ticks::Realtime(sampler) => !sampler.fetching(),
        }
    }

    /// The world announced the end and every tick up to it is written.
    pub fn complete(&self) -> bool {
        match &self.ticks {
            Ticks::Lockstep(recorder) => recorder.complete(),
            // Not while the rows wait for the world's history.
            Ticks::Realtime(sampler) => sampler.ended() && !sampler.fetching(),
        }
    }

    pub fn end(&self) -> Option<&End> {
        self.end.as_ref()
    }

    /// The exit reports, one per process.
    pub fn reports(&self) -> &[Report] {
        &self.reports
    }

    /// The vehicles lost so far: the world's end says, or before it, its losses.
    pub fn lost(&self) -> Vec<u32> {
        match (&self.end, &self.ticks) {
            (Some(end), _) => end.lost.iter().map(|l| l.id).collect(),
            (None, Ticks::Lockstep(recorder)) => recorder.losses().iter().map(|l| l.id).collect(),
            (None, Ticks::Realtime(_)) => Vec::new(),
        }
    }

    /// The roles whose exit report the end calls for and has not come.
    pub fn unreported(&self) -> Vec<(Role, u32)> {
        summary::unreported(&self.ids, self.end.as_ref(), &self.reports)
    }

    pub fn ticks_recorded(&self) -> u64 {
        match &self.ticks {
            Ticks::Lockstep(recorder) => recorder.ticks_recorded(),
            Ticks::Realtime(sampler) => sampler.ticks_recorded(),
        }
    }

    /// The last tick the world was heard of: in realtime, its newest state (the recorder's
    /// periods go on without it); in lockstep, the ticks recorded.
    pub fn world_ticks(&self) -> u64 {
        match &self.ticks {
            Ticks::Lockstep(recorder) => recorder.ticks_recorded(),
            Ticks::Realtime(sampler) => sampler.newest_state().unwrap_or(0),
        }
    }

    /// Messages taken from the world so far.
    pub fn from_world(&self) -> u64 {
        self.from_world
    }

    /// When the first tick was written, if one was.
    pub fn first_tick(&self) -> Option<Moment> {
        self.first
    }

    /// When the last tick was written, or the recording started.
    pub fn progress(&self) -> Moment {
        self.progress
    }

    /// Mean wall time of a tick in steady state, from the first tick written to the last.
    pub fn tick_wall_time(&self) -> Option<f64> {
        let first = self.first?;
        let ticks = self.ticks_recorded();
        (ticks > 1).then(|| (self.progress - first) / (ticks - 1) as f64)
    }

    pub fn results(&self) -> Results {
        match &self.ticks {
            Ticks::Lockstep(recorder) => recorder.results(),
            Ticks::Realtime(sampler) => sampler.results(),
        }
    }

    /// The recording ends: a realtime one writes the ticks it has, what is missing left empty.
    pub fn finish(&mut self, mut write: impl FnMut(&[State], &[Option<Command>])) -> Recorded {
        match &mut self.ticks {
            Ticks::Realtime(sampler) => {
                sampler.finish(&mut write);
                Recorded::Realtime {
                    never_heard: sampler.never_heard(),
                    newest_state: sampler.newest_state(),
                    missing_ticks: sampler.missing_ticks(),
                    came_at: sampler.came_at().unwrap_or(0),
                    players_from: sampler.players_from().cloned(),
                    recovered: sampler.recovered(),
                }
            }
            Ticks::Lockstep(recorder) => Recorded::Lockstep {
                contradicted_end: recorder.contradicted_end(),
            },
        }
    }
}

/// The world's end, kept once, its acknowledgement held for `settled`; the same end again (the
/// world asks again while the recorder fetches) is held too, not refused.
fn take_end<A>(
    end: &mut Option<End>,
    held: &mut Vec<A>,
    (e, ack): (End, A),
    take: impl FnOnce(End) -> Result<(), Reject>,
) -> Result<(), Refused> {
    if end.as_ref() != Some(&e) {
        take(e.clone())?;
        *end = Some(e);
    }
    held.push(ack);
    Ok(())
}

/// A process's exit report; the same process's report again replaces the first, so its counts
/// are not summed twice.
fn keep(reports: &mut Vec<Report>, report: Report) {
    let same = |r: &&mut Report| (&r.role, r.id, r.pid) == (&report.role, report.id, report.pid);
    match reports.iter_mut().find(same) {
        Some(r) => *r = report,
        None => reports.push(report),
    }
}

#[cfg(test)]
mod tests {
    use std::borrow::Cow;

    use super::*;
    use crate::fixtures::{case_b, command_at, still};
    use crate::mission::{ClockKind, Mission};
    use crate::msg::PROTOCOL_VERSION;

    fn at(s: f64) -> Moment {
        Moment::from_secs(s)
    }

    /// What the node asked of its shell, in order; each end's acknowledgement is a number.
    #[derive(Default)]
    struct Done {
        rows: Vec<u64>,
        fetches: Vec<(u64, u64)>,
        acks: Vec<u32>,
        clock_due: u32,
        overdue: Vec<Vec<u32>>,
        withdrawn: u32,
    }

    impl Io<u32> for Done {
        fn write(&mut self, states: &[State], _: &[Option<Command>]) {
            self.rows.push(states[0].tick);
        }
        fn horizon(&self) -> u64 {
            1_000
        }
        fn fetch(&mut self, fetch: Fetch) {
            self.fetches.push((fetch.from, fetch.to));
        }
        fn acknowledge(&mut self, ack: u32) {
            self.acks.push(ack);
        }
        fn clock_due(&mut self) {
            self.clock_due += 1;
        }
        fn overdue(&mut self, ids: &[u32]) {
            self.overdue.push(ids.to_vec());
        }
        fn withdraw(&mut self) {
            self.withdrawn += 1;
        }
    }

    fn record(m: &Mission, tick: u64) -> Input<u32> {
        let dt = m.mission.control_period;
        let ids = m.vehicles.iter().map(|v| v.id);
        Input::Tick(TickRecord {
            version: PROTOCOL_VERSION,
            tick,
            states: Cow::Owned(ids.clone().map(|id| still(id, tick, dt, [0.0, id as f64])).collect()),
            commands: Cow::Owned(ids.map(|id| Some(command_at(id, tick, 0.0))).collect()),
        })
    }

    fn end(ticks: u64) -> End {
        End {
            version: PROTOCOL_VERSION,
            ticks,
            lost: vec![],
            arrived: vec![],
        }
    }

    fn report(role: Role, id: u32, pid: u32) -> Input<u32> {
        Input::Report(Box::new(Report::new(role, id, pid)))
    }

    fn clock(m: &Mission, epoch: f64, tick: u64) -> Clock {
        Clock {
            version: PROTOCOL_VERSION,
            realtime: m.mission.clock == ClockKind::Realtime,
            time_scale: 1.0,
            epoch: UnixTime(epoch),
            tick,
            mission: m.digest(),
        }
    }

    /// A lockstep recording: its first record asks for the clock and holds every later message
    /// until it answers; rows leave once it has; the end is acknowledged at once (every tick
    /// before it came first); the token goes once, when the last report the end calls for is
    /// in; a process's report again replaces its first.
    #[test]
    fn a_lockstep_recording_writes_once_the_clock_answers_and_leaves_once_every_report_is_in() {
        let (m, _, t_f) = case_b();
        let mut node = RecorderNode::new(&m, t_f, at(0.0));
        let mut done = Done::default();
        assert!(node.takes_messages());
        node.handle(record(&m, 0), at(1.0), &mut done).unwrap();
        assert_eq!(done.clock_due, 1, "the first record: the clock answers now");
        assert!(!node.takes_messages(), "the rest wait for the clock");
        assert!(
            done.rows.is_empty(),
            "nothing written before the clock says the mission"
        );
        node.handle_clock(&clock(&m, 0.0, 0), UnixTime(0.0), at(2.0), &mut done);
        assert_eq!(done.rows, [0]);
        assert_eq!(node.first_tick(), Some(at(2.0)));
        for tick in 1..4 {
            node.handle(record(&m, tick), at(2.0 + tick as f64), &mut done).unwrap();
        }
        assert_eq!(done.rows, [0, 1, 2, 3]);
        assert_eq!(node.tick_wall_time(), Some(1.0), "3 s over ticks 0 to 3");
        assert_eq!(done.clock_due, 1, "asked once");
        node.handle(Input::End(end(4), 7), at(6.0), &mut done).unwrap();
        node.handle(Input::End(end(4), 8), at(6.0), &mut done).unwrap();
        assert_eq!(done.acks, [7, 8], "the same end again is acknowledged too");
        assert_eq!(
            node.handle(Input::End(end(5), 9), at(6.0), &mut done),
            Err(Refused::Message(Reject::Conflict))
        );
        assert!(node.complete() && node.end().is_some());
        assert_eq!(
            node.unreported(),
            [(Role::World, 0), (Role::Agent, 1), (Role::Agent, 2)]
        );
        node.handle(report(Role::World, 0, 10), at(7.0), &mut done).unwrap();
        node.handle(report(Role::Agent, 1, 11), at(7.0), &mut done).unwrap();
        node.handle(report(Role::Agent, 1, 11), at(7.0), &mut done).unwrap();
        assert_eq!(done.withdrawn, 0, "agent 2 has not reported");
        assert_eq!(node.reports().len(), 2, "agent 1's report again replaced its first");
        node.handle(report(Role::Agent, 2, 12), at(7.0), &mut done).unwrap();
        node.handle(report(Role::Agent, 2, 13), at(7.0), &mut done).unwrap();
        assert_eq!(done.withdrawn, 1, "withdrawn once");
        assert_eq!(
            node.reports().len(),
            4,
            "an agent started again reports as another process"
        );
        assert_eq!(node.from_world(), 7, "four records and three ends");
        assert_eq!(node.finish(|_, _| {}), Recorded::Lockstep { contradicted_end: None });
    }

    #[test]
    fn a_lockstep_recording_that_hears_a_later_tick_first_came_too_late() {
        let (m, _, t_f) = case_b();
        let mut node = RecorderNode::new(&m, t_f, at(0.0));
        let refused = node.handle(record(&m, 5), at(1.0), &mut Done::default());
        assert_eq!(refused, Err(Refused::CameLate { first_tick: 5 }));
        assert!(refused.unwrap_err().to_string().contains("--recorders 1"));
    }

    /// A realtime recording takes nothing before the clock; it starts at the tick under way
    /// when it subscribed; it asks the world's history for what the end shows missing, and
    /// holds the end's acknowledgement (the world answers the history until it has it) until
    /// the answer is in.
    #[test]
    fn a_realtime_recording_holds_the_end_until_the_history_has_answered() {
        let (mut m, _, t_f) = case_b();
        m.mission.clock = ClockKind::Realtime;
        let dt = m.mission.control_period;
        let mut node = RecorderNode::new(&m, t_f, at(0.0));
        let mut done = Done::default();
        assert!(!node.takes_messages(), "realtime messages wait for the clock");
        // Subscribed 2 periods after the epoch; the world answers at tick 3.
        node.handle_clock(&clock(&m, 0.0, 3), UnixTime(2.0 * dt), at(1.0), &mut done);
        assert!(node.takes_messages());
        let state = |id: u32, tick| Input::State(still(id, tick, dt, [0.0, 10.0 * id as f64]));
        for tick in 2..5 {
            for id in [1, 2] {
                node.handle(state(id, tick), at(2.0), &mut done).unwrap();
            }
        }
        // Of tick 5 and 6, only vehicle 1's of 6.
        node.handle(state(1, 6), at(3.0), &mut done).unwrap();
        assert_eq!(done.rows, [2, 3], "tick 4 waits for a later state of vehicle 2");
        node.handle(Input::End(end(7), 1), at(4.0), &mut done).unwrap();
        assert_eq!(done.fetches, [(5, 6)], "the ticks before the end");
        assert!(done.acks.is_empty(), "held while the history is asked");
        assert!(!node.complete());
        for history in [
            still(1, 5, dt, [0.0, 10.0]),
            still(2, 5, dt, [0.0, 20.0]),
            still(2, 6, dt, [0.0, 20.0]),
        ] {
            node.handle(Input::History(history), at(5.0), &mut done).unwrap();
        }
        assert!(done.acks.is_empty());
        node.handle(Input::Fetched(vec![]), at(5.0), &mut done).unwrap();
        assert_eq!(done.acks, [1]);
        assert!(node.complete());
        assert_eq!(node.world_ticks(), 6);
        match node.finish(|states, _| done.rows.push(states[0].tick)) {
            Recorded::Realtime { came_at, recovered, .. } => assert_eq!((came_at, recovered), (2, 3)),
            lockstep => panic!("{lockstep:?}"),
        }
        assert_eq!(done.rows, [2, 3, 4, 5, 6]);
    }
}
