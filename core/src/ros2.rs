//! ROS 2 as its Zenoh RMW speaks it (docs/ROS2.md names the RMW and its version), so that ROS 2 tools
//! on the fleet's network see the fleet with no bridge: the key expressions, liveliness tokens,
//! sample attachment and CDR payloads of the standard messages the world publishes. The format is
//! that RMW's from its 0.2.4 (ROS 2 Jazzy; Kilted's 0.6 and Rolling's are the same). Bytes only:
//! the world's shell puts them on the bus.

use crate::msg::{Command, State};

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

/// The namespace of every node and topic of the fleet.
pub const NAMESPACE: &str = "/tcpf";

/// The inertial frame of every pose (REP 105's `map`: x east, y north, z up; yaw
/// counter-clockwise from x, as the mission's headings are).
pub const MAP_FRAME: &str = "map";

/// The QoS every publisher declares: reliable, volatile, keep last 10 (rclcpp's default), the
/// durability written out, since the RMW's 0.2.0-0.2.2 read an empty one as transient local.
pub const QOS: &str = "1:2:1,10:,:,:,,";

/// A vehicle's body frame (REP 103: x forward, y left, z up).
pub fn body_frame(id: u32) -> String {
    format!("vehicle_{id}")
}

/// The odometry topic of vehicle `id`.
pub fn odometry_topic(id: u32) -> String {
    format!("{NAMESPACE}/vehicle_{id}/odom")
}

/// The coordination state of vehicle `id` (`gamma`).
pub fn gamma_topic(id: u32) -> String {
    format!("{NAMESPACE}/vehicle_{id}/gamma")
}

/// The fleet's coordination state (`coordination`).
pub fn coordination_topic() -> String {
    format!("{NAMESPACE}/coordination")
}

/// Where the RMW publishes `topic` (a fully qualified name) of type `ty` on `domain`: the
/// topic without its leading slash, its inner slashes kept as chunks.
pub fn data_key(domain: u32, topic: &str, ty: &Type) -> String {
    format!("{domain}/{}/{}/{}", topic.trim_matches('/'), ty.dds, ty.hash)
}

/// A name in a liveliness token: the RMW writes every `/` as `%`, the root as `%`.
fn mangled(name: &str) -> String {
    name.replace('/', "%")
}

/// The liveliness token that makes node `node` of `NAMESPACE` (entity `nid` of session `zid`)
/// part of the ROS 2 graph of `domain`: `ros2 node list` shows it while the token lives.
pub fn node_token(domain: u32, zid: &str, nid: u32, node: &str) -> String {
    format!("@ros2_lv/{domain}/{zid}/{nid}/{nid}/NN/%/{}/{node}", mangled(NAMESPACE))
}

/// The liveliness token of a publisher (entity `id` of node `nid`) of `topic`: `ros2 topic list`
/// shows the topic while it lives.
pub fn publisher_token(domain: u32, zid: &str, nid: u32, id: u32, node: &str, topic: &str, ty: &Type) -> String {
    format!(
        "@ros2_lv/{domain}/{zid}/{nid}/{id}/MP/%/{}/{node}/{}/{}/{}/{QOS}",
        mangled(NAMESPACE),
        mangled(topic),
        ty.dds,
        ty.hash
    )
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
    let (error, closest) = crate::metrics::spread(&gammas, &positions, &mut Vec::new(), |n| fleet[n].1.is_some());
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
        let mut cdr = Cdr::new();
        cdr.header(self.stamp, MAP_FRAME);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::PROTOCOL_VERSION;

    #[test]
    fn keys_and_tokens_are_the_rmws() {
        let zid = "5af83680cf352c29b0a98954d16a5470";
        let topic = odometry_topic(1);
        assert_eq!(
            data_key(0, &topic, &ODOMETRY),
            "0/tcpf/vehicle_1/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0"
        );
        assert_eq!(
            data_key(7, "/clock", &CLOCK),
            "7/clock/rosgraph_msgs::msg::dds_::Clock_/RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564"
        );
        assert_eq!(
            node_token(0, zid, 0, "world"),
            "@ros2_lv/0/5af83680cf352c29b0a98954d16a5470/0/0/NN/%/%tcpf/world"
        );
        assert_eq!(
            publisher_token(0, zid, 0, 3, "world", &topic, &ODOMETRY),
            "@ros2_lv/0/5af83680cf352c29b0a98954d16a5470/0/3/MP/%/%tcpf/world/%tcpf%vehicle_1%odom/nav_msgs::msg::dds_::Odometry_/RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0/1:2:1,10:,:,:,,"
        );
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
}
