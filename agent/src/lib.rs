//! tcpf-agent: the vehicle process. A Zenoh shell around core's `LockstepAgent` (lockstep) or
//! `RealtimeAgent` (realtime): it fetches its path, takes its vehicle's state, exchanges γ with
//! its neighbours and publishes commands. Started while the run is under way, it rejoins.

mod footprint;

use std::convert::Infallible;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use tcpf_bus::claim::{open_and_claim, Rivals};
use tcpf_bus::clock::{self, metronome, Beat, FleetClock, Monotonic};
use tcpf_bus::clock_query::{answered, ask_clock, await_clock, ClockAnswer, ClockBell};
use tcpf_bus::driver::{drive, Wiring};
use tcpf_bus::error::{Context, Error as BusError};
use tcpf_bus::exit_report::{report, RealtimeReport};
use tcpf_bus::keys::{Keys, Role};
use tcpf_bus::outlet::Outlet;
use tcpf_bus::paths::fetch_paths;
use tcpf_bus::presence::{presence_of, Presence, Waiting};
use tcpf_bus::rejected::Rejected;
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_bus::subscribe::{queue, subscribe, subscribe_into, subscribe_with, Received};
use tcpf_bus::waits::Timeouts;
use tcpf_core::fleet::membership::{AgentStartup, Awaited, Peer, StartupCheck, Waited};
use tcpf_core::mission::{ClockKind, Mission};
use tcpf_core::msg::{Checked, Clock, Command, End, Gamma, Loss, Lost, State};
use tcpf_core::outputs::ros2::Stamp;
use tcpf_core::roles::agent::Agent;
use tcpf_core::roles::lockstep::{AgentNode, Timing};
use tcpf_core::roles::lockstep_agent::{Input, LockstepAgent, Output, Source};
use tcpf_core::roles::lockstep_agent_task::{
    Exit as TaskExit, Input as TaskInput, LockstepAgentTask, Output as TaskOutput,
};
use tcpf_core::roles::machine::Shared;
use tcpf_core::roles::realtime::RealtimeAgent;
use tcpf_core::roles::realtime_agent::{
    Exit as RealtimeExit, Input as RealtimeInput, Output as RealtimeOutput, RealtimeAgentNode,
};
use tcpf_core::time::Moment;
use tokio::sync::mpsc::{self, Receiver, UnboundedReceiver, UnboundedSender};
use tokio::sync::Notify;
use zenoh::pubsub::Subscriber;
use zenoh::Session;

/// What an agent fails with: the bus's errors, or its own.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// `--id` names no vehicle of the mission.
    #[error("the mission has no vehicle with id {0}")]
    NoVehicle(u32),
    /// The world and the planner had not come within the startup timeout.
    #[error("agent {id}: no world and planner for mission {mission} within {within:?}")]
    NoFleet { id: u32, mission: String, within: Duration },
    /// A realtime world that had not started its clock by the startup timeout.
    #[error("agent {id}: the world did not start the clock of mission {mission} in time")]
    NoClock { id: u32, mission: String },
    /// Zenoh closed the liveliness subscription.
    #[error("liveliness subscription closed")]
    Closed,
    #[error(transparent)]
    Bus(#[from] BusError),
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Where in its period a realtime agent acts: after the world published the period's states,
/// and early enough that its command reaches the world before the next.
const AGENT_PHASE: f64 = 0.5;

#[derive(Debug, Clone)]
pub struct Options {
    /// Its waits: for the planner, the world and the neighbours at start (`startup`), a silent
    /// neighbour (`stale`), a gone world's end, a realtime world out of reach.
    pub timeouts: Timeouts,
    /// The ROS 2 domain to speak rmw_zenoh on (`--ros2`), over the mission's `[ros2]`.
    pub ros2: Option<u32>,
    /// Whether another process may be claiming the same role now (`--no-rivals`: no).
    pub rivals: Rivals,
}

/// Why the agent stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    /// The world announced the end of the run.
    Ended,
    /// The world or the planner is gone: nobody to act for.
    Orphaned,
    /// The world gave up on this vehicle (its agent was too slow to answer).
    Lost,
    Interrupted,
}

impl std::fmt::Display for Exit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Exit::Ended => "ended",
            Exit::Orphaned => "stopped: the world or the planner is gone",
            Exit::Lost => "stopped: the world gave up on this vehicle",
            Exit::Interrupted => "interrupted",
        })
    }
}

/// What both clocks' loops work with.
struct Shell {
    id: u32,
    /// The vehicles whose γ this agent takes (`Agent::audible`), whose presence it follows.
    audible: Vec<u32>,
    keys: Keys,
    session: Session,
    shutdown: Shutdown,
    rejected: Rejected,
    timeouts: Timeouts,
    presence: UnboundedReceiver<Presence>,
    ends: Receiver<Received<End>>,
    losses: Receiver<Received<Loss>>,
    _subscribers: Vec<Subscriber<()>>,
}

/// A realtime agent, its inbound queues and its outlets.
struct Queued {
    agent: Agent,
    states: Receiver<Received<State>>,
    gammas: Receiver<Received<Gamma>>,
    commands: Outlet,
    gamma_out: Outlet,
    ros2: Option<tcpf_bus::ros2::Agent>,
}

/// Where the vehicle's states and the neighbours' γ go, and whence the agent's messages leave.
enum Inbound {
    /// Realtime: queued for the loop, which acts at its own beat.
    Queued(Box<Queued>),
    /// Lockstep: into the node on Zenoh's thread.
    Fed {
        feed: Arc<Feed>,
        faults: UnboundedReceiver<BusError>,
    },
}

/// The agent runs: the code of its start (its session, its TLS, its configuration) need not stay
/// mapped (`footprint`), as dozens of agents share a host. Let go of as the loop starts, not a
/// while later: a lockstep run of the paper is over in a second.
fn let_go_of_the_start(id: u32) {
    tokio::task::spawn_blocking(move || {
        if let Some(kib) = footprint::drop_startup_code() {
            tracing::debug!("agent {id}: let go of {kib} KiB of mapped code");
        }
    });
}

/// The lockstep agent's machine, fed on Zenoh's thread: a state or γ goes in and the γ and
/// command it yields leave at once, without waking the agent's task. That handoff, a thread woken
/// per message, cost a fifth of a tick of 10 agents as processes. The task keeps what is slow:
/// liveliness, the end, the stale timeout.
///
/// Publishing from the callback cannot block on a full queue that only this thread would
/// drain: lockstep sends a message or two per tick, and no tick comes until they are delivered.
struct Feed {
    id: u32,
    keys: Keys,
    fed: Mutex<Fed>,
    commands: Outlet,
    gamma_out: Outlet,
    rejected: Rejected,
    faults: UnboundedSender<BusError>,
    /// A state came before the start: the world has started, and its clock answers.
    first_state: Notify,
    /// The agent's monotonic clock, which the machine's stale timeout counts in.
    monotonic: Monotonic,
}

struct Fed {
    machine: LockstepAgent,
    /// The agent as a ROS 2 node, and the control period its commands' stamps count in.
    ros2: Option<(tcpf_bus::ros2::Agent, f64)>,
}

impl Feed {
    fn lock(&self) -> MutexGuard<'_, Fed> {
        self.fed.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A state or γ that came on `key`: into the machine if it came on its sender's key.
    fn take(&self, key: &str, input: Input) {
        if let Input::Gamma(g) = &input {
            if !self.rejected.from_sender(key, g.from) {
                return;
            }
        }
        let mut fed = self.lock();
        fed.machine.handle(input, self.monotonic.now());
        self.perform(&mut fed);
    }

    /// The world's clock answered: what came before goes into the machine.
    fn start(&self) {
        let_go_of_the_start(self.id);
        let mut fed = self.lock();
        fed.machine.start(self.monotonic.now());
        self.perform(&mut fed);
    }

    /// Publishes what the machine has ready, counts what it refused and says what it gave up.
    fn perform(&self, fed: &mut Fed) {
        while let Some(output) = fed.machine.poll_output() {
            match output {
                Output::Gamma(gamma) => self.sent(self.gamma_out.put_now(&gamma)),
                Output::Command(command) => {
                    warn_if_not_finite(self.id, &command);
                    self.sent(self.commands.put_now(&command));
                    if let Some((ros2, period)) = &mut fed.ros2 {
                        // Lockstep: simulated time, as the world's stamps and /clock.
                        self.sent(ros2.put(&command, Stamp::from_seconds(command.tick as f64 * *period)));
                    }
                }
                Output::Rejected(why, source) => {
                    let key = match source {
                        Source::State => self.keys.state(self.id),
                        Source::Gamma(j) => self.keys.gamma(j),
                    };
                    self.rejected.reject(why, &key)
                }
                Output::WorldStarted => self.first_state.notify_one(),
                Output::Stale(j) => tracing::warn!(
                    "agent {}: neighbour {j} silent for {:?}; going on without it until it speaks again (the run is no longer reproducible)",
                    self.id,
                    fed.machine.stale_timeout()
                ),
                Output::Resumed(more) => tracing::info!(
                    "agent {}: resumed after {:.1} s stopped or starved; the neighbours get that long more",
                    self.id,
                    more.as_secs_f64()
                ),
            }
        }
    }

    /// A publication that failed ends the loop, which owns the error.
    fn sent(&self, publication: Result<(), BusError>) {
        if let Err(e) = publication {
            let _ = self.faults.send(e);
        }
    }
}

impl Shared<LockstepAgent> for Feed {
    fn with<R>(&self, change: impl FnOnce(&mut LockstepAgent, Moment) -> R) -> R {
        let mut fed = self.lock();
        let result = change(&mut fed.machine, self.monotonic.now());
        self.perform(&mut fed);
        result
    }
}

/// The lockstep agent's task, on the machine Zenoh's thread feeds.
type Task<'a> = LockstepAgentTask<'a, Feed, String>;

fn warn_if_not_finite(id: u32, command: &Command) {
    if !command.finite() {
        tracing::error!(
            "agent {id}: the command of tick {} holds a non-finite number; the world refuses it",
            command.tick
        );
    }
}

pub async fn run(mission: &Mission, id: u32, zenoh: &ZenohArgs, options: &Options) -> Result<Exit> {
    if !mission.vehicles.iter().any(|v| v.id == id) {
        return Err(Error::NoVehicle(id));
    }
    let realtime = mission.mission.clock == ClockKind::Realtime;
    let (keys, mut shutdown, session, claimed) = open_and_claim(
        zenoh,
        &mission.mission.name,
        (Role::Agent, id),
        options.rivals,
        &options.timeouts,
    )
    .await?;
    let rejected = Rejected::default();
    let ids = [id];
    let fetched = shutdown.unless(fetch_paths(&session, &keys, &ids, &options.timeouts, &rejected));
    let Some(paths) = fetched.await else {
        return Ok(Exit::Interrupted);
    };
    let path = paths?[0].1;
    let agent = Agent::new(mission, id, path);
    let neighbours: Vec<u32> = agent.neighbours().collect();
    let audible: Vec<u32> = agent.audible().collect();
    // Whose coming and going it acts on: the world, the planner and the vehicles it hears.
    let mut watched = vec![keys.alive(Role::World, "*"), keys.alive(Role::Planner, "*")];
    if audible.len() + 1 == mission.vehicles.len() {
        watched.push(keys.alive(Role::Agent, "*"));
    } else {
        watched.extend(audible.iter().map(|&j| keys.alive(Role::Agent, j)));
    }
    let (presence_subscribers, mut presence) = presence_of(&session, &keys, &watched).await?;

    let ros2 = match mission.ros2(options.ros2) {
        Some(config) => Some(tcpf_bus::ros2::Agent::declare(&session, &config, id, !realtime).await?),
        None => None,
    };
    let mut subscribers = Vec::new();
    let inbound = if realtime {
        let (s1, states) = subscribe::<State>(&session, &keys.state(id), &rejected).await?;
        let (gamma_tx, gammas) = queue();
        subscribers.push(s1);
        for &j in &audible {
            subscribers.push(subscribe_into::<Gamma>(&session, &keys.gamma(j), &rejected, gamma_tx.clone()).await?);
        }
        let queued = Queued {
            agent,
            states,
            gammas,
            commands: Outlet::for_clock(&session, keys.cmd(id), true).await?,
            gamma_out: Outlet::gamma(&session, keys.gamma(id), true).await?,
            ros2,
        };
        Inbound::Queued(Box::new(queued))
    } else {
        let (faults_tx, faults) = mpsc::unbounded_channel();
        let feed = Arc::new(Feed {
            id,
            keys: keys.clone(),
            fed: Mutex::new(Fed {
                machine: LockstepAgent::new(AgentNode::new(agent), options.timeouts.stale),
                ros2: ros2.map(|r| (r, mission.mission.control_period)),
            }),
            commands: Outlet::for_clock(&session, keys.cmd(id), false).await?,
            gamma_out: Outlet::gamma(&session, keys.gamma(id), false).await?,
            rejected: rejected.clone(),
            faults: faults_tx,
            first_state: Notify::new(),
            monotonic: Monotonic::start(),
        });
        let to = feed.clone();
        subscribers.push(
            subscribe_with::<State>(&session, &keys.state(id), &rejected, move |key, s| {
                to.take(key, Input::State(s))
            })
            .await?,
        );
        for &j in &audible {
            let to = feed.clone();
            subscribers.push(
                subscribe_with::<Gamma>(&session, &keys.gamma(j), &rejected, move |key, g| {
                    to.take(key, Input::Gamma(g))
                })
                .await?,
            );
        }
        Inbound::Fed { feed, faults }
    };
    let (s2, ends) = subscribe::<End>(&session, &keys.end(), &rejected).await?;
    let (s3, losses) = subscribe::<Loss>(&session, &keys.lost("*"), &rejected).await?;
    subscribers.extend([s2, s3]);
    subscribers.extend(presence_subscribers);
    tracing::info!(
        "agent {id}: path with t_f = {:.3} s, neighbours {neighbours:?}",
        path.t_f()
    );

    // The world's token first: its clock is declared before it, so whether the run is under way
    // (the clock answers) is then known for sure.
    let monotonic = Monotonic::start();
    let mut startup = AgentStartup::new(&audible, options.timeouts.startup, monotonic.now());
    match await_startup(&mut presence, &mut shutdown, &mut startup, &monotonic, Awaited::Fleet).await {
        Waited::Done => {}
        Waited::Interrupted => return Ok(Exit::Interrupted),
        Waited::Closed => return Err(Error::Closed),
        Waited::TimedOut(_) => {
            return Err(Error::NoFleet {
                id,
                mission: mission.mission.name.clone(),
                within: options.timeouts.startup,
            })
        }
    }
    // Listened for before the question, and before this agent's token, which the world waits for
    // before it starts: its announcement of the start cannot pass between them.
    let bell = ClockBell::declare(&session, &keys).await?;
    let under_way = ask_clock(&session, &keys, &rejected, &options.timeouts).await?;
    if let Some(clock) = &under_way {
        check_clock(mission, clock)?;
        tracing::info!("agent {id}: the run is under way (tick {}); rejoining it", clock.tick);
    }
    let token = session
        .liveliness()
        .declare_token(keys.alive(Role::Agent, id))
        .await
        .context("liveliness token")?;
    let mut shell = Shell {
        id,
        audible: audible.clone(),
        keys,
        session,
        shutdown,
        rejected,
        timeouts: options.timeouts,
        presence,
        ends,
        losses,
        _subscribers: subscribers,
    };

    let exit = match inbound {
        Inbound::Queued(queued) => {
            let clock = match under_way {
                Some(clock) => Some(clock),
                None => {
                    shell
                        .wait_for_clock(mission, bell, monotonic.at(startup.deadline()))
                        .await?
                }
            };
            match clock {
                Some(clock) => shell.realtime(mission, *queued, &clock).await?,
                None => Exit::Interrupted,
            }
        }
        Inbound::Fed { feed, mut faults } => {
            if under_way.is_some() {
                feed.with(|machine, now| machine.with(now, AgentNode::rejoin));
            } else {
                let (presence, shutdown) = (&mut shell.presence, &mut shell.shutdown);
                match await_startup(presence, shutdown, &mut startup, &monotonic, Awaited::Neighbours).await {
                    Waited::Interrupted => return Ok(Exit::Interrupted),
                    Waited::Closed => return Err(Error::Closed),
                    Waited::TimedOut(StartupCheck::WithoutNeighbours(absent)) => {
                        tracing::warn!("agent {id}: starting without neighbours {absent:?}")
                    }
                    Waited::Done | Waited::TimedOut(StartupCheck::NoFleet) => {}
                }
                if let Some(gone) = startup.deserted() {
                    tracing::warn!("agent {id}: the {gone} is gone before the run started; stopping");
                    return Ok(Exit::Orphaned);
                }
                let absent = startup.absent();
                for &j in &audible {
                    feed.with(|machine, now| machine.with(now, |node| node.set_gone(j, absent.contains(&j))));
                }
            }
            let exit = shell
                .lockstep(mission, under_way.is_none().then_some(bell), &feed, &mut faults)
                .await;
            feed.lock().machine.stop();
            exit?
        }
    };
    // Its report is acknowledged by the recorders (`report`): nothing to wait for.
    let _ = token.undeclare().await;
    let _ = claimed.undeclare().await;
    let _ = shell.session.close().await;
    Ok(exit)
}

/// Feeds liveliness changes into `startup` until what it awaits is there or its timeout leaves a
/// check.
async fn await_startup(
    presence: &mut UnboundedReceiver<Presence>,
    shutdown: &mut Shutdown,
    startup: &mut AgentStartup,
    monotonic: &Monotonic,
    awaited: Awaited,
) -> Waited {
    startup.awaiting(awaited);
    let mut heard = Waiting {
        changes: presence,
        shutdown,
        about: peer,
        said: |nothing: Infallible| match nothing {},
    };
    let Ok(waited) = drive(startup, &mut heard, *monotonic).await;
    waited
}

/// Whom a liveliness change is about, for an agent's startup.
fn peer(p: Presence) -> Option<Peer> {
    match p.role {
        Role::World => Some(Peer::World),
        Role::Planner => Some(Peer::Planner),
        Role::Agent => Some(Peer::Neighbour(p.id)),
        Role::Record => None,
    }
}

/// This agent's clock against the world's.
fn check_clock(mission: &Mission, clock: &Clock) -> Result<(), BusError> {
    clock::check_clock("agent", &clock::Expected::of(mission), clock)
}

impl Shell {
    /// This agent's exit report: its lockstep timing, or its realtime one.
    async fn report(&self, timing: &Timing, realtime: Option<RealtimeReport>) -> Result<()> {
        Ok(report(
            &self.session,
            &self.keys,
            (Role::Agent, self.id),
            &self.rejected,
            timing,
            realtime,
            &self.timeouts,
        )
        .await?)
    }

    /// Realtime: asks for the world's clock until it has started (`None` on a signal).
    async fn wait_for_clock(
        &mut self,
        mission: &Mission,
        bell: ClockBell,
        deadline: tokio::time::Instant,
    ) -> Result<Option<Clock>> {
        let mut answer = Some(await_clock(
            &self.session,
            &self.keys,
            &self.rejected,
            bell,
            &self.timeouts,
        ));
        let waited = tokio::time::timeout_at(deadline, answered(&mut answer));
        match self.shutdown.unless(waited).await {
            None => Ok(None),
            Some(Err(_)) => Err(Error::NoClock {
                id: self.id,
                mission: mission.mission.name.clone(),
            }),
            Some(Ok(clock)) => {
                let clock = clock?;
                check_clock(mission, &clock)?;
                Ok(Some(clock))
            }
        }
    }

    /// `unchecked`: the world had not started when this agent came, so whether its clock is
    /// lockstep is known only once it answers; until then the agent asks, when `unchecked` rings.
    async fn lockstep(
        &mut self,
        mission: &Mission,
        unchecked: Option<ClockBell>,
        feed: &Feed,
        faults: &mut UnboundedReceiver<BusError>,
    ) -> Result<Exit> {
        let id = self.id;
        // Came before the world started: what arrives stays held, and no command leaves, until
        // the world's clock says it runs this agent's mission (an agent of another would steer
        // its vehicle for hundreds of ticks before it heard). The clock answers once the world
        // has started, which it announces and its first state shows: asked at each.
        let clock = unchecked.map(|bell| await_clock(&self.session, &self.keys, &self.rejected, bell, &self.timeouts));
        if clock.is_none() {
            feed.start();
        }
        let mut machine = LockstepAgentTask::new(
            feed,
            self.timeouts.stale,
            self.timeouts.end_after_the_world,
            feed.monotonic.now(),
        );
        let mut wiring = Lockstep {
            shell: self,
            feed,
            mission,
            clock,
            faults,
            failed: None,
        };
        let Ok(exit) = drive(&mut machine, &mut wiring, feed.monotonic).await;
        let exit = match exit {
            TaskExit::Ended => Exit::Ended,
            TaskExit::Lost => Exit::Lost,
            TaskExit::Orphaned => Exit::Orphaned,
            TaskExit::Interrupted => Exit::Interrupted,
            TaskExit::Failed => return Err(wiring.failed.take().expect("a failure keeps its error").into()),
        };
        let (gamma, timing) = {
            let fed = feed.lock();
            (fed.machine.node().agent().gamma(), fed.machine.timing().clone())
        };
        tracing::info!("agent {id}: {exit} at γ = {gamma:.3}");
        self.report(&timing, None).await?;
        Ok(exit)
    }

    async fn realtime(&mut self, mission: &Mission, queued: Queued, clock: &Clock) -> Result<Exit> {
        let id = self.id;
        let fleet = FleetClock::new(clock, mission.mission.control_period);
        // γ_i starts at 0 for an agent there from the beginning, from wherever the vehicle is
        // for one that finds the run under way (started again, or late).
        let node = RealtimeAgent::new(queued.agent, mission, true);
        let mut machine = RealtimeAgentNode::new(node, fleet.period().as_secs_f64(), self.timeouts.world_away);
        let beats = metronome(fleet, AGENT_PHASE, fleet.periods_now().floor() as u64);
        let_go_of_the_start(id);
        let mut wiring = Realtime {
            shell: self,
            states: queued.states,
            gammas: queued.gammas,
            commands: queued.commands,
            gamma_out: queued.gamma_out,
            ros2: queued.ros2,
            beats,
            fleet,
            clock,
            control_period: mission.mission.control_period,
            published: 0,
        };
        let exit = match drive(&mut machine, &mut wiring, Monotonic::start()).await? {
            RealtimeExit::Ended => Exit::Ended,
            RealtimeExit::Interrupted => Exit::Interrupted,
            RealtimeExit::Orphaned => {
                tracing::warn!("agent {id}: the world did not come back; stopping");
                Exit::Orphaned
            }
        };
        let published = wiring.published;
        let node = machine.node();
        let timing = node.timing();
        tracing::info!(
            "agent {id}: {exit} at γ = {:.3}; period lateness p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms; {} overruns, {} skipped, {} stale states",
            node.agent().gamma(),
            timing.lateness_p50_ms,
            timing.lateness_p99_ms,
            timing.lateness_max_ms,
            timing.overruns,
            timing.skipped,
            timing.stale_states
        );
        self.report(
            &Timing::default(),
            Some(RealtimeReport {
                timing,
                published,
                ..RealtimeReport::default()
            }),
        )
        .await?;
        Ok(exit)
    }
}

/// A realtime agent's process for its machine: the metronome's beats, the vehicle's states, the
/// neighbours' γ (each checked for its sender's key), liveliness, the end and signals as inputs;
/// its γ and commands published, on ROS 2 too, and refusals counted by key.
struct Realtime<'a> {
    shell: &'a mut Shell,
    states: Receiver<Received<State>>,
    gammas: Receiver<Received<Gamma>>,
    commands: Outlet,
    gamma_out: Outlet,
    ros2: Option<tcpf_bus::ros2::Agent>,
    beats: Receiver<Beat>,
    fleet: FleetClock,
    clock: &'a Clock,
    control_period: f64,
    /// γ published.
    published: u64,
}

impl Wiring<RealtimeAgentNode<String>> for Realtime<'_> {
    type Error = Error;

    async fn next(&mut self) -> RealtimeInput<String> {
        let shell = &mut *self.shell;
        loop {
            tokio::select! {
                Some(beat) = self.beats.recv() => {
                    return RealtimeInput::Beat { tick: beat.tick, late_s: beat.late_s(), skipped: beat.skipped };
                }
                Some(s) = self.states.recv() => {
                    return RealtimeInput::State { state: s.message, horizon: self.fleet.horizon(), key: s.key };
                }
                Some(g) = self.gammas.recv() => if shell.rejected.from_sender(&g.key, g.message.from) {
                    return RealtimeInput::Gamma { gamma: g.message, horizon: self.fleet.horizon(), key: g.key };
                },
                Some(p) = shell.presence.recv() => match p.role {
                    Role::World => return RealtimeInput::World(p.alive),
                    Role::Planner if !p.alive => return RealtimeInput::PlannerGone,
                    _ => {}
                },
                Some(_) = shell.ends.recv() => return RealtimeInput::End,
                Some(_) = shell.losses.recv() => {}
                _ = shell.shutdown.recv() => return RealtimeInput::Interrupted,
            }
        }
    }

    async fn perform(
        &mut self,
        output: RealtimeOutput<String>,
        _: &RealtimeAgentNode<String>,
    ) -> Result<Option<RealtimeInput<String>>> {
        let id = self.shell.id;
        match output {
            RealtimeOutput::Gamma(gamma) => {
                self.gamma_out.put(&gamma).await?;
                self.published += 1;
            }
            RealtimeOutput::Command(command) => {
                warn_if_not_finite(id, &command);
                self.commands.put(&command).await?;
                if let Some(ros2) = &mut self.ros2 {
                    let t = command.tick as f64 * self.control_period;
                    ros2.put(&command, Stamp::of_fleet(self.clock, t))?;
                }
            }
            RealtimeOutput::Refused(why, key) => self.shell.rejected.reject(why, &key),
            RealtimeOutput::WorldAway(grace) => tracing::warn!(
                "agent {id}: the world is out of reach; acting on what it last sent, and waiting up to {grace:?} for it"
            ),
            RealtimeOutput::WorldBack => tracing::info!("agent {id}: the world is back"),
            RealtimeOutput::PlannerGone => {
                tracing::warn!("agent {id}: the planner is gone; going on with the path it served")
            }
        }
        Ok(None)
    }
}

/// A lockstep agent's task: the world's clock until it answers, liveliness, the end, losses,
/// publications that failed and signals.
struct Lockstep<'s> {
    shell: &'s mut Shell,
    feed: &'s Feed,
    mission: &'s Mission,
    /// The world's clock, until it answers.
    clock: Option<ClockAnswer>,
    faults: &'s mut UnboundedReceiver<BusError>,
    /// Why the run failed.
    failed: Option<BusError>,
}

impl Lockstep<'_> {
    fn failed(&mut self, e: BusError) -> TaskInput<String> {
        self.failed = Some(e);
        TaskInput::Failed
    }
}

impl<'a> Wiring<Task<'a>> for Lockstep<'_> {
    type Error = Infallible;

    async fn next(&mut self) -> TaskInput<String> {
        let shell = &mut *self.shell;
        loop {
            tokio::select! {
                Some(e) = self.faults.recv() => return self.failed(e),
                answer = answered(&mut self.clock), if self.clock.is_some() => {
                    self.clock = None;
                    return match answer.and_then(|clock| check_clock(self.mission, &clock)) {
                        Ok(()) => TaskInput::Started,
                        Err(e) => self.failed(e),
                    };
                }
                _ = self.feed.first_state.notified(), if self.clock.is_some() => {
                    self.clock.iter().for_each(ClockAnswer::look_again);
                }
                Some(p) = shell.presence.recv() => match p.role {
                    Role::World => return TaskInput::World(p.alive),
                    // This agent has its path: the planner serves only agents that start.
                    Role::Planner if !p.alive => return TaskInput::PlannerGone,
                    Role::Agent if shell.audible.contains(&p.id) => return TaskInput::Neighbour(p.id, p.alive),
                    _ => {}
                },
                Some(e) = shell.ends.recv() => return TaskInput::End(e.message, e.key),
                Some(l) = shell.losses.recv() => {
                    let lost = Lost::from(l.message);
                    if shell.rejected.from_sender(&l.key, lost.id) {
                        return TaskInput::Lost(lost, l.key);
                    }
                }
                _ = shell.shutdown.recv() => return TaskInput::Interrupted,
            }
        }
    }

    async fn perform(
        &mut self,
        output: TaskOutput<String>,
        _: &Task<'a>,
    ) -> Result<Option<TaskInput<String>>, Infallible> {
        let id = self.shell.id;
        match output {
            TaskOutput::Started => let_go_of_the_start(id),
            TaskOutput::Refused(why, key) => self.shell.rejected.reject(why, &key),
            TaskOutput::PlannerGone => {
                tracing::warn!("agent {id}: the planner is gone; going on with the path it served")
            }
            TaskOutput::Lost(lost) => tracing::warn!(
                "agent {id}: the world gave up on this vehicle at tick {} ({:?}); stopping",
                lost.tick,
                lost.reason
            ),
            TaskOutput::WorldGone => tracing::warn!("agent {id}: the world is gone; stopping"),
        }
        Ok(None)
    }
}
