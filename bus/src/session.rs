//! A Zenoh session from the options every role takes, as Zenoh's own tools spell them.

use std::path::PathBuf;
use std::time::Duration;

use zenoh::{Config, Session};

use crate::acl::Identity;
use crate::certificate;
use crate::credential::{self, Credential, Demand, Proof};
use crate::error::{failed, Context, Error, Result};
use crate::signals::Shutdown;
use tcpf_core::msg::{Checked, TickRecord};

#[derive(clap::Args, Debug, Clone, Default)]
pub struct ZenohArgs {
    /// Zenoh configuration file (JSON5); the other options apply on top of it.
    #[arg(short = 'c', long = "config", value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Endpoint to connect to, e.g. tcp/192.168.1.10:7447 (repeatable).
    #[arg(short = 'e', long = "connect", value_name = "ENDPOINT")]
    pub connect: Vec<String>,
    /// Endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable).
    #[arg(short = 'l', long = "listen", value_name = "ENDPOINT")]
    pub listen: Vec<String>,
    /// Zenoh mode: peer, client or router.
    #[arg(long = "mode", value_name = "MODE")]
    pub mode: Option<String>,
    /// A role's own certificate (`tcpf credential DIR MISSION` makes one per role:
    /// DIR/<role>.pem, presented over tls/ endpoints; with --passwords a key, DIR/<role>.key),
    /// which it presents to the router; for `tcpf router`, that DIR, whose certificates it
    /// demands and whose access rules it enforces. Or one credential the whole fleet shares
    /// (`tcpf credential FILE`), presented and demanded by every process: without -c or --mode,
    /// one that listens is then the fleet's router and one that connects its client.
    #[arg(long = "credential", value_name = "FILE", conflicts_with = "open")]
    pub credential: Option<PathBuf>,
    /// Run with no credential, on a network only you use: any process that reaches this one
    /// can join the fleet and speak for any role.
    #[arg(long = "open")]
    pub open: bool,
}

fn json_list(items: &[String]) -> String {
    serde_json::to_string(items).expect("strings encode")
}

/// Zenoh options that cannot work, whatever the network does: bad input (exit 2).
fn bad(message: String) -> Error {
    Error::BadZenohConfig(message)
}

/// A Zenoh error in a user's words: without the source file and line Zenoh appends to an error
/// and to each of its causes (` at /…/src/lib.rs:62.`, or a relative path for a crate of vendor/).
pub fn zenoh_words(e: impl std::fmt::Display) -> String {
    let text = e.to_string();
    let mut words = String::with_capacity(text.len());
    let mut rest = text.as_str();
    // Zenoh's own crates give absolute paths; a patched one of vendor/ a relative path.
    while let Some(at) = rest.find(" at ") {
        let path = &rest[at + 4..];
        let path = &path[..path.find(char::is_whitespace).unwrap_or(path.len())];
        // A source location may close a bracket: "(os error 98) at /…/tcp.rs:61.]".
        let location = path.trim_end_matches(['.', ']', ')']);
        let source = location
            .rsplit_once(".rs:")
            .is_some_and(|(_, line)| !line.is_empty() && line.bytes().all(|b| b.is_ascii_digit()));
        if source {
            words.push_str(&rest[..at]);
            words.push_str(path[location.len()..].trim_start_matches('.'));
        } else {
            words.push_str(&rest[..at + 4 + path.len()]);
        }
        rest = &rest[at + 4 + path.len()..];
    }
    words.push_str(rest);
    words.trim_end_matches('.').to_string()
}

/// A Zenoh configuration file, read as Zenoh reads it, with its errors by kind: the file not
/// there, JSON5 that does not parse, or keys and values Zenoh does not take (the parser's message
/// and where in the file).
fn from_file(path: &std::path::Path) -> Result<Config> {
    let bad_file = |why: String| bad(format!("{}: bad Zenoh config: {why}", path.display()));
    let text = std::fs::read_to_string(path).map_err(|e| bad_file(e.to_string()))?;
    let at = |e: json5::Error| match e {
        json5::Error::Message { msg, location: Some(l) } => {
            format!("line {}, column {}: {}", l.line, l.column, zenoh_words(msg))
        }
        json5::Error::Message { msg, location: None } => zenoh_words(msg),
    };
    let mut parsed = json5::Deserializer::from_str(&text).map_err(|e| bad_file(at(e)))?;
    Config::from_deserializer(&mut parsed).map_err(|e| match e {
        Ok(_) => bad_file("Zenoh read it but finds it invalid".into()),
        Err(e) => bad_file(at(e)),
    })
}

/// The transports this build of Zenoh has.
const TRANSPORTS: [&str; 4] = ["tcp", "udp", "tls", "quic"];

/// An endpoint Zenoh can parse, over a transport this build has, to an address with a port
/// (an IPv6 address in brackets).
fn endpoint(flag: &str, text: &str) -> Result<()> {
    let parsed: zenoh::config::EndPoint = text.parse().map_err(|_| {
        bad(format!(
            "{flag} {text}: an endpoint is <protocol>/<address>, e.g. tcp/192.168.1.10:7447"
        ))
    })?;
    if !TRANSPORTS.contains(&parsed.protocol().as_str()) {
        return Err(bad(format!(
            "{flag} {text}: this build speaks {} only",
            TRANSPORTS.join(", ")
        )));
    }
    for key in ENDPOINT_FILE_KEYS {
        if let Some(file) = parsed.config().get(key) {
            readable(file).map_err(|why| bad(format!("{flag} {text}: {key}: {file}: {why}")))?;
        }
    }
    let address = parsed.address();
    let address = address.as_str();
    let (host, port) = match address.strip_prefix('[') {
        Some(v6) => v6.split_once("]:").unwrap_or((v6, "")),
        None => address.rsplit_once(':').unwrap_or((address, "")),
    };
    if host.is_empty() || host.contains(':') && !address.starts_with('[') {
        return Err(bad(format!(
            "{flag} {text}: the address is host:port, an IPv6 host in brackets ([::1]:7447)"
        )));
    }
    if port.parse::<u16>().is_err() {
        return Err(bad(format!("{flag} {text}: the address needs a port, 0 to 65535")));
    }
    Ok(())
}

/// The endpoints under `key` of a config: a list, lists by mode, and groups of locators
/// (`{ strategy: "allOf", locators: [..] }`).
fn endpoints_of(config: &Config, key: &str) -> Vec<String> {
    fn strings(v: &serde_json::Value, out: &mut Vec<String>) {
        match v {
            serde_json::Value::String(s) => out.push(s.clone()),
            serde_json::Value::Array(a) => a.iter().for_each(|v| strings(v, out)),
            serde_json::Value::Object(o) => match o.get("locators") {
                Some(group) => strings(group, out),
                None => o.values().for_each(|v| strings(v, out)),
            },
            _ => {}
        }
    }
    let mut out = Vec::new();
    if let Some(v) = config.get_json(key).ok().and_then(|j| serde_json::from_str(&j).ok()) {
        strings(&v, &mut out);
    }
    out
}

/// The files a Zenoh config names: TLS certificates and keys, and the user-password dictionary.
const FILE_KEYS: [&str; 6] = [
    "transport/link/tls/root_ca_certificate",
    "transport/link/tls/listen_private_key",
    "transport/link/tls/listen_certificate",
    "transport/link/tls/connect_private_key",
    "transport/link/tls/connect_certificate",
    "transport/auth/usrpwd/dictionary_file",
];

/// The string `config` holds at `key`, if it holds one.
fn string_at(config: &Config, key: &str) -> Option<String> {
    config
        .get_json(key)
        .ok()
        .and_then(|j| serde_json::from_str::<Option<String>>(&j).ok())
        .flatten()
}

/// Every file `config` (read from `path`) names can be read: a missing certificate made a client
/// wait out its connect timeout and then blame the network.
fn files_of(config: &Config, path: &std::path::Path) -> Result<()> {
    for key in FILE_KEYS {
        let Some(file) = string_at(config, key) else {
            continue;
        };
        readable(&file).map_err(|why| bad(format!("{}: {key}: {file}: {why}", path.display())))?;
    }
    Ok(())
}

/// The files an endpoint's own TLS options name (`tls/host:port#root_ca_certificate_file=…`).
const ENDPOINT_FILE_KEYS: [&str; 5] = [
    "root_ca_certificate_file",
    "listen_private_key_file",
    "listen_certificate_file",
    "connect_private_key_file",
    "connect_certificate_file",
];

/// Why `file` cannot be read, if it cannot.
fn readable(file: &str) -> std::result::Result<(), String> {
    let unreadable = match std::fs::metadata(file) {
        Ok(m) if m.is_dir() => Some("a directory, not a file".to_string()),
        Ok(_) => std::fs::File::open(file).err().map(|e| e.to_string()),
        Err(e) => Some(e.to_string()),
    };
    let Some(why) = unreadable else { return Ok(()) };
    let here = match std::path::Path::new(file).is_relative() {
        true => std::env::current_dir().map_or_else(
            |_| String::new(),
            |d| format!(" (a relative path is from the working directory, {})", d.display()),
        ),
        false => String::new(),
    };
    Err(format!("{why}{here}"))
}

/// How many connections may be in their handshake at once, and for how long (ms), on a role
/// that listens. Zenoh closes every new connection while `transport/unicast/accept_pending` are
/// (100 by default, each for up to 10 s): a few hundred idle connections from anyone who could
/// reach the port kept every process of a fleet out. A pending connection costs a socket and a
/// timer, so thousands are cheap; a handshake on a loaded testbed takes milliseconds.
pub const ACCEPT_PENDING: usize = 4096;
pub const ACCEPT_TIMEOUT_MS: u64 = 5000;

/// Sets `key` of `config` to the JSON5 `value`.
fn set(config: &mut Config, key: &str, value: &str) -> Result<()> {
    config
        .insert_json5(key, value)
        .map_err(|e| failed!("zenoh {key}: {}", zenoh_words(e)))
}

/// A certificate is presented over TLS only: over another protocol a link would carry none, and
/// the router would refuse it without a word of why.
fn over_tls(config: &Config, key: &str, given: &std::path::Path) -> Result<()> {
    for e in endpoints_of(config, key) {
        if !(e.starts_with("tls/") || e.starts_with("quic/")) {
            let address = e.split_once('/').map_or(e.as_str(), |(_, a)| a);
            return Err(bad(format!(
                "--credential {}: a certificate is presented over TLS, and {key} has {e}: give tls/{address}",
                given.display()
            )));
        }
    }
    Ok(())
}

/// Sets each of `tls`'s keys in `config`'s `transport/link/tls`, keeping what a `-c` file says of
/// the others (its socket buffers, say).
fn present_tls(config: &mut Config, tls: serde_json::Value) -> Result<()> {
    for (key, value) in tls.as_object().into_iter().flatten() {
        set(config, &format!("transport/link/tls/{key}"), &value.to_string())?;
    }
    Ok(())
}

/// A router of a fleet with a credential per role (`tcpf credential DIR MISSION`): it demands
/// one of the roles' certificates (or users and passwords) of every link, and lets each do only
/// what its role does (the access rules made from the mission). `listen` is where it listens
/// when told nowhere.
fn guard(config: &mut Config, dir: &std::path::Path, listen: Option<&str>) -> Result<()> {
    let (demand, rules) =
        credential::read_fleet(dir).map_err(|why| bad(format!("--credential {}: {why}", dir.display())))?;
    match demand {
        Demand::Certificate(bundle) => {
            if let Some(listen) = listen {
                set(config, "listen/endpoints", &format!("[\"tls/{listen}\"]"))?;
            }
            over_tls(config, "listen/endpoints", dir)?;
            present_tls(config, certificate::tls(&bundle.authority, &bundle.pair, true))?;
        }
        Demand::Dictionary(dictionary) => {
            let dictionary = std::fs::canonicalize(&dictionary)
                .map_err(|e| bad(format!("--credential {}: {e}", dictionary.display())))?;
            let auth = serde_json::json!({ "dictionary_file": dictionary });
            config
                .insert_json5("transport/auth/usrpwd", &auth.to_string())
                .map_err(|e| failed!("--credential: {}", zenoh_words(e)))?;
        }
    }
    config.insert_json5("access_control", &rules.to_string()).map_err(|e| {
        bad(format!(
            "--credential {}: {}: {}",
            dir.display(),
            credential::ACCESS,
            zenoh_words(e)
        ))
    })?;
    set(config, "scouting/gossip/enabled", "false")
}

/// Why a role with no credential does not start unless told to (`--open`).
const RUNS_OPEN: &str = "this role would run open: its Zenoh configuration demands no credential, so any process that reaches it could join the fleet and speak for any role. Make a certificate per role once with `tcpf credential fleet mission.toml`, give the router `--credential fleet` and each role its own, over tls/ endpoints (`--credential fleet/agent-1.pem -e tls/HOST:PORT`; docs/TESTBED.md); or, where every host is trusted, one for all with `tcpf credential fleet.key`; or give -c a mutual-TLS configuration (configs/zenoh/tls/); or, on a network only you use, `--open`";

/// What `config` demands of the processes it meets, if anything: a user and password, or a
/// certificate (mutual TLS).
pub fn credential(config: &Config) -> Option<&'static str> {
    let set = |key: &str| {
        config
            .get_json(key)
            .is_ok_and(|v| !matches!(v.as_str(), "" | "null" | "false"))
    };
    if set("transport/auth/usrpwd/dictionary_file") || set("transport/auth/usrpwd/user") {
        Some("a user and password")
    } else if set("transport/link/tls/enable_mtls") {
        Some("a certificate (mutual TLS)")
    } else {
        None
    }
}

/// A role told to run with no credential (`--open`) says so as it starts: any process that
/// reaches it can join the fleet and speak for any role.
pub fn warn_if_open(config: &Config) {
    if credential(config).is_none() {
        let at = ["listen/endpoints", "connect/endpoints"]
            .iter()
            .map(|k| config.get_json(k).unwrap_or_default())
            .filter(|e| !matches!(e.as_str(), "" | "[]" | "{}"))
            .collect::<Vec<_>>()
            .join(" and ");
        tracing::warn!(
            "this role runs open (--open): its Zenoh configuration demands no credential, so any process that reaches {at} can join this fleet and speak for any role; `tcpf credential DIR MISSION` makes a certificate for each role's --credential and the router's (docs/TESTBED.md)"
        );
    }
}

/// The longest message Zenoh reassembles: the longest of any kind (`TickRecord`'s) and room for
/// Zenoh's own headers and a ROS 2 path. A longer one is dropped where it first arrives, unread
/// and not forwarded, instead of Zenoh's 1 GiB, which let a forger's 29 MB records stall a link.
const MAX_MESSAGE_BYTES: usize = <TickRecord as Checked>::MAX_BYTES + 1024 * 1024;

/// At most `MAX_MESSAGE_BYTES`, or less where a config file says so.
fn cap_messages(config: &mut Config) -> Result<()> {
    let key = "transport/link/rx/max_message_size";
    let given = config.get_json(key).ok().and_then(|v| v.parse::<usize>().ok());
    let cap = given.map_or(MAX_MESSAGE_BYTES, |g| g.min(MAX_MESSAGE_BYTES));
    set(config, key, &cap.to_string())
}

impl ZenohArgs {
    /// Without a config file: peer mode on 127.0.0.1, no multicast scouting, an ephemeral port,
    /// a handshake queue that idle connections do not fill (`ACCEPT_PENDING`), so that nothing
    /// needs installing and runs never meet by accident.
    pub fn config(&self) -> Result<Config> {
        let mut config = match &self.config {
            Some(path) => from_file(path)?,
            None => {
                let mut c = Config::default();
                set(&mut c, "mode", "\"peer\"")?;
                set(&mut c, "scouting/multicast/enabled", "false")?;
                set(&mut c, "listen/endpoints", "[\"tcp/127.0.0.1:0\"]")?;
                set(&mut c, "transport/unicast/accept_pending", &ACCEPT_PENDING.to_string())?;
                set(
                    &mut c,
                    "transport/unicast/accept_timeout",
                    &ACCEPT_TIMEOUT_MS.to_string(),
                )?;
                c
            }
        };
        if let Some(mode) = self.mode.as_deref().or(self.implied_mode()) {
            if !["peer", "client", "router"].contains(&mode) {
                return Err(bad(format!("--mode {mode}: expected peer, client or router")));
            }
            config
                .insert_json5("mode", &format!("\"{mode}\""))
                .map_err(|e| failed!("--mode: {}", zenoh_words(e)))?;
            // Without a config nothing is scouted for, and a router's open would sleep 500 ms
            // for it (a peer's waits as long for its --connect links, which it keeps).
            if self.config.is_none() && mode == "router" {
                config
                    .insert_json5("scouting/delay", "0")
                    .map_err(|e| failed!("zenoh scouting/delay: {}", zenoh_words(e)))?;
            }
        }
        for (flag, endpoints, key) in [
            ("--connect", &self.connect, "connect/endpoints"),
            ("--listen", &self.listen, "listen/endpoints"),
        ] {
            if !endpoints.is_empty() {
                for e in endpoints {
                    endpoint(flag, e)?;
                }
                config
                    .insert_json5(key, &json_list(endpoints))
                    .map_err(|e| bad(format!("{flag}: {}", zenoh_words(e))))?;
            }
        }
        // A config file's endpoints and files, too: Zenoh would find out only when it opens,
        // and say it as if the network had failed (or, for a certificate, not at all).
        if let Some(path) = &self.config {
            for key in ["connect/endpoints", "listen/endpoints"] {
                for e in endpoints_of(&config, key) {
                    endpoint(&format!("{}: {key}", path.display()), &e)?;
                }
            }
            files_of(&config, path)?;
        }
        if let Some(file) = &self.credential {
            self.present(&mut config, file)?;
        }
        if credential(&config).is_none() && !self.open {
            return Err(bad(RUNS_OPEN.to_string()));
        }
        cap_messages(&mut config)?;
        Ok(config)
    }

    /// Whether this process will be a client, whose every message passes through one router; a
    /// config that cannot be made is no client (opening the session says why).
    pub fn is_client(&self) -> bool {
        self.config()
            .is_ok_and(|c| string_at(&c, "mode").as_deref() == Some("client"))
    }

    /// The mode a credential implies without -c or --mode. Peers that find each other open links
    /// both ways, and with a user and password Zenoh 1.10 refuses the second
    /// (eclipse-zenoh/zenoh#2577), so a fleet with a credential meets at a router: the process
    /// that listens is that router, and one that only connects its client.
    fn implied_mode(&self) -> Option<&'static str> {
        if self.credential.is_none() || self.config.is_some() || self.mode.is_some() {
            return None;
        }
        match (self.listen.is_empty(), self.connect.is_empty()) {
            (false, _) => Some("router"),
            (true, false) => Some("client"),
            (true, true) => None,
        }
    }

    /// Makes `config` present and demand the credential in `file`, and suit the mode it implies;
    /// a router given a fleet directory (`guard`) demands every role's and enforces its rules.
    fn present(&self, config: &mut Config, file: &std::path::Path) -> Result<()> {
        let router = string_at(config, "mode").as_deref() == Some("router");
        if file.is_dir() && router {
            let told_nowhere = self.listen.is_empty() && self.config.is_none();
            return guard(config, file, told_nowhere.then_some("127.0.0.1:0"));
        }
        let given = |why: String| bad(format!("--credential {}: {why}", file.display()));
        let (user, password) = match credential::read(file).map_err(given)? {
            Credential::Password { user, password } => (user, password),
            Credential::Certificate(bundle) => {
                let name = bundle.name().map_err(|e| given(e.to_string()))?;
                if router {
                    return Err(given(format!(
                        "it is {name}'s certificate, one role's, and this process would be the fleet's router, which must let every role in: give the router the directory the certificates came from (`tcpf router --credential DIR -l tls/HOST:PORT`) and connect every role to it with -e"
                    )));
                }
                over_tls(config, "connect/endpoints", file)?;
                // A peer listens, and a plain listener would let in anyone with no certificate.
                if string_at(config, "mode").as_deref() != Some("client") {
                    over_tls(config, "listen/endpoints", file)?;
                }
                present_tls(config, certificate::tls(&bundle.authority, &bundle.pair, false))?;
                return self.suit_mode(config);
            }
        };
        // A router with one role's key would let in that role alone, and every other role would
        // wait out its timeout blaming the network.
        if router && user != credential::USER {
            return Err(bad(format!(
                "--credential {}: it is {user}'s key, one role's, and this process would be the fleet's router, which must let every role in: give the router the directory the keys came from (`tcpf router --credential DIR -l ENDPOINT`) and connect every role to it with -e",
                file.display()
            )));
        }
        let dictionary =
            std::fs::canonicalize(file).map_err(|e| bad(format!("--credential {}: {e}", file.display())))?;
        let auth = serde_json::json!({
            "user": user,
            "password": password,
            "dictionary_file": dictionary,
        });
        config
            .insert_json5("transport/auth/usrpwd", &auth.to_string())
            .map_err(|e| failed!("--credential: {}", zenoh_words(e)))?;
        self.suit_mode(config)
    }

    /// Makes `config` suit the mode its credential implies.
    fn suit_mode(&self, config: &mut Config) -> Result<()> {
        match self.implied_mode() {
            // Its clients need no gossip to find each other.
            Some("router") => set(config, "scouting/gossip/enabled", "false"),
            Some(_) => {
                // A client gives up at once if its router is not up (Zenoh's default): this one
                // waits for it, as a peer would, until the role's --startup-timeout.
                set(config, "connect/timeout_ms", "-1")?;
                set(
                    config,
                    "connect/retry",
                    "{ period_init_ms: 50, period_max_ms: 1000, period_increase_factor: 2 }",
                )
            }
            None => Ok(()),
        }
    }

    /// Refuses to speak as `identity` with another role's certificate or key (a fleet made by
    /// `tcpf credential DIR MISSION`): the router would drop everything this process says,
    /// without a word to it. The fleet's one shared user, or a configuration without a user or a
    /// certificate of `tcpf credential`, speaks for any role (a testbed's own certificates may
    /// name hosts rather than roles: its router's rules judge them).
    pub fn speaks_as(&self, identity: Identity) -> Result<()> {
        let config = self.config()?;
        let certificate = match &self.credential {
            Some(file) => match credential::read(file) {
                Ok(Credential::Certificate(bundle)) => Some(bundle.name()?),
                _ => None,
            },
            None => None,
        };
        let (name, proof) = match certificate {
            Some(name) => (Some(name), Proof::Certificates { hosts: &[] }),
            None => (string_at(&config, "transport/auth/usrpwd/user"), Proof::Passwords),
        };
        match name {
            Some(user) if user != credential::USER && user != identity.to_string() => {
                let own = credential::key_file(identity, proof);
                let (given, own) = match (&self.credential, &self.config) {
                    (Some(file), _) => (
                        format!("--credential {}", file.display()),
                        file.with_file_name(own).display().to_string(),
                    ),
                    (None, Some(file)) => (format!("-c {}", file.display()), own),
                    (None, None) => ("its configuration".to_string(), own),
                };
                Err(bad(format!(
                    "{given} is {user}'s, and this process is {identity}: the router lets each role's credential speak only as that role. Give it {own}"
                )))
            }
            _ => Ok(()),
        }
    }

    /// Whether the session these options open is a router, through which others' messages pass.
    pub fn routes(&self) -> Result<bool> {
        let mode = self
            .config()?
            .get_json("mode")
            .map_err(|e| failed!("zenoh mode: {e}"))?;
        Ok(mode.trim_matches('"') == "router")
    }

    /// `open`, unless a signal comes first: a client waits up to its connect timeout (a minute in
    /// configs/zenoh/) for a router that is not up, and Ctrl-C must not wait with it.
    /// Zenoh's open blocks the thread that polls it while it waits, so it opens on a task of
    /// its own.
    /// Opens the session unless a signal comes first, and gives up after `within` (a role's
    /// startup timeout): a role pointed at a router that does not answer says where it tries,
    /// and stops waiting when its timeout says so, not when a config file's connect timeout does.
    pub async fn open_unless(&self, shutdown: &mut Shutdown, within: Duration) -> Result<Session> {
        let config = self.config()?;
        warn_if_open(&config);
        let endpoints = config.get_json("connect/endpoints").unwrap_or_default();
        let trying = !matches!(endpoints.as_str(), "" | "[]" | "{}");
        if trying {
            tracing::info!("connecting to {endpoints}");
        }
        let opening = tokio::time::timeout(within, tokio::spawn(open(config)));
        match shutdown.unless(opening).await {
            Some(Ok(opened)) => opened.map_err(|e| failed!("opening the Zenoh session: {e}"))?,
            Some(Err(_)) if trying => Err(failed!(
                "cannot open the Zenoh session: nothing answered at {endpoints} within {} s (--startup-timeout), or it refused this process's credential; is the router up, reachable from this host, and given the same --credential (the fleet's shared one, or the directory this role's key came from)? (RUST_LOG=zenoh=debug says which)",
                within.as_secs_f64()
            )),
            Some(Err(_)) => Err(failed!(
                "cannot open the Zenoh session within {} s (--startup-timeout)",
                within.as_secs_f64()
            )),
            None => Err(Error::Interrupted("while the Zenoh session was opening")),
        }
    }

    pub async fn open(&self) -> Result<Session> {
        open(self.config()?).await
    }
}

/// Opens a session with `config`, saying in a user's words why it could not.
async fn open(config: Config) -> Result<Session> {
    let opened = zenoh::open(config).await.map_err(|e| failed!("{}", zenoh_words(e)));
    if let Err(e) = &opened {
        let words = e.to_string();
        if words.contains("listener") {
            let hint = if words.contains("Address already in use") {
                " (is another process listening there?)"
            } else if words.contains("Cannot assign requested address") {
                " (is that address one of this host's?)"
            } else {
                ""
            };
            return Err(failed!("cannot open the Zenoh session: {e}{hint}"));
        }
    }
    opened.context(
        "cannot open the Zenoh session: nothing answered at the endpoints to connect to, a \
             TLS handshake failed, or the router refused this process's credentials (is the \
             router up and reachable? does it accept this host's certificate? is the router's \
             certificate valid for the address connected to, and signed by the CA this host \
             trusts? to join a `tcpf run`, use a configuration of its run directory, which holds a \
             role's certificate: zenoh.json5 to record, observer.json5 to watch; \
             RUST_LOG=zenoh=debug says which)",
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every role's Zenoh reassembles no message longer than the longest kind, whatever its
    /// config file allows; a file that allows less keeps its own.
    #[test]
    fn no_role_reassembles_a_message_longer_than_the_protocols_longest() {
        let key = "transport/link/rx/max_message_size";
        let open = ZenohArgs {
            open: true,
            ..ZenohArgs::default()
        };
        let size = |c: &Config| c.get_json(key).unwrap().parse::<usize>().unwrap();
        assert_eq!(size(&open.config().unwrap()), MAX_MESSAGE_BYTES);
        assert_eq!(size(&Config::default()), 1 << 30, "Zenoh's own: 1 GiB");
        let mut small = Config::default();
        set(&mut small, key, "65536").unwrap();
        cap_messages(&mut small).unwrap();
        assert_eq!(size(&small), 65536);
    }

    #[test]
    fn zenoh_errors_lose_their_source_paths() {
        let raw = "invalid port value at /root/.cargo/registry/src/index/zenoh-link-commons-1.10.2/src/lib.rs:62.";
        assert_eq!(zenoh_words(raw), "invalid port value");
        let bracketed = "Can not create a new TCP listener bound to tcp/127.0.0.1:42975: [127.0.0.1:42975: Address already in use (os error 98) at /root/.cargo/registry/src/i/zenoh-link-commons-1.10.2/src/tcp.rs:61.] at /root/.cargo/registry/src/i/zenoh-link-tcp-1.10.2/src/unicast.rs:338.";
        assert_eq!(
            zenoh_words(bracketed),
            "Can not create a new TCP listener bound to tcp/127.0.0.1:42975: [127.0.0.1:42975: Address already in use (os error 98)]"
        );
        let chained = "Unable to bind UDP port 192.0.2.1:7446 at /r/zenoh-1.10.2/src/orchestrator.rs:689. - Caused by Cannot assign requested address";
        assert_eq!(
            zenoh_words(chained),
            "Unable to bind UDP port 192.0.2.1:7446 - Caused by Cannot assign requested address"
        );
        assert_eq!(zenoh_words("see /etc at /home/my files"), "see /etc at /home/my files");
        let vendored =
            "127.0.0.1:36167: Address already in use (os error 98) at vendor/zenoh-link-tls/src/unicast.rs:458";
        assert_eq!(
            zenoh_words(vendored),
            "127.0.0.1:36167: Address already in use (os error 98)"
        );

        assert_eq!(
            zenoh_words("no route to host at the shore"),
            "no route to host at the shore"
        );
    }

    #[test]
    fn a_bad_config_file_is_named_with_where_and_what_its_parser_found() {
        let dir = std::env::temp_dir().join(format!("tcpf-config-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("zenoh.json5");
        for (text, at, words) in [
            (
                "{ mode: \"client\", bogus: 1 }",
                "line 1, column ",
                "unknown field `bogus`",
            ),
            ("{ mode: \"client\",\n  mode: ", "line 2, column ", ""),
            (
                "{ connect: { endpoints: [\"foo\"] } }",
                "line 1, column ",
                "Endpoints must be of the form <protocol>/<address>",
            ),
        ] {
            std::fs::write(&file, text).unwrap();
            let e = from_file(&file).unwrap_err();
            assert!(matches!(e, Error::BadZenohConfig(_)), "{e}");
            let said = e.to_string();
            let expected = format!("{}: bad Zenoh config: {at}", file.display());
            assert!(said.starts_with(&expected) && said.contains(words), "{said}");
            assert!(!said.contains(".rs:") && !said.contains("Message {"), "{said}");
        }
        std::fs::write(&file, "{ mode: \"client\" }").unwrap();
        assert!(from_file(&file).is_ok());
        let e = from_file(&dir.join("nothing.json5")).unwrap_err().to_string();
        assert!(e.contains("nothing.json5: bad Zenoh config: No such file"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_config_naming_a_file_that_is_not_there_is_bad_input() {
        let dir = std::env::temp_dir().join(format!("tcpf-files-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let ca = dir.join("ca.pem");
        std::fs::write(&ca, "not checked here").unwrap();
        let config = dir.join("vehicle.json5");
        let write = |key: &str| {
            let text = format!(
                "{{ mode: \"client\", scouting: {{ multicast: {{ enabled: false }} }}, transport: {{ link: {{ tls: {{ root_ca_certificate: \"{}\", {key}: \"{}/missing.pem\" }} }} }} }}",
                ca.display(),
                dir.display()
            );
            std::fs::write(&config, text).unwrap();
        };
        let args = ZenohArgs {
            config: Some(config.clone()),
            open: true,
            ..Default::default()
        };
        for key in ["connect_certificate", "listen_private_key"] {
            write(key);
            let e = args.config().unwrap_err();
            assert!(matches!(e, Error::BadZenohConfig(_)), "{e}");
            let words = e.to_string();
            assert!(words.contains(&format!("transport/link/tls/{key}")), "{words}");
            assert!(words.contains("missing.pem: No such file"), "{words}");
        }
        std::fs::write(
            &config,
            format!(
                "{{ transport: {{ link: {{ tls: {{ root_ca_certificate: \"{}\" }} }} }} }}",
                ca.display()
            ),
        )
        .unwrap();
        assert!(args.config().is_ok(), "a file that is there");
        std::fs::write(
            &config,
            format!(
                "{{ transport: {{ link: {{ tls: {{ root_ca_certificate: \"{}\" }} }} }} }}",
                dir.display()
            ),
        )
        .unwrap();
        let e = args.config().unwrap_err().to_string();
        assert!(e.ends_with(": a directory, not a file"), "{e}");
        // The same files named in an endpoint's own options, on the command line.
        let missing = format!(
            "tls/127.0.0.1:7447#root_ca_certificate_file={}/missing.pem",
            dir.display()
        );
        let flagged = ZenohArgs {
            connect: vec![missing.clone()],
            ..Default::default()
        };
        let e = flagged.config().unwrap_err();
        assert!(matches!(e, Error::BadZenohConfig(_)), "{e}");
        let words = e.to_string();
        assert!(
            words.starts_with(&format!("--connect {missing}: root_ca_certificate_file: ")),
            "{words}"
        );
        assert!(words.contains("missing.pem: No such file"), "{words}");
        let there = format!("tls/127.0.0.1:7447#root_ca_certificate_file={}", ca.display());
        let flagged = ZenohArgs {
            connect: vec![there],
            open: true,
            ..Default::default()
        };
        assert!(flagged.config().is_ok(), "a file that is there");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn endpoints_are_checked_before_zenoh_sees_them() {
        for good in [
            "tcp/127.0.0.1:7447",
            "tcp/[::1]:0",
            "quic/shore.local:7447?iface=eth0",
            "udp/224.0.0.224:7447#iface=lo",
        ] {
            assert!(endpoint("-e", good).is_ok(), "{good}");
        }
        for bad in [
            "foo",
            "tcp/127.0.0.1",
            "udp/127.0.0.1:70000",
            "tls/host:port",
            "tcp/::1",
            "unixsock-stream//tmp/s",
            "ws/127.0.0.1:80",
        ] {
            let e = endpoint("-e", bad).unwrap_err();
            assert!(matches!(e, Error::BadZenohConfig(_)), "{bad}");
        }
    }

    #[test]
    fn a_role_runs_open_only_when_told_and_a_credential_makes_a_router_or_its_client() {
        let e = ZenohArgs::default().config().unwrap_err();
        assert!(matches!(e, Error::BadZenohConfig(_)), "{e}");
        let words = e.to_string();
        for named in ["run open", "tcpf credential fleet.key", "--credential", "--open"] {
            assert!(words.contains(named), "{named}: {words}");
        }
        let open = ZenohArgs {
            open: true,
            ..Default::default()
        };
        assert!(credential(&open.config().unwrap()).is_none());

        let dir = std::env::temp_dir().join(format!("tcpf-present-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("fleet.key");
        let password = credential::create(&file).unwrap();
        let with = |listen: &[&str], connect: &[&str], mode: Option<&str>| {
            let args = ZenohArgs {
                credential: Some(file.clone()),
                listen: listen.iter().map(|s| s.to_string()).collect(),
                connect: connect.iter().map(|s| s.to_string()).collect(),
                mode: mode.map(str::to_string),
                ..Default::default()
            };
            let config = args.config().unwrap();
            assert_eq!(credential(&config), Some("a user and password"));
            let user = config.get_json("transport/auth/usrpwd/user").unwrap();
            assert_eq!(user, "\"tcpf\"");
            let pass = config.get_json("transport/auth/usrpwd/password").unwrap();
            assert_eq!(pass, format!("\"{password}\""));
            config.get_json("mode").unwrap().trim_matches('"').to_string()
        };
        assert_eq!(with(&["tcp/127.0.0.1:0"], &[], None), "router");
        assert_eq!(with(&[], &["tcp/127.0.0.1:7447"], None), "client");
        assert_eq!(with(&[], &["tcp/127.0.0.1:7447"], Some("peer")), "peer");

        std::fs::set_permissions(&file, std::os::unix::fs::PermissionsExt::from_mode(0o640)).unwrap();
        let args = ZenohArgs {
            credential: Some(file.clone()),
            ..Default::default()
        };
        let e = args.config().unwrap_err();
        assert!(matches!(e, Error::BadZenohConfig(_)), "{e}");
        assert!(
            e.to_string()
                .starts_with(&format!("--credential {}: others may read it", file.display())),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_fleet_directory_makes_its_router_judge_and_each_credential_speak_only_as_its_role() {
        use crate::acl::{Fleet, Identity};
        let hosts = ["shore.local".to_string()];
        for (proof, protocol, demands, kind) in [
            (
                Proof::Certificates { hosts: &hosts },
                "tls",
                "a certificate (mutual TLS)",
                "certificate",
            ),
            (Proof::Passwords, "tcp", "a user and password", "key"),
        ] {
            let dir = std::env::temp_dir().join(format!("tcpf-fleet-{kind}-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&dir);
            let fleet = Fleet {
                keys: crate::keys::Keys::new("m"),
                vehicles: &[1, 2],
                ros2: None,
                played: &[],
            };
            credential::create_fleet(&dir, "m", &fleet, proof).unwrap();
            let router = ZenohArgs {
                credential: Some(dir.clone()),
                listen: vec![format!("{protocol}/127.0.0.1:0")],
                ..Default::default()
            };
            let config = router.config().unwrap();
            assert_eq!(credential(&config), Some(demands));
            assert_eq!(config.get_json("access_control/enabled").unwrap(), "true");
            assert_eq!(
                config.get_json("access_control/default_permission").unwrap(),
                "\"deny\""
            );
            assert!(config.get_json("transport/auth/usrpwd/user").unwrap() == "null");
            // Given to a role, the directory is refused: a role takes its own file.
            let role = ZenohArgs {
                credential: Some(dir.clone()),
                connect: vec![format!("{protocol}/127.0.0.1:7447")],
                ..Default::default()
            };
            let e = role.config().unwrap_err().to_string();
            assert!(e.contains("a role takes its own file"), "{e}");
            let agent = |id: u32| ZenohArgs {
                credential: Some(dir.join(credential::key_file(Identity::Agent(id), proof))),
                connect: vec![format!("{protocol}/127.0.0.1:7447")],
                ..Default::default()
            };
            assert_eq!(credential(&agent(1).config().unwrap()), Some(demands));
            agent(1).speaks_as(Identity::Agent(1)).unwrap();
            let e = agent(1).speaks_as(Identity::Agent(2)).unwrap_err();
            assert!(matches!(e, Error::BadZenohConfig(_)), "{e}");
            let words = e.to_string();
            assert!(words.contains("is agent-1's, and this process is agent-2"), "{words}");
            let own = dir.join(credential::key_file(Identity::Agent(2), proof));
            assert!(words.contains(&own.display().to_string()), "{words}");
            assert!(agent(1).speaks_as(Identity::World).is_err());
            // One role's credential makes no router: it would let that role alone in.
            let listening = ZenohArgs {
                credential: Some(dir.join(credential::key_file(Identity::Planner, proof))),
                listen: vec![format!("{protocol}/127.0.0.1:0")],
                ..Default::default()
            };
            let e = listening.config().unwrap_err().to_string();
            assert!(
                e.contains(&format!("it is planner's {kind}, one role's"))
                    && e.contains("tcpf router --credential DIR"),
                "{e}"
            );
            // Rules switched off are no rules: the router refuses to start on them.
            let access = dir.join(credential::ACCESS);
            std::fs::remove_file(&access).unwrap();
            credential::private(&access, "{ \"enabled\": false }").unwrap();
            let e = router.config().unwrap_err().to_string();
            assert!(e.contains("must be enabled and deny by default"), "{e}");
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }

    #[test]
    fn a_certificate_is_presented_over_tls_and_its_router_listens_there_unless_told() {
        use crate::acl::{Fleet, Identity};
        let dir = std::env::temp_dir().join(format!("tcpf-fleet-tls-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let fleet = Fleet {
            keys: crate::keys::Keys::new("m"),
            vehicles: &[1],
            ros2: None,
            played: &[],
        };
        let proof = Proof::Certificates { hosts: &[] };
        credential::create_fleet(&dir, "m", &fleet, proof).unwrap();
        let agent = ZenohArgs {
            credential: Some(dir.join(credential::key_file(Identity::Agent(1), proof))),
            connect: vec!["tcp/127.0.0.1:7447".into()],
            ..Default::default()
        };
        let e = agent.config().unwrap_err().to_string();
        assert!(
            e.contains("a certificate is presented over TLS, and connect/endpoints has tcp/127.0.0.1:7447: give tls/127.0.0.1:7447"),
            "{e}"
        );
        // A peer with a certificate would listen where anyone gets in without one.
        let peer = ZenohArgs {
            credential: agent.credential.clone(),
            mode: Some("peer".into()),
            ..Default::default()
        };
        let e = peer.config().unwrap_err().to_string();
        assert!(e.contains("listen/endpoints has tcp/127.0.0.1:0"), "{e}");
        let client = ZenohArgs {
            connect: vec!["tls/127.0.0.1:7447".into()],
            ..agent.clone()
        };
        let config = client.config().unwrap();
        assert_eq!(config.get_json("transport/link/tls/enable_mtls").unwrap(), "true");
        let router = ZenohArgs {
            credential: Some(dir.clone()),
            mode: Some("router".into()),
            ..Default::default()
        };
        let config = router.config().unwrap();
        assert_eq!(config.get_json("listen/endpoints").unwrap(), "[\"tls/127.0.0.1:0\"]");
        // The fleet's one shared user speaks for any role.
        let shared = dir.join("fleet.key");
        credential::create(&shared).unwrap();
        let any = ZenohArgs {
            credential: Some(shared),
            connect: vec!["tcp/127.0.0.1:7447".into()],
            ..Default::default()
        };
        any.speaks_as(Identity::World).unwrap();
        any.speaks_as(Identity::Agent(2)).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
