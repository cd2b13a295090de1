//! A user and password for each role of each `tcpf run`, and the world's access rules made from
//! its mission. Every link to the world, the run's router, demands a role's user and password
//! (Zenoh's user-password authentication), so the world knows which role sent each message, and
//! lets each do only what that role does (`tcpf_bus::acl`, by user name). A process needs a
//! role's configuration, an owner-only file of the run directory, to join, and holding one it can
//! speak only as that role: the recorder's (`zenoh.json5`, what a joining recorder or tool gets)
//! cannot forge a tick, an agent's cannot command another vehicle.
//!
//! Passwords over TCP, not certificates: Zenoh 1.10's `tls/` link reads and writes one TLS
//! session from two threads at once, and under a lockstep fleet's load its links break
//! (eclipse-zenoh/zenoh#2557, 2 runs of case (b) in 4 here); over QUIC a killed process's link
//! is found dead only when its lease runs out (30 s here), where TCP's closes at once, so a
//! killed agent went unnoticed and an interrupted fleet took that long to stop.

use std::path::{Path, PathBuf};

use anyhow::Result;
use serde_json::json;
use tcpf_bus::acl::{self, Fleet, Identity, Naming};
use tcpf_bus::credential::{private, secret};
use tcpf_bus::keys::Keys;
use tcpf_bus::session::{ACCEPT_PENDING, ACCEPT_TIMEOUT_MS};
use tcpf_core::mission::{Mission, Ros2Config};

/// How long a client of the run waits for the world to listen.
const CONNECT_TIMEOUT_MS: u64 = 60_000;

/// How long a process of the run may be silent before its link is closed (Zenoh's default: 10
/// s). Ctrl-Z stops the whole fleet (the launcher stops its children with it), and on `fg`
/// every process resumes with a silent link behind it: closed, the recorder would lose the run.
/// A killed process's connection closes at once anyway, and a hung one is the run's own
/// timeouts' (the command and stale timeouts) to find.
const LINK_PATIENCE_MS: u64 = 60_000;

/// What the links of a run are.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Links {
    /// Each role with its own user and password, and the world's access rules.
    PerRole,
    /// No user, no password, no rules: any process that reaches the port may speak for any role.
    /// Only `tcpf bench`'s baseline, on loopback, for what the rules cost.
    Plain,
}

/// The Zenoh configurations of a run, each an owner-only file in its directory holding one
/// role's user and password.
pub struct Configs {
    dir: PathBuf,
}

impl Configs {
    /// The configuration of `identity`.
    pub fn of(&self, identity: Identity) -> PathBuf {
        self.dir.join(file_name(identity))
    }
}

/// The file of `identity`'s configuration: `zenoh.json5` for a recorder (the launcher's own
/// session, and whoever joins the running fleet to record it), else
/// `<identity>.json5` (the world's, the run's router, listens at the endpoint, demands a role's
/// user and password of every link and enforces the access rules).
fn file_name(identity: Identity) -> String {
    match identity {
        Identity::Recorder => "zenoh.json5".to_string(),
        other => format!("{other}.json5"),
    }
}

/// Writes a configuration for every role of `mission` into `dir` (`Configs`), for a world
/// listening at `endpoint`, each with its role's user and a fresh password, and the world's
/// `credentials`, the dictionary of them all.
///
/// Clients of one router, not peers: access control is enforced where a message passes, so a
/// peer link between two roles would bypass it. A router also keeps the sockets of a fleet
/// linear in its size. The world is that router because most of a tick's messages are its own:
/// each state and command is then one hop, not two through the launcher (measured, runs
/// interleaved with the launcher as router: case (b) 0.20-0.26 -> 0.15-0.20 ms a tick, 10 agents
/// 0.49-0.54 -> 0.47-0.49 ms, 50 agents 2.46-2.77 -> 2.13-2.57 ms).
pub fn create(
    dir: &Path,
    endpoint: &str,
    mission: &Mission,
    ros2: Option<&Ros2Config>,
    links: Links,
) -> Result<Configs> {
    let vehicles: Vec<u32> = mission.vehicles.iter().map(|v| v.id).collect();
    let fleet = Fleet {
        keys: Keys::new(&mission.mission.name),
        vehicles: &vehicles,
        ros2,
        // Vehicles another program plays are a ROS 2 node's (`--ros2`).
        played: &[],
    };
    let dictionary_file = std::fs::canonicalize(dir)?.join("credentials");
    let mut dictionary = String::new();
    let link = json!({ "tx": { "lease": LINK_PATIENCE_MS } });
    for identity in acl::identities(&fleet) {
        let password = secret()?;
        dictionary.push_str(&format!("{identity}:{password}\n"));
        let mut usrpwd = json!({ "user": identity.to_string(), "password": password });
        if identity == Identity::World {
            usrpwd["dictionary_file"] = json!(dictionary_file);
        }
        let auth = match links {
            Links::PerRole => json!({ "usrpwd": usrpwd }),
            Links::Plain => json!({}),
        };
        let config = if identity == Identity::World {
            // A router's open sleeps the scouting delay (500 ms by default) for multicast to find
            // its peers; this one scouts for nothing, and every run's first tick waited on it.
            json!({
                "mode": "router",
                "scouting": { "multicast": { "enabled": false }, "gossip": { "enabled": false }, "delay": 0 },
                "listen": { "endpoints": [endpoint] },
                "connect": { "endpoints": [] },
                "transport": {
                    "auth": auth,
                    "link": link,
                    "unicast": { "accept_pending": ACCEPT_PENDING, "accept_timeout": ACCEPT_TIMEOUT_MS },
                },
                "access_control": match links {
                    Links::PerRole => acl::access_control(&fleet, Naming::Username),
                    Links::Plain => json!({ "enabled": false }),
                },
            })
        } else {
            json!({
                "mode": "client",
                "scouting": { "multicast": { "enabled": false } },
                // A client that comes before the world waits for it, as configs/zenoh/ do for a
                // router.
                "connect": {
                    "endpoints": [endpoint],
                    "timeout_ms": CONNECT_TIMEOUT_MS,
                    "retry": { "period_init_ms": 50, "period_max_ms": 1000, "period_increase_factor": 2 },
                },
                "transport": { "auth": auth, "link": link },
            })
        };
        private(
            &dir.join(file_name(identity)),
            &(serde_json::to_string_pretty(&config)? + "\n"),
        )?;
    }
    private(&dictionary_file, &dictionary)?;
    Ok(Configs { dir: dir.to_path_buf() })
}

/// Whether `name` is a file of `create` that holds a password.
fn is_secret(name: &str) -> bool {
    name.ends_with(".json5") || name == "credentials"
}

/// Removes the run's passwords from `dir` once its run is over: a sweep keeps hundreds of run
/// directories, which are copied and shared, and a password of a fleet that is gone opens nothing
/// but is still a password.
pub fn forget(dir: &Path) -> Result<()> {
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        if entry.file_name().to_str().is_some_and(is_secret) {
            std::fs::remove_file(entry.path())?;
        }
    }
    Ok(())
}

/// Writes `endpoint` (owner-only) into `dir` once the world listens there: its existence says
/// that the run can be joined.
pub fn announce(dir: &Path, endpoint: &str) -> Result<()> {
    private(&dir.join("endpoint"), &format!("{endpoint}\n"))
}
