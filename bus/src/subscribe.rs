//! Typed subscribers. A subscriber's callback only decodes and forwards, to a queue or straight
//! to a core machine: what to do with a message is the machines' business. Refused payloads are
//! counted (`Rejected`), never fatal.

use serde::de::DeserializeOwned;
use tcpf_core::msg::Checked;
use tokio::sync::mpsc;
use zenoh::pubsub::Subscriber;
use zenoh::sample::Locality;
use zenoh::Session;

use crate::codec::decode;
use crate::error::{failed, Result};
use crate::rejected::Rejected;

/// How many messages a subscription may hold before the next are dropped (and counted). Lockstep
/// has a few per tick in flight; the bound is for floods.
pub const QUEUE: usize = 8192;

/// A bounded queue for `subscribe_into`.
pub fn queue<T>() -> (mpsc::Sender<Received<T>>, mpsc::Receiver<Received<T>>) {
    mpsc::channel(QUEUE)
}

/// A message and the key it came on.
pub struct Received<T> {
    pub key: String,
    pub message: T,
}

/// Subscribes to `key` and forwards every usable message of type T.
pub async fn subscribe<T>(
    session: &Session,
    key: &str,
    rejected: &Rejected,
) -> Result<(Subscriber<()>, mpsc::Receiver<Received<T>>)>
where
    T: DeserializeOwned + Checked + Send + 'static,
{
    let (tx, rx) = queue();
    Ok((subscribe_into(session, key, rejected, tx).await?, rx))
}

/// As `subscribe`, into a channel that several subscriptions may share.
pub async fn subscribe_into<T>(
    session: &Session,
    key: &str,
    rejected: &Rejected,
    tx: mpsc::Sender<Received<T>>,
) -> Result<Subscriber<()>>
where
    T: DeserializeOwned + Checked + Send + 'static,
{
    subscribe_as(session, key, rejected, tx, |m| m).await
}

/// As `subscribe_into`, each message wrapped by `wrap`: subscriptions of several types share
/// one channel, and the receiver takes their messages in the order they arrived.
pub async fn subscribe_as<T, M>(
    session: &Session,
    key: &str,
    rejected: &Rejected,
    tx: mpsc::Sender<Received<M>>,
    wrap: fn(T) -> M,
) -> Result<Subscriber<()>>
where
    T: DeserializeOwned + Checked + Send + 'static,
    M: Send + 'static,
{
    subscribe_origin_as(session, key, Locality::Any, rejected, tx, wrap).await
}

/// As `subscribe_as`, hearing the sessions `origin` says: `Locality::Remote` for a process
/// that publishes on `key` too, and must not take its own words for another's.
pub async fn subscribe_origin_as<T, M>(
    session: &Session,
    key: &str,
    origin: Locality,
    rejected: &Rejected,
    tx: mpsc::Sender<Received<M>>,
    wrap: fn(T) -> M,
) -> Result<Subscriber<()>>
where
    T: DeserializeOwned + Checked + Send + 'static,
    M: Send + 'static,
{
    let overflowed = rejected.clone();
    let take = move |key: &str, message| {
        enqueue(&tx, key, wrap(message), &overflowed);
    };
    subscribe_from(session, key, origin, rejected, take).await
}

/// Queues what came on `key` for its receiver, counted as dropped if the queue is full; whether
/// it was queued.
pub(crate) fn enqueue<M>(tx: &mpsc::Sender<Received<M>>, key: &str, message: M, rejected: &Rejected) -> bool {
    let received = Received {
        key: key.to_string(),
        message,
    };
    match tx.try_send(received) {
        Ok(()) => true,
        Err(mpsc::error::TrySendError::Full(_)) => {
            rejected.overflow(key);
            false
        }
        Err(mpsc::error::TrySendError::Closed(_)) => false,
    }
}

/// Subscribes to `key` and hands every usable message of type T, with the key it came on, to
/// `take`, on Zenoh's thread: for a machine fed in place, without waking another task.
pub async fn subscribe_with<T>(
    session: &Session,
    key: &str,
    rejected: &Rejected,
    take: impl Fn(&str, T) + Send + Sync + 'static,
) -> Result<Subscriber<()>>
where
    T: DeserializeOwned + Checked + Send + 'static,
{
    subscribe_from(session, key, Locality::Any, rejected, take).await
}

/// As `subscribe_with`, hearing the sessions `origin` says.
async fn subscribe_from<T>(
    session: &Session,
    key: &str,
    origin: Locality,
    rejected: &Rejected,
    take: impl Fn(&str, T) + Send + Sync + 'static,
) -> Result<Subscriber<()>>
where
    T: DeserializeOwned + Checked + Send + 'static,
{
    let rejected = rejected.clone();
    let subscriber = session
        .declare_subscriber(key)
        .allowed_origin(origin)
        .callback(move |sample| {
            let key = sample.key_expr().as_str();
            match decode::<T>(&sample.payload().to_bytes()) {
                Ok(message) => take(key, message),
                Err(e) => rejected.invalid(e, key),
            }
        })
        .await
        .map_err(|e| failed!("cannot subscribe to {key}: {e}"))?;
    Ok(subscriber)
}
