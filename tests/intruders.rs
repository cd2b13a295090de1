//! Other processes on the bus of a running fleet: one without a certificate of the run (an outsider
//! that found the port); ones holding the certificate of a role an attacker would most
//! plausibly hold (a recorder's, an observer's, another vehicle's agent's), whose forgeries the
//! world's access rules drop; and ones holding the very role's they forge for, which the fleet's
//! own checks must catch. None may change a lockstep run's bits without the run
//! saying so; what an insider sends is refused, counted by kind, and logged as counts.

use std::collections::BTreeMap;
use std::net::TcpStream;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tcpf_core::msg::{Arrival, Command, End, Gamma, State, PROTOCOL_VERSION};
use zenoh::qos::CongestionControl;

mod common;
use common::{
    assert_none_left, assert_same_run, descendants, fleet, paper, run_in_process, scratch, summary,
    wait_until_simulated, Launch,
};

const MISSION: &str = "paper-b-current";
// About 4 s of lockstep ticks here, so that the flood is sent whole while the run lasts.
const SLOWER: [&str; 2] = ["--set", "mission.control_period=0.002"];

fn key(rest: &str) -> String {
    format!("tcpf/{MISSION}/{rest}")
}

fn endpoint(launch: &Launch) -> String {
    launch.wait_for("endpoint", "tls/");
    std::fs::read_to_string(launch.out.join("endpoint"))
        .unwrap()
        .trim()
        .to_string()
}

/// A peer on loopback that connects to `endpoint`, with nothing else: no credential.
fn outsider(endpoint: &str) -> zenoh::Config {
    let mut config = zenoh::Config::default();
    config.insert_json5("mode", "\"peer\"").unwrap();
    config.insert_json5("scouting/multicast/enabled", "false").unwrap();
    config
        .insert_json5("listen/endpoints", "[\"tcp/127.0.0.1:0\"]")
        .unwrap();
    config
        .insert_json5("connect/endpoints", &format!("[\"{endpoint}\"]"))
        .unwrap();
    config
}

/// A client of the run holding `identity`'s certificate (`recorder`, `observer`, `agent-2`,
/// `world`, ...), from its configuration in the run directory, as a process of the run's owner
/// could open; the world's, a router's, made a client of the world.
fn holding(run: &Path, identity: &str) -> zenoh::Config {
    let file = match identity {
        "recorder" => "zenoh.json5".to_string(),
        other => format!("{other}.json5"),
    };
    let text = std::fs::read_to_string(run.join(file)).unwrap();
    let config: serde_json::Value = serde_json::from_str(&text).unwrap();
    if identity == "world" {
        let tls = &config["transport"]["link"]["tls"];
        let as_client = serde_json::json!({
            "root_ca_certificate_base64": tls["root_ca_certificate_base64"],
            "connect_certificate_base64": tls["listen_certificate_base64"],
            "connect_private_key_base64": tls["listen_private_key_base64"],
            "enable_mtls": true,
        });
        return client(&config["listen"]["endpoints"][0], as_client);
    }
    zenoh::Config::from_json5(&config.to_string()).unwrap()
}

/// A client of the router at `endpoint` presenting Zenoh's `transport/link/tls` section `tls`.
fn client(endpoint: &serde_json::Value, tls: serde_json::Value) -> zenoh::Config {
    let config = serde_json::json!({
        "mode": "client",
        "scouting": { "multicast": { "enabled": false } },
        "connect": { "endpoints": [endpoint] },
        "transport": { "link": { "tls": tls } },
    });
    zenoh::Config::from_json5(&config.to_string()).unwrap()
}

async fn open(config: zenoh::Config) -> zenoh::Session {
    zenoh::open(config).await.unwrap()
}

/// Publishes without dropping: every message of the test reaches whoever can hear it.
async fn put(session: &zenoh::Session, key: &str, bytes: Vec<u8>) {
    session
        .put(key, bytes)
        .congestion_control(CongestionControl::Block)
        .await
        .unwrap();
}

/// Speaks as the world does to everyone: publishes for the agents, and hands over to the
/// recorders, which take the world's last words only by hand-over (docs/PROTOCOL.md).
async fn as_the_world(session: &zenoh::Session, key: &str, bytes: Vec<u8>) {
    put(session, key, bytes.clone()).await;
    let replies = session
        .get(key)
        .payload(bytes)
        .target(zenoh::query::QueryTarget::All)
        .consolidation(zenoh::query::ConsolidationMode::None)
        .timeout(Duration::from_secs(5))
        .await
        .unwrap();
    while replies.recv_async().await.is_ok() {}
}

/// What one tick of case (b) looks like on the bus, to forge from.
fn samples() -> (State, Command, Gamma) {
    let state = State {
        version: PROTOCOL_VERSION,
        tick: 0,
        id: 1,
        t: 0.0,
        position: [0.0, 0.0],
        heading: 0.0,
        sideslip: 0.0,
        sideslip_rate: 0.0,
        current: [0.0, 0.0],
        dynamics: None,
    };
    let command = Command {
        version: PROTOCOL_VERSION,
        tick: 0,
        id: 1,
        v: 0.0,
        r: 1.0,
        accel: 0.0,
        hold: false,
        gamma: 40.0,
        gamma_dot: 3.0,
        v_d: 0.0,
        x_e: 0.0,
        y_e: 0.0,
        psi_e: 0.0,
        receptions: vec![],
    };
    let gamma = Gamma {
        version: PROTOCOL_VERSION,
        tick: 0,
        from: 1,
        sample: Some(tcpf_core::msg::Sample {
            t: 0.0,
            gamma: 40.0,
            gamma_dot: 3.0,
            position: [0.0, 0.0],
        }),
        busy: false,
    };
    (state, command, gamma)
}

/// A client of the run at `endpoint` that trusts the run's authority (its certificate is no
/// secret) and presents a certificate named `world`, made by an authority of its own.
fn impostor(run: &Path, endpoint: &str) -> zenoh::Config {
    let text = std::fs::read_to_string(run.join("observer.json5")).unwrap();
    let observer: serde_json::Value = serde_json::from_str(&text).unwrap();
    let own = tcpf_bus::certificate::Authority::new(MISSION).unwrap();
    let world = own.issue("world", &[]).unwrap();
    let mut config = tcpf_bus::certificate::tls(&own.pem(), &world, false);
    config["root_ca_certificate_base64"] = observer["transport"]["link"]["tls"]["root_ca_certificate_base64"].clone();
    let mut impostor = client(&endpoint.into(), config);
    impostor.insert_json5("connect/timeout_ms", "2000").unwrap();
    impostor
}

#[tokio::test(flavor = "multi_thread")]
async fn a_process_without_the_runs_credential_can_neither_listen_nor_steer() {
    let _fleet = fleet();
    let dir = scratch("outsider");
    let mut launch = Launch::start(&paper("b-current"), &dir.join("p"), &SLOWER);
    let endpoint = endpoint(&launch);
    let refused = zenoh::open(impostor(&dir.join("p"), &endpoint)).await;
    assert!(
        refused.is_err(),
        "a certificate named world but not of the run's authority was let in"
    );
    let session = zenoh::open(outsider(&endpoint)).await.unwrap();
    // A session of its own, so as not to hear the forgeries below.
    let listener = zenoh::open(outsider(&endpoint)).await.unwrap();
    let heard = Arc::new(Mutex::new(0u64));
    let counter = heard.clone();
    let _listen = listener
        .declare_subscriber(key("**"))
        .callback(move |_| *counter.lock().unwrap() += 1)
        .await
        .unwrap();
    launch.wait_for("logs/world.log", "starting");

    // What steered a run before it had a credential: an end, γ for ticks to come, commands raced
    // against the agents', for every tick of the run.
    let (_, command, gamma) = samples();
    let mut sent = 0u64;
    for tick in 0..12_000u64 {
        if launch.child.try_wait().unwrap().is_some() {
            break;
        }
        if tick % 1000 == 0 {
            let end = End {
                version: PROTOCOL_VERSION,
                ticks: tick + 1,
                lost: vec![],
                arrived: everyone_arrived(tick),
            };
            put(&session, &key("end"), postcard::to_stdvec(&end).unwrap()).await;
        }
        for id in [1, 2] {
            let g = Gamma {
                tick,
                from: id,
                ..gamma
            };
            put(&session, &key(&format!("gamma/{id}")), postcard::to_stdvec(&g).unwrap()).await;
            let c = Command {
                tick,
                id,
                ..command.clone()
            };
            put(&session, &key(&format!("cmd/{id}")), postcard::to_stdvec(&c).unwrap()).await;
        }
        sent += 5;
        if tick % 100 == 0 {
            tokio::time::sleep(Duration::from_millis(2)).await;
        }
    }
    let status = launch.wait(Duration::from_secs(120));
    session.close().await.unwrap();
    let heard = *heard.lock().unwrap();
    let s = launch.summary();
    eprintln!(
        "outsider: sent {sent}, heard {heard}, the run refused {}",
        s["rejected_messages"]
    );
    assert!(status.success(), "{s}");
    assert_eq!(heard, 0, "without the credential nothing of the run is heard");
    assert_eq!(s["rejected_messages"], 0, "and nothing reaches it");
    run_in_process(&paper("b-current"), &dir.join("i"), &SLOWER);
    assert_same_run(&dir.join("p"), &dir.join("i"));
    let modes = |f: &str| std::fs::metadata(dir.join("p").join(f)).unwrap().permissions();
    for file in [
        "zenoh.json5",
        "world.json5",
        "agent-1.json5",
        "observer.json5",
        "endpoint",
    ] {
        use std::os::unix::fs::PermissionsExt;
        assert_eq!(modes(file).mode() & 0o777, 0o600, "{file} is the owner's only");
    }
    assert_none_left(&s);
}

/// Peak resident memory (kB) of the launcher (which records) and of each child, by role, polled
/// until the launcher exits.
fn peaks(launch: &mut Launch, mut meanwhile: impl FnMut()) -> BTreeMap<String, u64> {
    let mut peak: BTreeMap<String, u64> = BTreeMap::new();
    let hwm = |pid: u32| -> Option<(String, u64)> {
        let cmdline = std::fs::read(format!("/proc/{pid}/cmdline")).ok()?;
        let args: Vec<String> = cmdline
            .split(|b| *b == 0)
            .map(|a| String::from_utf8_lossy(a).into_owned())
            .collect();
        let role = match args.get(1).map(String::as_str) {
            Some("agent") => format!("agent {}", args[args.iter().position(|a| a == "--id")? + 1]),
            Some("run") => "launcher and recorder".into(),
            Some(other) => other.to_string(),
            None => return None,
        };
        let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
        let kb = status
            .lines()
            .find_map(|l| l.strip_prefix("VmHWM:"))?
            .trim()
            .trim_end_matches("kB")
            .trim()
            .parse()
            .ok()?;
        Some((role, kb))
    };
    while launch.child.try_wait().unwrap().is_none() {
        let root = launch.child.id();
        for pid in std::iter::once(root).chain(descendants(root)) {
            if let Some((role, kb)) = hwm(pid) {
                let p = peak.entry(role).or_default();
                *p = (*p).max(kb);
            }
        }
        meanwhile();
        std::thread::sleep(Duration::from_millis(20));
    }
    peak
}

/// A deterministic stream of junk.
struct Junk(u64);

impl Junk {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    fn bytes(&mut self) -> Vec<u8> {
        let n = (self.next() % 64) as usize;
        (0..n).map(|_| self.next() as u8).collect()
    }
}

const FLOOD: u64 = 100_000;

/// The insider: joins with the world's certificate, copies every genuine state,
/// command and γ it hears once as is and once with other values (for the tick under way), and
/// in between sends junk: random bytes, messages for ticks far ahead, NaN. Stops at FLOOD.
async fn flood(config: zenoh::Config, sent: Arc<Mutex<u64>>) {
    let session = open(config).await;
    let (tx, rx) = std::sync::mpsc::channel::<(String, Vec<u8>)>();
    let _copies = session
        .declare_subscriber(key("*/*"))
        .callback(move |s| {
            let _ = tx.send((s.key_expr().as_str().to_string(), s.payload().to_bytes().to_vec()));
        })
        .await
        .unwrap();
    let (state, command, gamma) = samples();
    let keys: Vec<String> = [
        "gamma/1", "gamma/2", "cmd/1", "cmd/2", "state/1", "state/2", "end", "lost/1",
    ]
    .iter()
    .map(|k| key(k))
    .collect();
    let mut junk = Junk(0x9e37_79b9_7f4a_7c15);
    let mut count = 0u64;
    let far = 1_000_000_000;
    // The last tick copied per key: the flooder hears its own copies too, and copies each
    // genuine message once.
    let mut copied: BTreeMap<String, u64> = BTreeMap::new();
    let mut fresh = |k: &str, tick: u64| {
        let last = copied.entry(k.to_string()).or_insert(u64::MAX);
        let new = tick < far && (*last == u64::MAX || tick > *last);
        if new {
            *last = tick;
        }
        new
    };
    while count < FLOOD {
        // Other values for the tick under way, right behind each genuine message.
        while let Ok((k, bytes)) = rx.try_recv() {
            let other = if k.contains("/gamma/") {
                postcard::from_bytes::<Gamma>(&bytes)
                    .ok()
                    .filter(|g| fresh(&k, g.tick))
                    .map(|g| {
                        let sample = g.sample.map(|s| tcpf_core::msg::Sample {
                            gamma: s.gamma + 0.5,
                            ..s
                        });
                        postcard::to_stdvec(&Gamma { sample, ..g }).unwrap()
                    })
            } else if k.contains("/cmd/") {
                postcard::from_bytes::<Command>(&bytes)
                    .ok()
                    .filter(|c| fresh(&k, c.tick))
                    .map(|c| postcard::to_stdvec(&Command { v: c.v + 0.25, ..c }).unwrap())
            } else if k.contains("/state/") {
                postcard::from_bytes::<State>(&bytes)
                    .ok()
                    .filter(|s| fresh(&k, s.tick))
                    .map(|s| {
                        let position = [s.position[0] + 1.0, s.position[1]];
                        postcard::to_stdvec(&State { position, ..s }).unwrap()
                    })
            } else {
                None
            };
            if let Some(other) = other {
                put(&session, &k, bytes).await;
                put(&session, &k, other).await;
                count += 2;
            }
        }
        for _ in 0..40 {
            let k = &keys[(junk.next() % keys.len() as u64) as usize];
            let n = junk.next() % 4;
            let id = if k.ends_with('2') { 2 } else { 1 };
            let bytes = match n {
                0 => junk.bytes(),
                1 => postcard::to_stdvec(&Gamma {
                    tick: far + junk.next() % far,
                    from: id,
                    ..gamma
                })
                .unwrap(),
                2 => postcard::to_stdvec(&State {
                    tick: far + junk.next() % far,
                    id,
                    heading: f64::NAN,
                    ..state
                })
                .unwrap(),
                _ => postcard::to_stdvec(&Command {
                    tick: far + junk.next() % far,
                    id,
                    ..command.clone()
                })
                .unwrap(),
            };
            let bytes = if k.ends_with("/end") {
                postcard::to_stdvec(&End {
                    version: PROTOCOL_VERSION,
                    ticks: far,
                    lost: vec![],
                    arrived: everyone_arrived(far - 1),
                })
                .unwrap()
            } else {
                bytes
            };
            put(&session, k, bytes).await;
            count += 1;
        }
        *sent.lock().unwrap() = count;
        tokio::time::sleep(Duration::from_millis(1)).await;
    }
    session.close().await.unwrap();
}

#[tokio::test(flavor = "multi_thread")]
async fn a_flood_from_inside_the_run_changes_nothing_and_is_counted_by_kind() {
    let _fleet = fleet();
    let dir = scratch("flood");
    let mut quiet = Launch::start(&paper("b-current"), &dir.join("quiet"), &SLOWER);
    let baseline = peaks(&mut quiet, || {});
    assert!(quiet.wait(Duration::from_secs(1)).success());

    let mut launch = Launch::start(&paper("b-current"), &dir.join("p"), &SLOWER);
    endpoint(&launch);
    let sent = Arc::new(Mutex::new(0u64));
    // With the world's own certificate, which may say anything: what is sent is refused by the
    // roles' own checks.
    let flooder = tokio::spawn(flood(holding(&dir.join("p"), "world"), sent.clone()));
    // Once the flood runs, agent 2 is stopped for a second: the world holds the tick under way
    // open for its command, and the insider's copies of agent 1's command reach it while it
    // does. Otherwise only an insider faster than the fleet reaches a tick under way: beside a
    // CPU hog, every copy of a run of 27 734 ticks came after its tick (counted as `past`), and
    // the run was rightly reproducible.
    let root = launch.child.id();
    let mut held = false;
    let flooded = tokio::task::block_in_place(|| {
        peaks(&mut launch, || {
            if held || *sent.lock().unwrap() < 1000 {
                return;
            }
            if let Some(agent) = common::agent_under(root, 2) {
                common::kill("-STOP", agent);
                std::thread::sleep(Duration::from_secs(1));
                common::kill("-CONT", agent);
                held = true;
            }
        })
    });
    assert!(held, "agent 2 was held while the flood ran");
    let status = launch.wait(Duration::from_secs(1));
    let sent = *sent.lock().unwrap();
    flooder.abort();
    let s = launch.summary();
    eprintln!(
        "flood: {sent} messages sent; refused {}: {}",
        s["rejected_messages"], s["rejections"]
    );
    eprintln!("peak RSS kB without the flood {baseline:?}, with it {flooded:?}");
    // Completed, but not reproducible (below): exit 1, as every lockstep run that is not.
    assert_eq!(
        (status.code(), &s["completed"]),
        (Some(1), &serde_json::json!(true)),
        "{s}"
    );
    assert!(sent >= FLOOD, "the whole flood was sent while the run lasted ({sent})");
    run_in_process(&paper("b-current"), &dir.join("i"), &SLOWER);
    assert_same_run(&dir.join("p"), &dir.join("i"));

    let kinds = &s["rejections"];
    for kind in ["undecodable", "non_finite", "future", "duplicate", "conflict"] {
        assert!(kinds[kind].as_u64().unwrap() > 0, "{kind} counted: {kinds}");
    }
    // Here every genuine message came first, but no receiver can know it: two messages of one
    // sender and tick make the run one that is not reproducible, and say why.
    assert_eq!(s["reproducible"], false, "{s}");
    assert!(
        s["reproducible_reasons"]
            .to_string()
            .contains("another process speaks for a role on the bus"),
        "{s}"
    );
    for (role, kb) in &flooded {
        // The world routes the flood to every subscriber of its keys.
        if ["agent", "launcher", "world"].iter().any(|r| role.starts_with(r)) {
            assert!(
                *kb <= 2 * baseline[role],
                "{role}: {kb} kB against {} kB",
                baseline[role]
            );
        }
    }
    let logs: u64 = std::fs::read_dir(dir.join("p/logs"))
        .unwrap()
        .map(|e| e.unwrap().metadata().unwrap().len())
        .sum();
    eprintln!("logs: {logs} bytes");
    assert!(
        logs < 1_000_000,
        "refusals are logged as counts, not one line each: {logs} bytes"
    );
    assert_none_left(&s);
}

/// A participant whose clock or tick count is wrong, in a realtime run: one state, command and γ
/// of each vehicle stamped a billion ticks ahead, sent a few times once the run is under way. Each
/// role refuses them as `future`; held as the freshest, they made every genuine message after them
/// `past`, and the vehicles never arrived.
#[tokio::test(flavor = "multi_thread")]
async fn messages_far_ahead_of_a_realtime_fleets_clock_are_refused_and_it_arrives_on_time() {
    let _fleet = fleet();
    let dir = scratch("ahead");
    let realtime = ["--clock", "realtime", "--time-scale", "10"];
    let mut launch = Launch::start(&paper("b-current"), &dir.join("p"), &realtime);
    endpoint(&launch);
    let session = open(holding(&dir.join("p"), "world")).await;
    tokio::task::block_in_place(|| wait_until_simulated(&dir.join("p"), 2.0));
    let (state, command, gamma) = samples();
    let far = 1_000_000_000;
    for round in 0..5 {
        for id in [1, 2] {
            let tick = far + round;
            let s = State { tick, id, ..state };
            put(&session, &key(&format!("state/{id}")), postcard::to_stdvec(&s).unwrap()).await;
            let c = Command {
                tick,
                id,
                ..command.clone()
            };
            put(&session, &key(&format!("cmd/{id}")), postcard::to_stdvec(&c).unwrap()).await;
            let g = Gamma {
                tick,
                from: id,
                ..gamma
            };
            put(&session, &key(&format!("gamma/{id}")), postcard::to_stdvec(&g).unwrap()).await;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    let status = tokio::task::block_in_place(|| launch.wait(Duration::from_secs(120)));
    session.close().await.unwrap();
    let s = launch.summary();
    assert!(status.success(), "{s}");
    // Each round: two states to the agents and two to the recorder, two commands to the world
    // and two to the recorder, one γ to each agent.
    assert_eq!(s["rejections"]["future"], 5 * 10, "{}", s["rejections"]);
    run_in_process(&paper("b-current"), &dir.join("i"), &[]);
    let lockstep = summary(&dir.join("i"));
    // 0.3 s on a quiet machine; beside a CPU hog, what the periods the run reports disturbed
    // allow (one run: 282 commands held over by the world, both vehicles 0.46 s late together).
    let allowed = common::allowed(&s, &dir.join("p"));
    let within = allowed.arrival.max(0.3);
    for (l, r) in s["vehicles"]
        .as_array()
        .unwrap()
        .iter()
        .zip(lockstep["vehicles"].as_array().unwrap())
    {
        let (ours, theirs) = (l["arrival_time"].as_f64().unwrap(), r["arrival_time"].as_f64().unwrap());
        assert!(
            (ours - theirs).abs() < within,
            "arrival {ours:.3} s against lockstep's {theirs:.3} s ({} disturbed periods, {} uneven γ: {within:.3} s allowed)",
            allowed.disturbed,
            allowed.uneven
        );
    }
    assert_none_left(&s);
}

/// How many idle connections the flood below holds open at once.
const IDLE: usize = 300;

/// Holds `IDLE` TCP connections to `address` open, idle, opening a new one for each that the
/// other side closes, until `stop` or 120 s; counts every one it opened in `opened`.
fn hold_idle_connections(address: String, stop: Arc<AtomicBool>, opened: Arc<AtomicU64>) {
    let mut held: Vec<TcpStream> = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(120);
    while !stop.load(Ordering::Relaxed) && Instant::now() < deadline {
        held.retain(|s| {
            let mut byte = [0u8; 1];
            match s.peek(&mut byte) {
                Ok(n) => n > 0,
                Err(e) => e.kind() == std::io::ErrorKind::WouldBlock,
            }
        });
        while held.len() < IDLE {
            let Ok(s) = TcpStream::connect(&address) else {
                break;
            };
            s.set_nonblocking(true).unwrap();
            held.push(s);
            opened.fetch_add(1, Ordering::Relaxed);
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// A process with no credential that holds hundreds of idle connections to the run's port
/// (opening another for each one closed) keeps nobody out: Zenoh refuses a new connection while
/// as many as `transport/unicast/accept_pending` have not finished their handshake, and 300 such
/// once kept a recorder out of a run waiting for it, and the launcher away from its own world.
#[test]
fn idle_connections_to_the_runs_port_keep_no_recorder_out() {
    let _fleet = fleet();
    let dir = scratch("connection-flood");
    let out = dir.join("p");
    let mut launch = Launch::start(
        &paper("b-current"),
        &out,
        &["--recorders", "1", "--startup-timeout", "30"],
    );
    let endpoint = endpoint(&launch);
    let (stop, opened) = (Arc::new(AtomicBool::new(false)), Arc::new(AtomicU64::new(0)));
    let address = endpoint.strip_prefix("tls/").expect("a TLS endpoint").to_string();
    let flood = {
        let (stop, opened) = (stop.clone(), opened.clone());
        std::thread::spawn(move || hold_idle_connections(address, stop, opened))
    };
    let until = Instant::now() + Duration::from_secs(30);
    while opened.load(Ordering::Relaxed) < IDLE as u64 {
        assert!(Instant::now() < until, "the flood could not open {IDLE} connections");
        std::thread::sleep(Duration::from_millis(20));
    }
    let recorded = dir.join("r");
    let mut recorder = common::Reaper(
        std::process::Command::new(env!("CARGO_BIN_EXE_tcpf"))
            .args(["record", &paper("b-current"), "-c"])
            .arg(out.join("zenoh.json5"))
            .arg("--out")
            .arg(&recorded)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let status = launch.wait(Duration::from_secs(120));
    let recorder_status = recorder.0.wait().unwrap();
    stop.store(true, Ordering::Relaxed);
    flood.join().unwrap();
    let opened = opened.load(Ordering::Relaxed);
    eprintln!("idle connections opened: {opened}");
    assert!(status.success(), "{}", launch.summary());
    assert!(recorder_status.success(), "the recorder joined and recorded");
    assert_eq!(summary(&recorded)["completed"], true);
    assert!(
        opened >= IDLE as u64,
        "the flood held {IDLE} connections ({opened} opened)"
    );
}

/// A forged verdict: both vehicles of case (b) arrived at `tick`.
fn everyone_arrived(tick: u64) -> Vec<Arrival> {
    vec![Arrival { id: 1, tick }, Arrival { id: 2, tick }]
}

/// Forges, with `session`, every word of the fleet a role other than its own says: an end and a
/// loss (published and handed over), states, commands and γ of vehicle 2 for ticks to come, a
/// tick record, and answers for the paths and the clock. Returns the queryables it declared,
/// which answer while they live.
async fn forge_everything(session: &zenoh::Session) -> Vec<zenoh::query::Queryable<()>> {
    let (state, command, gamma) = samples();
    let far = 1_000_000;
    let end = End {
        version: PROTOCOL_VERSION,
        ticks: 10,
        lost: vec![],
        arrived: everyone_arrived(9),
    };
    as_the_world(session, &key("end"), postcard::to_stdvec(&end).unwrap()).await;
    let loss = tcpf_core::msg::Loss::from(tcpf_core::msg::Lost {
        id: 2,
        tick: 1,
        reason: tcpf_core::msg::LossReason::Silent,
    });
    as_the_world(session, &key("lost/2"), postcard::to_stdvec(&loss).unwrap()).await;
    for round in 0..5 {
        let tick = far + round;
        let s = State { tick, id: 2, ..state };
        put(session, &key("state/2"), postcard::to_stdvec(&s).unwrap()).await;
        let c = Command {
            tick,
            id: 2,
            ..command.clone()
        };
        put(session, &key("cmd/2"), postcard::to_stdvec(&c).unwrap()).await;
        let g = Gamma { tick, from: 2, ..gamma };
        put(session, &key("gamma/2"), postcard::to_stdvec(&g).unwrap()).await;
        put(session, &key("tick"), vec![0xff; 64]).await;
    }
    let mut answering = Vec::new();
    for (what, bytes) in [("plan/2", vec![0u8; 32]), ("clock", vec![0u8; 16])] {
        answering.push(
            session
                .declare_queryable(key(what))
                .callback(move |query| {
                    use zenoh::Wait;
                    let _ = query.reply(query.key_expr().clone(), bytes.clone()).wait();
                })
                .await
                .unwrap(),
        );
    }
    answering
}

/// Processes holding the certificates an attacker would most plausibly hold, a recorder's (any
/// tool that joins a run to record it gets one), an observer's and vehicle 1's agent's, forge
/// every word of the fleet that is not theirs to say, while a lockstep run goes on: the world's
/// access rules drop each where it enters, no role sees one (nothing refused, nothing counted),
/// and the run is the in-process run's, bit for bit. With the shared password of before, each of
/// these made the run fail, end early, or lose a vehicle.
#[tokio::test(flavor = "multi_thread")]
async fn a_recorders_an_observers_or_another_agents_certificate_forges_nothing() {
    let _fleet = fleet();
    let dir = scratch("forgers");
    let out = dir.join("p");
    let mut launch = Launch::start(&paper("b-current"), &out, &SLOWER);
    endpoint(&launch);
    let mut forgers = Vec::new();
    for identity in ["recorder", "observer", "agent-1"] {
        forgers.push(open(holding(&out, identity)).await);
    }
    tokio::task::block_in_place(|| wait_until_simulated(&out, 1.0));
    let mut answering = Vec::new();
    for forger in &forgers {
        answering.extend(forge_everything(forger).await);
    }
    let (during, _) = common::last_recorded(&out).expect("a tick in telemetry.csv");
    let status = tokio::task::block_in_place(|| launch.wait(Duration::from_secs(120)));
    drop(answering);
    for forger in forgers {
        forger.close().await.unwrap();
    }
    let s = launch.summary();
    assert!(status.success(), "{s}");
    assert!(
        during < s["ticks"].as_u64().unwrap(),
        "the forgeries were sent while the run went on (by tick {during})"
    );
    assert_eq!(
        s["rejected_messages"], 0,
        "nothing forged reached a role: {}",
        s["rejections"]
    );
    assert_eq!(s["reproducible"], true, "{s}");
    run_in_process(&paper("b-current"), &dir.join("i"), &SLOWER);
    assert_same_run(&out, &dir.join("i"));
    assert_none_left(&s);
}

/// An end for a tick the fleet is about to reach, sent with the world's own certificate: the
/// recorder takes it (nothing tells it from the world's), but the fleet runs on past it, and every message of a later tick
/// contradicts it. The run says so: not completed, not reproducible, the contradicted end named
/// as the failure. Once, the recording stopped there with no failure while the fleet ran on.
#[tokio::test(flavor = "multi_thread")]
async fn a_forged_end_is_named_not_taken_for_the_runs_own() {
    let _fleet = fleet();
    let dir = scratch("forged-end");
    let out = dir.join("p");
    let mut launch = Launch::start(&paper("b-current"), &out, &SLOWER);
    endpoint(&launch);
    let session = open(holding(&out, "world")).await;
    tokio::task::block_in_place(|| wait_until_simulated(&out, 2.0));
    let (last, _) = common::last_recorded(&out).expect("a tick in telemetry.csv");
    // Ahead of every agent (which refuses an end it has not reached), behind the world soon.
    let forged = End {
        version: PROTOCOL_VERSION,
        ticks: last + 100,
        lost: vec![],
        arrived: everyone_arrived(last + 99),
    };
    as_the_world(&session, &key("end"), postcard::to_stdvec(&forged).unwrap()).await;
    let status = tokio::task::block_in_place(|| launch.wait(Duration::from_secs(120)));
    session.close().await.unwrap();
    let s = launch.summary();
    assert_eq!(status.code(), Some(1), "{s}");
    assert_eq!(s["reproducible"], false, "{s}");
    assert_eq!(s["completed"], false, "{s}");
    let why = s["failure"].as_str().unwrap_or_default();
    assert!(
        why.starts_with(&format!("the end announced after tick {} was contradicted", last + 99)),
        "{s}"
    );
    assert!(s["rejections"]["conflict"].as_u64().unwrap() > 0, "{s}");
}

/// A loss of vehicle 2 at tick 1, sent with the world's own certificate: its agent obeys and stops, and the world, no longer
/// hearing from it, loses the vehicle itself a few seconds later. A genuine world loses a vehicle
/// once: the second, different loss makes the run one that is not reproducible, and says that
/// another process spoke for a role. Once, the summary blamed the command timeout alone.
#[tokio::test(flavor = "multi_thread")]
async fn a_forged_loss_makes_the_run_say_another_process_spoke() {
    let _fleet = fleet();
    let dir = scratch("forged-loss");
    let out = dir.join("p");
    let mut launch = Launch::start(&paper("b-current"), &out, &["--command-timeout", "4"]);
    endpoint(&launch);
    let session = open(holding(&out, "world")).await;
    tokio::task::block_in_place(|| wait_until_simulated(&out, 1.0));
    let forged = tcpf_core::msg::Loss::from(tcpf_core::msg::Lost {
        id: 2,
        tick: 1,
        reason: tcpf_core::msg::LossReason::Silent,
    });
    as_the_world(&session, &key("lost/2"), postcard::to_stdvec(&forged).unwrap()).await;
    let status = tokio::task::block_in_place(|| launch.wait(Duration::from_secs(120)));
    session.close().await.unwrap();
    let s = launch.summary();
    assert_eq!(status.code(), Some(1), "{s}");
    assert_eq!(s["vehicles"][1]["lost"], true, "agent 2 obeyed the forged loss: {s}");
    assert_eq!(s["reproducible"], false, "{s}");
    assert!(
        s["reproducible_reasons"]
            .to_string()
            .contains("another process speaks for a role"),
        "{s}"
    );
    assert!(s["rejections"]["conflict"].as_u64().unwrap() >= 1, "{s}");
}

/// Vehicle 2's agent's own certificate commands vehicle 2 in a realtime run: for every command of its agent, one with
/// another speed stamped 20 ticks ahead (0.04 s of wall time at ×5, well within the skew allowed
/// between hosts' clocks). The world holds the freshest, so the forger steers the vehicle and its
/// agent's commands are refused as older. The run fails and says so. Once, it arrived with every
/// genuine command counted `past` and no word of why.
#[tokio::test(flavor = "multi_thread")]
async fn a_vehicle_commanded_ahead_of_the_clock_by_another_process_fails_the_run_by_name() {
    let _fleet = fleet();
    let dir = scratch("hijack");
    let out = dir.join("p");
    let realtime = ["--clock", "realtime", "--time-scale", "5"];
    let mut launch = Launch::start(&paper("b-current"), &out, &realtime);
    endpoint(&launch);
    let session = open(holding(&out, "agent-2")).await;
    let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel::<Vec<u8>>();
    let _genuine = session
        .declare_subscriber(key("cmd/2"))
        .callback(move |s| {
            let _ = tx.send(s.payload().to_bytes().to_vec());
        })
        .await
        .unwrap();
    let mut forged = 0u64;
    let mut seen = 0u64;
    while launch.child.try_wait().unwrap().is_none() {
        let Ok(Some(bytes)) = tokio::time::timeout(Duration::from_millis(200), rx.recv()).await else {
            continue;
        };
        let Ok(genuine) = postcard::from_bytes::<Command>(&bytes) else {
            continue;
        };
        // Its own copies come back too; each genuine tick is answered once.
        if genuine.tick <= seen {
            continue;
        }
        seen = genuine.tick + 20;
        let ahead = Command {
            tick: genuine.tick + 20,
            v: genuine.v * 0.5,
            ..genuine
        };
        put(&session, &key("cmd/2"), postcard::to_stdvec(&ahead).unwrap()).await;
        forged += 1;
    }
    let status = tokio::task::block_in_place(|| launch.wait(Duration::from_secs(120)));
    session.close().await.unwrap();
    let s = launch.summary();
    eprintln!("forged {forged} commands; the run: {}", s["failure"]);
    assert!(forged > 10, "the forger answered its agent ({forged})");
    assert_eq!(status.code(), Some(1), "{s}");
    let why = s["failure"].as_str().unwrap_or_default();
    assert!(why.contains("two processes commanded a vehicle"), "{s}");
}

/// The world's own password answers for the fleet's clock while the fleet waits for its world to start (the
/// agents and the launcher's recorder ask every so often until it answers), with another
/// mission's clock. Only the world that holds its role is listened to (`tcpf_core::fleet::claim`): the
/// run goes on as in-process, and each forged answer is counted as from the wrong sender.
/// Before, the first answer was taken, and every agent that heard it refused to run (exit 2).
#[tokio::test(flavor = "multi_thread")]
async fn a_clock_answered_by_another_process_than_the_world_is_counted_and_not_listened_to() {
    let _fleet = fleet();
    let dir = scratch("forged-clock");
    let out = dir.join("p");
    let mut launch = Launch::start(&paper("b-current"), &out, &["--recorders", "1"]);
    endpoint(&launch);
    let session = open(holding(&out, "world")).await;
    let forged = tcpf_core::msg::Clock {
        version: PROTOCOL_VERSION,
        realtime: false,
        time_scale: 1.0,
        epoch: tcpf_core::time::UnixTime(0.0),
        tick: 0,
        mission: 0xdead_beef,
    };
    let bytes = postcard::to_stdvec(&forged).unwrap();
    let answered = Arc::new(AtomicU64::new(0));
    let count = answered.clone();
    let _forger = session
        .declare_queryable(key("clock"))
        .callback(move |query| {
            use zenoh::Wait;
            count.fetch_add(1, Ordering::Relaxed);
            let _ = query.reply(query.key_expr().clone(), bytes.clone()).wait();
        })
        .await
        .unwrap();
    let until = Instant::now() + Duration::from_secs(30);
    while answered.load(Ordering::Relaxed) < 3 {
        assert!(Instant::now() < until, "nobody asked for the clock");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let recorded = dir.join("r");
    let recorder = tokio::process::Command::new(env!("CARGO_BIN_EXE_tcpf"))
        .args(["record", &paper("b-current"), "-c"])
        .arg(out.join("zenoh.json5"))
        .arg("--out")
        .arg(&recorded)
        .kill_on_drop(true)
        .output()
        .await
        .unwrap();
    assert!(
        recorder.status.success(),
        "{}",
        String::from_utf8_lossy(&recorder.stderr)
    );
    let status = tokio::task::block_in_place(|| launch.wait(Duration::from_secs(120)));
    session.close().await.unwrap();
    let s = launch.summary();
    assert!(status.success(), "{s}");
    run_in_process(&paper("b-current"), &dir.join("i"), &[]);
    assert_same_run(&out, &dir.join("i"));
    let wrong = s["rejections"]["wrong_sender"].as_u64().unwrap();
    eprintln!(
        "forged clock answers: {} sent, {wrong} counted",
        answered.load(Ordering::Relaxed)
    );
    assert!(wrong >= 1, "{s}");
    assert_none_left(&s);
}

/// The `tcpf` binary with `args`, its standard error in `log`.
fn tcpf_logged(args: &[&str], log: &Path) -> std::process::Child {
    std::process::Command::new(env!("CARGO_BIN_EXE_tcpf"))
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::fs::File::create(log).unwrap())
        .spawn()
        .unwrap()
}

/// A client of the router at `endpoint` presenting the certificate in `file` (a role's of
/// `tcpf credential DIR MISSION`).
fn presenting(file: &Path, endpoint: &str) -> zenoh::Config {
    let tcpf_bus::credential::Credential::Certificate(bundle) = tcpf_bus::credential::read(file).unwrap() else {
        panic!("{}: not a certificate", file.display())
    };
    client(
        &endpoint.into(),
        tcpf_bus::certificate::tls(&bundle.authority, &bundle.pair, false),
    )
}

/// A fleet started by hand with a certificate per role (`tcpf credential DIR MISSION`, the
/// router given the directory): a role given another role's certificate is refused by name
/// before it starts; holding agent 1's, the observer's or the recorder's, processes forge every
/// word of the fleet that is not theirs while the run goes on, and the router drops each where
/// it enters: the run is the in-process run, bit for bit, with nothing refused by any role.
#[tokio::test(flavor = "multi_thread")]
async fn a_fleet_started_by_hand_with_a_certificate_per_role_lets_each_speak_only_as_itself() {
    use std::os::unix::fs::PermissionsExt;
    let _fleet = fleet();
    let dir = scratch("keys");
    let keys = dir.join("fleet");
    let mission = paper("b-current");
    let made = common::tcpf(&["credential", keys.to_str().unwrap(), &mission]);
    assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode(&keys), 0o700);
    let mut files: Vec<String> = std::fs::read_dir(&keys)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    assert_eq!(
        files,
        [
            "access.json5",
            "agent-1.pem",
            "agent-2.pem",
            "observer.pem",
            "planner.pem",
            "recorder.pem",
            "router.pem",
            "world.pem"
        ]
    );
    for file in &files {
        assert_eq!(mode(&keys.join(file)), 0o600, "{file}");
    }
    let again = common::tcpf(&["credential", keys.to_str().unwrap(), &mission]);
    assert_eq!(again.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&again.stderr).contains("exists"));

    let key = |identity: &str| keys.join(format!("{identity}.pem")).to_str().unwrap().to_string();
    let log = |name: &str| dir.join(format!("{name}.log"));
    let (router, endpoint) = common::listening(|e| {
        tcpf_logged(
            &[
                "router",
                "--credential",
                keys.to_str().unwrap(),
                "-l",
                &common::over_tls(e),
            ],
            &log("router"),
        )
    });
    let endpoint = common::over_tls(&endpoint);
    let mut roles = vec![common::Reaper(router)];
    // Another role's certificate: refused by name, before it says anything.
    let wrong = common::tcpf(&[
        "agent",
        &mission,
        "--id",
        "2",
        "--credential",
        &key("agent-1"),
        "-e",
        &endpoint,
    ]);
    let said = String::from_utf8_lossy(&wrong.stderr);
    assert_eq!(wrong.status.code(), Some(2), "{said}");
    assert!(
        said.contains("is agent-1's, and this process is agent-2") && said.contains(&key("agent-2")),
        "{said}"
    );
    let role = |args: &[&str], identity: &str| {
        let mut all: Vec<&str> = args.to_vec();
        let own = key(identity);
        all.extend(["--credential", &own, "-e", &endpoint]);
        all.extend(SLOWER);
        common::Reaper(tcpf_logged(&all, &log(identity)))
    };
    roles.push(role(&["planner", &mission], "planner"));
    roles.push(role(&["world", &mission, "--recorders", "1"], "world"));
    roles.push(role(&["agent", &mission, "--id", "1"], "agent-1"));
    roles.push(role(&["agent", &mission, "--id", "2"], "agent-2"));
    let out = dir.join("p");
    let mut record = {
        let own = key("recorder");
        let mut all = vec!["record", &mission, "--credential", &own, "-e", &endpoint];
        all.extend(["--out", out.to_str().unwrap()]);
        all.extend(SLOWER);
        common::Reaper(tcpf_logged(&all, &log("recorder")))
    };
    let mut forgers = Vec::new();
    for identity in ["recorder", "observer", "agent-1"] {
        forgers.push(open(presenting(&keys.join(format!("{identity}.pem")), &endpoint)).await);
    }
    tokio::task::block_in_place(|| wait_until_simulated(&out, 1.0));
    let mut answering = Vec::new();
    for forger in &forgers {
        answering.extend(forge_everything(forger).await);
    }
    let (during, _) = common::last_recorded(&out).expect("a tick in telemetry.csv");
    let code =
        tokio::task::block_in_place(|| common::wait_exit(&mut record.0, Duration::from_secs(120), "the recorder"));
    drop(answering);
    for forger in forgers {
        forger.close().await.unwrap();
    }
    let said = std::fs::read_to_string(log("recorder")).unwrap();
    assert_eq!(code, Some(0), "{said}");
    let s = summary(&out);
    assert!(
        during < s["ticks"].as_u64().unwrap(),
        "the forgeries were sent while the run went on (by tick {during})"
    );
    assert_eq!(s["completed"], true, "{s}");
    assert_eq!(s["reproducible"], true, "{s}");
    assert_eq!(
        s["rejected_messages"], 0,
        "nothing forged reached a role: {}",
        s["rejections"]
    );
    run_in_process(&mission, &dir.join("i"), &SLOWER);
    assert_same_run(&out, &dir.join("i"));
    drop(roles);
}
