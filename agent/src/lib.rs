//! tcpf-agent: the vehicle process. A Zenoh shell around core's `AgentNode`: it fetches its path,
//! takes the world's state, exchanges γ with its neighbours peer to peer and publishes commands.

use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use tcpf_bus::keys::{Keys, Role};
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_bus::typed::{fetch_paths, presence, queue, report, subscribe, subscribe_into, Outlet, Rejected};
use tcpf_core::agent::Agent;
use tcpf_core::lockstep::AgentNode;
use tcpf_core::mission::Mission;
use tcpf_core::msg::{Checked, End, Gamma, Loss, State};

/// How long to wait for the end message after the world or the planner went away.
const END_GRACE: Duration = Duration::from_millis(500);

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

pub async fn run(mission: &Mission, id: u32, zenoh: &ZenohArgs, options: &Options) -> Result<Exit> {
    if !mission.vehicles.iter().any(|v| v.id == id) {
        return Err(anyhow!("the mission has no vehicle with id {id}"));
    }
    let keys = Keys::new(&mission.mission.name);
    let mut shutdown = Shutdown::new()?;
    let session = zenoh.open().await?;
    let rejected = Rejected::default();
    let (_presence, mut presence) = presence(&session, &keys).await?;
    let ids = [id];
    let fetched = shutdown.unless(fetch_paths(&session, &keys, &ids, options.startup_timeout, &rejected));
    let Some(paths) = fetched.await else {
        return Ok(Exit::Interrupted);
    };
    let path = paths?[0].1;
    let agent = Agent::new(mission, id, path);
    let neighbours: Vec<u32> = agent.neighbours().collect();
    let mut node = AgentNode::new(agent);
    // A neighbour counts once its token is seen.
    for &j in &neighbours {
        node.set_gone(j, true);
    }

    let (_states, mut states) = subscribe::<State>(&session, &keys.state(id), &rejected).await?;
    let (gamma_tx, mut gammas) = queue();
    let mut gamma_subscribers = Vec::new();
    for &j in &neighbours {
        gamma_subscribers.push(subscribe_into::<Gamma>(&session, &keys.gamma(j), &rejected, gamma_tx.clone()).await?);
    }
    let (_ends, mut ends) = subscribe::<End>(&session, &keys.end(), &rejected).await?;
    let (_losses, mut losses) = subscribe::<Loss>(&session, &keys.lost("*"), &rejected).await?;
    let commands = Outlet::new(&session, keys.cmd(id)).await?;
    let gamma_out = Outlet::new(&session, keys.gamma(id)).await?;
    let token = session
        .liveliness()
        .declare_token(keys.alive(Role::Agent, id))
        .await
        .map_err(|e| anyhow!("liveliness token: {e}"))?;
    tracing::info!(
        "agent {id}: path with t_f = {:.3} s, neighbours {neighbours:?}",
        path.t_f()
    );

    // Start only once the world and every neighbour are known, so that the first tick waits for
    // exactly the neighbours every later tick waits for.
    let (mut world, mut planner) = (false, false);
    let deadline = tokio::time::Instant::now() + options.startup_timeout;
    while !(world && planner && node.all_present()) {
        let Some(arrived) = shutdown
            .unless(tokio::time::timeout_at(deadline, presence.recv()))
            .await
        else {
            return Ok(Exit::Interrupted);
        };
        match arrived {
            Ok(Some(p)) => match p.role {
                Role::World => world = p.alive,
                Role::Planner => planner = p.alive,
                Role::Agent if neighbours.contains(&p.id) => node.set_gone(p.id, !p.alive),
                _ => {}
            },
            Ok(None) => return Err(anyhow!("liveliness subscription closed")),
            Err(_) if !(world && planner) => {
                return Err(anyhow!(
                    "agent {id}: no world and planner for mission {} within {:?}",
                    mission.mission.name,
                    options.startup_timeout
                ))
            }
            Err(_) => {
                tracing::warn!("agent {id}: starting without neighbours {:?}", node.waiting_for());
                break;
            }
        }
    }

    let mut waiting_since: Option<Instant> = None;
    let exit = loop {
        while let Some(command) = node.command() {
            if !command.finite() {
                tracing::error!(
                    "agent {id}: the command of tick {} holds a non-finite number; the world refuses it and will give up on this vehicle",
                    command.tick
                );
            }
            commands.put(&command).await?;
        }
        let waiting = node.waiting_for();
        if waiting.is_empty() {
            waiting_since = None;
        }
        let since = *waiting_since.get_or_insert_with(Instant::now);
        let stale = tokio::time::sleep_until((since + options.stale_timeout).into());
        tokio::select! {
            Some(s) = states.recv() => match node.on_state(s.message) {
                Ok(Some(gamma)) => gamma_out.put(&gamma).await?,
                Ok(None) => {}
                Err(e) => rejected.reject(e, &s.key),
            },
            Some(g) = gammas.recv() => {
                if Keys::id_of(&g.key) != Some(g.message.from) {
                    rejected.wrong_sender(&g.key);
                } else if let Err(e) = node.on_gamma(g.message) {
                    rejected.reject(e, &g.key);
                }
            }
            Some(p) = presence.recv() => match p.role {
                Role::World | Role::Planner if !p.alive => {
                    // At the end the planner may leave before the world's end message reaches us.
                    if let Ok(Some(e)) = tokio::time::timeout(END_GRACE, ends.recv()).await {
                        if node.on_end(&e.message).is_ok() {
                            break Exit::Ended;
                        }
                    }
                    tracing::warn!("agent {id}: the {} is gone; stopping", p.role);
                    break Exit::Orphaned;
                }
                Role::Agent if neighbours.contains(&p.id) => node.set_gone(p.id, !p.alive),
                _ => {}
            },
            Some(e) = ends.recv() => match node.on_end(&e.message) {
                Ok(()) => break Exit::Ended,
                Err(why) => rejected.reject(why, &e.key),
            },
            Some(l) = losses.recv() => {
                if Keys::id_of(&l.key) != Some(l.message.id) {
                    rejected.wrong_sender(&l.key);
                } else if l.message.id == id {
                    tracing::warn!(
                        "agent {id}: the world gave up on this vehicle at tick {} ({:?}); stopping",
                        l.message.tick,
                        l.message.reason
                    );
                    break Exit::Lost;
                } else if neighbours.contains(&l.message.id) {
                    // Nobody waits for a lost vehicle's agent: neither the world nor its neighbours.
                    node.set_gone(l.message.id, true);
                }
            }
            _ = shutdown.recv() => break Exit::Interrupted,
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
    report(&session, &keys, Role::Agent, id, &rejected, node.timing()).await?;
    drop(gamma_subscribers);
    let _ = token.undeclare().await;
    let _ = session.close().await;
    Ok(exit)
}
