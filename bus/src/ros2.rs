//! The fleet's ROS 2 side (`--ros2`, `[ros2]`): rmw_zenoh's publishers, subscriptions and graph
//! tokens on each role's own session, so that ROS 2 nodes on the same Zenoh network (rmw_zenoh,
//! or any implementation of its wire format) see the fleet, and play its vehicles, with no
//! bridge. What the bytes are is `tcpf_core::outputs::ros2`'s; this moves them.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use tcpf_core::mission::Ros2Config;
use tcpf_core::model::path::GeneralizedPath;
use tcpf_core::msg::{Command, State};
use tcpf_core::outputs::ros2::{self, Entity, FleetTopic, LinkCounts, Node, Stamp, Type};
use tokio::sync::mpsc;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::CongestionControl;
use zenoh::query::Queryable;
use zenoh::time::Timestamp;
use zenoh::{Session, Wait};

use crate::error::{failed, Result};
use crate::rejected::Rejected;
use crate::subscribe::{enqueue, queue, Received};

/// One ROS 2 publisher: its Zenoh publisher, the sequence number of its next sample, its GID.
struct Topic {
    publisher: Publisher<'static>,
    sequence: i64,
    gid: [u8; 16],
    _token: LivelinessToken,
}

impl Topic {
    /// Publishes `payload` with the attachment the RMW reads, and returns that attachment.
    fn put(&mut self, payload: Vec<u8>, stamp: Stamp) -> Result<[u8; 33]> {
        self.put_at(payload, stamp, None)
    }

    /// `put`, the sample carrying `timestamp`.
    fn put_at(&mut self, payload: Vec<u8>, stamp: Stamp, timestamp: Option<Timestamp>) -> Result<[u8; 33]> {
        let attachment = ros2::attachment(self.sequence, stamp.nanos(), self.gid);
        self.sequence += 1;
        self.publisher
            .put(payload)
            .attachment(attachment.to_vec())
            .timestamp(timestamp)
            .wait()
            .map_err(|e| failed!("publish on {}: {e}", self.publisher.key_expr()))?;
        Ok(attachment)
    }
}

/// A latched publisher's last sample, its attachment and its timestamp, for the late subscribers
/// who ask.
type LastSample = Arc<Mutex<Option<(Vec<u8>, [u8; 33], Timestamp)>>>;

/// A transient-local publisher as rmw_zenoh makes one with Zenoh's advanced publisher, built from
/// plain Zenoh: it keeps its last sample and answers a late subscriber's query for it on
/// `<key>/@adv/pub/<zid>/uhlc/_`, where a token says it is there. The sample carries one
/// timestamp, live and in every answer: a subscriber (zenoh-ext's `AdvancedSubscriber`, which
/// rmw_zenoh's is) asks when it starts and again when it sees the token, and takes from a `uhlc`
/// publisher only what is newer than what it has, so it takes the sample once.
struct Latched {
    topic: Topic,
    session: Session,
    last: LastSample,
    _cache: Queryable<()>,
    _detection: LivelinessToken,
}

impl Latched {
    fn put(&mut self, payload: Vec<u8>, stamp: Stamp) -> Result<()> {
        let timestamp = self.session.new_timestamp();
        let attachment = self.topic.put_at(payload.clone(), stamp, Some(timestamp))?;
        *self.last.lock().unwrap_or_else(|e| e.into_inner()) = Some((payload, attachment, timestamp));
        Ok(())
    }
}

/// A node as it is declared: its session and names, and the entity id of what it declares next.
struct Declaring {
    session: Session,
    ros2: Ros2Config,
    zid: String,
    name: String,
    next: u32,
    congestion: CongestionControl,
}

impl Declaring {
    /// Node `name` of the session's first (and only) ROS 2 context. In lockstep a publication
    /// waits for a slow subscriber, as the fleet's own messages do; in realtime it is dropped.
    fn new(session: &Session, ros2: &Ros2Config, name: String, lockstep: bool) -> Declaring {
        Declaring {
            session: session.clone(),
            ros2: ros2.clone(),
            zid: session.zid().to_string(),
            name,
            next: 0,
            congestion: if lockstep {
                CongestionControl::Block
            } else {
                CongestionControl::Drop
            },
        }
    }

    fn node(&self) -> Node<'_> {
        Node {
            zid: &self.zid,
            id: 0,
            name: &self.name,
        }
    }

    /// The token of the next entity, `kind` on `topic`.
    fn token(&mut self, kind: Entity, topic: &str, ty: &Type, qos: &str) -> String {
        self.next += 1;
        self.ros2.entity_token(&self.node(), self.next, kind, topic, ty, qos)
    }

    async fn declare_token(&self, token: String, what: &str) -> Result<LivelinessToken> {
        self.session
            .liveliness()
            .declare_token(token)
            .await
            .map_err(|e| failed!("cannot declare the ROS 2 {what}: {e}"))
    }

    async fn publisher(&mut self, topic: String, ty: Type, qos: &str) -> Result<Topic> {
        let key = self.ros2.data_key(&topic, &ty);
        let publisher = self
            .session
            .declare_publisher(key.clone())
            .congestion_control(self.congestion)
            .await
            .map_err(|e| failed!("cannot publish on {key}: {e}"))?;
        let token = self.token(Entity::Publisher, &topic, &ty, qos);
        let gid = ros2::gid(&token);
        Ok(Topic {
            publisher,
            sequence: 1,
            gid,
            _token: self.declare_token(token, &format!("publisher of {topic}")).await?,
        })
    }

    async fn latched(&mut self, topic: String, ty: Type) -> Result<Latched> {
        let key = self.ros2.data_key(&topic, &ty);
        let topic = self.publisher(topic, ty, ros2::QOS_TRANSIENT_LOCAL).await?;
        let adv = format!("{key}/@adv/pub/{}/uhlc/_", self.zid);
        let last: LastSample = Arc::default();
        let held = last.clone();
        let cache = self
            .session
            .declare_queryable(adv.clone())
            .callback(move |query| {
                let last = held.lock().unwrap_or_else(|e| e.into_inner()).clone();
                if let Some((payload, attachment, timestamp)) = last {
                    // The sample under the topic's own key: the subscriber's query accepts any.
                    let reply = query
                        .reply(key.clone(), payload)
                        .attachment(attachment.to_vec())
                        .timestamp(timestamp);
                    if let Err(e) = reply.wait() {
                        tracing::debug!("a late subscriber of {key} asked and was not answered: {e}");
                    }
                }
            })
            .await
            .map_err(|e| failed!("cannot serve the history of {adv}: {e}"))?;
        Ok(Latched {
            topic,
            session: self.session.clone(),
            last,
            _cache: cache,
            _detection: self.declare_token(adv, "transient-local publisher").await?,
        })
    }

    /// A subscription to `topic` whose samples go to `tx` as `(id, payload)`.
    async fn subscription(
        &mut self,
        topic: String,
        ty: Type,
        id: u32,
        tx: mpsc::Sender<Received<(u32, Vec<u8>)>>,
        rejected: &Rejected,
    ) -> Result<(Subscriber<()>, LivelinessToken)> {
        let key = self.ros2.data_key(&topic, &ty);
        let overflowed = rejected.clone();
        let subscriber = self
            .session
            .declare_subscriber(key.clone())
            .callback(move |sample| {
                let payload = sample.payload().to_bytes().into_owned();
                enqueue(&tx, sample.key_expr().as_str(), (id, payload), &overflowed);
            })
            .await
            .map_err(|e| failed!("cannot subscribe to {key}: {e}"))?;
        let token = self.token(Entity::Subscription, &topic, &ty, ros2::QOS);
        Ok((
            subscriber,
            self.declare_token(token, &format!("subscription of {topic}")).await?,
        ))
    }

    /// The node's own token, last: a tool that sees the node sees every topic of it.
    async fn done(&self) -> Result<LivelinessToken> {
        let token = self.ros2.node_token(&self.node());
        self.declare_token(token, &format!("node {}", self.name)).await
    }
}

/// The fleet as the world knows it, for its ROS 2 node.
pub struct Fleet<'a> {
    pub ids: &'a [u32],
    /// The vehicles the world integrates: every other is played by another program, perhaps a
    /// ROS 2 node, whose odometry the world listens to.
    pub simulated: &'a [u32],
    /// Every directed link of the communication graph, (from, to).
    pub links: &'a [(u32, u32)],
    pub lockstep: bool,
}

/// The world as the ROS 2 node `world` (or a recorder, for a world that does not speak ROS 2):
/// the odometry of the vehicles it simulates, every vehicle's planned path and coordination
/// state, each link's γ messages, the fleet's coordination and, in lockstep, `/clock`; and a
/// subscription to the odometry of each vehicle a ROS 2 node may play.
pub struct World {
    odometry: BTreeMap<u32, Topic>,
    gamma: BTreeMap<u32, Topic>,
    paths: BTreeMap<u32, Latched>,
    /// Per link, its counts (Vector3Stamped) and each message's cause (String).
    links: BTreeMap<(u32, u32), (Topic, Topic)>,
    counts: LinkCounts,
    coordination: Topic,
    clock: Option<Topic>,
    /// The vehicles other programs play, whose odometry the world may take.
    others: Vec<u32>,
    _played: Vec<(Subscriber<()>, LivelinessToken)>,
    node: Declaring,
    _node: LivelinessToken,
}

/// Odometry of played vehicles as it arrives, `(id, CDR)`, for the world's loop to decode.
pub type PlayedOdometry = mpsc::Receiver<Received<(u32, Vec<u8>)>>;

impl World {
    /// Declares the node `name` (`world`, or `recorder` for `tcpf record --ros2`) and its topics.
    pub async fn declare(session: &Session, ros2: &Ros2Config, fleet: &Fleet<'_>, name: &str) -> Result<World> {
        let mut node = Declaring::new(session, ros2, name.into(), fleet.lockstep);
        let clock = match fleet.lockstep {
            true => Some(node.publisher("/clock".into(), ros2::CLOCK, ros2::QOS).await?),
            false => None,
        };
        let mut odometry = BTreeMap::new();
        for &id in fleet.simulated {
            odometry.insert(
                id,
                node.publisher(ros2.odometry_topic(id), ros2::ODOMETRY, ros2::QOS)
                    .await?,
            );
        }
        let mut gamma = BTreeMap::new();
        let mut paths = BTreeMap::new();
        for &id in fleet.ids {
            gamma.insert(
                id,
                node.publisher(ros2.gamma_topic(id), ros2::VECTOR3_STAMPED, ros2::QOS)
                    .await?,
            );
            paths.insert(id, node.latched(ros2.path_topic(id), ros2::PATH).await?);
        }
        let mut links = BTreeMap::new();
        for &(from, to) in fleet.links {
            let counts = node
                .publisher(ros2.link_topic(from, to), ros2::VECTOR3_STAMPED, ros2::QOS)
                .await?;
            let causes = node
                .publisher(ros2.link_cause_topic(from, to), ros2::STRING, ros2::QOS)
                .await?;
            links.insert((from, to), (counts, causes));
        }
        let coordination = node
            .publisher(ros2.coordination_topic(), ros2::VECTOR3_STAMPED, ros2::QOS)
            .await?;
        let token = node.done().await?;
        Ok(World {
            odometry,
            gamma,
            paths,
            links,
            counts: LinkCounts::default(),
            coordination,
            clock,
            others: fleet
                .ids
                .iter()
                .copied()
                .filter(|id| !fleet.simulated.contains(id))
                .collect(),
            _played: Vec::new(),
            node,
            _node: token,
        })
    }

    /// Subscribes to the odometry of every vehicle the world does not simulate, once the run's
    /// clock has started: what a ROS 2 node playing one publishes before then is no state of
    /// the run.
    pub async fn listen(&mut self, rejected: &Rejected) -> Result<PlayedOdometry> {
        let (tx, played_odometry) = queue();
        for &id in &self.others {
            let topic = self.node.ros2.odometry_topic(id);
            let subscription = self
                .node
                .subscription(topic, ros2::ODOMETRY, id, tx.clone(), rejected)
                .await?;
            self._played.push(subscription);
        }
        Ok(played_odometry)
    }

    /// Publishes each vehicle's planned path once, each pose stamped `stamp_of(γ)`: kept for
    /// subscribers that come later.
    pub fn put_paths(&mut self, paths: &[(u32, GeneralizedPath)], stamp_of: impl Fn(f64) -> Stamp) -> Result<()> {
        for (id, path) in paths {
            if let Some(latched) = self.paths.get_mut(id) {
                latched.put(ros2::path(path, &stamp_of), stamp_of(0.0))?;
            }
        }
        Ok(())
    }

    /// Publishes the fleet at `stamp`: what `ros2::carried` says a tick carries, on the topics
    /// this node publishes (the odometry of the vehicles it simulates; the agents publish the
    /// commands).
    pub fn put<'a>(
        &mut self,
        fleet: impl Iterator<Item = (&'a State, Option<&'a Command>)>,
        stamp: Stamp,
    ) -> Result<()> {
        let fleet: Vec<(&State, Option<&Command>)> = fleet.collect();
        let mut published = Ok(());
        let lockstep = self.clock.is_some();
        ros2::carried(&mut self.counts, &fleet, stamp, lockstep, |topic, encode| {
            let publisher = match topic {
                FleetTopic::Clock => self.clock.as_mut(),
                FleetTopic::Odometry(id) => self.odometry.get_mut(&id),
                FleetTopic::Gamma(id) => self.gamma.get_mut(&id),
                FleetTopic::Link(from, to) => self.links.get_mut(&(from, to)).map(|(counts, _)| counts),
                FleetTopic::Cause(from, to) => self.links.get_mut(&(from, to)).map(|(_, causes)| causes),
                FleetTopic::Coordination => Some(&mut self.coordination),
                FleetTopic::Command(_) | FleetTopic::Path(_) => None,
            };
            if let (Some(publisher), Ok(())) = (publisher, &published) {
                published = publisher.put(encode(), stamp).map(|_| ());
            }
        });
        published
    }
}

/// The agent of a vehicle as the ROS 2 node `agent_<id>`: its commands on the vehicle's `cmd`,
/// which a ROS 2 node playing the vehicle (or its driver, remapped) follows.
pub struct Agent {
    command: Topic,
    _node: LivelinessToken,
}

impl Agent {
    pub async fn declare(session: &Session, ros2: &Ros2Config, id: u32, lockstep: bool) -> Result<Agent> {
        let mut node = Declaring::new(session, ros2, format!("agent_{id}"), lockstep);
        let command = node.publisher(ros2.command_topic(id), ros2::TWIST, ros2::QOS).await?;
        Ok(Agent {
            command,
            _node: node.done().await?,
        })
    }

    pub fn put(&mut self, command: &Command, stamp: Stamp) -> Result<()> {
        self.command.put(ros2::twist(command), stamp).map(|_| ())
    }
}

/// Whether the node `name` of the fleet is in the graph of `ros2`'s domain now.
pub async fn node_present(session: &Session, ros2: &Ros2Config, name: &str) -> Result<bool> {
    let key = ros2.any_node_token(name);
    let replies = session
        .liveliness()
        .get(key.clone())
        .await
        .map_err(|e| failed!("cannot ask the ROS 2 graph for {key}: {e}"))?;
    while let Ok(reply) = replies.recv_async().await {
        if reply.result().is_ok() {
            return Ok(true);
        }
    }
    Ok(false)
}
