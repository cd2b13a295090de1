//! Typed publishers and subscribers. A subscriber's callback only decodes and forwards: what to do
//! with a message is the core machines' business. Refused payloads are counted, never fatal.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use serde::de::DeserializeOwned;
use serde::Serialize;
use tcpf_core::lockstep::Timing;
use tcpf_core::msg::{Checked, PathMsg, Report, PROTOCOL_VERSION};
use tcpf_core::path::GeneralizedPath;
use tokio::sync::mpsc;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::CongestionControl;
use zenoh::sample::SampleKind;
use zenoh::Session;

use crate::codec::{decode, encode};
use crate::keys::{Keys, Role};

/// Messages refused by this process: undecodable, wrong version, non-finite or out of protocol.
#[derive(Debug, Clone, Default)]
pub struct Rejected(Arc<AtomicU64>);

impl Rejected {
    pub fn count(&self, what: &str, key: &str) {
        self.0.fetch_add(1, Ordering::Relaxed);
        tracing::warn!("dropped a message on {key}: {what}");
    }

    pub fn total(&self) -> u64 {
        self.0.load(Ordering::Relaxed)
    }
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
) -> Result<(Subscriber<()>, mpsc::UnboundedReceiver<Received<T>>)>
where
    T: DeserializeOwned + Checked + Send + 'static,
{
    let (tx, rx) = mpsc::unbounded_channel();
    Ok((subscribe_into(session, key, rejected, tx).await?, rx))
}

/// As `subscribe`, into a channel that several subscriptions may share.
pub async fn subscribe_into<T>(
    session: &Session,
    key: &str,
    rejected: &Rejected,
    tx: mpsc::UnboundedSender<Received<T>>,
) -> Result<Subscriber<()>>
where
    T: DeserializeOwned + Checked + Send + 'static,
{
    let rejected = rejected.clone();
    let subscriber = session
        .declare_subscriber(key)
        .callback(move |sample| {
            let key = sample.key_expr().as_str().to_string();
            match decode::<T>(&sample.payload().to_bytes()) {
                Ok(message) => {
                    let _ = tx.send(Received { key, message });
                }
                Err(e) => rejected.count(&format!("{e:?}"), &key),
            }
        })
        .await
        .map_err(|e| anyhow!("cannot subscribe to {key}: {e}"))?;
    Ok(subscriber)
}

/// A publisher that never drops: lockstep waits for every message.
pub struct Outlet {
    publisher: Publisher<'static>,
}

impl Outlet {
    pub async fn new(session: &Session, key: String) -> Result<Outlet> {
        let publisher = session
            .declare_publisher(key.clone())
            .congestion_control(CongestionControl::Block)
            .express(true)
            .await
            .map_err(|e| anyhow!("cannot publish on {key}: {e}"))?;
        Ok(Outlet { publisher })
    }

    pub async fn put<T: Serialize>(&self, message: &T) -> Result<()> {
        self.publisher
            .put(encode(message))
            .await
            .map_err(|e| anyhow!("publish on {}: {e}", self.publisher.key_expr()))
    }
}

/// A liveliness change of the mission: someone came or went.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Presence {
    pub role: Role,
    pub id: u32,
    pub alive: bool,
}

/// Follows every liveliness token of the mission, those already there included.
pub async fn presence(session: &Session, keys: &Keys) -> Result<(Subscriber<()>, mpsc::UnboundedReceiver<Presence>)> {
    let (tx, rx) = mpsc::unbounded_channel();
    let parser = keys.clone();
    let subscriber = session
        .liveliness()
        .declare_subscriber(keys.alive_all())
        .history(true)
        .callback(move |sample| {
            if let Some((role, id)) = parser.parse_alive(sample.key_expr().as_str()) {
                let _ = tx.send(Presence {
                    role,
                    id,
                    alive: sample.kind() == SampleKind::Put,
                });
            }
        })
        .await
        .map_err(|e| anyhow!("cannot follow liveliness: {e}"))?;
    Ok((subscriber, rx))
}

/// Asks the planner for the paths of `ids`, retrying until `timeout`.
pub async fn fetch_paths(
    session: &Session,
    keys: &Keys,
    ids: &[u32],
    timeout: Duration,
    rejected: &Rejected,
) -> Result<Vec<(u32, GeneralizedPath)>> {
    let deadline = Instant::now() + timeout;
    let selector = if ids.len() == 1 {
        keys.plan(ids[0])
    } else {
        keys.plan("*")
    };
    let mut found: BTreeMap<u32, GeneralizedPath> = BTreeMap::new();
    loop {
        let replies = session
            .get(selector.clone())
            .timeout(Duration::from_secs(2))
            .await
            .map_err(|e| anyhow!("cannot query {selector}: {e}"))?;
        while let Ok(reply) = replies.recv_async().await {
            let Ok(sample) = reply.result() else { continue };
            let key = sample.key_expr().as_str().to_string();
            match decode::<PathMsg>(&sample.payload().to_bytes()) {
                Ok(m) if Keys::id_of(&key) == Some(m.id) => {
                    found.insert(m.id, m.path);
                }
                Ok(_) => rejected.count("path for another vehicle", &key),
                Err(e) => rejected.count(&format!("{e:?}"), &key),
            }
        }
        let missing: Vec<u32> = ids.iter().copied().filter(|i| !found.contains_key(i)).collect();
        if missing.is_empty() {
            return Ok(ids.iter().map(|i| (*i, found[i])).collect());
        }
        if Instant::now() >= deadline {
            return Err(anyhow!(
                "no path from the planner for vehicle(s) {missing:?} within {:.0} s (is `tcpf planner` running for this mission?)",
                timeout.as_secs_f64()
            ));
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// Tells the recorder who this process was and what it refused, as it exits.
pub async fn report(
    session: &Session,
    keys: &Keys,
    role: Role,
    id: u32,
    rejected: &Rejected,
    timing: Timing,
) -> Result<()> {
    let report = Report {
        version: PROTOCOL_VERSION,
        role: role.as_str().into(),
        id,
        pid: std::process::id(),
        rejected: rejected.total(),
        stale_timeouts: timing.stale_timeouts,
        late_gammas: timing.late_gammas,
    };
    Outlet::new(session, keys.report(role, id)).await?.put(&report).await
}
