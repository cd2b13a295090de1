//! A networked testbed on one machine: a shore host (Zenoh router, planner, world, recorder) and
//! one host per vehicle (its agent), each a network namespace with its own address, as
//! tests/common/testbed.rs builds them. Needs root, as CI has, and openssl for certificates.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use common::testbed::Testbed;
use common::{
    arrivals, assert_same_run, paper, run_in_process, scratch, summary, timing, wait_until_simulated, without_command,
};

const TCPF: &str = env!("CARGO_BIN_EXE_tcpf");
const PORT: u16 = 7447;

fn repo(path: &str) -> String {
    format!("{}/{path}", env!("CARGO_MANIFEST_DIR"))
}

/// How the fleet's roles reach the router: configs/zenoh/ (plain TCP with the fleet's one key),
/// tls/ (mutual TLS over QUIC with certificates per host, tests/testbed/pki.sh), a certificate
/// per role made by `tcpf credential` (the router's access rules, configs/zenoh/acl/, made from
/// the mission), or udp/ (plain TCP, and UDP beside it for the vehicles' best-effort γ).
#[derive(Clone, Copy, PartialEq)]
enum Security {
    Plain,
    Tls,
    Acl,
    Udp,
}

/// Where `tcpf credential` writes the fleet directory of `Security::Acl`.
fn fleet_dir(dir: &Path) -> PathBuf {
    dir.join("fleet")
}

impl Security {
    fn config(self, role: &str) -> String {
        let role = if role.starts_with("vehicle") { "vehicle" } else { role };
        match (self, role) {
            (Security::Plain, _) | (Security::Udp, "shore") => repo(&format!("configs/zenoh/{role}.json5")),
            (Security::Udp, _) => repo(&format!("configs/zenoh/udp/{role}.json5")),
            (Security::Acl, _) => repo(&format!("configs/zenoh/{role}.json5")),
            _ => repo(&format!("configs/zenoh/tls/{role}.json5")),
        }
    }

    /// What the process of `identity` (`router` for the router) presents beyond its
    /// configuration: the fleet's credential where the configuration (plain TCP or UDP) demands
    /// none by itself, or its own certificate; the router, its fleet directory, on `tls/`.
    fn credential(self, dir: &Path, identity: &str) -> Vec<String> {
        match (self, identity) {
            (Security::Plain | Security::Udp, _) => {
                vec!["--credential".into(), common::credential().display().to_string()]
            }
            (Security::Tls, _) => vec![],
            (Security::Acl, "router") => vec![
                "--credential".into(),
                fleet_dir(dir).display().to_string(),
                "-l".into(),
                format!("tls/0.0.0.0:{PORT}"),
            ],
            (Security::Acl, _) => {
                let file = fleet_dir(dir).join(format!("{identity}.pem"));
                vec!["--credential".into(), file.display().to_string()]
            }
        }
    }

    /// Where a role on the shore reaches the router, if not where its configuration says: a
    /// certificate of `tcpf credential` is presented over `tls/` only.
    fn on_shore(self) -> Vec<String> {
        match self {
            Security::Acl => vec!["-e".into(), format!("tls/127.0.0.1:{PORT}")],
            _ => vec![],
        }
    }

    /// Mutual TLS with the testbed's own certificates rides QUIC: configs/zenoh/tls/router.json5
    /// says why not TCP.
    fn scheme(self) -> &'static str {
        match self {
            Security::Plain | Security::Udp => "tcp",
            Security::Tls => "quic",
            Security::Acl => "tls",
        }
    }

    /// A vehicle's Zenoh options: its configuration and the router's endpoint. The UDP variant
    /// names two endpoints in one group, which `-e` cannot say: its file is written with the
    /// shore's address instead.
    fn vehicle(self, dir: &Path, shore: &str) -> Vec<String> {
        let config = self.config("vehicle");
        if self == Security::Udp {
            let text = std::fs::read_to_string(&config).unwrap().replace("127.0.0.1", shore);
            let file = dir.join("vehicle-udp.json5");
            std::fs::write(&file, text).unwrap();
            vec!["-c".into(), file.display().to_string()]
        } else {
            let router = format!("{}/{shore}:{PORT}", self.scheme());
            vec!["-c".into(), config, "-e".into(), router]
        }
    }
}

/// A working directory per host, with the certificates its configuration names: `certs/ca.pem`,
/// the router's pair on the shore, and `certs/<role>.pem`/`.key` of `identity`.
fn host_dir(dir: &Path, host: &str, role: &str, identity: &str) -> PathBuf {
    let home = dir.join(host);
    let certs = home.join("certs");
    std::fs::create_dir_all(&certs).unwrap();
    let pki = dir.join("pki");
    if pki.join("ca.pem").is_file() {
        let copy = |from: &str, to: &str| std::fs::copy(pki.join(from), certs.join(to)).unwrap();
        copy("ca.pem", "ca.pem");
        copy(&format!("{identity}.pem"), &format!("{role}.pem"));
        copy(&format!("{identity}.key"), &format!("{role}.key"));
        if role == "shore" {
            copy("router.pem", "router.pem");
            copy("router.key", "router.key");
        }
    }
    home
}

/// The fleet's CA and certificates: the router's valid for the shore's address, and one
/// identity for the shore and for each vehicle.
fn make_pki(dir: &Path, bed: &Testbed) {
    let names = format!("IP:{},IP:127.0.0.1", bed.address("shore"));
    let status = Command::new("sh")
        .arg(repo("tests/testbed/pki.sh"))
        .arg(dir.join("pki"))
        .args([names.as_str(), "shore", "vehicle-1", "vehicle-2", "observer"])
        .status()
        .expect("sh runs");
    assert!(status.success(), "tests/testbed/pki.sh failed (is openssl installed?)");
}

fn as_strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

/// `mission` (case (b)) on `bed`: router, planner, world and recorder on the shore, each agent on its
/// vehicle's host (agent 2 first, then `before_agent_1`, then agent 1), every role a client of
/// the router. Returns the recorder's run directory once it has exited.
fn fleet(
    bed: &mut Testbed,
    dir: &Path,
    mission: &str,
    security: Security,
    before_agent_1: impl FnOnce(&mut Testbed),
) -> PathBuf {
    let recorder = start(bed, dir, mission, security, &[], before_agent_1);
    finish(bed, dir, recorder)
}

/// `fleet` without waiting: every role started, `clock` given to each. Returns the recorder's pid.
fn start(
    bed: &mut Testbed,
    dir: &Path,
    mission: &str,
    security: Security,
    clock: &[&str],
    before_agent_1: impl FnOnce(&mut Testbed),
) -> u32 {
    let mission = mission.to_string();
    let log = |name: &str| dir.join(format!("{name}.log"));
    let shore_dir = host_dir(dir, "shore", "shore", "shore");
    bed.spawn(
        "shore",
        &shore_dir,
        &log("router"),
        TCPF,
        &as_strs(
            &[
                vec!["router".into(), "-c".into(), security.config("router")],
                security.credential(dir, "router"),
            ]
            .concat(),
        ),
    );
    let shore = security.config("shore");
    let on_shore = |role: &str, identity: &str| {
        let mut args = vec![role.to_string(), mission.clone(), "-c".into(), shore.clone()];
        args.extend(security.on_shore());
        args.extend(security.credential(dir, identity));
        args.extend(clock.iter().map(|c| c.to_string()));
        args
    };
    bed.spawn(
        "shore",
        &shore_dir,
        &log("planner"),
        TCPF,
        &as_strs(&on_shore("planner", "planner")),
    );
    let mut world = on_shore("world", "world");
    world.extend(["--recorders".into(), "1".into()]);
    bed.spawn("shore", &shore_dir, &log("world"), TCPF, &as_strs(&world));
    let out = dir.join("run");
    let mut record = on_shore("record", "recorder");
    record.extend(["--out".into(), out.display().to_string()]);
    let recorder = bed.spawn("shore", &shore_dir, &log("record"), TCPF, &as_strs(&record));
    let vehicle = security.vehicle(dir, &bed.address("shore"));
    let agent = |bed: &mut Testbed, id: &str| {
        let host = format!("v{id}");
        let home = host_dir(dir, &host, "vehicle", &format!("vehicle-{id}"));
        let credential = security.credential(dir, &format!("agent-{id}"));
        let mut args = vec!["agent", &mission, "--id", id];
        args.extend(vehicle.iter().chain(&credential).map(String::as_str));
        args.extend(clock);
        bed.spawn(&host, &home, &log(&format!("agent-{id}")), TCPF, &args);
    };
    agent(bed, "2");
    before_agent_1(bed);
    agent(bed, "1");
    recorder
}

/// Waits for the recorder started by `start`; its run directory.
fn finish(bed: &mut Testbed, dir: &Path, recorder: u32) -> PathBuf {
    let log = |name: &str| dir.join(format!("{name}.log"));
    let status = bed.wait(recorder, Duration::from_secs(120));
    let read = |name: &str| std::fs::read_to_string(log(name)).unwrap_or_default();
    assert!(
        status.is_some_and(|s| s.success()),
        "the recorder: {status:?}\n{}\nrouter: {}\nworld: {}\nagent 1: {}",
        read("record"),
        read("router"),
        read("world"),
        read("agent-1")
    );
    dir.join("run")
}

/// Waits until the world started by `start` has run `wall` seconds of its clock.
fn world_has_run(dir: &Path, wall: f64) {
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    while !std::fs::read_to_string(dir.join("world.log")).is_ok_and(|l| l.contains("agents present, starting")) {
        assert!(std::time::Instant::now() < deadline, "the world never started");
        std::thread::sleep(Duration::from_millis(5));
    }
    std::thread::sleep(Duration::from_secs_f64(wall));
}

/// The simulated time `s` of the world's log line that says `text` followed by "at t = s s".
fn world_said_at(dir: &Path, text: &str) -> f64 {
    let log = std::fs::read_to_string(dir.join("world.log")).unwrap();
    log.lines()
        .find_map(|l| {
            l.split_once(text)?
                .1
                .strip_prefix(" at t = ")?
                .split_once(" s")?
                .0
                .parse()
                .ok()
        })
        .unwrap_or_else(|| panic!("the world never said {text:?}: {log}"))
}

/// The in-process run of `mission`, the reference every fleet here must equal.
fn reference(dir: &Path, mission: &str) -> PathBuf {
    let out = dir.join("in-process");
    run_in_process(mission, &out, &[]);
    out
}

#[test]
fn case_b_on_a_shore_host_and_two_vehicle_hosts_is_the_in_process_run() {
    let _fleet = common::fleet();
    let dir = scratch("hosts");
    let mut bed = Testbed::new("plain", &["shore", "v1", "v2"]);
    let out = fleet(&mut bed, &dir, &paper("b-current"), Security::Plain, |_| {});
    assert_same_run(&out, &reference(&dir, &paper("b-current")));
    assert_eq!(summary(&out)["completed"], true);
}

#[test]
fn with_mutual_tls_the_fleet_runs_and_a_process_without_a_certificate_cannot_join() {
    let _fleet = common::fleet();
    let dir = scratch("tls");
    let mut bed = Testbed::new("tls", &["shore", "v1", "v2", "outsider"]);
    make_pki(&dir, &bed);
    // Trusts the fleet's CA, so it would accept the router, but has no certificate of its own.
    let outsider = dir.join("outsider");
    std::fs::create_dir_all(outsider.join("certs")).unwrap();
    std::fs::copy(dir.join("pki/ca.pem"), outsider.join("certs/ca.pem")).unwrap();
    let config = outsider.join("no-certificate.json5");
    std::fs::write(
        &config,
        r#"{ mode: "client", scouting: { multicast: { enabled: false } },
             transport: { link: { protocols: ["quic"], tls: { root_ca_certificate: "certs/ca.pem" } } } }"#,
    )
    .unwrap();
    let router = format!("quic/{}:{PORT}", bed.address("shore"));
    let mut intruder = None;
    let outsider_run = outsider.join("run");
    let out = fleet(&mut bed, &dir, &paper("b-current"), Security::Tls, |bed| {
        let args = [
            "record",
            &paper("b-current"),
            "-c",
            config.to_str().unwrap(),
            "-e",
            &router,
            // It has no credential to give, and knows it.
            "--open",
            "--out",
            outsider_run.to_str().unwrap(),
        ];
        intruder = Some(bed.spawn("outsider", &outsider, &dir.join("outsider.log"), TCPF, &args));
    });
    let outsider_status = bed.wait(intruder.unwrap(), Duration::from_secs(30));
    let said = std::fs::read_to_string(dir.join("outsider.log")).unwrap();
    assert!(
        outsider_status.is_some_and(|s| !s.success()),
        "a process without a certificate joined: {outsider_status:?} {said}"
    );
    assert!(said.contains("cannot open the Zenoh session"), "{said}");
    assert!(!outsider.join("run/telemetry.csv").exists() || summary(&outsider.join("run"))["ticks"] == 0);
    assert_same_run(&out, &reference(&dir, &paper("b-current")));
}

/// Over QUIC a connection closed at once drops what it has not yet delivered: each role stays
/// after its last words until the recorder, which leaves once it has every report, is gone.
/// In realtime, where roles end within a period of each other, the summary has every role's
/// timing and names nobody as unreported.
#[test]
fn over_mutual_tls_every_role_of_a_realtime_fleet_reports_as_it_exits() {
    let _fleet = common::fleet();
    let dir = scratch("tls-reports");
    let mut bed = Testbed::new("tlsrep", &["shore", "v1", "v2"]);
    make_pki(&dir, &bed);
    let clock = ["--clock", "realtime", "--time-scale", "10"];
    let recorder = start(&mut bed, &dir, &paper("b-current"), Security::Tls, &clock, |_| {});
    let s = summary(&finish(&mut bed, &dir, recorder));
    assert_eq!(s["completed"], true, "{s}");
    assert!(s["unreported"].is_null(), "every role reported: {}", s["unreported"]);
    for (role, id) in [("world", 0), ("agent", 1), ("agent", 2)] {
        timing(&s, role, id);
    }
    assert!(
        s["links"].as_array().unwrap().iter().all(|l| l["published"].is_u64()),
        "{}",
        s["links"]
    );
}

#[test]
fn with_access_control_a_vehicle_can_steer_only_itself() {
    let _fleet = common::fleet();
    let dir = scratch("acl");
    let mut bed = Testbed::new("acl", &["shore", "v1", "v2", "rogue"]);
    let router = format!("tls/{}:{PORT}", bed.address("shore"));
    // Case (b) speaking ROS 2 as well: the agents publish their commands through the router.
    let mission = dir.join("mission.toml");
    let table = "\n[ros2]\ndomain = 0\n";
    std::fs::write(&mission, std::fs::read_to_string(paper("b-current")).unwrap() + table).unwrap();
    let mission = mission.display().to_string();
    // A certificate per role, the router's valid at the shore's address, and the router's rules,
    // all made from the mission; the rules are the ones configs/zenoh/acl/ shows.
    let fleet_dir = fleet_dir(&dir);
    let made = Command::new(TCPF)
        .arg("credential")
        .args([
            &fleet_dir.display().to_string(),
            &mission,
            "--host",
            &bed.address("shore"),
        ])
        .output()
        .unwrap();
    assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
    assert_eq!(
        std::fs::read_to_string(fleet_dir.join("access.json5")).unwrap(),
        std::fs::read_to_string(repo("configs/zenoh/acl/access.json5")).unwrap(),
        "configs/zenoh/acl/access.json5 is not what `tcpf credential` makes of case (b) with [ros2] domain = 0: \
         write it again (docs/TESTBED.md says how)"
    );
    let vehicle = Security::Acl.config("vehicle");
    let pem = |identity: &str| fleet_dir.join(format!("{identity}.pem")).display().to_string();
    let (mut rogue, mut intruder, mut observer) = (None, None, None);
    let out = fleet(&mut bed, &dir, &mission, Security::Acl, |bed| {
        // Beside the real agent 1: an agent 1 holding agent 2's certificate ...
        let home = host_dir(&dir, "rogue", "vehicle", "agent-2");
        let agent_2 = pem("agent-2");
        let args = [
            "agent",
            &mission,
            "--id",
            "1",
            "-c",
            &vehicle,
            "-e",
            &router,
            "--credential",
            &agent_2,
            "--startup-timeout",
            "5",
        ];
        rogue = Some(bed.spawn("rogue", &home, &dir.join("rogue.log"), TCPF, &args));
        // ... and agent 1's genuine certificate publishing as vehicle 2, all through the run.
        let home = host_dir(&dir, "intruder", "vehicle", "agent-1");
        let script = repo("tests/testbed/intruder.py");
        let agent_1 = pem("agent-1");
        let args = [
            script.as_str(),
            &vehicle,
            &agent_1,
            &router,
            "8",
            "tcpf/paper-b-current/gamma/2",
            "tcpf/paper-b-current/cmd/2",
            // As ROS 2 nodes too: vehicle 2's odometry, and its commands.
            "0/tcpf/vehicle_2/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
            "0/tcpf/vehicle_2/cmd/geometry_msgs::msg::dds_::Twist_/RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a",
        ];
        intruder = Some(bed.spawn("rogue", &home, &dir.join("intruder.log"), "python3", &args));
        // On shore, an observer of the ROS 2 graph with a certificate of its own.
        let home = host_dir(&dir, "observer", "vehicle", "observer");
        let script = repo("tests/testbed/observer.py");
        let seen = dir.join("observer.json").display().to_string();
        let observer_pem = pem("observer");
        let args = [script.as_str(), &vehicle, &observer_pem, &router, "0", &seen];
        observer = Some(bed.spawn("shore", &home, &dir.join("observer.log"), "python3", &args));
        for (who, said) in [
            ("intruder", "connected, publishing"),
            ("observer", "connected, listening"),
        ] {
            common::wait_for_text(&dir.join(format!("{who}.log")), said, Duration::from_secs(30));
        }
    });
    assert_same_run(&out, &reference(&dir, &mission));
    let s = summary(&out);
    assert_eq!(
        s["rejected_messages"], 0,
        "nothing the intruders sent reached a role: {}",
        s["rejections"]
    );
    // The rogue is refused by name before it says a word: everything it said as agent 1 with
    // agent 2's certificate the router would drop.
    let rogue_status = bed.wait(rogue.unwrap(), Duration::from_secs(30));
    let said = std::fs::read_to_string(dir.join("rogue.log")).unwrap();
    assert_eq!(rogue_status.and_then(|s| s.code()), Some(2), "{said}");
    assert!(said.contains("agent-2") && said.contains("agent-1"), "{said}");
    let _ = bed.wait(intruder.unwrap(), Duration::from_secs(30));
    let sent = std::fs::read_to_string(dir.join("intruder.log")).unwrap();
    assert!(sent.contains("messages sent"), "the intruder ran: {sent}");
    // The observer heard the world's topics and each agent's commands, through the router, and
    // nothing the intruder sent as vehicle 2, nor its own attempt to command vehicle 1.
    let observed = bed.wait(observer.unwrap(), Duration::from_secs(30));
    let log = std::fs::read_to_string(dir.join("observer.log")).unwrap_or_default();
    assert!(observed.is_some_and(|s| s.success()), "{log}");
    let seen: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("observer.json")).unwrap()).unwrap();
    assert_eq!(seen["forged"], 0, "{seen}");
    assert!(seen["world_seen"] == true && seen["world_gone"] == true, "{seen}");
    let ticks = s["ticks"].as_u64().unwrap();
    for topic in [
        "tcpf/vehicle_1/cmd",
        "tcpf/vehicle_2/cmd",
        "tcpf/vehicle_1/odom",
        "tcpf/vehicle_2/odom",
    ] {
        let n = seen["heard"][topic].as_u64().unwrap_or(0);
        assert!(n > 0 && n <= ticks + 1, "{topic}: {n} of {ticks} ticks: {seen}");
    }
}

#[test]
fn a_vehicle_host_whose_link_goes_down_for_ten_seconds_falls_behind_and_catches_up() {
    let _fleet = common::fleet();
    let dir = scratch("link-down");
    let mut bed = Testbed::new("down", &["shore", "v1", "v2"]);
    // In real time: the vehicle's host reconnects when TCP's next SYN gets through, which backs
    // off in wall seconds (seen 1 to 6 s after the link came back), and the path left to catch
    // up on is in simulated ones.
    let clock = ["--clock", "realtime", "--time-scale", "1"];
    let recorder = start(&mut bed, &dir, &paper("b-current"), Security::Plain, &clock, |_| {});
    // From the world's own start, not from telemetry.csv: a recorder that writes late under load
    // would put the outage where the fleet has too little path left to catch up.
    world_has_run(&dir, 10.0);
    bed.link("v2", false);
    let down_at = std::time::Instant::now();
    std::thread::sleep(Duration::from_secs(10));
    bed.link("v2", true);
    let out = finish(&mut bed, &dir, recorder);
    let s = summary(&out);
    assert_eq!(s["completed"], true, "both arrive: {}", s["vehicles"]);
    let arrivals = arrivals(&s);
    assert!(
        (arrivals[0] - arrivals[1]).abs() < 0.5,
        "coordination recovers after the outage: arrivals {arrivals:?}"
    );
    // While the link was down nothing of vehicle 2 reached vehicle 1: its γ went stale. The
    // window in simulated time is from about t = 10 s to 20 s (seen 9.5 to 19.9), and the world
    // saw agent 2 go a lease later and come back when TCP's backoff let it: inside that, surely.
    let messages = std::fs::read_to_string(out.join("messages.csv")).unwrap();
    let heard: Vec<f64> = messages
        .lines()
        .skip(1)
        .filter_map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[2] == "2" && f[3] == "1").then(|| f[1].parse().unwrap())
        })
        .collect();
    let (from, to) = (
        world_said_at(&dir, "agent 2 is gone"),
        world_said_at(&dir, "agent 2 is here"),
    );
    assert!(
        (11.0..17.0).contains(&from) && to - from > 4.0,
        "the world saw agent 2 gone from t = {from} s to {to} s"
    );
    assert!(
        // Agent 2's first γ back may reach agent 1 before its liveliness reaches the world.
        !heard.iter().any(|t| (from..to - 0.5).contains(t)),
        "γ of vehicle 2 reached vehicle 1 inside the outage"
    );
    assert!(heard.iter().any(|&t| t >= 32.0), "and again after it");
    let drifted = without_command(&s, 2);
    // From the world's noticing (the lease: 3 s, seen up to 6 under load) to the reconnection.
    assert!(drifted > 400, "vehicle 2 drifted during the outage: {}", s["timing"]);
    assert!(down_at.elapsed() < Duration::from_secs(90));
}

#[test]
fn loss_that_the_kernel_makes_on_a_vehicle_host_is_the_loss_the_model_predicts() {
    let _fleet = common::fleet();
    let dir = scratch("real-loss");
    // A real run is one draw of a random loss, in clumps, against the model's 100 draws of a loss
    // that takes one γ at a time: once in some twenty suites beside a CPU hog a run on time (2 of
    // 5 477 periods skipped) fell beyond the model's range and its tenth (0.581 s against
    // 0.358–0.561 s, with 0.341 of vehicle 2's γ lost). A run outside is therefore run again, and
    // two in a row fail.
    let mut outside = Vec::new();
    for attempt in 1..=2 {
        let run = dir.join(format!("try-{attempt}"));
        std::fs::create_dir_all(&run).unwrap();
        let (s, lossy) = lossy_run(&run, &format!("loss{attempt}"));
        // The model of the loss the network made (the rule's 0.3 is a probability, and 547 γ
        // draw it ± 0.02, more in clumps) on the same link alone (the real run loses nothing of
        // vehicle 1's γ), over 100 seeds: the real run must fall in its range (a run that behaves
        // exactly as the model falls outside the range of 20 one time in ten), give or take a
        // tenth for what the model leaves out: losses in clumps, and a realtime fleet's timing on
        // a loaded host (0.510 against a range ending at 0.510 was seen once). The error alone
        // hardly tells this loss from none (0.36 s): the fraction that arrived does.
        let loss = ((1.0 - lossy) * 1000.0).round() / 1000.0;
        let (min, mean, max) = modelled_error(&run.join("sweep"), loss);
        let error = s["max_coordination_error"].as_f64().unwrap();
        println!(
            "real loss {loss} on 2→1 (the rule's 0.3): coordination error {error:.3} s; \
             the model of it over 100 seeds: mean {mean:.3} s, {min:.3}–{max:.3} s"
        );
        let (low, high) = (0.9 * min, 1.1 * max);
        if (low..=high).contains(&error) {
            return;
        }
        outside.push(format!(
            "{error:.3} s outside the model's {min:.3}–{max:.3} s, give or take a tenth ({low:.3}–{high:.3} s; \
             100 seeds, loss {loss} on 2→1)"
        ));
    }
    panic!("coordination error in two runs in a row: {}", outside.join("; "));
}

/// Case (b) in realtime on a testbed (`tag` names it) whose network drops 30 % of the datagrams
/// vehicle 2's host sends, once the fleet is under way: the run's summary, and the fraction of
/// vehicle 2's γ that reached vehicle 1.
fn lossy_run(dir: &Path, tag: &str) -> (serde_json::Value, f64) {
    let mut bed = Testbed::new(tag, &["shore", "v1", "v2"]);
    // Zenoh's links as they open and close: a UDP link that a loaded machine once lost for good
    // (the session went on over TCP alone, 1 run in ~40) says when and why in the logs.
    bed.log_filter = Some("info,zenoh_transport::unicast=debug,zenoh::net::runtime::orchestrator=debug".into());
    // At time scale 2 (a 5 ms wall period) a loaded 2-core host still keeps the fleet's timing,
    // so that the run measures the network's loss, not the host (docs/TESTBED.md).
    let clock = ["--clock", "realtime", "--time-scale", "2"];
    let recorder = start(&mut bed, dir, &paper("b-current"), Security::Udp, &clock, |_| {});
    // Once the fleet is under way (its UDP links open at the start, and a lost handshake leaves
    // a session on TCP alone), the network loses 30 % of the datagrams vehicle 2's host sends:
    // its best-effort γ. Dropped where they arrive, at the shore: a drop in the sender's own
    // OUTPUT chain fails its send() with EPERM, which Zenoh takes for a broken link. The
    // mission's own loss is 0.
    wait_until_simulated(&dir.join("run"), 1.0);
    // And once vehicle 2's UDP link is open: on a loaded machine it may open after the first
    // second, and its handshake would then meet the rule.
    let udp = format!(
        "ss -Hun state established dst {}:{} | grep -q .",
        bed.address("shore"),
        PORT + 1
    );
    let deadline = std::time::Instant::now() + Duration::from_secs(30);
    while !bed.run("v2", &["sh", "-c", &udp]) {
        let links = |log: &str| {
            let text = std::fs::read_to_string(dir.join(log)).unwrap_or_default();
            let udp: Vec<&str> = text.lines().filter(|l| l.contains("udp")).collect();
            udp.join("\n")
        };
        assert!(
            std::time::Instant::now() < deadline,
            "vehicle 2's UDP link to the shore is not open: its session runs on TCP alone\nagent 2: {}\nrouter: {}",
            links("agent-2.log"),
            links("router.log")
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let v2 = bed.address("v2");
    let rule = [
        "iptables",
        "-A",
        "INPUT",
        "-p",
        "udp",
        "-s",
        &v2,
        "-m",
        "statistic",
        "--mode",
        "random",
        "--probability",
        "0.3",
        "-j",
        "DROP",
    ];
    assert!(
        bed.run("shore", &rule),
        "iptables on the shore host (apt-get install iptables)"
    );
    let out = finish(&mut bed, dir, recorder);
    let s = summary(&out);
    assert_eq!(s["completed"], true, "{}", s["vehicles"]);
    let link = |from: u64| {
        s["links"]
            .as_array()
            .unwrap()
            .iter()
            .find(|l| l["from"] == from)
            .cloned()
            .unwrap_or_else(|| panic!("no link from {from}: {}", s["links"]))
    };
    // What reached the receiver: γ judged at an instant, and γ overtaken by a newer one before
    // an instant (the receiver woke too late to use the first). The rest the network lost.
    let arrived = |l: &serde_json::Value| {
        (l["sent"].as_f64().unwrap() + l["overtaken"].as_f64().unwrap()) / l["published"].as_f64().unwrap()
    };
    let (lossy, clean) = (arrived(&link(2)), arrived(&link(1)));
    // 547 γ at loss 0.3: 0.70 ± 0.02 if each were dropped alone, but a datagram can carry more
    // than one, and the rule drops datagrams, so losses come in clumps: 0.627 was seen once in
    // about twenty runs. The bounds stay well clear of no loss (1.0) and of double it (0.4).
    assert!(
        (0.60..=0.80).contains(&lossy),
        "fraction of vehicle 2's γ that reached vehicle 1: {lossy:.3} ({})",
        link(2)
    );
    // The rule spares vehicle 1's host: its γ arrive but for what a loaded host drops on its own
    // (0.945 was seen beside a build), far above the 0.7 the rule would leave.
    assert!(
        clean > 0.9,
        "the network loses next to none of vehicle 1's γ: {clean:.3} ({})",
        link(1)
    );
    (s, lossy)
}

/// The model's largest coordination error of case (b) with `loss` on the link 2→1 alone, over
/// 100 seeds: (min, mean, max).
fn modelled_error(sweep: &Path, loss: f64) -> (f64, f64, f64) {
    let o = Command::new(TCPF)
        .args([
            "sweep",
            &paper("b-current"),
            "--set",
            &format!("comms.link=[{{from = 2, to = 1, loss = {loss}}}]"),
        ])
        .args(["--loss", "0", "--seeds", "100", "--out"])
        .arg(sweep)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let simulated: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(sweep.join("sweep.json")).unwrap()).unwrap();
    let band = &simulated["points"][0]["metrics"]["max_coordination_error"];
    let value = |k: &str| band[k].as_f64().unwrap();
    (value("min"), value("mean"), value("max"))
}
