//! The roles started by hand: planner, world, agent and recorder, each a process on the bus;
//! the router they meet at, and the credentials they prove themselves with.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::anyhow;
use clap::Args;
use tcpf_bus::acl::{Fleet, Identity};
use tcpf_bus::claim::Rivals;
use tcpf_bus::credential::Proof;
use tcpf_bus::keys::Keys;
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::waits::{self, Timeouts};
use tcpf_coordinator::planner_node;
use tcpf_core::mission;
use tcpf_report::provenance::Invocation;
use tcpf_report::table;

use crate::args::{recorders, ros2_domain, seconds, MissionArgs, RoleArgs};
use crate::failure::{code, role_failure, Failure};
use crate::missions::{load, solve};
use crate::outputs::{fresh_out, live_free, run_dir};
use crate::runtime::{role, runtime};

#[derive(Args)]
pub struct CredentialArgs {
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
}

#[derive(Args)]
pub struct RouterArgs {
    #[command(flatten)]
    zenoh: ZenohArgs,
}

#[derive(Args)]
pub struct PlannerArgs {
    #[command(flatten)]
    role: RoleArgs,
}

#[derive(Args)]
pub struct WorldArgs {
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
}

#[derive(Args)]
pub struct RecordArgs {
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
}

#[derive(Args)]
pub struct AgentArgs {
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
}

impl CredentialArgs {
    pub fn run(self) -> Result<ExitCode, Failure> {
        let Some(file) = self.mission else {
            return credential(&self.path);
        };
        let proof = match self.passwords {
            true => Proof::Passwords,
            false => Proof::Certificates { hosts: &self.hosts },
        };
        let mission = MissionArgs {
            file,
            set: self.set,
            flags: Vec::new(),
        };
        fleet_credentials(&self.path, &mission, self.ros2, &self.played, proof)
    }
}

impl RouterArgs {
    pub fn run(self) -> Result<ExitCode, Failure> {
        // Every message of a fleet on a router passes through it: a realtime role is late
        // when its router is.
        tcpf_bus::priority::for_realtime("router");
        runtime()?
            .block_on(tcpf_coordinator::router::run(&self.zenoh))
            .map_err(role_failure)?;
        Ok(ExitCode::SUCCESS)
    }
}

impl PlannerArgs {
    pub fn run(self) -> Result<ExitCode, Failure> {
        planner(&self.role.mission(), &self.role.zenoh)
    }
}

impl WorldArgs {
    pub fn run(self) -> Result<ExitCode, Failure> {
        let options = tcpf_world::Options {
            timeouts: Timeouts {
                startup: self.startup_timeout,
                command: self.command_timeout,
                rejoin: self.rejoin_timeout,
                ..Timeouts::default()
            },
            recorders: self.recorders,
            vehicles: self.vehicles,
            ros2: self.ros2,
            rivals: rivals(self.no_rivals, &self.role.zenoh),
        };
        world(&self.role.mission(), &self.role.zenoh, options)
    }
}

impl RecordArgs {
    pub fn run(self, invocation: Invocation) -> Result<ExitCode, Failure> {
        let mission = self.role.mission();
        record(
            &mission,
            &self.role.zenoh,
            self.out.as_deref(),
            self.live,
            self.startup_timeout,
            self.ros2,
            invocation,
        )
    }
}

impl AgentArgs {
    pub fn run(self) -> Result<ExitCode, Failure> {
        let options = tcpf_agent::Options {
            timeouts: Timeouts {
                startup: self.startup_timeout,
                stale: self.stale_timeout,
                ..Timeouts::default()
            },
            ros2: self.ros2,
            rivals: rivals(self.no_rivals, &self.role.zenoh),
        };
        agent(&self.role.mission(), &self.role.zenoh, self.id, options)
    }
}

/// Who may be claiming the same role: nobody, for a role `tcpf run` started; else every claim
/// is at one router, for a client, or contemporaries may not have met yet, for a peer. Only a
/// role started by hand reads its Zenoh config here (once more than its session will): one of
/// `tcpf run`'s, which a fleet of 200 starts at once, has no rival to ask about.
fn rivals(none: bool, zenoh: &ZenohArgs) -> Rivals {
    if none {
        Rivals::None
    } else if zenoh.is_client() {
        Rivals::OneRouter
    } else {
        Rivals::Possible
    }
}

/// `tcpf credential FILE`: a new credential for a fleet started by hand. An existing file is
/// never replaced: every host that holds it would be locked out of the fleet.
fn credential(file: &Path) -> Result<ExitCode, Failure> {
    if file.exists() {
        return Err(Failure::Input(anyhow!(
            "{}: exists; a credential is never overwritten (every host holding it would be locked out): remove it first to make a new one",
            file.display()
        )));
    }
    tcpf_bus::credential::create(file).map_err(Failure::input)?;
    sayln!(
        "wrote {0} (owner-only): copy it to every host of the fleet and give every role and the router `--credential {0}`; only processes that present it can join",
        file.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// `tcpf credential DIR MISSION`: a certificate (or key) per role of the mission, and the
/// router's and its access rules, in a new owner-only directory.
fn fleet_credentials(
    dir: &Path,
    args: &MissionArgs,
    ros2: Option<u32>,
    played: &[u32],
    proof: Proof,
) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    if let Some(id) = played.iter().find(|&&id| !mission.vehicles.iter().any(|v| v.id == id)) {
        return Err(Failure::Input(anyhow!(
            "--played: {} has no vehicle with id {id}",
            args.file.display()
        )));
    }
    if dir.exists() {
        return Err(Failure::Input(anyhow!(
            "{}: exists; a fleet's keys are never overwritten (every host holding one would be locked out): remove it first to make new ones",
            dir.display()
        )));
    }
    let vehicles: Vec<u32> = mission.vehicles.iter().map(|v| v.id).collect();
    let ros2 = mission.ros2(ros2);
    let fleet = Fleet {
        keys: Keys::new(&mission.mission.name),
        vehicles: &vehicles,
        ros2: ros2.as_ref(),
        played,
    };
    let identities =
        tcpf_bus::credential::create_fleet(dir, &mission.mission.name, &fleet, proof).map_err(Failure::input)?;
    let files: Vec<String> = identities
        .iter()
        .map(|&i| tcpf_bus::credential::key_file(i, proof))
        .collect();
    let (what, router, protocol) = match proof {
        Proof::Certificates { hosts } => {
            let at: Vec<&str> = ["localhost", "127.0.0.1"]
                .into_iter()
                .chain(hosts.iter().map(String::as_str))
                .collect();
            (
                "a certificate",
                format!("`router.pem` (valid at {})", at.join(", ")),
                "tls",
            )
        }
        Proof::Passwords => ("a key", "`credentials`".to_string(), "tcp"),
    };
    sayln!(
        "wrote {0} (owner-only) for mission {1}: {what} per role ({2}), and for the router {router} and `access.json5`.\n\
         On the router's host: tcpf router --credential {0} -l {protocol}/0.0.0.0:7447\n\
         On each role's host, its own file alone, e.g.: tcpf agent MISSION --id {3} --credential {0}/{4} -e {protocol}/ROUTER:7447\n\
         Each speaks only as its role: the router drops anything else it says.",
        dir.display(),
        mission.mission.name,
        files.join(", "),
        vehicles.first().copied().unwrap_or(1),
        tcpf_bus::credential::key_file(Identity::Agent(vehicles.first().copied().unwrap_or(1)), proof),
    );
    Ok(ExitCode::SUCCESS)
}

fn planner(args: &MissionArgs, zenoh: &ZenohArgs) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    zenoh.speaks_as(Identity::Planner).map_err(role_failure)?;
    let plan = solve(&mission, &args.file)?;
    let exit = role(planner_node::run(&mission, &plan, zenoh, &Timeouts::default()))?.map_err(role_failure)?;
    Ok(code(
        exit == planner_node::Exit::Ended,
        exit == planner_node::Exit::Interrupted,
    ))
}

fn world(args: &MissionArgs, zenoh: &ZenohArgs, options: tcpf_world::Options) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    if let Some(vehicles) = &options.vehicles {
        if mission.mission.clock != mission::ClockKind::Realtime {
            return Err(Failure::Input(anyhow!(
                "--vehicles: other processes can play vehicles only in realtime (--clock realtime); lockstep waits for every state"
            )));
        }
        if let Some(id) = vehicles
            .iter()
            .find(|&&id| !mission.vehicles.iter().any(|v| v.id == id))
        {
            return Err(Failure::Input(anyhow!(
                "--vehicles: {} has no vehicle with id {id}",
                args.file.display()
            )));
        }
    }
    zenoh.speaks_as(Identity::World).map_err(role_failure)?;
    realtime_priority(&mission, "world");
    let exit = role(tcpf_world::run(&mission, zenoh, &options))?.map_err(role_failure)?;
    Ok(code(
        matches!(exit, tcpf_world::Exit::Ended { lost: 0, short: 0, .. }),
        exit == tcpf_world::Exit::Interrupted,
    ))
}

fn agent(args: &MissionArgs, zenoh: &ZenohArgs, id: u32, options: tcpf_agent::Options) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    if !mission.vehicles.iter().any(|v| v.id == id) {
        return Err(Failure::Input(anyhow!(
            "--id {id}: {} has no vehicle with that id",
            args.file.display()
        )));
    }
    zenoh.speaks_as(Identity::Agent(id)).map_err(role_failure)?;
    realtime_priority(&mission, &format!("agent {id}"));
    let exit = role(tcpf_agent::run(&mission, id, zenoh, &options))?.map_err(role_failure)?;
    Ok(code(
        exit == tcpf_agent::Exit::Ended,
        exit == tcpf_agent::Exit::Interrupted,
    ))
}

fn record(
    args: &MissionArgs,
    zenoh: &ZenohArgs,
    out: Option<&Path>,
    live: Option<SocketAddr>,
    startup_timeout: Duration,
    ros2: Option<u32>,
    invocation: Invocation,
) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    let plan = solve(&mission, &args.file)?;
    fresh_out(out)?;
    live_free(live)?;
    // Bad Zenoh options are bad input before the run directory is made, which they would
    // leave behind half written.
    zenoh.speaks_as(Identity::Recorder).map_err(role_failure)?;
    let dir = run_dir(out, &mission, invocation)?;
    // Only when asked: the world and agents speak ROS 2 for a mission with [ros2] already.
    let options = tcpf_coordinator::recording::RecordOptions {
        live,
        timeouts: Timeouts {
            startup: startup_timeout,
            ..Timeouts::default()
        },
        ros2: ros2.and_then(|domain| mission.ros2(Some(domain))),
    };
    realtime_priority(&mission, "recorder");
    let summary = role(tcpf_coordinator::recording::record(
        &mission, &plan, &dir, zenoh, options,
    ))?
    .map_err(|e| {
        // Nothing recorded (no session, no world, refused by the world's clock): the
        // corrected command may take the same --out.
        if matches!(e, tcpf_coordinator::error::Error::NothingRecorded(_)) {
            dir.discard();
        }
        role_failure(e)
    })?;
    say!("{}", table::summary(&summary));
    sayln!("run directory: {}", dir.path.display());
    let realtime = mission.mission.clock == mission::ClockKind::Realtime;
    Ok(code(
        summary.completed && (summary.reproducible || realtime),
        summary.interrupted,
    ))
}

/// A role on the realtime clock asks for its share of the CPU before its runtime starts threads
/// (docs/CLOCK.md); in lockstep a late role only makes the tick wait.
fn realtime_priority(mission: &mission::Mission, role: &str) {
    if mission.mission.clock == mission::ClockKind::Realtime {
        tcpf_bus::priority::for_realtime(role);
    }
}
