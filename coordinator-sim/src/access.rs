//! A certificate for each role of each `tcpf run`, and the world's access rules made from its
//! mission. Every link to the world, the run's router, is mutual TLS and demands a certificate
//! signed by the run's own authority, made for this run and forgotten once the certificates are
//! signed, so the world knows which role sent each message by its certificate's name, and lets
//! each do only what that role does (`tcpf_bus::acl`). A process needs a role's configuration,
//! an owner-only file of the run directory, to join, and holding one it can speak only as that
//! role: the recorder's (`zenoh.json5`, what a joining recorder or tool gets) cannot forge a
//! tick, an agent's cannot command another vehicle.
//!
//! TLS over TCP, not QUIC: a killed process's TCP link closes at once, where QUIC's is found dead
//! only when its lease runs out (30 s here), so a killed agent would go unnoticed and an
//! interrupted fleet take that long to stop. Zenoh 1.10's TLS link needed a fix for that
//! (vendor/README.md).

use std::path::{Path, PathBuf};

use serde_json::json;
use tcpf_bus::acl::{self, Fleet, Identity, Naming};
use tcpf_bus::certificate::{self, Authority};
use tcpf_bus::credential::{private, secret};
use tcpf_bus::keys::Keys;
use tcpf_bus::session::{ACCEPT_PENDING, ACCEPT_TIMEOUT_MS};
use tcpf_core::mission::{Mission, Ros2Config};

use crate::error::{Context, Result};

/// How long a client of the run waits for the world to listen.
const CONNECT_TIMEOUT_MS: u64 = 60_000;

/// How long a process of the run may be silent before its link is closed (Zenoh's default: 10
/// s). Ctrl-Z stops the whole fleet (the launcher stops its children with it), and on `fg`
/// every process resumes with a silent link behind it: closed, the recorder would lose the run.
/// A killed process's connection closes at once anyway, and a hung one is the run's own
/// timeouts' (the command and stale timeouts) to find.
const LINK_PATIENCE_MS: u64 = 60_000;

/// What the links of a run are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Links {
    /// Mutual TLS: each role with its own certificate, and the world's access rules by its name.
    Certificates,
    /// TCP, each role with its own user and password, and the access rules by user name: for a
    /// Zenoh without TLS.
    Passwords,
    /// No credential, no rules: any process that reaches the port may speak for any role. Only
    /// `tcpf bench`'s baseline, on loopback, for what the rest costs.
    #[value(skip)]
    Plain,
}

impl Links {
    /// The Zenoh protocol of the run's endpoint.
    pub fn protocol(self) -> &'static str {
        match self {
            Links::Certificates => "tls",
            Links::Passwords | Links::Plain => "tcp",
        }
    }
}

/// The configuration a ROS 2 node (rmw_zenoh) listens to the run with: the observer's.
pub const ROS2_CONFIG: &str = "ros2.json5";

/// The Zenoh configurations of a run, each an owner-only file in its directory holding one
/// role's certificate and key, or user and password.
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
/// credential of every link and enforces the access rules).
fn file_name(identity: Identity) -> String {
    match identity {
        Identity::Recorder => "zenoh.json5".to_string(),
        other => format!("{other}.json5"),
    }
}

/// Writes a configuration for every role of `mission` into `dir` (`Configs`), for a world
/// listening at `endpoint`, each with its role's credential: a certificate of the run's
/// authority, or a user with a fresh password and, for the world, `credentials`, the dictionary
/// of them all.
///
/// Clients of one router, not peers: access control is enforced where a message passes, so a
/// peer link between two roles would bypass it. A router also keeps the sockets of a fleet
/// linear in its size. The world is that router because most of a tick's messages are its own:
/// each state and command is then one hop, not two through the launcher (measured, runs
/// interleaved with the launcher as router: case (b) 0.20-0.26 -> 0.15-0.20 ms a tick, 10 agents
/// 0.49-0.54 -> 0.47-0.49 ms, 50 agents 2.46-2.77 -> 2.13-2.57 ms).
///
/// With ROS 2, `ros2.json5` is the observer's configuration again, under the name a ROS 2 user
/// looks for: what a stock rmw_zenoh loads through `ZENOH_SESSION_CONFIG_URI` to listen. `open`,
/// a `tcp/` endpoint, is where the world also listens with no credential, for ROS 2 nodes that
/// come with none (rmw_zenoh's default configuration connects to `tcp/localhost:7447`): a link
/// there may do what an observer does, and nothing else.
pub fn create(
    dir: &Path,
    endpoint: &str,
    mission: &Mission,
    ros2: Option<&Ros2Config>,
    links: Links,
    open: Option<&str>,
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
    let authority = match links {
        Links::Certificates => Some(Authority::new(&mission.mission.name)?),
        Links::Passwords | Links::Plain => None,
    };
    for identity in acl::identities(&fleet) {
        let listens = identity == Identity::World;
        let mut auth = json!({});
        let mut link = json!({ "tx": { "lease": LINK_PATIENCE_MS } });
        if let Some(authority) = &authority {
            let hosts = match listens {
                true => vec![host_of(endpoint).to_string()],
                false => Vec::new(),
            };
            let pair = authority.issue(&identity.to_string(), &hosts)?;
            link["tls"] = certificate::tls(&authority.pem(), &pair, listens);
        } else if links == Links::Passwords {
            let password = secret()?;
            dictionary.push_str(&format!("{identity}:{password}\n"));
            let mut usrpwd = json!({ "user": identity.to_string(), "password": password });
            if listens {
                usrpwd["dictionary_file"] = json!(dictionary_file);
            }
            auth = json!({ "usrpwd": usrpwd });
        }
        let config = if identity == Identity::World {
            // A router's open sleeps the scouting delay (500 ms by default) for multicast to find
            // its peers; this one scouts for nothing, and every run's first tick waited on it.
            json!({
                "mode": "router",
                "scouting": { "multicast": { "enabled": false }, "gossip": { "enabled": false }, "delay": 0 },
                "listen": { "endpoints": std::iter::once(endpoint).chain(open).collect::<Vec<_>>() },
                "connect": { "endpoints": [] },
                "transport": {
                    "auth": auth,
                    "link": link,
                    "unicast": { "accept_pending": ACCEPT_PENDING, "accept_timeout": ACCEPT_TIMEOUT_MS },
                },
                "access_control": match links {
                    Links::Certificates => {
                        let mut rules = acl::access_control(&fleet, Naming::CommonName);
                        if open.is_some() {
                            acl::open_to_listeners(&mut rules, "tcp");
                        }
                        rules
                    }
                    Links::Passwords => acl::access_control(&fleet, Naming::Username),
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
        let text = serde_json::to_string_pretty(&config).context("cannot write a role's Zenoh configuration")? + "\n";
        private(&dir.join(file_name(identity)), &text)?;
        if identity == Identity::Observer && ros2.is_some() {
            private(&dir.join(ROS2_CONFIG), &text)?;
        }
    }
    if links == Links::Passwords {
        private(&dictionary_file, &dictionary)?;
    }
    Ok(Configs { dir: dir.to_path_buf() })
}

/// The host of `endpoint` (`tls/127.0.0.1:7447` -> `127.0.0.1`), which the world's certificate
/// names.
fn host_of(endpoint: &str) -> &str {
    let address = endpoint.split_once('/').map_or(endpoint, |(_, a)| a);
    address
        .rsplit_once(':')
        .map_or(address, |(h, _)| h)
        .trim_matches(['[', ']'])
}

/// Whether `name` is a file of `create` that holds a key or a password.
fn is_secret(name: &str) -> bool {
    name.ends_with(".json5") || name == "credentials"
}

/// Removes the run's keys and passwords from `dir` once its run is over: a sweep keeps hundreds
/// of run directories, which are copied and shared, and a key of a fleet that is gone opens
/// nothing but is still a key.
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
    Ok(private(&dir.join("endpoint"), &format!("{endpoint}\n"))?)
}
