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

impl ZenohArgs {
    /// Without a config file: peer mode on 127.0.0.1, no multicast scouting, an ephemeral port,
    /// so that nothing needs installing and runs never meet by accident.
    pub fn config(&self) -> Result<Config> {
        let mut config = match &self.config {
            Some(path) => Config::from_file(path).map_err(|e| anyhow!("{}: bad Zenoh config: {e}", path.display()))?,
            None => {
                let mut c = Config::default();
                let set =
                    |c: &mut Config, k: &str, v: &str| c.insert_json5(k, v).map_err(|e| anyhow!("zenoh {k}: {e}"));
                set(&mut c, "mode", "\"peer\"")?;
                set(&mut c, "scouting/multicast/enabled", "false")?;
                set(&mut c, "listen/endpoints", "[\"tcp/127.0.0.1:0\"]")?;
                c
            }
        };
        if let Some(mode) = &self.mode {
            if !["peer", "client", "router"].contains(&mode.as_str()) {
                return Err(anyhow!("--mode {mode}: expected peer, client or router"));
            }
            config
                .insert_json5("mode", &format!("\"{mode}\""))
                .map_err(|e| anyhow!("--mode: {e}"))?;
        }
        if !self.connect.is_empty() {
            config
                .insert_json5("connect/endpoints", &json_list(&self.connect))
                .map_err(|e| anyhow!("--connect: {e}"))?;
        }
        if !self.listen.is_empty() {
            config
                .insert_json5("listen/endpoints", &json_list(&self.listen))
                .map_err(|e| anyhow!("--listen: {e}"))?;
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
        zenoh::open(config).await.map_err(|e| anyhow!("{e}")).context(
            "cannot open the Zenoh session: nothing answered at the endpoints to connect to, or \
                 a TLS handshake failed (is the router up and reachable? does it accept this host's \
                 certificate? is the router's certificate valid for the address connected to, and \
                 signed by the CA this host trusts? RUST_LOG=zenoh=debug says which)",
        )
    }
}
