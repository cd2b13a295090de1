//! A Zenoh session from the options every role takes, as Zenoh's own tools spell them.

use std::path::PathBuf;

use anyhow::{anyhow, Context, Result};
use zenoh::{Config, Session};

use crate::signals::{Interrupted, Shutdown};

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
}

fn json_list(items: &[String]) -> String {
    serde_json::to_string(items).expect("strings encode")
}

/// Zenoh options that cannot work, whatever the network does: bad input (exit 2).
#[derive(Debug)]
pub struct BadZenohConfig(pub String);

impl std::fmt::Display for BadZenohConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for BadZenohConfig {}

fn bad(message: String) -> anyhow::Error {
    BadZenohConfig(message).into()
}

/// A Zenoh error in a user's words: without the source file and line each of Zenoh's errors
/// ends with (` at /…/src/lib.rs:62.`), and with a JSON5 parser's message and location taken
/// out of their Debug form.
pub fn zenoh_words(e: impl std::fmt::Display) -> String {
    let mut text = e.to_string();
    while let Some(at) = text.rfind(" at /") {
        let tail = &text[at..];
        if !tail.contains(".rs:") || tail.contains(' ') && tail[5..].contains(' ') {
            break;
        }
        text.truncate(at);
    }
    if let (Some(m), Some(end)) = (text.find("msg: \""), text.find("\", location")) {
        if m < end {
            let msg = text[m + 6..end].to_string();
            let line = text.split("line: ").nth(1).and_then(|r| r.split(',').next());
            let column = text.split("column: ").nth(1).and_then(|r| r.split(' ').next());
            text = match (line, column) {
                (Some(l), Some(c)) => format!("line {l}, column {c}: {msg}"),
                _ => msg,
            };
        }
    }
    text.trim_end_matches('.').to_string()
}

/// An endpoint Zenoh can parse, and, over IP, with a port that is one.
fn endpoint(flag: &str, text: &str) -> Result<()> {
    let parsed: zenoh::config::EndPoint = text.parse().map_err(|_| {
        bad(format!(
            "{flag} {text}: an endpoint is <protocol>/<address>, e.g. tcp/192.168.1.10:7447"
        ))
    })?;
    let ip = ["tcp", "udp", "tls", "quic"].contains(&parsed.protocol().as_str());
    let address = parsed.address();
    let port = address.as_str().rsplit_once(':').map(|(_, p)| p);
    if ip && port.is_none_or(|p| p.parse::<u16>().is_err()) {
        return Err(bad(format!("{flag} {text}: the address needs a port, 0 to 65535")));
    }
    Ok(())
}

impl ZenohArgs {
    /// Without a config file: peer mode on 127.0.0.1, no multicast scouting, an ephemeral port,
    /// so that nothing needs installing and runs never meet by accident.
    pub fn config(&self) -> Result<Config> {
        let mut config = match &self.config {
            Some(path) => Config::from_file(path)
                .map_err(|e| bad(format!("{}: bad Zenoh config: {}", path.display(), zenoh_words(e))))?,
            None => {
                let mut c = Config::default();
                let set = |c: &mut Config, k: &str, v: &str| {
                    c.insert_json5(k, v)
                        .map_err(|e| anyhow!("zenoh {k}: {}", zenoh_words(e)))
                };
                set(&mut c, "mode", "\"peer\"")?;
                set(&mut c, "scouting/multicast/enabled", "false")?;
                set(&mut c, "listen/endpoints", "[\"tcp/127.0.0.1:0\"]")?;
                c
            }
        };
        if let Some(mode) = &self.mode {
            if !["peer", "client", "router"].contains(&mode.as_str()) {
                return Err(bad(format!("--mode {mode}: expected peer, client or router")));
            }
            config
                .insert_json5("mode", &format!("\"{mode}\""))
                .map_err(|e| anyhow!("--mode: {}", zenoh_words(e)))?;
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
        Ok(config)
    }

    /// `open`, unless a signal comes first: a client waits up to its connect timeout (a minute in
    /// configs/zenoh/) for a router that is not up, and Ctrl-C must not wait with it.
    /// Zenoh's open blocks the thread that polls it while it waits, so it opens on a task of
    /// its own.
    pub async fn open_unless(&self, shutdown: &mut Shutdown) -> Result<Session> {
        let args = self.clone();
        let opening = tokio::spawn(async move { args.open().await });
        match shutdown.unless(opening).await {
            Some(opened) => opened.map_err(|e| anyhow!("opening the Zenoh session: {e}"))?,
            None => Err(Interrupted("while the Zenoh session was opening").into()),
        }
    }

    pub async fn open(&self) -> Result<Session> {
        let config = self.config()?;
        zenoh::open(config)
            .await
            .map_err(|e| anyhow!("{}", zenoh_words(e)))
            .context(
                "cannot open the Zenoh session: nothing answered at the endpoints to connect to, or \
                 a TLS handshake failed (is the router up and reachable? does it accept this host's \
                 certificate? is the router's certificate valid for the address connected to, and \
                 signed by the CA this host trusts? RUST_LOG=zenoh=debug says which)",
            )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zenoh_errors_lose_their_source_paths_and_debug_forms() {
        let raw = "invalid port value at /root/.cargo/registry/src/index/zenoh-link-commons-1.10.2/src/lib.rs:62.";
        assert_eq!(zenoh_words(raw), "invalid port value");
        let json = "JSON error: Message { msg: \"unknown field `bogus`, expected one of `id`\", location: \
                    Some(Location { line: 1, column: 19 }) } at /r/zenoh-config-1.10.2/src/lib.rs:1484.";
        assert_eq!(
            zenoh_words(json),
            "line 1, column 19: unknown field `bogus`, expected one of `id`"
        );
        assert_eq!(
            zenoh_words("no route to host at the shore"),
            "no route to host at the shore"
        );
    }

    #[test]
    fn endpoints_are_checked_before_zenoh_sees_them() {
        for good in [
            "tcp/127.0.0.1:7447",
            "tcp/[::1]:0",
            "quic/shore.local:7447?iface=eth0",
            "unixsock-stream//tmp/s",
        ] {
            assert!(endpoint("-e", good).is_ok(), "{good}");
        }
        for bad in ["foo", "tcp/127.0.0.1", "udp/127.0.0.1:70000", "tls/host:port"] {
            let e = endpoint("-e", bad).unwrap_err();
            assert!(e.downcast_ref::<BadZenohConfig>().is_some(), "{bad}");
        }
    }
}
