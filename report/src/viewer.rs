//! What Foxglove (or any MCAP reader) sees of a run: `run.mcap`, and the same channels served
//! live (`live`) while the run goes on. Every message is encoded once and stamped with the
//! fleet's time: its epoch (the wall clock as a lockstep run started, a realtime fleet's clock's
//! epoch) plus simulated time, so a recorded run replays at its own pace, a live one shows its
//! clock, and neither shows 1970. The file's `tcpf` metadata says so, with the frame convention,
//! and the mission as run is attached to it (`mission.toml`).
//!
//! Channels, per vehicle `<id>`:
//! - `/vehicle/<id>/pose` (`foxglove.PoseInFrame`, frame `world`): position and heading, every tick;
//! - `/vehicle/<id>/path` (`foxglove.PosesInFrame`): the planned path, once at t = 0;
//! - `/vehicle/<id>/coordination` (JSON): γ, γ̇ and the command with the errors behind it;
//! - `/vehicle/<id>/dynamics` (JSON), for a dynamic vehicle (MODEL D22): its body velocity,
//!   side-slip, and per thruster the command, motor and force;
//!
//! and `/links` (JSON): every γ message a link decided on, delivered or lost.

use std::fs::File;
use std::io::BufWriter;
use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;

use foxglove::messages::{Pose, PoseInFrame, PosesInFrame, Quaternion, Timestamp, Vector3};
use foxglove::{
    Context, Encode, McapAttachment, McapCompression, McapWriteOptions, McapWriterHandle, PartialMetadata, RawChannel,
    Schema,
};
use serde::Serialize;
use tcpf_core::mission::{digest_of, Mission};
use tcpf_core::model::path::GeneralizedPath;
use tcpf_core::msg::{Command, State};
use tcpf_core::time::UnixTime;

use crate::error::{failed, Context as _, Result};
use crate::live::{ChannelInfo, Live};
use crate::provenance::Invocation;

/// REP 105's `map`, the frame of the fleet's ROS 2 topics too (docs/ROS2.md): a Foxglove layout
/// shows a recorded run and a live ROS 2 connection alike.
const FRAME: &str = tcpf_core::outputs::ros2::MAP_FRAME;
/// Seconds of γ between two poses of a drawn path.
const PATH_STEP: f64 = 0.5;

const COORDINATION_SCHEMA: &str = r#"{"type":"object","properties":{"t":{"type":"number"},"gamma":{"type":"number"},"gamma_dot":{"type":"number"},"v":{"type":"number"},"r":{"type":"number"},"v_d":{"type":"number"},"x_e":{"type":"number"},"y_e":{"type":"number"},"psi_e":{"type":"number"}}}"#;
const DYNAMICS_SCHEMA: &str = r#"{"type":"object","properties":{"t":{"type":"number"},"surge":{"type":"number"},"sway":{"type":"number"},"yaw_rate":{"type":"number"},"beta":{"type":"number"},"command_1":{"type":"number"},"command_2":{"type":"number"},"motor_1":{"type":"number"},"motor_2":{"type":"number"},"thrust_1":{"type":"number"},"thrust_2":{"type":"number"}}}"#;
const LINK_SCHEMA: &str = r#"{"type":"object","properties":{"t":{"type":"number"},"from":{"type":"integer"},"to":{"type":"integer"},"delivered":{"type":"boolean"},"cause":{"type":"string","enum":["delivered","busy","half_duplex","collision","noise","loss","burst","outage","range"]},"sent_t":{"type":"number"},"distance":{"type":"number"},"sinr_db":{"type":"number"}}}"#;

/// One channel, in the file and, when live, on the server.
struct Topic {
    file: Arc<RawChannel>,
    live: u32,
    /// Sent once, so kept for the live clients that subscribe later.
    latched: bool,
}

struct Vehicle {
    id: u32,
    pose: Topic,
    coordination: Topic,
    /// Opened at the first state that reports a dynamic vehicle's velocity and thrusters.
    dynamics: Option<Topic>,
}

pub struct Viewer {
    /// Owns the file's channels: they close when it goes.
    context: Arc<Context>,
    vehicles: Vec<Vehicle>,
    /// The run's t = 0: known at the first tick.
    epoch: Option<UnixTime>,
    /// What goes out at the first tick, once the epoch is known: each planned path, and the
    /// file's metadata with the mission.
    paths: Vec<(Topic, Vec<Pose>)>,
    mission: String,
    /// Whose run it is, for the file's metadata.
    invocation: Invocation,
    links: Topic,
    mcap: Option<McapWriterHandle<BufWriter<File>>>,
    live: Option<Live>,
    buffer: Vec<u8>,
    json: Vec<u8>,
}

/// A message of `/vehicle/<id>/coordination`. Fields in the order of their names: the order in
/// which the JSON maps written before wrote them, so `run.mcap` is byte for byte what it was.
#[derive(Serialize)]
struct Coordination {
    gamma: f64,
    gamma_dot: f64,
    psi_e: f64,
    r: f64,
    t: f64,
    v: f64,
    v_d: f64,
    x_e: f64,
    y_e: f64,
}

/// A message of `/vehicle/<id>/dynamics`, fields in the order of their names.
#[derive(Serialize)]
struct Dynamics {
    beta: f64,
    command_1: f64,
    command_2: f64,
    motor_1: f64,
    motor_2: f64,
    surge: f64,
    sway: f64,
    t: f64,
    thrust_1: f64,
    thrust_2: f64,
    yaw_rate: f64,
}

/// A message of `/links`, fields in the order of their names.
#[derive(Serialize)]
struct Link {
    /// What became of it: `delivered`, or the cause that lost it (messages.csv's words).
    cause: &'static str,
    delivered: bool,
    /// m at the sending instant; absent for a frame a busy modem never sent.
    #[serde(skip_serializing_if = "Option::is_none")]
    distance: Option<f64>,
    from: u32,
    /// s: the sending instant (`t` is when the receiver judged it).
    sent_t: f64,
    /// dB, where an acoustic modem's physics judged it.
    #[serde(skip_serializing_if = "Option::is_none")]
    sinr_db: Option<f64>,
    t: f64,
    to: u32,
}

/// Nanoseconds since the Unix epoch of `t`.
fn nanos(t: UnixTime) -> u64 {
    (t.secs().max(0.0) * 1e9).round() as u64
}

/// What `run.mcap` says of its times and frames (its `tcpf` metadata).
const FRAMES: &str = "ENU (x east, y north, metres), as ROS's REP 103, in frame map (REP 105); headings and yaw counter-clockwise from x, in radians; the current's direction is where the water flows to";

fn stamp(t: UnixTime) -> Timestamp {
    let ns = nanos(t);
    Timestamp::new((ns / 1_000_000_000) as u32, (ns % 1_000_000_000) as u32)
}

/// A planar pose: position in the plane, heading as a rotation about z.
fn pose(x: f64, y: f64, heading: f64) -> Pose {
    let (s, c) = (0.5 * heading).sin_cos();
    Pose {
        position: Some(Vector3 { x, y, z: 0.0 }),
        orientation: Some(Quaternion {
            x: 0.0,
            y: 0.0,
            z: s,
            w: c,
        }),
    }
}

impl Viewer {
    /// Opens `file` for writing and, with `live`, serves the channels there. `paths` are the
    /// vehicles' planned paths, in the order of the states the ticks will give; `invocation`
    /// what the file's metadata names as the run's command.
    pub fn create(
        file: &Path,
        mission: &Mission,
        paths: &[(u32, GeneralizedPath)],
        live: Option<SocketAddr>,
        invocation: &Invocation,
    ) -> Result<Viewer> {
        let context = Context::new();
        // lz4 is a few kilobytes of C; zstd would compress better at the cost of a slow build.
        let options = McapWriteOptions::new().compression(Some(McapCompression::Lz4));
        let mcap = context
            .mcap_writer_with_options(options)
            .create_new_buffered_file(file)
            .with_context(|| format!("cannot write {}", file.display()))?;
        let live = live.map(Live::start).transpose()?;
        let mut viewer = Viewer {
            vehicles: Vec::with_capacity(paths.len()),
            epoch: None,
            paths: Vec::with_capacity(paths.len()),
            mission: mission.to_toml(),
            invocation: invocation.clone(),
            links: topic(&context, &live, "/links", json_schema("tcpf.Link", LINK_SCHEMA))?,
            context,
            mcap: Some(mcap),
            live,
            buffer: Vec::new(),
            json: Vec::new(),
        };
        for (id, path) in paths {
            let drawn = Topic {
                latched: true,
                ..viewer.topic::<PosesInFrame>(&format!("/vehicle/{id}/path"))?
            };
            let steps = (path.t_f() / PATH_STEP).ceil() as usize;
            let poses = (0..=steps)
                .map(|k| {
                    let p = path.at((k as f64 * PATH_STEP).min(path.t_f()));
                    pose(p.position.x, p.position.y, p.heading)
                })
                .collect();
            viewer.paths.push((drawn, poses));
            let vehicle = Vehicle {
                id: *id,
                dynamics: None,
                pose: viewer.topic::<PoseInFrame>(&format!("/vehicle/{id}/pose"))?,
                coordination: topic(
                    &viewer.context,
                    &viewer.live,
                    &format!("/vehicle/{id}/coordination"),
                    json_schema("tcpf.Coordination", COORDINATION_SCHEMA),
                )?,
            };
            viewer.vehicles.push(vehicle);
        }
        Ok(viewer)
    }

    /// A channel of one of Foxglove's message types.
    fn topic<T: Encode>(&self, name: &str) -> Result<Topic> {
        let schema = T::get_schema().ok_or_else(|| failed!("{name}: no schema"))?;
        topic(&self.context, &self.live, name, (schema, T::get_message_encoding()))
    }

    fn log(&self, topic: &Topic, bytes: &[u8], t: UnixTime) {
        topic
            .file
            .log_with_meta(bytes, PartialMetadata::with_log_time(nanos(t)));
        match &self.live {
            Some(live) if topic.latched => live.latch(topic.live, nanos(t), bytes),
            Some(live) => live.publish(topic.live, nanos(t), bytes),
            None => {}
        }
    }

    fn log_encoded<T: Encode>(&mut self, topic: &Topic, message: &T, t: UnixTime) {
        let mut buffer = std::mem::take(&mut self.buffer);
        buffer.clear();
        if message.encode(&mut buffer).is_ok() {
            self.log(topic, &buffer, t);
        }
        self.buffer = buffer;
    }

    /// The first tick's work: the epoch, the planned paths at t = 0, and the file's metadata.
    fn start(&mut self, epoch: UnixTime) {
        self.epoch = Some(epoch);
        for (drawn, poses) in std::mem::take(&mut self.paths) {
            let message = PosesInFrame {
                timestamp: Some(stamp(epoch)),
                frame_id: FRAME.into(),
                poses,
            };
            self.log_encoded(&drawn, &message, epoch);
        }
        let Some(mcap) = &self.mcap else { return };
        let invocation = &self.invocation;
        let metadata = [
            ("frames", FRAMES.to_string()),
            (
                "time",
                "log times are Unix time: the fleet's epoch plus simulated time (the wall clock as a lockstep run started; a realtime fleet's clock)".to_string(),
            ),
            ("epoch_unix_s", format!("{}", epoch.secs())),
            ("mission_digest", format!("{:016x}", digest_of(&self.mission))),
            ("command", invocation.command.join(" ")),
            ("tcpf_version", invocation.version.clone()),
            ("commit", invocation.commit.clone().unwrap_or_default()),
        ];
        let attachment = McapAttachment {
            log_time: nanos(epoch),
            create_time: nanos(epoch),
            name: "mission.toml".into(),
            media_type: "application/toml".into(),
            data: std::borrow::Cow::Borrowed(self.mission.as_bytes()),
        };
        let written = mcap
            .write_metadata("tcpf", metadata.into_iter().map(|(k, v)| (k.to_string(), v)).collect())
            .and_then(|()| mcap.attach(&attachment));
        if let Err(e) = written {
            tracing::warn!("run.mcap: {e}: its metadata and mission are not in it");
        }
    }

    /// One tick: every vehicle's state, and the commands of those that are not lost; `epoch` is
    /// the run's t = 0.
    pub fn tick(&mut self, epoch: UnixTime, states: &[State], commands: &[Option<Command>]) {
        if self.epoch.is_none() {
            self.start(epoch);
        }
        let mut vehicles = std::mem::take(&mut self.vehicles);
        let mut json = std::mem::take(&mut self.json);
        for ((vehicle, s), c) in vehicles.iter_mut().zip(states).zip(commands) {
            // What every message of this vehicle at this tick is stamped with.
            let at = epoch + s.t;
            let message = PoseInFrame {
                timestamp: Some(stamp(at)),
                frame_id: FRAME.into(),
                pose: Some(pose(s.position[0], s.position[1], s.heading + s.sideslip)),
            };
            self.log_encoded(&vehicle.pose, &message, at);
            if let Some(d) = &s.dynamics {
                if vehicle.dynamics.is_none() {
                    let name = format!("/vehicle/{}/dynamics", vehicle.id);
                    let schema = json_schema("tcpf.Dynamics", DYNAMICS_SCHEMA);
                    // A channel that cannot be opened leaves the others as they are.
                    vehicle.dynamics = topic(&self.context, &self.live, &name, schema)
                        .map_err(|e| tracing::warn!("run.mcap: {e}: the vehicle's dynamics are not recorded there"))
                        .ok();
                }
                if let Some(topic) = &vehicle.dynamics {
                    let dynamics = Dynamics {
                        beta: s.sideslip,
                        command_1: d.command[0],
                        command_2: d.command[1],
                        motor_1: d.motor[0],
                        motor_2: d.motor[1],
                        surge: d.surge,
                        sway: d.sway,
                        t: s.t,
                        thrust_1: d.thrust[0],
                        thrust_2: d.thrust[1],
                        yaw_rate: d.yaw_rate,
                    };
                    self.log_json(&mut json, topic, &dynamics, at);
                }
            }
            let Some(c) = c else { continue };
            let coordination = Coordination {
                gamma: c.gamma,
                gamma_dot: c.gamma_dot,
                psi_e: c.psi_e,
                r: c.r,
                t: s.t,
                v: c.v,
                v_d: c.v_d,
                x_e: c.x_e,
                y_e: c.y_e,
            };
            self.log_json(&mut json, &vehicle.coordination, &coordination, at);
            for r in &c.receptions {
                let link = Link {
                    cause: r.cause.name(),
                    delivered: r.delivered,
                    distance: r.distance,
                    from: r.from,
                    sent_t: r.sent,
                    sinr_db: r.sinr_db,
                    t: s.t,
                    to: c.id,
                };
                self.log_json(&mut json, &self.links, &link, at);
            }
        }
        self.json = json;
        self.vehicles = vehicles;
    }

    fn log_json<T: Serialize>(&self, buffer: &mut Vec<u8>, topic: &Topic, message: &T, t: UnixTime) {
        buffer.clear();
        if serde_json::to_writer(&mut *buffer, message).is_ok() {
            self.log(topic, buffer, t);
        }
    }

    /// Closes `run.mcap` and stops serving.
    pub fn finish(mut self) -> Result<()> {
        self.live.take();
        if let Some(mcap) = self.mcap.take() {
            mcap.close().map_err(|e| failed!("run.mcap: {e}"))?;
        }
        drop(self.context);
        Ok(())
    }
}

fn json_schema(name: &str, schema: &str) -> (Schema, String) {
    (
        Schema::new(name, "jsonschema", schema.as_bytes().to_vec()),
        "json".into(),
    )
}

fn topic(
    context: &Arc<Context>,
    live: &Option<Live>,
    name: &str,
    (schema, encoding): (Schema, String),
) -> Result<Topic> {
    let live = live.as_ref().map_or(0, |l| {
        l.add_channel(ChannelInfo {
            topic: name.into(),
            encoding: encoding.clone(),
            schema_name: schema.name.clone(),
            schema_encoding: schema.encoding.clone(),
            schema: schema.data.to_vec(),
        })
    });
    let file = context
        .channel_builder(name)
        .message_encoding(encoding)
        .schema(schema)
        .build_raw()
        .map_err(|e| failed!("channel {name}: {e}"))?;
    Ok(Topic {
        file,
        live,
        latched: false,
    })
}
