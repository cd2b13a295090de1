//! `tcpf planner`: solves MODEL §1 and serves each vehicle's generalized path, as a queryable (an
//! agent that starts late or restarts gets its path) and once as a publication.

use anyhow::{anyhow, Result};
use tcpf_bus::alarm::Alarm;
use tcpf_bus::clock::Monotonic;
use tcpf_bus::codec::encode;
use tcpf_bus::exit_report::report;
use tcpf_bus::keys::{Keys, Role};
use tcpf_bus::presence::presence;
use tcpf_bus::rejected::Rejected;
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_bus::subscribe::subscribe;
use tcpf_bus::waits;
use tcpf_core::mission::Mission;
use tcpf_core::model::planner::Plan;
use tcpf_core::msg::{End, PathMsg, PROTOCOL_VERSION};
use tcpf_core::roles::lockstep::Timing;
use tcpf_core::roles::planner_node::{Input, PlannerNode};
use zenoh::key_expr::KeyExpr;

pub use tcpf_core::roles::planner_node::Exit;

/// Serves `plan` until the world goes away (having announced the end, or not), or a signal.
pub async fn run(mission: &Mission, plan: &Plan, zenoh: &ZenohArgs) -> Result<Exit> {
    let keys = Keys::new(&mission.mission.name);
    let mut shutdown = Shutdown::new()?;
    // The planner has no --startup-timeout: it waits for its router as long as the other roles
    // do by default.
    let session = zenoh.open_unless(&mut shutdown, waits::STARTUP).await?;
    let rejected = Rejected::default();
    let paths: Vec<(KeyExpr<'static>, Vec<u8>)> = plan
        .vehicles
        .iter()
        .map(|v| {
            let key = KeyExpr::try_from(keys.plan(v.id)).expect("mission names are valid key chunks");
            (
                key,
                encode(&PathMsg {
                    version: PROTOCOL_VERSION,
                    id: v.id,
                    path: v.path,
                }),
            )
        })
        .collect();
    let queryable = session
        .declare_queryable(keys.plan("*"))
        .await
        .map_err(|e| anyhow!("cannot serve {}: {e}", keys.plan("*")))?;
    let (_presence, mut presence) = presence(&session, &keys).await?;
    let (_ends, mut ends) = subscribe::<End>(&session, &keys.end(), &rejected).await?;
    for (key, bytes) in &paths {
        session
            .put(key.clone(), bytes.clone())
            .await
            .map_err(|e| anyhow!("publish {key}: {e}"))?;
    }
    let token = session
        .liveliness()
        .declare_token(keys.alive(Role::Planner, 0))
        .await
        .map_err(|e| anyhow!("liveliness token: {e}"))?;
    tracing::info!(
        "planner: t_f = {:.3} s for {} vehicles, serving {}",
        plan.t_f,
        paths.len(),
        keys.plan("*")
    );

    let monotonic = Monotonic::start();
    let mut machine = PlannerNode::new(waits::END_AFTER_THE_WORLD);
    let mut alarm = Alarm::new(monotonic);
    let exit = loop {
        if let Some(exit) = machine.exit() {
            break exit;
        }
        alarm.set(machine.poll_timeout());
        tokio::select! {
            Ok(query) = queryable.recv_async() => {
                for (key, bytes) in paths.iter().filter(|(k, _)| k.intersects(query.key_expr())) {
                    if let Err(e) = query.reply(key.clone(), bytes.clone()).await {
                        tracing::warn!("planner: reply on {key} failed: {e}");
                    }
                }
            }
            Some(p) = presence.recv() => if p.role == Role::World {
                machine.handle(Input::World(p.alive), monotonic.now());
            },
            Some(_) = ends.recv() => machine.handle(Input::End, monotonic.now()),
            _ = shutdown.recv() => machine.handle(Input::Interrupted, monotonic.now()),
            _ = alarm.rung() => {
                machine.handle_timeout(monotonic.now());
            }
        }
    };
    tracing::info!("planner: {exit}");
    report(&session, &keys, Role::Planner, 0, &rejected, &Timing::default(), None).await?;
    let _ = token.undeclare().await;
    let _ = session.close().await;
    Ok(exit)
}
