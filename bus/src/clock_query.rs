//! The fleet's clock on the bus: the world answers it, the others ask it.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::{anyhow, Result};
use tcpf_core::msg::Clock;
use tokio::sync::oneshot;
use zenoh::query::{ConsolidationMode, QueryTarget};
use zenoh::{Session, Wait};

use crate::codec::{decode, encode};
use crate::keys::{Keys, Role};
use crate::rejected::Rejected;
use crate::waits;

/// The world's side of the clock: a queryable that answers once the run has started, with the
/// tick under way.
pub struct ClockServer {
    clock: Arc<Mutex<Option<Clock>>>,
    _queryable: zenoh::query::Queryable<()>,
}

impl ClockServer {
    /// Declare it before the world's token, so that whoever sees the world can ask it.
    pub async fn declare(session: &Session, keys: &Keys) -> Result<ClockServer> {
        let clock: Arc<Mutex<Option<Clock>>> = Arc::default();
        let shared = clock.clone();
        let key = keys.clock();
        let queryable = session
            .declare_queryable(key.clone())
            .callback(move |query| {
                let now = *shared.lock().unwrap_or_else(|e| e.into_inner());
                if let Some(clock) = now {
                    let _ = query.reply(query.key_expr().clone(), encode(&clock)).wait();
                }
            })
            .await
            .map_err(|e| anyhow!("cannot serve {key}: {e}"))?;
        Ok(ClockServer {
            clock,
            _queryable: queryable,
        })
    }

    /// The run has started, or is at `clock.tick`.
    pub fn set(&self, clock: Clock) {
        *self.clock.lock().unwrap_or_else(|e| e.into_inner()) = Some(clock);
    }
}

/// Asks the world for its clock once: `None` if the run has not started (or no world answers).
pub async fn ask_clock(session: &Session, keys: &Keys, rejected: &Rejected) -> Result<Option<Clock>> {
    let key = keys.clock();
    // Only the world that holds its role answers for the fleet's clock: another process that
    // answers is counted, and not listened to.
    let Some(world) = crate::claim::holder(session, keys, Role::World, 0).await? else {
        return Ok(None);
    };
    // Every answer, not one per key: the world's must not be consolidated away behind another's.
    let replies = session
        .get(key.clone())
        .target(QueryTarget::All)
        .consolidation(ConsolidationMode::None)
        .timeout(waits::CLOCK_QUERY)
        .await
        .map_err(|e| anyhow!("cannot query {key}: {e}"))?;
    let mut found = None;
    while let Ok(reply) = replies.recv_async().await {
        let Ok(sample) = reply.result() else { continue };
        if reply.replier_id().map(|id| id.zid().to_string()) != Some(world.session.clone()) {
            rejected.wrong_sender(&key);
            continue;
        }
        match decode::<Clock>(&sample.payload().to_bytes()) {
            Ok(clock) => found = found.or(Some(clock)),
            Err(e) => rejected.invalid(e, &key),
        }
    }
    Ok(found)
}

/// The world's clock, asked for until the world answers (it does once the run has started).
pub type ClockAnswer = oneshot::Receiver<Result<Clock>>;

/// Asks for the world's clock until it answers, first after `first`, then twice as long each
/// time up to `max` (a fleet of hundreds waiting for its world must not flood the router), on a
/// task of its own: a query dropped halfway (by a `select!` that went another way) would leave
/// its reply a closed channel. Dropping the receiver stops the asking.
pub fn await_clock(session: &Session, keys: &Keys, rejected: &Rejected, first: Duration, max: Duration) -> ClockAnswer {
    let (tx, rx) = oneshot::channel();
    let (session, keys, rejected) = (session.clone(), keys.clone(), rejected.clone());
    tokio::spawn(async move {
        let mut wait = first;
        while !tx.is_closed() {
            let answer = match ask_clock(&session, &keys, &rejected).await {
                Ok(None) => {
                    tokio::time::sleep(wait).await;
                    wait = (wait * 2).min(max);
                    continue;
                }
                Ok(Some(clock)) => Ok(clock),
                Err(e) => Err(e),
            };
            let _ = tx.send(answer);
            return;
        }
    });
    rx
}

/// The clock `await_clock` got; never, while `answer` is `None` (for a `select!` branch).
pub async fn answered(answer: &mut Option<ClockAnswer>) -> Result<Clock> {
    match answer {
        Some(answer) => answer
            .await
            .map_err(|_| anyhow!("the task asking for the world's clock stopped"))?,
        None => std::future::pending().await,
    }
}
