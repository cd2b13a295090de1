//! The recorder's Zenoh shell: the world's record of each tick (lockstep), or every state and
//! command (realtime), and every end, loss and exit report of a mission, fed to core's `Recorder`
//! (lockstep), which hands complete ticks to `telemetry.csv` in order, or to its `Sampler`
//! (realtime), which a metronome samples once a period on the fleet's clock.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use tcpf_bus::clock::{check_clock, metronome, Beat, Expected, FleetClock};
use tcpf_bus::keys::{Keys, Role};
use tcpf_bus::typed::{answered, await_clock, presence, present, subscribe_as, ClockAnswer, Received, Rejected};
use tcpf_core::links::LinkStats;
use tcpf_core::metrics::Results;
use tcpf_core::mission::{ClockKind, Mission};
use tcpf_core::msg::{Command, End, Loss, LossReason, Report, State, TickRecord};
use tcpf_core::realtime::{Sampler, STATES_DUE_S};
use tcpf_core::record::Recorder;
use tcpf_core::watch::WorldWatch;
use tokio::sync::mpsc::{self, Receiver};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::Session;

use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_core::planner::Plan;

use crate::progress::Ticks;
use tcpf_report::rundir::{RunDir, Telemetry};
use tcpf_report::summary::{ChildSummary, Clock, Mode, Restarts, Summary, REALTIME};
use tcpf_report::table;

/// How long `tcpf record` waits, after the world's end (or after the world left without one),
/// for a tick that does not come whole.
const END_STALL: Duration = Duration::from_secs(5);
/// Messages the recorder may hold before the next are dropped (and counted): it writes what a
/// fleet sends, so it may lag behind a fast lockstep fleet by many ticks (one message each).
const INBOX: usize = 65_536;

/// What the recorder takes, in one channel.
enum Message {
    Tick(TickRecord<'static>),
    State(State),
    Command(Command),
    End(End),
    Loss(Loss),
    Report(Report),
}

impl Message {
    /// Sent by the world: what says it is still there.
    fn is_the_worlds(&self) -> bool {
        matches!(self, Message::Tick(_) | Message::State(_) | Message::End(_))
    }
}

/// Where in its period the realtime recorder samples: after the agents' commands of the period
/// (at half of it), before the world's next states.
const RECORDER_PHASE: f64 = 0.9;
/// How long `tcpf record` waits after the end for the roles' exit reports.
const REPORT_GRACE: Duration = Duration::from_secs(2);
/// How often the recorder asks for the clock before the world has started.
const CLOCK_POLL: Duration = Duration::from_millis(50);

enum Machine {
    Lockstep(Recorder),
    Realtime {
        sampler: Sampler,
        /// Once the world has started its clock: the fleet's clock here, and its beats.
        beats: Option<(FleetClock, Receiver<Beat>)>,
        control_period: f64,
    },
}

/// `tcpf record` stopped before it recorded a tick (its session did not open, no world came,
/// the world's clock refused it): the context of its error.
#[derive(Debug)]
pub struct NothingRecorded;

impl std::fmt::Display for NothingRecorded {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("nothing recorded")
    }
}

/// How a recorded run ended, and who ran it.
pub struct Closing {
    /// The run reached its end.
    pub ended: bool,
    pub interrupted: bool,
    /// What stopped the run before its end, if something failed.
    pub failure: Option<String>,
    pub wall_time_s: f64,
    pub children: Vec<ChildSummary>,
    pub restarts: Vec<Restarts>,
    /// What went wrong without failing the run (the planner gone once the fleet ran).
    pub warnings: Vec<String>,
}

pub struct Recording {
    pub rejected: Rejected,
    machine: Machine,
    session: Session,
    keys: Keys,
    telemetry: Telemetry,
    /// Every message, in the order it arrived: a state may not overtake the command of an
    /// earlier tick that came before it, or the recorder would refuse a genuine message as one
    /// too far ahead once it lags.
    inbox: Receiver<Received<Message>>,
    pub exit_reports: Vec<Report>,
    pub end: Option<End>,
    /// When the last tick was written.
    pub progress: Instant,
    /// When the first tick was written.
    first: Option<Instant>,
    _subscribers: Vec<Subscriber<()>>,
    /// Withdrawn once the recording is complete and every report it waits for is in: the world
    /// and the agents wait for the recorders to leave before they close their sessions.
    token: Option<LivelinessToken>,
    /// The mission's vehicles.
    ids: Vec<u32>,
    /// Messages taken from the world so far.
    pub from_world: u64,
    /// The world's clock, until it has answered (it does once the run has started).
    clock: Option<ClockAnswer>,
    /// Lockstep: the first tick record has come.
    ticking: bool,
    /// The mission, clock and time scale the world's clock must have.
    expected: Expected,
}

impl Recording {
    /// Subscribes to the mission. The world waits for the recorder's token: declare it with
    /// `declare` once the recorder is sure to hear everyone.
    pub async fn start(session: &Session, mission: &Mission, t_f: f64, telemetry: Telemetry) -> Result<Recording> {
        let keys = Keys::new(&mission.mission.name);
        let rejected = Rejected::default();
        let (tx, inbox) = mpsc::channel(INBOX);
        let mut subscribers = Vec::new();
        if mission.mission.clock == ClockKind::Lockstep {
            subscribers.push(subscribe_as(session, &keys.tick(), &rejected, tx.clone(), Message::Tick).await?);
        } else {
            subscribers.push(subscribe_as(session, &keys.state("*"), &rejected, tx.clone(), Message::State).await?);
            subscribers.push(subscribe_as(session, &keys.cmd("*"), &rejected, tx.clone(), Message::Command).await?);
        }
        subscribers.push(subscribe_as(session, &keys.end(), &rejected, tx.clone(), Message::End).await?);
        subscribers.push(subscribe_as(session, &keys.lost("*"), &rejected, tx.clone(), Message::Loss).await?);
        let reports = format!("tcpf/{}/report/**", mission.mission.name);
        subscribers.push(subscribe_as(session, &reports, &rejected, tx, Message::Report).await?);
        let ids: Vec<u32> = mission.vehicles.iter().map(|v| v.id).collect();
        let dt = mission.mission.control_period;
        let machine = match mission.mission.clock {
            ClockKind::Lockstep => Machine::Lockstep(Recorder::new(&ids, t_f, dt)),
            ClockKind::Realtime => Machine::Realtime {
                sampler: Sampler::new(&ids, &mission.graph(), t_f, dt),
                beats: None,
                control_period: dt,
            },
        };
        let clock = await_clock(session, &keys, &rejected, CLOCK_POLL, CLOCK_POLL);
        Ok(Recording {
            rejected,
            machine,
            session: session.clone(),
            keys,
            telemetry,
            inbox,
            exit_reports: Vec::new(),
            end: None,
            progress: Instant::now(),
            first: None,
            _subscribers: subscribers,
            token: None,
            ids,
            from_world: 0,
            clock: Some(clock),
            ticking: false,
            expected: Expected::of(mission),
        })
    }

    /// Declares the recorder's token: the world, which waits for it, may start. Its id is
    /// random: process ids repeat across hosts and containers, and the world counts recorders
    /// by their tokens.
    pub async fn declare(&mut self) -> Result<()> {
        use std::hash::{BuildHasher, Hasher};
        let id = std::collections::hash_map::RandomState::new().build_hasher().finish() as u32;
        let token = self
            .session
            .liveliness()
            .declare_token(self.keys.alive(Role::Record, id))
            .await
            .map_err(|e| anyhow!("liveliness token: {e}"))?;
        self.token = Some(token);
        Ok(())
    }

    fn take_report(&mut self, key: &str, report: Report) {
        if !keep_report(&mut self.exit_reports, &self.keys, key, report) {
            self.rejected.wrong_sender(key);
        }
    }

    /// Takes one message (or, in realtime, one beat of the clock), and writes every tick it
    /// completes.
    pub async fn step(&mut self) -> Result<()> {
        let before = self.ticks();
        match &mut self.machine {
            Machine::Lockstep(recorder) => tokio::select! {
                m = self.inbox.recv() => {
                    let Some(m) = m else {
                        return Err(anyhow!("the recorder's subscriptions closed"));
                    };
                    self.from_world += m.message.is_the_worlds() as u64;
                    match m.message {
                        Message::Tick(t) => {
                            if !std::mem::replace(&mut self.ticking, true) {
                                // The world waits for this recorder's token before its first
                                // tick: a first record of a later one is a run this recorder
                                // came to too late.
                                if t.tick > 0 {
                                    return Err(anyhow!(
                                        "recorder: the lockstep run was under way when this recorder came (the first tick it heard is {}): a lockstep recording starts at tick 0, so start the world with --recorders 1, which waits for it",
                                        t.tick
                                    ));
                                }
                                // The clock answers now: asked again at once rather than at the
                                // next poll, as ticks are held until it has.
                                if self.clock.is_some() {
                                    self.clock = Some(await_clock(&self.session, &self.keys, &self.rejected, CLOCK_POLL, CLOCK_POLL));
                                }
                            }
                            if let Err(why) = recorder.on_tick(t) {
                                self.rejected.reject(why, &m.key);
                            }
                        }
                        // A lockstep recorder takes states and commands from the tick record.
                        Message::State(_) | Message::Command(_) => {}
                        Message::End(e) => match recorder.on_end(e.clone()) {
                            Ok(()) => self.end = Some(e),
                            Err(why) => self.rejected.reject(why, &m.key),
                        },
                        Message::Report(r) => self.take_report(&m.key, r),
                        Message::Loss(l) => self.rejected.check(&m.key, l.id, || recorder.on_lost(l.into())),
                    }
                }
                // A realtime world would send no record: say so rather than wait for one.
                answer = answered(&mut self.clock), if self.clock.is_some() => {
                    self.clock = None;
                    check_clock("recorder", &self.expected, &answer?)?;
                }
            },
            Machine::Realtime {
                sampler,
                beats,
                control_period,
            } => tokio::select! {
                Some(beat) = async { beats.as_mut()?.1.recv().await }, if beats.is_some() => {
                    let mut failure = Ok(());
                    let telemetry = &mut self.telemetry;
                    sampler.sample(beat.tick, |states, commands| failure = telemetry.tick(states, commands));
                    failure?;
                    if let Some(ids) = sampler.overdue_states() {
                        tracing::warn!(
                            "recorder: no state of {} has come in {STATES_DUE_S} s of the run (simulated), so nothing is recorded (a row needs every vehicle's state): is the program that plays it running, with this mission and these Zenoh endpoints?",
                            table::vehicles(&ids)
                        );
                    }
                }
                answer = answered(&mut self.clock), if self.clock.is_some() => {
                    self.clock = None;
                    let clock = answer?;
                    check_clock("recorder", &self.expected, &clock)?;
                    self.telemetry.set_epoch(clock.epoch);
                    let fleet = FleetClock::new(&clock, *control_period);
                    *beats = Some((fleet, metronome(fleet, RECORDER_PHASE, fleet.periods_now().floor() as u64)));
                }
                // Messages wait for the clock, which says how far ahead of it they may be.
                Some(m) = self.inbox.recv(), if beats.is_some() => {
                    self.from_world += m.message.is_the_worlds() as u64;
                    let Some((fleet, _)) = beats else {
                        unreachable!("taken only once the clock is known")
                    };
                    let horizon = fleet.horizon();
                    match m.message {
                        Message::Tick(_) | Message::Loss(_) => {}
                        Message::State(s) => self.rejected.check(&m.key, s.id, || sampler.on_state(s, horizon)),
                        Message::Command(c) => self.rejected.check(&m.key, c.id, || sampler.on_command(c, horizon)),
                        Message::End(e) => match sampler.on_end(e.clone()) {
                            Ok(()) => self.end = Some(e),
                            Err(why) => self.rejected.reject(why, &m.key),
                        },
                        Message::Report(r) => self.take_report(&m.key, r),
                    }
                }
            },
        }
        let mut failure = Ok(());
        // Nothing is written before the world's clock says it runs this recorder's mission: one
        // of another would write ticks it is then refused for. (On a task of its own, the
        // question leaves this step free to be dropped by its caller's select without loss.)
        if let (Machine::Lockstep(recorder), None) = (&mut self.machine, &self.clock) {
            let telemetry = &mut self.telemetry;
            recorder.drain(|states, commands| {
                if failure.is_ok() {
                    failure = telemetry.tick(states, commands);
                }
            });
        }
        if self.ticks() > before {
            self.progress = Instant::now();
            self.first.get_or_insert(self.progress);
        }
        if self.complete() && self.unreported().is_empty() {
            if let Some(token) = self.token.take() {
                let _ = token.undeclare().await;
            }
        }
        failure
    }

    /// The world announced the end and every tick up to it is written.
    pub fn complete(&self) -> bool {
        match &self.machine {
            Machine::Lockstep(recorder) => recorder.complete(),
            Machine::Realtime { sampler, .. } => sampler.ended(),
        }
    }

    /// The vehicles lost so far: the world's end says, or before it, its losses.
    pub fn lost(&self) -> Vec<u32> {
        match (&self.end, &self.machine) {
            (Some(end), _) => end.lost.iter().map(|l| l.id).collect(),
            (None, Machine::Lockstep(recorder)) => recorder.losses().iter().map(|l| l.id).collect(),
            (None, Machine::Realtime { .. }) => Vec::new(),
        }
    }

    /// The roles whose exit report the end calls for and has not come.
    pub fn unreported(&self) -> Vec<(Role, u32)> {
        unreported(&self.ids, self.end.as_ref(), &self.exit_reports)
    }

    pub fn ticks(&self) -> u64 {
        match &self.machine {
            Machine::Lockstep(recorder) => recorder.ticks_recorded(),
            Machine::Realtime { sampler, .. } => sampler.ticks_recorded(),
        }
    }

    /// The last tick the world was heard of: in realtime, its newest state (the recorder's
    /// periods go on without it); in lockstep, the ticks recorded.
    pub fn world_ticks(&self) -> u64 {
        match &self.machine {
            Machine::Lockstep(recorder) => recorder.ticks_recorded(),
            Machine::Realtime { sampler, .. } => sampler.newest_state().unwrap_or(0),
        }
    }

    /// Mean wall time of a tick in steady state, from the first tick written to the last.
    pub fn tick_wall_time(&self) -> Option<f64> {
        let first = self.first?;
        let ticks = self.ticks();
        (ticks > 1).then(|| (self.progress - first).as_secs_f64() / (ticks - 1) as f64)
    }

    pub fn results(&self) -> Results {
        match &self.machine {
            Machine::Lockstep(recorder) => recorder.results(),
            Machine::Realtime { sampler, .. } => sampler.results(),
        }
    }

    /// Ends the recording: flushes telemetry.csv and writes summary.json and report.html.
    pub fn close(mut self, mission: &Mission, dir: &RunDir, how: Closing) -> Result<Summary> {
        let Closing {
            ended,
            interrupted,
            mut failure,
            wall_time_s,
            children,
            restarts,
            warnings,
        } = how;
        // Cut short by a signal or by what stopped it: its roles may not have reported.
        let cut_short = interrupted || failure.is_some();
        if let Machine::Realtime { sampler, .. } = &mut self.machine {
            let mut written = Ok(());
            let telemetry = &mut self.telemetry;
            sampler.finish(|states, commands| written = telemetry.tick(states, commands));
            written?;
            let missing = sampler.never_heard();
            if !missing.is_empty() && !cut_short {
                failure = Some(format!(
                    "no state of {} ever came, so the telemetry has no row (a row needs every vehicle's state)",
                    table::vehicles(&missing)
                ));
            }
        }
        if let Machine::Lockstep(recorder) = &self.machine {
            if let Some((ticks, _)) = recorder.contradicted_end() {
                failure.get_or_insert(format!(
                    "the end announced after tick {} was contradicted: the fleet's messages of later ticks kept coming (a process on the bus spoke for the world?); the recording stops there",
                    ticks.saturating_sub(1)
                ));
            }
        }
        let mut results = self.results();
        for r in self.exit_reports.iter().filter(|r| r.role == Role::Agent.as_str()) {
            for &(from, n) in &r.late_gammas {
                match results.links.iter_mut().find(|l| (l.from, l.to) == (from, r.id)) {
                    Some(link) => link.unused += n,
                    None => results.links.push(LinkStats {
                        from,
                        to: r.id,
                        sent: 0,
                        delivered: 0,
                        dropped: 0,
                        unused: n,
                        published: None,
                        overtaken: None,
                    }),
                }
            }
        }
        let realtime = mission.mission.clock == ClockKind::Realtime;
        if realtime {
            // The metrics count the periods this recorder sampled; the run lasted the world's
            // ticks: as many as its end says, or, without one, to its newest state.
            if let Machine::Realtime { sampler, .. } = &self.machine {
                results.ticks = self
                    .end
                    .as_ref()
                    .map_or_else(|| sampler.newest_state().map_or(0, |k| k + 1), |end| end.ticks);
            }
            // What each sender published, against what reached its receivers (judged at an
            // instant, or overtaken before one): the network's own loss. An agent started again
            // reports once per life.
            let agent = |id: u32| {
                let mut reports = self
                    .exit_reports
                    .iter()
                    .filter(move |r| r.role == Role::Agent.as_str() && r.id == id)
                    .peekable();
                reports.peek().is_some().then_some(reports)
            };
            for v in results.vehicles.iter_mut() {
                let lives = 1 + restarts
                    .iter()
                    .filter(|r| r.id == v.id)
                    .map(|r| r.restarts)
                    .sum::<u64>();
                if let Some(reports) = agent(v.id) {
                    v.gamma_sent = broadcasts(v.gamma_sent, lives, reports.map(|r| r.published));
                }
            }
            for link in results.links.iter_mut() {
                link.published = agent(link.from).map(|r| r.map(|r| r.published).sum());
                link.overtaken = agent(link.to).map(|r| {
                    r.filter_map(|r| r.timing.as_ref())
                        .flat_map(|t| &t.overtaken)
                        .filter(|o| o.0 == link.from)
                        .map(|o| o.1)
                        .sum()
                });
            }
        }
        let mut reproducible_reasons = Summary::irreproducible_because(&self.exit_reports);
        let conflicts = self.rejected.totals().conflict;
        if conflicts > 0 {
            reproducible_reasons.push(tcpf_report::summary::conflicting("the recorder", conflicts));
        }
        let unreported = match (cut_short, children.is_empty()) {
            (false, _) => self.unreported(),
            // `tcpf record` interrupted: the fleet goes on, and its reports are yet to come.
            (true, true) => Vec::new(),
            // `tcpf run` interrupted stopped its children: one that did not report was killed.
            (true, false) => silent_children(&children, &self.lost()),
        };
        for &(role, id) in &unreported {
            tracing::warn!(
                "recorder: no exit report from {role} {id}: its refusals, timing and γ counts are not in the summary"
            );
            // Before the first tick there is nothing it could have done otherwise.
            if role == Role::Agent && !realtime && self.ticks() > 0 {
                reproducible_reasons.push(format!(
                    "agent {id} sent no exit report: whether it went on without a silent neighbour's γ is unknown"
                ));
            }
        }
        if realtime {
            reproducible_reasons.push(REALTIME.into());
            // An agent's commands are stamped by its clock, so each is fresher than the one
            // before, and a restarted agent's by the same clock: none is ever older than the one
            // the world holds, nor two different ones stamped alike. Some were: another process
            // commanded a vehicle, ahead of the clock, and the vehicle followed it instead of its
            // agent.
            let (past, conflict) = self
                .exit_reports
                .iter()
                .filter(|r| r.role == Role::World.as_str())
                .fold((0, 0), |(p, c), r| (p + r.rejected.past, c + r.rejected.conflict));
            if past + conflict > 0 {
                failure.get_or_insert(format!(
                    "the world refused {past} command(s) as older than one it held and {conflict} as another for a tick it had: two processes commanded a vehicle, and the one stamping ahead of the clock steered it (a process on the bus spoke for an agent?)"
                ));
            }
        } else {
            // When the world gives up on an agent is a matter of wall-clock time (its command
            // timeout, or when the agent's process died), which the in-process run knows nothing of.
            for v in results.vehicles.iter().filter(|v| v.lost) {
                let why = match v.lost_reason {
                    Some(LossReason::Silent) => "no command within the world's --command-timeout",
                    _ => "its agent's process went away",
                };
                reproducible_reasons.push(format!("vehicle {} was lost ({why})", v.id));
            }
        }
        reproducible_reasons.extend(
            restarts
                .iter()
                .map(|r| format!("agent {} was started again {} time(s)", r.id, r.restarts)),
        );
        // A role that ended badly while the run went on to its end (stopped by a signal, or an
        // error) leaves a run that did not go as it should: named, it is the run's failure.
        if failure.is_none() && !cut_short {
            let badly = ended_badly(&children, &self.lost(), Summary::all_arrived(&results));
            failure = (!badly.is_empty()).then(|| badly.join("; "));
        }
        let mut rejections = self.rejected.totals();
        self.exit_reports.iter().for_each(|r| rejections.add(&r.rejected));
        let mut summary = Summary {
            mission: mission.mission.name.clone(),
            seed: mission.mission.seed,
            mode: Mode::Processes,
            clock: if realtime { Clock::Realtime } else { Clock::Lockstep },
            completed: ended && failure.is_none() && Summary::all_arrived(&results),
            interrupted,
            failure,
            reproducible: reproducible_reasons.is_empty(),
            reproducible_reasons,
            sim_time_s: results.ticks as f64 * mission.mission.control_period,
            tick_wall_time_us: 1e6
                * self
                    .tick_wall_time()
                    .unwrap_or(if self.ticks() > 0 { wall_time_s } else { 0.0 }),
            results,
            wall_time_s,
            rejected_messages: rejections.total(),
            rejections,
            children,
            time_scale: realtime.then_some(mission.mission.time_scale),
            timing: Summary::timing_of(&self.exit_reports),
            restarts,
            unreported: unreported.iter().map(|(role, id)| format!("{role} {id}")).collect(),
            coordination_gain: Some(tcpf_core::agent::CoordinationGain::of(mission)),
            warnings,
        };
        summary.name_the_shortfall();
        // The summary first: a run directory whose telemetry could not be finished still says
        // how the run went.
        dir.write_summary(&summary)?;
        self.telemetry.finish()?;
        tcpf_report::report::write(&dir.path)?;
        Ok(summary)
    }
}

/// `tcpf record`: records a fleet started elsewhere (start the world with `--recorders 1`) until
/// the world's end or a signal, and writes the run directory.
pub async fn record(
    mission: &Mission,
    plan: &Plan,
    dir: &RunDir,
    zenoh: &ZenohArgs,
    live: Option<SocketAddr>,
    startup_timeout: Duration,
) -> Result<Summary> {
    let mut shutdown = Shutdown::new()?;
    dir.write_mission(mission)?;
    dir.write_plan(plan)?;
    let unrecorded = |e: anyhow::Error| e.context(NothingRecorded);
    let session = zenoh
        .open_unless(&mut shutdown, startup_timeout)
        .await
        .map_err(unrecorded)?;
    let mut recording = Recording::start(
        &session,
        mission,
        plan.t_f,
        dir.telemetry(mission, plan, Mode::Processes, live)?,
    )
    .await
    .map_err(unrecorded)?;
    let keys = Keys::new(&mission.mission.name);
    let (_presence, mut presence) = presence(&session, &keys).await.map_err(unrecorded)?;
    recording.declare().await.map_err(unrecorded)?;
    let progress = Ticks::new(mission);
    let started = Instant::now();
    // A world that dies says no end: without this the recording would wait for it forever.
    let mut world = WorldWatch::new(0.0);
    let now = || started.elapsed().as_secs_f64();
    let instant = |s: f64| started + Duration::from_secs_f64(s);
    let mut from_world = recording.from_world;
    // Who is present, asked on a task of its own while the recording goes on.
    let mut asking: Option<tokio::task::JoinHandle<Option<bool>>> = None;
    // Nor would one that never comes (another mission name, endpoint or credential).
    let give_up_at = started + startup_timeout;
    let realtime = mission.mission.clock == ClockKind::Realtime;
    let mut failure = None;
    let interrupted = loop {
        if recording.complete() {
            break false;
        }
        // When to give up: END_STALL without a tick after the end or after the world left; a
        // realtime recording goes on sampling without a world, so there only its absence counts.
        let stall_at = match world.left() {
            Some(left) if realtime => Some(instant(left) + END_STALL),
            left => (recording.end.is_some() || left.is_some()).then(|| recording.progress + END_STALL),
        };
        let ask_at = world.ask_at().filter(|_| asking.is_none()).map(instant);
        tokio::select! {
            r = recording.step() => {
                if let Err(e) = r {
                    if recording.ticks() == 0 {
                        return Err(unrecorded(e));
                    }
                    tracing::error!("recorder: {e:#}; writing what was recorded");
                    failure = Some(format!("the recorder failed: {e:#}"));
                    break false;
                }
                progress.set(recording.ticks());
                if recording.from_world > from_world {
                    from_world = recording.from_world;
                    world.heard(now());
                }
            }
            _ = shutdown.recv() => break true,
            Some(p) = presence.recv() => {
                if p.role == Role::World {
                    world.on_presence(p.alive, now());
                }
            }
            _ = tokio::time::sleep_until(ask_at.unwrap_or_else(Instant::now).into()), if ask_at.is_some() => {
                let (session, keys) = (session.clone(), keys.clone());
                asking = Some(tokio::spawn(async move {
                    match present(&session, &keys).await {
                        Ok(present) => Some(present.iter().any(|(role, _)| *role == Role::World)),
                        Err(e) => {
                            tracing::warn!("recorder: {e}");
                            None
                        }
                    }
                }));
            }
            answer = async { asking.as_mut().expect("asked").await }, if asking.is_some() => {
                asking = None;
                world.on_answer(answer.ok().flatten(), now());
                if world.left().is_some() {
                    tracing::warn!("recorder: the world's token is gone, though its leaving was never seen");
                }
            }
            _ = tokio::time::sleep_until(give_up_at.into()), if !world.seen() => {
                return Err(unrecorded(anyhow!(
                    "recorder: no world of mission {} within {startup_timeout:?}: is it started, with the same Zenoh endpoints (-e) and credentials as this recorder?",
                    mission.mission.name
                )));
            }
            _ = tokio::time::sleep_until(stall_at.unwrap_or_else(Instant::now).into()), if stall_at.is_some() => {
                let why = match recording.end {
                    Some(_) => format!(
                        "the world has ended, but tick {} never came whole here (a state or command of it did not reach the recorder)",
                        recording.ticks()
                    ),
                    None => format!(
                        "the world left without announcing the end, after tick {}",
                        recording.world_ticks()
                    ),
                };
                tracing::error!("recorder: {why}; writing what was recorded");
                failure = Some(why);
                break false;
            }
        }
    };
    if let Some(question) = asking {
        question.abort();
    }
    progress.finish();
    let wall_time_s = started.elapsed().as_secs_f64();
    // The world and the agents report as they exit, just after the end: a moment for them.
    let _ = tokio::time::timeout(REPORT_GRACE, async {
        while !interrupted && !recording.unreported().is_empty() {
            if recording.step().await.is_err() {
                break;
            }
        }
    })
    .await;
    let _ = session.close().await;
    let ended = !interrupted && recording.end.is_some();
    recording.close(
        mission,
        dir,
        Closing {
            ended,
            interrupted,
            failure,
            wall_time_s,
            children: Vec::new(),
            restarts: Vec::new(),
            warnings: Vec::new(),
        },
    )
}

/// A realtime vehicle's γ broadcasts, from what the neighbours' sampled commands show (`sampled`:
/// a row merges the broadcasts since the one before, so fewer) and what each life of its agent
/// that reported says it published: theirs, if all `lives` reported, else at least the sampled.
fn broadcasts(sampled: u64, lives: u64, published: impl Iterator<Item = u64>) -> u64 {
    let (told, published) = published.fold((0, 0), |(n, sum), p| (n + 1, sum + p));
    if told == lives {
        published
    } else {
        sampled.max(published)
    }
}

/// Keeps a process's exit report if its key names the role and id its body does (false if
/// not); the same process's report again replaces the first, so its counts are not summed twice.
fn keep_report(reports: &mut Vec<Report>, keys: &Keys, key: &str, report: Report) -> bool {
    if Role::parse(&report.role)
        .map(|role| keys.report(role, report.id))
        .as_deref()
        != Some(key)
    {
        return false;
    }
    let same = |r: &&mut Report| (&r.role, r.id, r.pid) == (&report.role, report.id, report.pid);
    match reports.iter_mut().find(same) {
        Some(r) => *r = report,
        None => reports.push(report),
    }
    true
}

/// After `tcpf run` was interrupted: the world and every agent not lost whose last life sent no
/// exit report (an earlier life of an agent started again died, and sends none).
/// The roles whose last life ended otherwise than with code 0, in words ("agent 2 exited with
/// code 130 (stopped by a signal)"), but for processes killed outright (SIGKILL: what `tcpf run`
/// does to a role that would not stop; a killed world fails the run and a killed agent loses its
/// vehicle already) and the agents of lost vehicles that exited as told (the world gave up on
/// them: their loss says it), unless a signal stopped them; nor the world's code 1 when not every
/// vehicle `arrived`, which is how it says so (the summary says which did not).
fn ended_badly(children: &[ChildSummary], lost: &[u32], arrived: bool) -> Vec<String> {
    let by_signal = |c: &ChildSummary| c.exit_code == Some(130) || c.exit_code.is_none();
    let world = Role::World.as_str();
    children
        .iter()
        .enumerate()
        .filter(|(k, c)| children[k + 1..].iter().all(|o| (&o.role, o.id) != (&c.role, c.id)))
        .map(|(_, c)| c)
        .filter(|c| c.exit_code != Some(0) && c.signal != Some(libc::SIGKILL))
        .filter(|c| !(c.role == Role::Agent.as_str() && lost.contains(&c.id)) || by_signal(c))
        .filter(|c| !(c.role == world && c.exit_code == Some(1) && !arrived))
        // Gone once the fleet ran, the planner is a warning (`Closing::warnings`), not a failure.
        .filter(|c| c.role != Role::Planner.as_str())
        .map(|c| {
            let (who, log) = match Role::parse(&c.role) {
                Some(Role::Agent) => (format!("agent {}", c.id), format!("agent-{}", c.id)),
                _ => (format!("the {}", c.role), c.role.clone()),
            };
            let how = match (c.exit_code, c.signal) {
                (Some(130), _) => "with code 130 (stopped by a signal)".to_string(),
                (Some(code), _) => format!("with code {code}"),
                (None, Some(signal)) => format!("killed by signal {signal}"),
                (None, None) => "without an exit code".to_string(),
            };
            format!("{who} exited {how}; see logs/{log}.log")
        })
        .collect()
}

fn silent_children(children: &[ChildSummary], lost: &[u32]) -> Vec<(Role, u32)> {
    children
        .iter()
        .enumerate()
        .filter(|(k, c)| children[k + 1..].iter().all(|o| (&o.role, o.id) != (&c.role, c.id)))
        .filter(|(_, c)| c.reported_pid.is_none())
        .filter_map(|(_, c)| match Role::parse(&c.role)? {
            Role::World => Some((Role::World, c.id)),
            Role::Agent if !lost.contains(&c.id) => Some((Role::Agent, c.id)),
            _ => None,
        })
        .collect()
}

/// Of a mission of vehicles `ids`, the roles whose exit report `end` calls for and that are not
/// among `reports`: the world, and the agent of every vehicle the world did not give up on (an
/// agent started again reports once per life; any one will do). None before the end.
fn unreported(ids: &[u32], end: Option<&End>, reports: &[Report]) -> Vec<(Role, u32)> {
    let Some(end) = end else {
        return Vec::new();
    };
    let agents = ids.iter().filter(|&&id| end.lost.iter().all(|l| l.id != id));
    std::iter::once((Role::World, 0))
        .chain(agents.map(|&id| (Role::Agent, id)))
        .filter(|&(role, id)| !reports.iter().any(|r| r.role == role.as_str() && r.id == id))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use tcpf_core::msg::{LossReason, Lost, PROTOCOL_VERSION};

    fn report(role: Role, id: u32) -> Report {
        Report {
            version: PROTOCOL_VERSION,
            role: role.as_str().into(),
            id,
            pid: 1,
            rejected: Default::default(),
            stale_timeouts: 0,
            late_gammas: vec![],
            timing: None,
            published: 0,
        }
    }

    #[test]
    fn the_end_calls_for_the_worlds_report_and_every_live_agents() {
        let end = End {
            version: PROTOCOL_VERSION,
            ticks: 100,
            lost: vec![Lost {
                id: 3,
                tick: 50,
                reason: LossReason::Gone,
            }],
        };
        assert_eq!(unreported(&[1, 2, 3], None, &[]), vec![], "nothing before the end");
        assert_eq!(
            unreported(
                &[1, 2, 3],
                Some(&end),
                &[report(Role::Planner, 0), report(Role::Agent, 2)]
            ),
            vec![(Role::World, 0), (Role::Agent, 1)],
            "the planner's report is not waited for, nor a lost vehicle's agent's"
        );
        let all = [report(Role::Agent, 1), report(Role::World, 0), report(Role::Agent, 2)];
        assert_eq!(unreported(&[1, 2, 3], Some(&end), &all), vec![]);
    }

    #[test]
    fn an_interrupted_run_names_the_children_killed_before_they_reported() {
        let child = |role: Role, id: u32, reported: bool| ChildSummary {
            role: role.as_str().into(),
            id,
            pid: 10 + id,
            exit_code: None,
            signal: None,
            rejected: reported.then_some(0),
            reported_pid: reported.then_some(10 + id),
        };
        let children = [
            child(Role::Planner, 0, false),
            child(Role::World, 0, true),
            child(Role::Agent, 1, false),
            child(Role::Agent, 2, false),
            child(Role::Agent, 3, false),
            child(Role::Agent, 3, true),
            child(Role::Agent, 4, false),
        ];
        assert_eq!(
            silent_children(&children, &[4]),
            vec![(Role::Agent, 1), (Role::Agent, 2)],
            "not the planner, not a life before the last, not a lost vehicle's agent"
        );
    }

    #[test]
    fn broadcasts_are_the_agents_own_count_when_every_life_reported() {
        assert_eq!(broadcasts(547, 1, [556].into_iter()), 556);
        assert_eq!(broadcasts(547, 2, [300, 256].into_iter()), 556);
        assert_eq!(
            broadcasts(547, 2, [256].into_iter()),
            547,
            "a life that died told nothing"
        );
        assert_eq!(broadcasts(100, 2, [256].into_iter()), 256);
    }

    #[test]
    fn a_report_is_kept_once_and_only_under_its_own_key() {
        let mut kept = Vec::new();
        let keys = Keys::new("m");
        let mut twice = report(Role::Agent, 2);
        assert!(keep_report(&mut kept, &keys, "tcpf/m/report/agent/2", twice.clone()));
        twice.stale_timeouts = 3;
        assert!(keep_report(&mut kept, &keys, "tcpf/m/report/agent/2", twice.clone()));
        assert_eq!(kept.len(), 1, "the same process again replaces its report");
        assert_eq!(kept[0].stale_timeouts, 3);
        assert!(!keep_report(&mut kept, &keys, "tcpf/m/report/agent/3", twice.clone()));
        assert!(!keep_report(&mut kept, &keys, "tcpf/m/report/world/2", twice.clone()));
        assert!(!keep_report(&mut kept, &keys, "tcpf/x/report/agent/2", twice.clone()));
        assert!(!keep_report(
            &mut kept,
            &keys,
            "tcpf/m/report/x/report/agent/2",
            twice.clone()
        ));
        twice.pid = 2;
        assert!(keep_report(&mut kept, &keys, "tcpf/m/report/agent/2", twice));
        assert_eq!(kept.len(), 2, "an agent started again reports as another process");
    }
}
