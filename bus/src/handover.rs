//! Last words that must reach the recorders (an exit report, the end, a loss) travel as a query
//! to every recorder's queryable, and each recorder's reply is its acknowledgement: the sender
//! knows who has them, instead of lingering a while and hoping. A recorder that did not answer
//! is asked again, up to `Timeouts::handover_attempts` times (`tcpf_core::fleet::handover`); what still
//! went unacknowledged is logged by the sender, and the recorder's summary names what never came
//! (an unreported role, a missed end).
//!
//! A query overtakes nothing sent before it on the same link, so a recorder that takes the end
//! has had every tick before it, or knows which it lost; it acknowledges the end once it has
//! fetched those from the world's history (`take_over_held`), which the world answers until
//! then.

use serde::de::DeserializeOwned;
use serde::Serialize;
use tcpf_core::fleet::handover::{Done, Handed, Handover, Step};
use tcpf_core::msg::Checked;
use tokio::sync::mpsc;
use zenoh::query::{ConsolidationMode, Query, QueryTarget, Queryable};
use zenoh::{Session, Wait};

use crate::clock::Monotonic;
use crate::codec::{decode, encode};
use crate::driver::{drive, Wiring};
use crate::error::{failed, Error, Result};
use crate::keys::{Keys, Role};
use crate::presence::present;
use crate::rejected::Rejected;
use crate::subscribe::{enqueue, Received};
use crate::waits::Timeouts;

/// Hands `message` over on `key` to every recorder of the mission and waits for their
/// acknowledgements (`tcpf_core::fleet::handover`), as often and as long as `timeouts` say;
/// `what` names it in the warning if some never came.
pub async fn hand_over<T: Serialize>(
    session: &Session,
    keys: &Keys,
    key: String,
    message: &T,
    what: &str,
    timeouts: &Timeouts,
) -> Result<Handed> {
    let mut handing = Handing {
        session,
        keys,
        key,
        payload: encode(message),
        what,
        timeouts,
    };
    let mut handover = Handover::new(timeouts.handover_attempts);
    let handed = drive(&mut handover, &mut handing, Monotonic::start()).await?;
    if handed.unacknowledged() > 0 {
        tracing::warn!(
            "{what}: {} of {} recorder(s) did not acknowledge it after {} attempts",
            handed.unacknowledged(),
            handed.recorders,
            handed.attempts
        );
    }
    Ok(handed)
}

/// A hand-over's steps: the recorders counted by their tokens, and asked by a query to all.
struct Handing<'a> {
    session: &'a Session,
    keys: &'a Keys,
    key: String,
    payload: Vec<u8>,
    what: &'a str,
    timeouts: &'a Timeouts,
}

impl Wiring<Handover<String>> for Handing<'_> {
    type Error = Error;

    async fn next(&mut self) -> Done<String> {
        std::future::pending().await
    }

    async fn perform(&mut self, step: Step, _: &Handover<String>) -> Result<Option<Done<String>>> {
        Ok(Some(match step {
            Step::Count => Done::Counted(
                present(self.session, self.keys, self.timeouts.presence_query)
                    .await?
                    .iter()
                    .filter(|(role, _)| *role == Role::Record)
                    .count(),
            ),
            Step::Ask => {
                let replies = self
                    .session
                    .get(self.key.clone())
                    .payload(self.payload.clone())
                    .target(QueryTarget::All)
                    .consolidation(ConsolidationMode::None)
                    .timeout(self.timeouts.handover_attempt)
                    .await
                    .map_err(|e| failed!("cannot hand over {}: {e}", self.what))?;
                let mut repliers = Vec::new();
                while let Ok(reply) = replies.recv_async().await {
                    if reply.result().is_ok() {
                        repliers.extend(reply.replier_id().map(|id| id.zid().to_string()));
                    }
                }
                Done::Answered(repliers)
            }
        }))
    }
}

/// A recorder's acknowledgement of one hand-over, for it to send once it has what the message
/// says it has (the end: every tick before it). Dropped unsent, the sender asks again.
pub struct Ack(Query);

impl Ack {
    pub fn send(self) {
        let key = self.0.key_expr().clone();
        if let Err(e) = self.0.reply(key.clone(), Vec::<u8>::new()).wait() {
            tracing::warn!("cannot acknowledge what came on {key}: {e}");
        }
    }
}

/// The recorder's side: takes what is handed over on `key` (each message wrapped by `wrap`, into
/// the channel its subscriptions share) and acknowledges it once it is queued. What cannot be
/// used is refused and counted, and not acknowledged; a full queue is counted and not
/// acknowledged either, so the sender asks again.
pub async fn take_over<T, M>(
    session: &Session,
    key: &str,
    rejected: &Rejected,
    tx: mpsc::Sender<Received<M>>,
    wrap: fn(T) -> M,
) -> Result<Queryable<()>>
where
    T: DeserializeOwned + Checked + Send + 'static,
    M: Send + 'static,
{
    declare(session, key, rejected, tx, move |message, ack| {
        (wrap(message), Some(ack))
    })
    .await
}

/// `take_over`, but the acknowledgement goes with the message, for the recorder to send once
/// it holds.
pub async fn take_over_held<T, M>(
    session: &Session,
    key: &str,
    rejected: &Rejected,
    tx: mpsc::Sender<Received<M>>,
    wrap: fn(T, Ack) -> M,
) -> Result<Queryable<()>>
where
    T: DeserializeOwned + Checked + Send + 'static,
    M: Send + 'static,
{
    declare(session, key, rejected, tx, move |message, ack| {
        (wrap(message, ack), None)
    })
    .await
}

/// The queryable of a hand-over: `deliver` makes the message to queue, and the acknowledgement
/// to send once it is queued, if it does not keep it.
async fn declare<T, M>(
    session: &Session,
    key: &str,
    rejected: &Rejected,
    tx: mpsc::Sender<Received<M>>,
    deliver: impl Fn(T, Ack) -> (M, Option<Ack>) + Send + Sync + 'static,
) -> Result<Queryable<()>>
where
    T: DeserializeOwned + Checked + Send + 'static,
    M: Send + 'static,
{
    let rejected = rejected.clone();
    session
        .declare_queryable(key)
        .callback(move |query| {
            let key = query.key_expr().as_str().to_string();
            let bytes = query.payload().map(|p| p.to_bytes().into_owned()).unwrap_or_default();
            let message = match decode::<T>(&bytes) {
                Ok(message) => message,
                Err(e) => return rejected.invalid(e, &key),
            };
            let (message, ack) = deliver(message, Ack(query));
            if enqueue(&tx, &key, message, &rejected) {
                ack.into_iter().for_each(Ack::send);
            }
        })
        .await
        .map_err(|e| failed!("cannot take over {key}: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lone_session;
    use tcpf_core::msg::{End, PROTOCOL_VERSION};

    /// The world waits for a recorder's acknowledgement of the end, asking again meanwhile, for
    /// as long as the recorder holds it (while it fetches the ticks it lost).
    #[tokio::test(flavor = "multi_thread")]
    async fn a_held_acknowledgement_keeps_the_sender_asking_until_it_is_sent() {
        let session = lone_session().await;
        let keys = Keys::new("held");
        let _token = session
            .liveliness()
            .declare_token(keys.alive(Role::Record, 0))
            .await
            .unwrap();
        let (tx, mut rx) = mpsc::channel(4);
        let rejected = Rejected::default();
        let _taken = take_over_held(&session, &keys.end(), &rejected, tx, |end: End, ack| (end, ack))
            .await
            .unwrap();
        let end = End {
            version: PROTOCOL_VERSION,
            ticks: 42,
            lost: vec![],
            arrived: vec![],
        };
        let sender = {
            let (session, keys, end) = (session.clone(), keys.clone(), end.clone());
            tokio::spawn(
                async move { hand_over(&session, &keys, keys.end(), &end, "the end", &Timeouts::default()).await },
            )
        };
        let (first, held) = rx.recv().await.unwrap().message;
        assert_eq!(first, end);
        let (again, ack) = rx.recv().await.unwrap().message;
        assert_eq!(again, end, "asked again once an attempt went unanswered");
        assert!(!sender.is_finished());
        held.send();
        ack.send();
        let handed = sender.await.unwrap().unwrap();
        assert_eq!(
            handed,
            Handed {
                acknowledged: 1,
                recorders: 1,
                attempts: 2
            }
        );
        assert_eq!(rejected.totals(), Default::default());
    }
}
