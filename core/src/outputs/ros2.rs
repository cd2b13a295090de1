//! ROS 2 as its Zenoh RMW speaks it (docs/ROS2.md names the RMW and its version), so that ROS 2 tools
//! on the fleet's network see the fleet with no bridge: the key expressions, liveliness tokens,
//! sample attachment and CDR payloads of the standard messages the world publishes. The format is
//! that RMW's from its 0.2.4 (ROS 2 Jazzy; Kilted's 0.6 and Rolling's are the same). Bytes only:
//! the world's shell puts them on the bus.

use crate::mission::{Mission, Ros2Config};
use crate::model::path::GeneralizedPath;
use crate::msg::{Clock, Command, State};
use crate::time::UnixTime;
use std::collections::BTreeMap;

/// A ROS 2 message type: its name, the name the RMW puts in keys, and its RIHS01 type hash
/// (REP 2011), which is part of every key: with a wrong one, nobody hears.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Type {
    pub name: &'static str,
    pub dds: &'static str,
    pub hash: &'static str,
}

pub const ODOMETRY: Type = Type {
    name: "nav_msgs/msg/Odometry",
    dds: "nav_msgs::msg::dds_::Odometry_",
    hash: "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
};

pub const CLOCK: Type = Type {
    name: "rosgraph_msgs/msg/Clock",
    dds: "rosgraph_msgs::msg::dds_::Clock_",
    hash: "RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564",
};

pub const VECTOR3_STAMPED: Type = Type {
    name: "geometry_msgs/msg/Vector3Stamped",
    dds: "geometry_msgs::msg::dds_::Vector3Stamped_",
    hash: "RIHS01_d4829622288cbb443886e7ea94ea5671a3b1be6bab4ad04224432a65f7d7887a",
};

pub const TWIST: Type = Type {
    name: "geometry_msgs/msg/Twist",
    dds: "geometry_msgs::msg::dds_::Twist_",
    hash: "RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a",
};

pub const STRING: Type = Type {
    name: "std_msgs/msg/String",
    dds: "std_msgs::msg::dds_::String_",
    hash: "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
};

pub const PATH: Type = Type {
    name: "nav_msgs/msg/Path",
    dds: "nav_msgs::msg::dds_::Path_",
    hash: "RIHS01_1957a5bb3cee5da65c4e52e52b65a93df227efce4c20f8458b36e73066ca334b",
};

/// The ROS 2 message definitions (`.msg`, as a bag's `ros2msg` schema holds them) of the types
/// the fleet publishes and of the types inside them, by name without `/msg/`.
const DEFINITIONS: &[(&str, &str)] = &[
    (
        "nav_msgs/Odometry",
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist",
    ),
    ("nav_msgs/Path", "std_msgs/Header header\ngeometry_msgs/PoseStamped[] poses"),
    ("rosgraph_msgs/Clock", "builtin_interfaces/Time clock"),
    ("std_msgs/Header", "builtin_interfaces/Time stamp\nstring frame_id"),
    ("std_msgs/String", "string data"),
    ("builtin_interfaces/Time", "int32 sec\nuint32 nanosec"),
    ("geometry_msgs/PoseWithCovariance", "geometry_msgs/Pose pose\nfloat64[36] covariance"),
    ("geometry_msgs/TwistWithCovariance", "geometry_msgs/Twist twist\nfloat64[36] covariance"),
    ("geometry_msgs/PoseStamped", "std_msgs/Header header\ngeometry_msgs/Pose pose"),
    ("geometry_msgs/Pose", "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation"),
    ("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z"),
    ("geometry_msgs/Quaternion", "float64 x\nfloat64 y\nfloat64 z\nfloat64 w"),
    ("geometry_msgs/Twist", "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular"),
    ("geometry_msgs/Vector3Stamped", "std_msgs/Header header\ngeometry_msgs/Vector3 vector"),
    ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z"),
];

impl Type {
    /// The type's full message definition as rosbag2 stores it (`ros2msg`): its own fields, then
    /// each type used in it, depth first, once, after a line of 80 `=` and `MSG: <name>`.
    pub fn definition(&self) -> String {
        fn of(name: &str) -> &'static str {
            DEFINITIONS
                .iter()
                .find(|(n, _)| *n == name)
                .map(|(_, d)| *d)
                .expect("every type inside a published one is defined")
        }
        fn inner(name: &str, seen: &mut Vec<&'static str>) {
            for line in of(name).lines() {
                let ty = line.split_whitespace().next().unwrap_or_default();
                let ty = ty.split('[').next().unwrap_or_default();
                if let Some(&(n, _)) = DEFINITIONS.iter().find(|(n, _)| *n == ty) {
                    if !seen.contains(&n) {
                        seen.push(n);
                        inner(n, seen);
                    }
                }
            }
        }
        let name = self.name.replace("/msg/", "/");
        let mut seen = Vec::new();
        inner(&name, &mut seen);
        let mut text = format!("{}\n", of(&name));
        for n in seen {
            text += &format!("{}\nMSG: {n}\n{}\n", "=".repeat(80), of(n));
        }
        text
    }
}

/// A topic the fleet's ROS 2 nodes publish (docs/ROS2.md's table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum FleetTopic {
    Clock,
    Odometry(u32),
    Command(u32),
    Path(u32),
    Gamma(u32),
    Link(u32, u32),
    Cause(u32, u32),
    Coordination,
}

impl FleetTopic {
    pub fn ty(self) -> Type {
        match self {
            FleetTopic::Clock => CLOCK,
            FleetTopic::Odometry(_) => ODOMETRY,
            FleetTopic::Command(_) => TWIST,
            FleetTopic::Path(_) => PATH,
            FleetTopic::Gamma(_) | FleetTopic::Link(..) | FleetTopic::Coordination => VECTOR3_STAMPED,
            FleetTopic::Cause(..) => STRING,
        }
    }

    /// Its QoS: a path is transient local, for late subscribers.
    pub fn qos(self) -> &'static str {
        match self {
            FleetTopic::Path(_) => QOS_TRANSIENT_LOCAL,
            _ => QOS,
        }
    }

    /// Its name under `ros2`'s namespace.
    pub fn name(self, ros2: &Ros2Config) -> String {
        match self {
            FleetTopic::Clock => "/clock".into(),
            FleetTopic::Odometry(id) => ros2.odometry_topic(id),
            FleetTopic::Command(id) => ros2.command_topic(id),
            FleetTopic::Path(id) => ros2.path_topic(id),
            FleetTopic::Gamma(id) => ros2.gamma_topic(id),
            FleetTopic::Link(from, to) => ros2.link_topic(from, to),
            FleetTopic::Cause(from, to) => ros2.link_cause_topic(from, to),
            FleetTopic::Coordination => ros2.coordination_topic(),
        }
    }

    /// Every topic of a fleet of `ids` over `links`, as a bag of it holds them.
    pub fn of_fleet(ids: &[u32], links: &[(u32, u32)], lockstep: bool) -> Vec<FleetTopic> {
        let clock = lockstep.then_some(FleetTopic::Clock);
        let vehicles = ids.iter().flat_map(|&id| {
            [
                FleetTopic::Odometry(id),
                FleetTopic::Command(id),
                FleetTopic::Path(id),
                FleetTopic::Gamma(id),
            ]
        });
        let links = links
            .iter()
            .flat_map(|&(from, to)| [FleetTopic::Link(from, to), FleetTopic::Cause(from, to)]);
        clock
            .into_iter()
            .chain(vehicles)
            .chain(links)
            .chain([FleetTopic::Coordination])
            .collect()
    }
}

/// What one tick of the fleet carries on its ROS 2 topics at `stamp`, in the order the world
/// publishes it: `/clock` (lockstep), then per vehicle its odometry and, if it holds a command,
/// that command (its agent's `cmd`), its coordination state and the links the command reports on
/// (a count when a message was sent, and its fate); then the fleet's coordination. Each message
/// is handed to `emit` as its encoder, so that a node which publishes only some of the topics
/// encodes only those.
pub fn carried(
    counts: &mut LinkCounts,
    fleet: &[(&State, Option<&Command>)],
    stamp: Stamp,
    lockstep: bool,
    mut emit: impl FnMut(FleetTopic, &dyn Fn() -> Vec<u8>),
) {
    if lockstep {
        emit(FleetTopic::Clock, &|| clock(stamp));
    }
    for &(state, command) in fleet {
        emit(FleetTopic::Odometry(state.id), &|| {
            Odometry::of(state, command, stamp).cdr()
        });
        let Some(command) = command else { continue };
        emit(FleetTopic::Command(state.id), &|| twist(command));
        emit(FleetTopic::Gamma(state.id), &|| gamma(state, command, stamp));
        for ((from, to), link_counts, cause) in counts.count(command) {
            if cause.was_sent() {
                emit(FleetTopic::Link(from, to), &|| link(link_counts, stamp));
            }
            emit(FleetTopic::Cause(from, to), &|| self::cause(cause));
        }
    }
    emit(FleetTopic::Coordination, &|| coordination(fleet, stamp));
}

/// The inertial frame of every pose (REP 105's `map`: x east, y north, z up; yaw
/// counter-clockwise from x, as the mission's headings are).
pub const MAP_FRAME: &str = "map";

/// The QoS of a publisher or subscription: reliable, keep last 10 (rclcpp's default), and
/// volatile, or transient local for what a late subscriber must still get. The durability is
/// written out, since the RMW's 0.2.0-0.2.2 read an empty one as transient local.
pub const QOS: &str = "1:2:1,10:,:,:,,";
pub const QOS_TRANSIENT_LOCAL: &str = "1:1:1,10:,:,:,,";

/// A vehicle's body frame (REP 103: x forward, y left, z up).
pub fn body_frame(id: u32) -> String {
    format!("vehicle_{id}")
}

/// What an entity of the graph is, as its liveliness token says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Entity {
    Publisher,
    Subscription,
}

/// The fleet's names in the ROS 2 graph of its domain: every topic and node under its namespace
/// but `/clock`, which ROS 2 nodes with `use_sim_time` look for at the root.
impl Ros2Config {
    fn topic(&self, rest: &str) -> String {
        match self.namespace.as_str() {
            "/" => format!("/{rest}"),
            ns => format!("{ns}/{rest}"),
        }
    }

    /// The odometry of vehicle `id`.
    pub fn odometry_topic(&self, id: u32) -> String {
        self.topic(&format!("vehicle_{id}/odom"))
    }

    /// The commands of vehicle `id`: what a ROS 2 node playing it follows.
    pub fn command_topic(&self, id: u32) -> String {
        self.topic(&format!("vehicle_{id}/cmd"))
    }

    /// The planned path of vehicle `id`.
    pub fn path_topic(&self, id: u32) -> String {
        self.topic(&format!("vehicle_{id}/path"))
    }

    /// The coordination state of vehicle `id`.
    pub fn gamma_topic(&self, id: u32) -> String {
        self.topic(&format!("vehicle_{id}/gamma"))
    }

    /// The γ messages of the directed link from `from` to `to`.
    pub fn link_topic(&self, from: u32, to: u32) -> String {
        self.topic(&format!("links/from_{from}_to_{to}"))
    }

    /// What became of each γ message of the link from `from` to `to`, as `messages.csv` says it.
    pub fn link_cause_topic(&self, from: u32, to: u32) -> String {
        self.topic(&format!("links/from_{from}_to_{to}/cause"))
    }

    /// The fleet's coordination state.
    pub fn coordination_topic(&self) -> String {
        self.topic("coordination")
    }

    /// Where the RMW publishes `topic` (a fully qualified name) of type `ty`: the domain, the
    /// topic without its leading slash, its inner slashes kept as chunks.
    pub fn data_key(&self, topic: &str, ty: &Type) -> String {
        format!("{}/{}/{}/{}", self.domain, topic.trim_matches('/'), ty.dds, ty.hash)
    }

    /// The liveliness token that makes `node` part of the graph: `ros2 node list` shows it
    /// while the token lives.
    pub fn node_token(&self, node: &Node) -> String {
        format!(
            "@ros2_lv/{}/{}/{}/{}/NN/%/{}/{}",
            self.domain,
            node.zid,
            node.id,
            node.id,
            mangled(&self.namespace),
            node.name
        )
    }

    /// A key expression of the token of the node `name` in any session: whether it is in the
    /// graph.
    pub fn any_node_token(&self, name: &str) -> String {
        format!(
            "@ros2_lv/{}/*/*/*/NN/%/{}/{name}",
            self.domain,
            mangled(&self.namespace)
        )
    }

    /// Every key the RMW publishes `topic` (a fully qualified name, or a namespace for every
    /// topic under it) under, whatever its type.
    pub fn topic_keys(&self, topic: &str) -> String {
        match topic.trim_matches('/') {
            "" => format!("{}/**", self.domain),
            topic => format!("{}/{topic}/**", self.domain),
        }
    }

    /// Key expressions of the liveliness tokens of the node `name` in any session: its own and
    /// those of its publishers and subscriptions.
    pub fn node_tokens(&self, name: &str) -> [String; 2] {
        let node = format!("@ros2_lv/{}/*/*/*/*/%/{}/{name}", self.domain, mangled(&self.namespace));
        [node.clone(), format!("{node}/**")]
    }

    /// The liveliness token of a publisher or subscription of `node` (its entity `id`) on
    /// `topic` with QoS `qos`: `ros2 topic list` shows the topic while it lives.
    pub fn entity_token(&self, node: &Node, id: u32, kind: Entity, topic: &str, ty: &Type, qos: &str) -> String {
        let kind = match kind {
            Entity::Publisher => "MP",
            Entity::Subscription => "MS",
        };
        format!(
            "@ros2_lv/{}/{}/{}/{id}/{kind}/%/{}/{}/{}/{}/{}/{qos}",
            self.domain,
            node.zid,
            node.id,
            mangled(&self.namespace),
            node.name,
            mangled(topic),
            ty.dds,
            ty.hash
        )
    }
}

/// A node of the graph: the Zenoh session it lives in, its entity id there, its name.
#[derive(Debug, Clone, Copy)]
pub struct Node<'a> {
    pub zid: &'a str,
    pub id: u32,
    pub name: &'a str,
}

/// A name in a liveliness token: the RMW writes every `/` as `%`, the root as `%`.
fn mangled(name: &str) -> String {
    name.replace('/', "%")
}

/// A publisher's GID as the RMW makes it: the XXH3 128-bit hash of its liveliness token, low
/// half first. It names the publisher in `ros2 topic info --verbose` and in each sample.
pub fn gid(token: &str) -> [u8; 16] {
    xxhash_rust::xxh3::xxh3_128(token.as_bytes()).to_le_bytes()
}

/// The attachment the RMW reads on every sample (it drops a sample without one): the
/// publisher's sequence number (from 1), the source timestamp in nanoseconds since the Unix
/// epoch, and the publisher's 16-byte GID, as Zenoh's extension serializer writes them: integers
/// little-endian, the GID after its length (16, one LEB128 byte).
pub fn attachment(sequence: i64, timestamp_ns: i64, gid: [u8; 16]) -> [u8; 33] {
    let mut out = [0u8; 33];
    out[..8].copy_from_slice(&sequence.to_le_bytes());
    out[8..16].copy_from_slice(&timestamp_ns.to_le_bytes());
    out[16] = 16;
    out[17..].copy_from_slice(&gid);
    out
}

/// builtin_interfaces/msg/Time: fleet time in whole seconds and nanoseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stamp {
    pub sec: i32,
    pub nanosec: u32,
}

impl Stamp {
    /// Fleet time `t` as the fleet's stamps say it (docs/ROS2.md, "Time"): simulated time on a
    /// lockstep clock, the wall clock of the fleet's epoch on a realtime one, whose simulated
    /// time runs `time_scale` times faster than the wall.
    pub fn of_fleet(clock: &Clock, t: f64) -> Stamp {
        match clock.realtime {
            true => Stamp::from_seconds(clock.epoch.at_simulated(t, clock.time_scale).secs()),
            false => Stamp::from_seconds(t),
        }
    }

    /// Fleet time `t` on `clock` (`of_fleet`), or, with none (lockstep), simulated time.
    pub fn of(clock: Option<&Clock>, t: f64) -> Stamp {
        clock.map_or_else(|| Stamp::from_seconds(t), |c| Stamp::of_fleet(c, t))
    }

    /// `t` seconds, to the nearest nanosecond.
    pub fn from_seconds(t: f64) -> Stamp {
        Stamp::from_nanos((t * 1e9).round() as i64)
    }

    pub fn from_nanos(ns: i64) -> Stamp {
        Stamp {
            sec: ns.div_euclid(1_000_000_000) as i32,
            nanosec: ns.rem_euclid(1_000_000_000) as u32,
        }
    }

    pub fn nanos(self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
}

/// Classic little-endian CDR (XCDR1), as the RMW writes it: the encapsulation header, then each
/// value aligned to its own size, counted from the end of the header.
struct Cdr(Vec<u8>);

const HEADER: usize = 4;

impl Cdr {
    fn new() -> Cdr {
        Cdr(vec![0x00, 0x01, 0x00, 0x00])
    }

    fn align(&mut self, size: usize) {
        while !(self.0.len() - HEADER).is_multiple_of(size) {
            self.0.push(0);
        }
    }

    fn u32(&mut self, v: u32) {
        self.align(4);
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    fn i32(&mut self, v: i32) {
        self.align(4);
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    fn f64(&mut self, v: f64) {
        self.align(8);
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    /// A string: its length with the NUL, its bytes, the NUL.
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.0.extend_from_slice(s.as_bytes());
        self.0.push(0);
    }

    fn time(&mut self, stamp: Stamp) {
        self.i32(stamp.sec);
        self.u32(stamp.nanosec);
    }

    fn header(&mut self, stamp: Stamp, frame: &str) {
        self.time(stamp);
        self.string(frame);
    }

    fn f64s(&mut self, values: &[f64]) {
        values.iter().for_each(|&v| self.f64(v));
    }
}

/// rosgraph_msgs/msg/Clock: what ROS 2 nodes with `use_sim_time` run on.
pub fn clock(stamp: Stamp) -> Vec<u8> {
    let mut cdr = Cdr::new();
    cdr.time(stamp);
    cdr.0
}

/// geometry_msgs/msg/Vector3Stamped of `v` at `stamp` in `frame`.
fn vector3(stamp: Stamp, frame: &str, v: [f64; 3]) -> Vec<u8> {
    let mut cdr = Cdr::new();
    cdr.header(stamp, frame);
    cdr.f64s(&v);
    cdr.0
}

/// A vehicle's coordination state, in its body frame's name: x its γ_i (s), y its γ̇_i, z how
/// far γ_i is ahead of the fleet's time (γ_i − t, s; negative: behind the plan's timing).
pub fn gamma(state: &State, command: &Command, stamp: Stamp) -> Vec<u8> {
    vector3(
        stamp,
        &body_frame(state.id),
        [command.gamma, command.gamma_dot, command.gamma - state.t],
    )
}

/// The fleet's coordination state, in `map`: x the coordination error max |γ_i − γ_j| over the
/// vehicles with a command (a lost one coordinates with nobody), y the smallest distance
/// between two vehicles (m; infinite for one), z the fleet's mean γ_i − t (s).
pub fn coordination(fleet: &[(&State, Option<&Command>)], stamp: Stamp) -> Vec<u8> {
    // The metrics' own spread (D16), so that x is the error a run's summary reports.
    let gammas: Vec<f64> = fleet.iter().map(|(_, c)| c.map_or(0.0, |c| c.gamma)).collect();
    let positions: Vec<[f64; 2]> = fleet.iter().map(|(s, _)| s.position).collect();
    let (error, closest) =
        crate::outputs::metrics::spread(&gammas, &positions, &mut Vec::new(), |n| fleet[n].1.is_some());
    let commanded = fleet.iter().filter(|(_, c)| c.is_some()).count();
    let lag = fleet.iter().filter_map(|(s, c)| c.map(|c| c.gamma - s.t)).sum::<f64>() / commanded.max(1) as f64;
    vector3(stamp, MAP_FRAME, [error, closest, lag])
}

/// Vehicle `id`'s motion as a ROS 2 user expects of odometry: its pose in `map`, and its velocity
/// over ground and yaw rate in its body frame (REP 105: an odometry's twist is in its child frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Odometry {
    pub id: u32,
    pub stamp: Stamp,
    pub position: [f64; 2],
    /// ψ_B, rad, counter-clockwise from x.
    pub yaw: f64,
    /// Body frame: forward, left; m/s over ground.
    pub velocity: [f64; 2],
    pub yaw_rate: f64,
}

impl Odometry {
    /// A vehicle's odometry at `state`, with the command held over the tick for a kinematic
    /// vehicle's speed through the water (a dynamic one reports its own, D22). Over ground is
    /// through the water plus the current, turned into the body frame.
    pub fn of(state: &State, command: Option<&Command>, stamp: Stamp) -> Odometry {
        let (water, yaw_rate) = match (&state.dynamics, command) {
            (Some(d), _) => ([d.surge, d.sway], d.yaw_rate),
            // The kinematic vehicle moves along ψ_F = ψ_B + β at v (MODEL §2).
            (None, Some(c)) => ([c.v * state.sideslip.cos(), c.v * state.sideslip.sin()], c.r),
            (None, None) => ([0.0, 0.0], 0.0),
        };
        let (sin, cos) = state.heading.sin_cos();
        let [cx, cy] = state.current;
        let current = [cos * cx + sin * cy, -sin * cx + cos * cy];
        Odometry {
            id: state.id,
            stamp,
            position: state.position,
            yaw: state.heading,
            velocity: [water[0] + current[0], water[1] + current[1]],
            yaw_rate,
        }
    }

    /// nav_msgs/msg/Odometry, covariances zero: the simulation knows its state exactly.
    pub fn cdr(&self) -> Vec<u8> {
        self.cdr_in(MAP_FRAME)
    }

    /// As `cdr`, its pose said to be in `frame`.
    pub(crate) fn cdr_in(&self, frame: &str) -> Vec<u8> {
        let mut cdr = Cdr::new();
        cdr.header(self.stamp, frame);
        cdr.string(&body_frame(self.id));
        let (sin, cos) = (self.yaw / 2.0).sin_cos();
        cdr.f64s(&[self.position[0], self.position[1], 0.0]);
        cdr.f64s(&[0.0, 0.0, sin, cos]);
        cdr.f64s(&[0.0; 36]);
        cdr.f64s(&[self.velocity[0], self.velocity[1], 0.0]);
        cdr.f64s(&[0.0, 0.0, self.yaw_rate]);
        cdr.f64s(&[0.0; 36]);
        cdr.0
    }
}

/// geometry_msgs/msg/Twist of a command, what a ROS 2 node playing the vehicle follows: linear.x
/// the speed through the water v along the vehicle's flow heading ψ_B + β (m/s), angular.z the
/// yaw rate r (rad/s), counter-clockwise.
pub fn twist(command: &Command) -> Vec<u8> {
    let mut cdr = Cdr::new();
    cdr.f64s(&[command.v, 0.0, 0.0, 0.0, 0.0, command.r]);
    cdr.0
}

/// Spacing of a published path's poses in γ, s of planned time: 10 poses a second is smoother
/// than any vehicle's turn and a few hundred poses a path.
pub const PATH_STEP: f64 = 0.1;

/// nav_msgs/msg/Path of a vehicle's generalized path on γ ∈ [0, t_f], a pose every
/// `PATH_STEP`: each pose where the plan puts the vehicle at time γ, heading along the path, and
/// stamped with that time (`stamp_of(γ)`), so a pose says where and when.
pub fn path(path: &GeneralizedPath, stamp_of: impl Fn(f64) -> Stamp) -> Vec<u8> {
    let t_f = path.t_f();
    let n = (t_f / PATH_STEP).ceil() as u32;
    let mut cdr = Cdr::new();
    cdr.header(stamp_of(0.0), MAP_FRAME);
    cdr.u32(n + 1);
    for k in 0..=n {
        let gamma = (f64::from(k) * PATH_STEP).min(t_f);
        let at = path.at(gamma);
        let (sin, cos) = (at.heading / 2.0).sin_cos();
        cdr.header(stamp_of(gamma), MAP_FRAME);
        cdr.f64s(&[at.position.x, at.position.y, 0.0, 0.0, 0.0, sin, cos]);
    }
    cdr.0
}

/// A directed link's γ messages so far, as the receiver's commands judged them: x sent (judged at
/// a communication instant; a modem's `busy` instants sent nothing), y delivered, z lost, in `map`. Counts only grow: a ROS 2 plot shows
/// the link's losses pile up, and their slope is its rate.
pub fn link(counts: LinkCount, stamp: Stamp) -> Vec<u8> {
    vector3(
        stamp,
        MAP_FRAME,
        [
            counts.sent as f64,
            counts.delivered as f64,
            (counts.sent - counts.delivered) as f64,
        ],
    )
}

/// std_msgs/msg/String: one γ message's fate on a link, `delivered` or the cause that lost it
/// (`half_duplex`, `collision`, … as `messages.csv` words it).
pub fn cause(cause: crate::msg::Cause) -> Vec<u8> {
    let mut cdr = Cdr::new();
    cdr.string(cause.name());
    cdr.0
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkCount {
    pub sent: u64,
    pub delivered: u64,
}

/// Every link's counts, from the commands that report them (each command's receptions), each
/// command once however often the world hands it over (a realtime world holds one for ticks).
#[derive(Debug, Default)]
pub struct LinkCounts {
    counted: BTreeMap<u32, u64>,
    links: BTreeMap<(u32, u32), LinkCount>,
}

impl LinkCounts {
    /// The links `command` reports on, as (from, to) with their counts after it and what became
    /// of the message (a busy instant too, which counts as nothing sent); none if it was counted
    /// already.
    pub fn count(&mut self, command: &Command) -> Vec<((u32, u32), LinkCount, crate::msg::Cause)> {
        if self.counted.get(&command.id).is_some_and(|&tick| tick >= command.tick) {
            return Vec::new();
        }
        self.counted.insert(command.id, command.tick);
        command
            .receptions
            .iter()
            .map(|r| {
                let link = (r.from, command.id);
                let c = self.links.entry(link).or_default();
                if r.cause.was_sent() {
                    c.sent += 1;
                    c.delivered += u64::from(r.delivered);
                }
                (link, *c, r.cause)
            })
            .collect()
    }
}

/// Classic CDR as it arrives: the encapsulation header (little-endian only: the RMW writes the
/// host's order, and ROS 2 runs on little-endian machines), then values aligned as `Cdr` writes
/// them.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

/// A payload that is not the message its key says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Malformed;

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8]) -> Result<Reader<'a>, Malformed> {
        match bytes {
            [0x00, 0x01, _, _, ..] => Ok(Reader { bytes, at: HEADER }),
            _ => Err(Malformed),
        }
    }

    fn take<const N: usize>(&mut self) -> Result<[u8; N], Malformed> {
        while !(self.at - HEADER).is_multiple_of(N) {
            self.at += 1;
        }
        let end = self.at + N;
        let taken = self.bytes.get(self.at..end).ok_or(Malformed)?;
        self.at = end;
        Ok(taken.try_into().expect("N bytes"))
    }

    fn u32(&mut self) -> Result<u32, Malformed> {
        self.take::<4>().map(u32::from_le_bytes)
    }

    fn f64(&mut self) -> Result<f64, Malformed> {
        self.take::<8>().map(f64::from_le_bytes)
    }

    fn f64s<const N: usize>(&mut self) -> Result<[f64; N], Malformed> {
        let mut out = [0.0; N];
        for v in &mut out {
            *v = self.f64()?;
        }
        Ok(out)
    }

    fn string(&mut self) -> Result<&'a str, Malformed> {
        let n = self.u32()? as usize;
        let end = self.at.checked_add(n).ok_or(Malformed)?;
        let bytes = self.bytes.get(self.at..end).ok_or(Malformed)?;
        self.at = end;
        match bytes.split_last() {
            Some((0, text)) => std::str::from_utf8(text).map_err(|_| Malformed),
            _ => Err(Malformed),
        }
    }

    fn stamp(&mut self) -> Result<Stamp, Malformed> {
        let sec = self.u32()? as i32;
        Ok(Stamp {
            sec,
            nanosec: self.u32()?,
        })
    }
}

impl Odometry {
    /// The odometry a ROS 2 node publishes for vehicle `id` (nav_msgs/msg/Odometry): its header's
    /// stamp, its pose's position and yaw, its twist (in its child frame, the body's, as REP 105
    /// has it). What else it says (frames, z, covariances) the fleet does not use.
    pub fn from_cdr(id: u32, bytes: &[u8]) -> Result<Odometry, Malformed> {
        let mut r = Reader::new(bytes)?;
        let stamp = r.stamp()?;
        r.string()?;
        r.string()?;
        let [x, y, _] = r.f64s::<3>()?;
        let [qx, qy, qz, qw] = r.f64s::<4>()?;
        r.f64s::<36>()?;
        let [vx, vy, _] = r.f64s::<3>()?;
        let [_, _, yaw_rate] = r.f64s::<3>()?;
        r.f64s::<36>()?;
        Ok(Odometry {
            id,
            stamp,
            position: [x, y],
            // The yaw of a quaternion, whatever its norm (REP 103's z-y-x order).
            yaw: (2.0 * (qw * qz + qx * qy)).atan2(1.0 - 2.0 * (qy * qy + qz * qz)),
            velocity: [vx, vy],
            yaw_rate,
        })
    }

    /// The frame an odometry's pose is in: its header's `frame_id`.
    pub fn frame_of(bytes: &[u8]) -> Result<&str, Malformed> {
        let mut r = Reader::new(bytes)?;
        r.stamp()?;
        r.string()
    }
}

/// Vehicles played by ROS 2 nodes, as the fleet sees them: each one's odometry made the `State`
/// its agent and the recorders take from a vehicle of the world's own (docs/ROS2.md).
#[derive(Debug, Clone)]
pub struct Played {
    /// The water current, inertial frame, m/s: the mission's, which the node need not know.
    current: [f64; 2],
    /// The fleet's t = 0 as the stamps count time, s; and how many simulated seconds a stamp's
    /// second is.
    epoch: UnixTime,
    time_scale: f64,
    control_period: f64,
    /// Per vehicle, its newest state.
    newest: BTreeMap<u32, State>,
    /// Per vehicle, its odometries that fell in a tick already taken.
    surplus: BTreeMap<u32, u64>,
    /// Odometries refused for their frame, by vehicle and frame name (`WRONG_FRAMES` names at
    /// most, each cut to `FRAME_NAME` bytes, the rest counted under `OTHER_FRAMES`).
    wrong_frames: BTreeMap<(u32, String), u64>,
}

/// How many frame names `Played` counts apart: a node that changes its frame every message
/// makes a count, not a list.
const WRONG_FRAMES: usize = 16;
const FRAME_NAME: usize = 64;
const OTHER_FRAMES: &str = "(other frames)";

/// Why a played vehicle's odometry made no state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refused {
    /// Longer than `ODOMETRY_MAX_BYTES`: refused unread.
    TooLarge,
    /// Not a nav_msgs/msg/Odometry in CDR.
    Malformed,
    NonFinite,
    /// Stamped before the fleet's t = 0: a vehicle's odometry flows before the run starts.
    Early,
    /// Older than one already taken (overtaken on the way).
    Stale,
    /// Of a tick whose state an earlier odometry already made: a tick has one state, which the
    /// world has published (a driver faster than the control period, or its jitter, puts two
    /// in one tick; taken, each would be a different state of that tick, a conflict). The
    /// first is taken rather than the newest: published as it comes, the agent acts on it
    /// within the period, where waiting for the tick to close would make every state a period
    /// older. Counted (`Played::surplus`).
    Surplus,
    /// Stamped more than `LEAD` ahead of the fleet's clock: a wrong clock, not a skew. Taken,
    /// it would be the vehicle's newest state until the fleet caught up with it, and every
    /// genuine one before then "older".
    Ahead,
    /// Its pose is in another frame than `MAP_FRAME`, the fleet's: taken, a driver's `odom`
    /// pose would put the vehicle where it is not. Counted by frame name (`Played::wrong_frames`).
    Frame,
}

/// The longest odometry taken: its numbers are 700 bytes, and its two frame names a few dozen.
pub const ODOMETRY_MAX_BYTES: usize = 4096;

/// s of fleet time: how far ahead of the fleet's clock a played vehicle's stamp may be (two
/// machines' clocks, a driver's latency).
pub const LEAD: f64 = 1.0;

impl Played {
    /// The vehicles of `mission`'s fleet whose clock began at Unix time `epoch` (realtime).
    pub fn new(mission: &Mission, epoch: UnixTime) -> Played {
        let (sin, cos) = mission.current.direction.sin_cos();
        Played {
            current: [mission.current.speed * cos, mission.current.speed * sin],
            epoch,
            time_scale: mission.mission.time_scale,
            control_period: mission.mission.control_period,
            newest: BTreeMap::new(),
            surplus: BTreeMap::new(),
            wrong_frames: BTreeMap::new(),
        }
    }

    /// The state of vehicle `id` that its node's odometry `cdr` says, the fleet's clock at tick
    /// `now`: refused if it is no odometry, in another frame than the map, stamped more than
    /// `LEAD` ahead of `now`, older than one already taken, or of the same tick as one taken
    /// (the first of a tick is its state).
    pub fn on_odometry(&mut self, id: u32, cdr: &[u8], now: u64) -> Result<State, Refused> {
        if cdr.len() > ODOMETRY_MAX_BYTES {
            return Err(Refused::TooLarge);
        }
        let odometry = Odometry::from_cdr(id, cdr).map_err(|Malformed| Refused::Malformed)?;
        let frame = Odometry::frame_of(cdr).map_err(|Malformed| Refused::Malformed)?;
        if frame != MAP_FRAME {
            self.count_frame(id, frame);
            return Err(Refused::Frame);
        }
        let state = self.state(&odometry)?;
        if state.t > now as f64 * self.control_period + LEAD {
            return Err(Refused::Ahead);
        }
        match self.newest.get(&id) {
            Some(held) if held.tick > state.tick => return Err(Refused::Stale),
            Some(held) if held.tick == state.tick => {
                *self.surplus.entry(id).or_default() += 1;
                return Err(Refused::Surplus);
            }
            _ => {}
        }
        self.newest.insert(id, state);
        Ok(state)
    }

    fn count_frame(&mut self, id: u32, frame: &str) {
        let mut name: String = frame.chars().take(FRAME_NAME).collect();
        if !self.wrong_frames.contains_key(&(id, name.clone())) && self.wrong_frames.len() >= WRONG_FRAMES {
            name = OTHER_FRAMES.into();
        }
        *self.wrong_frames.entry((id, name)).or_default() += 1;
    }

    /// Per vehicle, its odometries that fell in a tick already taken, in id order.
    pub fn surplus(&self) -> Vec<(u32, u64)> {
        self.surplus.iter().map(|(&id, &n)| (id, n)).collect()
    }

    /// The frames vehicle `id`'s odometries were refused for, each with how many.
    pub fn refused_frames(&self, id: u32) -> impl Iterator<Item = (&str, u64)> {
        let from = (id, String::new());
        self.wrong_frames
            .range(from..)
            .take_while(move |((v, _), _)| *v == id)
            .map(|((_, frame), &n)| (frame.as_str(), n))
    }

    /// The odometries refused for their frame: vehicle, frame name and how many, in that order.
    pub fn wrong_frames(&self) -> Vec<(u32, String, u64)> {
        self.wrong_frames
            .iter()
            .map(|((id, frame), &n)| (*id, frame.clone(), n))
            .collect()
    }

    /// Whether a node played vehicle `id`: its odometry made a state.
    pub fn heard(&self, id: u32) -> bool {
        self.newest.contains_key(&id)
    }

    /// The newest state of each vehicle a node played, in id order.
    pub fn states(&self) -> impl Iterator<Item = &State> {
        self.newest.values()
    }

    /// The state odometry `o` says: the tick its stamp falls on and its pose. The vehicle is
    /// taken as the kinematic vehicle of MODEL §2 without side-slip (ψ_F = ψ_B), as a vehicle of
    /// another program is (docs/PROTOCOL.md): a twist says β only as well as the vehicle knows the
    /// current, and a driver that leaves it zero would turn the current into a false β. Refused:
    /// odometry stamped before the fleet's t = 0, or not finite.
    fn state(&self, o: &Odometry) -> Result<State, Refused> {
        let t = self
            .epoch
            .simulated_at(UnixTime(o.stamp.nanos() as f64 * 1e-9), self.time_scale);
        if ![o.position[0], o.position[1], o.yaw, t].iter().all(|v| v.is_finite()) {
            return Err(Refused::NonFinite);
        }
        if t < -self.control_period / 2.0 {
            return Err(Refused::Early);
        }
        let tick = (t / self.control_period).round() as u64;
        Ok(State {
            version: crate::msg::PROTOCOL_VERSION,
            tick,
            id: o.id,
            t: tick as f64 * self.control_period,
            position: o.position,
            heading: o.yaw,
            sideslip: 0.0,
            sideslip_rate: 0.0,
            current: self.current,
            dynamics: None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::PROTOCOL_VERSION;

    #[test]
    fn keys_and_tokens_are_the_rmws() {
        let zid = "5af83680cf352c29b0a98954d16a5470";
        let fleet = Ros2Config::on(0);
        let topic = fleet.odometry_topic(1);
        assert_eq!(
            fleet.data_key(&topic, &ODOMETRY),
            "0/tcpf/vehicle_1/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0"
        );
        assert_eq!(
            Ros2Config::on(7).data_key("/clock", &CLOCK),
            "7/clock/rosgraph_msgs::msg::dds_::Clock_/RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564"
        );
        let world = Node {
            zid,
            id: 0,
            name: "world",
        };
        assert_eq!(
            fleet.node_token(&world),
            "@ros2_lv/0/5af83680cf352c29b0a98954d16a5470/0/0/NN/%/%tcpf/world"
        );
        assert_eq!(
            fleet.entity_token(&world, 3, Entity::Publisher, &topic, &ODOMETRY, QOS),
            "@ros2_lv/0/5af83680cf352c29b0a98954d16a5470/0/3/MP/%/%tcpf/world/%tcpf%vehicle_1%odom/nav_msgs::msg::dds_::Odometry_/RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0/1:2:1,10:,:,:,,"
        );
        let lab = Ros2Config {
            domain: 4,
            namespace: "/lab/fleet_1".into(),
        };
        let agent = Node {
            zid,
            id: 2,
            name: "agent_1",
        };
        assert_eq!(lab.command_topic(1), "/lab/fleet_1/vehicle_1/cmd");
        assert_eq!(
            lab.entity_token(&agent, 5, Entity::Subscription, &lab.command_topic(1), &TWIST, QOS),
            "@ros2_lv/4/5af83680cf352c29b0a98954d16a5470/2/5/MS/%/%lab%fleet_1/agent_1/%lab%fleet_1%vehicle_1%cmd/geometry_msgs::msg::dds_::Twist_/RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a/1:2:1,10:,:,:,,"
        );
        let root = Ros2Config {
            domain: 0,
            namespace: "/".into(),
        };
        assert_eq!(
            (root.link_topic(2, 1), root.path_topic(3), root.coordination_topic()),
            (
                "/links/from_2_to_1".into(),
                "/vehicle_3/path".into(),
                "/coordination".into()
            )
        );
        assert_eq!(
            root.node_token(&world),
            "@ros2_lv/0/5af83680cf352c29b0a98954d16a5470/0/0/NN/%/%/world"
        );
        assert_eq!(lab.any_node_token("world"), "@ros2_lv/4/*/*/*/NN/%/%lab%fleet_1/world");
    }

    #[test]
    fn the_attachment_is_33_bytes_in_the_rmws_layout() {
        let gid: [u8; 16] = std::array::from_fn(|i| i as u8 + 1);
        let a = attachment(3, 1_500_000_000, gid);
        assert_eq!(a[..8], [3, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(i64::from_le_bytes(a[8..16].try_into().unwrap()), 1_500_000_000);
        assert_eq!(a[16], 16);
        assert_eq!(a[17..], gid);
    }

    #[test]
    fn a_definition_holds_each_type_inside_once_depth_first() {
        let rule = "=".repeat(80);
        assert_eq!(
            TWIST.definition(),
            format!("geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n{rule}\nMSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n")
        );
        let inside = |ty: Type| -> Vec<String> {
            ty.definition()
                .lines()
                .filter_map(|l| l.strip_prefix("MSG: ").map(str::to_string))
                .collect()
        };
        assert_eq!(
            inside(PATH),
            [
                "std_msgs/Header",
                "builtin_interfaces/Time",
                "geometry_msgs/PoseStamped",
                "geometry_msgs/Pose",
                "geometry_msgs/Point",
                "geometry_msgs/Quaternion"
            ]
        );
        assert_eq!(inside(ODOMETRY).len(), 9);
        assert_eq!(STRING.definition(), "string data\n");
        let topics = FleetTopic::of_fleet(&[1, 2], &[(1, 2), (2, 1)], true);
        assert_eq!(topics.len(), 1 + 2 * 4 + 2 * 2 + 1);
        assert!(topics.iter().all(|t| !t.ty().definition().is_empty()));
        assert_eq!(FleetTopic::Path(1).qos(), QOS_TRANSIENT_LOCAL);
    }

    #[test]
    fn stamps_split_whole_seconds_and_nanoseconds() {
        assert_eq!(
            Stamp::from_seconds(45.69),
            Stamp {
                sec: 45,
                nanosec: 690_000_000
            }
        );
        assert_eq!(
            Stamp::from_nanos(-1),
            Stamp {
                sec: -1,
                nanosec: 999_999_999
            }
        );
        assert_eq!(Stamp::from_seconds(1.25).nanos(), 1_250_000_000);
        let mut fleet = Clock {
            version: crate::msg::PROTOCOL_VERSION,
            realtime: false,
            time_scale: 5.0,
            epoch: UnixTime(1_000.0),
            tick: 0,
            mission: 0,
        };
        assert_eq!(
            Stamp::of_fleet(&fleet, 10.0),
            Stamp::from_seconds(10.0),
            "lockstep: simulated time"
        );
        fleet.realtime = true;
        assert_eq!(
            Stamp::of_fleet(&fleet, 10.0),
            Stamp::from_seconds(1_002.0),
            "realtime at 5x"
        );
        assert_eq!(
            clock(Stamp { sec: 2, nanosec: 5 }),
            [0, 1, 0, 0, 2, 0, 0, 0, 5, 0, 0, 0]
        );
    }

    fn state(heading: f64, sideslip: f64, current: [f64; 2]) -> State {
        State {
            version: PROTOCOL_VERSION,
            tick: 10,
            id: 2,
            t: 0.1,
            position: [3.0, -4.0],
            heading,
            sideslip,
            sideslip_rate: 0.0,
            current,
            dynamics: None,
        }
    }

    fn command(v: f64, r: f64) -> Command {
        Command {
            v,
            r,
            ..crate::fixtures::command_at(2, 10, 0.0)
        }
    }

    #[test]
    fn odometry_is_over_ground_in_the_body_frame() {
        let stamp = Stamp::from_seconds(0.1);
        // Heading north at 1 m/s through the water, a current of 0.5 m/s east: over ground the
        // vehicle goes forward at 1 and to its right (body y < 0) at 0.5.
        let o = Odometry::of(
            &state(std::f64::consts::FRAC_PI_2, 0.0, [0.5, 0.0]),
            Some(&command(1.0, 0.2)),
            stamp,
        );
        assert!(
            (o.velocity[0] - 1.0).abs() < 1e-12 && (o.velocity[1] + 0.5).abs() < 1e-12,
            "{o:?}"
        );
        assert_eq!((o.yaw_rate, o.position, o.id), (0.2, [3.0, -4.0], 2));
        // A side-slip of β: the water carries the speed along ψ_B + β.
        let o = Odometry::of(&state(0.0, 0.1, [0.0, 0.0]), Some(&command(2.0, 0.0)), stamp);
        assert!(
            (o.velocity[0] - 2.0 * 0.1f64.cos()).abs() < 1e-12 && (o.velocity[1] - 2.0 * 0.1f64.sin()).abs() < 1e-12
        );
        // No command yet: the current alone.
        let o = Odometry::of(&state(0.0, 0.0, [0.0, 0.3]), None, stamp);
        assert_eq!(o.velocity, [0.0, 0.3]);
    }

    /// Offsets from the layout of nav_msgs/msg/Odometry in classic CDR: the header's stamp and
    /// frame, the child frame, then 8-aligned doubles.
    #[test]
    fn odometry_cdr_puts_every_field_where_cdr_aligns_it() {
        let o = Odometry {
            id: 1,
            stamp: Stamp { sec: 3, nanosec: 7 },
            position: [1.5, -2.5],
            yaw: std::f64::consts::FRAC_PI_2,
            velocity: [0.25, 0.5],
            yaw_rate: -0.125,
        };
        let b = o.cdr();
        let f = |at: usize| f64::from_le_bytes(b[HEADER + at..HEADER + at + 8].try_into().unwrap());
        let u = |at: usize| u32::from_le_bytes(b[HEADER + at..HEADER + at + 4].try_into().unwrap());
        assert_eq!(b[..HEADER], [0, 1, 0, 0]);
        assert_eq!((u(0), u(4), u(8)), (3, 7, 4));
        assert_eq!(&b[HEADER + 12..HEADER + 16], b"map\0");
        assert_eq!(u(16), 10);
        assert_eq!(&b[HEADER + 20..HEADER + 30], b"vehicle_1\0");
        assert_eq!((f(32), f(40), f(48)), (1.5, -2.5, 0.0));
        assert!(
            (f(72) - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-15
                && (f(80) - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-15
        );
        assert_eq!((f(88 + 288), f(96 + 288), f(128 + 288)), (0.25, 0.5, -0.125));
        assert_eq!(b.len(), HEADER + 136 + 288 + 288);
    }

    /// The three doubles at the end of a Vector3Stamped.
    fn vector(cdr: &[u8]) -> [f64; 3] {
        let at = cdr.len() - 24;
        std::array::from_fn(|k| f64::from_le_bytes(cdr[at + 8 * k..at + 8 * k + 8].try_into().unwrap()))
    }

    #[test]
    fn the_coordination_state_leaves_out_a_vehicle_with_no_command() {
        let mut a = state(0.0, 0.0, [0.0, 0.0]);
        let mut b = a;
        let mut lost = a;
        (a.id, b.id, lost.id) = (1, 2, 3);
        (b.position, lost.position) = ([6.0, 0.0], [3.0, -3.5]);
        let (ca, cb) = (
            crate::fixtures::command_at(1, 10, 0.3),
            crate::fixtures::command_at(2, 10, 0.05),
        );
        let stamp = Stamp::from_seconds(0.1);
        // γ 0.3 and 0.05 at t = 0.1; the third vehicle, lost, has no γ but is still in the way.
        let v = vector(&coordination(&[(&a, Some(&ca)), (&b, Some(&cb)), (&lost, None)], stamp));
        assert!((v[0] - 0.25).abs() < 1e-15 && (v[2] - 0.075).abs() < 1e-15, "{v:?}");
        assert_eq!(v[1], 0.5, "the lost vehicle is 0.5 m from vehicle 1");
        assert_eq!(vector(&gamma(&a, &ca, stamp)), [0.3, 1.0, 0.3 - 0.1]);
        let alone = vector(&coordination(&[(&a, Some(&ca))], stamp));
        assert_eq!((alone[0], alone[1]), (0.0, f64::INFINITY), "a fleet of one");
    }

    #[test]
    fn a_twist_carries_the_speed_and_yaw_rate() {
        let b = twist(&command(0.75, -0.125));
        let f: Vec<f64> = b[HEADER..]
            .chunks(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert_eq!((b.len(), f), (HEADER + 48, vec![0.75, 0.0, 0.0, 0.0, 0.0, -0.125]));
    }

    #[test]
    fn odometry_reads_back_what_it_writes_and_refuses_what_it_is_not() {
        let o = Odometry {
            id: 2,
            stamp: Stamp {
                sec: 12,
                nanosec: 340_000_000,
            },
            position: [3.5, -1.25],
            yaw: 2.5,
            velocity: [0.5, 0.125],
            yaw_rate: 0.0625,
        };
        let back = Odometry::from_cdr(2, &o.cdr()).unwrap();
        assert!((back.yaw - 2.5).abs() < 1e-12, "{back:?}");
        assert_eq!(Odometry { yaw: 2.5, ..back }, o);
        // A yaw past ±π comes back as the same heading.
        let back = Odometry::from_cdr(2, &Odometry { yaw: -3.0, ..o }.cdr()).unwrap();
        assert!((back.yaw + 3.0).abs() < 1e-12);
        let bytes = o.cdr();
        assert_eq!(
            Odometry::from_cdr(2, &bytes[..bytes.len() - 1]),
            Err(Malformed),
            "cut short"
        );
        assert_eq!(Odometry::from_cdr(2, &[]), Err(Malformed));
        let mut big_endian = bytes.clone();
        big_endian[1] = 0;
        assert_eq!(Odometry::from_cdr(2, &big_endian), Err(Malformed));
        let mut unterminated = bytes;
        unterminated[HEADER + 12 + 3] = b'!';
        assert_eq!(
            Odometry::from_cdr(2, &unterminated),
            Err(Malformed),
            "a frame without its NUL"
        );
    }

    #[test]
    fn a_played_vehicles_odometry_is_the_state_of_the_tick_its_stamp_falls_on() {
        let (mut mission, _, _) = crate::fixtures::case_b();
        mission.mission.time_scale = 5.0;
        let mut played = Played::new(&mission, UnixTime(1_000.0));
        let o = Odometry {
            id: 2,
            stamp: Stamp::from_seconds(1_002.000_6),
            position: [1.0, 2.0],
            yaw: 0.5,
            velocity: [0.0, 0.0],
            yaw_rate: 0.0,
        };
        assert!(!played.heard(2));
        // 2.0006 wall seconds at 5x: t = 10.003 s, tick 1000 to the nearest period.
        let s = played.on_odometry(2, &o.cdr(), 1000).unwrap();
        assert_eq!(
            (s.id, s.tick, s.t, s.position, s.heading),
            (2, 1000, 10.0, [1.0, 2.0], 0.5)
        );
        // Case (b)'s current, 0.1 m/s towards π.
        assert!(
            (s.current[0] + 0.1).abs() < 1e-15 && s.current[1].abs() < 1e-15,
            "{:?}",
            s.current
        );
        assert_eq!((s.sideslip, s.dynamics), (0.0, None));
        assert!(crate::msg::Checked::finite(&s) && played.heard(2));
        let at = |t: f64| Odometry {
            stamp: Stamp::from_seconds(t),
            ..o
        };
        let again = Odometry {
            position: [1.5, 2.0],
            ..at(1_002.0)
        };
        assert_eq!(
            played.on_odometry(2, &again.cdr(), 1000),
            Err(Refused::Surplus),
            "the same tick again: its state is the first's"
        );
        assert_eq!(played.states().next().map(|s| s.position), Some([1.0, 2.0]));
        assert_eq!(played.on_odometry(2, &at(1_001.0).cdr(), 1000), Err(Refused::Stale));
        // 0.5 wall s ahead at 5x: 2.5 s of the fleet's time ahead of tick 1000; 2038, years.
        assert_eq!(played.on_odometry(2, &at(1_002.5).cdr(), 1000), Err(Refused::Ahead));
        assert_eq!(
            played.on_odometry(2, &at(2_145_916_800.0).cdr(), 1000),
            Err(Refused::Ahead)
        );
        assert_eq!(
            played.on_odometry(2, &at(1_002.1).cdr(), 1000).map(|s| s.tick),
            Ok(1050),
            "0.5 s of the fleet's time ahead: a clock's skew"
        );
        assert_eq!(
            played.on_odometry(3, &at(999.0).cdr(), 1000),
            Err(Refused::Early),
            "before t = 0"
        );
        let mut long = at(1_003.0).cdr();
        long.resize(ODOMETRY_MAX_BYTES + 1, 0);
        assert_eq!(
            played.on_odometry(2, &long, 1000),
            Err(Refused::TooLarge),
            "refused unread"
        );
        // A driver's own odometry frame is no map: refused, and counted under its name.
        let odom = at(1_003.0).cdr_in("odom");
        assert_eq!(Odometry::frame_of(&odom), Ok("odom"));
        assert_eq!(played.on_odometry(2, &odom, 1000), Err(Refused::Frame));
        assert_eq!(played.on_odometry(2, &odom, 1000), Err(Refused::Frame));
        for n in 0..WRONG_FRAMES + 3 {
            let frame = format!("frame_{n}_{}", "x".repeat(100));
            assert_eq!(
                played.on_odometry(3, &at(1_003.0).cdr_in(&frame), 1000),
                Err(Refused::Frame)
            );
        }
        let counted = played.wrong_frames();
        assert_eq!(counted.len(), WRONG_FRAMES + 1, "{counted:?}");
        assert_eq!(counted[0], (2, "odom".to_string(), 2));
        assert!(counted.iter().all(|(_, f, _)| f.len() <= FRAME_NAME), "{counted:?}");
        assert!(counted.contains(&(3, OTHER_FRAMES.to_string(), 4)), "{counted:?}");
        assert_eq!(played.refused_frames(2).collect::<Vec<_>>(), [("odom", 2)]);
        assert_eq!(played.refused_frames(3).count(), WRONG_FRAMES);
        let nan = Odometry {
            position: [f64::NAN, 0.0],
            ..o
        };
        assert_eq!(played.on_odometry(2, &nan.cdr(), 1000), Err(Refused::NonFinite));
        assert_eq!(played.on_odometry(2, &[0, 1, 0, 0, 7], 1000), Err(Refused::Malformed));
        assert!(!played.heard(3));
        let held: Vec<(u32, u64)> = played.states().map(|s| (s.id, s.tick)).collect();
        assert_eq!(held, [(2, 1050)], "the newest state of each vehicle heard");
    }

    #[test]
    fn links_count_each_command_once() {
        let mut counts = LinkCounts::default();
        let heard = |tick, delivered| Command {
            receptions: vec![crate::msg::Reception::of(
                1,
                if delivered {
                    crate::msg::Cause::Delivered
                } else {
                    crate::msg::Cause::Loss
                },
                0.0,
                None,
            )],
            ..crate::fixtures::command_at(2, tick, 0.0)
        };
        use crate::msg::Cause;
        assert_eq!(
            counts.count(&heard(10, true)),
            vec![((1, 2), LinkCount { sent: 1, delivered: 1 }, Cause::Delivered)]
        );
        assert_eq!(counts.count(&heard(10, true)), vec![], "the same command held again");
        let after = counts.count(&heard(20, false));
        assert_eq!(after, vec![((1, 2), LinkCount { sent: 2, delivered: 1 }, Cause::Loss)]);
        assert_eq!(vector(&link(after[0].1, Stamp::from_seconds(0.2))), [2.0, 1.0, 1.0]);
        // A busy instant is no message sent: its cause is said, the counts stay.
        let busy = Command {
            receptions: vec![crate::msg::Reception::of(1, Cause::Busy, 0.3, None)],
            ..crate::fixtures::command_at(2, 30, 0.0)
        };
        assert_eq!(
            counts.count(&busy),
            vec![((1, 2), LinkCount { sent: 2, delivered: 1 }, Cause::Busy)]
        );
        let said = cause(Cause::HalfDuplex);
        assert_eq!(
            &said[..8],
            [0, 1, 0, 0, 12, 0, 0, 0],
            "CDR: header, then the length with its NUL"
        );
        assert_eq!(&said[8..], b"half_duplex\0");
        assert_eq!(
            counts.count(&crate::fixtures::command_at(2, 21, 0.0)),
            vec![],
            "no instant"
        );
    }

    /// nav_msgs/msg/Path: its header, the pose count, then each pose's header (stamp and frame)
    /// and pose, 8-aligned, every 0.1 s of γ up to t_f exactly.
    #[test]
    fn a_path_is_where_and_when_the_plan_puts_the_vehicle() {
        let (_, paths, t_f) = crate::fixtures::case_b();
        let b = path(&paths[0].1, Stamp::from_seconds);
        let mut r = Reader::new(&b).unwrap();
        assert_eq!(
            (r.stamp().unwrap(), r.string().unwrap()),
            (Stamp::from_seconds(0.0), "map")
        );
        let n = r.u32().unwrap() as usize;
        assert_eq!(n, (t_f / PATH_STEP).ceil() as usize + 1);
        for k in 0..n {
            let gamma = (k as f64 * PATH_STEP).min(t_f);
            let at = paths[0].1.at(gamma);
            assert_eq!(
                (r.stamp().unwrap(), r.string().unwrap()),
                (Stamp::from_seconds(gamma), "map")
            );
            let [x, y, z, qx, qy, qz, qw] = r.f64s::<7>().unwrap();
            assert_eq!([x, y, z, qx, qy], [at.position.x, at.position.y, 0.0, 0.0, 0.0]);
            assert!((2.0 * qz.atan2(qw) - at.heading).abs() < 1e-12);
        }
        assert_eq!(r.at, b.len(), "nothing after the last pose");
    }
}
