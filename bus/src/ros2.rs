//! The world's ROS 2 side (`--ros2 DOMAIN`): rmw_zenoh's publishers and graph tokens on the
//! fleet's own session, so that ROS 2 nodes on the same Zenoh network (rmw_zenoh, or any
//! implementation of its wire format) see the fleet with no bridge. What the bytes are is
//! `tcpf_core::ros2`'s; this moves them.

use anyhow::{anyhow, Result};
use tcpf_core::msg::{Command, State};
use tcpf_core::ros2::{self, Odometry, Stamp, Type};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::{Session, Wait};

/// One ROS 2 publisher: its Zenoh publisher, the sequence number of its next sample, its GID.
struct Topic {
    publisher: Publisher<'static>,
    sequence: i64,
    gid: [u8; 16],
    _token: LivelinessToken,
}

impl Topic {
    fn put(&mut self, payload: Vec<u8>, stamp: Stamp) -> Result<()> {
        let attachment = ros2::attachment(self.sequence, stamp.nanos(), self.gid);
        self.sequence += 1;
        self.publisher
            .put(payload)
            .attachment(attachment.to_vec())
            .wait()
            .map_err(|e| anyhow!("publish on {}: {e}", self.publisher.key_expr()))
    }
}

/// The world as the ROS 2 node `/tcpf/world`: every vehicle's odometry and coordination state,
/// the fleet's, and, in lockstep, `/clock`.
pub struct World {
    odometry: Vec<(u32, Topic)>,
    gamma: Vec<(u32, Topic)>,
    coordination: Topic,
    clock: Option<Topic>,
    _node: LivelinessToken,
}

/// The node's name in `ros2 node list` (under `ros2::NAMESPACE`).
const NODE: &str = "world";

impl World {
    /// Declares the node and its publishers on `domain`: odometry of every vehicle of `ids`, and
    /// `/clock` when the fleet's time is simulated (`lockstep`). In lockstep a publication waits
    /// for a slow subscriber, as the fleet's own messages do; in realtime it is dropped instead.
    pub async fn declare(session: &Session, domain: u32, ids: &[u32], lockstep: bool) -> Result<World> {
        let zid = session.zid().to_string();
        let congestion = if lockstep {
            CongestionControl::Block
        } else {
            CongestionControl::Drop
        };
        let mut entity = 0;
        let mut topic = |name: String, ty: Type| {
            entity += 1;
            declare(session, domain, &zid, entity, name, ty, congestion)
        };
        let clock = match lockstep {
            true => Some(topic("/clock".to_string(), ros2::CLOCK).await?),
            false => None,
        };
        let mut odometry = Vec::with_capacity(ids.len());
        for &id in ids {
            odometry.push((id, topic(ros2::odometry_topic(id), ros2::ODOMETRY).await?));
        }
        let mut gamma = Vec::with_capacity(ids.len());
        for &id in ids {
            gamma.push((id, topic(ros2::gamma_topic(id), ros2::VECTOR3_STAMPED).await?));
        }
        let coordination = topic(ros2::coordination_topic(), ros2::VECTOR3_STAMPED).await?;
        // Last: a tool that sees the node in the graph sees every topic of it.
        let node = session
            .liveliness()
            .declare_token(ros2::node_token(domain, &zid, 0, NODE))
            .await
            .map_err(|e| anyhow!("cannot declare the ROS 2 node: {e}"))?;
        Ok(World {
            odometry,
            gamma,
            coordination,
            clock,
            _node: node,
        })
    }

    /// Publishes the fleet at `stamp`: `/clock`, then each vehicle's odometry from its state and
    /// the command it holds and, if it holds one, its coordination state, then the fleet's.
    pub fn put<'a>(
        &mut self,
        fleet: impl Iterator<Item = (&'a State, Option<&'a Command>)>,
        stamp: Stamp,
    ) -> Result<()> {
        if let Some(clock) = &mut self.clock {
            clock.put(ros2::clock(stamp), stamp)?;
        }
        let fleet: Vec<(&State, Option<&Command>)> = fleet.collect();
        for &(state, command) in &fleet {
            if let Some((_, topic)) = self.odometry.iter_mut().find(|(id, _)| *id == state.id) {
                topic.put(Odometry::of(state, command, stamp).cdr(), stamp)?;
            }
            let gamma = self.gamma.iter_mut().find(|(id, _)| *id == state.id);
            if let (Some((_, topic)), Some(command)) = (gamma, command) {
                topic.put(ros2::gamma(state, command, stamp), stamp)?;
            }
        }
        self.coordination.put(ros2::coordination(&fleet, stamp), stamp)
    }
}

/// A publisher of `topic` as entity `entity` of the node, with its graph token.
async fn declare(
    session: &Session,
    domain: u32,
    zid: &str,
    entity: u32,
    topic: String,
    ty: Type,
    congestion: CongestionControl,
) -> Result<Topic> {
    let key = ros2::data_key(domain, &topic, &ty);
    let publisher = session
        .declare_publisher(key.clone())
        .congestion_control(congestion)
        .await
        .map_err(|e| anyhow!("cannot publish on {key}: {e}"))?;
    let token = ros2::publisher_token(domain, zid, 0, entity, NODE, &topic, &ty);
    let gid = ros2::gid(&token);
    let token = session
        .liveliness()
        .declare_token(token)
        .await
        .map_err(|e| anyhow!("cannot declare the ROS 2 publisher of {topic}: {e}"))?;
    Ok(Topic {
        publisher,
        sequence: 1,
        gid,
        _token: token,
    })
}
