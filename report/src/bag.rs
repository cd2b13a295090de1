//! The run as a rosbag2, `rosbag2/` in the run directory of a run that speaks ROS 2: what the
//! fleet's ROS 2 topics carry (`ros2::carried`, the planned paths at the first tick), tick by
//! tick as the rows of telemetry.csv have them, for ROS 2's own tools (`ros2 bag info`, `ros2 bag
//! play`, PlotJuggler's rosbag2 loader). One MCAP file with the `ros2` profile: per topic a
//! channel of CDR messages under its type's `ros2msg` schema, with its QoS; and `metadata.yaml`,
//! rosbag2's version 9 (Jazzy's), written at the end with each topic's count and type hash.
//!
//! Header stamps are the topics' own (docs/ROS2.md, "Time"); log times are run.mcap's: the
//! fleet's epoch plus simulated time, so a bag replays at simulated pace.

use std::collections::BTreeMap;
use std::fs::{self, File};
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use mcap::records::{MessageHeader, Metadata};
use tcpf_core::mission::{Mission, Ros2Config};
use tcpf_core::model::path::GeneralizedPath;
use tcpf_core::msg::{Clock, Command, State};
use tcpf_core::outputs::ros2::{self, FleetTopic, LinkCounts, Stamp};
use tcpf_core::time::UnixTime;

use crate::error::{Context, Result};

/// The bag's directory in the run directory, and its one file, named as rosbag2 names them.
pub const DIR: &str = "rosbag2";
const FILE: &str = "rosbag2_0.mcap";
/// Every file the bag's directory holds.
pub const FILES: [&str; 2] = [FILE, "metadata.yaml"];

/// One topic of the bag: its MCAP channel, and the messages written on it.
struct Channel {
    id: u16,
    messages: u64,
}

pub struct Bag {
    writer: mcap::Writer<BufWriter<File>>,
    dir: PathBuf,
    ros2: Ros2Config,
    lockstep: bool,
    channels: BTreeMap<FleetTopic, Channel>,
    counts: LinkCounts,
    /// Written at the first tick, once the stamps are known.
    paths: Vec<(u32, GeneralizedPath)>,
    /// Log times of the first and last message, ns.
    span: Option<(u64, u64)>,
}

/// A time in seconds as MCAP's nanoseconds.
fn nanos(t: f64) -> u64 {
    (t * 1e9).round().max(0.0) as u64
}

impl Bag {
    /// Creates `rosbag2/` in `run_dir`, with a channel for each topic of the mission's fleet.
    pub fn create(
        run_dir: &Path,
        mission: &Mission,
        paths: &[(u32, GeneralizedPath)],
        ros2: &Ros2Config,
    ) -> Result<Bag> {
        let dir = run_dir.join(DIR);
        let cannot = || format!("cannot write {}", dir.display());
        fs::create_dir_all(&dir).with_context(cannot)?;
        let file = File::create(dir.join(FILE)).with_context(cannot)?;
        let mut writer = mcap::WriteOptions::new()
            .profile("ros2")
            .library(format!("tcpf {}", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Lz4))
            .create(BufWriter::new(file))
            .with_context(cannot)?;
        let lockstep = mission.mission.clock == tcpf_core::mission::ClockKind::Lockstep;
        let ids: Vec<u32> = paths.iter().map(|(id, _)| *id).collect();
        let mut channels = BTreeMap::new();
        for topic in FleetTopic::of_fleet(&ids, &mission.directed_links(), lockstep) {
            let ty = topic.ty();
            let schema = writer
                .add_schema(ty.name, "ros2msg", ty.definition().as_bytes())
                .with_context(cannot)?;
            let qos = BTreeMap::from([("offered_qos_profiles".to_string(), qos_yaml(topic, ""))]);
            let id = writer
                .add_channel(schema, &topic.name(ros2), "cdr", &qos)
                .with_context(cannot)?;
            channels.insert(topic, Channel { id, messages: 0 });
        }
        Ok(Bag {
            writer,
            dir,
            ros2: ros2.clone(),
            lockstep,
            channels,
            counts: LinkCounts::default(),
            paths: paths.to_vec(),
            span: None,
        })
    }

    fn write(&mut self, topic: FleetTopic, cdr: &[u8], log_time: u64) -> Result<()> {
        let Some(channel) = self.channels.get_mut(&topic) else {
            return Ok(());
        };
        channel.messages += 1;
        let header = MessageHeader {
            channel_id: channel.id,
            sequence: channel.messages as u32,
            log_time,
            publish_time: log_time,
        };
        self.span = Some(self.span.map_or((log_time, log_time), |(first, _)| (first, log_time)));
        self.writer
            .write_to_known_channel(&header, cdr)
            .with_context(|| format!("cannot write {}", self.dir.join(FILE).display()))
    }

    /// One row: every vehicle's state and command. `epoch` is the run's t = 0;
    /// `clock` a realtime fleet's clock, whose stamps are wall time (none in lockstep).
    pub fn tick(
        &mut self,
        epoch: UnixTime,
        clock: Option<&Clock>,
        states: &[State],
        commands: &[Option<Command>],
    ) -> Result<()> {
        let Some(first) = states.first() else {
            return Ok(());
        };
        let stamp_of = |t: f64| Stamp::of(clock, t);
        // Apart, so that the epoch's size costs the simulated time no precision.
        let log_time = nanos(epoch.secs()) + nanos(first.t);
        for (id, path) in std::mem::take(&mut self.paths) {
            self.write(FleetTopic::Path(id), &ros2::path(&path, stamp_of), log_time)?;
        }
        let fleet: Vec<(&State, Option<&Command>)> = states.iter().zip(commands.iter().map(Option::as_ref)).collect();
        let mut carried = Vec::new();
        ros2::carried(
            &mut self.counts,
            &fleet,
            stamp_of(first.t),
            self.lockstep,
            |topic, encode| {
                carried.push((topic, encode()));
            },
        );
        for (topic, cdr) in carried {
            self.write(topic, &cdr, log_time)?;
        }
        Ok(())
    }

    /// Closes the MCAP file and writes `metadata.yaml`, also kept in the file as rosbag2's
    /// MCAP storage keeps it.
    pub fn finish(mut self) -> Result<()> {
        let metadata = self.metadata();
        let cannot = || format!("cannot write {}", self.dir.display());
        self.writer
            .write_metadata(&Metadata {
                name: "rosbag2".into(),
                metadata: BTreeMap::from([("serialized_metadata".to_string(), metadata.clone())]),
            })
            .with_context(cannot)?;
        self.writer.finish().with_context(cannot)?;
        fs::write(self.dir.join("metadata.yaml"), metadata).with_context(cannot)
    }

    /// rosbag2's `metadata.yaml`, version 9.
    fn metadata(&self) -> String {
        let (first, last) = self.span.unwrap_or((0, 0));
        let duration = last - first;
        let messages: u64 = self.channels.values().map(|c| c.messages).sum();
        let mut topics = String::new();
        for (topic, channel) in &self.channels {
            let ty = topic.ty();
            topics += &format!(
                "    - topic_metadata:\n        name: {}\n        type: {}\n        serialization_format: cdr\n        offered_qos_profiles:\n{}\n        type_description_hash: {}\n      message_count: {}\n",
                quoted(&topic.name(&self.ros2)),
                quoted(ty.name),
                qos_yaml(*topic, "          "),
                ty.hash,
                channel.messages
            );
        }
        format!(
            "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n  duration:\n    nanoseconds: {duration}\n  starting_time:\n    nanoseconds_since_epoch: {first}\n  message_count: {messages}\n  topics_with_message_count:\n{topics}  compression_format: \"\"\n  compression_mode: \"\"\n  relative_file_paths:\n    - {FILE}\n  files:\n    - path: {FILE}\n      starting_time:\n        nanoseconds_since_epoch: {first}\n      duration:\n        nanoseconds: {duration}\n      message_count: {messages}\n  custom_data: ~\n  ros_distro: jazzy\n"
        )
    }
}

/// A YAML string, double-quoted (JSON's quoting is YAML's).
fn quoted(text: &str) -> String {
    serde_json::to_string(text).expect("a string is JSON")
}

/// The QoS a topic is offered with, as rosbag2 writes it (a YAML list of one profile, each line
/// after `indent`): the fleet's publishers' (`ros2::QOS`), transient local for a path; no
/// deadline, lifespan or lease (rmw's "infinite").
fn qos_yaml(topic: FleetTopic, indent: &str) -> String {
    let durability = match topic.qos() {
        ros2::QOS_TRANSIENT_LOCAL => "transient_local",
        _ => "volatile",
    };
    let infinite = "\n    sec: 9223372036\n    nsec: 854775807";
    let profile = format!(
        "- history: keep_last\n  depth: 10\n  reliability: reliable\n  durability: {durability}\n  deadline:{infinite}\n  lifespan:{infinite}\n  liveliness: automatic\n  liveliness_lease_duration:{infinite}\n  avoid_ros_namespace_conventions: false"
    );
    profile
        .lines()
        .map(|line| format!("{indent}{line}"))
        .collect::<Vec<_>>()
        .join("\n")
}
