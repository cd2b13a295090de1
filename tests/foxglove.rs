//! Runs open in Foxglove: `run.mcap` read back by an independent reader (Python's `mcap`
//! package), and `--live` served over Foxglove's WebSocket protocol to a client that connects
//! while the fleet runs.

use std::net::TcpListener;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use serde_json::Value;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;
use tokio_tungstenite::tungstenite::Message;

mod common;
use common::{fleet, kill, paper, scratch, Reaper};

const READ_MCAP: &str = r##"
import json, sys
from collections import Counter
from mcap.reader import make_reader
with open(sys.argv[1], "rb") as f:
    reader = make_reader(f)
    counts, schemas, times = Counter(), {}, {}
    for schema, channel, message in reader.iter_messages():
        counts[channel.topic] += 1
        schemas[channel.topic] = schema.name if schema else None
        times.setdefault(channel.topic, []).append(message.log_time)
out = {t: {"count": counts[t], "schema": schemas[t], "first": times[t][0], "last": times[t][-1]} for t in counts}
with open(sys.argv[1], "rb") as f:
    reader = make_reader(f)
    out["#metadata"] = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    out["#attachments"] = {a.name: a.data.decode() for a in reader.iter_attachments()}
print(json.dumps(out))
"##;

#[test]
fn run_mcap_holds_a_pose_per_vehicle_and_tick_in_foxglove_schemas() {
    let _fleet = fleet();
    let dir = scratch("mcap");
    let unix = || {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_secs_f64()
    };
    let started = unix();
    let status = Command::new(env!("CARGO_BIN_EXE_tcpf"))
        .args(["run", &paper("b-current"), "--out", dir.to_str().unwrap()])
        .stdout(Stdio::null())
        .status()
        .unwrap();
    let finished = unix();
    assert!(status.success());
    let out = Command::new("python3")
        .args(["-c", READ_MCAP, dir.join("run.mcap").to_str().unwrap()])
        .output()
        .expect("python3 runs");
    assert!(
        out.status.success(),
        "reading run.mcap with Python's mcap package (pip install mcap; scripts/test installs it): {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let channels: Value = serde_json::from_slice(&out.stdout).unwrap();
    let summary: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    let ticks = summary["ticks"].as_u64().unwrap();
    let dt = 0.01;
    for id in [1, 2] {
        let pose = &channels[format!("/vehicle/{id}/pose")];
        assert_eq!(pose["count"], ticks, "one pose per tick: {channels}");
        assert_eq!(pose["schema"], "foxglove.PoseInFrame");
        // Stamped with the fleet's time: the run's start on the wall clock, plus simulated time.
        let first = pose["first"].as_u64().unwrap() as f64 * 1e-9;
        assert!(
            (started..finished).contains(&first),
            "t = 0 at {first}, not in the run's [{started}, {finished})"
        );
        let last = pose["last"].as_u64().unwrap() as f64 * 1e-9;
        assert!(
            (last - first - (ticks - 1) as f64 * dt).abs() < 1e-6,
            "the last tick's time, {last} s"
        );
        assert_eq!(
            channels[format!("/vehicle/{id}/path")]["schema"],
            "foxglove.PosesInFrame"
        );
        assert_eq!(channels[format!("/vehicle/{id}/coordination")]["count"], ticks);
    }
    let sent: u64 = summary["links"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["sent"].as_u64().unwrap())
        .sum();
    assert_eq!(channels["/links"]["count"], sent, "one link event per γ message");
    let metadata = &channels["#metadata"]["tcpf"];
    assert!(
        metadata["frames"].as_str().unwrap().starts_with("ENU (x east, y north"),
        "{metadata}"
    );
    let mission_as_run = std::fs::read_to_string(dir.join("mission.toml")).unwrap();
    let digest = format!("{:016x}", tcpf_core::mission::digest_of(&mission_as_run));
    assert_eq!(metadata["mission_digest"], digest.as_str(), "{metadata}");
    assert_eq!(metadata["tcpf_version"], env!("CARGO_PKG_VERSION"), "{metadata}");
    assert!(metadata["command"].as_str().unwrap().contains(" run "), "{metadata}");
    let epoch: f64 = metadata["epoch_unix_s"].as_str().unwrap().parse().unwrap();
    assert!((epoch - started).abs() < finished - started + 1.0, "{metadata}");
    let mission = channels["#attachments"]["mission.toml"].as_str().unwrap();
    assert_eq!(mission, std::fs::read_to_string(dir.join("mission.toml")).unwrap());
}

/// A mixed fleet: the dynamic vehicle's velocity and thrusters on a channel of its own, a tick
/// each, and none for the kinematic one.
#[test]
fn run_mcap_holds_a_dynamic_vehicles_thrusters() {
    let _fleet = fleet();
    let dir = scratch("mcap-dynamic");
    let status = Command::new(env!("CARGO_BIN_EXE_tcpf"))
        .args([
            "run",
            &paper("b-current"),
            "--in-process",
            "--out",
            dir.to_str().unwrap(),
        ])
        .args(["--set", "vehicle.2.vehicle_model={ kind = \"medusa\" }"])
        .stdout(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    let out = Command::new("python3")
        .args(["-c", READ_MCAP, dir.join("run.mcap").to_str().unwrap()])
        .output()
        .expect("python3 runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let channels: Value = serde_json::from_slice(&out.stdout).unwrap();
    let summary: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    let dynamics = &channels["/vehicle/2/dynamics"];
    assert_eq!(dynamics["count"], summary["ticks"], "{channels}");
    assert_eq!(dynamics["schema"], "tcpf.Dynamics");
    assert!(
        channels.get("/vehicle/1/dynamics").is_none(),
        "vehicle 1 is kinematic: {channels}"
    );
    let thrusters = &summary["vehicles"][1]["thrusters"];
    assert!(thrusters["max_command"].as_f64().unwrap() > 30.0, "{summary}");
    assert!(summary["vehicles"][0].get("thrusters").is_none(), "{summary}");
}

/// Case (b) on the wall clock at `scale` into `dir`, served live on `port`: a lockstep run can
/// end before a client has subscribed.
fn live_run(dir: &std::path::Path, port: u16, scale: &str) -> Reaper {
    Reaper(
        Command::new(env!("CARGO_BIN_EXE_tcpf"))
            .args(["run", &paper("b-current"), "--out", dir.to_str().unwrap()])
            .args(["--live", &format!("127.0.0.1:{port}")])
            .args(["--clock", "realtime", "--time-scale", scale])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    )
}

/// A client's opening request to the live view on `port`, as Foxglove's older clients make it.
fn foxglove_request(port: u16) -> tokio_tungstenite::tungstenite::handshake::client::Request {
    let mut request = format!("ws://127.0.0.1:{port}").into_client_request().unwrap();
    request
        .headers_mut()
        .insert("Sec-WebSocket-Protocol", "foxglove.websocket.v1".parse().unwrap());
    request
}

type Socket = tokio_tungstenite::WebSocketStream<tokio::net::TcpStream>;

/// One client of the live view on `port`: its socket and the server's response, or what failed.
async fn join(port: u16) -> Result<(Socket, tokio_tungstenite::tungstenite::handshake::client::Response), String> {
    let stream = tokio::net::TcpStream::connect(("127.0.0.1", port))
        .await
        .map_err(|e| e.to_string())?;
    tokio_tungstenite::client_async(foxglove_request(port), stream)
        .await
        .map_err(|e| e.to_string())
}

/// The first client of the live view of `run`, once it serves (a minute at most).
async fn first_client(
    run: &mut Reaper,
    port: u16,
) -> (Socket, tokio_tungstenite::tungstenite::handshake::client::Response) {
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        match join(port).await {
            Ok(joined) => return joined,
            Err(e) => {
                assert!(Instant::now() < deadline, "no live server on port {port}: {e}");
                assert!(
                    run.0.try_wait().unwrap().is_none(),
                    "the run ended before a client could join"
                );
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        }
    }
}

/// The live view serves at most 8 clients and closes the connection of one that sends more
/// than 64 KiB at once (30 clients each holding a 64 MB partial message took the launcher to
/// 2.3 GB, and 38 under a 4 GB limit aborted it mid-run without a summary).
#[tokio::test(flavor = "multi_thread")]
async fn the_live_view_bounds_its_clients_and_what_they_send() {
    let _fleet = fleet();
    let dir = scratch("live-bounds");
    let port = free_port();
    // 55 s of simulated time in about 11 s: long enough for every client below.
    let mut run = live_run(&dir, port, "5");
    let connect = || async { join(port).await.map(|(socket, _)| socket) };
    let mut served = vec![first_client(&mut run, port).await.0];
    for _ in 1..8 {
        served.push(connect().await.expect("up to 8 clients are served"));
    }
    assert!(connect().await.is_err(), "a ninth client is refused");
    // One of them sends a message of a megabyte: its connection is closed.
    let big = "x".repeat(1 << 20);
    let mut greedy = served.pop().unwrap();
    let _ = greedy.send(Message::text(big)).await;
    let closed = tokio::time::timeout(Duration::from_secs(30), async {
        loop {
            match greedy.next().await {
                None | Some(Err(_)) | Some(Ok(Message::Close(_))) => return true,
                Some(Ok(_)) => {}
            }
        }
    })
    .await;
    assert_eq!(closed, Ok(true), "the connection of a client sending 1 MB is closed");
    // Its place is free again.
    let deadline = Instant::now() + Duration::from_secs(10);
    while connect().await.is_err() {
        assert!(Instant::now() < deadline, "the closed client's place is not freed");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    drop(served);
    let status = tokio::task::spawn_blocking(move || run.0.wait().unwrap())
        .await
        .unwrap();
    assert!(status.success(), "the run completes beside them");
}

/// Connections that never finish their WebSocket handshake, and clients that never read, hold
/// no place for long: 8 clients that take nothing and 200 raw TCP connections are dropped
/// within seconds (5 s for a handshake, two pings unanswered), and a genuine viewer is served.
#[tokio::test(flavor = "multi_thread")]
async fn the_live_view_drops_connections_that_never_shake_hands_and_clients_that_never_read() {
    let _fleet = fleet();
    let dir = scratch("live-stalled");
    let port = free_port();
    // In real time: 55 s, stopped once the viewer is served.
    let mut run = live_run(&dir, port, "1");
    drop(first_client(&mut run, port).await);
    let mut deaf = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(30);
    while deaf.len() < 8 {
        assert!(Instant::now() < deadline, "8 clients served");
        match join(port).await {
            Ok((socket, _)) => deaf.push(socket),
            Err(_) => tokio::time::sleep(Duration::from_millis(50)).await,
        }
    }
    let mut mute = Vec::new();
    for _ in 0..200 {
        if let Ok(stream) = tokio::net::TcpStream::connect(("127.0.0.1", port)).await {
            mute.push(stream);
        }
    }
    assert!(join(port).await.is_err(), "every place is held");
    let started = Instant::now();
    let mut viewer = loop {
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "no place freed for a viewer"
        );
        match join(port).await {
            Ok((socket, _)) => break socket,
            Err(_) => tokio::time::sleep(Duration::from_millis(200)).await,
        }
    };
    eprintln!(
        "a viewer served {:.1} s after the places were taken",
        started.elapsed().as_secs_f64()
    );
    let spoke = tokio::time::timeout(Duration::from_secs(10), viewer.next()).await;
    assert!(
        matches!(spoke, Ok(Some(Ok(Message::Text(_))))),
        "the viewer is told what the server serves: {spoke:?}"
    );
    kill("-INT", run.0.id());
    drop((deaf, mute));
    let status = tokio::task::spawn_blocking(move || run.0.wait().unwrap())
        .await
        .unwrap();
    assert_eq!(status.code(), Some(130), "the run stops on Ctrl-C");
}

/// A port nobody listens on now.
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

#[tokio::test(flavor = "multi_thread")]
async fn live_serves_the_fleet_over_foxglove_websocket() {
    let _fleet = fleet();
    let dir = scratch("live");
    let port = free_port();
    // In real time: the run lasts its 55 s, far longer than a client takes to join, subscribe
    // and see 10 poses on any machine, and is stopped (Ctrl-C) once it has (at x5 a loaded
    // machine once let the run end first).
    let mut run = live_run(&dir, port, "1");
    let (mut socket, response) = first_client(&mut run, port).await;
    assert_eq!(response.headers()["Sec-WebSocket-Protocol"], "foxglove.websocket.v1");

    let mut channels: Vec<Value> = Vec::new();
    let mut server_info = false;
    let mut subscribed = false;
    let (mut poses, mut paths) = (0, 0);
    // The path was sent once, before any client: it comes as the subscription is made.
    let (mut first_pose, mut latest_pose, mut path_time) = (u64::MAX, 0, None);
    while poses < 10 || paths == 0 {
        let message = tokio::time::timeout(Duration::from_secs(30), socket.next())
            .await
            .expect("the server speaks within 30 s")
            .expect("the connection stays open")
            .unwrap();
        match message {
            Message::Text(text) => {
                let op: Value = serde_json::from_str(&text).unwrap();
                match op["op"].as_str() {
                    Some("serverInfo") => server_info = true,
                    Some("advertise") => channels.extend(op["channels"].as_array().unwrap().iter().cloned()),
                    _ => {}
                }
                let id = |topic: &str| channels.iter().find(|c| c["topic"] == topic).map(|c| c["id"].clone());
                if let (false, Some(pose), Some(path)) = (subscribed, id("/vehicle/1/pose"), id("/vehicle/1/path")) {
                    let subscribe = serde_json::json!({"op": "subscribe", "subscriptions": [
                        {"id": 7, "channelId": pose}, {"id": 8, "channelId": path},
                    ]});
                    socket.send(Message::text(subscribe.to_string())).await.unwrap();
                    subscribed = true;
                }
            }
            // Message data: opcode 1, u32 subscription id, u64 log time, payload.
            Message::Binary(data) if data.first() == Some(&1) => {
                let log_time = u64::from_le_bytes(data[5..13].try_into().unwrap());
                match u32::from_le_bytes(data[1..5].try_into().unwrap()) {
                    7 => {
                        poses += 1;
                        first_pose = first_pose.min(log_time);
                        latest_pose = latest_pose.max(log_time);
                    }
                    8 => {
                        path_time = Some(log_time);
                        assert!(data.len() > 1000, "a path of many poses: {} bytes", data.len());
                        paths += 1;
                    }
                    other => panic!("a message for subscription {other}"),
                }
            }
            _ => {}
        }
    }
    assert!(server_info, "serverInfo first");
    // The path is of the fleet's t = 0, its epoch on the wall clock: no later than any pose, and
    // of today (not 1970).
    let path_time = path_time.unwrap();
    assert!(
        path_time <= first_pose,
        "the path at {path_time} ns, a pose at {first_pose} ns"
    );
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .as_secs_f64();
    assert!(
        (path_time as f64 * 1e-9 - now).abs() < 3600.0,
        "the path at {path_time} ns"
    );
    let topics: Vec<&str> = channels.iter().map(|c| c["topic"].as_str().unwrap()).collect();
    for topic in [
        "/vehicle/1/pose",
        "/vehicle/2/pose",
        "/vehicle/1/path",
        "/vehicle/1/coordination",
        "/links",
    ] {
        assert!(topics.contains(&topic), "{topic} advertised: {topics:?}");
    }
    let pose = channels.iter().find(|c| c["topic"] == "/vehicle/2/pose").unwrap();
    assert_eq!(pose["schemaName"], "foxglove.PoseInFrame");
    // To the end, as the run ends on Ctrl-C: the last tick's pose, then a Close frame. The last
    // may have come already: the run can end within the period the signal took to arrive.
    kill("-INT", run.0.id());
    let (mut last, mut closed) = (latest_pose, false);
    while let Ok(Some(Ok(message))) = tokio::time::timeout(Duration::from_secs(30), socket.next()).await {
        match message {
            Message::Binary(data) if data[1..5] == 7u32.to_le_bytes() => {
                last = u64::from_le_bytes(data[5..13].try_into().unwrap());
            }
            Message::Close(_) => closed = true,
            _ => {}
        }
    }
    let status = run.0.wait().unwrap();
    assert_eq!(
        status.code(),
        Some(130),
        "the run stops on Ctrl-C with a client attached"
    );
    assert!(closed, "the server closes the connection with a Close frame");
    // The wall clock's recorder may write a row a period past the world's end (an arrival is
    // stamped at most a period late): the view ends where telemetry.csv does.
    let telemetry = std::fs::read_to_string(dir.join("telemetry.csv")).unwrap();
    let end: f64 = telemetry
        .lines()
        .skip(1)
        .map(|row| row.split(',').collect::<Vec<_>>())
        .filter(|row| row[2] == "1")
        .last()
        .map(|row| row[1].parse().unwrap())
        .expect("vehicle 1 recorded");
    // Counted from the path's time, the fleet's t = 0 (nanoseconds of Unix time: 1 µs apart at
    // most from rounding each).
    let t = (last - path_time) as f64 * 1e-9;
    assert!(
        (t - end).abs() < 2e-6,
        "the last pose sent is of t = {t} s, vehicle 1's last row of t = {end} s"
    );
}

/// `--live` on port 0 serves on a port of the system's choosing, and says which.
#[test]
fn the_live_view_says_where_it_serves() {
    let _fleet = fleet();
    let dir = scratch("live-port");
    let o = Command::new(env!("CARGO_BIN_EXE_tcpf"))
        .args([
            "run",
            &paper("a-nominal"),
            "--in-process",
            "--out",
            dir.to_str().unwrap(),
        ])
        .args(["--live", "127.0.0.1:0"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let port = stderr
        .split("live view for Foxglove on ws://127.0.0.1:")
        .nth(1)
        .and_then(|rest| rest.lines().next()?.trim().parse::<u16>().ok())
        .unwrap_or_else(|| panic!("no address: {stderr}"));
    assert_ne!(port, 0);
}
