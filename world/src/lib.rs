//! tcpf-world: the world process. A Zenoh shell around core's `WorldNode`: it publishes every
//! vehicle's state, waits for every live agent's command and integrates; it is the lockstep clock.

use std::collections::BTreeSet;
use std::time::Duration;

use anyhow::{anyhow, Result};
use tcpf_bus::keys::{Keys, Role};
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_bus::typed::{fetch_paths, presence, report, subscribe, Outlet, Presence, Rejected};
use tcpf_core::lockstep::{Timing, WorldNode};
use tcpf_core::mission::Mission;
use tcpf_core::msg::{Command, Loss, LossReason, Lost, PROTOCOL_VERSION};

#[derive(Debug, Clone)]
pub struct Options {
    /// How long to wait for the planner and every agent (and recorder) at start.
    pub startup_timeout: Duration,
    /// Recorders to wait for before the first tick, so that they miss nothing.
    pub recorders: usize,
    /// How long a tick waits for a live agent's command before that vehicle is lost (silent).
    pub command_timeout: Duration,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exit {
    /// Every vehicle arrived (or was lost), or max_duration.
    Ended {
        ticks: u64,
        lost: usize,
    },
    Interrupted,
}

pub async fn run(mission: &Mission, zenoh: &ZenohArgs, options: &Options) -> Result<Exit> {
    let keys = Keys::new(&mission.mission.name);
    let mut shutdown = Shutdown::new()?;
    let session = zenoh.open().await?;
    let rejected = Rejected::default();
    let (_presence, mut presence) = presence(&session, &keys).await?;
    let ids: Vec<u32> = mission.vehicles.iter().map(|v| v.id).collect();
    let fetched = shutdown.unless(fetch_paths(&session, &keys, &ids, options.startup_timeout, &rejected));
    let Some(paths) = fetched.await else {
        return Ok(Exit::Interrupted);
    };
    let paths = paths?;
    let t_f = paths[0].1.t_f();
    let mut node = WorldNode::new(mission, &paths, t_f);
    let (_commands, mut commands) = subscribe::<Command>(&session, &keys.cmd("*"), &rejected).await?;
    let mut outlets = Vec::with_capacity(ids.len());
    for id in &ids {
        outlets.push(Outlet::new(&session, keys.state(id)).await?);
    }
    let end_out = Outlet::new(&session, keys.end()).await?;
    let token = session
        .liveliness()
        .declare_token(keys.alive(Role::World, 0))
        .await
        .map_err(|e| anyhow!("liveliness token: {e}"))?;

    let mut present: BTreeSet<(&'static str, u32)> = BTreeSet::new();
    let track = |p: Presence, present: &mut BTreeSet<(&'static str, u32)>| {
        if p.alive {
            present.insert((p.role.as_str(), p.id));
        } else {
            present.remove(&(p.role.as_str(), p.id));
        }
    };
    let agent = |id: &u32, present: &BTreeSet<(&'static str, u32)>| present.contains(&(Role::Agent.as_str(), *id));
    let recorders =
        |present: &BTreeSet<(&'static str, u32)>| present.iter().filter(|p| p.0 == Role::Record.as_str()).count();
    let deadline = tokio::time::Instant::now() + options.startup_timeout;
    loop {
        if ids.iter().all(|i| agent(i, &present)) && recorders(&present) >= options.recorders {
            break;
        }
        let Some(arrived) = shutdown
            .unless(tokio::time::timeout_at(deadline, presence.recv()))
            .await
        else {
            return Ok(Exit::Interrupted);
        };
        match arrived {
            Ok(Some(p)) => track(p, &mut present),
            Ok(None) => return Err(anyhow!("liveliness subscription closed")),
            Err(_) => {
                let missing: Vec<u32> = ids.iter().copied().filter(|i| !agent(i, &present)).collect();
                return Err(anyhow!(
                    "world: after {:?}, agents {missing:?} and {} of {} recorders still missing",
                    options.startup_timeout,
                    options.recorders.saturating_sub(recorders(&present)),
                    options.recorders
                ));
            }
        }
    }
    tracing::info!("world: {} agents present, starting", ids.len());

    let announce = |lost: Lost| {
        let (session, key) = (&session, keys.lost(lost.id));
        async move {
            let loss = Loss {
                version: PROTOCOL_VERSION,
                id: lost.id,
                tick: lost.tick,
                reason: lost.reason,
            };
            Outlet::new(session, key).await?.put(&loss).await
        }
    };
    let exit = 'run: loop {
        for (outlet, state) in outlets.iter().zip(node.states()) {
            outlet.put(state).await?;
        }
        let deadline = tokio::time::Instant::now() + options.command_timeout;
        while !node.waiting_for().is_empty() {
            tokio::select! {
                Some(c) = commands.recv() => {
                    if Keys::id_of(&c.key) != Some(c.message.id) {
                        rejected.wrong_sender(&c.key);
                    } else if let Err(e) = node.on_command(c.message) {
                        rejected.reject(e, &c.key);
                    }
                }
                Some(p) = presence.recv() => {
                    if p.role == Role::Agent && !p.alive && ids.contains(&p.id) {
                        tracing::warn!("world: agent {} is gone at t = {:.2} s; its vehicle drifts", p.id, node.states()[0].t);
                        if let Some(lost) = node.on_lost(p.id, LossReason::Gone) {
                            announce(lost).await?;
                        }
                    }
                }
                _ = tokio::time::sleep_until(deadline) => {
                    for id in node.waiting_for() {
                        tracing::warn!(
                            "world: agent {id} sent no command of t = {:.2} s within {:?}; its vehicle is lost and drifts",
                            node.states()[0].t,
                            options.command_timeout
                        );
                        if let Some(lost) = node.on_lost(id, LossReason::Silent) {
                            announce(lost).await?;
                        }
                    }
                }
                _ = shutdown.recv() => {
                    end_out.put(&node.interrupted()).await?;
                    break 'run Exit::Interrupted;
                }
            }
        }
        if let Some(end) = node.advance(|_, _| {}) {
            end_out.put(&end).await?;
            break Exit::Ended {
                ticks: end.ticks,
                lost: end.lost.len(),
            };
        }
    };
    tracing::info!("world: {exit:?}");
    report(&session, &keys, Role::World, 0, &rejected, &Timing::default()).await?;
    let _ = token.undeclare().await;
    let _ = session.close().await;
    Ok(exit)
}
