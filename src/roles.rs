//! The roles started by hand: planner, world, agent and recorder, each a process on the bus.

use std::net::SocketAddr;
use std::path::Path;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::anyhow;
use tcpf_bus::acl::{Fleet, Identity};
use tcpf_bus::credential::Proof;
use tcpf_bus::keys::Keys;
use tcpf_bus::session::ZenohArgs;
use tcpf_coordinator::planner_node;
use tcpf_core::mission;
use tcpf_report::table;

use crate::cli::MissionArgs;
use crate::outputs::{fresh_out, live_free, run_dir};
use crate::{code, load, role, role_failure, solve, Failure};

/// `tcpf credential FILE`: a new credential for a fleet started by hand. An existing file is
/// never replaced: every host that holds it would be locked out of the fleet.
pub fn credential(file: &Path) -> Result<ExitCode, Failure> {
    if file.exists() {
        return Err(Failure::Input(anyhow!(
            "{}: exists; a credential is never overwritten (every host holding it would be locked out): remove it first to make a new one",
            file.display()
        )));
    }
    tcpf_bus::credential::create(file).map_err(Failure::Input)?;
    sayln!(
        "wrote {0} (owner-only): copy it to every host of the fleet and give every role and the router `--credential {0}`; only processes that present it can join",
        file.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// `tcpf credential DIR MISSION`: a certificate (or key) per role of the mission, and the
/// router's and its access rules, in a new owner-only directory.
pub fn fleet_credentials(
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
        tcpf_bus::credential::create_fleet(dir, &mission.mission.name, &fleet, proof).map_err(Failure::Input)?;
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

pub fn planner(args: &MissionArgs, zenoh: &ZenohArgs) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    zenoh.speaks_as(Identity::Planner).map_err(role_failure)?;
    let plan = solve(&mission, &args.file)?;
    let exit = role(planner_node::run(&mission, &plan, zenoh))?.map_err(role_failure)?;
    Ok(code(
        exit == planner_node::Exit::Ended,
        exit == planner_node::Exit::Interrupted,
    ))
}

pub fn world(args: &MissionArgs, zenoh: &ZenohArgs, options: tcpf_world::Options) -> Result<ExitCode, Failure> {
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

pub fn agent(
    args: &MissionArgs,
    zenoh: &ZenohArgs,
    id: u32,
    options: tcpf_agent::Options,
) -> Result<ExitCode, Failure> {
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

pub fn record(
    args: &MissionArgs,
    zenoh: &ZenohArgs,
    out: Option<&Path>,
    live: Option<SocketAddr>,
    startup_timeout: Duration,
    ros2: Option<u32>,
) -> Result<ExitCode, Failure> {
    let mission = load(args, None)?;
    let plan = solve(&mission, &args.file)?;
    fresh_out(out)?;
    live_free(live)?;
    // Bad Zenoh options are bad input before the run directory is made, which they would
    // leave behind half written.
    zenoh.speaks_as(Identity::Recorder).map_err(role_failure)?;
    let dir = run_dir(out, &mission)?;
    // Only when asked: the world and agents speak ROS 2 for a mission with [ros2] already.
    let options = tcpf_coordinator::recording::RecordOptions {
        live,
        startup_timeout,
        ros2: ros2.and_then(|domain| mission.ros2(Some(domain))),
    };
    realtime_priority(&mission, "recorder");
    let summary = role(tcpf_coordinator::recording::record(
        &mission, &plan, &dir, zenoh, options,
    ))?
    .map_err(|e| {
        // Nothing recorded (no session, no world, refused by the world's clock): the
        // corrected command may take the same --out.
        if e.downcast_ref::<tcpf_coordinator::recording::NothingRecorded>()
            .is_some()
        {
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
