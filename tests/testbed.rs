//! A networked testbed on one machine: a shore host (Zenoh router, planner, world, recorder) and
//! one host per vehicle (its agent), each a network namespace with its own address, as
//! tests/common/testbed.rs builds them. Needs root, as CI has.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::testbed::Testbed;
use common::{assert_same_run, paper, run_in_process, scratch, summary};

const TCPF: &str = env!("CARGO_BIN_EXE_tcpf");
const PORT: u16 = 7447;

fn zenoh_config(name: &str) -> String {
    format!("{}/configs/zenoh/{name}.json5", env!("CARGO_MANIFEST_DIR"))
}

/// The fleet of case (b) on `bed`: router, planner, world and recorder on the shore, each agent
/// on its vehicle's host, every role a client of the router. `config(role)` is the Zenoh
/// configuration of a role (`router`, `shore` or `vehicle-<id>`), `clock` extra role options.
/// Returns the recorder's run directory once the recorder has exited.
fn fleet(bed: &mut Testbed, dir: &Path, config: impl Fn(&str) -> String, clock: &[&str]) -> PathBuf {
    let mission = paper("b-current");
    let router = format!("tcp/{}:{PORT}", bed.address("shore"));
    let log = |name: &str| dir.join(format!("{name}.log"));
    bed.spawn("shore", dir, &log("router"), TCPF, &["router", "-c", &config("router")]);
    let shore = config("shore");
    let on_shore = |role: &str| {
        let mut args = vec![role.to_string(), mission.clone(), "-c".into(), shore.clone()];
        args.extend(clock.iter().map(|s| s.to_string()));
        args
    };
    let planner = on_shore("planner");
    bed.spawn("shore", dir, &log("planner"), TCPF, &as_strs(&planner));
    let mut world = on_shore("world");
    world.extend(["--recorders".into(), "1".into()]);
    bed.spawn("shore", dir, &log("world"), TCPF, &as_strs(&world));
    for id in ["1", "2"] {
        let vehicle = config(&format!("vehicle-{id}"));
        let mut args = vec!["agent", &mission, "--id", id, "-c", &vehicle, "-e", &router];
        args.extend(clock);
        bed.spawn(&format!("v{id}"), dir, &log(&format!("agent-{id}")), TCPF, &args);
    }
    let out = dir.join("run");
    let mut record = on_shore("record");
    record.extend(["--out".into(), out.display().to_string()]);
    let recorder = bed.spawn("shore", dir, &log("record"), TCPF, &as_strs(&record));
    let status = bed.wait(recorder, Duration::from_secs(120));
    let read = |name: &str| std::fs::read_to_string(log(name)).unwrap_or_default();
    assert!(
        status.is_some_and(|s| s.success()),
        "the recorder: {status:?}\n{}\nworld: {}\nagent 1: {}",
        read("record"),
        read("world"),
        read("agent-1")
    );
    out
}

fn as_strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

#[test]
fn case_b_on_a_shore_host_and_two_vehicle_hosts_is_the_in_process_run() {
    let dir = scratch("hosts");
    let mut bed = Testbed::new("plain", &["shore", "v1", "v2"]);
    let config = |role: &str| match role {
        "router" | "shore" => zenoh_config(role),
        _ => zenoh_config("vehicle"),
    };
    let out = fleet(&mut bed, &dir, config, &[]);
    run_in_process(&paper("b-current"), &dir.join("in-process"), &[]);
    assert_same_run(&out, &dir.join("in-process"));
    assert_eq!(summary(&out)["completed"], true);
}
