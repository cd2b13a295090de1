//! Typed publishers, each with the congestion control and reliability its clock needs.

use serde::Serialize;
use zenoh::pubsub::Publisher;
use zenoh::qos::{CongestionControl, Reliability};
use zenoh::{Session, Wait};

use crate::codec::encode;
use crate::error::{failed, Result};

/// A publisher: one that never drops for lockstep, which waits for every message; one that
/// drops under congestion for realtime, where the freshest message wins and a late one is
/// worth nothing.
pub struct Outlet {
    publisher: Publisher<'static>,
}

impl Outlet {
    pub async fn new(session: &Session, key: String) -> Result<Outlet> {
        Outlet::with(session, key, CongestionControl::Block, Reliability::Reliable, false).await
    }

    /// For a process's last words (its report, the world's end): sent at once. A batched message
    /// can be overtaken by the undeclarations of a closing session, which travel at a higher
    /// priority, and then be dropped on arrival for a key no longer known.
    pub async fn last_words(session: &Session, key: String) -> Result<Outlet> {
        Outlet::with(session, key, CongestionControl::Block, Reliability::Reliable, true).await
    }

    /// `Outlet::new` in lockstep; in realtime one that drops under congestion.
    pub async fn for_clock(session: &Session, key: String, realtime: bool) -> Result<Outlet> {
        if realtime {
            Outlet::with(session, key, CongestionControl::Drop, Reliability::Reliable, true).await
        } else {
            Outlet::new(session, key).await
        }
    }

    /// γ: in realtime best-effort as well, so that it travels over a datagram link where the
    /// session has one (configs/zenoh/udp/): a γ the network loses is lost, as on a modem,
    /// instead of being sent again late.
    pub async fn gamma(session: &Session, key: String, realtime: bool) -> Result<Outlet> {
        if realtime {
            Outlet::with(session, key, CongestionControl::Drop, Reliability::BestEffort, true).await
        } else {
            Outlet::new(session, key).await
        }
    }

    async fn with(
        session: &Session,
        key: String,
        congestion: CongestionControl,
        reliability: Reliability,
        express: bool,
    ) -> Result<Outlet> {
        let publisher = session
            .declare_publisher(key.clone())
            .congestion_control(congestion)
            .reliability(reliability)
            // Lockstep cares for throughput: a burst (the world's states of a tick, the commands
            // a router forwards to the world) leaves in one batch, one write, instead of one
            // write per message; that cut a 10-agent tick by a quarter. Zenoh takes a batch as
            // soon as its sender thread runs, so a message waits only under back-pressure, which
            // realtime, where a late message is worth nothing, must not risk: it is express.
            .express(express)
            .await
            .map_err(|e| failed!("cannot publish on {key}: {e}"))?;
        Ok(Outlet { publisher })
    }

    /// `put` from a thread that must not await: a Zenoh callback.
    pub fn put_now<T: Serialize>(&self, message: &T) -> Result<()> {
        self.publisher
            .put(encode(message))
            .wait()
            .map_err(|e| failed!("publish on {}: {e}", self.publisher.key_expr()))
    }

    pub async fn put<T: Serialize>(&self, message: &T) -> Result<()> {
        self.publisher
            .put(encode(message))
            .await
            .map_err(|e| failed!("publish on {}: {e}", self.publisher.key_expr()))
    }
}

/// Publishes one message on `key` at once, without a declared publisher: for a rare message such
/// as a vehicle's loss (from a Zenoh callback, which must not await) or a process's report. Over
/// QUIC a message may overtake the declaration of a publisher made just before it.
pub fn say_now<T: Serialize>(session: &Session, key: String, message: &T) -> Result<()> {
    session
        .put(key.clone(), encode(message))
        .congestion_control(CongestionControl::Block)
        .reliability(Reliability::Reliable)
        .express(true)
        .wait()
        .map_err(|e| failed!("publish on {key}: {e}"))
}
