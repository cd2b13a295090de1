//! The recorder's Zenoh shell: the world's record of each tick (lockstep), or every state and
//! command (realtime), and every end, loss and exit report of a mission, checked for their
//! senders' keys and fed to core's `RecorderNode`, which writes every tick it completes, in
//! order, through the outlets here.

use std::convert::Infallible;
use std::net::SocketAddr;
use std::time::{Duration, Instant};

use tcpf_bus::clock::{check_clock, unix_now, Expected, FleetClock, Monotonic};
use tcpf_bus::clock_query::{answered, await_clock, ClockAnswer, ClockBell};
use tcpf_bus::driver::{drive, Wiring};
use tcpf_bus::handover::{take_over, take_over_held, Ack};
use tcpf_bus::history;
use tcpf_bus::keys::{Keys, Role};
use tcpf_bus::presence::{presence, present, Presence};
use tcpf_bus::rejected::Rejected;
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_bus::subscribe::{subscribe_as, Received};
use tcpf_bus::waits::Timeouts;
use tcpf_core::mission::{ClockKind, Mission, Ros2Config};
use tcpf_core::model::path::GeneralizedPath;
use tcpf_core::model::planner::Plan;
use tcpf_core::msg::Fetch;
use tcpf_core::msg::{Clock, Command, Loss, Report, State};
use tcpf_core::outputs::metrics::Results;
use tcpf_core::outputs::ros2::Stamp;
use tcpf_core::outputs::summary::{self, Closing, Mode, Summary};
use tcpf_core::roles::realtime::STATES_DUE_S;
use tcpf_core::roles::recorder_node::{Input, Io, RecorderNode, Refused};
use tcpf_core::roles::recorder_watch::{Input as WatchInput, Output as WatchOutput, RecorderWatch, Stop};
use tcpf_core::time::UnixTime;
use tcpf_report::rundir::{RunDir, Telemetry};
use tokio::sync::mpsc::{self, Receiver, Sender, UnboundedReceiver};
use tokio::task::JoinHandle;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::query::Queryable;
use zenoh::Session;

use crate::error::{failed, Error, Result};
use crate::progress::Ticks;

/// Messages the recorder may hold before the next are dropped (and counted): it writes what a
/// fleet sends, so it may lag behind a fast lockstep fleet by many ticks (one message each).
const INBOX: usize = 65_536;

/// `tcpf record` stopped before it recorded a tick, for `e`.
fn unrecorded(e: impl Into<Error>) -> Error {
    Error::NothingRecorded(Box::new(e.into()))
}

pub struct Recording {
    pub rejected: Rejected,
    node: RecorderNode<Ack>,
    outlets: Outlets,
    /// Every message, in the order it arrived: a state may not overtake the command of an
    /// earlier tick that came before it, or the recorder would refuse a genuine message as one
    /// too far ahead once it lags.
    inbox: Receiver<Received<Input<Ack>>>,
    _subscribers: Vec<Subscriber<()>>,
    _queryables: Vec<Queryable<()>>,
    /// Withdrawn once the node says so: the world and the agents wait for the recorders to
    /// leave before they close their sessions.
    token: Option<LivelinessToken>,
    /// The world's clock, until it has answered (it does once the run has started).
    clock: Option<ClockAnswer>,
    /// The mission, clock and time scale the world's clock must have.
    expected: Expected,
    /// When every subscription was in place, on the wall clock.
    subscribed: UnixTime,
    monotonic: Monotonic,
}

/// What the node's `Io` does here: the run directory's telemetry, ROS 2, the world's history.
struct Outlets {
    telemetry: Telemetry,
    /// `tcpf record --ros2`: the fleet as a ROS 2 node, for a world that does not speak it.
    ros2: Option<Speaking>,
    /// Realtime, once the world has started its clock: the fleet's clock here.
    fleet: Option<FleetClock>,
    session: Session,
    keys: Keys,
    rejected: Rejected,
    /// How long the world's history is waited for.
    history_fetch: Duration,
    /// Where the world's history answers, into the inbox.
    answers: Sender<Received<Input<Ack>>>,
    /// The first write that failed: the rest are not tried.
    failure: Result<()>,
    clock_due: bool,
    withdraw: bool,
}

impl Io<Ack> for Outlets {
    fn write(&mut self, states: &[State], commands: &[Option<Command>]) {
        if self.failure.is_ok() {
            self.failure = write_tick(&mut self.telemetry, &mut self.ros2, states, commands);
        }
    }

    fn horizon(&self) -> u64 {
        self.fleet.as_ref().map_or(0, FleetClock::horizon)
    }

    fn fetch(&mut self, fetch: Fetch) {
        history::ask(
            &self.session,
            &self.keys,
            fetch,
            self.history_fetch,
            &self.rejected,
            self.answers.clone(),
            history_answer,
        );
    }

    fn acknowledge(&mut self, ack: Ack) {
        ack.send();
    }

    fn clock_due(&mut self) {
        self.clock_due = true;
    }

    fn overdue(&mut self, ids: &[u32]) {
        tracing::warn!(
            "recorder: no state of {} has come in {STATES_DUE_S} s of the run (simulated), so nothing is recorded (a row needs every vehicle's state): is the program that plays it running, with this mission and these Zenoh endpoints?",
            summary::vehicles(ids)
        );
    }

    fn withdraw(&mut self) {
        self.withdraw = true;
    }
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
        Ok(self.node.put_paths(&self.paths, |t| Stamp::of(clock.as_ref(), t))?)
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
            let carried = states.iter().zip(commands).map(|(s, c)| (s, c.as_ref()));
            Ok(r.node.put(carried, stamp)?)
        }
        None => Ok(()),
    }
}

/// Whether a message came on the key of the sender it names: a vehicle's, or the role and id
/// of an exit report.
fn from_its_sender(message: &Input<Ack>, key: &str, keys: &Keys, rejected: &Rejected) -> bool {
    let id = match message {
        Input::State(s) => s.id,
        Input::Command(c) => c.id,
        Input::Loss(l) => l.id,
        Input::Report(r) => {
            let own = Role::parse(&r.role).map(|role| keys.report(role, r.id)).as_deref() == Some(key);
            if !own {
                rejected.wrong_sender(key);
            }
            return own;
        }
        Input::Tick(_) | Input::End(..) | Input::History(_) | Input::Fetched(_) => return true,
    };
    rejected.from_sender(key, id)
}

impl Recording {
    /// Subscribes to the mission. The world waits for the recorder's token: declare it with
    /// `declare` once the recorder is sure to hear everyone.
    pub async fn start(
        session: &Session,
        mission: &Mission,
        t_f: f64,
        telemetry: Telemetry,
        timeouts: &Timeouts,
    ) -> Result<Recording> {
        let keys = Keys::new(&mission.mission.name);
        let rejected = Rejected::default();
        let (tx, inbox) = mpsc::channel(INBOX);
        let mut subscribers = Vec::new();
        if mission.mission.clock == ClockKind::Lockstep {
            subscribers.push(subscribe_as(session, &keys.tick(), &rejected, tx.clone(), Input::Tick).await?);
            // A loss as the world announces it, in order with its ticks: its hand-over, on a task
            // of the world's own, can come after the records of hundreds of ticks that no longer
            // wait for the lost vehicle (a loaded machine: 256 of them, the recorder's window, and
            // every later tick was refused as too far ahead). The hand-over, which this recorder
            // acknowledges, repeats it.
            subscribers.push(subscribe_as(session, &keys.lost("*"), &rejected, tx.clone(), loss).await?);
        } else {
            subscribers.push(subscribe_as(session, &keys.state("*"), &rejected, tx.clone(), Input::State).await?);
            subscribers.push(subscribe_as(session, &keys.cmd("*"), &rejected, tx.clone(), Input::Command).await?);
        }
        // The roles' last words come as hand-overs, which this recorder acknowledges.
        let queryables = vec![
            take_over_held(session, &keys.end(), &rejected, tx.clone(), Input::End).await?,
            take_over(session, &keys.lost("*"), &rejected, tx.clone(), loss).await?,
            take_over(session, &keys.reports(), &rejected, tx.clone(), |r| {
                Input::Report(Box::new(r))
            })
            .await?,
        ];
        let monotonic = Monotonic::start();
        // Before the recorder's token, which the world waits for: its announcement that it has
        // started cannot pass by unheard.
        let clock = await_clock(
            session,
            &keys,
            &rejected,
            ClockBell::declare(session, &keys).await?,
            timeouts,
        );
        Ok(Recording {
            rejected: rejected.clone(),
            node: RecorderNode::new(mission, t_f, monotonic.now()),
            outlets: Outlets {
                telemetry,
                ros2: None,
                fleet: None,
                session: session.clone(),
                keys,
                rejected,
                history_fetch: timeouts.history_fetch,
                answers: tx,
                failure: Ok(()),
                clock_due: false,
                withdraw: false,
            },
            inbox,
            _subscribers: subscribers,
            _queryables: queryables,
            token: None,
            clock: Some(clock),
            expected: Expected::of(mission),
            subscribed: unix_now(),
            monotonic,
        })
    }

    /// Speaks ROS 2 as the node `recorder` (`tcpf record --ros2`), before the recorder's token
    /// lets a lockstep world start: refused if the fleet's world speaks it already, as every
    /// topic would be published twice.
    pub async fn speak_ros2(&mut self, ros2: &Ros2Config, mission: &Mission, plan: &Plan) -> Result<()> {
        let session = &self.outlets.session;
        if tcpf_bus::ros2::node_present(session, ros2, "world").await? {
            return Err(failed!(
                "the fleet's world speaks ROS 2 on domain {} already (its --ros2 or [ros2]): a recorder with --ros2 would publish every topic again; leave --ros2 out",
                ros2.domain
            )
            .into());
        }
        let lockstep = mission.mission.clock == ClockKind::Lockstep;
        let links = mission.directed_links();
        let ids: Vec<u32> = mission.vehicles.iter().map(|v| v.id).collect();
        let fleet = tcpf_bus::ros2::Fleet {
            ids: &ids,
            simulated: &ids,
            links: &links,
            lockstep,
        };
        let node = tcpf_bus::ros2::World::declare(session, ros2, &fleet, "recorder").await?;
        let mut speaking = Speaking {
            node,
            paths: plan.paths(),
            clock: None,
        };
        if lockstep {
            speaking.put_paths()?;
        }
        self.outlets.ros2 = Some(speaking);
        Ok(())
    }

    /// Declares the recorder's token: the world, which waits for it, may start. Its id is
    /// random: process ids repeat across hosts and containers, and the world counts recorders
    /// by their tokens.
    pub async fn declare(&mut self) -> Result<()> {
        use std::hash::{BuildHasher, Hasher};
        let id = std::collections::hash_map::RandomState::new().build_hasher().finish() as u32;
        let token = self
            .outlets
            .session
            .liveliness()
            .declare_token(self.outlets.keys.alive(Role::Record, id))
            .await
            .map_err(|e| failed!("liveliness token: {e}"))?;
        self.token = Some(token);
        Ok(())
    }

    /// Takes one message or the world's clock, and writes every tick it completes.
    pub async fn step(&mut self) -> Result<()> {
        tokio::select! {
            answer = answered(&mut self.clock), if self.clock.is_some() => {
                self.clock = None;
                let clock = answer?;
                check_clock("recorder", &self.expected, &clock)?;
                if self.expected.realtime {
                    self.outlets.telemetry.set_clock(clock);
                    self.outlets.fleet = Some(FleetClock::new(&clock, self.node.control_period()));
                    if let Some(ros2) = &mut self.outlets.ros2 {
                        ros2.clock = Some(clock);
                        ros2.put_paths()?;
                    }
                }
                self.node.handle_clock(&clock, self.subscribed, self.monotonic.now(), &mut self.outlets);
            }
            m = self.inbox.recv(), if self.node.takes_messages() => {
                let Some(Received { key, message }) = m else {
                    return Err(failed!("the recorder's subscriptions closed").into());
                };
                if from_its_sender(&message, &key, &self.outlets.keys, &self.rejected) {
                    match self.node.handle(message, self.monotonic.now(), &mut self.outlets) {
                        Ok(()) => {}
                        Err(Refused::Message(why)) => self.rejected.reject(why, &key),
                        Err(late @ Refused::CameLate { .. }) => return Err(failed!("recorder: {late}").into()),
                    }
                }
            }
        }
        if std::mem::take(&mut self.outlets.clock_due) {
            self.clock.iter().for_each(ClockAnswer::look_again);
        }
        if std::mem::take(&mut self.outlets.withdraw) {
            if let Some(token) = self.token.take() {
                let _ = token.undeclare().await;
            }
        }
        std::mem::replace(&mut self.outlets.failure, Ok(()))
    }

    /// The world announced the end and every tick up to it is written.
    pub fn complete(&self) -> bool {
        self.node.complete()
    }

    pub fn ended(&self) -> bool {
        self.node.end().is_some()
    }

    pub fn reports(&self) -> &[Report] {
        self.node.reports()
    }

    /// The vehicles lost so far: the world's end says, or before it, its losses.
    pub fn lost(&self) -> Vec<u32> {
        self.node.lost()
    }

    /// The roles whose exit report the end calls for and has not come.
    pub fn unreported(&self) -> Vec<(Role, u32)> {
        self.node.unreported()
    }

    pub fn ticks(&self) -> u64 {
        self.node.ticks_recorded()
    }

    /// The last tick the world was heard of (`RecorderNode::world_ticks`).
    pub fn world_ticks(&self) -> u64 {
        self.node.world_ticks()
    }

    /// Messages taken from the world so far.
    pub fn from_world(&self) -> u64 {
        self.node.from_world()
    }

    /// The recorder's monotonic clock, on which its machines' times are.
    pub fn clock(&self) -> Monotonic {
        self.monotonic
    }

    /// When the first tick was written, if one was.
    pub fn first_tick(&self) -> Option<Instant> {
        self.node.first_tick().map(|at| self.monotonic.at(at).into_std())
    }

    pub fn results(&self) -> Results {
        self.node.results()
    }

    /// Ends the recording: flushes telemetry.csv and writes summary.json and report.html.
    pub fn close(mut self, mission: &Mission, dir: &RunDir, how: Closing) -> Result<Summary> {
        let outlets = &mut self.outlets;
        let recorded = self.node.finish(|states, commands| outlets.write(states, commands));
        std::mem::replace(&mut outlets.failure, Ok(()))?;
        let summary = summary::of_recording(
            summary::Recording {
                mission,
                results: self.results(),
                recorded,
                reports: self.node.reports(),
                end: self.node.end(),
                lost: self.lost(),
                rejections: self.rejected.totals(),
                ticks_recorded: self.ticks(),
                tick_wall_time_s: self.node.tick_wall_time(),
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
        self.outlets.telemetry.finish()?;
        tcpf_report::report::write(&dir.path, &tcpf_report::report::Options::default())?;
        Ok(summary)
    }
}

/// A loss as the world announces it, or hands it over.
/// The world's history as the recorder's node takes it.
fn history_answer(answer: history::Answer) -> Input<Ack> {
    match answer {
        history::Answer::State(state) => Input::History(state),
        history::Answer::Done(unkept) => Input::Fetched(unkept),
    }
}

fn loss(loss: Loss) -> Input<Ack> {
    Input::Loss(loss.into())
}

/// How `tcpf record` records: `live` serves it to Foxglove, `ros2` to ROS 2 tools.
pub struct RecordOptions {
    pub live: Option<SocketAddr>,
    /// Its waits: for the world (`startup`), its clock, its history, who is present.
    pub timeouts: Timeouts,
    pub ros2: Option<Ros2Config>,
}

/// `tcpf record`: records a fleet started elsewhere (start the world with `--recorders 1`) until
/// the world's end or a signal, and writes the run directory.
pub async fn record(
    mission: &Mission,
    plan: &Plan,
    dir: &RunDir,
    zenoh: &ZenohArgs,
    options: RecordOptions,
) -> Result<Summary> {
    let RecordOptions { live, timeouts, ros2 } = options;
    let startup_timeout = timeouts.startup;
    let mut shutdown = Shutdown::new()?;
    dir.write_mission(mission, tcpf_core::outputs::summary::Mode::Processes)?;
    dir.write_plan(plan)?;
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
        &timeouts,
    )
    .await
    .map_err(unrecorded)?;
    if let Some(ros2) = &ros2 {
        recording.speak_ros2(ros2, mission, plan).await.map_err(unrecorded)?;
    }
    let keys = Keys::new(&mission.mission.name);
    let (_presence, presence) = presence(&session, &keys).await.map_err(unrecorded)?;
    recording.declare().await.map_err(unrecorded)?;
    let clock = recording.clock();
    let realtime = mission.mission.clock == ClockKind::Realtime;
    // A world that dies says no end, and one may never come (another mission name, endpoint or
    // credential): without these waits the recording would wait for it forever.
    let mut watch = RecorderWatch::new(clock.now(), startup_timeout.as_secs_f64(), realtime);
    let mut recorder = Recorder {
        recording: &mut recording,
        session: &session,
        keys: &keys,
        presence_query: timeouts.presence_query,
        presence,
        shutdown,
        progress: Ticks::new(mission),
        asking: None,
        error: None,
        failure: None,
    };
    let Ok(exit) = drive(&mut watch, &mut recorder, clock).await;
    let Recorder {
        asking,
        error,
        failure,
        progress,
        ..
    } = recorder;
    if let Some(question) = asking {
        question.abort();
    }
    progress.finish();
    let interrupted = exit.stop == Stop::Interrupted;
    match exit.stop {
        Stop::Unrecorded => return Err(unrecorded(error.expect("a failed step keeps its error"))),
        Stop::NoWorld => {
            return Err(unrecorded(failed!(
                "recorder: no world of mission {} within {startup_timeout:?}: is it started, with the same Zenoh endpoints (-e) and credentials as this recorder?",
                mission.mission.name
            )))
        }
        Stop::Complete | Stop::Interrupted | Stop::Failed | Stop::Stalled => {}
    }
    let wall_time_s = exit.at.secs();
    let _ = session.close().await;
    let ended = !interrupted && recording.ended();
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

/// `tcpf record`'s process for its watch: each step of the recording, the world's liveliness
/// and signals as inputs; the question of who is present asked on a task of its own while the
/// recording goes on.
struct Recorder<'a> {
    recording: &'a mut Recording,
    session: &'a Session,
    keys: &'a Keys,
    /// How long the question of who is present waits for the router.
    presence_query: Duration,
    presence: UnboundedReceiver<Presence>,
    shutdown: Shutdown,
    progress: Ticks,
    asking: Option<JoinHandle<Option<bool>>>,
    /// The error of a failed step.
    error: Option<Error>,
    /// Why the run failed, for its summary.
    failure: Option<String>,
}

impl Wiring<RecorderWatch> for Recorder<'_> {
    type Error = Infallible;

    async fn next(&mut self) -> WatchInput {
        loop {
            tokio::select! {
                r = self.recording.step() => {
                    let ticks = self.recording.ticks();
                    if let Err(e) = r {
                        if ticks > 0 {
                            tracing::error!("recorder: {e:#}; writing what was recorded");
                            self.failure.get_or_insert_with(|| format!("the recorder failed: {e:#}"));
                        }
                        self.error.get_or_insert(e);
                        return WatchInput::Failed { ticks };
                    }
                    self.progress.set(ticks);
                    return WatchInput::Recorded {
                        ticks,
                        from_world: self.recording.from_world(),
                        ended: self.recording.ended(),
                        complete: self.recording.complete(),
                        unreported: self.recording.unreported().len(),
                    };
                }
                _ = self.shutdown.recv() => return WatchInput::Interrupted,
                Some(p) = self.presence.recv() => if p.role == Role::World {
                    return WatchInput::World(p.alive);
                },
                answer = async { self.asking.as_mut().expect("asked").await }, if self.asking.is_some() => {
                    self.asking = None;
                    return WatchInput::Answer(answer.ok().flatten());
                }
            }
        }
    }

    async fn perform(&mut self, output: WatchOutput, _: &RecorderWatch) -> Result<Option<WatchInput>, Infallible> {
        match output {
            WatchOutput::Ask => {
                let (session, keys, within) = (self.session.clone(), self.keys.clone(), self.presence_query);
                self.asking = Some(tokio::spawn(async move {
                    match present(&session, &keys, within).await {
                        Ok(present) => Some(present.iter().any(|(role, _)| *role == Role::World)),
                        Err(e) => {
                            tracing::warn!("recorder: {e}");
                            None
                        }
                    }
                }));
            }
            WatchOutput::WorldHere => tracing::info!("recorder: the world is here"),
            WatchOutput::LeftUnseen => {
                tracing::warn!("recorder: the world's token is gone, though its leaving was never seen")
            }
            WatchOutput::Stalled { ended } => {
                let why = if ended {
                    format!(
                        "the world has ended, but tick {} never came whole here (a state or command of it did not reach the recorder)",
                        self.recording.ticks()
                    )
                } else {
                    format!(
                        "the world left without announcing the end, after tick {}",
                        self.recording.world_ticks()
                    )
                };
                tracing::error!("recorder: {why}; writing what was recorded");
                self.failure = Some(why);
            }
        }
        Ok(None)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_report_is_taken_only_under_its_own_key() {
        let keys = Keys::new("m");
        let rejected = Rejected::default();
        let report = || Input::Report(Box::new(Report::new(Role::Agent, 2, 1)));
        let taken = |key| from_its_sender(&report(), key, &keys, &rejected);
        assert!(taken("tcpf/m/report/agent/2"));
        assert!(!taken("tcpf/m/report/agent/3"));
        assert!(!taken("tcpf/m/report/world/2"));
        assert!(!taken("tcpf/x/report/agent/2"));
        assert!(!taken("tcpf/m/report/x/report/agent/2"));
        assert_eq!(rejected.totals().wrong_sender, 4);
    }
}
