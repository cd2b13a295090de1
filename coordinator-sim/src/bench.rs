//! `tcpf bench`: how a lockstep tick compares with a raw Zenoh round trip between two processes,
//! both measured in the same invocation (this machine is shared and noisy: only the ratio means
//! something).

use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

use anyhow::{anyhow, Context, Result};
use tcpf_bus::keys::{Keys, Role};
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::typed::{presence, subscribe, Outlet, Rejected};
use tcpf_core::msg::{Gamma, Sample, PROTOCOL_VERSION};
use tokio::process::Command;

const PING: &str = "tcpf/bench/ping";
const PONG: &str = "tcpf/bench/pong";

fn probe(tick: u64) -> Gamma {
    Gamma {
        version: PROTOCOL_VERSION,
        tick,
        from: 0,
        sample: Some(Sample {
            t: tick as f64,
            gamma: tick as f64,
            gamma_dot: 1.0,
            position: [0.0, 0.0],
        }),
    }
}

/// The echo side: answers every ping with a pong of the same payload until `count` echoes.
pub async fn pong(zenoh: &ZenohArgs, count: u64) -> Result<()> {
    let session = zenoh.open().await?;
    let rejected = Rejected::default();
    let (_sub, mut pings) = subscribe::<Gamma>(&session, PING, &rejected).await?;
    let out = Outlet::new(&session, PONG.into()).await?;
    let token = Keys::new("bench").alive(Role::Agent, 0);
    let _token = session
        .liveliness()
        .declare_token(token)
        .await
        .map_err(|e| anyhow!("{e}"))?;
    for _ in 0..count {
        let Some(ping) = pings.recv().await else { break };
        out.put(&ping.message).await?;
    }
    let _ = session.close().await;
    Ok(())
}

/// Round-trip times to a `tcpf pong` child on a loopback port, sorted.
pub async fn ping(exe: &Path, count: u64) -> Result<Vec<Duration>> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")?.local_addr()?.port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let session = ZenohArgs {
        listen: vec![endpoint.clone()],
        ..ZenohArgs::default()
    }
    .open()
    .await?;
    let rejected = Rejected::default();
    let (_sub, mut pongs) = subscribe::<Gamma>(&session, PONG, &rejected).await?;
    let (_alive, mut alive) = presence(&session, &Keys::new("bench")).await?;
    let out = Outlet::new(&session, PING.into()).await?;
    let mut child = Command::new(exe)
        .args(["pong", "--count", &(count + 100).to_string(), "-e", &endpoint])
        .stdout(Stdio::null())
        .kill_on_drop(true)
        .spawn()
        .context("cannot start tcpf pong")?;
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    while tokio::time::timeout_at(deadline, alive.recv())
        .await
        .map_err(|_| anyhow!("pong never came up"))?
        .is_none_or(|p| !p.alive)
    {}
    let mut times = Vec::with_capacity(count as usize);
    for k in 0..count + 100 {
        let start = Instant::now();
        out.put(&probe(k)).await?;
        loop {
            let p = tokio::time::timeout(Duration::from_secs(5), pongs.recv())
                .await
                .map_err(|_| anyhow!("no pong"))?;
            if p.is_some_and(|p| p.message.tick == k) {
                break;
            }
        }
        // The first hundred warm the route up.
        if k >= 100 {
            times.push(start.elapsed());
        }
    }
    let _ = child.wait().await;
    let _ = session.close().await;
    times.sort_unstable();
    Ok(times)
}
