//! A networked testbed on one machine: a shore host (Zenoh router, planner, world, recorder) and
//! one host per vehicle (its agent), each a network namespace with its own address, as
//! tests/common/testbed.rs builds them. Needs root, as CI has, and openssl for certificates.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use common::testbed::Testbed;
use common::{assert_same_run, paper, run_in_process, scratch, summary};

const TCPF: &str = env!("CARGO_BIN_EXE_tcpf");
const PORT: u16 = 7447;

fn repo(path: &str) -> String {
    format!("{}/{path}", env!("CARGO_MANIFEST_DIR"))
}

/// How the fleet's roles reach the router: `plain`, `tls` or `acl` (configs/zenoh/).
#[derive(Clone, Copy, PartialEq)]
enum Security {
    Plain,
    Tls,
    Acl,
}

impl Security {
    fn config(self, role: &str) -> String {
        let role = if role.starts_with("vehicle") { "vehicle" } else { role };
        match (self, role) {
            (Security::Plain, _) => repo(&format!("configs/zenoh/{role}.json5")),
            (Security::Acl, "router") => repo("configs/zenoh/acl/router.json5"),
            _ => repo(&format!("configs/zenoh/tls/{role}.json5")),
        }
    }

    /// Mutual TLS rides QUIC: configs/zenoh/tls/router.json5 says why not TCP.
    fn scheme(self) -> &'static str {
        if self == Security::Plain {
            "tcp"
        } else {
            "quic"
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
        .args([names.as_str(), "shore", "vehicle-1", "vehicle-2"])
        .status()
        .expect("sh runs");
    assert!(status.success(), "tests/testbed/pki.sh failed (is openssl installed?)");
}

fn as_strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

/// Case (b) on `bed`: router, planner, world and recorder on the shore, each agent on its
/// vehicle's host (agent 2 first, then `before_agent_1`, then agent 1), every role a client of
/// the router. Returns the recorder's run directory once it has exited.
fn fleet(bed: &mut Testbed, dir: &Path, security: Security, before_agent_1: impl FnOnce(&mut Testbed)) -> PathBuf {
    let mission = paper("b-current");
    let router = format!("{}/{}:{PORT}", security.scheme(), bed.address("shore"));
    let log = |name: &str| dir.join(format!("{name}.log"));
    let shore_dir = host_dir(dir, "shore", "shore", "shore");
    bed.spawn(
        "shore",
        &shore_dir,
        &log("router"),
        TCPF,
        &["router", "-c", &security.config("router")],
    );
    let shore = security.config("shore");
    let on_shore = |role: &str| vec![role.to_string(), mission.clone(), "-c".into(), shore.clone()];
    bed.spawn(
        "shore",
        &shore_dir,
        &log("planner"),
        TCPF,
        &as_strs(&on_shore("planner")),
    );
    let mut world = on_shore("world");
    world.extend(["--recorders".into(), "1".into()]);
    bed.spawn("shore", &shore_dir, &log("world"), TCPF, &as_strs(&world));
    let out = dir.join("run");
    let mut record = on_shore("record");
    record.extend(["--out".into(), out.display().to_string()]);
    let recorder = bed.spawn("shore", &shore_dir, &log("record"), TCPF, &as_strs(&record));
    let vehicle = security.config("vehicle");
    let agent = |bed: &mut Testbed, id: &str| {
        let host = format!("v{id}");
        let home = host_dir(dir, &host, "vehicle", &format!("vehicle-{id}"));
        let args = ["agent", &mission, "--id", id, "-c", &vehicle, "-e", &router];
        bed.spawn(&host, &home, &log(&format!("agent-{id}")), TCPF, &args);
    };
    agent(bed, "2");
    before_agent_1(bed);
    agent(bed, "1");
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
    out
}

/// The in-process run of case (b), the reference every fleet here must equal.
fn reference(dir: &Path) -> PathBuf {
    let out = dir.join("in-process");
    run_in_process(&paper("b-current"), &out, &[]);
    out
}

#[test]
fn case_b_on_a_shore_host_and_two_vehicle_hosts_is_the_in_process_run() {
    let dir = scratch("hosts");
    let mut bed = Testbed::new("plain", &["shore", "v1", "v2"]);
    let out = fleet(&mut bed, &dir, Security::Plain, |_| {});
    assert_same_run(&out, &reference(&dir));
    assert_eq!(summary(&out)["completed"], true);
}

#[test]
fn with_mutual_tls_the_fleet_runs_and_a_process_without_a_certificate_cannot_join() {
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
    let out = fleet(&mut bed, &dir, Security::Tls, |bed| {
        let args = [
            "record",
            &paper("b-current"),
            "-c",
            config.to_str().unwrap(),
            "-e",
            &router,
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
    assert_same_run(&out, &reference(&dir));
}

#[test]
fn with_access_control_a_vehicle_can_steer_only_itself() {
    let dir = scratch("acl");
    let mut bed = Testbed::new("acl", &["shore", "v1", "v2", "rogue"]);
    make_pki(&dir, &bed);
    let router = format!("quic/{}:{PORT}", bed.address("shore"));
    let mission = paper("b-current");
    let vehicle = Security::Acl.config("vehicle");
    let (mut rogue, mut intruder) = (None, None);
    let out = fleet(&mut bed, &dir, Security::Acl, |bed| {
        // Before the real agent 1: an agent 1 holding vehicle 2's certificate ...
        let home = host_dir(&dir, "rogue", "vehicle", "vehicle-2");
        let args = [
            "agent",
            &mission,
            "--id",
            "1",
            "-c",
            &vehicle,
            "-e",
            &router,
            "--startup-timeout",
            "5",
        ];
        rogue = Some(bed.spawn("rogue", &home, &dir.join("rogue.log"), TCPF, &args));
        // ... and vehicle 1's genuine certificate publishing as vehicle 2, all through the run.
        let home = host_dir(&dir, "intruder", "vehicle", "vehicle-1");
        let script = repo("tests/testbed/intruder.py");
        let args = [
            script.as_str(),
            &vehicle,
            &router,
            "8",
            "tcpf/paper-b-current/gamma/2",
            "tcpf/paper-b-current/cmd/2",
        ];
        intruder = Some(bed.spawn("rogue", &home, &dir.join("intruder.log"), "python3", &args));
        std::thread::sleep(Duration::from_secs(1));
    });
    assert_same_run(&out, &reference(&dir));
    let s = summary(&out);
    assert_eq!(
        s["rejected_messages"], 0,
        "nothing the intruders sent reached a role: {}",
        s["rejections"]
    );
    let rogue_status = bed.wait(rogue.unwrap(), Duration::from_secs(30));
    let said = std::fs::read_to_string(dir.join("rogue.log")).unwrap();
    assert!(rogue_status.is_some_and(|s| !s.success()), "{said}");
    assert!(
        said.contains("no path from the planner"),
        "the rogue got nothing: {said}"
    );
    let _ = bed.wait(intruder.unwrap(), Duration::from_secs(30));
    let sent = std::fs::read_to_string(dir.join("intruder.log")).unwrap();
    assert!(sent.contains("messages sent"), "the intruder ran: {sent}");
}
