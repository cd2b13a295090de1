//! `tcpf planner`: solves MODEL §1 and serves each vehicle's generalized path, as a queryable (an
//! agent that starts late or restarts gets its path) and once as a publication.

use std::convert::Infallible;

use tcpf_bus::clock::Monotonic;
use tcpf_bus::codec::encode;
use tcpf_bus::driver::drive;
use tcpf_bus::exit_report::report;
use tcpf_bus::keys::{Keys, Role};
use tcpf_bus::presence::{presence, Presence};
use tcpf_bus::rejected::Rejected;
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_bus::subscribe::{subscribe, Received};
use tcpf_bus::waits::Timeouts;
use tcpf_core::mission::Mission;
use tcpf_core::model::planner::Plan;
use tcpf_core::msg::{End, PathMsg, PROTOCOL_VERSION};
use tcpf_core::roles::lockstep::Timing;
use tcpf_core::roles::planner_node::{Input, PlannerNode};
use tokio::sync::mpsc::{Receiver, UnboundedReceiver};
use zenoh::handlers::FifoChannelHandler;
use zenoh::key_expr::KeyExpr;
use zenoh::query::{Query, Queryable};
use zenoh::Wait;

use crate::error::{failed, Result};

pub use tcpf_core::roles::planner_node::Exit;

/// Serves `plan` until the world goes away (having announced the end, or not), or a signal.
pub async fn run(mission: &Mission, plan: &Plan, zenoh: &ZenohArgs, timeouts: &Timeouts) -> Result<Exit> {
    let keys = Keys::new(&mission.mission.name);
    let mut shutdown = Shutdown::new()?;
    let session = zenoh.open_unless(&mut shutdown, timeouts.startup).await?;
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
        .map_err(|e| failed!("cannot serve {}: {e}", keys.plan("*")))?;
    let (_presence, presence) = presence(&session, &keys).await?;
    let (_ends, ends) = subscribe::<End>(&session, &keys.end(), &rejected).await?;
    for (key, bytes) in &paths {
        session
            .put(key.clone(), bytes.clone())
            .await
            .map_err(|e| failed!("publish {key}: {e}"))?;
    }
    let token = session
        .liveliness()
        .declare_token(keys.alive(Role::Planner, 0))
        .await
        .map_err(|e| failed!("liveliness token: {e}"))?;
    tracing::info!(
        "planner: t_f = {:.3} s for {} vehicles, serving {}",
        plan.t_f,
        paths.len(),
        keys.plan("*")
    );

    let mut wiring = Wiring {
        paths,
        queryable,
        presence,
        ends,
        shutdown,
    };
    let mut machine = PlannerNode::new(timeouts.end_after_the_world);
    let Ok(exit) = drive(&mut machine, &mut wiring, Monotonic::start()).await;
    tracing::info!("planner: {exit}");
    report(
        &session,
        &keys,
        (Role::Planner, 0),
        &rejected,
        &Timing::default(),
        None,
        timeouts,
    )
    .await?;
    let _ = token.undeclare().await;
    let _ = session.close().await;
    Ok(exit)
}

/// The planner's process: the world's liveliness, ends and signals for its machine. It answers
/// the queries for paths itself, which the machine has no say in.
struct Wiring {
    paths: Vec<(KeyExpr<'static>, Vec<u8>)>,
    queryable: Queryable<FifoChannelHandler<Query>>,
    presence: UnboundedReceiver<Presence>,
    ends: Receiver<Received<End>>,
    shutdown: Shutdown,
}

impl tcpf_bus::driver::Wiring<PlannerNode> for Wiring {
    type Error = Infallible;

    async fn next(&mut self) -> Input {
        loop {
            tokio::select! {
                Ok(query) = self.queryable.recv_async() => {
                    for (key, bytes) in self.paths.iter().filter(|(k, _)| k.intersects(query.key_expr())) {
                        if let Err(e) = query.reply(key.clone(), bytes.clone()).wait() {
                            tracing::warn!("planner: reply on {key} failed: {e}");
                        }
                    }
                }
                Some(p) = self.presence.recv() => if p.role == Role::World {
                    return Input::World(p.alive);
                },
                Some(_) = self.ends.recv() => return Input::End,
                _ = self.shutdown.recv() => return Input::Interrupted,
            }
        }
    }

    async fn perform(&mut self, output: Infallible, _: &PlannerNode) -> Result<Option<Input>, Infallible> {
        match output {}
    }
}
