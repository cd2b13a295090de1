//! ROS 2 nodes of another implementation than tcpf's own: hiroz (ZettaScale's ROS 2 over Zenoh in
//! Rust, with the rmw_zenoh key format) subscribes to a lockstep fleet on sim time, and plays
//! vehicle 2 of a realtime fleet whose world simulates vehicle 1. They present a certificate and
//! nothing else, as a stock rmw_zenoh (whose Zenoh has TLS but no user-password authentication)
//! can. The tcpf binary is `$TCPF_BIN` (by default the workspace's release build); each test
//! kills what it started.

use std::path::Path;
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use hiroz::context::{ZContext, ZContextBuilder};
use hiroz::qos::{QosDurability, QosProfile};
use hiroz::Builder;
use hiroz_msgs::builtin_interfaces::Time;
use hiroz_msgs::geometry_msgs::{Point, Pose, PoseWithCovariance, Quaternion, Twist, TwistWithCovariance, Vector3};
use hiroz_msgs::nav_msgs::{Odometry, Path as RosPath};
use hiroz_msgs::rosgraph_msgs::Clock;
use hiroz_msgs::std_msgs::Header;
use serde_json::Value;

#[path = "../../common/fleet.rs"]
// Shared by the interop crates: not every one uses every helper.
#[allow(dead_code)]
mod fleet;
#[path = "../../../tests/common/held.rs"]
mod held;
use fleet::{repo, scratch, spawn, summary, tcpf_bin, telemetry, wait_exit, wait_for};

fn free_endpoint() -> String {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    format!("tls/127.0.0.1:{port}")
}

/// Zenoh's `transport/link/tls` for a client presenting the certificate file of `tcpf credential
/// DIR MISSION` at `path`: its certificate, its key, then the fleet's authority, in PEM.
fn presenting(path: &Path) -> Value {
    use base64::Engine;
    let text = std::fs::read_to_string(path).unwrap();
    let mut pems = Vec::new();
    let mut rest = text.as_str();
    while let Some(at) = rest.find("-----BEGIN ") {
        let label = &rest[at + 11..at + 11 + rest[at + 11..].find("-----").unwrap()];
        let end = format!("-----END {label}-----");
        let stop = rest.find(&end).unwrap() + end.len();
        pems.push(format!("{}\n", &rest[at..stop]));
        rest = &rest[stop..];
    }
    let inline = |pem: &String| base64::engine::general_purpose::STANDARD.encode(pem);
    serde_json::json!({
        "connect_certificate_base64": inline(&pems[0]),
        "connect_private_key_base64": inline(&pems[1]),
        "root_ca_certificate_base64": inline(&pems[2]),
        "enable_mtls": true,
    })
}

fn seconds(t: &Time) -> f64 {
    f64::from(t.sec) + f64::from(t.nanosec) * 1e-9
}

/// A ROS 2 context on domain 7, a client of the router at `endpoint` presenting the certificate
/// file at `pem`.
fn client(endpoint: &str, pem: &str) -> ZContext {
    ZContextBuilder::default()
        .with_domain_id(7)
        .with_mode("client")
        .with_connect_endpoints([endpoint])
        .disable_multicast_scouting()
        .with_json("transport/link/tls", presenting(Path::new(pem)))
        .build()
        .unwrap()
}

/// An odometry as heard: its child frame, stamp (s) and position.
type Heard = (String, f64, f64, f64);

/// A lockstep case (b) with `--ros2 6`, held for one more recorder: a hiroz node subscribes to
/// `/clock` and to both vehicles' odometry, then a recorder's token lets the run start. It hears
/// every tick's time in order and every odometry, stamped with the tick's time and placed as
/// the telemetry says.
#[tokio::test(flavor = "multi_thread")]
async fn a_hiroz_node_on_sim_time_hears_every_tick_and_every_odometry() {
    let dir = scratch("sim-time");
    let out = dir.join("run");
    let mission = repo("configs/paper/b-current.toml");
    let args = [
        "run",
        &mission,
        "--out",
        out.to_str().unwrap(),
        "--ros2",
        "6",
        "--recorders",
        "1",
    ];
    let mut run = spawn(&dir, "run", &args);
    wait_for(&out.join("endpoint"), "tls/", Duration::from_secs(60));
    let ctx = ZContextBuilder::default()
        .with_config_file(out.join("zenoh.json5"))
        .with_domain_id(6)
        .build()
        .unwrap();
    let node = ctx.create_node("hiroz_probe").build().unwrap();
    let clock: Arc<Mutex<Vec<f64>>> = Arc::default();
    let heard = clock.clone();
    let _clock = node
        .create_sub::<Clock>("/clock")
        .build_with_callback(move |c: Clock| heard.lock().unwrap().push(seconds(&c.clock)))
        .unwrap();
    let odometry: Arc<Mutex<Vec<Heard>>> = Arc::default();
    let mut subscriptions = Vec::new();
    for id in [1, 2] {
        let heard = odometry.clone();
        let sub = node
            .create_sub::<Odometry>(&format!("/tcpf/vehicle_{id}/odom"))
            .build_with_callback(move |o: Odometry| {
                let p = &o.pose.pose.position;
                heard
                    .lock()
                    .unwrap()
                    .push((o.child_frame_id.clone(), seconds(&o.header.stamp), p.x, p.y));
            })
            .unwrap();
        subscriptions.push(sub);
    }
    // The recorder the run waits for: once it is here, the first tick comes.
    let session = zenoh::open(zenoh::Config::from_file(out.join("zenoh.json5")).unwrap())
        .await
        .unwrap();
    let token = session
        .liveliness()
        .declare_token("tcpf/paper-b-current/alive/record/78")
        .await
        .unwrap();
    assert!(
        wait_exit(&mut run, Duration::from_secs(120)).success(),
        "{}",
        std::fs::read_to_string(dir.join("run.log")).unwrap()
    );
    token.undeclare().await.unwrap();
    session.close().await.unwrap();

    let rows = telemetry(&out);
    let ticks = rows.iter().filter(|r| r[2] == "1").count();
    // The last samples may still be on their way when the run has exited: wait until a /clock
    // per tick and an odometry per row have come (or 10 s, after which the assertions below say
    // what is missing).
    let deadline = Instant::now() + Duration::from_secs(10);
    let all_here = || clock.lock().unwrap().len() >= ticks && odometry.lock().unwrap().len() >= rows.len();
    while !all_here() && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let clock = clock.lock().unwrap().clone();
    assert_eq!(clock.len(), ticks, "a /clock sample per tick");
    for (k, t) in clock.iter().enumerate() {
        assert!((t - k as f64 * 0.01).abs() < 1e-9, "tick {k} at {t}");
    }
    let odometry = odometry.lock().unwrap().clone();
    let received = odometry.len() as f64 / rows.len() as f64;
    assert!(
        received >= 0.99,
        "{} of {} odometry samples ({received:.4})",
        odometry.len(),
        rows.len()
    );
    for row in &rows {
        let (t, x, y): (f64, f64, f64) = (
            row[1].parse().unwrap(),
            row[3].parse().unwrap(),
            row[4].parse().unwrap(),
        );
        let frame = format!("vehicle_{}", row[2]);
        let o = odometry.iter().find(|o| o.0 == frame && (o.1 - t).abs() < 1e-9);
        let o = o.unwrap_or_else(|| panic!("no odometry of {frame} stamped {t}"));
        assert_eq!((o.2, o.3), (x, y), "{frame} at t = {t}");
        assert!(
            clock.iter().any(|c| (c - o.1).abs() < 1e-9),
            "stamped with a tick of /clock"
        );
    }
}

/// What the hiroz node playing a vehicle knows: its pose, and the command it follows.
#[derive(Clone, Copy, Default)]
struct Body {
    x: f64,
    y: f64,
    yaw: f64,
    v: f64,
    r: f64,
}

/// Plays vehicle `id` in namespace `/tcpf` until `stop`: its start from the planned path
/// (transient local), then every `period` of wall time the kinematics of docs/MODEL.md §2 over
/// `period × time_scale` of simulated time in `current`, its odometry stamped with the wall clock.
/// Returns the commands it heard, the odometry it published and the copies of its path it was
/// given after the first (a transient-local subscriber asks twice: at its start, and when it
/// sees the publisher's token).
fn play(
    ctx: &ZContext,
    id: u32,
    time_scale: f64,
    period: f64,
    current: [f64; 2],
    stop: &Mutex<bool>,
) -> (u64, u64, u64) {
    let node = ctx.create_node(format!("hiroz_vehicle_{id}")).build().unwrap();
    let latched = QosProfile {
        durability: QosDurability::TransientLocal,
        ..Default::default()
    };
    let path = node
        .create_sub::<RosPath>(&format!("/tcpf/vehicle_{id}/path"))
        .with_qos(latched)
        .build()
        .unwrap();
    let first = path
        .recv_timeout(Duration::from_secs(60))
        .expect("the planned path")
        .poses[0]
        .pose
        .clone();
    let q = &first.orientation;
    let body = Arc::new(Mutex::new(Body {
        x: first.position.x,
        y: first.position.y,
        yaw: 2.0 * q.z.atan2(q.w),
        ..Body::default()
    }));
    let commands = Arc::new(Mutex::new(0u64));
    let (steer, heard) = (body.clone(), commands.clone());
    let _commands = node
        .create_sub::<Twist>(&format!("/tcpf/vehicle_{id}/cmd"))
        .build_with_callback(move |t: Twist| {
            let mut b = steer.lock().unwrap();
            (b.v, b.r) = (t.linear.x, t.angular.z);
            *heard.lock().unwrap() += 1;
        })
        .unwrap();
    let odometry = node
        .create_pub::<Odometry>(&format!("/tcpf/vehicle_{id}/odom"))
        .build()
        .unwrap();
    let mut published = 0;
    let mut last = std::time::SystemTime::now();
    while !*stop.lock().unwrap() {
        let now = std::time::SystemTime::now();
        let h = now.duration_since(last).unwrap().as_secs_f64() * time_scale;
        last = now;
        let b = {
            let mut b = body.lock().unwrap();
            // Exact for v and r held over the step: ψ is linear in time.
            let half = 0.5 * b.r * h;
            let sinc = if half == 0.0 { 1.0 } else { half.sin() / half };
            let mid = b.yaw + half;
            b.x += h * (b.v * sinc * mid.cos() + current[0]);
            b.y += h * (b.v * sinc * mid.sin() + current[1]);
            b.yaw = (b.yaw + b.r * h).sin().atan2((b.yaw + b.r * h).cos());
            *b
        };
        let stamp = now.duration_since(std::time::UNIX_EPOCH).unwrap();
        let message = Odometry {
            header: Header {
                stamp: Time {
                    sec: stamp.as_secs() as i32,
                    nanosec: stamp.subsec_nanos(),
                },
                frame_id: "map".into(),
            },
            child_frame_id: format!("vehicle_{id}"),
            pose: PoseWithCovariance {
                pose: Pose {
                    position: Point { x: b.x, y: b.y, z: 0.0 },
                    orientation: Quaternion {
                        x: 0.0,
                        y: 0.0,
                        z: (b.yaw / 2.0).sin(),
                        w: (b.yaw / 2.0).cos(),
                    },
                },
                ..Default::default()
            },
            twist: TwistWithCovariance {
                twist: Twist {
                    linear: Vector3 { x: b.v, y: 0.0, z: 0.0 },
                    angular: Vector3 { x: 0.0, y: 0.0, z: b.r },
                },
                ..Default::default()
            },
        };
        odometry.publish(&message).unwrap();
        published += 1;
        let spent = std::time::SystemTime::now().duration_since(now).unwrap_or_default();
        std::thread::sleep(Duration::from_secs_f64(period).saturating_sub(spent));
    }
    let heard = *commands.lock().unwrap();
    let mut copies = 0;
    while path.recv_timeout(Duration::from_millis(10)).is_ok() {
        copies += 1;
    }
    (heard, published, copies)
}

/// Case (b) in realtime at time scale 5, by hand: the world simulates vehicle 1 (`--vehicles 1`)
/// and a hiroz node plays vehicle 2. Both arrive, with a coordination error under 1 s, and the
/// summary names vehicle 2 as played by a ROS 2 node.
#[tokio::test(flavor = "multi_thread")]
async fn a_hiroz_node_plays_vehicle_2_beside_a_world_that_simulates_vehicle_1() {
    let dir = scratch("plays");
    let mission = repo("configs/paper/b-current.toml");
    // A certificate per role, the ROS 2 graph's rules among the router's.
    let fleet = dir.join("fleet");
    let made = Command::new(tcpf_bin())
        .args(["credential", fleet.to_str().unwrap(), &mission, "--ros2", "7"])
        .output()
        .unwrap();
    assert!(made.status.success(), "{made:?}");
    let own = |identity: &str| fleet.join(format!("{identity}.pem")).display().to_string();
    let endpoint = free_endpoint();
    let e = endpoint.as_str();
    let clock = ["--clock", "realtime", "--time-scale", "5"];
    let role = |name: &str, args: &[&str]| {
        let credential = own(name);
        spawn(&dir, name, &[args, &clock, &["--credential", &credential]].concat())
    };
    let _router = spawn(
        &dir,
        "router",
        &["router", "--credential", fleet.to_str().unwrap(), "-l", e],
    );
    let _planner = role("planner", &["planner", &mission, "-e", e]);
    let _world = role(
        "world",
        &[
            "world",
            &mission,
            "-e",
            e,
            "--recorders",
            "1",
            "--vehicles",
            "1",
            "--ros2",
            "7",
        ],
    );
    let _agent_1 = role("agent-1", &["agent", &mission, "--id", "1", "-e", e, "--ros2", "7"]);
    let _agent_2 = role("agent-2", &["agent", &mission, "--id", "2", "-e", e, "--ros2", "7"]);
    // The node connects once the router listens.
    let address = endpoint.trim_start_matches("tls/").to_string();
    let deadline = Instant::now() + Duration::from_secs(30);
    while std::net::TcpStream::connect(&address).is_err() {
        assert!(Instant::now() < deadline, "the router does not listen at {address}");
        std::thread::sleep(Duration::from_millis(20));
    }
    let ctx = client(e, &own("vehicle-2"));
    let stop = Arc::new(Mutex::new(false));
    let playing = {
        let stop = stop.clone();
        // Case (b)'s current: 0.1 m/s towards π. Twice a control period (0.01 s of the fleet's
        // time, 0.002 s of the wall's at 5x), as a driver faster than the fleet publishes: two
        // odometries in one tick, and one state of it.
        let current = [0.1 * std::f64::consts::PI.cos(), 0.1 * std::f64::consts::PI.sin()];
        std::thread::spawn(move || play(&ctx, 2, 5.0, 0.001, current, &stop))
    };
    // A late joiner: a transient-local subscriber that comes once the run is under way, as an
    // observer, is given vehicle 1's path once, though it asks twice.
    let late = {
        let ctx = client(e, &own("observer"));
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_secs(3));
            let node = ctx.create_node("hiroz_late").build().unwrap();
            let latched = QosProfile {
                durability: QosDurability::TransientLocal,
                ..Default::default()
            };
            let path = node
                .create_sub::<RosPath>("/tcpf/vehicle_1/path")
                .with_qos(latched)
                .build()
                .unwrap();
            let mut given = 0;
            while path.recv_timeout(Duration::from_secs(2)).is_ok() {
                given += 1;
            }
            given
        })
    };
    let out = dir.join("run");
    let mut record = role(
        "recorder",
        &["record", &mission, "-e", e, "--out", out.to_str().unwrap()],
    );
    let status = wait_exit(&mut record, Duration::from_secs(120));
    assert_eq!(
        late.join().unwrap(),
        1,
        "copies of vehicle 1's path given to a late joiner"
    );
    *stop.lock().unwrap() = true;
    let (commands, published, copies) = playing.join().unwrap();
    assert_eq!(copies, 0, "the path again, {copies} time(s), after the first");
    let log = |name: &str| std::fs::read_to_string(dir.join(format!("{name}.log"))).unwrap_or_default();
    assert!(status.success(), "record: {}\nworld: {}", log("recorder"), log("world"));
    let s = summary(&out);
    let arrivals: Vec<f64> = s["vehicles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["arrival_time"].as_f64().unwrap())
        .collect();
    let error = s["max_coordination_error"].as_f64().unwrap();
    // An agent starved beside a CPU hog skips periods, and the world holds its last command, whose
    // γ is of the tick it was made for, until the next one comes (one run: agent 2 skipped 533
    // periods, the world held a γ 5 s behind vehicle 1's for a tick, and both arrived 1.4 ms apart).
    let held = held::held_gamma_s(&s);
    assert!(
        error < 1.0 + held,
        "coordination error {error:.3} s ({held:.2} s of periods skipped by an agent); arrivals {arrivals:?}\n{}",
        s["timing"]
    );
    assert!((arrivals[0] - arrivals[1]).abs() < 1.0, "arrivals {arrivals:?}");
    assert_eq!(s["vehicles"][1]["played_by"], "ros2", "{}", s["vehicles"]);
    assert!(s["vehicles"][0].get("played_by").is_none(), "{}", s["vehicles"]);
    assert_eq!(s["rejected_messages"], 0, "{}", s["rejections"]);
    assert!(
        commands > 1000 && published > 1000,
        "{commands} commands heard, {published} odometry published"
    );
    eprintln!(
        "hiroz played vehicle 2: {commands} commands heard, {published} odometry published; arrivals {arrivals:?}, coordination error {error:.3} s"
    );
}
