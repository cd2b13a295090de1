//! A fresh Zenoh user and password for each `tcpf run`. Every node of the fleet demands them of
//! every link (Zenoh's user-password authentication), so only processes that can read the run
//! directory's owner-only files can join: another user's process, or one that merely knows the
//! port, cannot publish into the run.

use std::path::{Path, PathBuf};

use anyhow::Result;
use serde_json::json;
use tcpf_bus::credential::{self, private};
use tcpf_bus::session::{ACCEPT_PENDING, ACCEPT_TIMEOUT_MS};

/// How long a client of the run waits for the world to listen.
const CONNECT_TIMEOUT_MS: u64 = 60_000;

/// How long a process of the run may be silent before its link is closed (Zenoh's default: 10
/// s). Ctrl-Z stops the whole fleet (the launcher stops its children with it), and on `fg`
/// every process resumes with a silent link behind it: closed, the recorder would lose the run.
/// A killed process's connection closes at once anyway, and a hung one is the run's own
/// timeouts' (the command and stale timeouts) to find.
const LINK_PATIENCE_MS: u64 = 60_000;

/// The Zenoh configurations of a run, both owner-only files in its directory.
pub struct Configs {
    /// `zenoh.json5`: a client of the run's router, with the run's user and password. Every
    /// child but the world gets it, and so does whoever joins the running fleet.
    pub client: PathBuf,
    /// `world.json5`: the world's, the run's router, which listens at the endpoint and demands
    /// the credential of every link.
    pub world: PathBuf,
}

/// Writes the run's credential (`credentials`, Zenoh's user-password dictionary) and the Zenoh
/// configurations that use it (`Configs`) into `dir`, for a router at `endpoint`.
///
/// Clients of one router, not peers: peers that find each other by gossip open links both ways,
/// and with user-password authentication Zenoh 1.10 refuses the second (eclipse-zenoh/zenoh#2577),
/// which under load can leave a process without a link. A router also keeps the sockets of a
/// fleet linear in its size. The world is that router because most of a tick's messages are its
/// own: each state and command is then one hop, not two through the launcher (measured, runs
/// interleaved with the launcher as router: case (b) 0.20-0.26 -> 0.15-0.20 ms a tick, 10 agents
/// 0.49-0.54 -> 0.47-0.49 ms, 50 agents 2.46-2.77 -> 2.13-2.57 ms).
pub fn create(dir: &Path, endpoint: &str) -> Result<Configs> {
    let dictionary = dir.join("credentials");
    let password = credential::create(&dictionary)?;
    let dictionary = std::fs::canonicalize(&dictionary)?;
    let auth = json!({ "usrpwd": {
        "user": credential::USER,
        "password": password,
        "dictionary_file": dictionary,
    } });
    let patience = json!({ "tx": { "lease": LINK_PATIENCE_MS } });
    let client = json!({
        "mode": "client",
        "scouting": { "multicast": { "enabled": false } },
        // A client that comes before the world waits for it, as configs/zenoh/ do for a router.
        "connect": {
            "endpoints": [endpoint],
            "timeout_ms": CONNECT_TIMEOUT_MS,
            "retry": { "period_init_ms": 50, "period_max_ms": 1000, "period_increase_factor": 2 },
        },
        "transport": { "auth": auth, "link": patience },
    });
    // A router's open sleeps the scouting delay (500 ms by default) for multicast to find its
    // peers; this one scouts for nothing, and every run's first tick waited on it.
    let world = json!({
        "mode": "router",
        "scouting": { "multicast": { "enabled": false }, "gossip": { "enabled": false }, "delay": 0 },
        "listen": { "endpoints": [endpoint] },
        "connect": { "endpoints": [] },
        "transport": {
            "auth": auth,
            "link": patience,
            "unicast": { "accept_pending": ACCEPT_PENDING, "accept_timeout": ACCEPT_TIMEOUT_MS },
        },
    });
    let configs = Configs {
        client: dir.join("zenoh.json5"),
        world: dir.join("world.json5"),
    };
    private(&configs.client, &(serde_json::to_string_pretty(&client)? + "\n"))?;
    private(&configs.world, &(serde_json::to_string_pretty(&world)? + "\n"))?;
    Ok(configs)
}

/// The files of `create` that hold the run's password.
pub const SECRETS: [&str; 3] = ["credentials", "zenoh.json5", "world.json5"];

/// Removes the run's secrets from `dir` once its run is over: a sweep keeps hundreds of run
/// directories, which are copied and shared, and a password of a fleet that is gone opens
/// nothing but is still a password.
pub fn forget(dir: &Path) -> Result<()> {
    for file in SECRETS {
        match std::fs::remove_file(dir.join(file)) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e.into()),
            _ => {}
        }
    }
    Ok(())
}

/// Writes `endpoint` (owner-only) into `dir` once the world listens there: its existence says
/// that the run can be joined.
pub fn announce(dir: &Path, endpoint: &str) -> Result<()> {
    private(&dir.join("endpoint"), &format!("{endpoint}\n"))
}
