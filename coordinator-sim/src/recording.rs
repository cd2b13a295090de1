//! The recorder's Zenoh shell: the world's record of each tick (lockstep), or every state and
//! command (realtime), and every end, loss and exit report of a mission, fed to core's `Recorder`
//! (lockstep), which hands complete ticks to `telemetry.csv` in order, or to its `Sampler`
//! (realtime), which writes every tick the world ran, in order, asking the world's history for
//! the states that never came.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use tcpf_bus::clock::{check_clock, unix_now, Expected, FleetClock, Monotonic};
use tcpf_bus::clock_query::{answered, await_clock, ClockAnswer, ClockBell};
use tcpf_bus::handover::{take_over, take_over_held, Ack};
use tcpf_bus::history;
use tcpf_bus::keys::{Keys, Role};
use tcpf_bus::presence::{presence, present};
use tcpf_bus::rejected::Rejected;
use tcpf_bus::subscribe::{subscribe_as, Received};
use tcpf_core::fleet::watch::{Due, RecorderWaits};
use tcpf_core::mission::{ClockKind, Mission, Ros2Config};
use tcpf_core::msg::{Clock, Command, End, Loss, Report, State, TickRecord};
use tcpf_core::outputs::metrics::Results;
use tcpf_core::roles::lockstep::Reject;
use tcpf_core::roles::realtime::{Sampler, STATES_DUE_S};
use tcpf_core::roles::record::Recorder;
use tokio::sync::mpsc::{self, Receiver, Sender};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::query::Queryable;
use zenoh::Session;

use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_core::model::path::GeneralizedPath;
use tcpf_core::model::planner::Plan;
use tcpf_core::outputs::ros2::Stamp;

use crate::progress::Ticks;
use tcpf_core::outputs::summary::{self, Closing, Mode, Recorded, Summary};
use tcpf_core::time::UnixTime;
use tcpf_report::rundir::{RunDir, Telemetry};

/// Messages the recorder may hold before the next are dropped (and counted): it writes what a
/// fleet sends, so it may lag behind a fast lockstep fleet by many ticks (one message each).
const INBOX: usize = 65_536;

/// What the recorder takes, in one channel.
enum Message {
    Tick(TickRecord<'static>),
    State(State),
    Command(Command),
    /// The end, with the acknowledgement the world waits for: sent once every tick before it
    /// is in, from the world's history if need be.
    End(End, Ack),
    Loss(Loss),
    Report(Box<Report>),
    /// Realtime: a state the world's history gave, and the end of its answer (the vehicles it
    /// keeps none of).
    History(State),
    Fetched(Vec<u32>),
}

impl Message {
    /// Sent by the world: what says it is still there.
    fn is_the_worlds(&self) -> bool {
        matches!(
            self,
            Message::Tick(_) | Message::State(_) | Message::End(..) | Message::History(_)
        )
    }
}
/// How long `tcpf record` waits after the end for the roles' exit reports.
const REPORT_GRACE: Duration = Duration::from_secs(2);

/// Each machine boxed: both are large (their metrics), and a recording holds one.
enum Machine {
    Lockstep(Box<Recorder>),
    Realtime {
        sampler: Box<Sampler>,
        /// Once the world has started its clock: the fleet's clock here.
        fleet: Option<FleetClock>,
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
    /// Where the world's history answers, into the inbox.
    answers: Sender<Received<Message>>,
    pub exit_reports: Vec<Report>,
    pub end: Option<End>,
    /// When the last tick was written.
    pub progress: Instant,
    /// When the first tick was written.
    first: Option<Instant>,
    _subscribers: Vec<Subscriber<()>>,
    _queryables: Vec<Queryable<()>>,
    /// The end's acknowledgements, until the recording has every tick before it.
    held: Vec<Ack>,
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
    /// `tcpf record --ros2`: the fleet as a ROS 2 node, for a world that does not speak it.
    ros2: Option<Speaking>,
    /// When every subscription was in place, on the wall clock: what the world published since,
    /// this recorder heard (or may fetch).
    subscribed: UnixTime,
}

/// What `tcpf record --ros2` publishes of each tick it writes, as the node `recorder`: what a
/// world with `--ros2` would, so that ROS 2 tools see a fleet started without it.
struct Speaking {
    node: tcpf_bus::ros2::World,
    paths: Vec<(u32, GeneralizedPath)>,
    /// Realtime: the fleet's clock, once it has answered; lockstep: none, stamps are simulated
    /// time.
    clock: Option<Clock>,
}

impl Speaking {
    fn put_paths(&mut self) -> Result<()> {
        let clock = self.clock;
        self.node.put_paths(&self.paths, |t| Stamp::of(clock.as_ref(), t))
    }
}

/// Writes a tick of the telemetry and, with `--ros2`, publishes it.
fn write_tick(
    telemetry: &mut Telemetry,
    ros2: &mut Option<Speaking>,
    states: &[State],
    commands: &[Option<Command>],
) -> Result<()> {
    telemetry.tick(states, commands)?;
    match ros2 {
        Some(r) => {
            let stamp = Stamp::of(r.clock.as_ref(), states[0].t);
            r.node
                .put(states.iter().zip(commands).map(|(s, c)| (s, c.as_ref())), stamp)
        }
        None => Ok(()),
    }
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
            // A loss as the world announces it, in order with its ticks: its hand-over, on a task
            // of the world's own, can come after the records of hundreds of ticks that no longer
            // wait for the lost vehicle (a loaded machine: 256 of them, the recorder's window, and
            // every later tick was refused as too far ahead). The hand-over, which this recorder
            // acknowledges, repeats it.
            subscribers.push(subscribe_as(session, &keys.lost("*"), &rejected, tx.clone(), Message::Loss).await?);
        } else {
            subscribers.push(subscribe_as(session, &keys.state("*"), &rejected, tx.clone(), Message::State).await?);
            subscribers.push(subscribe_as(session, &keys.cmd("*"), &rejected, tx.clone(), Message::Command).await?);
        }
        // The roles' last words come as hand-overs, which this recorder acknowledges.
        let queryables = vec![
            take_over_held(session, &keys.end(), &rejected, tx.clone(), Message::End).await?,
            take_over(session, &keys.lost("*"), &rejected, tx.clone(), Message::Loss).await?,
            take_over(session, &keys.reports(), &rejected, tx.clone(), |r| {
                Message::Report(Box::new(r))
            })
            .await?,
        ];
        let ids: Vec<u32> = mission.vehicles.iter().map(|v| v.id).collect();
        let dt = mission.mission.control_period;
        let machine = match mission.mission.clock {
            ClockKind::Lockstep => Machine::Lockstep(Box::new(Recorder::new(&ids, t_f, dt).with_faults(mission))),
            ClockKind::Realtime => Machine::Realtime {
                sampler: Box::new(Sampler::new(&ids, &mission.graph(), t_f, dt).with_faults(mission)),
                fleet: None,
                control_period: dt,
            },
        };
        // Before the recorder's token, which the world waits for: its announcement that it has
        // started cannot pass by unheard.
        let clock = await_clock(session, &keys, &rejected, ClockBell::declare(session, &keys).await?);
        Ok(Recording {
            rejected,
            machine,
            session: session.clone(),
            keys,
            telemetry,
            inbox,
            answers: tx,
            exit_reports: Vec::new(),
            end: None,
            progress: Instant::now(),
            first: None,
            _subscribers: subscribers,
            _queryables: queryables,
            held: Vec::new(),
            token: None,
            ids,
            from_world: 0,
            clock: Some(clock),
            ticking: false,
            expected: Expected::of(mission),
            ros2: None,
            subscribed: unix_now(),
        })
    }

    /// Speaks ROS 2 as the node `recorder` (`tcpf record --ros2`), before the recorder's token
    /// lets a lockstep world start: refused if the fleet's world speaks it already, as every
    /// topic would be published twice.
    pub async fn speak_ros2(&mut self, ros2: &Ros2Config, mission: &Mission, plan: &Plan) -> Result<()> {
        if tcpf_bus::ros2::node_present(&self.session, ros2, "world").await? {
            return Err(anyhow!(
                "the fleet's world speaks ROS 2 on domain {} already (its --ros2 or [ros2]): a recorder with --ros2 would publish every topic again; leave --ros2 out",
                ros2.domain
            ));
        }
        let lockstep = mission.mission.clock == ClockKind::Lockstep;
        let links = mission.directed_links();
        let fleet = tcpf_bus::ros2::Fleet {
            ids: &self.ids,
            simulated: &self.ids,
            links: &links,
            lockstep,
        };
        let node = tcpf_bus::ros2::World::declare(&self.session, ros2, &fleet, "recorder").await?;
        let mut speaking = Speaking {
            node,
            paths: plan.paths(),
            clock: None,
        };
        if lockstep {
            speaking.put_paths()?;
        }
        self.ros2 = Some(speaking);
        Ok(())
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

    /// Takes one message (or, in realtime, one beat of the clock), and writes every tick it
    /// completes.
    pub async fn step(&mut self) -> Result<()> {
        let before = self.ticks();
        match &mut self.machine {
            Machine::Lockstep(recorder) => tokio::select! {
                // Once the ticks have begun, the rest wait here until the clock answers: the
                // machine writes nothing before it, and its window of ticks (a few ms of a fast
                // fleet) would fill and refuse every later genuine tick as too far ahead.
                m = self.inbox.recv(), if !self.ticking || self.clock.is_none() => {
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
                                // The clock answers now: asked again at once, should its
                                // announcement be slower, as ticks are held until it has.
                                self.clock.iter().for_each(ClockAnswer::look_again);
                            }
                            if let Err(why) = recorder.on_tick(t) {
                                self.rejected.reject(why, &m.key);
                            }
                        }
                        // A lockstep recorder takes states and commands from the tick record.
                        Message::State(_) | Message::Command(_) | Message::History(_) | Message::Fetched(_) => {}
                        Message::End(e, ack) => take_end(&mut self.end, &mut self.held, &self.rejected, &m.key, (e, ack), |e| recorder.on_end(e)),
                        Message::Report(r) => take_report(&mut self.exit_reports, &self.keys, &self.rejected, &m.key, *r),
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
                fleet,
                control_period,
            } => tokio::select! {
                answer = answered(&mut self.clock), if self.clock.is_some() => {
                    self.clock = None;
                    let clock = answer?;
                    check_clock("recorder", &self.expected, &clock)?;
                    self.telemetry.set_clock(clock);
                    if let Some(ros2) = &mut self.ros2 {
                        ros2.clock = Some(clock);
                        ros2.put_paths()?;
                    }
                    // The tick under way when the subscriptions were in place, on the fleet's
                    // clock (never later than the one the clock's answer names).
                    let subscribed = (self.subscribed - clock.epoch) * clock.time_scale / *control_period;
                    sampler.start_at(clock.tick.min(subscribed.max(0.0) as u64));
                    *fleet = Some(FleetClock::new(&clock, *control_period));
                }
                // Messages wait for the clock, which says how far ahead of it they may be.
                Some(m) = self.inbox.recv(), if fleet.is_some() => {
                    self.from_world += m.message.is_the_worlds() as u64;
                    let Some(fleet) = fleet else {
                        unreachable!("taken only once the clock is known")
                    };
                    let horizon = fleet.horizon();
                    match m.message {
                        Message::Tick(_) | Message::Loss(_) => {}
                        Message::State(s) => self.rejected.check(&m.key, s.id, || sampler.on_state(s, horizon)),
                        Message::Command(c) => self.rejected.check(&m.key, c.id, || sampler.on_command(c, horizon)),
                        // On the history's key, which names no vehicle: the fetch says which.
                        Message::History(s) => {
                            if let Err(why) = sampler.on_history(s) {
                                self.rejected.reject(why, &m.key);
                            }
                        }
                        Message::Fetched(unkept) => sampler.on_fetched(&unkept),
                        Message::End(e, ack) => take_end(&mut self.end, &mut self.held, &self.rejected, &m.key, (e, ack), |e| sampler.on_end(e)),
                        Message::Report(r) => take_report(&mut self.exit_reports, &self.keys, &self.rejected, &m.key, *r),
                    }
                    let mut failure = Ok(());
                    let (telemetry, ros2) = (&mut self.telemetry, &mut self.ros2);
                    sampler.drain(|states, commands| {
                        if failure.is_ok() {
                            failure = write_tick(telemetry, ros2, states, commands);
                        }
                    });
                    failure?;
                    if let Some(fetch) = sampler.fetch() {
                        let answers = self.answers.clone();
                        history::ask(&self.session, &self.keys, fetch, &self.rejected, answers, Message::History, Message::Fetched);
                    }
                    if let Some(ids) = sampler.overdue_states() {
                        tracing::warn!(
                            "recorder: no state of {} has come in {STATES_DUE_S} s of the run (simulated), so nothing is recorded (a row needs every vehicle's state): is the program that plays it running, with this mission and these Zenoh endpoints?",
                            tcpf_core::outputs::summary::vehicles(&ids)
                        );
                    }
                }
            },
        }
        let mut failure = Ok(());
        // Nothing is written before the world's clock says it runs this recorder's mission: one
        // of another would write ticks it is then refused for. (On a task of its own, the
        // question leaves this step free to be dropped by its caller's select without loss.)
        if let (Machine::Lockstep(recorder), None) = (&mut self.machine, &self.clock) {
            let (telemetry, ros2) = (&mut self.telemetry, &mut self.ros2);
            recorder.drain(|states, commands| {
                if failure.is_ok() {
                    failure = write_tick(telemetry, ros2, states, commands);
                }
            });
        }
        if self.settled() {
            self.held.drain(..).for_each(Ack::send);
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
            // Not while the rows wait for the world's history.
            Machine::Realtime { sampler, .. } => sampler.ended() && !sampler.fetching(),
        }
    }

    /// Every tick before the end is in, or known lost: a lockstep recorder's came before the
    /// end; a realtime one's may wait for the world's history, which the world answers until it
    /// has the end's acknowledgement.
    fn settled(&self) -> bool {
        match &self.machine {
            Machine::Lockstep(_) => true,
            Machine::Realtime { sampler, .. } => !sampler.fetching(),
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
        summary::unreported(&self.ids, self.end.as_ref(), &self.exit_reports)
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

    /// When the first tick was written, if one was.
    pub fn first_tick(&self) -> Option<Instant> {
        self.first
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
        let recorded = match &mut self.machine {
            Machine::Realtime { sampler, .. } => {
                let mut written = Ok(());
                let (telemetry, ros2) = (&mut self.telemetry, &mut self.ros2);
                sampler.finish(|states, commands| written = write_tick(telemetry, ros2, states, commands));
                written?;
                Recorded::Realtime {
                    never_heard: sampler.never_heard(),
                    newest_state: sampler.newest_state(),
                    missing_ticks: sampler.missing_ticks(),
                    came_at: sampler.came_at().unwrap_or(0),
                    players_from: sampler.players_from().cloned(),
                    recovered: sampler.recovered(),
                }
            }
            Machine::Lockstep(recorder) => Recorded::Lockstep {
                contradicted_end: recorder.contradicted_end(),
            },
        };
        let summary = summary::of_recording(
            summary::Recording {
                mission,
                results: self.results(),
                recorded,
                reports: &self.exit_reports,
                end: self.end.as_ref(),
                lost: self.lost(),
                rejections: self.rejected.totals(),
                ticks_recorded: self.ticks(),
                tick_wall_time_s: self.tick_wall_time(),
            },
            how,
        );
        for who in &summary.unreported {
            tracing::warn!(
                "recorder: no exit report from {who}: its refusals, timing and γ counts are not in the summary"
            );
        }
        // The summary first: a run directory whose telemetry could not be finished still says
        // how the run went.
        dir.write_summary(&summary)?;
        self.telemetry.finish()?;
        tcpf_report::report::write(&dir.path, &tcpf_report::report::Options::default())?;
        Ok(summary)
    }
}

/// `tcpf record`: records a fleet started elsewhere (start the world with `--recorders 1`) until
/// the world's end or a signal, and writes the run directory.
/// How `tcpf record` records: `live` serves it to Foxglove, `ros2` to ROS 2 tools.
pub struct RecordOptions {
    pub live: Option<SocketAddr>,
    pub startup_timeout: Duration,
    pub ros2: Option<Ros2Config>,
}

pub async fn record(
    mission: &Mission,
    plan: &Plan,
    dir: &RunDir,
    zenoh: &ZenohArgs,
    options: RecordOptions,
) -> Result<Summary> {
    let RecordOptions {
        live,
        startup_timeout,
        ros2,
    } = options;
    let mut shutdown = Shutdown::new()?;
    dir.write_mission(mission, tcpf_core::outputs::summary::Mode::Processes)?;
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
        // The bag of a fleet that speaks ROS 2, by the mission's `[ros2]`, or by this recorder.
        dir.telemetry(
            mission,
            plan,
            Mode::Processes,
            live,
            ros2.as_ref().or(mission.ros2.as_ref()),
        )?,
    )
    .await
    .map_err(unrecorded)?;
    if let Some(ros2) = &ros2 {
        recording.speak_ros2(ros2, mission, plan).await.map_err(unrecorded)?;
    }
    let keys = Keys::new(&mission.mission.name);
    let (_presence, mut presence) = presence(&session, &keys).await.map_err(unrecorded)?;
    recording.declare().await.map_err(unrecorded)?;
    let progress = Ticks::new(mission);
    let clock = Monotonic::start();
    let realtime = mission.mission.clock == ClockKind::Realtime;
    // A world that dies says no end, and one may never come (another mission name, endpoint or
    // credential): without these waits the recording would wait for it forever.
    let mut waits = RecorderWaits::new(clock.now(), startup_timeout.as_secs_f64(), realtime);
    let (mut from_world, mut written) = (recording.from_world, 0);
    // Who is present, asked on a task of its own while the recording goes on.
    let mut asking: Option<tokio::task::JoinHandle<Option<bool>>> = None;
    let mut failure = None;
    let interrupted = loop {
        if recording.complete() {
            break false;
        }
        let woken_for = waits.poll_timeout();
        tokio::select! {
            r = recording.step() => {
                let ticks = recording.ticks();
                if let Err(e) = r {
                    if ticks == 0 {
                        return Err(unrecorded(e));
                    }
                    tracing::error!("recorder: {e:#}; writing what was recorded");
                    failure = Some(format!("the recorder failed: {e:#}"));
                    break false;
                }
                if ticks > written {
                    written = ticks;
                    waits.progressed(clock.now());
                }
                progress.set(ticks);
                if recording.from_world > from_world {
                    from_world = recording.from_world;
                    waits.heard(clock.now());
                }
                if recording.end.is_some() {
                    waits.ended();
                }
            }
            _ = shutdown.recv() => break true,
            Some(p) = presence.recv() => {
                if p.role == Role::World {
                    if p.alive && !waits.seen() {
                        tracing::info!("recorder: the world is here");
                    }
                    waits.on_presence(p.alive, clock.now());
                }
            }
            answer = async { asking.as_mut().expect("asked").await }, if asking.is_some() => {
                asking = None;
                waits.on_answer(answer.ok().flatten(), clock.now());
                if waits.left().is_some() {
                    tracing::warn!("recorder: the world's token is gone, though its leaving was never seen");
                }
            }
            _ = tokio::time::sleep_until(clock.at(woken_for.unwrap_or_default())), if woken_for.is_some() => {
                match waits.handle_timeout(clock.now()) {
                    None => {}
                    Some(Due::Ask) => {
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
                    Some(Due::NoWorld) => {
                        return Err(unrecorded(anyhow!(
                            "recorder: no world of mission {} within {startup_timeout:?}: is it started, with the same Zenoh endpoints (-e) and credentials as this recorder?",
                            mission.mission.name
                        )));
                    }
                    Some(Due::Stalled) => {
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
            }
        }
    };
    if let Some(question) = asking {
        question.abort();
    }
    progress.finish();
    let wall_time_s = clock.now().secs();
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
    let first_tick_s = recording.first_tick().map(|at| clock.since(at));
    recording.close(
        mission,
        dir,
        Closing {
            ended,
            interrupted,
            failure,
            wall_time_s,
            first_tick_s,
            children: Vec::new(),
            restarts: Vec::new(),
            warnings: Vec::new(),
        },
    )
}

/// Keeps a process's exit report if its key names the role and id its body does, else counts it
/// as from the wrong sender.
/// The world's end, kept once, its acknowledgement held for `settled`; the same end again (the
/// world asks again while the recorder fetches) is held too, not refused.
fn take_end(
    end: &mut Option<End>,
    held: &mut Vec<Ack>,
    rejected: &Rejected,
    key: &str,
    (e, ack): (End, Ack),
    take: impl FnOnce(End) -> Result<(), Reject>,
) {
    if end.as_ref() == Some(&e) {
        return held.push(ack);
    }
    match take(e.clone()) {
        Ok(()) => {
            *end = Some(e);
            held.push(ack);
        }
        Err(why) => rejected.reject(why, key),
    }
}

fn take_report(reports: &mut Vec<Report>, keys: &Keys, rejected: &Rejected, key: &str, report: Report) {
    if !keep_report(reports, keys, key, report) {
        rejected.wrong_sender(key);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_report_is_kept_once_and_only_under_its_own_key() {
        let mut kept = Vec::new();
        let keys = Keys::new("m");
        let mut twice = Report::new(Role::Agent, 2, 1);
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
