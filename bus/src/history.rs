//! The realtime world's history on the bus: the world serves `history` (what it answers is
//! `RealtimeWorld::answer`'s), and a recorder asks it for the states its `Sampler` never got.

use std::time::Duration;

use tcpf_core::msg::{Fetch, State};
use tokio::sync::mpsc;
use zenoh::query::{ConsolidationMode, Query, Queryable};
use zenoh::{Session, Wait};

use crate::codec::{decode, encode};
use crate::error::{failed, Result};
use crate::keys::Keys;
use crate::rejected::Rejected;
use crate::subscribe::{enqueue, Received};

/// Fetches the world may hold before the next are dropped (and counted): a recorder asks once
/// at a time.
const PENDING: usize = 64;

/// A recorder's fetch, for the world's loop to answer.
pub struct Asked {
    pub fetch: Fetch,
    query: Query,
}

/// The world's `history` queryable: each usable fetch goes to the world's loop, which answers it
/// with `answer`.
pub async fn serve(
    session: &Session,
    keys: &Keys,
    rejected: &Rejected,
) -> Result<(Queryable<()>, mpsc::Receiver<Asked>)> {
    let (tx, rx) = mpsc::channel(PENDING);
    let key = keys.history();
    let rejected = rejected.clone();
    let queryable = session
        .declare_queryable(key.clone())
        .callback(move |query| {
            let key = query.key_expr().as_str().to_string();
            let bytes = query.payload().map(|p| p.to_bytes().into_owned()).unwrap_or_default();
            match decode::<Fetch>(&bytes) {
                Ok(fetch) => {
                    if tx.try_send(Asked { fetch, query }).is_err() {
                        rejected.overflow(&key);
                    }
                }
                Err(e) => rejected.invalid(e, &key),
            }
        })
        .await
        .map_err(|e| failed!("cannot serve {key}: {e}"))?;
    Ok((queryable, rx))
}

/// Answers `asked` with the states the world's history holds of it, then, as an error reply,
/// the vehicles of which it keeps none.
pub fn answer<'a>(asked: &Asked, states: impl Iterator<Item = &'a State>, unkept: Vec<u32>) -> Result<()> {
    let key = asked.query.key_expr().clone();
    for state in states {
        asked
            .query
            .reply(key.clone(), encode(state))
            .wait()
            .map_err(|e| failed!("cannot answer {key}: {e}"))?;
    }
    if !unkept.is_empty() {
        let unkept = Fetch {
            ids: unkept,
            ..asked.fetch.clone()
        };
        asked
            .query
            .reply_err(encode(&unkept))
            .wait()
            .map_err(|e| failed!("cannot answer {key}: {e}"))?;
    }
    Ok(())
}

/// What the world's history gives a recorder that asked it.
#[derive(Debug)]
pub enum Answer {
    /// A state it kept.
    State(State),
    /// It has answered: with the vehicles it keeps none of (also when it did not answer within
    /// the wait, or at all, with none).
    Done(Vec<u32>),
}

/// Asks the world's history for `fetch` on a task of its own, waiting at most `within`: each
/// answer goes to `tx` as `answer(..)` makes it, the last one `Answer::Done`.
pub fn ask<M: Send + 'static>(
    session: &Session,
    keys: &Keys,
    fetch: Fetch,
    within: Duration,
    rejected: &Rejected,
    tx: mpsc::Sender<Received<M>>,
    answer: fn(Answer) -> M,
) {
    let (session, key, rejected) = (session.clone(), keys.history(), rejected.clone());
    tokio::spawn(async move {
        let mut unkept = Vec::new();
        // Every state, as it comes: each reply is on the same key, which consolidation would
        // keep one of.
        let get = session
            .get(key.clone())
            .payload(encode(&fetch))
            .consolidation(ConsolidationMode::None)
            .timeout(within);
        match get.await {
            Ok(replies) => {
                while let Ok(reply) = replies.recv_async().await {
                    match reply.result() {
                        Ok(sample) => match decode::<State>(&sample.payload().to_bytes()) {
                            Ok(s) => {
                                enqueue(&tx, &key, answer(Answer::State(s)), &rejected);
                            }
                            Err(e) => rejected.invalid(e, &key),
                        },
                        Err(error) => match decode::<Fetch>(&error.payload().to_bytes()) {
                            Ok(f) => unkept.extend(f.ids),
                            Err(e) => rejected.invalid(e, &key),
                        },
                    }
                }
            }
            Err(e) => tracing::warn!("recorder: cannot ask the world's history ({key}): {e}"),
        }
        // Sent even if the queue is full, or the rows would wait for it forever.
        let _ = tx
            .send(Received {
                key,
                message: answer(Answer::Done(unkept)),
            })
            .await;
    });
}
