//! The command line: every subcommand and flag, and how a value is read from it.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, Parser, Subcommand};
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::waits;
use tcpf_core::mission;

#[derive(Parser)]
#[command(
    name = "tcpf",
    version,
    about = "Time-coordinated path following for fleets of vehicles"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Args)]
pub struct MissionArgs {
    /// Mission file (TOML).
    pub file: PathBuf,
    /// Override a mission key: `section.key=value`, `section.table.key=value`, or
    /// `vehicle.<id>.key=value`.
    #[arg(long = "set", value_name = "K=V")]
    pub set: Vec<String>,
    /// The `set`s that stand for other flags, and those flags as typed: what an error names.
    #[arg(skip)]
    pub flags: Vec<(String, String)>,
}

#[derive(Args)]
#[command(group(clap::ArgGroup::new("values").required(true).multiple(true).args(["loss", "param"])))]
pub struct SweepArgs {
    /// Mission file (TOML).
    pub file: PathBuf,
    /// Override a mission key: `section.key=value`, `section.table.key=value`, or
    /// `vehicle.<id>.key=value`.
    #[arg(long = "set", value_name = "K=V")]
    pub set: Vec<String>,
    /// Loss probabilities to sweep (comms.loss), e.g. 0,0.3,0.6,0.9: --param comms.loss=...
    #[arg(long, value_delimiter = ',')]
    pub loss: Vec<String>,
    /// Any mission key and its values: KEY=V1,V2,... Repeat it for a grid (every combination);
    /// a list or a table in brackets or braces is one value.
    #[arg(long, value_name = "KEY=V1,V2,...")]
    pub param: Vec<String>,
    /// Seeds per grid point: S to S + N − 1 (each a run's --seed).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=i64::MAX as u64))]
    pub seeds: u64,
    /// The first seed.
    #[arg(long, value_name = "S", default_value_t = 1)]
    pub seed_start: u64,
    /// In-process runs at once (default: the cores).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..=4096), conflicts_with = "processes")]
    pub jobs: Option<u64>,
    /// Run only shard I of K: the runs k with k mod K = I − 1, into a directory of its own
    /// (`tcpf sweep merge` joins the shards).
    #[arg(long, value_name = "I/K", value_parser = shard)]
    pub shard: Option<tcpf_report::sweep::Shard>,
    /// Run only the runs missing from --out (and those that failed), and write its tables again.
    #[arg(long, requires = "out")]
    pub resume: bool,
    /// Run each as a real fleet of processes (one after the other) instead of in-process.
    #[arg(long)]
    pub processes: bool,
    /// Keep per grid point the mean and 95 % interval over the seeds of the coordination error
    /// and the clearance against time (series.csv, and their figures). Not with --shard: a
    /// shard's series are not merged.
    #[arg(long, conflicts_with = "shard")]
    pub series: bool,
    /// The band around each mean in the figures.
    #[arg(long, value_parser = ["ci95", "min-max"], default_value = "ci95")]
    pub band: String,
    /// The figures' printed width: column (3.5 in), double (two columns, 7.16 in) or inches;
    /// every text is at least 8 pt at it.
    #[arg(long, value_name = "WIDTH", default_value = "column", value_parser = figure_width)]
    pub figure_width: f64,
    /// Output directory (default runs/<mission>-sweep-<timestamp>/).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// How a sweep's figures are drawn: `--band` and `--figure-width`. (Flags of `SweepArgs` and
/// of `sweep merge` themselves: clap takes an optional flattened struct as absent when it holds
/// another.)
pub fn look(band: &str, figure_width: f64) -> tcpf_report::sweep::figures::Look {
    use tcpf_report::sweep::figures::{Band, Look};
    Look {
        band: match band {
            "min-max" => Band::MinMax,
            _ => Band::Ci95,
        },
        width: figure_width,
    }
}

fn figure_width(text: &str) -> Result<f64, String> {
    use tcpf_report::style::{COLUMN, DOUBLE_COLUMN};
    match text {
        "column" => Ok(COLUMN),
        "double" => Ok(DOUBLE_COLUMN),
        _ => match text.strip_suffix("in").unwrap_or(text).trim().parse::<f64>() {
            Ok(w) if (2.0..=20.0).contains(&w) => Ok(w),
            _ => Err(format!(
                "{text}: give column (3.5 in), double (7.16 in) or a width in inches from 2 to 20"
            )),
        },
    }
}

#[derive(Subcommand)]
pub enum SweepCommand {
    /// Join the shards of one sweep (`--shard I/K`) into what the sweep unsharded writes.
    Merge {
        /// The shards' directories.
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// The merged sweep's directory (new).
        #[arg(long)]
        out: PathBuf,
        /// The band around each mean in the figures.
        #[arg(long, value_parser = ["ci95", "min-max"], default_value = "ci95")]
        band: String,
        /// The figures' printed width: column (3.5 in), double (two columns, 7.16 in) or inches;
        /// every text is at least 8 pt at it.
        #[arg(long, value_name = "WIDTH", default_value = "column", value_parser = figure_width)]
        figure_width: f64,
    },
}

/// Which clock the fleet runs on; on top of the mission's `[mission] clock` and `time_scale`.
#[derive(Args, Clone)]
pub struct ClockArgs {
    /// lockstep (the world waits for every command: reproducible) or realtime (the wall clock).
    #[arg(long, value_parser = ["lockstep", "realtime"])]
    pub clock: Option<String>,
    /// Realtime: simulated seconds per wall second (1: real time).
    #[arg(long, value_name = "X", value_parser = time_scale, allow_hyphen_values = true)]
    pub time_scale: Option<f64>,
}

impl ClockArgs {
    /// The mission keys these flags stand for, each with its flag. `--clock lockstep` alone
    /// also sets the time scale back to 1, which only the realtime clock may change.
    pub fn sets(&self) -> Vec<(String, String)> {
        let mut sets = Vec::new();
        if let Some(c) = &self.clock {
            sets.push((format!("mission.clock={c}"), format!("--clock {c}")));
            if c == "lockstep" && self.time_scale.is_none() {
                sets.push(("mission.time_scale=1.0".into(), format!("--clock {c}")));
            }
        }
        if let Some(x) = self.time_scale {
            sets.push((format!("mission.time_scale={x:?}"), format!("--time-scale {x}")));
        }
        sets
    }
}

/// What every role started by hand takes: its mission, the Zenoh options of its session, and
/// the clock (the planner too, whose paths do not depend on it, so that one command line serves
/// every role).
#[derive(Args)]
pub struct RoleArgs {
    #[command(flatten)]
    pub mission: MissionArgs,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    #[command(flatten)]
    pub clock: ClockArgs,
}

/// What `tcpf run` does when an agent dies.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Restart {
    /// Its vehicle is lost and drifts.
    Never,
    /// The agent is started again and rejoins.
    OnFailure,
}

#[derive(Subcommand)]
pub enum Generated {
    /// Vehicles in parallel lanes 4 m apart on a ring, against a cross current (ring5 grown).
    Lanes {
        /// How many vehicles (one lane each).
        #[arg(long, value_parser = clap::value_parser!(u32).range(2..=i64::from(mission::generate::MAX_VEHICLES)))]
        vehicles: u32,
        /// Loss probability of every link.
        #[arg(long, default_value_t = 0.2, value_parser = probability)]
        loss: f64,
    },
}

/// A time scale on the command line, within the mission's bound.
fn time_scale(text: &str) -> Result<f64, String> {
    let (min, max) = (mission::MIN_TIME_SCALE, mission::MAX_TIME_SCALE);
    match text.parse::<f64>() {
        Ok(x) if (min..=max).contains(&x) => Ok(x),
        _ => Err(format!(
            "{text}: give simulated seconds per wall second, in [{min}, {max}]"
        )),
    }
}

/// The most recorders a run waits for: each is a process on the bus, and a count beyond any
/// fleet's is a typo (18446744073709551615, plus the launcher's own, wrapped to none at all).
const MAX_RECORDERS: u64 = 64;

fn recorders() -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::<usize>::new().range(0..=MAX_RECORDERS)
}

/// `tcpf run --recorders`: the recorders beside the launcher's own, which its world counts too.
fn more_recorders() -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::<usize>::new().range(0..=MAX_RECORDERS - 1)
}

/// A ROS 2 domain id: ROS 2 allows 0 to 232.
fn ros2_domain() -> clap::builder::RangedU64ValueParser<u32> {
    clap::builder::RangedU64ValueParser::<u32>::new().range(0..=232)
}

/// A probability on the command line: a number in [0, 1].
fn probability(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(p) if (0.0..=1.0).contains(&p) => Ok(p),
        _ => Err(format!("{text}: give a probability in [0, 1]")),
    }
}

#[derive(Subcommand)]
pub enum Command {
    /// Launch a mission, record it and write the run directory.
    Run {
        #[command(flatten)]
        mission: MissionArgs,
        #[command(flatten)]
        clock: ClockArgs,
        /// Start a dead agent again (it rejoins the run), or never (its vehicle is lost).
        #[arg(long, value_enum, default_value = "never", conflicts_with = "in_process")]
        restart: Restart,
        /// Run directory (default runs/<mission>-<timestamp>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Drive every machine in one loop instead of one process per role (the reference).
        #[arg(long)]
        in_process: bool,
        /// Mission seed (overrides mission.seed); a TOML integer, so at most 2^63 − 1.
        #[arg(long, value_parser = clap::value_parser!(u64).range(..=i64::MAX as u64))]
        seed: Option<u64>,
        /// Serve the run to Foxglove live over its WebSocket protocol (default 127.0.0.1:8765).
        #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:8765")]
        live: Option<SocketAddr>,
        /// Seconds a tick waits for a live agent's command; then its vehicle is lost (silent).
        /// More than the agents' stale timeout.
        #[arg(long, default_value = waits::COMMAND_S, value_parser = command_timeout, allow_hyphen_values = true, conflicts_with = "in_process")]
        command_timeout: Duration,
        /// Speak ROS 2 (rmw_zenoh) on this domain beside tcpf's own protocol, over the mission's
        /// [ros2] domain: the world and every agent as ROS 2 nodes (docs/ROS2.md).
        #[arg(long, value_name = "DOMAIN", num_args = 0..=1, default_missing_value = "0", value_parser = ros2_domain(), conflicts_with = "in_process")]
        ros2: Option<u32>,
        /// With ROS 2, the world also listens here with no credential (by default where
        /// rmw_zenohd would, tcp/127.0.0.1:7447): a stock ROS 2 node on this machine joins with
        /// no configuration at all, and may only listen. For a network only you use.
        #[arg(long, value_name = "ENDPOINT", num_args = 0..=1, default_missing_value = "tcp/127.0.0.1:7447", conflicts_with = "in_process")]
        ros2_open: Option<String>,
        /// Start the run only once N more recorders have joined: `tcpf record` or tools of your
        /// own, with the run directory's `zenoh.json5` (-c).
        #[arg(long, value_name = "N", default_value_t = 0, value_parser = more_recorders(), conflicts_with = "in_process")]
        recorders: usize,
        /// Seconds the world waits for every agent and recorder before it gives up and says who
        /// is missing.
        #[arg(long, default_value = waits::STARTUP_S, value_parser = seconds, allow_hyphen_values = true, conflicts_with = "in_process")]
        startup_timeout: Duration,
        /// How each role proves to the world which it is: its own certificate (mutual TLS), or
        /// its own user and password over TCP, for tools whose Zenoh has no TLS.
        #[arg(long, value_enum, default_value = "certificates", conflicts_with = "in_process")]
        links: tcpf_coordinator::launcher::Links,
    },
    /// Solve the trajectory generation problem and print the plan.
    Plan {
        #[command(flatten)]
        mission: MissionArgs,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Fault-injection experiment: every (grid point, seed) pair, summarised per grid point.
    #[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
    Sweep {
        #[command(subcommand)]
        merge: Option<SweepCommand>,
        #[command(flatten)]
        sweep: Option<SweepArgs>,
    },
    /// Print a generated mission file, for fleets of any size.
    Gen {
        #[command(subcommand)]
        mission: Generated,
    },
    /// Write (again) a run directory's report.html from its recorded files.
    Report {
        /// The run directory.
        dir: PathBuf,
        /// The figures' printed width (figures/*.pdf, *.svg): column (3.5 in), double (7.16 in)
        /// or inches; every text is at least 8 pt at it.
        #[arg(long, value_name = "WIDTH", default_value = "column", value_parser = figure_width)]
        figure_width: f64,
    },
    /// Every speed figure beside its baseline: the plan, the in-process fleet, the lockstep tick
    /// against a raw Zenoh round trip, the agents' memory and sockets.
    Bench {
        #[command(flatten)]
        mission: MissionArgs,
        /// Round trips to time.
        #[arg(long, default_value_t = 2000, value_parser = clap::value_parser!(u64).range(1..))]
        count: u64,
        /// Also fleets of `tcpf gen lanes --vehicles N` of these sizes as processes, each the best
        /// of three runs, beside the round trip (e.g. `--fleets 10,200`; 200 lanes take minutes).
        #[arg(long, value_name = "N,...", value_delimiter = ',', value_parser = clap::value_parser!(u32).range(2..=i64::from(mission::generate::MAX_VEHICLES)))]
        fleets: Vec<u32>,
    },
    /// The echo side of `tcpf bench`.
    #[command(hide = true)]
    Pong {
        #[command(flatten)]
        zenoh: ZenohArgs,
        #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
        count: u64,
        /// Names its liveliness token.
        #[arg(long, default_value_t = 0)]
        id: u32,
    },
    /// Make a fleet's credentials for roles started by hand: with a mission, a directory of one
    /// certificate per role and the router's, with its access rules; without, one user and
    /// password that every role and the router share.
    Credential {
        /// The directory (with a mission) or file to write; it must not exist.
        path: PathBuf,
        /// Mission file (TOML): its roles each get their own certificate, and the router (`tcpf
        /// router --credential DIR`) lets each do only what its role does.
        mission: Option<PathBuf>,
        /// Override a mission key, as the roles will (its name and vehicles name the keys).
        #[arg(long = "set", value_name = "K=V", requires = "mission")]
        set: Vec<String>,
        /// Certificates for the fleet speaking ROS 2 in this domain too (one per vehicle for the
        /// ROS 2 node that plays it), over the mission's `[ros2]`.
        #[arg(long, value_name = "DOMAIN", requires = "mission")]
        ros2: Option<u32>,
        /// Vehicles another program plays on the fleet's own protocol (ids, comma-separated):
        /// each gets a certificate, `vehicle-<id>.pem`, that may publish that vehicle's states.
        #[arg(long, value_delimiter = ',', value_name = "IDS", requires = "mission")]
        played: Vec<u32>,
        /// A name or address the router is reached at, besides this host's (localhost,
        /// 127.0.0.1): its certificate is valid there alone. Repeat for each.
        #[arg(
            long = "host",
            value_name = "HOST",
            requires = "mission",
            conflicts_with = "passwords"
        )]
        hosts: Vec<String>,
        /// A user and password per role (`<identity>.key`) instead of a certificate, over TCP:
        /// for a Zenoh without TLS.
        #[arg(long, requires = "mission")]
        passwords: bool,
    },
    /// A Zenoh router for a testbed: every role connects to it (configs/zenoh/).
    Router {
        #[command(flatten)]
        zenoh: ZenohArgs,
    },
    /// Role: plan and serve every vehicle's path.
    Planner {
        #[command(flatten)]
        role: RoleArgs,
    },
    /// Role: the world, which integrates the vehicles and keeps the fleet's clock.
    World {
        #[command(flatten)]
        role: RoleArgs,
        /// Realtime: simulate only these vehicles (ids, comma-separated); other processes play
        /// the others by publishing their State and taking their Command.
        #[arg(long, value_delimiter = ',', value_name = "IDS")]
        vehicles: Option<Vec<u32>>,
        /// Lockstep: seconds a tick waits for a gone agent to come back before its vehicle is
        /// lost (default: lost at once).
        #[arg(long, value_parser = seconds, allow_hyphen_values = true)]
        rejoin_timeout: Option<Duration>,
        /// Recorders to wait for before the first tick.
        #[arg(long, default_value_t = 0, value_parser = recorders())]
        recorders: usize,
        /// Seconds to wait, from the start, for the plan, the agents and the recorders.
        #[arg(long, default_value = waits::STARTUP_S, value_parser = seconds, allow_hyphen_values = true)]
        startup_timeout: Duration,
        /// Seconds a tick waits for a live agent's command; then its vehicle is lost (silent).
        #[arg(long, default_value = waits::COMMAND_S, value_parser = seconds, allow_hyphen_values = true)]
        command_timeout: Duration,
        /// Speak ROS 2 (rmw_zenoh) on this domain beside tcpf's own protocol, over the mission's
        /// [ros2] domain: the node /tcpf/world, with odometry, paths, coordination, links and, in
        /// lockstep, /clock; it takes the odometry of a vehicle a ROS 2 node plays (docs/ROS2.md).
        #[arg(long, value_name = "DOMAIN", num_args = 0..=1, default_missing_value = "0", value_parser = ros2_domain())]
        ros2: Option<u32>,
        /// Set by `tcpf run` for the roles it starts: no other process can be claiming this
        /// role now, so the claim is decided at once instead of after 1.5 s.
        #[arg(long, hide = true)]
        no_rivals: bool,
    },
    /// Role: record a fleet started by hand (start its world with --recorders 1).
    Record {
        #[command(flatten)]
        role: RoleArgs,
        /// Run directory (default runs/<mission>-<timestamp>/).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Serve the run to Foxglove live over its WebSocket protocol (default 127.0.0.1:8765).
        #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:8765")]
        live: Option<SocketAddr>,
        /// Seconds to wait for the world.
        #[arg(long, default_value = waits::STARTUP_S, value_parser = seconds, allow_hyphen_values = true)]
        startup_timeout: Duration,
        /// Publish what is recorded to ROS 2 (rmw_zenoh) on this domain, as the node
        /// /tcpf/recorder: for a fleet whose world does not speak ROS 2 (docs/ROS2.md).
        #[arg(long, value_name = "DOMAIN", num_args = 0..=1, default_missing_value = "0", value_parser = ros2_domain())]
        ros2: Option<u32>,
    },
    /// Role: the agent of one vehicle.
    Agent {
        #[command(flatten)]
        role: RoleArgs,
        /// The vehicle's id.
        #[arg(long)]
        id: u32,
        /// Seconds to wait for the planner, the world and the neighbours.
        #[arg(long, default_value = waits::STARTUP_S, value_parser = seconds, allow_hyphen_values = true)]
        startup_timeout: Duration,
        /// Seconds after which a silent neighbour stops being counted.
        #[arg(long, default_value = waits::STALE_S, value_parser = seconds, allow_hyphen_values = true)]
        stale_timeout: Duration,
        /// Speak ROS 2 (rmw_zenoh) on this domain, over the mission's [ros2] domain: the node
        /// /tcpf/agent_<id>, its commands on /tcpf/vehicle_<id>/cmd (docs/ROS2.md).
        #[arg(long, value_name = "DOMAIN", num_args = 0..=1, default_missing_value = "0", value_parser = ros2_domain())]
        ros2: Option<u32>,
        /// Set by `tcpf run` for the roles it starts: no other process can be claiming this
        /// role now, so the claim is decided at once instead of after 1.5 s.
        #[arg(long, hide = true)]
        no_rivals: bool,
    },
}

/// A duration on the command line: seconds, finite, positive and at most a day.
fn shard(text: &str) -> Result<tcpf_report::sweep::Shard, String> {
    tcpf_report::sweep::Shard::parse(text)
}

fn seconds(text: &str) -> Result<Duration, String> {
    let s: f64 = text
        .parse()
        .map_err(|_| format!("`{text}` is not a number of seconds"))?;
    if s.is_finite() && s > 0.0 && s <= 86_400.0 {
        Ok(Duration::from_secs_f64(s))
    } else {
        Err(format!("{text} s: give a number of seconds in (0, 86400]"))
    }
}

/// `tcpf run --command-timeout`: more than the agents' stale timeout, or an agent waiting for a
/// silent neighbour would be lost with it.
fn command_timeout(text: &str) -> Result<Duration, String> {
    match seconds(text)? {
        d if d <= waits::STALE => Err(format!(
            "{text} s: must exceed the agents' stale timeout ({} s), or an agent waiting for a silent neighbour would be lost with it",
            waits::STALE.as_secs()
        )),
        d => Ok(d),
    }
}
