//! tcpf-agent: the vehicle process. A Zenoh shell around core's `AgentNode` (lockstep) or
//! `RealtimeAgent` (realtime): it fetches its path, takes its vehicle's state, exchanges γ with
//! its neighbours and publishes commands. Started while the run is under way, it rejoins.

use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use tcpf_bus::clock::{metronome, FleetClock};
use tcpf_bus::keys::{Keys, Role};
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_bus::typed::{
    ask_clock, fetch_paths, presence, queue, report, subscribe, subscribe_into, Outlet, Presence, Received, Rejected,
};
use tcpf_core::agent::Agent;
use tcpf_core::lockstep::{AgentNode, Timing};
use tcpf_core::mission::{ClockKind, Mission};
use tcpf_core::msg::{Checked, Clock, Command, End, Gamma, Loss, State};
use tcpf_core::realtime::RealtimeAgent;
use tokio::sync::mpsc::{Receiver, UnboundedReceiver};
use zenoh::pubsub::Subscriber;
use zenoh::Session;

/// How long to wait for the end message after the world or the planner went away.
const END_GRACE: Duration = Duration::from_millis(500);
/// How often a realtime agent asks for the clock while the world has not started.
const CLOCK_POLL: Duration = Duration::from_millis(50);
/// Where in its period a realtime agent acts: after the world published the period's states,
/// and early enough that its command reaches the world before the next.
const AGENT_PHASE: f64 = 0.5;

#[derive(Debug, Clone)]
pub struct Options {
    /// How long to wait for the planner, the world and the neighbours at start.
    pub startup_timeout: Duration,
    /// A live neighbour whose γ has not come for this long stops being counted.
    pub stale_timeout: Duration,
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

/// A clock this agent cannot run with: bad input, not a failure of the run.
#[derive(Debug)]
pub struct WrongClock(pub String);

impl std::fmt::Display for WrongClock {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for WrongClock {}

/// What both clocks' loops work with.
struct Shell {
    id: u32,
    neighbours: Vec<u32>,
    keys: Keys,
    session: Session,
    shutdown: Shutdown,
    rejected: Rejected,
    presence: UnboundedReceiver<Presence>,
    states: Receiver<Received<State>>,
    gammas: Receiver<Received<Gamma>>,
    ends: Receiver<Received<End>>,
    losses: Receiver<Received<Loss>>,
    commands: Outlet,
    gamma_out: Outlet,
    _subscribers: Vec<Subscriber<()>>,
}

pub async fn run(mission: &Mission, id: u32, zenoh: &ZenohArgs, options: &Options) -> Result<Exit> {
    if !mission.vehicles.iter().any(|v| v.id == id) {
        return Err(anyhow!("the mission has no vehicle with id {id}"));
    }
    let realtime = mission.mission.clock == ClockKind::Realtime;
    let keys = Keys::new(&mission.mission.name);
    let mut shutdown = Shutdown::new()?;
    let session = zenoh.open().await?;
    let rejected = Rejected::default();
    let (presence_subscriber, mut presence) = presence(&session, &keys).await?;
    let ids = [id];
    let fetched = shutdown.unless(fetch_paths(&session, &keys, &ids, options.startup_timeout, &rejected));
    let Some(paths) = fetched.await else {
        return Ok(Exit::Interrupted);
    };
    let path = paths?[0].1;
    let agent = Agent::new(mission, id, path);
    let neighbours: Vec<u32> = agent.neighbours().collect();

    let (s1, states) = subscribe::<State>(&session, &keys.state(id), &rejected).await?;
    let (gamma_tx, gammas) = queue();
    let mut subscribers = vec![s1];
    for &j in &neighbours {
        subscribers.push(subscribe_into::<Gamma>(&session, &keys.gamma(j), &rejected, gamma_tx.clone()).await?);
    }
    let (s2, ends) = subscribe::<End>(&session, &keys.end(), &rejected).await?;
    let (s3, losses) = subscribe::<Loss>(&session, &keys.lost("*"), &rejected).await?;
    subscribers.extend([s2, s3, presence_subscriber]);
    let commands = Outlet::for_clock(&session, keys.cmd(id), realtime).await?;
    let gamma_out = Outlet::gamma(&session, keys.gamma(id), realtime).await?;
    tracing::info!(
        "agent {id}: path with t_f = {:.3} s, neighbours {neighbours:?}",
        path.t_f()
    );

    // The world's token first: its clock is declared before it, so whether the run is under way
    // (the clock answers) is then known for sure.
    let (mut world, mut planner) = (false, false);
    let mut present: Vec<u32> = Vec::new();
    let deadline = tokio::time::Instant::now() + options.startup_timeout;
    let mut note = |p: Presence, world: &mut bool, planner: &mut bool| match p.role {
        Role::World => *world = p.alive,
        Role::Planner => *planner = p.alive,
        Role::Agent if neighbours.contains(&p.id) => {
            present.retain(|&j| j != p.id);
            if p.alive {
                present.push(p.id);
            }
        }
        _ => {}
    };
    while !(world && planner) {
        let Some(arrived) = shutdown
            .unless(tokio::time::timeout_at(deadline, presence.recv()))
            .await
        else {
            return Ok(Exit::Interrupted);
        };
        match arrived {
            Ok(Some(p)) => note(p, &mut world, &mut planner),
            Ok(None) => return Err(anyhow!("liveliness subscription closed")),
            Err(_) => {
                return Err(anyhow!(
                    "agent {id}: no world and planner for mission {} within {:?}",
                    mission.mission.name,
                    options.startup_timeout
                ))
            }
        }
    }
    let under_way = ask_clock(&session, &keys, &rejected).await?;
    if let Some(clock) = &under_way {
        check_clock(mission, clock)?;
        tracing::info!("agent {id}: the run is under way (tick {}); rejoining it", clock.tick);
    }
    let token = session
        .liveliness()
        .declare_token(keys.alive(Role::Agent, id))
        .await
        .map_err(|e| anyhow!("liveliness token: {e}"))?;
    let mut shell = Shell {
        id,
        neighbours: neighbours.clone(),
        keys,
        session,
        shutdown,
        rejected,
        presence,
        states,
        gammas,
        ends,
        losses,
        commands,
        gamma_out,
        _subscribers: subscribers,
    };

    let exit = if realtime {
        let clock = match under_way {
            Some(clock) => Some(clock),
            None => shell.wait_for_clock(mission, deadline).await?,
        };
        match clock {
            Some(clock) => shell.realtime(mission, agent, &clock, options).await?,
            None => Exit::Interrupted,
        }
    } else {
        let mut node = AgentNode::new(agent);
        if under_way.is_some() {
            node.rejoin();
        } else {
            // A neighbour counts once its token is seen, so that the first tick waits for
            // exactly the neighbours every later tick waits for.
            for &j in &neighbours {
                node.set_gone(j, !present.contains(&j));
            }
            while !node.all_present() {
                let Some(arrived) = shell
                    .shutdown
                    .unless(tokio::time::timeout_at(deadline, shell.presence.recv()))
                    .await
                else {
                    return Ok(Exit::Interrupted);
                };
                match arrived {
                    Ok(Some(p)) if p.role == Role::Agent && neighbours.contains(&p.id) => node.set_gone(p.id, !p.alive),
                    Ok(Some(_)) => {}
                    Ok(None) => return Err(anyhow!("liveliness subscription closed")),
                    Err(_) => {
                        tracing::warn!("agent {id}: starting without neighbours {:?}", node.waiting_for());
                        break;
                    }
                }
            }
        }
        shell.lockstep(node, options).await?
    };
    let _ = token.undeclare().await;
    let _ = shell.session.close().await;
    Ok(exit)
}

/// One time scale and one kind of clock for the whole fleet.
fn check_clock(mission: &Mission, clock: &Clock) -> Result<()> {
    let realtime = mission.mission.clock == ClockKind::Realtime;
    if clock.realtime != realtime {
        let kind = |r: bool| if r { "realtime" } else { "lockstep" };
        return Err(WrongClock(format!(
            "this agent runs the {} clock but the world runs {}: start every role with the same --clock",
            kind(realtime),
            kind(clock.realtime)
        ))
        .into());
    }
    if realtime && clock.time_scale != mission.mission.time_scale {
        return Err(WrongClock(format!(
            "this agent runs at time scale {} but the world at {}: start every role with the same --time-scale",
            mission.mission.time_scale, clock.time_scale
        ))
        .into());
    }
    Ok(())
}

impl Shell {
    /// Realtime: asks for the world's clock until it has started (`None` on a signal).
    async fn wait_for_clock(&mut self, mission: &Mission, deadline: tokio::time::Instant) -> Result<Option<Clock>> {
        loop {
            if let Some(clock) = ask_clock(&self.session, &self.keys, &self.rejected).await? {
                check_clock(mission, &clock)?;
                return Ok(Some(clock));
            }
            if tokio::time::Instant::now() >= deadline {
                return Err(anyhow!(
                    "agent {}: the world did not start the clock of mission {} in time",
                    self.id,
                    mission.mission.name
                ));
            }
            if self.shutdown.unless(tokio::time::sleep(CLOCK_POLL)).await.is_none() {
                return Ok(None);
            }
        }
    }

    async fn publish(&self, command: &Command) -> Result<()> {
        if !command.finite() {
            tracing::error!(
                "agent {}: the command of tick {} holds a non-finite number; the world refuses it",
                self.id,
                command.tick
            );
        }
        self.commands.put(command).await
    }

    /// An `End` from the world, or the world or planner gone: whether to stop, and why.
    async fn world_gone(&mut self, role: Role, accept: impl Fn(&End) -> bool) -> Exit {
        // At the end the planner may leave before the world's end message reaches us.
        if let Ok(Some(e)) = tokio::time::timeout(END_GRACE, self.ends.recv()).await {
            if accept(&e.message) {
                return Exit::Ended;
            }
        }
        tracing::warn!("agent {}: the {role} is gone; stopping", self.id);
        Exit::Orphaned
    }

    async fn lockstep(&mut self, mut node: AgentNode, options: &Options) -> Result<Exit> {
        let id = self.id;
        let mut waiting_since: Option<Instant> = None;
        let exit = loop {
            while let Some(command) = node.command() {
                self.publish(&command).await?;
            }
            let waiting = node.waiting_for();
            if waiting.is_empty() {
                waiting_since = None;
            }
            let since = *waiting_since.get_or_insert_with(Instant::now);
            let stale = tokio::time::sleep_until((since + options.stale_timeout).into());
            tokio::select! {
                Some(s) = self.states.recv() => match node.on_state(s.message) {
                    Ok(Some(gamma)) => self.gamma_out.put(&gamma).await?,
                    Ok(None) => {}
                    Err(e) => self.rejected.reject(e, &s.key),
                },
                Some(g) = self.gammas.recv() => {
                    self.rejected.check(&g.key, g.message.from, || node.on_gamma(g.message));
                }
                Some(p) = self.presence.recv() => match p.role {
                    Role::World | Role::Planner if !p.alive => {
                        break self.world_gone(p.role, |e| node.on_end(e).is_ok()).await;
                    }
                    Role::Agent if self.neighbours.contains(&p.id) => node.set_gone(p.id, !p.alive),
                    _ => {}
                },
                Some(e) = self.ends.recv() => match node.on_end(&e.message) {
                    Ok(()) => break Exit::Ended,
                    Err(why) => self.rejected.reject(why, &e.key),
                },
                Some(l) = self.losses.recv() => {
                    if Keys::id_of(&l.key) != Some(l.message.id) {
                        self.rejected.wrong_sender(&l.key);
                    } else if l.message.id == id {
                        tracing::warn!(
                            "agent {id}: the world gave up on this vehicle at tick {} ({:?}); stopping",
                            l.message.tick,
                            l.message.reason
                        );
                        break Exit::Lost;
                    } else if self.neighbours.contains(&l.message.id) {
                        // Nobody waits for a lost vehicle's agent: neither the world nor its neighbours.
                        node.set_gone(l.message.id, true);
                    }
                }
                _ = self.shutdown.recv() => break Exit::Interrupted,
                _ = stale, if !waiting.is_empty() => {
                    for j in waiting {
                        tracing::warn!(
                            "agent {id}: neighbour {j} silent for {:?}; going on without it until it speaks again (the run is no longer reproducible)",
                            options.stale_timeout
                        );
                        node.on_stale(j);
                    }
                }
            }
        };
        tracing::info!("agent {id}: {exit:?} at γ = {:.3}", node.agent().gamma());
        report(
            &self.session,
            &self.keys,
            Role::Agent,
            id,
            &self.rejected,
            node.timing(),
            None,
        )
        .await?;
        Ok(exit)
    }

    async fn realtime(&mut self, mission: &Mission, agent: Agent, clock: &Clock, options: &Options) -> Result<Exit> {
        let id = self.id;
        // When the world went out of reach, and until when to wait for it: on a testbed a link
        // that drops for a while must not end the vehicle's mission.
        let mut away: Option<tokio::time::Instant> = None;
        let mut published = 0;
        let fleet = FleetClock::new(clock, mission.mission.control_period);
        let period = fleet.period().as_secs_f64();
        // γ_i starts from the vehicle's position: at its start for an agent there from the
        // beginning, wherever it is for one started again.
        let mut node = RealtimeAgent::new(agent, true);
        let mut beats = metronome(fleet, AGENT_PHASE, fleet.periods_now().floor() as u64);
        let exit = loop {
            tokio::select! {
                Some(beat) = beats.recv() => {
                    if let Some(action) = node.act(beat.tick, beat.late_s(), period, beat.skipped) {
                        if let Some(gamma) = action.gamma {
                            self.gamma_out.put(&gamma).await?;
                            published += 1;
                        }
                        self.publish(&action.command).await?;
                    }
                }
                Some(s) = self.states.recv() => {
                    if let Err(e) = node.on_state(s.message) {
                        self.rejected.reject(e, &s.key);
                    }
                }
                Some(g) = self.gammas.recv() => {
                    self.rejected.check(&g.key, g.message.from, || node.on_gamma(g.message));
                }
                Some(p) = self.presence.recv() => {
                    if p.role == Role::World && !p.alive && away.is_none() {
                        tracing::warn!(
                            "agent {id}: the world is out of reach; acting on what it last sent, and waiting up to {:?} for it",
                            options.startup_timeout
                        );
                        away = Some(tokio::time::Instant::now() + options.startup_timeout);
                    } else if p.role == Role::World && p.alive && away.take().is_some() {
                        tracing::info!("agent {id}: the world is back");
                    }
                }
                _ = tokio::time::sleep_until(away.unwrap_or_else(tokio::time::Instant::now)), if away.is_some() => {
                    tracing::warn!("agent {id}: the world did not come back; stopping");
                    break Exit::Orphaned;
                }
                Some(_) = self.ends.recv() => break Exit::Ended,
                Some(_) = self.losses.recv() => {}
                _ = self.shutdown.recv() => break Exit::Interrupted,
            }
        };
        let timing = node.timing();
        tracing::info!(
            "agent {id}: {exit:?} at γ = {:.3}; period lateness p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms; {} overruns, {} skipped, {} stale states",
            node.agent().gamma(),
            timing.lateness_p50_ms,
            timing.lateness_p99_ms,
            timing.lateness_max_ms,
            timing.overruns,
            timing.skipped,
            timing.stale_states
        );
        report(
            &self.session,
            &self.keys,
            Role::Agent,
            id,
            &self.rejected,
            &Timing::default(),
            Some((timing, published)),
        )
        .await?;
        Ok(exit)
    }
}
