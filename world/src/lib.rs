//! tcpf-world: the world process. A Zenoh shell around core's `WorldNode` in lockstep (it
//! publishes every vehicle's state, waits for every live agent's command and integrates: it is
//! the clock) or `RealtimeWorld` in realtime (it integrates on a metronome with the freshest
//! commands, serves the wall-clock epoch everyone keeps time by, and answers recorders from its
//! history of the states it ran).

use std::collections::BTreeMap;
use std::convert::Infallible;
use std::sync::{Arc, Mutex, MutexGuard};

use tcpf_bus::claim::{open_and_claim, Rivals};
use tcpf_bus::clock::{metronome, unix_now, Beat, FleetClock, Monotonic};
use tcpf_bus::clock_query::ClockServer;
use tcpf_bus::driver::{drive, Wiring};
use tcpf_bus::error::{Context, Error as BusError};
use tcpf_bus::exit_report::{report, RealtimeReport};
use tcpf_bus::handover::hand_over;
use tcpf_bus::history::Asked;
use tcpf_bus::keys::{Keys, Role};
use tcpf_bus::outlet::{say_now, Outlet};
use tcpf_bus::paths::fetch_paths;
use tcpf_bus::presence::{Followed, Presence, Waiting};
use tcpf_bus::rejected::Rejected;
use tcpf_bus::ros2::PlayedOdometry;
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_bus::subscribe::{queue, subscribe_as, subscribe_origin_as, subscribe_with, Received};
use tcpf_bus::waits::Timeouts;
use tcpf_core::fleet::membership::{Arrival, Decision, Gathered, Gathering, Member, Missing};
use tcpf_core::mission::{ClockKind, Mission};
use tcpf_core::model::path::GeneralizedPath;
use tcpf_core::msg::{Clock, Command, End, Loss, LossReason, Lost, Player, State, TickRecord, PROTOCOL_VERSION};
use tcpf_core::outputs::ros2::{Played, Stamp, MAP_FRAME};
use tcpf_core::roles::lockstep::{Reject, Timing, WorldNode};
use tcpf_core::roles::lockstep_world::{Io, LockstepWorld};
use tcpf_core::roles::lockstep_world_task::{Exit as TaskExit, Input as TaskInput, LockstepWorldTask, SharedWorld};
use tcpf_core::roles::realtime::RealtimeWorld;
use tcpf_core::roles::realtime_world::{
    Exit as RealtimeExit, Input as RealtimeInput, Output as RealtimeOutput, RealtimeWorldNode,
};
use tcpf_core::time::{Moment, UnixTime};
use tokio::sync::mpsc::{self, Receiver, UnboundedReceiver, UnboundedSender};
use zenoh::liveliness::LivelinessToken;
use zenoh::sample::Locality;
use zenoh::Session;

/// What a world fails with: the bus's errors, or its fleet that did not gather.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error(transparent)]
    Bus(#[from] BusError),
    /// Agents or recorders that had not come within the startup timeout.
    #[error("world: {0}")]
    Missing(Missing),
    /// Zenoh closed the liveliness subscription.
    #[error("liveliness subscription closed")]
    Closed,
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// How far ahead of now a realtime world sets t = 0: every process waiting for the clock (each
/// asks a few times a second) has it before the first period, so nobody starts late.
const REALTIME_LEAD_S: f64 = 0.5;

#[derive(Debug, Clone)]
pub struct Options {
    /// Its waits: for the planner and every agent (and recorder) at start (`startup`), a live
    /// agent's command (`command`), a gone agent coming back (`rejoin`), the hand-overs.
    pub timeouts: Timeouts,
    /// Recorders to wait for before the first tick, so that they miss nothing.
    pub recorders: usize,
    /// Realtime: the vehicles this world simulates; the others are played by other processes.
    pub vehicles: Option<Vec<u32>>,
    /// The ROS 2 domain to speak rmw_zenoh on (`--ros2`), over the mission's `[ros2]`.
    pub ros2: Option<u32>,
    /// Whether another process may be claiming the same role now (`--no-rivals`: no).
    pub rivals: Rivals,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    /// Every vehicle arrived (or was lost), or max_duration: `short` vehicles did neither.
    Ended {
        ticks: u64,
        lost: usize,
        short: usize,
    },
    Interrupted,
}

impl std::fmt::Display for Exit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Exit::Ended { ticks, lost, short: 0 } => write!(f, "ended after {ticks} ticks, {lost} vehicle(s) lost"),
            Exit::Ended { ticks, lost, short } => write!(
                f,
                "ended after {ticks} ticks, {lost} vehicle(s) lost, {short} not arrived by the mission's max_duration"
            ),
            Exit::Interrupted => write!(f, "interrupted"),
        }
    }
}

/// What both clocks' loops work with.
struct Shell<'a> {
    keys: Keys,
    session: Session,
    shutdown: Shutdown,
    rejected: Rejected,
    timeouts: Timeouts,
    presence: &'a mut Followed,
    /// One per simulated vehicle, in the mission's order.
    outlets: Arc<Vec<Outlet>>,
    end_out: Arc<Outlet>,
    clock: Arc<ClockServer>,
    /// Realtime: the fleet as ROS 2 nodes see it, and the vehicles they may play.
    ros2: Option<Ros2Side>,
}

/// The next odometry of a vehicle a ROS 2 node plays; never, without ROS 2.
async fn played_odometry(ros2: &mut Option<Ros2Side>) -> Option<Received<(u32, Vec<u8>)>> {
    match ros2 {
        Some(Ros2Side {
            odometry: Some(odometry),
            ..
        }) => odometry.recv().await,
        _ => std::future::pending().await,
    }
}

/// Answers a recorder's fetch from the world's history. A recorder gone while it was answered
/// costs it the ticks, not the run.
fn answer_fetch(node: &RealtimeWorld, asked: tcpf_bus::history::Asked) {
    let (states, unkept) = node.answer(&asked.fetch);
    if let Err(e) = tcpf_bus::history::answer(&asked, states, unkept) {
        tracing::warn!("world: {e}");
    }
}

/// What the realtime world hears: every vehicle's commands, and the states of those other
/// processes play.
enum Heard {
    Command(Command),
    State(State),
}

/// The realtime world's ROS 2 node, and where the states of vehicles played by ROS 2 nodes go.
struct Ros2Side {
    node: tcpf_bus::ros2::World,
    /// Once the run has started.
    odometry: Option<PlayedOdometry>,
    /// Per vehicle the world does not simulate, where its states go once a node plays it.
    outlets: BTreeMap<u32, Outlet>,
}

/// Where the agents' commands go.
enum Inbound {
    /// Realtime: queued for the loop, which integrates on its own beat.
    Queued(Receiver<Received<Heard>>),
    /// Lockstep: into the node on Zenoh's thread.
    Fed {
        stepper: Arc<Stepper>,
        ends: UnboundedReceiver<Result<End, BusError>>,
    },
}

/// The lockstep world, fed on Zenoh's thread: the command that completes a tick advances it,
/// and the next states leave at once, without waking the world's task (the agents answer the
/// same way; 10 agents as processes, a tick 0.60 -> 0.54 ms). The task keeps what is slow:
/// liveliness, the command timeout, signals. A loss is announced under the same lock, before
/// the states of the tick that no longer waits for the vehicle.
struct Stepper {
    stepped: Mutex<Stepped>,
    session: Session,
    keys: Keys,
    outlets: Arc<Vec<Outlet>>,
    /// Each closed tick, for recorders: it leaves in the batch of the next tick's states.
    tick_out: Outlet,
    end_out: Arc<Outlet>,
    clock: Arc<ClockServer>,
    /// The world's monotonic clock, which its machine's deadlines count in.
    monotonic: Monotonic,
    rejected: Rejected,
    /// For the hand-overs of losses, and the log of a vehicle lost for silence.
    timeouts: Timeouts,
    /// The end, once published, or a publication that failed: the task stops on either.
    ends: UnboundedSender<Result<End, BusError>>,
    /// The losses being handed over to the recorders.
    handovers: Mutex<Vec<tokio::task::JoinHandle<()>>>,
}

struct Stepped {
    world: LockstepWorld,
    /// The clock the world serves, but for its tick.
    clock: Clock,
    /// Each closed tick, for ROS 2 nodes (`--ros2`).
    ros2: Option<tcpf_bus::ros2::World>,
}

impl Stepper {
    fn lock(&self) -> MutexGuard<'_, Stepped> {
        self.stepped.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Hands `act` the world's machine, the time and the outlets it does its work through.
    fn with(&self, act: impl FnOnce(&mut LockstepWorld, Moment, &mut Doing)) {
        let now = self.monotonic.now();
        let mut stepped = self.lock();
        let Stepped { world, clock, ros2 } = &mut *stepped;
        act(
            world,
            now,
            &mut Doing {
                stepper: self,
                clock,
                ros2,
            },
        );
    }

    /// A command on `key`: one whose contents name another vehicle is counted and dropped, as
    /// is anything once the end is out.
    fn take(&self, key: &str, command: Command) {
        self.with(|world, now, doing| {
            if !world.over() && self.rejected.from_sender(key, command.id) {
                world.handle_command(command, now, doing);
            }
        });
    }

    /// Tells the agents that a vehicle is lost, and hands it over to the recorders on a task of
    /// its own, while the fleet goes on (the end repeats it, should that fail).
    fn announce(&self, lost: Lost) {
        let loss = Loss::from(lost);
        if let Err(e) = say_now(&self.session, self.keys.lost(lost.id), &loss) {
            let _ = self.ends.send(Err(e));
        }
        let (session, keys, timeouts) = (self.session.clone(), self.keys.clone(), self.timeouts);
        let handing = tokio::spawn(async move {
            let what = format!("world: the loss of vehicle {}", lost.id);
            if let Err(e) = hand_over(&session, &keys, keys.lost(lost.id), &loss, &what, &timeouts).await {
                tracing::warn!("{e}");
            }
        });
        self.handovers.lock().unwrap_or_else(|e| e.into_inner()).push(handing);
    }

    /// A publication failed: the task stops on it.
    fn failed(&self, e: BusError) {
        let _ = self.ends.send(Err(e));
    }
}

/// For the task: the same, its outlets lent as any `Io` (the commands' path, which calls
/// `Stepper::with`, keeps them as they are).
impl SharedWorld for Stepper {
    fn with(&self, act: impl FnOnce(&mut LockstepWorld, Moment, &mut dyn Io)) {
        Stepper::with(self, |world, now, doing| act(world, now, doing));
    }
}

/// What the lockstep world's machine does, through the process's outlets, under its lock.
struct Doing<'a> {
    stepper: &'a Stepper,
    clock: &'a Clock,
    ros2: &'a mut Option<tcpf_bus::ros2::World>,
}

impl Io for Doing<'_> {
    fn states(&mut self, tick: u64, states: &[State]) {
        self.stepper.clock.set(Clock { tick, ..*self.clock });
        for (outlet, state) in self.stepper.outlets.iter().zip(states) {
            if let Err(e) = outlet.put_now(state) {
                self.stepper.failed(e);
            }
        }
    }

    fn record(&mut self, record: TickRecord<'_>) {
        let put = self.stepper.tick_out.put_now(&record);
        let recorded = match self.ros2 {
            Some(ros2) => put.and_then(|()| {
                let fleet = record.states.iter().zip(record.commands.iter().map(Option::as_ref));
                ros2.put(fleet, Stamp::from_seconds(record.states[0].t))
            }),
            None => put,
        };
        if let Err(e) = recorded {
            self.stepper.failed(e);
        }
    }

    fn end(&mut self, end: &End) {
        let _ = self
            .stepper
            .ends
            .send(self.stepper.end_out.put_now(end).map(|()| end.clone()));
    }

    fn lost(&mut self, lost: Lost) {
        self.stepper.announce(lost);
    }

    fn rejected(&mut self, id: u32, reject: Reject) {
        self.stepper.rejected.reject(reject, &self.stepper.keys.cmd(id));
    }

    fn decided(&mut self, decision: &Decision, t: f64) {
        match *decision {
            Decision::AwaitReturn { id, within } => {
                tracing::warn!("world: agent {id} is gone at t = {t:.2} s; waiting {within:?} for it to come back");
            }
            Decision::Lose {
                id,
                reason: LossReason::Silent,
                ..
            } => tracing::warn!(
                "world: agent {id} sent no command of t = {t:.2} s within {:?}; its vehicle is lost and drifts",
                self.stepper.timeouts.command
            ),
            Decision::Lose {
                id,
                reason: LossReason::Gone,
                awaited: true,
            } => tracing::warn!("world: agent {id} did not come back; its vehicle drifts"),
            Decision::Lose {
                id,
                reason: LossReason::Gone,
                awaited: false,
            } => tracing::warn!("world: agent {id} is gone at t = {t:.2} s; its vehicle drifts"),
            Decision::TellAgain(lost) => tracing::warn!(
                "world: an agent of vehicle {} is here at t = {t:.2} s, but the vehicle was lost at tick {}: telling it again",
                lost.id,
                lost.tick
            ),
            Decision::Back(id) => tracing::info!("world: agent {id} is back at t = {t:.2} s"),
            Decision::Resumed(more) => tracing::info!(
                "world: resumed after {:.1} s stopped or starved; the agents' commands get that long more",
                more.as_secs_f64()
            ),
        }
    }

    fn again(&mut self, n: usize, state: &State) {
        if let Err(e) = self.stepper.outlets[n].put_now(state) {
            self.stepper.failed(e);
        }
    }
}

pub async fn run(mission: &Mission, zenoh: &ZenohArgs, options: &Options) -> Result<Exit> {
    let (keys, shutdown, session, claimed) = open_and_claim(
        zenoh,
        &mission.mission.name,
        (Role::World, 0),
        options.rivals,
        &options.timeouts,
    )
    .await?;
    let rejected = Rejected::default();
    // A world that routes the fleet (`tcpf run`'s) carries everyone's exit report to the
    // recorders: it leaves only once its roles have had theirs acknowledged, and left.
    let routes = zenoh.routes()?;
    // Followed from before the world's token, so that at its end the world knows who is still
    // there without asking.
    let mut presence = Followed::follow(&session, &keys).await?;
    let (exit, token) = serve(mission, options, &keys, &session, &mut presence, shutdown, rejected).await?;
    tracing::info!("world: {exit}");
    // The recorders acknowledged the end; it reaches the agents before the world leaves.
    match (routes, exit) {
        (true, _) => presence.linger(&[Role::Agent], options.timeouts.handover()).await,
        (false, Exit::Ended { .. }) => presence.linger(&[Role::Agent], options.timeouts.linger).await,
        (false, Exit::Interrupted) => {}
    }
    if let Some(token) = token {
        let _ = token.undeclare().await;
    }
    let _ = claimed.undeclare().await;
    // The planner reports once the world's token has gone.
    if routes {
        presence.linger(&[Role::Planner], options.timeouts.handover()).await;
    }
    let _ = session.close().await;
    Ok(exit)
}

/// The world's work, from an open session to its exit, with the token it declared once ready.
async fn serve(
    mission: &Mission,
    options: &Options,
    keys: &Keys,
    session: &Session,
    presence: &mut Followed,
    mut shutdown: Shutdown,
    rejected: Rejected,
) -> Result<(Exit, Option<LivelinessToken>)> {
    let ids: &[u32] = &mission.vehicles.iter().map(|v| v.id).collect::<Vec<_>>();
    let simulated: Vec<u32> = match &options.vehicles {
        Some(v) => ids.iter().copied().filter(|i| v.contains(i)).collect(),
        None => ids.to_vec(),
    };
    let realtime = mission.mission.clock == ClockKind::Realtime;
    // Computed once: a TOML of the whole mission, which the clock carries.
    let digest = mission.digest();
    // What a role on another host whose mission is not this one is told to compare with.
    tracing::info!("world: mission {} (digest {digest:016x})", mission.mission.name);
    // One deadline for the plan, the agents and the recorders: whoever waits on the world (its
    // launcher) knows when it will have said who is missing.
    let monotonic = Monotonic::start();
    let mut gathering = Gathering::new(ids, options.recorders, options.timeouts.startup, monotonic.now());
    let fetched = shutdown.unless(fetch_paths(session, keys, ids, &options.timeouts, &rejected));
    let Some(paths) = fetched.await else {
        return Ok((Exit::Interrupted, None));
    };
    let paths = paths?;
    let mut outlets = Vec::with_capacity(simulated.len());
    for id in &simulated {
        outlets.push(Outlet::for_clock(session, keys.state(id), realtime).await?);
    }
    let outlets = Arc::new(outlets);
    let links = mission.directed_links();
    let fleet = tcpf_bus::ros2::Fleet {
        ids,
        simulated: &simulated,
        links: &links,
        lockstep: !realtime,
    };
    let mut ros2 = match mission.ros2(options.ros2) {
        Some(config) => {
            let node = tcpf_bus::ros2::World::declare(session, &config, &fleet, "world").await?;
            let mut outlets = BTreeMap::new();
            for &id in ids.iter().filter(|id| !simulated.contains(id)) {
                outlets.insert(id, Outlet::for_clock(session, keys.state(id), realtime).await?);
            }
            Some(Ros2Side {
                node,
                odometry: None,
                outlets,
            })
        }
        None => None,
    };
    if let Some(ros2) = ros2.as_mut().filter(|_| !realtime) {
        // Lockstep: simulated time from 0, as every stamp.
        ros2.node.put_paths(&paths, Stamp::from_seconds)?;
    }
    let end_out = Arc::new(Outlet::last_words(session, keys.end()).await?);
    let clock = Arc::new(ClockServer::declare(session, keys).await?);
    let (_commands, inbound) = if realtime {
        let (tx, heard) = queue();
        let mut subscribers = vec![subscribe_as(session, &keys.cmd("*"), &rejected, tx.clone(), Heard::Command).await?];
        // The states of the vehicles other processes play, by which the world judges their
        // arrival; not its own, which it publishes for those ROS 2 nodes play.
        for id in ids.iter().filter(|id| !simulated.contains(id)) {
            let key = keys.state(id);
            subscribers
                .push(subscribe_origin_as(session, &key, Locality::Remote, &rejected, tx.clone(), Heard::State).await?);
        }
        (subscribers, Inbound::Queued(heard))
    } else {
        let (ends_tx, ends) = mpsc::unbounded_channel();
        let stepper = Arc::new(Stepper {
            stepped: Mutex::new(Stepped {
                world: LockstepWorld::new(
                    WorldNode::new(mission, &paths),
                    options.timeouts.command,
                    options.timeouts.rejoin,
                    monotonic.now(),
                ),
                clock: Clock {
                    version: PROTOCOL_VERSION,
                    realtime: false,
                    time_scale: mission.mission.time_scale,
                    epoch: UnixTime::default(),
                    tick: 0,
                    mission: digest,
                },
                ros2: ros2.take().map(|r| r.node),
            }),
            session: session.clone(),
            keys: keys.clone(),
            outlets: outlets.clone(),
            tick_out: Outlet::new(session, keys.tick()).await?,
            end_out: end_out.clone(),
            clock: clock.clone(),
            monotonic,
            rejected: rejected.clone(),
            timeouts: options.timeouts,
            ends: ends_tx,
            handovers: Mutex::new(Vec::new()),
        });
        // One subscription per vehicle, not one to cmd/*: Zenoh caches a route only for a key it
        // has a resource for, and on cmd/* it matched every arriving command against every key
        // the session knew (50 agents: the world's CPU 2.33 -> 1.80 s a run).
        let mut subscribers = Vec::with_capacity(ids.len());
        for id in ids {
            let to = stepper.clone();
            let take = move |key: &str, c| to.take(key, c);
            subscribers.push(subscribe_with::<Command>(session, &keys.cmd(id), &rejected, take).await?);
        }
        (subscribers, Inbound::Fed { stepper, ends })
    };
    let token = session
        .liveliness()
        .declare_token(keys.alive(Role::World, 0))
        .await
        .context("liveliness token")?;

    let mut heard = Waiting {
        changes: presence,
        shutdown: &mut shutdown,
        about: member,
        said: arrived,
    };
    let Ok(gathered) = drive(&mut gathering, &mut heard, monotonic).await;
    match gathered {
        Gathered::Complete => {}
        Gathered::Interrupted => return Ok((Exit::Interrupted, None)),
        Gathered::Closed => return Err(Error::Closed),
        Gathered::Missing(missing) => return Err(Error::Missing(missing)),
    }
    tracing::info!(
        "world: {} agents present, starting ({:?} clock, simulating vehicles {simulated:?})",
        ids.len(),
        mission.mission.clock
    );
    let mut shell = Shell {
        keys: keys.clone(),
        session: session.clone(),
        shutdown,
        rejected,
        timeouts: options.timeouts,
        presence,
        outlets,
        end_out,
        clock,
        ros2,
    };
    let exit = match inbound {
        Inbound::Queued(commands) => shell.realtime(mission, digest, &paths, &simulated, commands).await?,
        Inbound::Fed { stepper, mut ends } => shell.lockstep(&paths, &stepper, &mut ends).await?,
    };
    Ok((exit, Some(token)))
}

impl Shell<'_> {
    /// The world's exit report: a realtime world's timing with it.
    async fn report(&self, realtime: Option<RealtimeReport>) -> Result<()> {
        let timing = Timing::default();
        Ok(report(
            &self.session,
            &self.keys,
            (Role::World, 0),
            &self.rejected,
            &timing,
            realtime,
            &self.timeouts,
        )
        .await?)
    }

    async fn lockstep(
        &mut self,
        paths: &[(u32, GeneralizedPath)],
        stepper: &Stepper,
        ends: &mut UnboundedReceiver<Result<End, BusError>>,
    ) -> Result<Exit> {
        let ids: Vec<u32> = paths.iter().map(|p| p.0).collect();
        stepper.lock().clock.epoch = unix_now();
        stepper.with(|world, now, doing| world.start(now, doing));
        let mut machine = LockstepWorldTask::new(stepper);
        let mut wiring = Lockstep {
            shell: self,
            ids,
            ends,
            failed: None,
        };
        let Ok(exit) = drive(&mut machine, &mut wiring, stepper.monotonic).await;
        let (exit, end) = match exit {
            TaskExit::Ended(end) => {
                let exit = Exit::Ended {
                    ticks: end.ticks,
                    lost: end.lost.len(),
                    short: stepper.lock().world.not_arrived(),
                };
                (exit, Some(end))
            }
            // The end the interrupt published, unless one was out already.
            TaskExit::Interrupted => (Exit::Interrupted, wiring.ends.try_recv().ok().transpose()?),
            TaskExit::Failed => return Err(wiring.failed.take().expect("a failure keeps its error").into()),
        };
        let handing: Vec<_> = std::mem::take(&mut *stepper.handovers.lock().unwrap_or_else(|e| e.into_inner()));
        for loss in handing {
            let _ = loss.await;
        }
        if let Some(end) = &end {
            self.hand_over_end(end).await?;
        }
        self.report(None).await?;
        Ok(exit)
    }

    /// Hands the end over to the recorders: acknowledged, they have every tick before it too.
    async fn hand_over_end(&self, end: &End) -> Result<()> {
        hand_over(
            &self.session,
            &self.keys,
            self.keys.end(),
            end,
            "world: the end",
            &self.timeouts,
        )
        .await?;
        Ok(())
    }

    async fn realtime(
        &mut self,
        mission: &Mission,
        digest: u64,
        paths: &[(u32, GeneralizedPath)],
        simulated: &[u32],
        heard: Receiver<Received<Heard>>,
    ) -> Result<Exit> {
        let ids: Vec<u32> = paths.iter().map(|p| p.0).collect();
        let clock = Clock {
            version: PROTOCOL_VERSION,
            realtime: true,
            time_scale: mission.mission.time_scale,
            epoch: unix_now() + REALTIME_LEAD_S,
            tick: 0,
            mission: digest,
        };
        self.clock.set(clock);
        let control_period = mission.mission.control_period;
        let fleet = FleetClock::new(&clock, control_period);
        let mut machine = RealtimeWorldNode::new(
            RealtimeWorld::new(mission, paths, simulated),
            Played::new(mission, clock.epoch),
            ids.clone(),
            fleet.period().as_secs_f64(),
            control_period,
        );
        if let Some(ros2) = &mut self.ros2 {
            ros2.node.put_paths(paths, |t| Stamp::of_fleet(&clock, t))?;
            ros2.odometry = Some(ros2.node.listen(&self.rejected).await?);
        }
        // Before the first states: a recorder that missed them may ask at once.
        let (_history, mut fetches) = tcpf_bus::history::serve(&self.session, &self.keys, &self.rejected).await?;
        for (outlet, state) in self.outlets.iter().zip(machine.node().states()) {
            outlet.put(state).await?;
        }
        let mut wiring = Realtime {
            shell: self,
            heard,
            fetches: &mut fetches,
            beats: metronome(fleet, 0.0, 1),
            fleet,
            clock,
            control_period,
        };
        let RealtimeExit { end, interrupted } = drive(&mut machine, &mut wiring, Monotonic::start()).await?;
        let node = machine.node();
        let exit = match interrupted {
            true => Exit::Interrupted,
            false => Exit::Ended {
                ticks: end.ticks,
                lost: end.lost.len(),
                short: node.not_arrived(),
            },
        };
        // A recorder acknowledges the end once it has every tick before it: the states it lost
        // of the last ones, it fetches meanwhile.
        let handing = self.hand_over_end(&end);
        tokio::pin!(handing);
        loop {
            tokio::select! {
                handed = &mut handing => break handed?,
                Some(asked) = fetches.recv() => answer_fetch(node, asked),
            }
        }
        let timing = node.timing();
        tracing::info!(
            "world: period lateness p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms; {} overruns, {} skipped, {} late commands",
            timing.lateness_p50_ms,
            timing.lateness_p99_ms,
            timing.lateness_max_ms,
            timing.overruns,
            timing.skipped,
            timing.late_commands
        );
        self.report(Some(RealtimeReport {
            timing,
            published: 0,
            played: ids
                .iter()
                .filter(|id| !simulated.contains(id))
                .map(|&id| {
                    (
                        id,
                        if machine.played().heard(id) {
                            Player::Ros2
                        } else {
                            Player::Process
                        },
                    )
                })
                .collect(),
            wrong_frames: machine.played().wrong_frames(),
            surplus_odometries: machine.played().surplus(),
        }))
        .await?;
        Ok(exit)
    }
}

/// A realtime world's process for its machine: the metronome's beats, the commands and played
/// states (each checked for its sender's key), ROS 2 nodes' odometry, the recorders' questions,
/// the agents' liveliness and signals as inputs; each tick's states published, and the end.
struct Realtime<'s, 'a> {
    shell: &'s mut Shell<'a>,
    heard: Receiver<Received<Heard>>,
    fetches: &'s mut Receiver<Asked>,
    beats: Receiver<Beat>,
    fleet: FleetClock,
    clock: Clock,
    /// Simulated seconds a tick.
    control_period: f64,
}

type RealtimeNode = RealtimeWorldNode<String, Asked>;

impl Wiring<RealtimeNode> for Realtime<'_, '_> {
    type Error = Error;

    async fn next(&mut self) -> RealtimeInput<String, Asked> {
        let shell = &mut *self.shell;
        let horizon = || self.fleet.horizon();
        loop {
            tokio::select! {
                Some(beat) = self.beats.recv() => {
                    return RealtimeInput::Beat { tick: beat.tick, late_s: beat.late_s(), skipped: beat.skipped };
                }
                Some(asked) = self.fetches.recv() => return RealtimeInput::Fetch(asked),
                Some(h) = self.heard.recv() => match h.message {
                    Heard::Command(command) => if shell.rejected.from_sender(&h.key, command.id) {
                        return RealtimeInput::Command { command, horizon: horizon(), key: h.key };
                    },
                    Heard::State(state) => if shell.rejected.from_sender(&h.key, state.id) {
                        return RealtimeInput::Played { state, horizon: horizon(), key: h.key };
                    },
                },
                Some(o) = played_odometry(&mut shell.ros2) => {
                    let (id, cdr) = o.message;
                    return RealtimeInput::Odometry { id, cdr, horizon: horizon(), key: o.key };
                }
                Some(p) = shell.presence.recv() => if p.role == Role::Agent {
                    return RealtimeInput::Agent { id: p.id, alive: p.alive };
                },
                _ = shell.shutdown.recv() => return RealtimeInput::Interrupted,
            }
        }
    }

    async fn perform(
        &mut self,
        output: RealtimeOutput<String, Asked>,
        machine: &RealtimeNode,
    ) -> Result<Option<RealtimeInput<String, Asked>>> {
        let shell = &mut *self.shell;
        match output {
            RealtimeOutput::Tick(tick) => {
                let node = machine.node();
                shell.clock.set(Clock { tick, ..self.clock });
                for (outlet, state) in shell.outlets.iter().zip(node.states()) {
                    outlet.put(state).await?;
                }
                if let Some(ros2) = &mut shell.ros2 {
                    let t = tick as f64 * self.control_period;
                    let fleet = node.states().iter().chain(machine.played().states());
                    ros2.node.put(
                        fleet.map(|s| (s, node.command_of(s.id))),
                        Stamp::of_fleet(&self.clock, t),
                    )?;
                }
            }
            RealtimeOutput::End(end) => shell.end_out.put(&end).await?,
            RealtimeOutput::Answer(asked) => answer_fetch(machine.node(), asked),
            RealtimeOutput::PlayedState(state) => {
                if let Some(ros2) = &shell.ros2 {
                    ros2.outlets[&state.id].put(&state).await?;
                }
            }
            RealtimeOutput::Refused(why, key) => shell.rejected.reject(why, &key),
            RealtimeOutput::Invalid(why, key) => shell.rejected.invalid(why, &key),
            RealtimeOutput::WrongFrame { id, frame } => tracing::warn!(
                "world: vehicle {id}'s odometry is in frame '{frame}', not '{MAP_FRAME}', the fleet's: refused, as is every one not in '{MAP_FRAME}' (the summary counts them by frame)"
            ),
            RealtimeOutput::Agent { id, alive: true, t } => tracing::info!("world: agent {id} is here at t = {t:.2} s"),
            RealtimeOutput::Agent { id, alive: false, t } => {
                tracing::warn!("world: agent {id} is gone at t = {t:.2} s; its vehicle drifts until it comes back")
            }
        }
        Ok(None)
    }
}

/// A lockstep world's task: the agents' liveliness, the end and signals.
struct Lockstep<'s, 'a> {
    shell: &'s mut Shell<'a>,
    ids: Vec<u32>,
    ends: &'s mut UnboundedReceiver<Result<End, BusError>>,
    /// The error of a publication that failed.
    failed: Option<BusError>,
}

impl Wiring<LockstepWorldTask<'_, Stepper>> for Lockstep<'_, '_> {
    type Error = Infallible;

    async fn next(&mut self) -> TaskInput {
        loop {
            tokio::select! {
                Some(end) = self.ends.recv() => return match end {
                    Ok(end) => TaskInput::End(end),
                    Err(e) => {
                        self.failed = Some(e);
                        TaskInput::Failed
                    }
                },
                Some(p) = self.shell.presence.recv() => if p.role == Role::Agent && self.ids.contains(&p.id) {
                    return TaskInput::Agent(p.id, p.alive);
                },
                _ = self.shell.shutdown.recv() => return TaskInput::Interrupted,
            }
        }
    }

    async fn perform(
        &mut self,
        output: Infallible,
        _: &LockstepWorldTask<'_, Stepper>,
    ) -> Result<Option<TaskInput>, Infallible> {
        match output {}
    }
}

/// Whom a liveliness change is about, as the world gathers its fleet.
fn member(p: Presence) -> Option<Member> {
    match p.role {
        Role::Agent => Some(Member::Agent(p.id)),
        Role::Record => Some(Member::Recorder(p.id)),
        Role::World | Role::Planner => None,
    }
}

fn arrived(arrival: Arrival) {
    match arrival {
        Arrival::Agent { id, here, of } => tracing::info!("world: agent {id} is here ({here} of {of})"),
        Arrival::Recorder { here, of } => tracing::info!("world: a recorder is here ({here} of {of})"),
    }
}
