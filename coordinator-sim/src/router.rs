//! `tcpf router`: a Zenoh router and nothing else, for a testbed's shore host. Every role of the
//! fleet is its client; access control, when configured, is enforced here (docs/TESTBED.md).

use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;

use crate::error::{failed, Result};

/// Routes until SIGINT, SIGTERM or SIGHUP. Router mode unless the options say otherwise.
pub async fn run(zenoh: &ZenohArgs) -> Result<()> {
    let mut shutdown = Shutdown::new()?;
    let zenoh = ZenohArgs {
        mode: zenoh.mode.clone().or_else(|| Some("router".into())),
        ..zenoh.clone()
    };
    let config = zenoh.config()?;
    tcpf_bus::session::warn_if_open(&config);
    let session = zenoh::open(config)
        .await
        .map_err(|e| failed!("cannot open the Zenoh router: {}", tcpf_bus::session::zenoh_words(e)))?;
    // The locators it got, not the endpoints it was given: a port 0 becomes the one bound, an
    // unspecified address the host's.
    let listening: Vec<String> = session.info().locators().await.iter().map(|l| l.to_string()).collect();
    tracing::info!("router {} listening on {}", session.zid(), listening.join(", "));
    shutdown.recv().await;
    tracing::info!("router: stopping");
    Ok(session.close().await.map_err(|e| failed!("closing the router: {e}"))?)
}
