//! A stock ROS 2 joins a fleet: a Zenoh built as rmw_zenoh builds it (this crate's Cargo.toml),
//! with no user-password authentication and Zenoh's TLS link as published, opens its session as
//! rmw_zenoh does, from a configuration file (`ZENOH_SESSION_CONFIG_URI`), and listens to a
//! lockstep run: the run's `ros2.json5` (mutual TLS, the run's certificate for listening), or
//! with `--ros2-open` nothing but what rmw_zenoh's default configuration says. The tcpf binary is
//! `$TCPF_BIN` (by default the workspace's release build); each test kills what it started.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::Value;
use zenoh::liveliness::LivelinessToken;
use zenoh::sample::Sample;
use zenoh::Session;
use zenoh_ext::{AdvancedSubscriber, AdvancedSubscriberBuilderExt, HistoryConfig, RecoveryConfig};

#[path = "../../common/fleet.rs"]
// Shared by the interop crates: not every one uses every helper.
#[allow(dead_code)]
mod fleet;
use fleet::{repo, scratch, spawn, telemetry, wait_exit, wait_for, Reaper};

const DOMAIN: u32 = 6;
const MISSION: &str = "paper-b-current";

/// What a ROS 2 node hears of the domain: per topic (`tcpf/vehicle_1/odom`, `clock`), each
/// sample's payload.
type Heard = Arc<Mutex<BTreeMap<String, Vec<Vec<u8>>>>>;

/// A session opened as rmw_zenoh opens its own: `Config::from_file`.
async fn open(config: &Path) -> zenoh::Result<Session> {
    zenoh::open(zenoh::Config::from_file(config)?).await
}

/// Subscribes to everything of the domain, as `ros2 topic echo` of every topic would, keeping
/// each sample by its topic: the key's chunks before the type's (`<domain>/<topic…>/<type>/<hash>`).
async fn listen(session: &Session) -> (Heard, zenoh::pubsub::Subscriber<()>) {
    let heard: Heard = Arc::default();
    let into = heard.clone();
    let subscriber = session
        .declare_subscriber(format!("{DOMAIN}/**"))
        .callback(move |sample: Sample| {
            let key = sample.key_expr().as_str();
            let chunks: Vec<&str> = key.split('/').collect();
            let topic = chunks[1..chunks.len().saturating_sub(2)].join("/");
            into.lock()
                .unwrap()
                .entry(topic)
                .or_default()
                .push(sample.payload().to_bytes().to_vec());
        })
        .await
        .unwrap();
    (heard, subscriber)
}

/// The ROS 2 nodes a session sees in the graph (the names of the node tokens,
/// `@ros2_lv/<domain>/<zid>/<nid>/<eid>/NN/<enclave>/<namespace>/<name>`), once it sees the
/// fleet's three, or 10 s have passed: the agents declare theirs as they start, after the world.
async fn nodes(session: &Session) -> Vec<String> {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let mut names = Vec::new();
        for token in tokens(session, &format!("@ros2_lv/{DOMAIN}/**")).await {
            let chunks: Vec<&str> = token.split('/').collect();
            if chunks.get(5) == Some(&"NN") {
                names.push(format!("{}/{}", chunks[7].replace('%', "/"), chunks[8]));
            }
        }
        names.sort();
        if names.len() >= 3 || Instant::now() >= deadline {
            return names;
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// The run this test listens to: case (b) in lockstep on domain `DOMAIN`, held until one more
/// recorder has joined, so that nothing is published before the listener is there.
fn held_run(dir: &Path, extra: &[&str]) -> Reaper {
    let out = dir.join("run");
    let mission = repo("configs/paper/b-current.toml");
    let domain = DOMAIN.to_string();
    let mut args = vec![
        "run",
        &mission,
        "--out",
        out.to_str().unwrap(),
        "--ros2",
        &domain,
        "--recorders",
        "1",
    ];
    args.extend(extra);
    let run = spawn(dir, "run", &args);
    wait_for(&out.join("endpoint"), "tls/", Duration::from_secs(60));
    run
}

/// The recorder the held run waits for (the run's `zenoh.json5`), listening for what no role of
/// the fleet publishes: `probe/**` on the fleet's keys and in the ROS 2 domain.
struct Recorder {
    session: Session,
    probes: Arc<Mutex<Vec<String>>>,
    _subscribers: Vec<zenoh::pubsub::Subscriber<()>>,
}

impl Recorder {
    async fn join(dir: &Path) -> Recorder {
        let session = open(&dir.join("run/zenoh.json5")).await.unwrap();
        let probes: Arc<Mutex<Vec<String>>> = Arc::default();
        let mut subscribers = Vec::new();
        for key in [format!("tcpf/{MISSION}/probe/**"), format!("{DOMAIN}/tcpf/probe/**")] {
            let into = probes.clone();
            let subscriber = session
                .declare_subscriber(key)
                .callback(move |s: Sample| into.lock().unwrap().push(s.key_expr().to_string()))
                .await
                .unwrap();
            subscribers.push(subscriber);
        }
        // Its subscriptions reach the router before anyone probes.
        tokio::time::sleep(Duration::from_millis(500)).await;
        Recorder {
            session,
            probes,
            _subscribers: subscribers,
        }
    }

    /// Lets the run start and waits for it to end; returns the probes heard.
    async fn release(self, run: &mut Reaper, dir: &Path) -> Vec<String> {
        let token = self.start().await;
        self.finish(token, run, dir).await
    }

    /// Lets the run start: the recorder the world waits for is here.
    async fn start(&self) -> LivelinessToken {
        self.session
            .liveliness()
            .declare_token(format!("tcpf/{MISSION}/alive/record/78"))
            .await
            .unwrap()
    }

    /// Waits for the run to end; returns the probes heard.
    async fn finish(self, token: LivelinessToken, run: &mut Reaper, dir: &Path) -> Vec<String> {
        let status = wait_exit(run, Duration::from_secs(120));
        assert!(
            status.success(),
            "{}",
            std::fs::read_to_string(dir.join("run.log")).unwrap()
        );
        token.undeclare().await.unwrap();
        self.session.close().await.unwrap();
        let heard = self.probes.lock().unwrap().clone();
        heard
    }
}

/// Says something on the fleet's keys and in its ROS 2 domain, as a listener must not.
async fn probe(session: &Session) {
    for key in [
        format!("tcpf/{MISSION}/probe/forged"),
        format!("{DOMAIN}/tcpf/probe/forged"),
    ] {
        session.put(key, vec![0u8; 8]).await.unwrap();
    }
}

/// A CDR reader (little-endian, after the 4-byte encapsulation header) of what these tests read
/// of ROS 2 messages.
struct Cdr<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Cdr<'_> {
    fn new(payload: &[u8]) -> Cdr<'_> {
        assert_eq!(&payload[..2], [0, 1], "CDR little-endian");
        Cdr {
            bytes: &payload[4..],
            at: 0,
        }
    }

    fn take<const N: usize>(&mut self) -> [u8; N] {
        self.at = self.at.div_ceil(N) * N;
        let out = self.bytes[self.at..self.at + N].try_into().unwrap();
        self.at += N;
        out
    }

    /// A `builtin_interfaces/Time` in seconds.
    fn time(&mut self) -> f64 {
        let sec = i32::from_le_bytes(self.take());
        let nanosec = u32::from_le_bytes(self.take());
        f64::from(sec) + f64::from(nanosec) * 1e-9
    }

    fn string(&mut self) -> String {
        let len = u32::from_le_bytes(self.take()) as usize;
        let text = &self.bytes[self.at..self.at + len - 1];
        self.at += len;
        String::from_utf8(text.to_vec()).unwrap()
    }

    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }
}

/// An odometry's stamp, child frame and position.
fn odometry(payload: &[u8]) -> (f64, String, f64, f64) {
    let mut cdr = Cdr::new(payload);
    let stamp = cdr.time();
    let _frame = cdr.string();
    let child = cdr.string();
    (stamp, child, cdr.f64(), cdr.f64())
}

/// Every /clock of the run, one per tick in order, and every odometry of both vehicles, each as
/// telemetry.csv has that vehicle at that time.
fn assert_heard_the_run(heard: &Heard, out: &Path) {
    let rows = telemetry(out);
    let ticks = rows.iter().filter(|r| r[2] == "1").count();
    // The last samples may still be on their way when the run has exited.
    let deadline = Instant::now() + Duration::from_secs(10);
    let count = |topic: &str| heard.lock().unwrap().get(topic).map_or(0, Vec::len);
    let all = || count("clock") >= ticks && count("tcpf/vehicle_1/odom") + count("tcpf/vehicle_2/odom") >= rows.len();
    while !all() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    let heard = heard.lock().unwrap();
    let clock: Vec<f64> = heard["clock"].iter().map(|p| Cdr::new(p).time()).collect();
    assert_eq!(clock.len(), ticks, "a /clock per tick");
    for (k, t) in clock.iter().enumerate() {
        assert!((t - k as f64 * 0.01).abs() < 1e-9, "tick {k} at {t}");
    }
    for id in ["1", "2"] {
        let of: Vec<&Vec<String>> = rows.iter().filter(|r| r[2] == id).collect();
        let odometry: Vec<_> = heard[&format!("tcpf/vehicle_{id}/odom")]
            .iter()
            .map(|p| odometry(p))
            .collect();
        assert_eq!(odometry.len(), of.len(), "an odometry of vehicle {id} per row");
        for (row, (stamp, child, x, y)) in of.iter().zip(&odometry) {
            let expected: (f64, f64, f64) = (
                row[1].parse().unwrap(),
                row[3].parse().unwrap(),
                row[4].parse().unwrap(),
            );
            assert_eq!(child, &format!("vehicle_{id}"));
            // A stamp is whole nanoseconds; the row's time the tick's in seconds.
            assert!(
                (stamp - expected.0).abs() < 1e-9,
                "vehicle {id} stamped {stamp} at t = {}",
                expected.0
            );
            assert_eq!(
                (*x, *y),
                (expected.1, expected.2),
                "vehicle {id}'s odometry at t = {}",
                expected.0
            );
        }
    }
}

/// A session opened from `config` sees the fleet's ROS 2 graph, hears the whole held run, and
/// what it says reaches no one.
async fn listens_only(config: &Path, run: &mut Reaper, dir: &Path) {
    let session = open(config).await.unwrap();
    assert_eq!(
        nodes(&session).await,
        ["/tcpf/agent_1", "/tcpf/agent_2", "/tcpf/world"],
        "the fleet's ROS 2 graph"
    );
    let (heard, _subscriber) = listen(&session).await;
    let recorder = Recorder::join(dir).await;
    probe(&session).await;
    let forged = recorder.release(run, dir).await;
    assert!(forged.is_empty(), "a listener spoke: {forged:?}");
    assert_heard_the_run(&heard, &dir.join("run"));
    session.close().await.unwrap();
}

/// The run's `ros2.json5`, as rmw_zenoh loads it, sees the fleet's ROS 2 graph and hears every
/// odometry and /clock of a lockstep run. The same file without its TLS settings, or presenting
/// no certificate of its own, joins nothing.
#[tokio::test(flavor = "multi_thread")]
async fn ros2_json5_lets_a_stock_rmw_zenoh_hear_the_whole_run() {
    let dir = scratch("ros2-json5");
    let out = dir.join("run");
    let mut run = held_run(&dir, &[]);
    let config = out.join("ros2.json5");

    let text: Value = serde_json::from_str(&std::fs::read_to_string(&config).unwrap()).unwrap();
    for (name, strip) in [
        ("no TLS settings", &["transport", "link", "tls"][..]),
        (
            "no certificate of its own",
            &["transport", "link", "tls", "connect_certificate_base64"][..],
        ),
    ] {
        let mut bare = text.clone();
        let (last, path) = strip.split_last().unwrap();
        let parent = path.iter().fold(&mut bare, |v, k| &mut v[*k]);
        parent.as_object_mut().unwrap().remove(*last);
        if *last == "connect_certificate_base64" {
            parent.as_object_mut().unwrap().remove("connect_private_key_base64");
        }
        // Not a minute of retries for a link that cannot be made.
        bare["connect"]["timeout_ms"] = 3000.into();
        let file = dir.join("bare.json5");
        std::fs::write(&file, bare.to_string()).unwrap();
        assert!(open(&file).await.is_err(), "a session with {name} joined the fleet");
    }

    listens_only(&config, &mut run, &dir).await;
}

/// `--ros2-open`: where rmw_zenoh's default configuration connects (`tcp/localhost:7447`, a
/// peer, no multicast scouting), a session with nothing else in its configuration, no
/// credential, hears every odometry and /clock of a lockstep run, and what it says reaches no one.
#[tokio::test(flavor = "multi_thread")]
async fn an_open_run_lets_a_ros2_node_with_no_configuration_listen_and_only_listen() {
    let dir = scratch("open");
    let mut run = held_run(&dir, &["--ros2-open"]);
    wait_for(
        &dir.join("run.log"),
        "OPEN to listeners: the world also listens at tcp/127.0.0.1:7447",
        Duration::from_secs(10),
    );
    let defaults = dir.join("rmw_zenoh-defaults.json5");
    std::fs::write(
        &defaults,
        r#"{ mode: "peer", connect: { endpoints: ["tcp/localhost:7447"] }, listen: { endpoints: ["tcp/localhost:0"] },
            scouting: { multicast: { enabled: false } } }"#,
    )
    .unwrap();
    listens_only(&defaults, &mut run, &dir).await;
}

/// The keys of the fleet's transient-local topics, as their `@adv` tokens name them
/// (`<key>/@adv/pub/<zid>/uhlc/_`): a planned path per vehicle.
async fn latched_keys(session: &Session) -> Vec<String> {
    let mut keys: Vec<String> = tokens(session, &format!("{DOMAIN}/**/@adv/pub/**"))
        .await
        .iter()
        .map(|token| token.split("/@adv/").next().unwrap().to_string())
        .collect();
    keys.sort();
    keys
}

/// The liveliness tokens under `key` that the session sees now.
async fn tokens(session: &Session, key: &str) -> Vec<String> {
    let replies = session
        .liveliness()
        .get(key)
        .timeout(Duration::from_secs(5))
        .await
        .unwrap();
    let mut tokens = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result() {
            tokens.push(sample.key_expr().to_string());
        }
    }
    tokens
}

/// How many samples came on each key.
type Deliveries = Arc<Mutex<BTreeMap<String, usize>>>;

/// A transient-local subscription as rmw_zenoh declares one (`SubscriptionData::init`, for the
/// fleet's paths' QoS: reliable, transient local, keep last 10): zenoh-ext's
/// `AdvancedSubscriber`, detected through liveliness, asking for the history of late publishers
/// with no timeout, recovering by heartbeat.
async fn subscribe_as_rmw_zenoh(session: &Session, key: &str, into: &Deliveries) -> AdvancedSubscriber<()> {
    let into = into.clone();
    session
        .declare_subscriber(key.to_string())
        .history(HistoryConfig::default().detect_late_publishers().max_samples(10))
        .query_timeout(Duration::from_millis(u64::MAX))
        .subscriber_detection()
        .recovery(RecoveryConfig::default().heartbeat())
        .callback(move |sample: Sample| {
            *into.lock().unwrap().entry(sample.key_expr().to_string()).or_default() += 1;
        })
        .await
        .unwrap()
}

/// Waits up to `within` for a sample on each of `keys`, then a second more for any copy.
async fn settle(deliveries: &Deliveries, keys: &[String], within: Duration) -> BTreeMap<String, usize> {
    let deadline = Instant::now() + within;
    while deliveries.lock().unwrap().len() < keys.len() && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    tokio::time::sleep(Duration::from_secs(1)).await;
    let got = deliveries.lock().unwrap().clone();
    got
}

/// A ROS 2 subscriber of a planned path, declared as rmw_zenoh declares it, receives the path
/// exactly once: joining before the run starts (the world's live sample and its answer to the
/// history query are one sample to it), and joining while it runs (the answer alone).
#[tokio::test(flavor = "multi_thread")]
async fn a_late_subscriber_as_rmw_zenoh_makes_one_receives_each_path_once() {
    let dir = scratch("late");
    let mut run = held_run(&dir, &["--clock", "realtime", "--time-scale", "5"]);
    let config = dir.join("run/ros2.json5");
    let early = open(&config).await.unwrap();
    assert_eq!(nodes(&early).await.len(), 3, "the fleet's ROS 2 graph");
    let keys = latched_keys(&early).await;
    assert_eq!(keys.len(), 2, "a path per vehicle: {keys:?}");
    assert!(
        keys.iter().all(|k| k.contains("/path/nav_msgs::msg::dds_::Path_/")),
        "{keys:?}"
    );
    let before: Deliveries = Arc::default();
    let mut subscribers = Vec::new();
    for key in &keys {
        subscribers.push(subscribe_as_rmw_zenoh(&early, key, &before).await);
    }
    let recorder = Recorder::join(&dir).await;
    let token = recorder.start().await;
    let once: BTreeMap<String, usize> = keys.iter().map(|k| (k.clone(), 1)).collect();
    assert_eq!(
        settle(&before, &keys, Duration::from_secs(20)).await,
        once,
        "joined before the start"
    );
    // The run is under way: the world publishes its vehicles' odometry.
    let (heard, _odometry) = listen(&early).await;
    let odometry = "tcpf/vehicle_1/odom";
    let deadline = Instant::now() + Duration::from_secs(10);
    while !heard.lock().unwrap().contains_key(odometry) && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert!(
        heard.lock().unwrap().contains_key(odometry),
        "no odometry: {:?}",
        heard.lock().unwrap().keys().collect::<Vec<_>>()
    );
    let late = open(&config).await.unwrap();
    let after: Deliveries = Arc::default();
    for key in &keys {
        subscribers.push(subscribe_as_rmw_zenoh(&late, key, &after).await);
    }
    assert_eq!(
        settle(&after, &keys, Duration::from_secs(10)).await,
        once,
        "joined while it runs"
    );
    assert!(
        run.0.try_wait().unwrap().is_none(),
        "the run ended before the late subscriber had its paths"
    );
    drop(subscribers);
    recorder.finish(token, &mut run, &dir).await;
    late.close().await.unwrap();
    early.close().await.unwrap();
}
